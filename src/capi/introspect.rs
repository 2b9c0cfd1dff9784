//! Introspection and properties: anariGetObjectSubtypes, anariGetObjectInfo,
//! anariGetParameterInfo, anariGetProperty, anariDeviceGetProcAddress.

use std::ffi::{c_char, c_void};

use crate::capi::cache::{cached, leak_c_string, leak_slice, leak_string_list};
use crate::capi::types::*;
use crate::capi::{device_of, guard, plain_string, string_arg};
use crate::device::Device;
use crate::device::catalog::Kinds;
use crate::device::datatype::*;
use crate::device::property::{self, PropertyValue};
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::*;
use crate::kinds::KINDS;

fn spec_for(object_type: ANARIDataType, subtype: Option<&str>) -> Option<&'static ObjectSpec> {
    KINDS
        .find(object_type, subtype.unwrap_or(""))
        .or_else(|| KINDS.find(object_type, "default"))
        .filter(|s| {
            subtype.is_none_or(|st| st == s.subtype || s.subtype.is_empty() || st == "default")
        })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariGetObjectSubtypes(
    device: ANARIDevice,
    object_type: ANARIDataType,
) -> *mut *const c_char {
    const F: &str = "anariGetObjectSubtypes";
    guard(F, device, std::ptr::null_mut(), || {
        if device_of(F, device).is_none() {
            return std::ptr::null_mut();
        }
        let names = KINDS.subtype_names(object_type);
        cached(format!("subtypes {object_type}"), || {
            leak_string_list(&names)
        }) as _
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

/// anariGetObjectInfo's answer: the address of the cached value, or 0 when there is none. Shared
/// with the SDK device (`crate::sdk`), so both boundaries hand out the same pointers.
pub(crate) fn object_info(
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
            let mut list: Vec<ANARIParameter> = std::iter::once(&crate::device::spec::NAME_PARAM)
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

#[unsafe(no_mangle)]
pub extern "C" fn anariGetObjectInfo(
    device: ANARIDevice,
    object_type: ANARIDataType,
    object_subtype: *const c_char,
    info_name: *const c_char,
    info_type: ANARIDataType,
) -> *const c_void {
    const F: &str = "anariGetObjectInfo";
    guard(F, device, std::ptr::null(), || {
        let Some(dev) = device_of(F, device) else {
            return std::ptr::null();
        };
        let Some(info) = string_arg(&dev, F, "infoName", info_name) else {
            return std::ptr::null();
        };
        let subtype = plain_string(object_subtype);
        object_info(object_type, subtype.as_deref(), &info, info_type) as *const c_void
    })
}

/// anariGetParameterInfo's answer: the address of the cached value, or 0 when there is none.
/// Shared with the SDK device (`crate::sdk`).
pub(crate) fn parameter_info(
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

#[unsafe(no_mangle)]
pub extern "C" fn anariGetParameterInfo(
    device: ANARIDevice,
    object_type: ANARIDataType,
    object_subtype: *const c_char,
    parameter_name: *const c_char,
    parameter_type: ANARIDataType,
    info_name: *const c_char,
    info_type: ANARIDataType,
) -> *const c_void {
    const F: &str = "anariGetParameterInfo";
    guard(F, device, std::ptr::null(), || {
        let Some(dev) = device_of(F, device) else {
            return std::ptr::null();
        };
        get_parameter_info(
            &dev,
            object_type,
            object_subtype,
            parameter_name,
            parameter_type,
            info_name,
            info_type,
        )
    })
}

/// anariGetParameterInfo once the device is known (shared with the SDK device's slot).
pub(crate) fn get_parameter_info(
    dev: &Device,
    object_type: ANARIDataType,
    object_subtype: *const c_char,
    parameter_name: *const c_char,
    parameter_type: ANARIDataType,
    info_name: *const c_char,
    info_type: ANARIDataType,
) -> *const c_void {
    const F: &str = "anariGetParameterInfo";
    let (Some(name), Some(info)) = (
        string_arg(dev, F, "parameterName", parameter_name),
        string_arg(dev, F, "infoName", info_name),
    ) else {
        return std::ptr::null();
    };
    let subtype = plain_string(object_subtype);
    parameter_info(
        object_type,
        subtype.as_deref(),
        &name,
        parameter_type,
        &info,
        info_type,
    ) as *const c_void
}

/// Writes a property value into `mem` if the type matches and `size` is large enough; returns 1
/// when written, 0 otherwise. Shared with the SDK device (`crate::sdk`).
pub(crate) fn write_property(
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
        PropertyValue::Float32Vec2(v) => v.iter().flat_map(|f| f.to_ne_bytes()).collect(),
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

/// Reads a property. Returns 1 and writes `mem` on success; 0 (writing nothing) when the
/// property is unknown, of another type, or `size` is too small.
#[unsafe(no_mangle)]
pub extern "C" fn anariGetProperty(
    device: ANARIDevice,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    mem: *mut c_void,
    size: u64,
    mask: ANARIWaitMask,
) -> std::ffi::c_int {
    const F: &str = "anariGetProperty";
    guard(F, device, 0, || {
        let Some(dev) = device_of(F, device) else {
            return 0;
        };
        get_property(&dev, object as usize, name, data_type, mem, size, mask)
    })
}

/// anariGetProperty once the device is known, for the object with registry handle `handle`
/// (the device's own handle asks for a device property); shared with the SDK device's slot.
pub(crate) fn get_property(
    dev: &Device,
    handle: usize,
    name: *const c_char,
    data_type: ANARIDataType,
    mem: *mut c_void,
    size: u64,
    mask: ANARIWaitMask,
) -> std::ffi::c_int {
    const F: &str = "anariGetProperty";
    let Some(name) = string_arg(dev, F, "name", name) else {
        return 0;
    };
    if mem.is_null() {
        dev.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            None,
            format!("{F}('{name}'): 'mem' is NULL"),
        );
        return 0;
    }
    let value = if handle == dev.handle {
        property::device_property(dev, &name)
    } else {
        let Some(target) = dev.resolve(F, handle) else {
            return 0;
        };
        property::object_property(dev, &target, &name, mask & ANARI_WAIT != 0)
    };
    match value {
        Some(v) => write_property(&v, data_type, mem, size),
        None => 0,
    }
}

/// cavetrace's own functions, by name, for anariDeviceGetProcAddress.
pub type ANARIProcAddress = Option<unsafe extern "C" fn()>;

#[unsafe(no_mangle)]
pub extern "C" fn anariDeviceGetProcAddress(
    device: ANARIDevice,
    name: *const c_char,
) -> ANARIProcAddress {
    const F: &str = "anariDeviceGetProcAddress";
    guard(F, device, None, || {
        let dev = device_of(F, device)?;
        let name = string_arg(&dev, F, "name", name)?;
        crate::capi::extension::lookup(&name)
    })
}
