//! The block pipeline (rays made a block at a time, packet traversal, the fast renderer's lean
//! shading, hit records per tile) against the plain per-pixel path (each ray made alone, traced
//! alone, shaded by the general primary shading): every channel byte for byte (colour alone,
//! colour and depth, every channel), on triangles, quads, spheres, a tube, an instance, a
//! volume and a mirror, mono, stereo (side by side, interleaved, anaglyph), several viewers and
//! the light-field camera, both renderers.

mod common;
use common::*;

use std::sync::Mutex;
use std::sync::atomic::Ordering;

use cavetrace::render::frame::PLAIN_PER_PIXEL_PATH;

/// Not a multiple of the 8×8 blocks or the 32×32 tiles: whole and partial blocks both.
const SIZE: [u32; 2] = [76, 58];

/// Every channel the device has, as (name, type).
const CHANNELS: [(&str, ANARIDataType); 9] = [
    ("channel.color", ANARI_FLOAT32_VEC4),
    ("channel.depth", ANARI_FLOAT32),
    ("channel.windowDepth", ANARI_FLOAT32),
    ("channel.primitiveId", ANARI_UINT32),
    ("channel.objectId", ANARI_UINT32),
    ("channel.instanceId", ANARI_UINT32),
    ("channel.normal", ANARI_FLOAT32_VEC3),
    ("channel.albedo", ANARI_FLOAT32_VEC3),
    ("channel.parallax", ANARI_FLOAT32),
];

/// Held while a frame renders with [`PLAIN_PER_PIXEL_PATH`] set for it.
static RENDERING: Mutex<()> = Mutex::new(());

/// Each channel's bytes of one render, through the block pipeline or the plain path.
fn render(
    dev: ANARIDevice,
    world: ANARIWorld,
    camera: ANARICamera,
    renderer: &str,
    channels: &[(&str, ANARIDataType)],
    plain: bool,
    background: Option<ANARIArray2D>,
) -> Vec<Vec<u8>> {
    let renderer = anariNewRenderer(dev, c(renderer).as_ptr());
    if let Some(image) = background {
        set_object(dev, renderer, "background", ANARI_ARRAY2D, image);
    }
    commit(dev, renderer);
    let frame = anariNewFrame(dev);
    set(dev, frame, "size", ANARI_UINT32_VEC2, &SIZE);
    for (name, data_type) in channels {
        set(dev, frame, name, ANARI_DATA_TYPE, data_type);
    }
    set_object(dev, frame, "world", ANARI_WORLD, world);
    set_object(dev, frame, "camera", ANARI_CAMERA, camera);
    set_object(dev, frame, "renderer", ANARI_RENDERER, renderer);
    commit(dev, frame);
    // The switch is the process's: the tests of this file render in turn, else one test's
    // pipeline frame could start while another has the plain path switched on (and compare
    // the plain path with itself).
    let one_at_a_time = RENDERING
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    PLAIN_PER_PIXEL_PATH.store(plain, Ordering::SeqCst);
    render_and_wait(dev, frame);
    PLAIN_PER_PIXEL_PATH.store(false, Ordering::SeqCst);
    drop(one_at_a_time);
    let bytes = channels
        .iter()
        .map(|(name, _)| read_channel::<u8>(dev, frame, name).0)
        .collect();
    release_all(dev, &[renderer, frame]);
    bytes
}

/// Asserts that the block pipeline's channels equal the plain path's byte for byte, and that
/// the scene was seen (some pixel hit something).
fn assert_same(dev: ANARIDevice, world: ANARIWorld, camera: ANARICamera, what: &str) {
    assert_same_with(dev, world, camera, None, what);
}

/// [`assert_same`] with a background image on the renderers when `background` is given.
fn assert_same_with(
    dev: ANARIDevice,
    world: ANARIWorld,
    camera: ANARICamera,
    background: Option<ANARIArray2D>,
    what: &str,
) {
    for renderer in ["fast", "default"] {
        // Colour alone takes the fast renderer's colour-only path; colour and depth (what a VR
        // application asks for) records depth alone; every channel records them all.
        for channels in [&CHANNELS[..1], &CHANNELS[..2], &CHANNELS[..]] {
            let pipeline = render(dev, world, camera, renderer, channels, false, background);
            let plain = render(dev, world, camera, renderer, channels, true, background);
            for (k, (name, _)) in channels.iter().enumerate() {
                let first_difference = pipeline[k].iter().zip(&plain[k]).position(|(a, b)| a != b);
                assert_eq!(
                    first_difference,
                    None,
                    "{what}, {renderer} renderer, {name} ({} channels): first differing byte",
                    channels.len()
                );
                assert_eq!(pipeline[k].len(), plain[k].len(), "{what} {name}");
            }
            if channels.len() == CHANNELS.len() {
                let ids = &pipeline[3];
                assert!(
                    ids.chunks_exact(4).any(|id| id != [0xff; 4]),
                    "{what}: nothing hit"
                );
            }
        }
    }
}

fn off_axis(dev: ANARIDevice, stereo: &str) -> ANARICamera {
    let camera = anariNewCamera(dev, c("offAxis").as_ptr());
    set(
        dev,
        camera,
        "screen.lowerLeft",
        ANARI_FLOAT32_VEC3,
        &[-0.8f32, -0.6, 0.0],
    );
    set(
        dev,
        camera,
        "screen.lowerRight",
        ANARI_FLOAT32_VEC3,
        &[0.8f32, -0.6, 0.0],
    );
    set(
        dev,
        camera,
        "screen.upperRight",
        ANARI_FLOAT32_VEC3,
        &[0.8f32, 0.6, 0.0],
    );
    set(
        dev,
        camera,
        "position",
        ANARI_FLOAT32_VEC3,
        &[0.05f32, 0.02, 1.5],
    );
    set(dev, camera, "near", ANARI_FLOAT32, &0.05f32);
    set_string(dev, camera, "stereoMode", stereo);
    commit(dev, camera);
    camera
}

/// Two viewers in front of the screen of [`off_axis`], blended `mode`, in `stereo` mode.
fn viewers(dev: ANARIDevice, mode: &str, stereo: &str) -> ANARICamera {
    let camera = off_axis(dev, stereo);
    let arrays = [
        ("viewer.position", [[-0.3f32, 0.1, 1.4], [0.4, -0.05, 1.6]]),
        ("viewer.direction", [[0.2f32, 0.0, -1.0], [-0.3, 0.1, -1.0]]),
        ("viewer.right", [[1.0f32, 0.0, 0.0], [0.95, 0.0, 0.3]]),
    ];
    for (name, values) in arrays {
        let array = array1d(dev, ANARI_FLOAT32_VEC3, &values);
        set_object(dev, camera, name, ANARI_ARRAY1D, array);
        anariRelease(dev, array);
    }
    set_string(dev, camera, "viewerMode", mode);
    set(dev, camera, "viewerCutoffAngle", ANARI_FLOAT32, &0.5f32);
    set(dev, camera, "viewerTiles", ANARI_UINT32_VEC2, &[5u32, 4]);
    commit(dev, camera);
    camera
}

/// The light-field camera of [`light_field`] with `views` snapped views and every flip of
/// the calibration (the block's subpixel rays then take their eyes from the views' table).
fn light_field_flipped(dev: ANARIDevice, views: u32) -> ANARICamera {
    let camera = light_field(dev);
    set(dev, camera, "views", ANARI_UINT32, &views);
    for flip in ["invView", "flipImageX", "flipImageY", "flipSubpixels"] {
        set(dev, camera, flip, ANARI_BOOL, &1u8);
    }
    commit(dev, camera);
    camera
}

fn light_field(dev: ANARIDevice) -> ANARICamera {
    let camera = anariNewCamera(dev, c("lightField").as_ptr());
    set(
        dev,
        camera,
        "screen.lowerLeft",
        ANARI_FLOAT32_VEC3,
        &[-0.8f32, -0.6, 0.0],
    );
    set(
        dev,
        camera,
        "screen.lowerRight",
        ANARI_FLOAT32_VEC3,
        &[0.8f32, -0.6, 0.0],
    );
    set(
        dev,
        camera,
        "screen.upperRight",
        ANARI_FLOAT32_VEC3,
        &[0.8f32, 0.6, 0.0],
    );
    for (name, value) in [
        ("pitch", 49.82f32),
        ("slope", 5.04),
        ("center", 0.177),
        ("dpi", 338.0),
        ("viewCone", 40.0),
        ("viewingDistance", 1.5),
    ] {
        set(dev, camera, name, ANARI_FLOAT32, &value);
    }
    commit(dev, camera);
    camera
}

/// Every camera of the test, by name.
fn cameras(dev: ANARIDevice) -> Vec<(&'static str, ANARICamera)> {
    let perspective = perspective_camera(dev, [0.05, 0.02, 1.5], [0.0, 0.0, -1.0], 0.8);
    let mut cameras = vec![
        ("perspective", perspective),
        ("offAxis mono", off_axis(dev, "none")),
    ];
    for stereo in [
        "sideBySide",
        "rowInterleaved",
        "columnInterleaved",
        "checkerboard",
        "anaglyph",
    ] {
        cameras.push((stereo, off_axis(dev, stereo)));
    }
    cameras.push(("two viewers, perPixel", viewers(dev, "perPixel", "none")));
    cameras.push(("two viewers, tiles", viewers(dev, "tiles", "none")));
    cameras.push(("two viewers, zones", viewers(dev, "zones", "none")));
    // Interleaved eyes of blended cameras: rays made four at a time into half packets.
    for (name, stereo) in [
        ("two viewers, perPixel, rowInterleaved", "rowInterleaved"),
        ("two viewers, perPixel, checkerboard", "checkerboard"),
    ] {
        cameras.push((name, viewers(dev, "perPixel", stereo)));
    }
    cameras.push((
        "two viewers, perPixel, sideBySide",
        viewers(dev, "perPixel", "sideBySide"),
    ));
    cameras.push(("light field", light_field(dev)));
    cameras.push((
        "light field, 45 views, flipped",
        light_field_flipped(dev, 45),
    ));
    cameras
}

#[test]
fn block_pipeline_channels_equal_the_plain_per_pixel_path() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let with_volume = mixed_world(dev);
    // The same scene without its volume: the fast renderer's lean shading applies only there.
    let without_volume = mixed_world(dev);
    anariUnsetParameter(dev, without_volume, c("volume").as_ptr());
    commit(dev, without_volume);
    let cameras = cameras(dev);
    for (name, camera) in &cameras {
        assert_same(dev, without_volume, *camera, &format!("{name}, no volume"));
        assert_same(dev, with_volume, *camera, &format!("{name}, with a volume"));
    }
    assert_eq!(log.errors(), vec![]);
    for (_, camera) in cameras {
        anariRelease(dev, camera);
    }
    release_all(dev, &[with_volume, without_volume]);
    release_device(lib, dev);
}

/// A bumpy mesh coloured per vertex with vertex normals (shaded per hit) beside a plain quad
/// (shaded from its constant colour), meeting inside blocks, under a background image: the
/// fast renderer's block shading mixes both kinds of surface and misses in one block.
fn coloured_smooth_world(dev: ANARIDevice) -> ANARIWorld {
    let grid = 6;
    let vertex = |i: u32, j: u32| {
        let (x, y) = (
            -0.8 + 1.2 * i as f32 / grid as f32,
            -0.5 + j as f32 / grid as f32,
        );
        [x, y, -0.6 + 0.1 * (7.0 * x).sin() * (5.0 * y).cos()]
    };
    let mut positions = Vec::new();
    for j in 0..grid {
        for i in 0..grid {
            let [a, b, c, d] =
                [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)].map(|(i, j)| vertex(i, j));
            positions.extend([a, b, d, a, d, c]);
        }
    }
    let colors: Vec<[f32; 3]> = positions
        .iter()
        .map(|p| [0.5 + 0.5 * p[0], 0.5 + 0.5 * p[1], 0.3])
        .collect();
    let normals: Vec<[f32; 3]> = positions
        .iter()
        .map(|p| {
            let n = [0.3 * (3.0 * p[0]).sin(), 0.2 * p[1], 1.0];
            let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            n.map(|v| v / length)
        })
        .collect();
    let mesh = triangle_geometry(dev, &positions);
    set_array(dev, mesh, "vertex.color", ANARI_FLOAT32_VEC3, &colors);
    set_array(dev, mesh, "vertex.normal", ANARI_FLOAT32_VEC3, &normals);
    commit(dev, mesh);
    let coloured = matte_colored_by(dev, "color");
    let quad = geometry_with(dev, "quad", |g| {
        let corners = [
            [0.3f32, -0.3, -0.4],
            [0.7, -0.3, -0.4],
            [0.7, 0.3, -0.4],
            [0.3, 0.3, -0.4],
        ];
        set_array(dev, g, "vertex.position", ANARI_FLOAT32_VEC3, &corners);
    });
    let plain = material(dev, [0.2, 0.6, 0.9], 0.0, 1.0);
    let surfaces = [
        surface(dev, mesh, coloured, 1),
        surface(dev, quad, plain, 2),
    ];
    let world = world_of(dev, &surfaces);
    release_all(
        dev,
        &[mesh, quad, coloured, plain, surfaces[0], surfaces[1]],
    );
    world
}

#[test]
fn block_pipeline_equals_the_plain_path_on_coloured_smooth_surfaces_under_a_background_image() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = coloured_smooth_world(dev);
    let image = array2d(
        dev,
        ANARI_FLOAT32_VEC4,
        &[
            [1.0f32, 0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0, 1.0],
            [1.0, 1.0, 1.0, 0.5],
        ],
        [2, 2],
    );
    let cameras = [
        (
            "perspective",
            perspective_camera(dev, [0.05, 0.02, 1.5], [0.0, 0.0, -1.0], 0.8),
        ),
        ("sideBySide", off_axis(dev, "sideBySide")),
    ];
    for (name, camera) in cameras {
        assert_same_with(dev, world, camera, None, &format!("{name}, coloured mesh"));
        let what = format!("{name}, coloured mesh, background image");
        assert_same_with(dev, world, camera, Some(image), &what);
        anariRelease(dev, camera);
    }
    assert_eq!(log.errors(), vec![]);
    release_all(dev, &[world, image]);
    release_device(lib, dev);
}
