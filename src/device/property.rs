//! Object properties (anariGetProperty): values computed from committed state.

use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;

pub const VERSION_MAJOR: i32 = 0;
pub const VERSION_MINOR: i32 = 1;
pub const VERSION_PATCH: i32 = 0;
pub const VERSION_NAME: &str = "cavetrace 0.1.0";
/// Largest index a geometry's index arrays may hold (UINT32 indices).
pub const GEOMETRY_MAX_INDEX: u64 = u32::MAX as u64 - 1;

#[derive(Clone, Debug, PartialEq)]
pub enum PropertyValue {
    Int32(i32),
    UInt64(u64),
    Float32(f32),
    Float32Vec2([f32; 2]),
    Bool(bool),
    Box3([f32; 6]),
    String(&'static str),
    StringList(Vec<&'static str>),
}

impl PropertyValue {
    pub fn data_type(&self) -> ANARIDataType {
        match self {
            PropertyValue::Int32(_) => ANARI_INT32,
            PropertyValue::UInt64(_) => ANARI_UINT64,
            PropertyValue::Float32(_) => ANARI_FLOAT32,
            PropertyValue::Float32Vec2(_) => ANARI_FLOAT32_VEC2,
            PropertyValue::Bool(_) => ANARI_BOOL,
            PropertyValue::Box3(_) => ANARI_FLOAT32_BOX3,
            PropertyValue::String(_) => ANARI_STRING,
            PropertyValue::StringList(_) => ANARI_STRING_LIST,
        }
    }
}

pub fn device_property(device: &Device, name: &str) -> Option<PropertyValue> {
    Some(match name {
        "version" => {
            PropertyValue::Int32(VERSION_MAJOR * 10000 + VERSION_MINOR * 100 + VERSION_PATCH)
        }
        "version.major" => PropertyValue::Int32(VERSION_MAJOR),
        "version.minor" => PropertyValue::Int32(VERSION_MINOR),
        "version.patch" => PropertyValue::Int32(VERSION_PATCH),
        "version.name" => PropertyValue::String(VERSION_NAME),
        "geometryMaxIndex" => PropertyValue::UInt64(GEOMETRY_MAX_INDEX),
        "extension" => PropertyValue::StringList(device.kinds().extensions()),
        _ => return None,
    })
}

/// A property of an object; `wait` lets frame properties wait for the render to finish.
pub fn object_property(
    device: &Device,
    object: &Object,
    name: &str,
    wait: bool,
) -> Option<PropertyValue> {
    match object.kind {
        ANARI_FRAME => object.frame.as_ref()?.property(name, wait),
        _ => device.kinds().property(device, object, name),
    }
}
