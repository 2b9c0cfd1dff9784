//! The `lightField` camera: every colour channel of every pixel is the same channel of that
//! pixel's subpixel ray, which an offAxis camera whose eye is the subpixel's view renders as a
//! pixel of a frame three times as wide.

mod common;
use common::*;

/// A 0.6 m × 0.4 m panel in the plane z = 0, centred on the origin; views 1 m in front of it.
const LL: [f32; 3] = [-0.3, -0.2, 0.0];
const LR: [f32; 3] = [0.3, -0.2, 0.0];
const UR: [f32; 3] = [0.3, 0.2, 0.0];
const DISTANCE: f64 = 1.0;
/// The grid's surface id.
const GRID: u32 = 1;

/// The calibration of the tests: the sample 2560×1600 panel's values.
struct Calibration {
    pitch: f32,
    slope: f32,
    center: f32,
    dpi: f32,
    view_cone: f32,
    inv_view: bool,
    flip_subpixels: bool,
    flip_x: bool,
    views: u32,
}

const SAMPLE: Calibration = Calibration {
    pitch: 49.82,
    slope: 5.04,
    center: 0.177,
    dpi: 338.0,
    view_cone: 40.0,
    inv_view: false,
    flip_subpixels: false,
    flip_x: false,
    views: 0,
};

/// A grid of small squares on the panel's plane (ids that no view changes), a sphere in front
/// of it and one behind (they shift with the view).
fn world(dev: ANARIDevice) -> ANARIWorld {
    let mut squares = Vec::new();
    for i in 0..7 {
        for j in 0..5 {
            let (x, y) = (-0.29 + 0.083 * i as f32, -0.19 + 0.077 * j as f32);
            let (x1, y1) = (x + 0.07, y + 0.065);
            squares.extend([
                [x, y, 0.0],
                [x1, y, 0.0],
                [x1, y1, 0.0],
                [x, y, 0.0],
                [x1, y1, 0.0],
                [x, y1, 0.0],
            ]);
        }
    }
    let grid = triangle_geometry(dev, &squares);
    let spheres = sphere_geometry(dev, &[[0.05, 0.02, 0.15], [-0.1, -0.05, -0.3]], 0.08);
    let grid_surface = matte_surface(dev, grid, [0.9, 0.7, 0.3]);
    let sphere_surface = matte_surface(dev, spheres, [0.2, 0.6, 0.9]);
    for (surface, id) in [(grid_surface, GRID), (sphere_surface, GRID + 1)] {
        set(dev, surface, "id", ANARI_UINT32, &id);
        commit(dev, surface);
    }
    let world = world_of(dev, &[grid_surface, sphere_surface]);
    release_all(dev, &[grid, spheres, grid_surface, sphere_surface]);
    world
}

fn light_field(dev: ANARIDevice, cal: &Calibration) -> ANARICamera {
    let camera = anariNewCamera(dev, c("lightField").as_ptr());
    set(dev, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, &LL);
    set(dev, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, &LR);
    set(dev, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, &UR);
    for (name, value) in [
        ("pitch", cal.pitch),
        ("slope", cal.slope),
        ("center", cal.center),
        ("dpi", cal.dpi),
        ("viewCone", cal.view_cone),
    ] {
        set(dev, camera, name, ANARI_FLOAT32, &value);
    }
    set(
        dev,
        camera,
        "viewingDistance",
        ANARI_FLOAT32,
        &(DISTANCE as f32),
    );
    for (name, value) in [
        ("invView", cal.inv_view),
        ("flipSubpixels", cal.flip_subpixels),
        ("flipImageX", cal.flip_x),
    ] {
        set(dev, camera, name, ANARI_BOOL, &u8::from(value));
    }
    set(dev, camera, "views", ANARI_UINT32, &cal.views);
    commit(dev, camera);
    camera
}

/// Colours and primitive ids of a render.
type Image = (Vec<[f32; 4]>, Vec<u32>);

/// (colours, primitive ids) of `camera` at `size`, fast renderer.
fn render(dev: ANARIDevice, world: ANARIWorld, camera: ANARICamera, size: [u32; 2]) -> Image {
    let renderer = plain_renderer(dev, "fast");
    let frame = frame_for(dev, world, camera, renderer, size);
    let (colors, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    let (ids, _, _) = read_channel::<u32>(dev, frame, "channel.primitiveId");
    let (objects, _, _) = read_channel::<u32>(dev, frame, "channel.objectId");
    release_all(dev, &[renderer, frame]);
    // Primitive ids of the grid's squares; other surfaces' read as u32::MAX.
    let ids = ids
        .iter()
        .zip(&objects)
        .map(|(id, object)| if *object == GRID { *id } else { u32::MAX })
        .collect();
    (colors, ids)
}

/// The eye of subpixel k of pixel (x, y) on a w×h panel, as the issue defines it (in f64,
/// rounded to the FLOAT32 an application would pass an offAxis camera).
fn subpixel_eye(c: &Calibration, x: u32, y: u32, k: u32, w: u32, h: u32) -> [f32; 3] {
    // The subpixel's centre as the frame computes it (a pixel of a frame 3w wide).
    let s = f64::from(((3 * x + k) as f32 + 0.5) / (3 * w) as f32);
    let t = f64::from((y as f32 + 0.5) / h as f32);
    let (wf, hf, slope) = (f64::from(w), f64::from(h), f64::from(c.slope));
    let tilt = -hf / (wf * slope);
    let p = f64::from(c.pitch) * (wf / f64::from(c.dpi)) * 1f64.atan2(slope).cos();
    let subp = p / (3.0 * wf);
    // u = s − 1/(3w) + ... : the pixel centre plus k subpixels is s plus one subpixel.
    let mut f = ((s + t * tilt) * p - f64::from(c.center) + subp).rem_euclid(1.0);
    if c.inv_view {
        f = 1.0 - f;
    }
    if c.views > 0 {
        let n = f64::from(c.views);
        f = ((f * n).floor().min(n - 1.0) + 0.5) / n;
    }
    let offset = DISTANCE * ((f - 0.5) * f64::from(c.view_cone).to_radians()).tan();
    [offset as f32, 0.0, DISTANCE as f32]
}

fn off_axis(dev: ANARIDevice, eye: [f32; 3]) -> ANARICamera {
    let camera = anariNewCamera(dev, c("offAxis").as_ptr());
    set(dev, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, &LL);
    set(dev, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, &LR);
    set(dev, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, &UR);
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &eye);
    commit(dev, camera);
    camera
}

/// Checks every channel of every pixel of a light-field frame against offAxis renders from the
/// subpixels' eyes; returns how many distinct eyes were used.
fn check_against_off_axis(
    dev: ANARIDevice,
    world: ANARIWorld,
    cal: &Calibration,
    w: u32,
    h: u32,
) -> usize {
    let camera = light_field(dev, cal);
    let (colors, ids) = render(dev, world, camera, [w, h]);
    anariRelease(dev, camera);
    let channel = |k: u32| {
        if cal.flip_subpixels {
            2 - k as usize
        } else {
            k as usize
        }
    };
    let mut views: Vec<([f32; 3], Image)> = Vec::new();
    for y in 0..h {
        for x in 0..w {
            for k in 0..3 {
                let eye = subpixel_eye(cal, x, y, k, w, h);
                let index = match views.iter().position(|(e, _)| *e == eye) {
                    Some(index) => index,
                    None => {
                        let camera = off_axis(dev, eye);
                        views.push((eye, render(dev, world, camera, [3 * w, h])));
                        anariRelease(dev, camera);
                        views.len() - 1
                    }
                };
                let (view_colors, view_ids) = &views[index].1;
                let (i, j) = ((y * w + x) as usize, (y * 3 * w + 3 * x + k) as usize);
                let ch = channel(k);
                assert_eq!(
                    colors[i][ch], view_colors[j][ch],
                    "pixel ({x}, {y}) subpixel {k} (eye {eye:?})"
                );
                if ch == 1 {
                    assert_eq!(
                        ids[i], view_ids[j],
                        "pixel ({x}, {y}): the green subpixel's id"
                    );
                }
            }
        }
    }
    views.len()
}

#[test]
fn every_subpixel_shows_its_views_ray() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = world(dev);
    // Snapped to 5 views, then continuous, then with the calibration's flags.
    let used = check_against_off_axis(dev, world, &Calibration { views: 5, ..SAMPLE }, 24, 16);
    assert_eq!(used, 5);
    let used = check_against_off_axis(dev, world, &SAMPLE, 6, 4);
    assert!(used > 30, "{used} distinct eyes for 72 subpixels");
    check_against_off_axis(
        dev,
        world,
        &Calibration {
            inv_view: true,
            views: 7,
            ..SAMPLE
        },
        18,
        10,
    );
    check_against_off_axis(
        dev,
        world,
        &Calibration {
            flip_subpixels: true,
            views: 7,
            ..SAMPLE
        },
        18,
        10,
    );
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    anariRelease(dev, world);
    release_device(lib, dev);
}

#[test]
fn the_panel_plane_looks_the_same_from_every_view_and_flip_image_x_mirrors_it() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = world(dev);
    let (w, h) = (40, 24);
    let plain = light_field(dev, &SAMPLE);
    let (_, ids) = render(dev, world, plain, [w, h]);
    let mirrored = light_field(
        dev,
        &Calibration {
            flip_x: true,
            ..SAMPLE
        },
    );
    let (_, mirrored_ids) = render(dev, world, mirrored, [w, h]);
    // The green subpixel's ray of a pixel that sees the grid meets the grid where the mirrored
    // pixel's does.
    let mut compared = 0;
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (
                ids[(y * w + x) as usize],
                mirrored_ids[(y * w + w - 1 - x) as usize],
            );
            if a != u32::MAX && b != u32::MAX {
                assert_eq!(a, b, "pixel ({x}, {y})");
                compared += 1;
            }
        }
    }
    assert!(compared > 100, "{compared}");
    // Bad calibration is reported naming the parameter.
    set(dev, plain, "slope", ANARI_FLOAT32, &0.0f32);
    commit(dev, plain);
    let errors = log.errors();
    assert!(errors.iter().any(|e| e.1.contains("'slope'")), "{errors:?}");
    release_all(dev, &[plain, mirrored, world]);
    release_device(lib, dev);
}

/// The eye of quilt view k of n, as the issue defines it: E((k+½)/n).
fn quilt_eye(k: u32, n: u32) -> [f32; 3] {
    let f = (f64::from(k) + 0.5) / f64::from(n);
    let offset = DISTANCE * ((f - 0.5) * f64::from(SAMPLE.view_cone).to_radians()).tan();
    [offset as f32, 0.0, DISTANCE as f32]
}

#[test]
fn every_quilt_view_is_the_off_axis_frame_of_its_eye() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = world(dev);
    // 4 × 3 views on a frame the views do not divide evenly: view columns 12, 13, 12, 13
    // pixels wide, rows 10, 10, 11 high.
    let (w, h, columns, rows) = (50u32, 31u32, 4u32, 3u32);
    let camera = light_field(dev, &SAMPLE);
    set(dev, camera, "quilt", ANARI_UINT32_VEC2, &[columns, rows]);
    commit(dev, camera);
    let (colors, ids) = render(dev, world, camera, [w, h]);
    let split = |size: u32, parts: u32, i: u32| size * i / parts;
    let mut distinct: Vec<Vec<[f32; 4]>> = Vec::new();
    for row in 0..rows {
        for column in 0..columns {
            // View 0 at the bottom left, rows bottom to top.
            let k = row * columns + column;
            let (x0, y0) = (split(w, columns, column), split(h, rows, row));
            let (vw, vh) = (
                split(w, columns, column + 1) - x0,
                split(h, rows, row + 1) - y0,
            );
            let view = off_axis(dev, quilt_eye(k, columns * rows));
            let (view_colors, view_ids) = render(dev, world, view, [vw, vh]);
            anariRelease(dev, view);
            for y in 0..vh {
                for x in 0..vw {
                    let i = ((y0 + y) * w + x0 + x) as usize;
                    let j = (y * vw + x) as usize;
                    assert_eq!(colors[i], view_colors[j], "view {k} pixel ({x}, {y})");
                    assert_eq!(ids[i], view_ids[j], "view {k} pixel ({x}, {y})");
                }
            }
            if !distinct.contains(&view_colors) && vw == 12 && vh == 10 {
                distinct.push(view_colors);
            }
        }
    }
    // The spheres off the panel's plane shift from view to view.
    assert!(
        distinct.len() >= 3,
        "{} distinct 12×10 views",
        distinct.len()
    );
    // Half a quilt is reported naming the parameter.
    set(dev, camera, "quilt", ANARI_UINT32_VEC2, &[4u32, 0]);
    commit(dev, camera);
    let errors = log.errors();
    assert!(errors.iter().any(|e| e.1.contains("'quilt'")), "{errors:?}");
    release_all(dev, &[camera, world]);
    release_device(lib, dev);
}
