//! Shared helpers for integration tests that drive the C API in-process.
#![allow(dead_code, unused_imports)]

mod scenes;
pub use scenes::*;

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
    fill_array(dev, a, data);
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
    let surface = surface_of(dev, geometry, material);
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

/// A world whose only instance holds `surfaces` in a group, placed by `transform` (column-major).
pub fn instanced_world_of(
    dev: ANARIDevice,
    surfaces: &[ANARISurface],
    transform: [f32; 16],
) -> ANARIWorld {
    let instance = instance_of(dev, surfaces, transform, None);
    let world = anariNewWorld(dev);
    let instances = object_array(dev, ANARI_INSTANCE, &[instance]);
    set_object(dev, world, "instance", ANARI_ARRAY1D, instances);
    commit(dev, world);
    for object in [instance, instances] {
        anariRelease(dev, object);
    }
    world
}

/// A committed instance of one group holding `surfaces`, placed by `transform`, with `id` if
/// given (the caller releases it).
pub fn instance_of(
    dev: ANARIDevice,
    surfaces: &[ANARISurface],
    transform: [f32; 16],
    id: Option<u32>,
) -> ANARIInstance {
    let group = anariNewGroup(dev);
    let group_surfaces = object_array(dev, ANARI_SURFACE, surfaces);
    set_object(dev, group, "surface", ANARI_ARRAY1D, group_surfaces);
    commit(dev, group);
    let instance = anariNewInstance(dev, c("transform").as_ptr());
    set_object(dev, instance, "group", ANARI_GROUP, group);
    set(dev, instance, "transform", ANARI_FLOAT32_MAT4, &transform);
    if let Some(id) = id {
        set(dev, instance, "id", ANARI_UINT32, &id);
    }
    commit(dev, instance);
    for object in [group_surfaces, group] {
        anariRelease(dev, object);
    }
    instance
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

/// Releases every object in `objects`.
pub fn release_all(dev: ANARIDevice, objects: &[ANARIObject]) {
    for &object in objects {
        anariRelease(dev, object);
    }
}

/// Releases the device and unloads its library.
pub fn release_device(lib: ANARILibrary, dev: ANARIDevice) {
    anariRelease(dev, dev);
    anariUnloadLibrary(lib);
}

/// Copies `data` into managed `array`, which must hold exactly data.len() elements of T.
fn fill_array<T: Copy>(dev: ANARIDevice, array: ANARIArray, data: &[T]) {
    let p = anariMapArray(dev, array) as *mut T;
    // SAFETY: every caller made `array` with data.len() elements of T.
    unsafe { std::ptr::copy_nonoverlapping(data.as_ptr(), p, data.len()) };
    anariUnmapArray(dev, array);
}

/// A managed 2D array of `size` elements filled with `data` (first row first).
pub fn array2d<T: Copy>(
    dev: ANARIDevice,
    ty: ANARIDataType,
    data: &[T],
    size: [u64; 2],
) -> ANARIArray2D {
    assert_eq!(data.len() as u64, size[0] * size[1]);
    let a = unfilled_array2d(dev, ty, size);
    fill_array(dev, a, data);
    a
}

/// A managed 2D array of `size` elements of `ty`, never written.
pub fn unfilled_array2d(dev: ANARIDevice, ty: ANARIDataType, size: [u64; 2]) -> ANARIArray2D {
    anariNewArray2D(
        dev,
        std::ptr::null(),
        None,
        std::ptr::null(),
        ty,
        size[0],
        size[1],
    )
}

/// A managed 3D array of `size` elements filled with `data` (x fastest).
pub fn array3d<T: Copy>(
    dev: ANARIDevice,
    ty: ANARIDataType,
    data: &[T],
    size: [u64; 3],
) -> ANARIArray3D {
    assert_eq!(data.len() as u64, size[0] * size[1] * size[2]);
    let a = anariNewArray3D(
        dev,
        std::ptr::null(),
        None,
        std::ptr::null(),
        ty,
        size[0],
        size[1],
        size[2],
    );
    fill_array(dev, a, data);
    a
}

/// Sets parameter `name` of `object` to a new 1D array of `data`, which the object then owns.
pub fn set_array<T: Copy>(
    dev: ANARIDevice,
    object: ANARIObject,
    name: &str,
    ty: ANARIDataType,
    data: &[T],
) {
    let array = array1d(dev, ty, data);
    set_object(dev, object, name, ANARI_ARRAY1D, array);
    anariRelease(dev, array);
}

/// A committed triangle soup geometry (three positions a triangle).
pub fn triangle_geometry(dev: ANARIDevice, positions: &[[f32; 3]]) -> ANARIGeometry {
    let geometry = anariNewGeometry(dev, c("triangle").as_ptr());
    set_array(
        dev,
        geometry,
        "vertex.position",
        ANARI_FLOAT32_VEC3,
        positions,
    );
    commit(dev, geometry);
    geometry
}

/// An uncommitted indexed triangle geometry over a `cells`×`cells` grid of vertices
/// `(cells + 1)²`, vertex (i, j) at `vertex(i, j)` (row j after row j − 1); each cell split
/// into triangles (a, a+1, a+n+1) and (a, a+n+1, a+n) for its corner a and n = cells + 1.
/// Returns the geometry and its triangles as vertex triples.
pub fn grid_geometry(
    dev: ANARIDevice,
    cells: u32,
    vertex: impl Fn(u32, u32) -> [f32; 3],
) -> (ANARIGeometry, Vec<[[f32; 3]; 3]>) {
    let n = cells + 1;
    let positions: Vec<[f32; 3]> = (0..n)
        .flat_map(|j| (0..n).map(move |i| (i, j)))
        .map(|(i, j)| vertex(i, j))
        .collect();
    let mut indices = Vec::with_capacity((cells * cells * 2) as usize);
    for j in 0..cells {
        for i in 0..cells {
            let a = j * n + i;
            indices.push([a, a + 1, a + n + 1]);
            indices.push([a, a + n + 1, a + n]);
        }
    }
    let geometry = anariNewGeometry(dev, c("triangle").as_ptr());
    set_array(
        dev,
        geometry,
        "vertex.position",
        ANARI_FLOAT32_VEC3,
        &positions,
    );
    set_array(
        dev,
        geometry,
        "primitive.index",
        ANARI_UINT32_VEC3,
        &indices,
    );
    let triangles = indices
        .iter()
        .map(|corners| corners.map(|k| positions[k as usize]))
        .collect();
    (geometry, triangles)
}

/// A committed `size`×`size` frame with only an sRGB colour channel (what a display shows).
pub fn square_frame(
    dev: ANARIDevice,
    size: u32,
    world: ANARIWorld,
    camera: ANARICamera,
    renderer: ANARIRenderer,
) -> ANARIFrame {
    let frame = anariNewFrame(dev);
    set(dev, frame, "size", ANARI_UINT32_VEC2, &[size, size]);
    let color = ANARI_UFIXED8_RGBA_SRGB;
    set(dev, frame, "channel.color", ANARI_DATA_TYPE, &color);
    set_object(dev, frame, "world", ANARI_WORLD, world);
    set_object(dev, frame, "camera", ANARI_CAMERA, camera);
    set_object(dev, frame, "renderer", ANARI_RENDERER, renderer);
    commit(dev, frame);
    frame
}

/// A committed sphere geometry of one `radius` around `centers`.
pub fn sphere_geometry(dev: ANARIDevice, centers: &[[f32; 3]], radius: f32) -> ANARIGeometry {
    let geometry = anariNewGeometry(dev, c("sphere").as_ptr());
    set_array(
        dev,
        geometry,
        "vertex.position",
        ANARI_FLOAT32_VEC3,
        centers,
    );
    set(dev, geometry, "radius", ANARI_FLOAT32, &radius);
    commit(dev, geometry);
    geometry
}

/// A committed surface of `geometry` and `material` (both stay the caller's).
pub fn surface_of(
    dev: ANARIDevice,
    geometry: ANARIGeometry,
    material: ANARIMaterial,
) -> ANARISurface {
    let surface = anariNewSurface(dev);
    set_object(dev, surface, "geometry", ANARI_GEOMETRY, geometry);
    set_object(dev, surface, "material", ANARI_MATERIAL, material);
    commit(dev, surface);
    surface
}

/// A committed matte material coloured by the geometry attribute `attribute` (e.g. "color").
pub fn matte_colored_by(dev: ANARIDevice, attribute: &str) -> ANARIMaterial {
    let material = anariNewMaterial(dev, c("matte").as_ptr());
    set_string(dev, material, "color", attribute);
    commit(dev, material);
    material
}

/// A committed perspective camera at `position` looking along `direction`.
pub fn perspective_camera(
    dev: ANARIDevice,
    position: [f32; 3],
    direction: [f32; 3],
    fovy: f32,
) -> ANARICamera {
    let camera = anariNewCamera(dev, c("perspective").as_ptr());
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &position);
    set(dev, camera, "direction", ANARI_FLOAT32_VEC3, &direction);
    set(dev, camera, "fovy", ANARI_FLOAT32, &fovy);
    commit(dev, camera);
    camera
}

/// A committed orthographic camera at `position` looking down −z (up +y), `height` tall, aspect 1.
pub fn orthographic_camera(dev: ANARIDevice, position: [f32; 3], height: f32) -> ANARICamera {
    let camera = anariNewCamera(dev, c("orthographic").as_ptr());
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &position);
    set(
        dev,
        camera,
        "direction",
        ANARI_FLOAT32_VEC3,
        &[0.0f32, 0.0, -1.0],
    );
    set(dev, camera, "up", ANARI_FLOAT32_VEC3, &[0.0f32, 1.0, 0.0]);
    set(dev, camera, "height", ANARI_FLOAT32, &height);
    set(dev, camera, "aspect", ANARI_FLOAT32, &1.0f32);
    commit(dev, camera);
    camera
}

/// A committed renderer of `subtype` with every parameter at its default.
pub fn plain_renderer(dev: ANARIDevice, subtype: &str) -> ANARIRenderer {
    let renderer = anariNewRenderer(dev, c(subtype).as_ptr());
    commit(dev, renderer);
    renderer
}

/// Adds channel `name` of type `ty` to `frame` and commits it.
pub fn add_channel(dev: ANARIDevice, frame: ANARIFrame, name: &str, ty: ANARIDataType) {
    set(dev, frame, name, ANARI_DATA_TYPE, &ty);
    commit(dev, frame);
}

/// Renders `frame` and waits until it is ready.
pub fn render_and_wait(dev: ANARIDevice, frame: ANARIFrame) {
    anariRenderFrame(dev, frame);
    anariFrameReady(dev, frame, ANARI_WAIT);
}

/// The strings of a NULL-terminated list the device returned.
pub fn c_strings(mut list: *const *const c_char) -> Vec<String> {
    let mut out = Vec::new();
    // SAFETY: the device returns NULL-terminated lists of C strings that outlive these reads.
    unsafe {
        while !list.is_null() && !(*list).is_null() {
            out.push(
                std::ffi::CStr::from_ptr(*list)
                    .to_string_lossy()
                    .into_owned(),
            );
            list = list.add(1);
        }
    }
    out
}

/// The device's "extension" property.
pub fn device_extensions(dev: ANARIDevice) -> Vec<String> {
    let mut list: *const *const c_char = std::ptr::null();
    let found = anariGetProperty(
        dev,
        dev,
        c("extension").as_ptr(),
        ANARI_STRING_LIST,
        &mut list as *mut _ as _,
        std::mem::size_of::<usize>() as u64,
        ANARI_WAIT,
    );
    assert_eq!(found, 1);
    c_strings(list)
}

/// Asserts every component of `actual` is within 1e-4 of `expected`.
pub fn assert_near<const N: usize>(actual: [f32; N], expected: [f32; N], what: &str) {
    for k in 0..N {
        assert!(
            (actual[k] - expected[k]).abs() < 1e-4,
            "{what}: got {actual:?}, expected {expected:?}"
        );
    }
}

/// The "bounds" property of `object` (the return status is left to the tests of properties).
pub fn bounds_of(dev: ANARIDevice, object: ANARIObject) -> [f32; 6] {
    let mut bounds = [0f32; 6];
    anariGetProperty(
        dev,
        object,
        c("bounds").as_ptr(),
        ANARI_FLOAT32_BOX3,
        bounds.as_mut_ptr() as _,
        24,
        ANARI_WAIT,
    );
    bounds
}

/// A committed directional light shining along `direction` (irradiance 1).
pub fn directional_light(dev: ANARIDevice, direction: [f32; 3]) -> ANARILight {
    let light = anariNewLight(dev, c("directional").as_ptr());
    set(dev, light, "direction", ANARI_FLOAT32_VEC3, &direction);
    commit(dev, light);
    light
}

/// Gives `world` one directional light shining along `direction` (irradiance 1) and commits it.
pub fn light_world(dev: ANARIDevice, world: ANARIWorld, direction: [f32; 3]) {
    let light = directional_light(dev, direction);
    let lights = object_array(dev, ANARI_LIGHT, &[light]);
    set_object(dev, world, "light", ANARI_ARRAY1D, lights);
    commit(dev, world);
    release_all(dev, &[light, lights]);
}

/// CPU seconds used by this process so far (all threads): rates per CPU second stay meaningful
/// on a shared machine.
pub fn cpu_seconds() -> f64 {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `now` is a valid, writable timespec for the duration of the call.
    let status = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut now) };
    if status != 0 {
        return 0.0;
    }
    now.tv_sec as f64 + now.tv_nsec as f64 * 1e-9
}

/// The camera's rays through the pixel centres of a `size`×`size` frame, in the order the
/// frame traces them (8×8 blocks of sixteen 2×2 quads).
pub fn camera_rays(dev: ANARIDevice, camera: ANARICamera, size: u32) -> Vec<cavetrace::accel::Ray> {
    let rays = camera_rays_with_pixels(dev, camera, size);
    rays.into_iter().map(|(_, ray)| ray).collect()
}

/// [`camera_rays`], each with its pixel `(x, y)`.
pub fn camera_rays_with_pixels(
    dev: ANARIDevice,
    camera: ANARICamera,
    size: u32,
) -> Vec<((u32, u32), cavetrace::accel::Ray)> {
    let model = cavetrace::device::registry::device(dev as usize)
        .and_then(|d| d.lookup(camera as usize))
        .and_then(|o| o.derived_as::<cavetrace::camera::CameraModel>())
        .expect("committed camera");
    let viewport = model.0.viewports(size, size)[0];
    let eye = model.0.prepare(viewport.eye, size, size);
    let mut rays = Vec::with_capacity((size * size) as usize);
    for by in (0..size).step_by(8) {
        for bx in (0..size).step_by(8) {
            for i in 0..64 {
                let (quad, lane) = (i / 4, i % 4);
                let x = bx + (quad % 4) * 2 + lane % 2;
                let y = by + (quad / 4) * 2 + lane / 2;
                let (u, v) = (
                    (x as f32 + 0.5) / size as f32,
                    (y as f32 + 0.5) / size as f32,
                );
                let r = eye.ray(u, v, glam::Vec2::ZERO);
                let ray = cavetrace::accel::Ray::new(r.origin, r.direction, r.t_min, r.t_max);
                rays.push(((x, y), ray));
            }
        }
    }
    rays
}

/// The acceleration structure a world of `geometry` alone (committed, identity placement) traces
/// against, for tracing rays without a frame.
pub fn geometry_scene(dev: ANARIDevice, geometry: ANARIGeometry) -> cavetrace::accel::SceneBvh {
    let device = cavetrace::device::registry::device(dev as usize).expect("device");
    let bvh = device
        .lookup(geometry as usize)
        .and_then(|o| cavetrace::scene::geometry::current(&device, &o))
        .map(|g| g.bvh.clone())
        .expect("committed geometry");
    cavetrace::accel::SceneBvh::build(vec![cavetrace::accel::InstanceDesc {
        transform: glam::Affine3A::IDENTITY,
        geometries: vec![bvh],
    }])
}
