//! Introspection answers (anariGetObjectInfo, anariGetParameterInfo, anariGetProperty) for the
//! SDK device. They mirror `crate::capi::introspect`, whose helpers are private to that module;
//! the answers come from the same tables and the same cache keys, so both boundaries hand out
//! the same pointers.

use std::ffi::c_void;

use crate::capi::cache::{cached, leak_c_string, leak_slice, leak_string_list};
use crate::capi::types::ANARIParameter;
use crate::device::catalog;
use crate::device::datatype::*;
use crate::device::property::PropertyValue;
use crate::device::spec::{NAME_PARAM, ObjectSpec, ParamSpec, SpecValue};

fn spec_for(object_type: ANARIDataType, subtype: Option<&str>) -> Option<&'static ObjectSpec> {
    catalog::find(object_type, subtype.unwrap_or(""))
        .or_else(|| catalog::find(object_type, "default"))
        .filter(|s| {
            subtype.is_none_or(|st| st == s.subtype || s.subtype.is_empty() || st == "default")
        })
}

/// Encodes a table value as `data_type` bytes, when it is of that type.
fn spec_value_bytes(value: SpecValue, data_type: ANARIDataType) -> Option<Vec<u8>> {
    let floats = |v: &[f32]| v.iter().flat_map(|f| f.to_ne_bytes()).collect::<Vec<u8>>();
    let bytes = match (value, data_type) {
        (SpecValue::Bool(b), ANARI_BOOL) => vec![b as u8],
        (SpecValue::Int(i), ANARI_INT32) => i.to_ne_bytes().to_vec(),
        (SpecValue::Int(i), ANARI_UINT32) if i >= 0 => (i as u32).to_ne_bytes().to_vec(),
        (SpecValue::UInt(u), ANARI_UINT32) => u.to_ne_bytes().to_vec(),
        (SpecValue::UInt(u), ANARI_INT32) => (u as i32).to_ne_bytes().to_vec(),
        (SpecValue::Float(f), ANARI_FLOAT32) => f.to_ne_bytes().to_vec(),
        (SpecValue::Floats(v), t) if element_size(t) == Some(v.len() * 4) => floats(v),
        (SpecValue::UInts(v), t) if element_size(t) == Some(v.len() * 4) => {
            v.iter().flat_map(|u| u.to_ne_bytes()).collect()
        }
        (SpecValue::DataType(d), ANARI_DATA_TYPE) => d.to_ne_bytes().to_vec(),
        _ => return None,
    };
    Some(bytes)
}

/// anariGetObjectInfo: the address of the answer, or 0 when there is none.
pub(super) fn object_info(
    object_type: ANARIDataType,
    subtype: Option<&str>,
    info: &str,
    info_type: ANARIDataType,
) -> usize {
    let Some(spec) = spec_for(object_type, subtype) else {
        return 0;
    };
    let key = format!("info {} {} {info} {info_type}", spec.kind, spec.subtype);
    match (info, info_type) {
        ("description", ANARI_STRING) => cached(key, || leak_c_string(spec.description) as usize),
        ("parameter", ANARI_PARAMETER_LIST) => cached(key, || {
            let mut list: Vec<ANARIParameter> = std::iter::once(&NAME_PARAM)
                .chain(spec.all_params())
                .flat_map(|p| {
                    p.types.iter().map(|t| ANARIParameter {
                        name: leak_c_string(p.name),
                        data_type: *t,
                    })
                })
                .collect();
            list.push(ANARIParameter {
                name: std::ptr::null(),
                data_type: ANARI_UNKNOWN,
            });
            leak_slice(&list)
        }),
        ("channel", ANARI_STRING_LIST) if !spec.channels.is_empty() => {
            cached(key, || leak_string_list(spec.channels))
        }
        ("extension", ANARI_STRING_LIST) => cached(key, || leak_string_list(spec.extensions)),
        _ => 0,
    }
}

/// anariGetParameterInfo: the address of the answer, or 0 when there is none.
pub(super) fn parameter_info(
    object_type: ANARIDataType,
    subtype: Option<&str>,
    name: &str,
    param_type: ANARIDataType,
    info: &str,
    info_type: ANARIDataType,
) -> usize {
    let Some(spec) = spec_for(object_type, subtype) else {
        return 0;
    };
    let Some(param) = spec.param(name).filter(|p| p.types.contains(&param_type)) else {
        return 0;
    };
    param_info_value(spec, param, param_type, info, info_type)
}

fn param_info_value(
    spec: &'static ObjectSpec,
    param: &'static ParamSpec,
    param_type: ANARIDataType,
    info: &str,
    info_type: ANARIDataType,
) -> usize {
    let key = format!(
        "param {} {} {} {param_type} {info} {info_type}",
        spec.kind, spec.subtype, param.name
    );
    let value_of = |v: SpecValue| -> usize {
        if let (SpecValue::Str(s), ANARI_STRING) = (v, info_type) {
            return cached(key.clone(), || leak_c_string(s) as usize);
        }
        if info_type != param_type {
            return 0;
        }
        match spec_value_bytes(v, param_type) {
            Some(bytes) => cached(key.clone(), || leak_slice(&bytes)),
            None => 0,
        }
    };
    match (info, info_type) {
        ("required", ANARI_BOOL) => cached(key, || leak_slice(&[param.required as u8])),
        ("description", ANARI_STRING) => cached(key, || leak_c_string(param.description) as usize),
        ("default", _) => value_of(param.default),
        ("minimum", _) => value_of(param.minimum),
        ("maximum", _) => value_of(param.maximum),
        ("value", ANARI_STRING_LIST) if param_type == ANARI_STRING && !param.values.is_empty() => {
            cached(key, || leak_string_list(param.values))
        }
        ("value", ANARI_DATA_TYPE_LIST)
            if param_type == ANARI_DATA_TYPE && !param.values.is_empty() =>
        {
            let mut types: Vec<ANARIDataType> = param
                .values
                .iter()
                .filter_map(|n| type_from_name(n))
                .collect();
            types.push(ANARI_UNKNOWN);
            cached(key, || leak_slice(&types))
        }
        ("elementType", ANARI_DATA_TYPE_LIST) if !param.element_types.is_empty() => {
            let mut types = param.element_types.to_vec();
            types.push(ANARI_UNKNOWN);
            cached(key, || leak_slice(&types))
        }
        _ => 0,
    }
}

/// Writes a property value into `mem` if the type matches and `size` is large enough; returns 1
/// when written, 0 otherwise.
pub(super) fn write_property(
    value: &PropertyValue,
    data_type: ANARIDataType,
    mem: *mut c_void,
    size: u64,
) -> i32 {
    if value.data_type() != data_type {
        return 0;
    }
    let bytes: Vec<u8> = match value {
        PropertyValue::Int32(v) => v.to_ne_bytes().to_vec(),
        PropertyValue::UInt64(v) => v.to_ne_bytes().to_vec(),
        PropertyValue::Float32(v) => v.to_ne_bytes().to_vec(),
        PropertyValue::Bool(v) => vec![*v as u8],
        PropertyValue::Box3(v) => v.iter().flat_map(|f| f.to_ne_bytes()).collect(),
        PropertyValue::String(s) => {
            let pointer = cached(format!("property string {s}"), || leak_c_string(s) as usize);
            pointer.to_ne_bytes().to_vec()
        }
        PropertyValue::StringList(list) => {
            let pointer = cached(format!("property list {}", list.join(",")), || {
                leak_string_list(list)
            });
            pointer.to_ne_bytes().to_vec()
        }
    };
    if (size as usize) < bytes.len() {
        return 0;
    }
    // SAFETY: `mem` is writable for `size` bytes (caller contract) and we write no more.
    unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), mem as *mut u8, bytes.len()) };
    1
}
