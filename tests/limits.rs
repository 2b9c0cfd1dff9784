//! Requests beyond what the device or the machine can hold: each is reported (OUT_OF_MEMORY or
//! INVALID_ARGUMENT) before anything is allocated, and the device renders normally afterwards.
//! Nothing here allocates the sizes it asks for; the geometry cases hand the device shared
//! arrays that claim more elements than their memory holds, which a device that read them
//! before checking would crash on.

mod common;

use common::*;

/// MemAvailable in bytes, as the device reads it.
fn available_memory() -> u64 {
    let meminfo = std::fs::read_to_string("/proc/meminfo").unwrap();
    let line = meminfo
        .lines()
        .find(|l| l.starts_with("MemAvailable:"))
        .unwrap();
    let kib: u64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    kib * 1024
}

/// The process's peak resident memory (VmHWM) in bytes: a refusal must come before the memory
/// is touched, not after.
fn peak_resident() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    let kib: u64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    kib * 1024
}

const PEAK_LIMIT: u64 = 1 << 30;

/// A triangle 2 m in front of the default camera, in a world, and a frame of `size` seeing it.
struct Scene {
    geometry: ANARIGeometry,
    surface: ANARISurface,
    world: ANARIWorld,
    camera: ANARICamera,
    renderer: ANARIRenderer,
    frame: ANARIFrame,
}

fn scene(dev: ANARIDevice, size: [u32; 2]) -> Scene {
    let geometry = triangle_geometry(
        dev,
        &[[-1.0, -1.0, -2.0], [1.0, -1.0, -2.0], [0.0, 1.0, -2.0]],
    );
    let surface = matte_surface(dev, geometry, [1.0, 1.0, 1.0]);
    let world = world_of(dev, &[surface]);
    let camera = anariNewCamera(dev, c("perspective").as_ptr());
    commit(dev, camera);
    let renderer = plain_renderer(dev, "default");
    let frame = frame_for(dev, world, camera, renderer, size);
    Scene {
        geometry,
        surface,
        world,
        camera,
        renderer,
        frame,
    }
}

impl Scene {
    fn release(self, dev: ANARIDevice) {
        release_all(
            dev,
            &[
                self.geometry,
                self.surface,
                self.world,
                self.camera,
                self.renderer,
                self.frame,
            ],
        );
    }
}

/// Renders a 16×16 frame of the triangle and checks its centre depth: the device still works.
fn assert_renders_normally(dev: ANARIDevice, frame: ANARIFrame, log: &Log) {
    set(dev, frame, "size", ANARI_UINT32_VEC2, &[16u32, 16]);
    commit(dev, frame);
    let (depth, w, h) = render_channel::<f32>(dev, frame, "channel.depth");
    assert_eq!((w, h), (16, 16));
    let centre = depth[8 * 16 + 8];
    assert!((centre - 2.0).abs() < 0.01, "centre depth {centre}");
    assert!(log.errors().is_empty());
}

/// The one error the log holds: its code and text.
fn one_error(log: &Log) -> (i32, String) {
    let errors = log.errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    errors[0].clone()
}

#[test]
fn a_frame_of_100000_squared_is_out_of_memory_and_the_device_renders_after() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let s = scene(dev, [100_000, 100_000]);
    assert!(log.errors().is_empty());
    anariRenderFrame(dev, s.frame);
    assert_eq!(anariFrameReady(dev, s.frame, ANARI_WAIT), 1);
    let (code, text) = one_error(&log);
    assert_eq!(code, ANARI_STATUS_OUT_OF_MEMORY);
    assert!(
        text.starts_with("anariRenderFrame:")
            && text.contains("100000×100000")
            && text.contains("exceeds 32768 pixels per side"),
        "{text}"
    );
    // Nothing was rendered: no channel to map.
    let color = c("channel.color");
    let null = std::ptr::null_mut();
    assert!(anariMapFrame(dev, s.frame, color.as_ptr(), null, null, null.cast()).is_null());
    log.take();
    assert_renders_normally(dev, s.frame, &log);
    s.release(dev);
    release_device(lib, dev);
}

#[test]
fn frame_buffers_beyond_the_available_memory_are_refused_before_allocating() {
    // 32768×32768 with every channel and accumulation: 76 bytes a pixel, 76 GiB.
    let needed = 76u64 << 30;
    if available_memory() >= needed {
        eprintln!("skipped: this machine has more than 76 GiB available");
        return;
    }
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let s = scene(dev, [32_768, 32_768]);
    add_channel(dev, s.frame, "channel.albedo", ANARI_FLOAT32_VEC3);
    add_channel(dev, s.frame, "channel.normal", ANARI_FLOAT32_VEC3);
    add_channel(dev, s.frame, "channel.windowDepth", ANARI_FLOAT32);
    set(dev, s.frame, "accumulation", ANARI_BOOL, &1u8);
    commit(dev, s.frame);
    assert!(log.errors().is_empty());
    anariRenderFrame(dev, s.frame);
    assert_eq!(anariFrameReady(dev, s.frame, ANARI_WAIT), 1);
    let (code, text) = one_error(&log);
    assert_eq!(code, ANARI_STATUS_OUT_OF_MEMORY);
    assert!(
        text.starts_with("anariRenderFrame:")
            && text.contains("32768×32768")
            && text.contains("of memory is available"),
        "{text}"
    );
    let peak = peak_resident();
    assert!(peak < PEAK_LIMIT, "peak resident memory {peak} bytes");
    set(dev, s.frame, "accumulation", ANARI_BOOL, &0u8);
    assert_renders_normally(dev, s.frame, &log);
    s.release(dev);
    release_device(lib, dev);
}

#[test]
fn arrays_that_overflow_or_exceed_the_available_memory_are_refused() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let s = scene(dev, [16, 16]);
    let new_array = |count: u64| {
        anariNewArray1D(
            dev,
            std::ptr::null(),
            None,
            std::ptr::null(),
            ANARI_UINT8,
            count,
        )
    };
    // Element count × element size overflows 64 bits.
    let overflowing = anariNewArray2D(
        dev,
        std::ptr::null(),
        None,
        std::ptr::null(),
        ANARI_FLOAT32_VEC4,
        u64::MAX / 8,
        8,
    );
    assert!(overflowing.is_null());
    let (code, text) = one_error(&log);
    assert_eq!(code, ANARI_STATUS_OUT_OF_MEMORY);
    assert!(
        text.starts_with("anariNewArray2D:") && text.contains("overflow"),
        "{text}"
    );
    // More than the machine has available, by 1 GiB: refused before the allocator is asked
    // (which, overcommitting, might say yes and let the zero-filling kill the process).
    let too_big = available_memory() + (1 << 30);
    assert!(new_array(too_big).is_null());
    let (code, text) = one_error(&log);
    assert_eq!(code, ANARI_STATUS_OUT_OF_MEMORY);
    assert!(
        text.starts_with("anariNewArray1D:")
            && text.contains("ANARI_UINT8")
            && text.contains("of memory is available")
            && text.ends_with("no array was created"),
        "{text}"
    );
    let peak = peak_resident();
    assert!(peak < PEAK_LIMIT, "peak resident memory {peak} bytes");
    // A modest array is still fine.
    let small = new_array(1 << 20);
    assert!(!small.is_null());
    anariRelease(dev, small);
    assert_renders_normally(dev, s.frame, &log);
    s.release(dev);
    release_device(lib, dev);
}

/// A shared array claiming `count` elements of `ty` over a few bytes of real memory: the device
/// must refuse it before reading past them.
fn claimed_array(dev: ANARIDevice, ty: ANARIDataType, count: u64) -> ANARIArray1D {
    static BYTES: [u64; 8] = [0; 8];
    let array = anariNewArray1D(
        dev,
        BYTES.as_ptr().cast(),
        None,
        std::ptr::null(),
        ty,
        count,
    );
    assert!(!array.is_null());
    array
}

#[test]
fn geometries_beyond_the_max_index_or_the_memory_are_refused_and_the_world_still_renders() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let s = scene(dev, [16, 16]);
    let mut max_index = 0u64;
    anariGetProperty(
        dev,
        dev,
        c("geometryMaxIndex").as_ptr(),
        ANARI_UINT64,
        (&mut max_index as *mut u64).cast(),
        8,
        ANARI_WAIT,
    );
    assert_eq!(max_index, u32::MAX as u64 - 1);

    // More spheres than a geometry can index.
    let centers = claimed_array(dev, ANARI_FLOAT32_VEC3, max_index + 2);
    let spheres = anariNewGeometry(dev, c("sphere").as_ptr());
    set_object(dev, spheres, "vertex.position", ANARI_ARRAY1D, centers);
    commit(dev, spheres);
    let (code, text) = one_error(&log);
    assert_eq!(code, ANARI_STATUS_INVALID_ARGUMENT);
    assert!(
        text.starts_with("anariCommitParameters: geometry 'sphere'")
            && text.contains("'vertex.position' has 4294967296 elements")
            && text.contains("geometryMaxIndex"),
        "{text}"
    );

    // More triangles than a geometry can index.
    let corners = claimed_array(dev, ANARI_FLOAT32_VEC3, 3);
    let indices = claimed_array(dev, ANARI_UINT32_VEC3, max_index + 2);
    let triangles = anariNewGeometry(dev, c("triangle").as_ptr());
    set_object(dev, triangles, "vertex.position", ANARI_ARRAY1D, corners);
    set_object(dev, triangles, "primitive.index", ANARI_ARRAY1D, indices);
    commit(dev, triangles);
    let (code, text) = one_error(&log);
    assert_eq!(code, ANARI_STATUS_INVALID_ARGUMENT);
    assert!(
        text.contains("geometry 'triangle'") && text.contains("'primitive.index' has 4294967296"),
        "{text}"
    );

    // Within the index range, but more than the machine could build (160+ bytes a primitive).
    let many = claimed_array(dev, ANARI_FLOAT32_VEC3, max_index);
    let big = anariNewGeometry(dev, c("sphere").as_ptr());
    set_object(dev, big, "vertex.position", ANARI_ARRAY1D, many);
    let fits = available_memory() / 200 >= max_index;
    if !fits {
        commit(dev, big);
        let (code, text) = one_error(&log);
        assert_eq!(code, ANARI_STATUS_OUT_OF_MEMORY);
        assert!(
            text.contains("geometry 'sphere' has 4294967294 primitives")
                && text.contains("of memory is available"),
            "{text}"
        );
    }

    let peak = peak_resident();
    assert!(peak < PEAK_LIMIT, "peak resident memory {peak} bytes");

    // All three in the world beside the triangle: they are skipped, the triangle renders.
    let surfaces: Vec<ANARISurface> = [spheres, triangles, big]
        .iter()
        .map(|g| matte_surface(dev, *g, [1.0, 0.0, 0.0]))
        .collect();
    let mut all = surfaces.clone();
    all.push(s.surface);
    let array = object_array(dev, ANARI_SURFACE, &all);
    set_object(dev, s.world, "surface", ANARI_ARRAY1D, array);
    commit(dev, s.world);
    assert_renders_normally(dev, s.frame, &log);

    // Release the users before the arrays, whose memory is not what they claim: a shared
    // array released while still in use would be copied.
    s.release(dev);
    release_all(dev, &surfaces);
    release_all(dev, &[array, spheres, triangles, big]);
    release_all(dev, &[centers, corners, indices, many]);
    release_device(lib, dev);
}
