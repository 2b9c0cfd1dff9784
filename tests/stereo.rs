//! Stereo frames: both eyes of a sideBySide/topBottom frame, and each pixel of an interleaved
//! one, equal each eye rendered alone (on every camera that takes `stereoMode`), the parallax
//! channel against the closed form, cyclopean lighting and anaglyphs.

mod common;
use common::*;
use glam::DVec3;

const IPD: f64 = 0.0635;
const SIZE: u32 = 40;

/// The offAxis screen of these tests: 1.6 m × 1.2 m in the plane z = 0, centred on the origin.
const LL: [f32; 3] = [-0.8, -0.6, 0.0];
const LR: [f32; 3] = [0.8, -0.6, 0.0];
const UR: [f32; 3] = [0.8, 0.6, 0.0];
const HEAD: [f32; 3] = [0.05, 0.02, 1.5];

fn off_axis(dev: ANARIDevice, stereo: &str, head: [f32; 3]) -> ANARICamera {
    let camera = anariNewCamera(dev, c("offAxis").as_ptr());
    set(dev, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, &LL);
    set(dev, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, &LR);
    set(dev, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, &UR);
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &head);
    set_string(dev, camera, "stereoMode", stereo);
    commit(dev, camera);
    camera
}

fn perspective(dev: ANARIDevice, stereo: &str, focus: f32) -> ANARICamera {
    let camera = perspective_camera(dev, HEAD, [0.0, 0.0, -1.0], 0.8);
    set(dev, camera, "focusDistance", ANARI_FLOAT32, &focus);
    set_string(dev, camera, "stereoMode", stereo);
    commit(dev, camera);
    camera
}

/// A dome camera at the head looking along −z, its image circle about 69° across.
fn fisheye(dev: ANARIDevice, stereo: &str) -> ANARICamera {
    let camera = anariNewCamera(dev, c("fisheye").as_ptr());
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &HEAD);
    set(
        dev,
        camera,
        "dome.direction",
        ANARI_FLOAT32_VEC3,
        &[0.0f32, 0.0, -1.0],
    );
    set(
        dev,
        camera,
        "dome.up",
        ANARI_FLOAT32_VEC3,
        &[0.0f32, 1.0, 0.0],
    );
    set(dev, camera, "fov", ANARI_FLOAT32, &1.2f32);
    set_string(dev, camera, "stereoMode", stereo);
    commit(dev, camera);
    camera
}

/// A 360° camera at the head, its frame the part of the panorama around −z.
fn omnidirectional(dev: ANARIDevice, stereo: &str) -> ANARICamera {
    let camera = anariNewCamera(dev, c("omnidirectional").as_ptr());
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &HEAD);
    set(
        dev,
        camera,
        "direction",
        ANARI_FLOAT32_VEC3,
        &[0.0f32, 0.0, -1.0],
    );
    set(dev, camera, "up", ANARI_FLOAT32_VEC3, &[0.0f32, 1.0, 0.0]);
    let region = [0.4f32, 0.35, 0.6, 0.65];
    set(dev, camera, "imageRegion", ANARI_FLOAT32_BOX2, &region);
    set_string(dev, camera, "stereoMode", stereo);
    commit(dev, camera);
    camera
}

/// The stereo cameras these tests compare: every camera type that takes `stereoMode`.
const STEREO_CAMERAS: [&str; 4] = ["offAxis", "perspective", "fisheye", "omnidirectional"];

/// A camera of type `camera_type` with stereo mode `mode`.
fn stereo_camera(dev: ANARIDevice, camera_type: &str, mode: &str) -> ANARICamera {
    match camera_type {
        "offAxis" => off_axis(dev, mode, HEAD),
        "perspective" => perspective(dev, mode, 1.5),
        "fisheye" => fisheye(dev, mode),
        "omnidirectional" => omnidirectional(dev, mode),
        other => panic!("no stereo camera {other}"),
    }
}

/// Every channel of one render, as bits (colour as floats).
struct Image {
    width: u32,
    color: Vec<[f32; 4]>,
    depth: Vec<u32>,
    window_depth: Vec<u32>,
    parallax: Vec<u32>,
    primitive: Vec<u32>,
    object: Vec<u32>,
    instance: Vec<u32>,
}

fn render(
    dev: ANARIDevice,
    world: ANARIWorld,
    camera: ANARICamera,
    renderer: ANARIRenderer,
    size: [u32; 2],
) -> Image {
    let frame = frame_for(dev, world, camera, renderer, size);
    set(
        dev,
        frame,
        "channel.windowDepth",
        ANARI_DATA_TYPE,
        &ANARI_FLOAT32,
    );
    add_channel(dev, frame, "channel.parallax", ANARI_FLOAT32);
    let (color, width, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    let bits = |name: &str| {
        read_channel::<f32>(dev, frame, name)
            .0
            .iter()
            .map(|v| v.to_bits())
            .collect()
    };
    let image = Image {
        width,
        color,
        depth: bits("channel.depth"),
        window_depth: bits("channel.windowDepth"),
        parallax: bits("channel.parallax"),
        primitive: read_channel::<u32>(dev, frame, "channel.primitiveId").0,
        object: read_channel::<u32>(dev, frame, "channel.objectId").0,
        instance: read_channel::<u32>(dev, frame, "channel.instanceId").0,
    };
    anariRelease(dev, frame);
    image
}

/// Asserts that `pair`'s pixels at `offset` equal `alone`'s: ids, depths, window depths and
/// parallax bit for bit, colours within 1/255.
fn assert_same_eye(pair: &Image, offset: (u32, u32), alone: &Image, what: &str) {
    for y in 0..SIZE {
        for x in 0..SIZE {
            let a = (y * alone.width + x) as usize;
            let p = ((y + offset.1) * pair.width + x + offset.0) as usize;
            let at = format!("{what}, pixel {x},{y}");
            assert_eq!(pair.primitive[p], alone.primitive[a], "{at}: primitiveId");
            assert_eq!(pair.object[p], alone.object[a], "{at}: objectId");
            assert_eq!(pair.instance[p], alone.instance[a], "{at}: instanceId");
            assert_eq!(pair.depth[p], alone.depth[a], "{at}: depth");
            assert_eq!(
                pair.window_depth[p], alone.window_depth[a],
                "{at}: windowDepth"
            );
            assert_eq!(pair.parallax[p], alone.parallax[a], "{at}: parallax");
            for channel in 0..4 {
                let difference = (pair.color[p][channel] - alone.color[a][channel]).abs();
                assert!(
                    difference <= 1.0 / 255.0,
                    "{at}: colour {:?} vs {:?}",
                    pair.color[p],
                    alone.color[a]
                );
            }
        }
    }
}

#[test]
fn both_eyes_of_a_stereo_frame_equal_each_eye_rendered_alone() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = mixed_world(dev);
    for renderer_type in ["fast", "default"] {
        let renderer = plain_renderer(dev, renderer_type);
        for camera_type in STEREO_CAMERAS {
            let make = |mode: &str| stereo_camera(dev, camera_type, mode);
            let alone = |eye: &str| {
                let camera = make(eye);
                let image = render(dev, world, camera, renderer, [SIZE, SIZE]);
                anariRelease(dev, camera);
                image
            };
            let (left, right) = (alone("left"), alone("right"));
            // The eyes differ (parallax), so the comparisons are not vacuous.
            assert!(
                left.depth != right.depth,
                "{camera_type}: the eyes see the same depths"
            );
            let seen = left
                .depth
                .iter()
                .filter(|d| f32::from_bits(**d).is_finite())
                .count();
            assert!(seen > 500, "{camera_type}: {seen} pixels hit");
            for (mode, size, left_at, right_at) in [
                ("sideBySide", [2 * SIZE, SIZE], (0, 0), (SIZE, 0)),
                // The left eye is the top half; rows count from the bottom.
                ("topBottom", [SIZE, 2 * SIZE], (0, SIZE), (0, 0)),
            ] {
                let camera = make(mode);
                let pair = render(dev, world, camera, renderer, size);
                anariRelease(dev, camera);
                let what = format!("{renderer_type} {camera_type} {mode}");
                assert_same_eye(&pair, left_at, &left, &format!("{what} left eye"));
                assert_same_eye(&pair, right_at, &right, &format!("{what} right eye"));
            }
        }
        anariRelease(dev, renderer);
    }
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    anariRelease(dev, world);
    release_device(lib, dev);
}

/// A matte rectangle parallel to the plane z = 0 at height `z`, with an id.
fn wall_at(dev: ANARIDevice, x: [f32; 2], z: f32, id: u32) -> ANARISurface {
    let [x0, x1] = x;
    let geometry = triangle_geometry(
        dev,
        &[
            [x0, -3.0, z],
            [x1, -3.0, z],
            [x1, 3.0, z],
            [x0, -3.0, z],
            [x1, 3.0, z],
            [x0, 3.0, z],
        ],
    );
    let surface = matte_surface(dev, geometry, [0.5; 3]);
    set(dev, surface, "id", ANARI_UINT32, &id);
    commit(dev, surface);
    anariRelease(dev, geometry);
    surface
}

/// Renders `camera` with the parallax channel: (parallax, objectId, frame width, parallaxRange).
fn parallax_of(
    dev: ANARIDevice,
    world: ANARIWorld,
    camera: ANARICamera,
    size: [u32; 2],
) -> (Vec<f32>, Vec<u32>, [f32; 2]) {
    let renderer = plain_renderer(dev, "fast");
    let frame = frame_for(dev, world, camera, renderer, size);
    add_channel(dev, frame, "channel.parallax", ANARI_FLOAT32);
    let (parallax, _, _) = render_channel::<f32>(dev, frame, "channel.parallax");
    let (objects, _, _) = read_channel::<u32>(dev, frame, "channel.objectId");
    let mut range = [0.0f32; 2];
    let found = anariGetProperty(
        dev,
        frame,
        c("parallaxRange").as_ptr(),
        ANARI_FLOAT32_VEC2,
        range.as_mut_ptr().cast(),
        8,
        ANARI_WAIT,
    );
    assert_eq!(found, 1, "parallaxRange");
    release_all(dev, &[renderer, frame]);
    (parallax, objects, range)
}

/// Checks every pixel against `expected(object id)` and the range against the pixels.
fn assert_parallax(
    values: &[f32],
    objects: &[u32],
    range: [f32; 2],
    expected: impl Fn(u32) -> f64,
    what: &str,
) {
    let mut seen = std::collections::BTreeSet::new();
    for (i, (&value, &object)) in values.iter().zip(objects).enumerate() {
        if object == u32::MAX {
            assert!(
                value.is_nan(),
                "{what}: pixel {i} shows the background but has parallax {value}"
            );
            continue;
        }
        let expected = expected(object);
        assert!(
            (f64::from(value) - expected).abs() < 2e-6,
            "{what}: pixel {i} (object {object}): {value} vs {expected}"
        );
        seen.insert(object);
    }
    assert!(seen.len() >= 3, "{what}: objects seen {seen:?}");
    let low = values
        .iter()
        .copied()
        .filter(|v| !v.is_nan())
        .fold(f32::INFINITY, f32::min);
    let high = values
        .iter()
        .copied()
        .filter(|v| !v.is_nan())
        .fold(f32::NEG_INFINITY, f32::max);
    assert_eq!(range, [low, high], "{what}: parallaxRange");
}

#[test]
fn parallax_is_ipd_times_depth_difference_over_depth() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // Walls parallel to the screen (z = 0) behind it, on it and in front of it.
    let walls = [
        ([-3.0f32, -0.2], -1.0f32, 1u32),
        ([-0.2, 0.2], 0.0, 2),
        ([0.2, 3.0], 0.6, 3),
    ];
    let surfaces: Vec<ANARISurface> = walls
        .iter()
        .map(|&(x, z, id)| wall_at(dev, x, z, id))
        .collect();
    let world = world_of(dev, &surfaces);
    let wall_z = |id: u32| f64::from(walls[id as usize - 1].1);

    // offAxis: the eyes at distance z₀ from the screen; a wall at distance z from the eyes.
    let head_distance = f64::from(HEAD[2]);
    let off_axis_expected = |id: u32| {
        let z = head_distance - wall_z(id);
        IPD * (z - head_distance) / z
    };
    for mode in ["none", "left", "sideBySide", "topBottom"] {
        let camera = off_axis(dev, mode, HEAD);
        let size = if mode == "sideBySide" {
            [2 * SIZE, SIZE]
        } else {
            [SIZE, SIZE]
        };
        let (values, objects, range) = parallax_of(dev, world, camera, size);
        assert_parallax(
            &values,
            &objects,
            range,
            off_axis_expected,
            &format!("offAxis {mode}"),
        );
        assert!(
            range[0] < 0.0 && range[1] > 0.0,
            "offAxis {mode}: {range:?}"
        );
        anariRelease(dev, camera);
    }
    // A head rolled by 30° in the screen plane: the horizontal part of the baseline counts.
    let roll = 30f64.to_radians();
    let camera = off_axis(dev, "sideBySide", HEAD);
    set(
        dev,
        camera,
        "right",
        ANARI_FLOAT32_VEC3,
        &[roll.cos() as f32, roll.sin() as f32, 0.0],
    );
    commit(dev, camera);
    let (values, objects, range) = parallax_of(dev, world, camera, [2 * SIZE, SIZE]);
    assert_parallax(
        &values,
        &objects,
        range,
        |id| off_axis_expected(id) * roll.cos(),
        "offAxis rolled head",
    );
    anariRelease(dev, camera);

    // perspective: zero parallax at focusDistance, here the middle wall.
    let focus = head_distance;
    let camera = perspective(dev, "sideBySide", focus as f32);
    let (values, objects, range) = parallax_of(dev, world, camera, [2 * SIZE, SIZE]);
    assert_parallax(&values, &objects, range, off_axis_expected, "perspective");
    anariRelease(dev, camera);

    // A matrix camera has no stereo pair: no parallax anywhere.
    let camera = anariNewCamera(dev, c("matrix").as_ptr());
    commit(dev, camera);
    let (values, _, range) = parallax_of(dev, world, camera, [SIZE, SIZE]);
    assert!(values.iter().all(|v| v.is_nan()));
    assert!(range[0].is_nan() && range[1].is_nan());
    anariRelease(dev, camera);

    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_all(dev, &surfaces);
    anariRelease(dev, world);
    release_device(lib, dev);
}

/// Where the eye at `eye` sees `point` on the screen, as (s, t) in [0,1]².
fn screen_coordinates(eye: DVec3, point: DVec3) -> (f64, f64) {
    let ll = DVec3::from(LL.map(f64::from));
    let lr = DVec3::from(LR.map(f64::from));
    let ur = DVec3::from(UR.map(f64::from));
    // The screen is the plane z = 0.
    let along = point - eye;
    let on_screen = eye + along * (-eye.z / along.z);
    let (x, y) = (lr - ll, ur - lr);
    (
        (on_screen - ll).dot(x) / x.length_squared(),
        (on_screen - ll).dot(y) / y.length_squared(),
    )
}

/// For surface points seen by the left eye, (left colour, right colour) of the same point:
/// the right eye's colour comes from a 1×1 frame whose pixel centre is that point's image.
fn colours_of_the_same_points(
    dev: ANARIDevice,
    world: ANARIWorld,
    renderer: ANARIRenderer,
    object: u32,
) -> Vec<([f32; 4], [f32; 4])> {
    let head = DVec3::from(HEAD.map(f64::from));
    let half = DVec3::X * (IPD / 2.0);
    let (left_eye, right_eye) = (head - half, head + half);
    let camera = off_axis(dev, "left", HEAD);
    let left = render(dev, world, camera, renderer, [SIZE, SIZE]);
    anariRelease(dev, camera);
    let mut pairs = Vec::new();
    for y in (1..SIZE).step_by(3) {
        for x in (1..SIZE).step_by(3) {
            let i = (y * SIZE + x) as usize;
            if left.object[i] != object {
                continue;
            }
            // The hit point from the pixel's ray and its depth (distance from the eye).
            let (s, t) = (
                (f64::from(x) + 0.5) / f64::from(SIZE),
                (f64::from(y) + 0.5) / f64::from(SIZE),
            );
            let ll = DVec3::from(LL.map(f64::from));
            let screen_point = ll + s * DVec3::new(1.6, 0.0, 0.0) + t * DVec3::new(0.0, 1.2, 0.0);
            let depth = f64::from(f32::from_bits(left.depth[i]));
            let point = left_eye + (screen_point - left_eye).normalize() * depth;
            let (s, t) = screen_coordinates(right_eye, point);
            let half_pixel = 1e-4;
            let camera = off_axis(dev, "right", HEAD);
            let region = [
                s - half_pixel,
                t - half_pixel,
                s + half_pixel,
                t + half_pixel,
            ]
            .map(|v| v as f32);
            set(dev, camera, "imageRegion", ANARI_FLOAT32_BOX2, &region);
            commit(dev, camera);
            let right = render(dev, world, camera, renderer, [1, 1]);
            anariRelease(dev, camera);
            if right.object[0] == object {
                pairs.push((left.color[i], right.color[0]));
            }
        }
    }
    assert!(pairs.len() >= 10, "only {} points compared", pairs.len());
    pairs
}

fn largest_difference(pairs: &[([f32; 4], [f32; 4])]) -> f32 {
    pairs
        .iter()
        .flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs()))
        .fold(0.0, f32::max)
}

#[test]
fn cyclopean_lighting_gives_both_eyes_one_colour_per_surface_point() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // A sphere close to the eyes (so the eyes' directions differ most) in front of a floor
    // with a colour gradient for the mirror to reflect.
    let ball = sphere_geometry(dev, &[[0.0, 0.0, 0.4]], 0.3);
    let floor = triangle_geometry(
        dev,
        &[
            [-1.0, -0.4, 1.5],
            [1.0, -0.4, 1.5],
            [1.0, -0.4, -1.0],
            [-1.0, -0.4, 1.5],
            [1.0, -0.4, -1.0],
            [-1.0, -0.4, -1.0],
        ],
    );
    let colors: [[f32; 3]; 6] = [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 0.0],
    ];
    set_array(dev, floor, "vertex.color", ANARI_FLOAT32_VEC3, &colors);
    commit(dev, floor);
    let floor_material = matte_colored_by(dev, "color");
    let floor_surface = surface(dev, floor, floor_material, 2);
    let light = anariNewLight(dev, c("directional").as_ptr());
    set(
        dev,
        light,
        "direction",
        ANARI_FLOAT32_VEC3,
        &[0.2f32, -1.0, -0.3],
    );
    commit(dev, light);
    let lights = object_array(dev, ANARI_LIGHT, &[light]);
    for (renderer_type, metallic, roughness) in [
        ("fast", 0.0, 1.0),
        ("default", 1.0, 0.0),
        ("default", 1.0, 0.4),
    ] {
        let ball_material = material(dev, [0.8, 0.8, 0.8], metallic, roughness);
        let ball_surface = surface(dev, ball, ball_material, 1);
        let world = world_of(dev, &[ball_surface, floor_surface]);
        set_object(dev, world, "light", ANARI_ARRAY1D, lights);
        commit(dev, world);
        let what = format!("{renderer_type} renderer, metallic {metallic}, roughness {roughness}");
        let mut differences = Vec::new();
        for lighting in ["cyclopean", "perEye"] {
            let renderer = anariNewRenderer(dev, c(renderer_type).as_ptr());
            set_string(dev, renderer, "stereoLighting", lighting);
            commit(dev, renderer);
            differences.push(largest_difference(&colours_of_the_same_points(
                dev, world, renderer, 1,
            )));
            anariRelease(dev, renderer);
        }
        // One point, one colour under cyclopean lighting; two views of it otherwise.
        assert!(
            differences[0] <= 1.0 / 255.0,
            "{what}: cyclopean {differences:?}"
        );
        assert!(
            differences[1] > 2.0 / 255.0,
            "{what}: perEye {differences:?}"
        );
        release_all(dev, &[ball_material, ball_surface, world]);
    }

    // Mono frames do not depend on the parameter.
    let ball_material = material(dev, [0.8, 0.8, 0.8], 1.0, 0.2);
    let ball_surface = surface(dev, ball, ball_material, 1);
    let world = world_of(dev, &[ball_surface, floor_surface]);
    set_object(dev, world, "light", ANARI_ARRAY1D, lights);
    commit(dev, world);
    for renderer_type in ["fast", "default"] {
        let mut images = Vec::new();
        for lighting in ["cyclopean", "perEye"] {
            let renderer = anariNewRenderer(dev, c(renderer_type).as_ptr());
            set_string(dev, renderer, "stereoLighting", lighting);
            commit(dev, renderer);
            let camera = off_axis(dev, "none", HEAD);
            images.push(render(dev, world, camera, renderer, [SIZE, SIZE]).color);
            release_all(dev, &[camera, renderer]);
        }
        assert_eq!(images[0], images[1], "{renderer_type} mono");
    }

    // A value that is neither is reported, naming the parameter.
    let renderer = anariNewRenderer(dev, c("fast").as_ptr());
    set_string(dev, renderer, "stereoLighting", "bothEyes");
    commit(dev, renderer);
    assert!(
        log.errors()
            .iter()
            .any(|e| e.1.contains("'stereoLighting'") && e.1.contains("bothEyes")),
        "{:?}",
        log.errors()
    );
    release_all(
        dev,
        &[renderer, ball_material, ball_surface, world, lights, light],
    );
    release_all(dev, &[ball, floor, floor_material, floor_surface]);
    release_device(lib, dev);
}

#[test]
fn interleaved_pixels_are_the_eye_images_pixels() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = mixed_world(dev);
    let renderer = plain_renderer(dev, "default");
    let camera_of = |camera_type: &str, mode: &str, right_first: bool| {
        let camera = stereo_camera(dev, camera_type, mode);
        set(
            dev,
            camera,
            "interleaveStartRight",
            ANARI_BOOL,
            &u8::from(right_first),
        );
        commit(dev, camera);
        camera
    };
    for camera_type in STEREO_CAMERAS {
        let alone = |eye: &str| {
            let camera = camera_of(camera_type, eye, false);
            let image = render(dev, world, camera, renderer, [SIZE, SIZE]);
            anariRelease(dev, camera);
            image
        };
        let eyes = [alone("left"), alone("right")];
        for (mode, parity) in [
            ("rowInterleaved", (|_, y| y) as fn(u32, u32) -> u32),
            ("columnInterleaved", |x, _| x),
            ("checkerboard", |x, y| x + y),
        ] {
            for right_first in [false, true] {
                let camera = camera_of(camera_type, mode, right_first);
                let image = render(dev, world, camera, renderer, [SIZE, SIZE]);
                anariRelease(dev, camera);
                let mut from = [0; 2];
                for y in 0..SIZE {
                    for x in 0..SIZE {
                        // Even parity is the left eye's unless the right eye comes first.
                        let eye = ((parity(x, y) % 2) ^ u32::from(right_first)) as usize;
                        from[eye] += 1;
                        let i = (y * SIZE + x) as usize;
                        let expected = &eyes[eye];
                        let at = format!(
                            "{camera_type} {mode} right first {right_first}, pixel {x},{y}"
                        );
                        assert_eq!(
                            image.primitive[i], expected.primitive[i],
                            "{at}: primitiveId"
                        );
                        assert_eq!(image.object[i], expected.object[i], "{at}: objectId");
                        assert_eq!(image.depth[i], expected.depth[i], "{at}: depth");
                        assert_eq!(
                            image.window_depth[i], expected.window_depth[i],
                            "{at}: windowDepth"
                        );
                        assert_eq!(image.parallax[i], expected.parallax[i], "{at}: parallax");
                        assert_eq!(image.color[i], expected.color[i], "{at}: colour");
                    }
                }
                assert_eq!(from, [SIZE * SIZE / 2; 2]);
            }
        }
    }
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_all(dev, &[renderer, world]);
    release_device(lib, dev);
}

#[test]
fn anaglyph_combines_both_eyes_by_the_dubois_matrices() {
    // Dubois' least-squares red-cyan matrices (rows: output red, green, blue) on linear RGB.
    const LEFT: [[f32; 3]; 3] = [
        [0.437, 0.449, 0.164],
        [-0.062, -0.062, -0.024],
        [-0.048, -0.050, -0.017],
    ];
    const RIGHT: [[f32; 3]; 3] = [
        [-0.011, -0.032, -0.007],
        [0.377, 0.761, 0.009],
        [-0.026, -0.093, 1.234],
    ];
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = mixed_world(dev);
    for renderer_type in ["fast", "default"] {
        let renderer = plain_renderer(dev, renderer_type);
        let image = |mode: &str| {
            let camera = off_axis(dev, mode, HEAD);
            let image = render(dev, world, camera, renderer, [SIZE, SIZE]);
            anariRelease(dev, camera);
            image
        };
        let (left, right, combined) = (image("left"), image("right"), image("anaglyph"));
        let mut differing = 0;
        for i in 0..(SIZE * SIZE) as usize {
            let at = format!("{renderer_type}, pixel {i}");
            // The channels other than colour are the left eye's.
            assert_eq!(combined.primitive[i], left.primitive[i], "{at}");
            assert_eq!(combined.depth[i], left.depth[i], "{at}");
            assert_eq!(combined.parallax[i], left.parallax[i], "{at}");
            let (l, r) = (left.color[i], right.color[i]);
            for k in 0..3 {
                let expected = (0..3)
                    .map(|j| LEFT[k][j] * l[j] + RIGHT[k][j] * r[j])
                    .sum::<f32>()
                    .clamp(0.0, 1.0);
                assert!(
                    (combined.color[i][k] - expected).abs() < 1e-6,
                    "{at}: channel {k}: {} vs {expected}",
                    combined.color[i][k]
                );
            }
            differing += usize::from(l != r);
        }
        // The eyes differ, so the right eye's part is checked too.
        assert!(
            differing > 100,
            "{renderer_type}: {differing} pixels differ between the eyes"
        );
        anariRelease(dev, renderer);
    }
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    anariRelease(dev, world);
    release_device(lib, dev);
}
