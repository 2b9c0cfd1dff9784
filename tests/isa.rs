//! The ray kernels' instruction-set paths (device parameter `isa`): a frame rendered on the
//! AVX2 or AVX-512 path equals the baseline's bit for bit — a light-field frame (one single ray per
//! subpixel), a `default` frame with shadow rays and a mirror, and `fast` stereo frames (eyes
//! shaded from their cyclopean point) — and bad values are reported. On a scene of one triangle
//! mesh, and on one of several placements, the AVX2 and AVX-512 light-field frames trace their
//! subpixel rays eight at a time grouped by eye: the same frame again. A path the CPU lacks falls back to the widest it has
//! (with a warning), so every value renders.

mod common;
use cavetrace::isa::Isa;
use common::*;
use std::sync::{Mutex, MutexGuard};

/// The path is the process's and creating a device selects the environment's: the tests here
/// take turns, so that each renders on the path it selected.
fn one_at_a_time() -> MutexGuard<'static, ()> {
    static TURN: Mutex<()> = Mutex::new(());
    TURN.lock().unwrap_or_else(|e| e.into_inner())
}

/// Selects path `name` through the device parameter `isa` and checks that the kernels took it
/// (the widest narrower one where this CPU lacks it).
fn select_path(dev: ANARIDevice, name: &str) {
    set_string(dev, dev, "isa", name);
    commit(dev, dev);
    let wanted = Isa::usable(Isa::parse(name).expect("a path's name"));
    assert_eq!(cavetrace::isa::selected(), wanted, "isa {name}");
}

/// The corners of a 24×16 grid of squares at three depths, two triangles per square.
fn grid_triangles() -> Vec<[f32; 3]> {
    let mut triangles = Vec::new();
    for i in 0..24 {
        for j in 0..16 {
            let (x, y) = (-0.6 + 0.05 * i as f32, -0.4 + 0.05 * j as f32);
            let z = -0.1 * ((i + j) % 3) as f32;
            triangles.extend([[x, y, z], [x + 0.05, y, z], [x + 0.05, y + 0.05, z]]);
            triangles.extend([[x, y, z], [x + 0.05, y + 0.05, z], [x, y + 0.05, z]]);
        }
    }
    triangles
}

/// A grid of triangles, spheres in front of it and a mirror sphere, lit by a directional light.
fn world(dev: ANARIDevice) -> ANARIWorld {
    let grid = triangle_geometry(dev, &grid_triangles());
    let spheres = sphere_geometry(dev, &[[0.1, 0.05, 0.2], [-0.2, -0.1, 0.1]], 0.08);
    let mirror_ball = sphere_geometry(dev, &[[0.3, -0.2, 0.15]], 0.1);
    let mirror = anariNewMaterial(dev, c("physicallyBased").as_ptr());
    set(dev, mirror, "metallic", ANARI_FLOAT32, &1.0f32);
    set(dev, mirror, "roughness", ANARI_FLOAT32, &0.0f32);
    commit(dev, mirror);
    let mirror_surface = anariNewSurface(dev);
    set_object(dev, mirror_surface, "geometry", ANARI_GEOMETRY, mirror_ball);
    set_object(dev, mirror_surface, "material", ANARI_MATERIAL, mirror);
    commit(dev, mirror_surface);
    let surfaces = [
        matte_surface(dev, grid, [0.9, 0.7, 0.3]),
        matte_surface(dev, spheres, [0.2, 0.6, 0.9]),
        mirror_surface,
    ];
    let world = world_of(dev, &surfaces);
    light_world(dev, world, [-0.3f32, -0.4, -1.0]);
    release_all(dev, &[grid, spheres, mirror_ball, mirror]);
    release_all(dev, &surfaces);
    world
}

fn light_field_camera(dev: ANARIDevice) -> ANARICamera {
    let camera = anariNewCamera(dev, c("lightField").as_ptr());
    set(
        dev,
        camera,
        "screen.lowerLeft",
        ANARI_FLOAT32_VEC3,
        &[-0.3f32, -0.2, 0.0],
    );
    set(
        dev,
        camera,
        "screen.lowerRight",
        ANARI_FLOAT32_VEC3,
        &[0.3f32, -0.2, 0.0],
    );
    set(
        dev,
        camera,
        "screen.upperRight",
        ANARI_FLOAT32_VEC3,
        &[0.3f32, 0.2, 0.0],
    );
    set(dev, camera, "viewingDistance", ANARI_FLOAT32, &1.0f32);
    commit(dev, camera);
    camera
}

/// A perspective stereo camera in `mode` (both eyes in one frame), eyes 6.4 cm apart.
fn stereo_camera(dev: ANARIDevice, mode: &str) -> ANARICamera {
    let camera = perspective_camera(dev, [0.1, 0.2, 1.5], [-0.05, -0.1, -1.0], 0.6);
    set_string(dev, camera, "stereoMode", mode);
    set(
        dev,
        camera,
        "interpupillaryDistance",
        ANARI_FLOAT32,
        &0.064f32,
    );
    commit(dev, camera);
    camera
}

/// Every channel of a render, as bits.
/// Every channel of a frame rendered, as bits: colour, depth, object and instance ids, then
/// primitive ids (last).
fn render_bits(dev: ANARIDevice, frame: ANARIFrame) -> Vec<u32> {
    let (colors, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    let (depths, _, _) = read_channel::<f32>(dev, frame, "channel.depth");
    let (objects, _, _) = read_channel::<u32>(dev, frame, "channel.objectId");
    let (instances, _, _) = read_channel::<u32>(dev, frame, "channel.instanceId");
    let (ids, _, _) = read_channel::<u32>(dev, frame, "channel.primitiveId");
    let mut bits: Vec<u32> = colors.iter().flatten().map(|v| v.to_bits()).collect();
    bits.extend(depths.iter().map(|v| v.to_bits()));
    bits.extend(objects);
    bits.extend(instances);
    bits.extend(ids);
    bits
}

#[test]
fn every_path_renders_the_baselines_frame_bit_for_bit() {
    let _turn = one_at_a_time();
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = world(dev);
    let cameras = [
        (light_field_camera(dev), "fast"),
        (light_field_camera(dev), "default"),
        (
            perspective_camera(dev, [0.1, 0.2, 1.5], [-0.05, -0.1, -1.0], 0.6),
            "default",
        ),
        // Stereo eyes shaded from their cyclopean point: eight lanes per vector with AVX2 and
        // AVX-512.
        (stereo_camera(dev, "sideBySide"), "fast"),
        (stereo_camera(dev, "checkerboard"), "fast"),
    ];
    for (camera, renderer_type) in cameras {
        let renderer = plain_renderer(dev, renderer_type);
        let frame = frame_for(dev, world, camera, renderer, [96, 64]);
        let mut images = Vec::new();
        for isa in ["baseline", "avx2", "avx512", "auto"] {
            select_path(dev, isa);
            images.push((isa, render_bits(dev, frame)));
        }
        for (isa, image) in &images[1..] {
            let differing = image
                .iter()
                .zip(&images[0].1)
                .filter(|(a, b)| a != b)
                .count();
            assert_eq!(differing, 0, "{renderer_type}: {isa} against baseline");
        }
        release_all(dev, &[frame, renderer, camera]);
    }
    // Warnings for a path this CPU lacks are fine; nothing else is reported.
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    set_string(dev, dev, "isa", "sse9");
    commit(dev, dev);
    let errors = log.errors();
    assert!(
        errors
            .iter()
            .any(|(_, text)| text.contains("'isa'") && text.contains("sse9")),
        "{errors:?}"
    );
    anariRelease(dev, world);
    release_device(lib, dev);
}

/// The worlds of the light-field frames traced by eye.
#[derive(Clone, Copy, Debug)]
enum LightFieldWorld {
    /// The triangle grid of [`world`] alone, lit, as one surface of the world.
    Grid,
    /// The same in an instance with a transform.
    TurnedGrid,
    /// Several placements: the grid twice in one place in two colours (every hit a tie
    /// between surfaces, which the colour, object id and depth show), spheres before it, and
    /// the grid again in a turned instance.
    Several,
}

/// The grid scaled by 0.9, turned by 0.2 rad about z, moved 5 cm right and back.
fn turned_transform() -> [f32; 16] {
    glam::Mat4::from_scale_rotation_translation(
        glam::Vec3::splat(0.9),
        glam::Quat::from_rotation_z(0.2),
        glam::Vec3::new(0.05, 0.0, -0.05),
    )
    .to_cols_array()
}

/// A world of [`LightFieldWorld`] whose light-field subpixel rays the AVX2 and AVX-512 paths
/// trace eight at a time, grouped by eye.
fn light_field_world(dev: ANARIDevice, kind: LightFieldWorld) -> ANARIWorld {
    let grid = triangle_geometry(dev, &grid_triangles());
    let surface = matte_surface(dev, grid, [0.9, 0.7, 0.3]);
    let world = match kind {
        LightFieldWorld::Grid => world_of(dev, &[surface]),
        LightFieldWorld::TurnedGrid => instanced_world_of(dev, &[surface], turned_transform()),
        LightFieldWorld::Several => several_placements_world(dev, grid, surface),
    };
    light_world(dev, world, [-0.3f32, -0.4, -1.0]);
    release_all(dev, &[grid, surface]);
    world
}

/// [`LightFieldWorld::Several`] from the grid and its surface.
fn several_placements_world(
    dev: ANARIDevice,
    grid: ANARIGeometry,
    surface: ANARISurface,
) -> ANARIWorld {
    let twin = matte_surface(dev, grid, [0.3, 0.8, 0.4]);
    let spheres = sphere_geometry(dev, &[[0.1, 0.05, 0.2], [-0.2, -0.1, 0.1]], 0.08);
    let balls = matte_surface(dev, spheres, [0.2, 0.6, 0.9]);
    let turned = matte_surface(dev, grid, [0.8, 0.3, 0.6]);
    for (id, object) in [surface, twin, balls, turned].into_iter().enumerate() {
        set(dev, object, "id", ANARI_UINT32, &(id as u32 + 1));
        commit(dev, object);
    }
    let instances = [
        instance_of(
            dev,
            &[surface, twin, balls],
            glam::Mat4::IDENTITY.to_cols_array(),
            Some(7),
        ),
        instance_of(dev, &[turned], turned_transform(), Some(8)),
    ];
    let world = anariNewWorld(dev);
    let array = object_array(dev, ANARI_INSTANCE, &instances);
    set_object(dev, world, "instance", ANARI_ARRAY1D, array);
    commit(dev, world);
    release_all(dev, &[array, twin, spheres, balls, turned]);
    release_all(dev, &instances);
    world
}

#[test]
fn a_light_field_frame_traced_by_eye_is_the_baselines_frame() {
    let _turn = one_at_a_time();
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    for kind in [
        LightFieldWorld::Grid,
        LightFieldWorld::TurnedGrid,
        LightFieldWorld::Several,
    ] {
        let world = light_field_world(dev, kind);
        for (views, renderer_type) in [(0u32, "fast"), (45, "fast"), (0, "default")] {
            let camera = light_field_camera(dev);
            set(dev, camera, "views", ANARI_UINT32, &views);
            commit(dev, camera);
            let renderer = plain_renderer(dev, renderer_type);
            // Three tiles by two: whole tiles of whole 8×8 blocks (traced by eye), and partial
            // blocks at the right and top (traced ray by ray).
            let frame = frame_for(dev, world, camera, renderer, [84, 64]);
            let mut images = Vec::new();
            for isa in ["baseline", "avx2", "avx512"] {
                select_path(dev, isa);
                images.push(render_bits(dev, frame));
            }
            let differing = |k: usize| {
                images[k]
                    .iter()
                    .zip(&images[0])
                    .filter(|(a, b)| a != b)
                    .count()
            };
            let hits = images[0][images[0].len() - 84 * 64..]
                .iter()
                .filter(|id| **id != u32::MAX)
                .count();
            let what = format!("{renderer_type}, {views} views, {kind:?}");
            assert!(
                hits > 84 * 64 / 2,
                "{what}: only {hits} pixels hit the grid"
            );
            assert_eq!(differing(1), 0, "{what}: avx2 against baseline");
            assert_eq!(differing(2), 0, "{what}: avx512 against baseline");
            release_all(dev, &[frame, renderer, camera]);
        }
        anariRelease(dev, world);
    }
    set_string(dev, dev, "isa", "auto");
    commit(dev, dev);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}
