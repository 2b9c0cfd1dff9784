//! Several tracked viewers on the offAxis camera, through the device: a grid lying on the
//! screen is seen where each pixel is in every mode and eye, one viewer renders today's image
//! bit for bit, and bad viewer parameters are reported at commit.
mod common;
use common::*;

const SIZE: [u32; 2] = [64, 48];

/// The front wall of a 3 m CAVE (floor at y = 0).
const LL: [f32; 3] = [-1.5, 0.0, -1.5];
const LR: [f32; 3] = [1.5, 0.0, -1.5];
const UR: [f32; 3] = [1.5, 3.0, -1.5];
const HEAD: [f32; 3] = [0.45, 1.62, 0.3];

/// Cells of the grid on the wall, across and up.
const CELLS: u32 = 6;

/// A grid of CELLS×CELLS squares lying in the wall's plane, two triangles each: square (i, j)
/// holds primitives 2(j·CELLS + i) (below its rising diagonal) and 2(j·CELLS + i) + 1.
fn wall_grid() -> Vec<[f32; 3]> {
    let mut positions = Vec::new();
    let corner = |s: f32, t: f32| [LL[0] + 3.0 * s, LL[1] + 3.0 * t, LL[2]];
    let step = 1.0 / CELLS as f32;
    for j in 0..CELLS {
        for i in 0..CELLS {
            let (s, t) = (i as f32 * step, j as f32 * step);
            let (a, b) = (corner(s, t), corner(s + step, t));
            let (c, d) = (corner(s + step, t + step), corner(s, t + step));
            positions.extend([a, b, c, a, c, d]);
        }
    }
    positions
}

/// The primitive a pixel centre (s, t) of the screen sees on the grid; `None` within `margin`
/// of a cell edge or diagonal.
fn grid_primitive(s: f64, t: f64, margin: f64) -> Option<u32> {
    let (u, v) = (s * f64::from(CELLS), t * f64::from(CELLS));
    let (i, j) = (u.floor(), v.floor());
    let (a, b) = (u - i, v - j);
    if a.min(b).min(1.0 - a).min(1.0 - b) < margin || (a - b).abs() < margin {
        return None;
    }
    let cell = j as u32 * CELLS + i as u32;
    Some(2 * cell + u32::from(b > a))
}

/// The grid, plus triangles in front of and behind the wall at several depths.
fn world(dev: ANARIDevice, with_depth: bool) -> ANARIWorld {
    let mut positions = wall_grid();
    if with_depth {
        for k in 0..10 {
            let x = -1.2 + 0.25 * k as f32;
            let y = 0.4 + 0.2 * k as f32;
            let z = -0.4 - 0.4 * k as f32;
            positions.extend([[x, y, z], [x + 0.6, y, z], [x + 0.2, y + 0.7, z - 0.1]]);
        }
    }
    let colors: Vec<[f32; 4]> = (0..positions.len())
        .map(|i| {
            let k = (i / 3) as f32;
            [(k * 0.37) % 1.0, (k * 0.61) % 1.0, (k * 0.23) % 1.0, 1.0]
        })
        .collect();
    let geometry = triangle_geometry(dev, &positions);
    let col = array1d(dev, ANARI_FLOAT32_VEC4, &colors);
    set_object(dev, geometry, "vertex.color", ANARI_ARRAY1D, col);
    commit(dev, geometry);
    let material = matte_colored_by(dev, "color");
    let surface = surface_of(dev, geometry, material);
    let world = world_of(dev, &[surface]);
    release_all(dev, &[geometry, col, material, surface]);
    world
}

/// Viewers: head position, gaze target on the wall (in screen units), right vector.
type Viewer = ([f32; 3], [f32; 2], [f32; 3]);

fn viewers_two() -> Vec<Viewer> {
    vec![
        ([-0.4, 1.7, 0.2], [0.25, 0.6], [1.0, 0.0, 0.0]),
        ([0.5, 1.6, 0.4], [0.8, 0.4], [0.9, 0.0, 0.3]),
    ]
}

fn off_axis(dev: ANARIDevice, stereo: &str) -> ANARICamera {
    let camera = anariNewCamera(dev, c("offAxis").as_ptr());
    set(dev, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, &LL);
    set(dev, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, &LR);
    set(dev, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, &UR);
    set(dev, camera, "near", ANARI_FLOAT32, &0.05f32);
    set_string(dev, camera, "stereoMode", stereo);
    camera
}

fn set_viewers(dev: ANARIDevice, camera: ANARICamera, viewers: &[Viewer], mode: &str) {
    let heads: Vec<[f32; 3]> = viewers.iter().map(|v| v.0).collect();
    let gazes: Vec<[f32; 3]> = viewers
        .iter()
        .map(|(head, [s, t], _)| {
            let target = [LL[0] + 3.0 * s, LL[1] + 3.0 * t, LL[2]];
            [
                target[0] - head[0],
                target[1] - head[1],
                target[2] - head[2],
            ]
        })
        .collect();
    let rights: Vec<[f32; 3]> = viewers.iter().map(|v| v.2).collect();
    let arrays = [
        ("viewer.position", array1d(dev, ANARI_FLOAT32_VEC3, &heads)),
        ("viewer.direction", array1d(dev, ANARI_FLOAT32_VEC3, &gazes)),
        ("viewer.right", array1d(dev, ANARI_FLOAT32_VEC3, &rights)),
    ];
    for (name, array) in arrays {
        set_object(dev, camera, name, ANARI_ARRAY1D, array);
        anariRelease(dev, array);
    }
    set_string(dev, camera, "viewerMode", mode);
    set(dev, camera, "viewerCutoffAngle", ANARI_FLOAT32, &0.5f32);
    set(dev, camera, "viewerTiles", ANARI_UINT32_VEC2, &[5u32, 4]);
}

struct Rendered {
    ids: Vec<u32>,
    depth: Vec<f32>,
    window_depth: Vec<f32>,
    color: Vec<[f32; 4]>,
}

fn render(dev: ANARIDevice, world: ANARIWorld, camera: ANARICamera, renderer: &str) -> Rendered {
    let renderer = plain_renderer(dev, renderer);
    let frame = frame_for(dev, world, camera, renderer, SIZE);
    add_channel(dev, frame, "channel.depth", ANARI_FLOAT32);
    add_channel(dev, frame, "channel.windowDepth", ANARI_FLOAT32);
    let (ids, w, h) = render_channel::<u32>(dev, frame, "channel.primitiveId");
    assert_eq!([w, h], SIZE);
    let depth = read_channel::<f32>(dev, frame, "channel.depth").0;
    let window_depth = read_channel::<f32>(dev, frame, "channel.windowDepth").0;
    let color = read_channel::<[f32; 4]>(dev, frame, "channel.color").0;
    anariRelease(dev, frame);
    anariRelease(dev, renderer);
    Rendered {
        ids,
        depth,
        window_depth,
        color,
    }
}

/// Pixel `(x, y)` of the frame as (s, t) on the screen, for the eye viewport it lies in.
fn screen_coordinates(stereo: &str, x: u32, y: u32) -> (f64, f64) {
    let [w, h] = SIZE;
    let (x, width) = match stereo {
        "sideBySide" if x >= w / 2 => (x - w / 2, w - w / 2),
        "sideBySide" => (x, w / 2),
        _ => (x, w),
    };
    (
        (f64::from(x) + 0.5) / f64::from(width),
        (f64::from(y) + 0.5) / f64::from(h),
    )
}

#[test]
fn the_wall_grid_is_seen_where_each_pixel_is_for_every_mode_and_eye() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = world(dev, false);
    let mut viewers = viewers_two();
    viewers.push(([0.0, 1.5, 0.9], [0.5, 0.2], [1.0, 0.0, 0.0]));
    for mode in ["perPixel", "tiles", "zones"] {
        for stereo in ["none", "sideBySide"] {
            let camera = off_axis(dev, stereo);
            set_viewers(dev, camera, &viewers, mode);
            commit(dev, camera);
            let r = render(dev, world, camera, "fast");
            let mut checked = 0;
            for y in 0..SIZE[1] {
                for x in 0..SIZE[0] {
                    let (s, t) = screen_coordinates(stereo, x, y);
                    if let Some(expected) = grid_primitive(s, t, 0.02) {
                        let got = r.ids[(y * SIZE[0] + x) as usize];
                        assert_eq!(got, expected, "{mode} {stereo} pixel ({x}, {y})");
                        checked += 1;
                    }
                }
            }
            assert!(checked > (SIZE[0] * SIZE[1]) as usize / 2, "{checked}");
            anariRelease(dev, camera);
        }
    }
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    anariRelease(dev, world);
    release_device(lib, dev);
}

#[test]
fn one_viewer_renders_todays_image_bit_for_bit() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = world(dev, true);
    let gaze_target = [0.3f32, 0.55];
    for stereo in ["none", "sideBySide"] {
        let today = off_axis(dev, stereo);
        set(dev, today, "position", ANARI_FLOAT32_VEC3, &HEAD);
        commit(dev, today);
        for renderer in ["fast", "default"] {
            let expected = render(dev, world, today, renderer);
            assert!(expected.ids.iter().any(|id| *id >= 2 * CELLS * CELLS));
            for mode in ["perPixel", "tiles", "zones"] {
                let camera = off_axis(dev, stereo);
                set_viewers(dev, camera, &[(HEAD, gaze_target, [1.0, 0.0, 0.0])], mode);
                commit(dev, camera);
                let got = render(dev, world, camera, renderer);
                let what = format!("{stereo} {renderer} {mode}");
                assert_eq!(got.ids, expected.ids, "{what}");
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got.depth), bits(&expected.depth), "{what}");
                assert_eq!(
                    bits(&got.window_depth),
                    bits(&expected.window_depth),
                    "{what}"
                );
                let colors =
                    |v: &[[f32; 4]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(colors(&got.color), colors(&expected.color), "{what}");
                anariRelease(dev, camera);
            }
        }
        anariRelease(dev, today);
    }
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    anariRelease(dev, world);
    release_device(lib, dev);
}

#[test]
fn two_viewers_change_the_image_only_off_the_wall() {
    // Objects on the wall look the same to everyone; objects in front of or behind it are seen
    // from the blended positions, so their pixels move.
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = world(dev, true);
    let today = off_axis(dev, "none");
    set(
        dev,
        today,
        "position",
        ANARI_FLOAT32_VEC3,
        &viewers_two()[0].0,
    );
    commit(dev, today);
    let alone = render(dev, world, today, "fast");
    let camera = off_axis(dev, "none");
    set_viewers(dev, camera, &viewers_two(), "perPixel");
    commit(dev, camera);
    let shared = render(dev, world, camera, "fast");
    let on_wall = |id: u32| id < 2 * CELLS * CELLS;
    let mut differing_off_wall = 0;
    for (a, b) in alone.ids.iter().zip(&shared.ids) {
        if on_wall(*a) && on_wall(*b) {
            assert_eq!(a, b);
        } else {
            differing_off_wall += usize::from(a != b);
        }
    }
    assert!(differing_off_wall > 20, "{differing_off_wall}");
    anariRelease(dev, camera);
    anariRelease(dev, today);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    anariRelease(dev, world);
    release_device(lib, dev);
}

#[test]
fn bad_viewer_parameters_are_reported_at_commit_and_render_background() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = world(dev, false);
    // (parameter named in the message, how the camera is spoilt, what the message says)
    type Case = (&'static str, fn(ANARIDevice, ANARICamera), &'static str);
    let cases: [Case; 6] = [
        (
            "viewer.direction",
            |dev, camera| {
                let one = array1d(dev, ANARI_FLOAT32_VEC3, &[[0.0f32, 0.0, -1.0]]);
                set_object(dev, camera, "viewer.direction", ANARI_ARRAY1D, one);
                anariRelease(dev, one);
            },
            "has 1 elements but viewer.position has 2",
        ),
        (
            "viewer.position",
            |dev, camera| {
                let behind = array1d(
                    dev,
                    ANARI_FLOAT32_VEC3,
                    &[[0.0f32, 1.5, 0.2], [0.0, 1.5, -2.0]],
                );
                set_object(dev, camera, "viewer.position", ANARI_ARRAY1D, behind);
                anariRelease(dev, behind);
            },
            "viewer 1",
        ),
        (
            "viewer.direction",
            |dev, camera| {
                let zero = array1d(dev, ANARI_FLOAT32_VEC3, &[[0.0f32, 0.0, -1.0], [0.0; 3]]);
                set_object(dev, camera, "viewer.direction", ANARI_ARRAY1D, zero);
                anariRelease(dev, zero);
            },
            "viewer 1",
        ),
        (
            "viewerCutoffAngle",
            |dev, camera| set(dev, camera, "viewerCutoffAngle", ANARI_FLOAT32, &0.0f32),
            "(0, π]",
        ),
        (
            "viewerMode",
            |dev, camera| set_string(dev, camera, "viewerMode", "perTile"),
            "perPixel, tiles, zones",
        ),
        (
            "viewer.position",
            |dev, camera| {
                let scalars = array1d(dev, ANARI_FLOAT32, &[1.0f32, 2.0, 3.0]);
                set_object(dev, camera, "viewer.position", ANARI_ARRAY1D, scalars);
                anariRelease(dev, scalars);
            },
            "ARRAY1D of FLOAT32_VEC3",
        ),
    ];
    for (parameter, spoil, needle) in cases {
        let camera = off_axis(dev, "none");
        set_viewers(dev, camera, &viewers_two(), "perPixel");
        spoil(dev, camera);
        log.take();
        commit(dev, camera);
        let errors = log.errors();
        assert_eq!(errors.len(), 1, "{parameter}: {errors:?}");
        let message = &errors[0].1;
        assert!(
            message.contains(&format!("'{parameter}'")) && message.contains(needle),
            "{message}"
        );
        let r = render(dev, world, camera, "fast");
        assert!(r.ids.iter().all(|id| *id == u32::MAX), "{parameter}");
        anariRelease(dev, camera);
    }
    anariRelease(dev, world);
    release_device(lib, dev);
}
