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

// Written out one by one (not by a macro) so that cbindgen puts each in the header.

#[unsafe(no_mangle)]
pub extern "C" fn anariNewLight(device: ANARIDevice, subtype: *const c_char) -> ANARILight {
    new_object("anariNewLight", device, ANARI_LIGHT, Some(subtype))
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewCamera(device: ANARIDevice, subtype: *const c_char) -> ANARICamera {
    new_object("anariNewCamera", device, ANARI_CAMERA, Some(subtype))
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewGeometry(device: ANARIDevice, subtype: *const c_char) -> ANARIGeometry {
    new_object("anariNewGeometry", device, ANARI_GEOMETRY, Some(subtype))
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewSpatialField(
    device: ANARIDevice,
    subtype: *const c_char,
) -> ANARISpatialField {
    new_object(
        "anariNewSpatialField",
        device,
        ANARI_SPATIAL_FIELD,
        Some(subtype),
    )
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewVolume(device: ANARIDevice, subtype: *const c_char) -> ANARIVolume {
    new_object("anariNewVolume", device, ANARI_VOLUME, Some(subtype))
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewMaterial(device: ANARIDevice, subtype: *const c_char) -> ANARIMaterial {
    new_object("anariNewMaterial", device, ANARI_MATERIAL, Some(subtype))
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewSampler(device: ANARIDevice, subtype: *const c_char) -> ANARISampler {
    new_object("anariNewSampler", device, ANARI_SAMPLER, Some(subtype))
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewInstance(device: ANARIDevice, subtype: *const c_char) -> ANARIInstance {
    new_object("anariNewInstance", device, ANARI_INSTANCE, Some(subtype))
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewRenderer(device: ANARIDevice, subtype: *const c_char) -> ANARIRenderer {
    new_object("anariNewRenderer", device, ANARI_RENDERER, Some(subtype))
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewSurface(device: ANARIDevice) -> ANARISurface {
    new_object("anariNewSurface", device, ANARI_SURFACE, None)
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewGroup(device: ANARIDevice) -> ANARIGroup {
    new_object("anariNewGroup", device, ANARI_GROUP, None)
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewWorld(device: ANARIDevice) -> ANARIWorld {
    new_object("anariNewWorld", device, ANARI_WORLD, None)
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewFrame(device: ANARIDevice) -> ANARIFrame {
    new_object("anariNewFrame", device, ANARI_FRAME, None)
}

/// The kind named by anariNewObject's objectType ("geometry", "spatialField", …).
pub(crate) fn kind_from_name(name: &str) -> Option<ANARIDataType> {
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
