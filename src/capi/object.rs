//! Object creation and lifetime: anariNew*, anariRetain, anariRelease.

use std::ffi::c_char;

use crate::capi::types::*;
use crate::capi::{device_of, guard, plain_string, string_arg};
use crate::device::datatype::*;
use crate::device::registry;
use crate::device::status::*;

fn new_object(
    function: &'static str,
    device: ANARIDevice,
    kind: ANARIDataType,
    subtype: Option<*const c_char>,
) -> ANARIObject {
    guard(function, device, std::ptr::null_mut(), || {
        let Some(device) = device_of(function, device) else {
            return std::ptr::null_mut();
        };
        let subtype = match subtype {
            Some(pointer) => match string_arg(&device, function, "type", pointer) {
                Some(s) => s,
                None => return std::ptr::null_mut(),
            },
            None => String::new(),
        };
        device.new_object(function, kind, &subtype) as ANARIObject
    })
}

macro_rules! new_with_subtype {
    ($name:ident, $handle:ty, $kind:expr) => {
        #[unsafe(no_mangle)]
        pub extern "C" fn $name(device: ANARIDevice, subtype: *const c_char) -> $handle {
            new_object(stringify!($name), device, $kind, Some(subtype))
        }
    };
}

macro_rules! new_without_subtype {
    ($name:ident, $handle:ty, $kind:expr) => {
        #[unsafe(no_mangle)]
        pub extern "C" fn $name(device: ANARIDevice) -> $handle {
            new_object(stringify!($name), device, $kind, None)
        }
    };
}

new_with_subtype!(anariNewLight, ANARILight, ANARI_LIGHT);
new_with_subtype!(anariNewCamera, ANARICamera, ANARI_CAMERA);
new_with_subtype!(anariNewGeometry, ANARIGeometry, ANARI_GEOMETRY);
new_with_subtype!(anariNewSpatialField, ANARISpatialField, ANARI_SPATIAL_FIELD);
new_with_subtype!(anariNewVolume, ANARIVolume, ANARI_VOLUME);
new_with_subtype!(anariNewMaterial, ANARIMaterial, ANARI_MATERIAL);
new_with_subtype!(anariNewSampler, ANARISampler, ANARI_SAMPLER);
new_with_subtype!(anariNewInstance, ANARIInstance, ANARI_INSTANCE);
new_with_subtype!(anariNewRenderer, ANARIRenderer, ANARI_RENDERER);
new_without_subtype!(anariNewSurface, ANARISurface, ANARI_SURFACE);
new_without_subtype!(anariNewGroup, ANARIGroup, ANARI_GROUP);
new_without_subtype!(anariNewWorld, ANARIWorld, ANARI_WORLD);
new_without_subtype!(anariNewFrame, ANARIFrame, ANARI_FRAME);

/// The kind named by anariNewObject's objectType ("geometry", "spatialField", …).
fn kind_from_name(name: &str) -> Option<ANARIDataType> {
    Some(match name {
        "light" => ANARI_LIGHT,
        "camera" => ANARI_CAMERA,
        "geometry" => ANARI_GEOMETRY,
        "spatialField" => ANARI_SPATIAL_FIELD,
        "volume" => ANARI_VOLUME,
        "surface" => ANARI_SURFACE,
        "material" => ANARI_MATERIAL,
        "sampler" => ANARI_SAMPLER,
        "group" => ANARI_GROUP,
        "instance" => ANARI_INSTANCE,
        "world" => ANARI_WORLD,
        "renderer" => ANARI_RENDERER,
        "frame" => ANARI_FRAME,
        _ => return None,
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewObject(
    device: ANARIDevice,
    object_type: *const c_char,
    subtype: *const c_char,
) -> ANARIObject {
    const F: &str = "anariNewObject";
    guard(F, device, std::ptr::null_mut(), || {
        let Some(dev) = device_of(F, device) else {
            return std::ptr::null_mut();
        };
        let Some(type_name) = string_arg(&dev, F, "objectType", object_type) else {
            return std::ptr::null_mut();
        };
        let Some(kind) = kind_from_name(&type_name) else {
            dev.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                None,
                format!("{F}: unknown object type '{type_name}'; no object was created"),
            );
            return std::ptr::null_mut();
        };
        let subtype = plain_string(subtype).unwrap_or_default();
        dev.new_object(F, kind, &subtype) as ANARIObject
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariRetain(device: ANARIDevice, object: ANARIObject) {
    const F: &str = "anariRetain";
    guard(F, device, (), || {
        if let Some(device) = device_of(F, device) {
            device.retain(F, object as usize);
        }
    })
}

/// Drops a reference. `anariRelease(device, device)` releases the device itself; its last
/// release stops rendering, joins its threads and frees every object.
#[unsafe(no_mangle)]
pub extern "C" fn anariRelease(device: ANARIDevice, object: ANARIObject) {
    const F: &str = "anariRelease";
    guard(F, device, (), || {
        if let Some(dev) = device_of(F, device) {
            dev.release(F, object as usize);
        }
    })
}

/// Number of live cavetrace devices in the process (for tests and leak checks).
#[unsafe(no_mangle)]
pub extern "C" fn cavetraceLiveDeviceCount() -> u64 {
    guard("cavetraceLiveDeviceCount", std::ptr::null_mut(), 0, || {
        registry::live_device_count() as u64
    })
}
