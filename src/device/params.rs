//! Parameter values and parameter sets. Objects keep a staged set (what the application set)
//! and a committed set (a snapshot taken at anariCommitParameters) that rendering reads.

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Mat4, UVec2, Vec2, Vec3, Vec4};

use crate::device::datatype::*;
use crate::device::object::Object;

/// One parameter value, owned: strings are copied and objects are retained.
#[derive(Clone, Debug)]
pub enum ParamValue {
    /// Plain data (numbers, vectors, matrices, boxes, bools, data types), at most 64 bytes.
    Data {
        data_type: ANARIDataType,
        bytes: [u8; 64],
    },
    String(String),
    /// A retained object; `data_type` is the kind it was set as.
    Object {
        data_type: ANARIDataType,
        object: Arc<Object>,
    },
    /// Pointers and function pointers (VOID_POINTER, STATUS_CALLBACK, …) stored as addresses.
    Pointer {
        data_type: ANARIDataType,
        address: usize,
    },
}

impl ParamValue {
    pub fn data_type(&self) -> ANARIDataType {
        match self {
            ParamValue::Data { data_type, .. }
            | ParamValue::Object { data_type, .. }
            | ParamValue::Pointer { data_type, .. } => *data_type,
            ParamValue::String(_) => ANARI_STRING,
        }
    }

    /// Builds plain data from raw bytes (`bytes.len()` must be the element size, ≤ 64).
    pub fn from_bytes(data_type: ANARIDataType, bytes: &[u8]) -> Option<ParamValue> {
        if bytes.len() > 64 {
            return None;
        }
        let mut storage = [0u8; 64];
        storage[..bytes.len()].copy_from_slice(bytes);
        Some(ParamValue::Data {
            data_type,
            bytes: storage,
        })
    }

    pub fn from_f32s(data_type: ANARIDataType, values: &[f32]) -> ParamValue {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_ne_bytes()).collect();
        ParamValue::from_bytes(data_type, &bytes).expect("at most 16 floats")
    }

    /// The same value: equal data, strings and pointers, the same object.
    pub fn same_as(&self, other: &ParamValue) -> bool {
        match (self, other) {
            (
                ParamValue::Data { data_type, bytes },
                ParamValue::Data {
                    data_type: t,
                    bytes: b,
                },
            ) => data_type == t && bytes == b,
            (ParamValue::String(a), ParamValue::String(b)) => a == b,
            (
                ParamValue::Object { data_type, object },
                ParamValue::Object {
                    data_type: t,
                    object: o,
                },
            ) => data_type == t && Arc::ptr_eq(object, o),
            (
                ParamValue::Pointer { data_type, address },
                ParamValue::Pointer {
                    data_type: t,
                    address: a,
                },
            ) => data_type == t && address == a,
            _ => false,
        }
    }

    fn data(&self, expected: ANARIDataType) -> Option<&[u8; 64]> {
        match self {
            ParamValue::Data { data_type, bytes } if *data_type == expected => Some(bytes),
            _ => None,
        }
    }
}

fn f32_at(bytes: &[u8], index: usize) -> f32 {
    let offset = index * 4;
    f32::from_ne_bytes(bytes[offset..offset + 4].try_into().unwrap())
}

fn u32_at(bytes: &[u8], index: usize) -> u32 {
    let offset = index * 4;
    u32::from_ne_bytes(bytes[offset..offset + 4].try_into().unwrap())
}

/// A set of named parameters.
#[derive(Clone, Debug, Default)]
pub struct ParamSet {
    values: HashMap<String, ParamValue>,
}

impl ParamSet {
    pub fn set(&mut self, name: &str, value: ParamValue) {
        self.values.insert(name.to_owned(), value);
    }
    pub fn unset(&mut self, name: &str) -> bool {
        self.values.remove(name).is_some()
    }
    pub fn clear(&mut self) {
        self.values.clear();
    }
    pub fn get(&self, name: &str) -> Option<&ParamValue> {
        self.values.get(name)
    }
    pub fn contains(&self, name: &str) -> bool {
        self.values.contains_key(name)
    }
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.values.keys().map(String::as_str)
    }
    pub fn iter(&self) -> impl Iterator<Item = (&str, &ParamValue)> {
        self.values
            .iter()
            .map(|(name, value)| (name.as_str(), value))
    }
    pub fn len(&self) -> usize {
        self.values.len()
    }
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// FLOAT32 (FLOAT64 is narrowed).
    pub fn get_f32(&self, name: &str) -> Option<f32> {
        let value = self.get(name)?;
        if let Some(bytes) = value.data(ANARI_FLOAT32) {
            return Some(f32_at(bytes, 0));
        }
        value
            .data(ANARI_FLOAT64)
            .map(|b| f64::from_ne_bytes(b[..8].try_into().unwrap()) as f32)
    }
    /// UINT32 (INT32 ≥ 0 accepted too).
    pub fn get_u32(&self, name: &str) -> Option<u32> {
        let value = self.get(name)?;
        if let Some(bytes) = value.data(ANARI_UINT32) {
            return Some(u32_at(bytes, 0));
        }
        self.get_i32(name).and_then(|v| u32::try_from(v).ok())
    }
    pub fn get_i32(&self, name: &str) -> Option<i32> {
        self.get(name)?
            .data(ANARI_INT32)
            .map(|b| i32::from_ne_bytes(b[..4].try_into().unwrap()))
    }
    /// BOOL is one byte: any non-zero byte is true.
    pub fn get_bool(&self, name: &str) -> Option<bool> {
        self.get(name)?.data(ANARI_BOOL).map(|b| b[0] != 0)
    }
    pub fn get_data_type(&self, name: &str) -> Option<ANARIDataType> {
        self.get(name)?
            .data(ANARI_DATA_TYPE)
            .map(|b| i32::from_ne_bytes(b[..4].try_into().unwrap()))
    }
    pub fn get_vec2(&self, name: &str) -> Option<Vec2> {
        let b = self.get(name)?.data(ANARI_FLOAT32_VEC2)?;
        Some(Vec2::new(f32_at(b, 0), f32_at(b, 1)))
    }
    pub fn get_vec3(&self, name: &str) -> Option<Vec3> {
        let b = self.get(name)?.data(ANARI_FLOAT32_VEC3)?;
        Some(Vec3::new(f32_at(b, 0), f32_at(b, 1), f32_at(b, 2)))
    }
    pub fn get_vec4(&self, name: &str) -> Option<Vec4> {
        let b = self.get(name)?.data(ANARI_FLOAT32_VEC4)?;
        Some(Vec4::new(
            f32_at(b, 0),
            f32_at(b, 1),
            f32_at(b, 2),
            f32_at(b, 3),
        ))
    }
    pub fn get_uvec2(&self, name: &str) -> Option<UVec2> {
        let b = self.get(name)?.data(ANARI_UINT32_VEC2)?;
        Some(UVec2::new(u32_at(b, 0), u32_at(b, 1)))
    }
    /// FLOAT32_MAT4, column-major as in OpenGL.
    pub fn get_mat4(&self, name: &str) -> Option<Mat4> {
        let b = self.get(name)?.data(ANARI_FLOAT32_MAT4)?;
        let mut columns = [0f32; 16];
        for (i, c) in columns.iter_mut().enumerate() {
            *c = f32_at(b, i);
        }
        Some(Mat4::from_cols_array(&columns))
    }
    /// FLOAT32_BOX2 as [lo.x, lo.y, hi.x, hi.y].
    pub fn get_box2(&self, name: &str) -> Option<[f32; 4]> {
        let b = self.get(name)?.data(ANARI_FLOAT32_BOX2)?;
        Some([f32_at(b, 0), f32_at(b, 1), f32_at(b, 2), f32_at(b, 3)])
    }
    pub fn get_string(&self, name: &str) -> Option<&str> {
        match self.get(name)? {
            ParamValue::String(s) => Some(s),
            _ => None,
        }
    }
    pub fn get_object(&self, name: &str) -> Option<&Arc<Object>> {
        match self.get(name)? {
            ParamValue::Object { object, .. } => Some(object),
            _ => None,
        }
    }
    pub fn get_pointer(&self, name: &str, data_type: ANARIDataType) -> Option<usize> {
        match self.get(name)? {
            ParamValue::Pointer {
                data_type: t,
                address,
            } if *t == data_type => Some(*address),
            _ => None,
        }
    }
    /// Raw bytes of a plain-data parameter whatever its type.
    pub fn get_raw(&self, name: &str) -> Option<(ANARIDataType, &[u8])> {
        match self.get(name)? {
            ParamValue::Data { data_type, bytes } => {
                let size = element_size(*data_type)?;
                Some((*data_type, &bytes[..size]))
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typed_getters_read_what_was_set() {
        let mut set = ParamSet::default();
        set.set("fovy", ParamValue::from_f32s(ANARI_FLOAT32, &[0.5]));
        set.set(
            "position",
            ParamValue::from_f32s(ANARI_FLOAT32_VEC3, &[1.0, 2.0, 3.0]),
        );
        let m: Vec<f32> = (0..16).map(|i| i as f32).collect();
        set.set("view", ParamValue::from_f32s(ANARI_FLOAT32_MAT4, &m));
        set.set("on", ParamValue::from_bytes(ANARI_BOOL, &[1]).unwrap());
        set.set("stereoMode", ParamValue::String("sideBySide".into()));
        assert_eq!(set.get_f32("fovy"), Some(0.5));
        assert_eq!(set.get_vec3("position"), Some(Vec3::new(1.0, 2.0, 3.0)));
        assert_eq!(set.get_mat4("view").unwrap().col(1).x, 4.0);
        assert_eq!(set.get_bool("on"), Some(true));
        assert_eq!(set.get_string("stereoMode"), Some("sideBySide"));
        // Wrong type reads as absent.
        assert_eq!(set.get_vec3("fovy"), None);
        assert!(set.unset("fovy"));
        assert_eq!(set.get_f32("fovy"), None);
    }
}
