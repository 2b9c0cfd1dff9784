//! Frame-time budgets (`ANARI_CAVETRACE_FRAME_BUDGET`): a budgeted render traces an evenly
//! spread subset of the pixels and fills the rest from traced neighbours; renders of the
//! unchanged frame refine it until it equals the unbudgeted image in every channel.
mod common;
use common::*;

/// The front wall of a 3 m CAVE and a tracked head, as in the camera tests.
const LL: [f32; 3] = [-1.5, 0.0, -1.5];
const LR: [f32; 3] = [1.5, 0.0, -1.5];
const UR: [f32; 3] = [1.5, 3.0, -1.5];
const HEAD: [f32; 3] = [0.45, 1.62, 0.3];

/// Every channel a frame can produce, with its type and pixel size.
const CHANNELS: &[(&str, ANARIDataType, usize)] = &[
    ("channel.color", ANARI_FLOAT32_VEC4, 16),
    ("channel.depth", ANARI_FLOAT32, 4),
    ("channel.primitiveId", ANARI_UINT32, 4),
    ("channel.objectId", ANARI_UINT32, 4),
    ("channel.instanceId", ANARI_UINT32, 4),
    ("channel.albedo", ANARI_FLOAT32_VEC3, 12),
    ("channel.normal", ANARI_FLOAT32_VEC3, 12),
    ("channel.windowDepth", ANARI_FLOAT32, 4),
];

/// Triangles at several depths and a few spheres, lit by a directional light.
fn scene(dev: ANARIDevice) -> ANARIWorld {
    let mut positions = Vec::new();
    for k in 0..12 {
        let x = -1.2 + 0.22 * k as f32;
        let y = 0.4 + 0.19 * k as f32;
        let z = -0.6 - 0.35 * k as f32;
        positions.extend([[x, y, z], [x + 0.6, y, z], [x + 0.2, y + 0.7, z - 0.1]]);
    }
    let triangles = triangle_geometry(dev, &positions);
    let spheres = sphere_geometry(
        dev,
        &[[-0.8, 2.2, -1.0], [0.3, 0.9, -2.0], [0.9, 2.0, -0.4]],
        0.3,
    );
    let a = matte_surface(dev, triangles, [0.8, 0.5, 0.2]);
    let b = matte_surface(dev, spheres, [0.2, 0.6, 0.9]);
    set(dev, b, "id", ANARI_UINT32, &7u32);
    commit(dev, b);
    let world = world_of(dev, &[a, b]);
    light_world(dev, world, [-0.3f32, -1.0, -0.5]);
    release_all(dev, &[triangles, spheres, a, b]);
    world
}

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

/// A frame with every channel; `budget` seconds and `pixels` per render when given.
fn frame(
    dev: ANARIDevice,
    world: ANARIWorld,
    camera: ANARICamera,
    renderer: ANARIRenderer,
    size: [u32; 2],
    budget: Option<(f32, u32)>,
) -> ANARIFrame {
    let frame = frame_for(dev, world, camera, renderer, size);
    for &(name, ty, _) in CHANNELS {
        set(dev, frame, name, ANARI_DATA_TYPE, &ty);
    }
    if let Some((seconds, pixels)) = budget {
        set(dev, frame, "budget", ANARI_FLOAT32, &seconds);
        set(dev, frame, "budgetPixels", ANARI_UINT32, &pixels);
    }
    commit(dev, frame);
    frame
}

/// Every channel's bytes, in the order of [`CHANNELS`].
fn channels(dev: ANARIDevice, frame: ANARIFrame) -> Vec<Vec<u8>> {
    CHANNELS
        .iter()
        .map(|&(name, _, bytes)| {
            let (mut w, mut h, mut t) = (0u32, 0u32, 0);
            let name = c(name);
            let p = anariMapFrame(dev, frame, name.as_ptr(), &mut w, &mut h, &mut t) as *const u8;
            assert!(!p.is_null());
            // SAFETY: the mapped channel holds w×h pixels of `bytes` bytes while mapped.
            let pixels =
                unsafe { std::slice::from_raw_parts(p, (w * h) as usize * bytes) }.to_vec();
            anariUnmapFrame(dev, frame, name.as_ptr());
            pixels
        })
        .collect()
}

fn progress(dev: ANARIDevice, frame: ANARIFrame) -> f32 {
    let mut value = -1.0f32;
    let written = anariGetProperty(
        dev,
        frame,
        c("progress").as_ptr(),
        ANARI_FLOAT32,
        (&mut value as *mut f32).cast(),
        4,
        ANARI_WAIT,
    );
    assert_eq!(written, 1, "progress property");
    value
}

/// Renders until `progress` is 1; returns the progress after each render.
fn refine(dev: ANARIDevice, frame: ANARIFrame, most: usize) -> Vec<f32> {
    let mut seen = Vec::new();
    while seen.last() != Some(&1.0) {
        assert!(
            seen.len() < most,
            "not complete after {most} renders: {seen:?}"
        );
        render_and_wait(dev, frame);
        seen.push(progress(dev, frame));
    }
    seen
}

fn assert_same_channels(a: &[Vec<u8>], b: &[Vec<u8>], what: &str) {
    for ((name, _, _), (a, b)) in CHANNELS.iter().zip(a.iter().zip(b)) {
        assert!(a == b, "{what}: {name} differs");
    }
}

#[test]
fn a_converged_budgeted_frame_equals_the_unbudgeted_frame_in_every_channel() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let size = [70, 45];
    for renderer_type in ["fast", "default"] {
        for stereo in [
            "none",
            "sideBySide",
            "topBottom",
            "rowInterleaved",
            "checkerboard",
            "anaglyph",
        ] {
            let what = format!("{renderer_type} {stereo}");
            let camera = off_axis(dev, stereo, HEAD);
            let renderer = plain_renderer(dev, renderer_type);
            let plain = frame(dev, world, camera, renderer, size, None);
            render_and_wait(dev, plain);
            assert_eq!(progress(dev, plain), 1.0);
            let expected = channels(dev, plain);
            let budgeted = frame(dev, world, camera, renderer, size, Some((0.01, 300)));
            let steps = refine(dev, budgeted, 100);
            // 3150 pixels, about 300 more per render (whole units of up to 32×32 lattice
            // points), the first render at least one pixel per 16×16 block.
            assert!(steps.len() >= 5, "{what}: {steps:?}");
            assert!(steps.windows(2).all(|p| p[0] < p[1]), "{what}: {steps:?}");
            assert_same_channels(&channels(dev, budgeted), &expected, &what);
            // Nothing changed: a further render keeps the complete image.
            render_and_wait(dev, budgeted);
            assert_eq!(progress(dev, budgeted), 1.0);
            assert_same_channels(&channels(dev, budgeted), &expected, &what);
            release_all(dev, &[plain, budgeted, camera, renderer]);
        }
    }
    anariRelease(dev, world);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

/// The pixel an untraced pixel copies when only every 16th row and column is traced: per
/// axis the nearer traced line, the lower one on ties and where the upper one lies beyond
/// the frame.
fn corner_source(x: u32, y: u32, width: u32, height: u32) -> (u32, u32) {
    let near = |p: u32, extent: u32| {
        let (line, d) = (p - p % 16, p % 16);
        if d > 8 && line + 16 < extent {
            line + 16
        } else {
            line
        }
    };
    (near(x, width), near(y, height))
}

#[test]
fn a_partial_frame_copies_ids_and_depths_from_the_nearest_traced_pixel() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let size = [83, 51];
    let camera = off_axis(dev, "none", HEAD);
    let renderer = plain_renderer(dev, "fast");
    let plain = frame(dev, world, camera, renderer, size, None);
    render_and_wait(dev, plain);
    let expected = channels(dev, plain);
    // One pixel per render: only the mandatory coarsest level (every 16th row and column).
    let budgeted = frame(dev, world, camera, renderer, size, Some((0.01, 1)));
    render_and_wait(dev, budgeted);
    let blocks = 83u32.div_ceil(16) * 51u32.div_ceil(16);
    assert_eq!(progress(dev, budgeted), blocks as f32 / (83.0 * 51.0));
    let partial = channels(dev, budgeted);
    let mut differ = 0;
    for y in 0..51 {
        for x in 0..83 {
            let k = (y * 83 + x) as usize;
            let (sx, sy) = corner_source(x, y, 83, 51);
            let source = (sy * 83 + sx) as usize;
            for (channel, &(name, _, bytes)) in CHANNELS.iter().enumerate().skip(1) {
                // Every channel but colour is a copy of the source's exact value.
                assert_eq!(
                    partial[channel][k * bytes..(k + 1) * bytes],
                    expected[channel][source * bytes..(source + 1) * bytes],
                    "{name} at ({x}, {y}) from ({sx}, {sy})"
                );
            }
            differ += usize::from(
                expected[2][k * 4..k * 4 + 4] != expected[2][source * 4..source * 4 + 4],
            );
        }
    }
    // The scene has edges, so the copies are not the exact image.
    assert!(differ > 50, "only {differ} ids differ from the exact image");
    release_all(dev, &[plain, budgeted, camera, renderer, world]);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

/// Colour (RGB) of pixel `k` of a FLOAT32_VEC4 colour channel.
fn rgb(color: &[u8], k: usize) -> [f32; 3] {
    std::array::from_fn(|c| {
        let at = 16 * k + 4 * c;
        f32::from_ne_bytes([color[at], color[at + 1], color[at + 2], color[at + 3]])
    })
}

/// Mean absolute difference over pixels and RGB of colours `a(k)` and `b(k)`.
fn mean_error(pixels: usize, a: impl Fn(usize) -> [f32; 3], b: impl Fn(usize) -> [f32; 3]) -> f64 {
    let sum: f64 = (0..pixels)
        .map(|k| {
            let (a, b) = (a(k), b(k));
            (0..3).map(|c| f64::from((a[c] - b[c]).abs())).sum::<f64>()
        })
        .sum();
    sum / (3 * pixels) as f64
}

/// Large spheres (smooth shading) in front of a wall of two triangles (another object).
fn smooth_scene(dev: ANARIDevice) -> ANARIWorld {
    let wall = triangle_geometry(
        dev,
        &[
            [-1.5, 0.0, -2.5],
            [1.5, 0.0, -2.5],
            [1.5, 3.0, -2.5],
            [-1.5, 0.0, -2.5],
            [1.5, 3.0, -2.5],
            [-1.5, 3.0, -2.5],
        ],
    );
    let spheres = sphere_geometry(dev, &[[-0.5, 1.2, -1.6], [0.6, 2.0, -1.9]], 0.6);
    let a = matte_surface(dev, wall, [0.8, 0.5, 0.2]);
    let b = matte_surface(dev, spheres, [0.2, 0.6, 0.9]);
    for (surface, id) in [(a, 3u32), (b, 7)] {
        set(dev, surface, "id", ANARI_UINT32, &id);
        commit(dev, surface);
    }
    let world = world_of(dev, &[a, b]);
    light_world(dev, world, [-0.3f32, -1.0, -0.5]);
    release_all(dev, &[wall, spheres, a, b]);
    world
}

#[test]
fn a_partial_frame_interpolates_colour_closer_to_the_converged_frame_than_nearest_copies() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = smooth_scene(dev);
    let (width, height) = (161u32, 117u32);
    let pixels = (width * height) as usize;
    let camera = off_axis(dev, "none", HEAD);
    for renderer_type in ["fast", "default"] {
        let renderer = plain_renderer(dev, renderer_type);
        let plain = frame(dev, world, camera, renderer, [width, height], None);
        render_and_wait(dev, plain);
        let converged = channels(dev, plain);
        // Only the coarsest level: every 16th row and column traced.
        let budgeted = frame(
            dev,
            world,
            camera,
            renderer,
            [width, height],
            Some((0.01, 1)),
        );
        render_and_wait(dev, budgeted);
        let partial = channels(dev, budgeted);
        let nearest = |k: usize| {
            let (x, y) = (k as u32 % width, k as u32 / width);
            let (sx, sy) = corner_source(x, y, width, height);
            (sy * width + sx) as usize
        };
        let exact = |k: usize| rgb(&converged[0], k);
        let interpolated = mean_error(pixels, |k| rgb(&partial[0], k), exact);
        let copied = mean_error(pixels, |k| exact(nearest(k)), exact);
        // Pixels of cells that show one object throughout (in the converged frame), where the
        // fill is not limited by what the coarse lattice missed.
        let object = |k: usize| &converged[3][4 * k..4 * k + 4];
        let cell = |k: usize| (k as u32 % width / 16, k as u32 / width / 16);
        // A cell with its far lattice lines (as the fill reads them), all one object.
        let one_object = |(cx, cy): (u32, u32)| {
            let (x0, y0) = (cx * 16, cy * 16);
            let corner = object((y0 * width + x0) as usize);
            (y0..=(y0 + 16).min(height - 1)).all(|y| {
                (x0..=(x0 + 16).min(width - 1)).all(|x| object((y * width + x) as usize) == corner)
            })
        };
        let mixed: std::collections::HashSet<(u32, u32)> =
            (0..pixels).map(cell).filter(|&c| !one_object(c)).collect();
        let interior: Vec<usize> = (0..pixels).filter(|&k| !mixed.contains(&cell(k))).collect();
        let interior_error = |of: &dyn Fn(usize) -> [f32; 3]| {
            mean_error(interior.len(), |i| of(interior[i]), |i| exact(interior[i]))
        };
        let interior_interpolated = interior_error(&|k| rgb(&partial[0], k));
        let interior_copied = interior_error(&|k| exact(nearest(k)));
        eprintln!(
            "{renderer_type}: mean colour error {interpolated:.5} interpolated, {copied:.5} copied; \
             inside one object ({} pixels): {interior_interpolated:.5}, {interior_copied:.5}",
            interior.len()
        );
        assert!(
            interpolated < copied,
            "{renderer_type}: mean colour error {interpolated} interpolated, {copied} copied"
        );
        assert!(
            interior_interpolated < 0.9 * interior_copied,
            "{renderer_type}: inside one object {interior_interpolated} interpolated, {interior_copied} copied"
        );
        for k in 0..pixels {
            let (x, y) = (k as u32 % width, k as u32 / width);
            // Traced pixels are exact; every other colour lies within its cell's traced corners.
            if x % 16 == 0 && y % 16 == 0 {
                assert_eq!(rgb(&partial[0], k), exact(k), "traced ({x}, {y})");
                continue;
            }
            let (x0, y0) = (x - x % 16, y - y % 16);
            let upper = |p: u32, extent: u32| if p + 16 < extent { p + 16 } else { p };
            let (x1, y1) = (upper(x0, width), upper(y0, height));
            let corners = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
                .map(|(cx, cy)| exact((cy * width + cx) as usize));
            for c in 0..3 {
                let low = corners.iter().map(|v| v[c]).fold(f32::INFINITY, f32::min);
                let high = corners
                    .iter()
                    .map(|v| v[c])
                    .fold(f32::NEG_INFINITY, f32::max);
                let value = rgb(&partial[0], k)[c];
                assert!(
                    (low - 1e-6..=high + 1e-6).contains(&value),
                    "{renderer_type} ({x}, {y}) channel {c}: {value} outside {low}..{high}"
                );
            }
        }
        release_all(dev, &[plain, budgeted, renderer]);
    }
    release_all(dev, &[camera, world]);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn a_change_restarts_refinement_at_the_coarsest_level() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let size = [64, 48];
    let camera = off_axis(dev, "none", HEAD);
    let renderer = plain_renderer(dev, "fast");
    // One pixel per render: the coarsest level, then one unit (here a whole level) per render.
    let budgeted = frame(dev, world, camera, renderer, size, Some((0.01, 1)));
    let coarsest = 1.0 / 256.0;
    render_and_wait(dev, budgeted);
    assert_eq!(progress(dev, budgeted), coarsest);
    render_and_wait(dev, budgeted);
    render_and_wait(dev, budgeted);
    // The lattices of strides 16, 8 and 4 are traced: a sixteenth of the pixels.
    assert_eq!(progress(dev, budgeted), 1.0 / 16.0);
    // The head moves: the next render starts again with the coarsest level.
    set(
        dev,
        camera,
        "position",
        ANARI_FLOAT32_VEC3,
        &[0.2f32, 1.5, 0.4],
    );
    commit(dev, camera);
    render_and_wait(dev, budgeted);
    assert_eq!(progress(dev, budgeted), coarsest);
    // The restarted refinement converges to the new view's exact image.
    refine(dev, budgeted, 100);
    let plain = frame(dev, world, camera, renderer, size, None);
    render_and_wait(dev, plain);
    assert_same_channels(
        &channels(dev, budgeted),
        &channels(dev, plain),
        "moved head",
    );
    release_all(dev, &[plain, budgeted, camera, renderer, world]);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn budget_zero_renders_every_pixel_and_a_timed_budget_converges() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let size = [90, 60];
    let camera = off_axis(dev, "sideBySide", HEAD);
    let renderer = plain_renderer(dev, "default");
    let plain = frame(dev, world, camera, renderer, size, None);
    render_and_wait(dev, plain);
    let expected = channels(dev, plain);
    let zero = frame(dev, world, camera, renderer, size, Some((0.0, 1)));
    render_and_wait(dev, zero);
    assert_eq!(progress(dev, zero), 1.0);
    assert_same_channels(&channels(dev, zero), &expected, "budget 0");
    // A budget far below what the frame needs, timed: each render traces at least the
    // coarsest level or one more unit, and the image still converges to the exact one.
    let timed = frame(dev, world, camera, renderer, size, Some((1e-6, 0)));
    // Levels of 1, 1, 1, 1, 1, 1 and 4 units per eye: the coarsest level of both eyes,
    // then a unit per render, at most 19 renders.
    let steps = refine(dev, timed, 19);
    assert!(steps[0] > 0.0 && steps[0] < 1.0, "{steps:?}");
    assert_same_channels(&channels(dev, timed), &expected, "timed budget");
    release_all(dev, &[plain, zero, timed, camera, renderer, world]);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn accumulation_goes_on_after_a_budgeted_frame_converges() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let size = [40, 32];
    let camera = off_axis(dev, "none", HEAD);
    let renderer = plain_renderer(dev, "default");
    let plain = frame(dev, world, camera, renderer, size, None);
    let budgeted = frame(dev, world, camera, renderer, size, Some((0.01, 250)));
    for frame in [plain, budgeted] {
        set(dev, frame, "accumulation", ANARI_BOOL, &1u8);
        commit(dev, frame);
    }
    render_and_wait(dev, plain);
    let first = channels(dev, plain);
    refine(dev, budgeted, 100);
    assert_same_channels(&channels(dev, budgeted), &first, "first pass");
    // The second pass is jittered: both frames accumulate it alike.
    render_and_wait(dev, plain);
    render_and_wait(dev, budgeted);
    assert_eq!(progress(dev, budgeted), 1.0);
    let second = channels(dev, plain);
    assert!(second[0] != first[0], "the second pass changed nothing");
    assert_same_channels(&channels(dev, budgeted), &second, "second pass");
    release_all(dev, &[plain, budgeted, camera, renderer, world]);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn a_negative_budget_is_reported_and_renders_every_pixel() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let camera = off_axis(dev, "none", HEAD);
    let renderer = plain_renderer(dev, "fast");
    let frame = frame(dev, world, camera, renderer, [16, 16], Some((-1.0, 0)));
    let errors = log.errors();
    assert!(
        errors
            .iter()
            .any(|(_, e)| e.contains("'budget'") && e.contains("-1")),
        "{errors:?}"
    );
    render_and_wait(dev, frame);
    assert_eq!(progress(dev, frame), 1.0);
    release_all(dev, &[frame, camera, renderer, world]);
    release_device(lib, dev);
}
