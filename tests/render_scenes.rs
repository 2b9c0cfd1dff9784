//! Rendering correctness: pixels, depths, ids, shadows, mirrors, samplers, instancing, frames.
mod common;
use common::*;
use glam::Vec3;

fn renderer(dev: ANARIDevice, subtype: &str, ambient: f32) -> ANARIRenderer {
    let r = anariNewRenderer(dev, c(subtype).as_ptr());
    if subtype == "default" {
        set(dev, r, "ambientRadiance", ANARI_FLOAT32, &ambient);
        set(
            dev,
            r,
            "background",
            ANARI_FLOAT32_VEC4,
            &[0.0f32, 0.0, 0.0, 1.0],
        );
    }
    commit(dev, r);
    r
}

/// Ray direction through pixel centre (x+½, y+½) of a w×h perspective frame looking down −z.
fn pixel_ray(x: u32, y: u32, w: u32, h: u32, fovy: f32) -> Vec3 {
    let t = (fovy / 2.0).tan();
    let aspect = w as f32 / h as f32;
    let u = (2.0 * (x as f32 + 0.5) / w as f32 - 1.0) * t * aspect;
    let v = (2.0 * (y as f32 + 0.5) / h as f32 - 1.0) * t;
    Vec3::new(u, v, -1.0).normalize()
}

#[test]
fn a_triangle_covers_exactly_the_pixels_its_projection_covers_at_the_analytic_depth() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let tri = [[-0.7f32, -0.4, -2.0], [0.9, -0.6, -2.5], [0.1, 0.8, -1.8]];
    let g = triangle_geometry(dev, &tri);
    let s = matte_surface(dev, g, [1.0, 1.0, 1.0]);
    let world = world_of(dev, &[s]);
    let fovy = 1.0f32;
    let camera = perspective_camera(dev, [0.0, 0.0, 0.0], [0.0, 0.0, -1.0], fovy);
    let r = renderer(dev, "fast", 0.0);
    let (w, h) = (80u32, 60u32);
    let frame = frame_for(dev, world, camera, r, [w, h]);
    let (ids, _, _) = render_channel::<u32>(dev, frame, "channel.primitiveId");
    let (depth, _, _) = read_channel::<f32>(dev, frame, "channel.depth");
    let [a, b, cc] = tri.map(Vec3::from);
    let normal = (b - a).cross(cc - a);
    let mut covered = 0;
    for y in 0..h {
        for x in 0..w {
            let d = pixel_ray(x, y, w, h, fovy);
            // Analytic ray-plane hit and inside test by edge signs.
            let t = normal.dot(a) / normal.dot(d);
            let p = d * t;
            let inside = [(a, b), (b, cc), (cc, a)]
                .iter()
                .all(|(e0, e1)| (*e1 - *e0).cross(p - *e0).dot(normal) >= 0.0);
            let i = (y * w + x) as usize;
            // Skip pixels whose centre is within a hair of an edge (either answer is right).
            let margin = [(a, b), (b, cc), (cc, a)]
                .iter()
                .map(|(e0, e1)| {
                    ((*e1 - *e0).cross(p - *e0).dot(normal)
                        / normal.length()
                        / (*e1 - *e0).length())
                    .abs()
                })
                .fold(f32::INFINITY, f32::min);
            if margin < 1e-4 {
                continue;
            }
            if inside {
                covered += 1;
                assert_eq!(ids[i], 0, "pixel {x},{y} should be covered");
                assert!(
                    (depth[i] - t).abs() < 1e-4 * t,
                    "pixel {x},{y}: depth {} vs {t}",
                    depth[i]
                );
            } else {
                assert_eq!(ids[i], u32::MAX, "pixel {x},{y} should be empty");
                assert!(depth[i].is_infinite());
            }
        }
    }
    assert!(covered > 300, "{covered}");
    release_all(dev, &[g, s, world, camera, r, frame]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn a_spheres_silhouette_is_the_analytic_circle() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let center = Vec3::new(0.3, -0.2, -4.0);
    let radius = 0.9;
    let g = sphere_geometry(dev, &[center.to_array()], radius);
    let s = matte_surface(dev, g, [1.0, 1.0, 1.0]);
    let world = world_of(dev, &[s]);
    let fovy = 0.8;
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], fovy);
    let r = renderer(dev, "fast", 0.0);
    let (w, h) = (64u32, 64u32);
    let frame = frame_for(dev, world, camera, r, [w, h]);
    let (ids, _, _) = render_channel::<u32>(dev, frame, "channel.primitiveId");
    let (depth, _, _) = read_channel::<f32>(dev, frame, "channel.depth");
    let mut inside_count = 0;
    for y in 0..h {
        for x in 0..w {
            let d = pixel_ray(x, y, w, h, fovy);
            let along = d.dot(center);
            let miss_distance = (center - d * along).length();
            let i = (y * w + x) as usize;
            if (miss_distance - radius).abs() < 2e-4 {
                continue;
            }
            if miss_distance < radius {
                inside_count += 1;
                assert_eq!(ids[i], 0, "pixel {x},{y}");
                let t = along - (radius * radius - miss_distance * miss_distance).sqrt();
                assert!((depth[i] - t).abs() < 1e-4 * t, "depth {} vs {t}", depth[i]);
            } else {
                assert_eq!(ids[i], u32::MAX, "pixel {x},{y}");
            }
        }
    }
    assert!(inside_count > 200);
    release_all(dev, &[g, s, world, camera, r, frame]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn a_shadow_falls_where_the_geometry_says() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // Floor at y = 0 seen from above; a small occluding square at y = 1 over x,z ∈ [-0.25, 0.25];
    // the light shines straight down, so the shadow is the square's footprint.
    let floor = triangle_geometry(
        dev,
        &[
            [-2.0, 0.0, -2.0],
            [2.0, 0.0, 2.0],
            [2.0, 0.0, -2.0],
            [-2.0, 0.0, -2.0],
            [-2.0, 0.0, 2.0],
            [2.0, 0.0, 2.0],
        ],
    );
    let blocker = triangle_geometry(
        dev,
        &[
            [-0.25, 1.0, -0.25],
            [0.25, 1.0, 0.25],
            [0.25, 1.0, -0.25],
            [-0.25, 1.0, -0.25],
            [-0.25, 1.0, 0.25],
            [0.25, 1.0, 0.25],
        ],
    );
    let s1 = matte_surface(dev, floor, [1.0, 1.0, 1.0]);
    let s2 = matte_surface(dev, blocker, [1.0, 1.0, 1.0]);
    set(dev, s2, "id", ANARI_UINT32, &7u32);
    commit(dev, s2);
    let world = world_of(dev, &[s1, s2]);
    let light = anariNewLight(dev, c("directional").as_ptr());
    set(
        dev,
        light,
        "direction",
        ANARI_FLOAT32_VEC3,
        &[0.0f32, -1.0, 0.0],
    );
    set(
        dev,
        light,
        "irradiance",
        ANARI_FLOAT32,
        &std::f32::consts::PI,
    );
    commit(dev, light);
    let lights = object_array(dev, ANARI_LIGHT, &[light]);
    set_object(dev, world, "light", ANARI_ARRAY1D, lights);
    commit(dev, world);
    // Camera above, looking down at the floor from off to the side so the blocker does not hide
    // its own shadow completely.
    let camera = perspective_camera(dev, [1.2, 3.0, 0.0], [-0.4, -1.0, 0.0], 1.2);
    set(dev, camera, "up", ANARI_FLOAT32_VEC3, &[0.0f32, 0.0, -1.0]);
    commit(dev, camera);
    let r = renderer(dev, "default", 0.0);
    let (w, h) = (64u32, 64u32);
    let frame = frame_for(dev, world, camera, r, [w, h]);
    let (color, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    let (depth, _, _) = read_channel::<f32>(dev, frame, "channel.depth");
    let (objects, _, _) = read_channel::<u32>(dev, frame, "channel.objectId");
    // Reconstruct each floor hit point from the camera ray and depth; lit = 1 (albedo 1 ×
    // irradiance π / π), shadowed = 0.
    let eye = Vec3::new(1.2, 3.0, 0.0);
    let forward = Vec3::new(-0.4, -1.0, 0.0).normalize();
    let right = forward.cross(Vec3::new(0.0, 0.0, -1.0)).normalize();
    let up = right.cross(forward);
    let t = (1.2f32 / 2.0).tan();
    let (mut lit, mut shadowed) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if objects[i] == 7 || depth[i].is_infinite() {
                continue;
            }
            let u = (2.0 * (x as f32 + 0.5) / w as f32 - 1.0) * t;
            let v = (2.0 * (y as f32 + 0.5) / h as f32 - 1.0) * t;
            let d = (forward + right * u + up * v).normalize();
            let p = eye + d * depth[i];
            assert!(p.y.abs() < 1e-3, "floor hit at {p}");
            let edge = (p.x.abs() - 0.25).abs().min((p.z.abs() - 0.25).abs());
            if edge < 0.02 {
                continue;
            }
            let under = p.x.abs() < 0.25 && p.z.abs() < 0.25;
            if under {
                shadowed += 1;
                assert!(
                    color[i][0] < 1e-3,
                    "pixel {x},{y} at {p} should be in shadow: {:?}",
                    color[i]
                );
            } else {
                lit += 1;
                assert!(
                    (color[i][0] - 1.0).abs() < 1e-3,
                    "pixel {x},{y} at {p} should be lit: {:?}",
                    color[i]
                );
            }
        }
    }
    assert!(shadowed > 10 && lit > 500, "{shadowed} {lit}");
    release_all(
        dev,
        &[
            floor, blocker, s1, s2, world, light, lights, camera, r, frame,
        ],
    );
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn a_mirror_sphere_shows_the_reflected_object() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // Camera at the origin looks at a mirror sphere; behind the camera a big green triangle.
    let mirror = sphere_geometry(dev, &[[0.0, 0.0, -3.0]], 1.0);
    let material = anariNewMaterial(dev, c("physicallyBased").as_ptr());
    set(
        dev,
        material,
        "baseColor",
        ANARI_FLOAT32_VEC3,
        &[1.0f32, 1.0, 1.0],
    );
    set(dev, material, "metallic", ANARI_FLOAT32, &1.0f32);
    set(dev, material, "roughness", ANARI_FLOAT32, &0.0f32);
    commit(dev, material);
    let s1 = surface_of(dev, mirror, material);
    let wall = triangle_geometry(
        dev,
        &[[-20.0, -20.0, 5.0], [20.0, -20.0, 5.0], [0.0, 20.0, 5.0]],
    );
    let s2 = matte_surface(dev, wall, [0.0, 1.0, 0.0]);
    let world = world_of(dev, &[s1, s2]);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], 0.6);
    // Ambient light only, so the wall's colour is ambient × albedo/π = (0, 1, 0) × π/π.
    let r = renderer(dev, "default", std::f32::consts::PI);
    let frame = frame_for(dev, world, camera, r, [32, 32]);
    let (color, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    let (ids, _, _) = read_channel::<u32>(dev, frame, "channel.primitiveId");
    // The centre pixel hits the sphere head-on and reflects straight back to the wall: green.
    let centre = color[16 * 32 + 16];
    assert_eq!(ids[16 * 32 + 16], 0);
    assert!(
        centre[1] > 0.95 && centre[0] < 0.05 && centre[2] < 0.05,
        "{centre:?}"
    );
    // Outside the sphere, the background (black).
    assert!(color[0][1] < 1e-6);
    release_all(
        dev,
        &[mirror, material, s1, wall, s2, world, camera, r, frame],
    );
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn sampler_colours_spheres_by_a_vertex_attribute_as_in_the_demo() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // Three spheres in a row with attribute0 = 0, 0.5, 1 through a 2-texel colour map
    // (red → blue), linear filtering: red, purple, blue.
    let g = anariNewGeometry(dev, c("sphere").as_ptr());
    let centers = array1d(
        dev,
        ANARI_FLOAT32_VEC3,
        &[[-2.0f32, 0.0, -6.0], [0.0, 0.0, -6.0], [2.0, 0.0, -6.0]],
    );
    let attribute = array1d(dev, ANARI_FLOAT32, &[0.0f32, 0.5, 1.0]);
    set_object(dev, g, "vertex.position", ANARI_ARRAY1D, centers);
    set_object(dev, g, "vertex.attribute0", ANARI_ARRAY1D, attribute);
    set(dev, g, "radius", ANARI_FLOAT32, &0.5f32);
    commit(dev, g);
    let texels = array1d(
        dev,
        ANARI_FLOAT32_VEC3,
        &[[1.0f32, 0.0, 0.0], [0.0, 0.0, 1.0]],
    );
    let sampler = anariNewSampler(dev, c("image1D").as_ptr());
    set_object(dev, sampler, "image", ANARI_ARRAY1D, texels);
    set_string(dev, sampler, "inAttribute", "attribute0");
    // Map [0,1] onto the texel centres (0.25 … 0.75) so the ends are pure colours.
    let scale: [f32; 16] = [
        0.5, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ];
    set(dev, sampler, "inTransform", ANARI_FLOAT32_MAT4, &scale);
    set(
        dev,
        sampler,
        "inOffset",
        ANARI_FLOAT32_VEC4,
        &[0.25f32, 0.0, 0.0, 0.0],
    );
    commit(dev, sampler);
    let material = anariNewMaterial(dev, c("matte").as_ptr());
    set_object(dev, material, "color", ANARI_SAMPLER, sampler);
    commit(dev, material);
    let s = surface_of(dev, g, material);
    let world = world_of(dev, &[s]);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], 0.8);
    let r = renderer(dev, "default", std::f32::consts::PI);
    let frame = frame_for(dev, world, camera, r, [96, 32]);
    add_channel(dev, frame, "channel.albedo", ANARI_FLOAT32_VEC3);
    anariRenderFrame(dev, frame);
    let (albedo, w, h) = read_channel::<[f32; 3]>(dev, frame, "channel.albedo");
    let (ids, _, _) = read_channel::<u32>(dev, frame, "channel.primitiveId");
    let centre_of = |cx: f32| {
        // The pixel nearest the projection of a sphere centre.
        let t = (0.8f32 / 2.0).tan();
        let aspect = w as f32 / h as f32;
        let x = ((cx / 6.0 / (t * aspect) + 1.0) / 2.0 * w as f32) as u32;
        (h / 2 * w + x) as usize
    };
    let expect = [
        (-2.0, 0u32, [1.0, 0.0, 0.0]),
        (0.0, 1, [0.5, 0.0, 0.5]),
        (2.0, 2, [0.0, 0.0, 1.0]),
    ];
    for (cx, id, rgb) in expect {
        let i = centre_of(cx);
        assert_eq!(ids[i], id);
        for k in 0..3 {
            assert!(
                (albedo[i][k] - rgb[k]).abs() < 1e-4,
                "sphere {id}: {:?} vs {rgb:?}",
                albedo[i]
            );
        }
    }
    release_all(
        dev,
        &[
            g, centers, attribute, texels, sampler, material, s, world, camera, r, frame,
        ],
    );
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn srgb_channel_encodes_known_linear_values() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = anariNewWorld(dev);
    commit(dev, world);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], 1.0);
    let r = anariNewRenderer(dev, c("default").as_ptr());
    set(
        dev,
        r,
        "background",
        ANARI_FLOAT32_VEC4,
        &[0.5f32, 0.2159, 0.0, 1.0],
    );
    commit(dev, r);
    let frame = frame_for(dev, world, camera, r, [4, 4]);
    set(
        dev,
        frame,
        "channel.color",
        ANARI_DATA_TYPE,
        &ANARI_UFIXED8_RGBA_SRGB,
    );
    commit(dev, frame);
    let (srgb, _, _) = render_channel::<[u8; 4]>(dev, frame, "channel.color");
    assert!(
        srgb.iter().all(|p| *p == [188, 128, 0, 255]),
        "{:?}",
        srgb[0]
    );
    set(
        dev,
        frame,
        "channel.color",
        ANARI_DATA_TYPE,
        &ANARI_UFIXED8_VEC4,
    );
    commit(dev, frame);
    let (linear, _, _) = render_channel::<[u8; 4]>(dev, frame, "channel.color");
    assert_eq!(linear[0], [128, 55, 0, 255]);
    release_all(dev, &[world, camera, r, frame]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn frames_poll_wait_discard_and_accumulate() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let g = sphere_geometry(dev, &[[0.0, 0.0, -3.0]], 1.0);
    let s = matte_surface(dev, g, [1.0, 1.0, 1.0]);
    let world = world_of(dev, &[s]);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], 1.0);
    let r = renderer(dev, "default", 1.0);
    let frame = frame_for(dev, world, camera, r, [800, 800]);
    anariRenderFrame(dev, frame);
    // Polling returns at once; WAIT blocks until done.
    let _ = anariFrameReady(dev, frame, ANARI_NO_WAIT);
    assert_eq!(anariFrameReady(dev, frame, ANARI_WAIT), 1);
    assert_eq!(anariFrameReady(dev, frame, ANARI_NO_WAIT), 1);
    // Discard stops a big render early: much faster than a full one.
    set(dev, r, "pixelSamples", ANARI_INT32, &16i32);
    commit(dev, r);
    let start = std::time::Instant::now();
    anariRenderFrame(dev, frame);
    anariFrameReady(dev, frame, ANARI_WAIT);
    let full = start.elapsed();
    let start = std::time::Instant::now();
    anariRenderFrame(dev, frame);
    anariDiscardFrame(dev, frame);
    anariFrameReady(dev, frame, ANARI_WAIT);
    let discarded = start.elapsed();
    assert!(
        discarded < full / 2,
        "discard {discarded:?} vs full {full:?}"
    );

    // Accumulation: with 1 sample per pass, edge pixels refine (change) over passes while
    // nothing changes, and a change of the scene restarts from the first pass.
    set(dev, r, "pixelSamples", ANARI_INT32, &1i32);
    commit(dev, r);
    set(dev, frame, "accumulation", ANARI_BOOL, &1u8);
    set(dev, frame, "size", ANARI_UINT32_VEC2, &[64u32, 64]);
    commit(dev, frame);
    let (first, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    let (second, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    let (third, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    let changed = |a: &[[f32; 4]], b: &[[f32; 4]]| a.iter().zip(b).filter(|(x, y)| x != y).count();
    assert!(
        changed(&first, &second) > 5 && changed(&first, &third) > 20,
        "later passes refine the edge pixels: {} {} {}",
        changed(&first, &second),
        changed(&second, &third),
        changed(&first, &third)
    );
    assert!(changed(&second, &third) > 5);
    assert!(
        changed(&first, &third) < 64 * 64 / 2,
        "only edge pixels change"
    );
    // Interior pixels (no edge inside the pixel) are the same in every pass.
    assert_eq!(first[32 * 64 + 32], third[32 * 64 + 32]);
    commit(dev, camera);
    let (restarted, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    assert_eq!(
        changed(&restarted, &first),
        0,
        "a commit restarts accumulation"
    );
    release_all(dev, &[g, s, world, camera, r, frame]);
    release_device(lib, dev);
    let e = log.errors();
    assert!(e.is_empty(), "{e:?}");
}

#[test]
fn bad_primitives_are_reported_and_skipped() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let g = anariNewGeometry(dev, c("triangle").as_ptr());
    let p = array1d(
        dev,
        ANARI_FLOAT32_VEC3,
        &[
            [-1.0f32, -1.0, -3.0],
            [1.0, -1.0, -3.0],
            [0.0, 1.0, -3.0],
            [f32::NAN, 0.0, 0.0],
        ],
    );
    let index = array1d(
        dev,
        ANARI_UINT32_VEC3,
        &[[0u32, 1, 2], [0, 1, 3], [0, 1, 99]],
    );
    set_object(dev, g, "vertex.position", ANARI_ARRAY1D, p);
    set_object(dev, g, "primitive.index", ANARI_ARRAY1D, index);
    commit(dev, g);
    let e = log.errors();
    assert_eq!(e.len(), 2, "{e:?}");
    assert!(e[0].1.contains("primitive 1") && e[1].1.contains("primitive 2"));
    let sg = sphere_geometry(dev, &[[0.0, 0.0, -3.0], [0.0, 0.0, -3.0]], -1.0);
    assert!(log.errors().len() == 2);
    let s = matte_surface(dev, g, [1.0, 1.0, 1.0]);
    let s2 = matte_surface(dev, sg, [1.0, 1.0, 1.0]);
    let world = world_of(dev, &[s, s2]);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], 1.0);
    let r = renderer(dev, "fast", 0.0);
    let frame = frame_for(dev, world, camera, r, [16, 16]);
    let (ids, _, _) = render_channel::<u32>(dev, frame, "channel.primitiveId");
    assert_eq!(ids[8 * 16 + 8], 0, "the good triangle keeps its id");
    release_all(dev, &[g, p, index, sg, s, s2, world, camera, r, frame]);
    release_device(lib, dev);
}

static CALLBACK_DONE: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);

unsafe extern "C" fn on_frame_done(
    user: *const std::ffi::c_void,
    device: *mut std::ffi::c_void,
    frame: *mut std::ffi::c_void,
) {
    assert_eq!(user as usize, 0xF00D);
    // The callback may look at the frame it is told about without waiting for itself.
    assert_eq!(anariFrameReady(device, frame, ANARI_WAIT), 1);
    let (pixels, w, h) = read_channel::<[f32; 4]>(device, frame, "channel.color");
    assert_eq!((pixels.len(), w, h), (64, 8, 8));
    std::thread::sleep(std::time::Duration::from_millis(50));
    CALLBACK_DONE.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
}

#[test]
fn the_completion_callback_finishes_before_the_frame_is_ready() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = anariNewWorld(dev);
    commit(dev, world);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], 1.0);
    let r = renderer(dev, "fast", 0.0);
    let frame = frame_for(dev, world, camera, r, [8, 8]);
    let callback: unsafe extern "C" fn(
        *const std::ffi::c_void,
        *mut std::ffi::c_void,
        *mut std::ffi::c_void,
    ) = on_frame_done;
    set(
        dev,
        frame,
        "frameCompletionCallback",
        ANARI_FRAME_COMPLETION_CALLBACK,
        &callback,
    );
    // A VOID_POINTER value is passed as `mem` itself.
    anariSetParameter(
        dev,
        frame,
        c("frameCompletionCallbackUserData").as_ptr(),
        ANARI_VOID_POINTER,
        0xF00D as *const std::ffi::c_void,
    );
    commit(dev, frame);
    for round in 1..=2 {
        anariRenderFrame(dev, frame);
        assert_eq!(anariFrameReady(dev, frame, ANARI_WAIT), 1);
        assert_eq!(
            CALLBACK_DONE.load(std::sync::atomic::Ordering::SeqCst),
            round
        );
    }
    // Mapping twice keeps both mappings valid; each unmap ends one.
    let name = c("channel.color");
    let (mut w, mut h, mut t) = (0u32, 0u32, 0);
    let first = anariMapFrame(dev, frame, name.as_ptr(), &mut w, &mut h, &mut t);
    let second = anariMapFrame(dev, frame, name.as_ptr(), &mut w, &mut h, &mut t);
    assert!(!first.is_null() && first == second);
    anariUnmapFrame(dev, frame, name.as_ptr());
    anariUnmapFrame(dev, frame, name.as_ptr());
    assert!(log.errors().is_empty());
    anariUnmapFrame(dev, frame, name.as_ptr());
    assert_eq!(log.errors().len(), 1, "a third unmap has nothing to unmap");
    release_all(dev, &[world, camera, r, frame]);
    release_device(lib, dev);
}

#[test]
fn ambient_radiance_times_albedo_is_the_colour_of_a_matte_surface() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let g = sphere_geometry(dev, &[[0.0, 0.0, -3.0]], 1.0);
    let s = matte_surface(dev, g, [0.7, 0.7, 0.7]);
    let world = world_of(dev, &[s]);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], 1.0);
    let r = renderer(dev, "default", 0.5);
    let frame = frame_for(dev, world, camera, r, [8, 8]);
    let (color, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    // Radiance L from every direction gives irradiance πL; a Lambertian surface returns ρ/π of it.
    assert!(
        (color[4 * 8 + 4][0] - 0.35).abs() < 1e-5,
        "{:?}",
        color[4 * 8 + 4]
    );
    release_all(dev, &[g, s, world, camera, r, frame]);
    release_device(lib, dev);
}

#[test]
fn rendering_again_rewrites_every_pixel_and_leaves_mapped_pixels_alone() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let g = sphere_geometry(dev, &[[0.0, 0.0, -4.0]], 1.0);
    let s = matte_surface(dev, g, [1.0, 1.0, 1.0]);
    let world = world_of(dev, &[s]);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], 0.8);
    let r = renderer(dev, "fast", 0.0);
    let frame = frame_for(dev, world, camera, r, [32, 32]);
    let (sphere_ids, _, _) = render_channel::<u32>(dev, frame, "channel.primitiveId");
    let (sphere_depth, _, _) = read_channel::<f32>(dev, frame, "channel.depth");
    assert!(sphere_ids.iter().filter(|id| **id == 0).count() > 100);

    // Keep the sphere's depth mapped while the camera turns away and the frame renders again.
    let name = c("channel.depth");
    let (mut w, mut h, mut t) = (0u32, 0u32, 0);
    let mapped = anariMapFrame(dev, frame, name.as_ptr(), &mut w, &mut h, &mut t) as *const f32;
    assert!(!mapped.is_null());
    let look = |direction: [f32; 3]| {
        set(dev, camera, "direction", ANARI_FLOAT32_VEC3, &direction);
        commit(dev, camera);
    };
    look([0.0, 0.0, 1.0]);
    anariRenderFrame(dev, frame);
    anariFrameReady(dev, frame, ANARI_WAIT);
    // SAFETY: the channel stays mapped (32×32 floats) until the unmap below.
    let still_mapped = unsafe { std::slice::from_raw_parts(mapped, (w * h) as usize) };
    assert_eq!(still_mapped, &sphere_depth[..]);
    anariUnmapFrame(dev, frame, name.as_ptr());

    // Render after render with nothing mapped: every channel of every pixel is rewritten.
    for _ in 0..2 {
        look([0.0, 0.0, -1.0]);
        let (ids, _, _) = render_channel::<u32>(dev, frame, "channel.primitiveId");
        let (depth, _, _) = read_channel::<f32>(dev, frame, "channel.depth");
        assert_eq!(ids, sphere_ids);
        assert_eq!(depth, sphere_depth);
        look([0.0, 0.0, 1.0]);
        let (ids, _, _) = render_channel::<u32>(dev, frame, "channel.primitiveId");
        let (depth, _, _) = read_channel::<f32>(dev, frame, "channel.depth");
        let (color, _, _) = read_channel::<[f32; 4]>(dev, frame, "channel.color");
        assert!(ids.iter().all(|id| *id == u32::MAX));
        assert!(depth.iter().all(|d| *d == f32::INFINITY));
        assert!(color.iter().all(|c| *c == [0.0, 0.0, 0.0, 1.0]));
    }
    release_all(dev, &[g, s, world, camera, r, frame]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn geometry_colours_take_every_color_element_type_of_the_specification() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // A large triangle in front of an orthographic camera: every pixel sees it.
    let positions = [[-5.0f32, -5.0, -1.0], [5.0, -5.0, -1.0], [0.0, 5.0, -1.0]];
    let camera = orthographic_camera(dev, [0.0, 0.0, 0.0], 1.0);
    let renderer = plain_renderer(dev, "fast");
    // Each case: one primitive.color of an element type and the linear colour it must give.
    let srgb_188 = ((188.0f32 / 255.0 + 0.055) / 1.055).powf(2.4);
    let cases: [(ANARIDataType, [f32; 3]); 3] = [
        (ANARI_UFIXED8_RGB_SRGB, [srgb_188, 0.0, 1.0]),
        (ANARI_UFIXED8_R_SRGB, [srgb_188, 0.0, 0.0]),
        (ANARI_UFIXED32_VEC3, [1.0, 0.0, 0.5]),
    ];
    for (element_type, expected) in cases {
        let geometry = triangle_geometry(dev, &positions);
        let colors = match element_type {
            ANARI_UFIXED8_RGB_SRGB => array1d(dev, element_type, &[[188u8, 0, 255]]),
            ANARI_UFIXED8_R_SRGB => array1d(dev, element_type, &[188u8]),
            _ => array1d(dev, element_type, &[[u32::MAX, 0, u32::MAX / 2]]),
        };
        set_object(dev, geometry, "primitive.color", ANARI_ARRAY1D, colors);
        commit(dev, geometry);
        anariRelease(dev, colors);
        let material = matte_colored_by(dev, "color");
        let surface = surface_of(dev, geometry, material);
        let world = world_of(dev, &[surface]);
        let frame = frame_for(dev, world, camera, renderer, [4, 4]);
        add_channel(dev, frame, "channel.albedo", ANARI_FLOAT32_VEC3);
        let (albedo, _, _) = render_channel::<[f32; 3]>(dev, frame, "channel.albedo");
        for pixel in albedo {
            assert_near(
                pixel,
                expected,
                &format!("primitive.color of type {element_type}"),
            );
        }
        release_all(dev, &[geometry, material, surface, world, frame]);
    }
    release_all(dev, &[camera, renderer]);
    release_device(lib, dev);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
}

#[test]
fn the_fast_renderer_gives_the_same_colours_with_or_without_other_channels() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let tri = triangle_geometry(
        dev,
        &[[-0.9, -0.6, -2.0], [0.2, -0.7, -2.2], [-0.3, 0.5, -1.9]],
    );
    let ball = sphere_geometry(dev, &[[0.45, 0.2, -2.5]], 0.35);
    let red = matte_surface(dev, tri, [0.9, 0.1, 0.1]);
    let blue = matte_surface(dev, ball, [0.1, 0.2, 0.9]);
    let world = world_of(dev, &[red, blue]);
    let camera = perspective_camera(dev, [0.0, 0.0, 0.0], [0.0, 0.0, -1.0], 1.0);
    let r = anariNewRenderer(dev, c("fast").as_ptr());
    set(
        dev,
        r,
        "background",
        ANARI_FLOAT32_VEC4,
        &[0.0f32, 0.5, 0.0, 1.0],
    );
    commit(dev, r);
    let frame = frame_for(dev, world, camera, r, [48, 40]);
    // With hit channels the colour comes from the full primary sample...
    let (with_hits, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    // ...without them from the fast renderer's colour-only path.
    for name in [
        "channel.depth",
        "channel.primitiveId",
        "channel.objectId",
        "channel.instanceId",
    ] {
        anariUnsetParameter(dev, frame, c(name).as_ptr());
    }
    commit(dev, frame);
    let (colour_only, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    assert_eq!(with_hits, colour_only);
    let count = |pick: fn(&[f32; 4]) -> bool| colour_only.iter().filter(|p| pick(p)).count();
    assert!(count(|p| p[0] > 0.3 && p[2] < 0.2) > 20, "red triangle");
    assert!(count(|p| p[2] > 0.3 && p[0] < 0.2) > 20, "blue sphere");
    assert!(count(|p| *p == [0.0, 0.5, 0.0, 1.0]) > 20, "background");
    release_all(dev, &[tri, ball, red, blue, world, camera, r, frame]);
    release_device(lib, dev);
}
