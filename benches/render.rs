//! Device-level benchmark: prints figures, asserts nothing.
//!
//!     cargo bench --bench render            (full size: 1M triangles at 1600×1600)
//!     CAVETRACE_BENCH_QUICK=1 cargo bench --bench render   (small, for a smoke run)
//!
//! Scenes: a height field of ~1M triangles seen by a tracked head (the camera moves every
//! frame), rendered (a) by the "fast" renderer and (b) by the "default" renderer with one
//! directional light and shadows; and a cloud of 100k spheres. Printed: Mrays/s (primary rays),
//! median frame ms, BVH build ms, first-frame latency (commit to image), bytes per triangle.

#[path = "../tests/common/mod.rs"]
mod common;
use common::*;
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

struct Setup {
    dev: ANARIDevice,
    camera: ANARICamera,
    renderer: ANARIRenderer,
    frame: ANARIFrame,
    world: ANARIWorld,
}

fn height_field(dev: ANARIDevice, cells: u32) -> (ANARIGeometry, usize) {
    let n = cells + 1;
    let mut positions = Vec::with_capacity((n * n) as usize);
    for j in 0..n {
        for i in 0..n {
            let x = i as f32 / cells as f32 * 2.0 - 1.0;
            let z = j as f32 / cells as f32 * 2.0 - 1.0;
            let y = 0.05 * (x * 9.0).sin() * (z * 7.0).cos();
            positions.push([x, y, z]);
        }
    }
    let mut indices = Vec::with_capacity((cells * cells * 2) as usize);
    for j in 0..cells {
        for i in 0..cells {
            let a = j * n + i;
            indices.push([a, a + 1, a + n + 1]);
            indices.push([a, a + n + 1, a + n]);
        }
    }
    let g = anariNewGeometry(dev, c("triangle").as_ptr());
    let p = array1d(dev, ANARI_FLOAT32_VEC3, &positions);
    let ix = array1d(dev, ANARI_UINT32_VEC3, &indices);
    set_object(dev, g, "vertex.position", ANARI_ARRAY1D, p);
    set_object(dev, g, "primitive.index", ANARI_ARRAY1D, ix);
    anariRelease(dev, p);
    anariRelease(dev, ix);
    (g, indices.len())
}

fn sphere_cloud(dev: ANARIDevice, count: usize) -> ANARIGeometry {
    let mut state = 12345u32;
    let mut random = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as f32 / u32::MAX as f32
    };
    let centers: Vec<[f32; 3]> = (0..count)
        .map(|_| [random() * 2.0 - 1.0, random() * 0.5, random() * 2.0 - 1.0])
        .collect();
    let g = anariNewGeometry(dev, c("sphere").as_ptr());
    let p = array1d(dev, ANARI_FLOAT32_VEC3, &centers);
    set_object(dev, g, "vertex.position", ANARI_ARRAY1D, p);
    set(dev, g, "radius", ANARI_FLOAT32, &0.01f32);
    anariRelease(dev, p);
    g
}

fn setup(dev: ANARIDevice, geometry: ANARIGeometry, renderer_type: &str, size: u32) -> Setup {
    let surface = matte_surface(dev, geometry, [0.7, 0.7, 0.7]);
    let world = world_of(dev, &[surface]);
    anariRelease(dev, surface);
    if renderer_type == "default" {
        let light = anariNewLight(dev, c("directional").as_ptr());
        set(
            dev,
            light,
            "direction",
            ANARI_FLOAT32_VEC3,
            &[-0.3f32, -1.0, -0.4],
        );
        set(dev, light, "irradiance", ANARI_FLOAT32, &3.0f32);
        commit(dev, light);
        let lights = object_array(dev, ANARI_LIGHT, &[light]);
        set_object(dev, world, "light", ANARI_ARRAY1D, lights);
        commit(dev, world);
        anariRelease(dev, light);
        anariRelease(dev, lights);
    }
    let camera = anariNewCamera(dev, c("perspective").as_ptr());
    let renderer = anariNewRenderer(dev, c(renderer_type).as_ptr());
    commit(dev, renderer);
    let frame = anariNewFrame(dev);
    set(dev, frame, "size", ANARI_UINT32_VEC2, &[size, size]);
    set(
        dev,
        frame,
        "channel.color",
        ANARI_DATA_TYPE,
        &ANARI_UFIXED8_RGBA_SRGB,
    );
    set_object(dev, frame, "world", ANARI_WORLD, world);
    set_object(dev, frame, "camera", ANARI_CAMERA, camera);
    set_object(dev, frame, "renderer", ANARI_RENDERER, renderer);
    commit(dev, frame);
    Setup {
        dev,
        camera,
        renderer,
        frame,
        world,
    }
}

/// Moves the tracked head a little and commits the camera, as a VR application does per frame.
fn track_head(s: &Setup, step: u32) {
    let t = step as f32 * 0.05;
    let eye = [0.1 * t.sin(), 1.2 + 0.02 * t.cos(), 1.6];
    let target = [0.0f32, 0.0, 0.0];
    let dir = [target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]];
    set(s.dev, s.camera, "position", ANARI_FLOAT32_VEC3, &eye);
    set(s.dev, s.camera, "direction", ANARI_FLOAT32_VEC3, &dir);
    set(s.dev, s.camera, "fovy", ANARI_FLOAT32, &0.9f32);
    commit(s.dev, s.camera);
}

fn render_once(s: &Setup) -> f64 {
    let start = Instant::now();
    anariRenderFrame(s.dev, s.frame);
    anariFrameReady(s.dev, s.frame, ANARI_WAIT);
    start.elapsed().as_secs_f64() * 1e3
}

fn run(label: &str, s: &Setup, size: u32, frames: u32) {
    let ms: Vec<f64> = (0..frames)
        .map(|i| {
            track_head(s, i + 1);
            render_once(s)
        })
        .collect();
    let median_ms = median(ms);
    let mrays = (size as f64 * size as f64) / (median_ms * 1e3);
    println!(
        "{label}: median frame {median_ms:.1} ms, {mrays:.2} Mrays/s (primary, {size}x{size}, {frames} frames)"
    );
}

fn release(s: Setup) {
    for o in [s.camera, s.renderer, s.frame, s.world] {
        anariRelease(s.dev, o);
    }
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let quick = std::env::var_os("CAVETRACE_BENCH_QUICK").is_some();
    let (cells, size, spheres, frames) = if quick {
        (100, 256, 5_000, 3)
    } else {
        (708, 1600, 100_000, 7)
    };
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);

    let (geometry, triangles) = height_field(dev, cells);
    let start = Instant::now();
    commit(dev, geometry);
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let bytes = cavetrace::device::registry::device(dev as usize)
        .and_then(|d| d.lookup(geometry as usize))
        .and_then(|o| o.derived_as::<cavetrace::scene::geometry::Geometry>())
        .map(|g| g.memory_bytes())
        .unwrap_or(0);
    println!(
        "height field: {triangles} triangles, BVH build (commit) {build_ms:.0} ms, {:.1} bytes/triangle",
        bytes as f64 / triangles as f64
    );

    let fast = setup(dev, geometry, "fast", size);
    track_head(&fast, 0);
    let first = render_once(&fast);
    println!(
        "first frame (scene already committed): {first:.1} ms; commit + first frame: {:.1} ms",
        build_ms + first
    );
    run("(a) fast renderer, moving head", &fast, size, frames);
    release(fast);
    let shaded = setup(dev, geometry, "default", size);
    track_head(&shaded, 0);
    run(
        "(b) default renderer, 1 directional light + shadows, moving head",
        &shaded,
        size,
        frames,
    );
    release(shaded);
    anariRelease(dev, geometry);

    let cloud = sphere_cloud(dev, spheres);
    let start = Instant::now();
    commit(dev, cloud);
    println!(
        "sphere cloud: {spheres} spheres, BVH build {:.0} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
    let s = setup(dev, cloud, "fast", size);
    track_head(&s, 0);
    run("(c) 100k spheres, fast renderer", &s, size, frames);
    release(s);
    anariRelease(dev, cloud);
    anariRelease(dev, dev);
    anariUnloadLibrary(lib);
    let errors = log.errors();
    if !errors.is_empty() {
        println!("status errors during the benchmark: {errors:?}");
    }
}
