//! Shared helpers for integration tests that drive the C API in-process.
#![allow(dead_code, unused_imports)]

use std::ffi::{CString, c_char, c_void};
use std::sync::Mutex;

pub use cavetrace::capi::array::*;
pub use cavetrace::capi::frame::*;
pub use cavetrace::capi::introspect::*;
pub use cavetrace::capi::library::*;
pub use cavetrace::capi::object::*;
pub use cavetrace::capi::params::*;
pub use cavetrace::capi::types::*;
pub use cavetrace::device::datatype::*;
pub use cavetrace::device::status::*;

/// Messages received by the status callback: (severity, code, text).
pub struct Log(pub Mutex<Vec<(i32, i32, String)>>);

impl Log {
    pub fn new() -> Box<Log> {
        Box::new(Log(Mutex::new(Vec::new())))
    }
    pub fn take(&self) -> Vec<(i32, i32, String)> {
        std::mem::take(&mut self.0.lock().unwrap())
    }
    /// Errors (severity ≤ ERROR) received so far, clearing the log.
    pub fn errors(&self) -> Vec<(i32, String)> {
        self.take()
            .into_iter()
            .filter(|(s, _, _)| *s <= ANARI_SEVERITY_ERROR)
            .map(|(_, c, t)| (c, t))
            .collect()
    }
}

pub unsafe extern "C" fn record_status(
    user: *const c_void,
    _device: *mut c_void,
    _source: *mut c_void,
    _source_type: ANARIDataType,
    severity: ANARIStatusSeverity,
    code: ANARIStatusCode,
    message: *const c_char,
) {
    // SAFETY: tests pass a live Log as user data and the device passes a C string.
    let log = unsafe { &*(user as *const Log) };
    let text = unsafe { std::ffi::CStr::from_ptr(message) }
        .to_string_lossy()
        .into_owned();
    log.0.lock().unwrap().push((severity, code, text));
}

pub fn c(s: &str) -> CString {
    CString::new(s).unwrap()
}

/// A device whose status messages land in `log`.
pub fn device_with_log(log: &Log) -> (ANARILibrary, ANARIDevice) {
    let lib = anariLoadLibrary(
        c("cavetrace").as_ptr(),
        Some(record_status),
        log as *const Log as *const c_void,
    );
    assert!(!lib.is_null());
    let dev = anariNewDevice(lib, c("default").as_ptr());
    assert!(!dev.is_null());
    (lib, dev)
}

pub fn set<T>(dev: ANARIDevice, obj: ANARIObject, name: &str, ty: ANARIDataType, value: &T) {
    anariSetParameter(
        dev,
        obj,
        c(name).as_ptr(),
        ty,
        value as *const T as *const c_void,
    );
}

pub fn set_object(
    dev: ANARIDevice,
    obj: ANARIObject,
    name: &str,
    ty: ANARIDataType,
    value: ANARIObject,
) {
    set(dev, obj, name, ty, &value);
}

pub fn set_string(dev: ANARIDevice, obj: ANARIObject, name: &str, value: &str) {
    let v = c(value);
    anariSetParameter(
        dev,
        obj,
        c(name).as_ptr(),
        ANARI_STRING,
        v.as_ptr() as *const c_void,
    );
}

pub fn commit(dev: ANARIDevice, obj: ANARIObject) {
    anariCommitParameters(dev, obj);
}

/// A managed 1D array filled with `data`.
pub fn array1d<T: Copy>(dev: ANARIDevice, ty: ANARIDataType, data: &[T]) -> ANARIArray1D {
    let a = anariNewArray1D(
        dev,
        std::ptr::null(),
        None,
        std::ptr::null(),
        ty,
        data.len() as u64,
    );
    let p = anariMapArray(dev, a) as *mut T;
    // SAFETY: the managed array holds data.len() elements of T.
    unsafe { std::ptr::copy_nonoverlapping(data.as_ptr(), p, data.len()) };
    anariUnmapArray(dev, a);
    a
}

pub fn object_array(dev: ANARIDevice, ty: ANARIDataType, objects: &[ANARIObject]) -> ANARIArray1D {
    array1d(dev, ty, objects)
}

/// Surface from a geometry and a matte material of `color`.
pub fn matte_surface(dev: ANARIDevice, geometry: ANARIGeometry, color: [f32; 3]) -> ANARISurface {
    let material = anariNewMaterial(dev, c("matte").as_ptr());
    set(dev, material, "color", ANARI_FLOAT32_VEC3, &color);
    commit(dev, material);
    let surface = anariNewSurface(dev);
    set_object(dev, surface, "geometry", ANARI_GEOMETRY, geometry);
    set_object(dev, surface, "material", ANARI_MATERIAL, material);
    commit(dev, surface);
    anariRelease(dev, material);
    surface
}

/// A world holding `surfaces` directly.
pub fn world_of(dev: ANARIDevice, surfaces: &[ANARISurface]) -> ANARIWorld {
    let world = anariNewWorld(dev);
    let array = object_array(dev, ANARI_SURFACE, surfaces);
    set_object(dev, world, "surface", ANARI_ARRAY1D, array);
    anariRelease(dev, array);
    commit(dev, world);
    world
}

pub fn frame_for(
    dev: ANARIDevice,
    world: ANARIWorld,
    camera: ANARICamera,
    renderer: ANARIRenderer,
    size: [u32; 2],
) -> ANARIFrame {
    let frame = anariNewFrame(dev);
    set(dev, frame, "size", ANARI_UINT32_VEC2, &size);
    set(
        dev,
        frame,
        "channel.color",
        ANARI_DATA_TYPE,
        &ANARI_FLOAT32_VEC4,
    );
    set(dev, frame, "channel.depth", ANARI_DATA_TYPE, &ANARI_FLOAT32);
    set(
        dev,
        frame,
        "channel.primitiveId",
        ANARI_DATA_TYPE,
        &ANARI_UINT32,
    );
    set(
        dev,
        frame,
        "channel.objectId",
        ANARI_DATA_TYPE,
        &ANARI_UINT32,
    );
    set(
        dev,
        frame,
        "channel.instanceId",
        ANARI_DATA_TYPE,
        &ANARI_UINT32,
    );
    set_object(dev, frame, "world", ANARI_WORLD, world);
    set_object(dev, frame, "camera", ANARI_CAMERA, camera);
    set_object(dev, frame, "renderer", ANARI_RENDERER, renderer);
    commit(dev, frame);
    frame
}

/// Renders and copies a channel out (T must match the channel's type).
pub fn render_channel<T: Copy>(
    dev: ANARIDevice,
    frame: ANARIFrame,
    channel: &str,
) -> (Vec<T>, u32, u32) {
    anariRenderFrame(dev, frame);
    anariFrameReady(dev, frame, ANARI_WAIT);
    read_channel(dev, frame, channel)
}

pub fn read_channel<T: Copy>(
    dev: ANARIDevice,
    frame: ANARIFrame,
    channel: &str,
) -> (Vec<T>, u32, u32) {
    let (mut w, mut h, mut t) = (0u32, 0u32, 0);
    let name = c(channel);
    let p = anariMapFrame(dev, frame, name.as_ptr(), &mut w, &mut h, &mut t) as *const T;
    assert!(!p.is_null(), "channel {channel} not mapped");
    // SAFETY: the mapped channel holds w×h elements of T while mapped.
    let pixels = unsafe { std::slice::from_raw_parts(p, (w * h) as usize) }.to_vec();
    anariUnmapFrame(dev, frame, name.as_ptr());
    (pixels, w, h)
}
