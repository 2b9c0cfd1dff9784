//! The object model through the C API: lifetimes, staging, errors, properties, introspection.
mod common;
use common::*;
use std::ffi::{CStr, c_void};
use std::sync::atomic::{AtomicUsize, Ordering};

fn triangle_scene(dev: ANARIDevice, z: f32) -> (ANARIGeometry, ANARISurface, ANARIWorld) {
    let positions: [[f32; 3]; 3] = [[-1.0, -1.0, z], [1.0, -1.0, z], [0.0, 1.0, z]];
    let geometry = triangle_geometry(dev, &positions);
    let surface = matte_surface(dev, geometry, [1.0, 1.0, 1.0]);
    let world = world_of(dev, &[surface]);
    (geometry, surface, world)
}

fn basic_frame(dev: ANARIDevice, world: ANARIWorld, size: [u32; 2]) -> ANARIFrame {
    let camera = anariNewCamera(dev, c("perspective").as_ptr());
    commit(dev, camera);
    let renderer = plain_renderer(dev, "default");
    let frame = frame_for(dev, world, camera, renderer, size);
    anariRelease(dev, camera);
    anariRelease(dev, renderer);
    frame
}

fn centre_depth(dev: ANARIDevice, frame: ANARIFrame, size: [u32; 2]) -> f32 {
    let (depth, _, _) = render_channel::<f32>(dev, frame, "channel.depth");
    depth[((size[1] / 2) * size[0] + size[0] / 2) as usize]
}

#[test]
fn objects_used_by_others_outlive_their_application_release() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let (geometry, surface, world) = triangle_scene(dev, -2.0);
    // The application lets go of everything but the world.
    anariRelease(dev, geometry);
    anariRelease(dev, surface);
    let frame = basic_frame(dev, world, [32, 32]);
    anariRelease(dev, world);
    assert!((centre_depth(dev, frame, [32, 32]) - 2.0).abs() < 1e-3);
    assert!(log.errors().is_empty());
    // A released handle is no longer the application's to use.
    commit(dev, geometry);
    let errors = log.errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert_eq!(errors[0].0, ANARI_STATUS_INVALID_ARGUMENT);
    assert!(
        errors[0].1.contains("anariCommitParameters") && errors[0].1.contains("not a live object")
    );
    anariRelease(dev, frame);
    release_device(lib, dev);
}

static DELETES: AtomicUsize = AtomicUsize::new(0);
unsafe extern "C" fn count_delete(user: *const c_void, memory: *const c_void) {
    assert_eq!(user as usize, 0xC0FFEE);
    // SAFETY: the test passed a leaked Box<[f32; 9]> as captured memory.
    drop(unsafe { Box::from_raw(memory as *mut [[f32; 3]; 3]) });
    DELETES.fetch_add(1, Ordering::SeqCst);
}

#[test]
fn captured_memory_is_deleted_once_when_the_last_user_lets_go() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let memory = Box::into_raw(Box::new([
        [-1.0f32, -1.0, -2.0],
        [1.0, -1.0, -2.0],
        [0.0, 1.0, -2.0],
    ]));
    let array = anariNewArray1D(
        dev,
        memory as *const c_void,
        Some(count_delete),
        0xC0FFEE as *const c_void,
        ANARI_FLOAT32_VEC3,
        3,
    );
    let geometry = anariNewGeometry(dev, c("triangle").as_ptr());
    set_object(dev, geometry, "vertex.position", ANARI_ARRAY1D, array);
    commit(dev, geometry);
    let before = DELETES.load(Ordering::SeqCst);
    anariRelease(dev, array);
    assert_eq!(
        DELETES.load(Ordering::SeqCst),
        before,
        "the geometry still uses the array"
    );
    anariRelease(dev, geometry);
    assert_eq!(DELETES.load(Ordering::SeqCst), before + 1);
    release_device(lib, dev);
    assert_eq!(DELETES.load(Ordering::SeqCst), before + 1, "exactly once");
    assert!(log.errors().is_empty());
}

#[test]
fn parameters_take_effect_only_at_commit() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let (geometry, surface, world) = triangle_scene(dev, -2.0);
    let frame = basic_frame(dev, world, [16, 16]);
    let d = centre_depth(dev, frame, [16, 16]);
    assert!((d - 2.0).abs() < 0.01, "{d} {:?}", log.take());
    // Staged but not committed: the same picture.
    let moved: [[f32; 3]; 3] = [[-1.0, -1.0, -5.0], [1.0, -1.0, -5.0], [0.0, 1.0, -5.0]];
    let array = array1d(dev, ANARI_FLOAT32_VEC3, &moved);
    set_object(dev, geometry, "vertex.position", ANARI_ARRAY1D, array);
    assert!((centre_depth(dev, frame, [16, 16]) - 2.0).abs() < 0.02);
    commit(dev, geometry);
    assert!((centre_depth(dev, frame, [16, 16]) - 5.0).abs() < 0.02);
    // Unset + commit removes the positions: nothing to hit any more.
    anariUnsetParameter(dev, geometry, c("vertex.position").as_ptr());
    commit(dev, geometry);
    assert!(centre_depth(dev, frame, [16, 16]).is_infinite());
    let errors = log.errors();
    assert!(
        errors.iter().any(|(_, t)| t.contains("vertex.position")),
        "{errors:?}"
    );
    release_all(dev, &[array, geometry, surface, world, frame]);
    release_device(lib, dev);
}

#[test]
fn misuse_is_reported_with_the_right_code_and_has_no_effect() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let geometry = anariNewGeometry(dev, c("triangle").as_ptr());

    // Wrong parameter type: names object, parameter, given and accepted types.
    set(dev, geometry, "vertex.position", ANARI_FLOAT32, &1.0f32);
    let e = log.errors();
    assert_eq!(e.len(), 1);
    assert_eq!(e[0].0, ANARI_STATUS_INVALID_ARGUMENT);
    for word in [
        "geometry 'triangle'",
        "vertex.position",
        "ANARI_FLOAT32",
        "ANARI_ARRAY1D",
    ] {
        assert!(e[0].1.contains(word), "{word} missing in {}", e[0].1);
    }

    // A handle of the wrong kind.
    let material = anariNewMaterial(dev, c("matte").as_ptr());
    let surface = anariNewSurface(dev);
    set_object(dev, surface, "geometry", ANARI_GEOMETRY, material);
    let e = log.errors();
    assert!(e.len() == 1 && e[0].1.contains("material 'matte'"), "{e:?}");

    // NULL parameter name, invalid data type, NULL object, never-created object.
    anariSetParameter(
        dev,
        geometry,
        std::ptr::null(),
        ANARI_FLOAT32,
        &1.0f32 as *const f32 as _,
    );
    set(dev, geometry, "x", 9999, &1.0f32);
    anariCommitParameters(dev, std::ptr::null_mut());
    anariCommitParameters(dev, 0x1234_5670 as ANARIObject);
    let e = log.errors();
    assert_eq!(e.len(), 4, "{e:?}");
    assert!(
        e.iter()
            .all(|(code, _)| *code == ANARI_STATUS_INVALID_ARGUMENT)
    );
    assert!(e[0].1.contains("'name' is NULL"));
    assert!(e[1].1.contains("9999"));
    assert!(e[2].1.contains("NULL"));
    assert!(e[3].1.contains("not a live object"));

    // Mapping twice and unmapping an unmapped array.
    let array = anariNewArray1D(
        dev,
        std::ptr::null(),
        None,
        std::ptr::null(),
        ANARI_FLOAT32,
        4,
    );
    assert!(!anariMapArray(dev, array).is_null());
    assert!(anariMapArray(dev, array).is_null());
    anariUnmapArray(dev, array);
    anariUnmapArray(dev, array);
    let e = log.errors();
    assert_eq!(e.len(), 2);
    assert!(
        e.iter()
            .all(|(code, _)| *code == ANARI_STATUS_INVALID_OPERATION)
    );

    // Sizes that overflow, or cannot be allocated, are OUT_OF_MEMORY and return NULL.
    let huge = unfilled_array2d(dev, ANARI_FLOAT32_VEC4, [u64::MAX / 8, 8]);
    assert!(huge.is_null());
    let too_big = anariNewArray1D(
        dev,
        std::ptr::null(),
        None,
        std::ptr::null(),
        ANARI_UINT8,
        1 << 62,
    );
    assert!(too_big.is_null());
    let e = log.errors();
    assert_eq!(e.len(), 2);
    assert!(
        e.iter()
            .all(|(code, _)| *code == ANARI_STATUS_OUT_OF_MEMORY)
    );

    // An unknown subtype is a warning, and the object is still usable (and ignored).
    let unknown = anariNewGeometry(dev, c("teapot").as_ptr());
    assert!(!unknown.is_null());
    let warnings = log.take();
    assert!(
        warnings
            .iter()
            .any(|(s, _, t)| *s == ANARI_SEVERITY_WARNING && t.contains("teapot"))
    );
    commit(dev, unknown);
    assert!(log.errors().is_empty());

    release_all(dev, &[geometry, material, surface, array, unknown]);
    release_device(lib, dev);
}

#[test]
fn properties_are_typed_and_never_written_past_size() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let mut version = 0i32;
    assert_eq!(
        anariGetProperty(
            dev,
            dev,
            c("version").as_ptr(),
            ANARI_INT32,
            &mut version as *mut i32 as _,
            4,
            ANARI_WAIT
        ),
        1
    );
    assert_eq!(version, 100);
    // Wrong type, too small a size: 0 and nothing written.
    let mut bytes = [0xAAu8; 8];
    assert_eq!(
        anariGetProperty(
            dev,
            dev,
            c("geometryMaxIndex").as_ptr(),
            ANARI_UINT64,
            bytes.as_mut_ptr() as _,
            4,
            ANARI_WAIT
        ),
        0
    );
    assert_eq!(bytes, [0xAA; 8]);
    assert_eq!(
        anariGetProperty(
            dev,
            dev,
            c("version").as_ptr(),
            ANARI_FLOAT32,
            bytes.as_mut_ptr() as _,
            8,
            ANARI_WAIT
        ),
        0
    );
    assert_eq!(bytes, [0xAA; 8]);
    let mut list: *const *const std::ffi::c_char = std::ptr::null();
    assert_eq!(
        anariGetProperty(
            dev,
            dev,
            c("extension").as_ptr(),
            ANARI_STRING_LIST,
            &mut list as *mut _ as _,
            8,
            ANARI_WAIT
        ),
        1
    );
    let names = c_strings(list);
    assert!(
        names.contains(&"ANARI_KHR_GEOMETRY_TRIANGLE".to_string()),
        "{names:?}"
    );
    assert!(names.contains(&"ANARI_KHR_FRAME_ACCUMULATION".to_string()));

    // World bounds follow the geometry.
    let (geometry, surface, world) = triangle_scene(dev, -2.0);
    let mut bounds = [0f32; 6];
    assert_eq!(
        anariGetProperty(
            dev,
            world,
            c("bounds").as_ptr(),
            ANARI_FLOAT32_BOX3,
            bounds.as_mut_ptr() as _,
            24,
            ANARI_WAIT
        ),
        1
    );
    assert_eq!(bounds, [-1.0, -1.0, -2.0, 1.0, 1.0, -2.0]);
    // Frame duration after a render.
    let frame = basic_frame(dev, world, [8, 8]);
    anariRenderFrame(dev, frame);
    let mut duration = -1f32;
    assert_eq!(
        anariGetProperty(
            dev,
            frame,
            c("duration").as_ptr(),
            ANARI_FLOAT32,
            &mut duration as *mut f32 as _,
            4,
            ANARI_WAIT
        ),
        1
    );
    assert!((0.0..10.0).contains(&duration));
    release_all(dev, &[geometry, surface, world, frame]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn introspection_comes_from_the_tables() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let geometries = c_strings(anariGetObjectSubtypes(dev, ANARI_GEOMETRY));
    assert_eq!(
        geometries,
        [
            "triangle",
            "quad",
            "sphere",
            "cylinder",
            "cone",
            "curve",
            "isosurface"
        ]
    );
    let renderers = c_strings(anariGetObjectSubtypes(dev, ANARI_RENDERER));
    assert_eq!(renderers[0], "default");
    let description = anariGetObjectInfo(
        dev,
        ANARI_GEOMETRY,
        c("sphere").as_ptr(),
        c("description").as_ptr(),
        ANARI_STRING,
    );
    assert!(!description.is_null());
    // The parameter list contains vertex.position as an ARRAY1D.
    let params = anariGetObjectInfo(
        dev,
        ANARI_GEOMETRY,
        c("triangle").as_ptr(),
        c("parameter").as_ptr(),
        ANARI_PARAMETER_LIST,
    ) as *const ANARIParameter;
    let mut found = false;
    // SAFETY: the list ends with a NULL name.
    unsafe {
        let mut p = params;
        while !(*p).name.is_null() {
            if CStr::from_ptr((*p).name).to_str() == Ok("vertex.position") {
                found = (*p).data_type == ANARI_ARRAY1D;
            }
            p = p.add(1);
        }
    }
    assert!(found);
    let radius = anariGetParameterInfo(
        dev,
        ANARI_GEOMETRY,
        c("sphere").as_ptr(),
        c("radius").as_ptr(),
        ANARI_FLOAT32,
        c("default").as_ptr(),
        ANARI_FLOAT32,
    ) as *const f32;
    // SAFETY: the default of a FLOAT32 parameter is one float.
    assert_eq!(unsafe { *radius }, 1.0);
    let required = anariGetParameterInfo(
        dev,
        ANARI_GEOMETRY,
        c("sphere").as_ptr(),
        c("vertex.position").as_ptr(),
        ANARI_ARRAY1D,
        c("required").as_ptr(),
        ANARI_BOOL,
    ) as *const u8;
    // SAFETY: "required" is one ANARI_BOOL byte.
    assert_eq!(unsafe { *required }, 1);
    let channels = c_strings(anariGetObjectInfo(
        dev,
        ANARI_FRAME,
        std::ptr::null(),
        c("channel").as_ptr(),
        ANARI_STRING_LIST,
    ) as _);
    assert!(channels.contains(&"channel.windowDepth".to_string()));
    let missing = anariGetParameterInfo(
        dev,
        ANARI_GEOMETRY,
        c("sphere").as_ptr(),
        c("nope").as_ptr(),
        ANARI_FLOAT32,
        c("default").as_ptr(),
        ANARI_FLOAT32,
    );
    assert!(missing.is_null());
    release_device(lib, dev);
}

#[test]
fn library_names_and_device_subtypes() {
    let log = Log::new();
    let user = &*log as *const Log as *const c_void;
    for name in ["cavetrace", "default"] {
        let lib = anariLoadLibrary(c(name).as_ptr(), Some(record_status), user);
        assert!(!lib.is_null());
        anariUnloadLibrary(lib);
    }
    let other = anariLoadLibrary(c("helide").as_ptr(), Some(record_status), user);
    assert!(other.is_null());
    let e = log.errors();
    assert!(e.len() == 1 && e[0].1.contains("helide"), "{e:?}");
    let lib = anariLoadLibrary(c("cavetrace").as_ptr(), Some(record_status), user);
    assert!(anariNewDevice(lib, c("vulkan").as_ptr()).is_null());
    assert_eq!(log.errors().len(), 1);
    anariLoadModule(lib, c("extra").as_ptr());
    assert!(log.errors()[0].1.contains("no loadable modules"));
    assert_eq!(
        c_strings(anariGetDeviceSubtypes(lib)),
        ["default", "cavetrace"]
    );
    anariUnloadLibrary(lib);
}

#[test]
fn releasing_the_device_mid_render_is_safe() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let (geometry, surface, world) = triangle_scene(dev, -2.0);
    let frame = basic_frame(dev, world, [512, 512]);
    anariRenderFrame(dev, frame);
    release_all(dev, &[geometry, surface, world, frame]);
    assert!(cavetrace::device::registry::device(dev as usize).is_some());
    anariRelease(dev, dev);
    assert!(cavetrace::device::registry::device(dev as usize).is_none());
    // The handle is dead now: calls are reported (on stderr) and ignored.
    anariCommitParameters(dev, dev);
    anariUnloadLibrary(lib);
}

#[test]
fn parameters_set_during_a_render_affect_only_the_next_frame() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let (geometry, surface, world) = triangle_scene(dev, -2.0);
    let frame = basic_frame(dev, world, [256, 256]);
    anariRenderFrame(dev, frame);
    // While rendering: move the triangle and commit from another thread.
    let (d, g) = (dev as usize, geometry as usize);
    std::thread::spawn(move || {
        let moved: [[f32; 3]; 3] = [[-1.0, -1.0, -7.0], [1.0, -1.0, -7.0], [0.0, 1.0, -7.0]];
        let array = array1d(d as ANARIDevice, ANARI_FLOAT32_VEC3, &moved);
        set_object(
            d as ANARIDevice,
            g as ANARIObject,
            "vertex.position",
            ANARI_ARRAY1D,
            array,
        );
        commit(d as ANARIDevice, g as ANARIObject);
        anariRelease(d as ANARIDevice, array);
    })
    .join()
    .unwrap();
    anariFrameReady(dev, frame, ANARI_WAIT);
    let (depth, _, _) = read_channel::<f32>(dev, frame, "channel.depth");
    assert!((depth[128 * 256 + 128] - 2.0).abs() < 1e-3);
    assert!((centre_depth(dev, frame, [256, 256]) - 7.0).abs() < 1e-3);
    release_all(dev, &[geometry, surface, world, frame]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn a_released_shared_array_is_copied_before_the_application_frees_it() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let mut memory = [[-1.0f32, -1.0, -2.0], [1.0, -1.0, -2.0], [0.0, 1.0, -2.0]];
    let array = anariNewArray1D(
        dev,
        memory.as_ptr() as *const c_void,
        None,
        std::ptr::null(),
        ANARI_FLOAT32_VEC3,
        3,
    );
    let geometry = anariNewGeometry(dev, c("triangle").as_ptr());
    set_object(dev, geometry, "vertex.position", ANARI_ARRAY1D, array);
    anariRelease(dev, array);
    // The application may now reuse its memory; the device must not see it.
    memory.iter_mut().for_each(|v| *v = [100.0; 3]);
    commit(dev, geometry);
    let surface = matte_surface(dev, geometry, [1.0; 3]);
    let world = world_of(dev, &[surface]);
    let mut bounds = [0f32; 6];
    assert_eq!(
        anariGetProperty(
            dev,
            world,
            c("bounds").as_ptr(),
            ANARI_FLOAT32_BOX3,
            bounds.as_mut_ptr() as _,
            24,
            ANARI_WAIT
        ),
        1
    );
    assert_eq!(bounds, [-1.0, -1.0, -2.0, 1.0, 1.0, -2.0]);
    // An empty world has no bounds.
    let empty = anariNewWorld(dev);
    commit(dev, empty);
    assert_eq!(
        anariGetProperty(
            dev,
            empty,
            c("bounds").as_ptr(),
            ANARI_FLOAT32_BOX3,
            bounds.as_mut_ptr() as _,
            24,
            ANARI_WAIT
        ),
        0
    );
    release_all(dev, &[geometry, surface, world, empty]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn map_frame_writes_only_the_outputs_it_is_given() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let (geometry, surface, world) = triangle_scene(dev, -2.0);
    let frame = basic_frame(dev, world, [24, 16]);
    render_and_wait(dev, frame);
    let color = c("channel.color");
    let null = std::ptr::null_mut::<u32>();
    let no_type = std::ptr::null_mut::<ANARIDataType>();
    // Every out pointer NULL: the pixels are still returned.
    let pixels = anariMapFrame(dev, frame, color.as_ptr(), null, null, no_type);
    assert!(!pixels.is_null());
    anariUnmapFrame(dev, frame, color.as_ptr());
    // Each one alone is written; the others stay NULL and are not touched.
    let mut width = 0u32;
    assert!(!anariMapFrame(dev, frame, color.as_ptr(), &mut width, null, no_type).is_null());
    anariUnmapFrame(dev, frame, color.as_ptr());
    let mut height = 0u32;
    assert!(!anariMapFrame(dev, frame, color.as_ptr(), null, &mut height, no_type).is_null());
    anariUnmapFrame(dev, frame, color.as_ptr());
    let mut pixel_type = ANARI_UNKNOWN;
    assert!(!anariMapFrame(dev, frame, color.as_ptr(), null, null, &mut pixel_type).is_null());
    anariUnmapFrame(dev, frame, color.as_ptr());
    assert_eq!((width, height, pixel_type), (24, 16, ANARI_FLOAT32_VEC4));
    // A failed map writes 0, 0, ANARI_UNKNOWN to the pointers it has.
    let missing = c("channel.albedo");
    let mut width = 7u32;
    assert!(anariMapFrame(dev, frame, missing.as_ptr(), &mut width, null, no_type).is_null());
    assert_eq!(width, 0);
    let errors = log.errors();
    assert!(
        errors.len() == 1 && errors[0].1.contains("'channel.albedo' is not available"),
        "{errors:?}"
    );
    release_all(dev, &[geometry, surface, world, frame]);
    release_device(lib, dev);
}
