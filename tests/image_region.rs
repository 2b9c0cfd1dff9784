//! `imageRegion` beyond `[0,1]²` and reversed, for every camera with an image plane: a reversed
//! region mirrors the frame pixel for pixel, a larger region shows the default image shrunk
//! into its middle with more of the scene around it, offAxis and matrix rays cross the screen
//! where the region puts them, and only non-finite or empty regions are rejected.
mod common;
use cavetrace::capi::offaxis::cavetraceOffAxisMatrices;
use common::*;

const NO_ID: u32 = u32::MAX;

/// Frame size of the default view: powers of two, so pixel centres and the regions below map
/// to the same image-plane coordinates exactly (mirrored and enlarged frames trace the same
/// rays as the default one).
const SIZE: [u32; 2] = [64, 32];

/// A CAVE wall 4 m × 2 m, 2 m in front of the eye.
const LL: [f32; 3] = [-2.0, -1.0, -2.0];
const LR: [f32; 3] = [2.0, -1.0, -2.0];
const UR: [f32; 3] = [2.0, 1.0, -2.0];
const EYE: [f32; 3] = [0.3, 0.2, 0.0];

const CAMERAS: [&str; 5] = [
    "perspective",
    "orthographic",
    "offAxis",
    "matrix",
    "fisheye",
];

/// Right triangles (not mirror-symmetric) on a grid in the plane z = −5, each its own primitive
/// id, the grid itself not symmetric either (rows shifted).
fn scene(dev: ANARIDevice) -> ANARIWorld {
    let mut positions = Vec::new();
    for row in -6..=6 {
        for column in -12..=12 {
            let x = column as f32 + 0.13 * row as f32;
            let y = row as f32;
            positions.extend([[x, y, -5.0], [x + 0.6, y, -5.0], [x, y + 0.45, -5.0]]);
        }
    }
    let geometry = triangle_geometry(dev, &positions);
    let surface = matte_surface(dev, geometry, [0.8, 0.6, 0.2]);
    let world = world_of(dev, &[surface]);
    release_all(dev, &[geometry, surface]);
    world
}

fn matrices() -> ([f32; 16], [f32; 16]) {
    let (mut view, mut proj) = ([0f32; 16], [0f32; 16]);
    let status = cavetraceOffAxisMatrices(
        LL.as_ptr(),
        LR.as_ptr(),
        UR.as_ptr(),
        EYE.as_ptr(),
        0.1,
        100.0,
        view.as_mut_ptr(),
        proj.as_mut_ptr(),
    );
    assert_eq!(status, ANARI_STATUS_NO_ERROR);
    (view, proj)
}

/// A committed camera of `kind` looking at the scene, imageRegion at its default.
fn camera(dev: ANARIDevice, kind: &str) -> ANARICamera {
    let camera = anariNewCamera(dev, c(kind).as_ptr());
    let origin = [0.0f32; 3];
    match kind {
        "perspective" => set(dev, camera, "position", ANARI_FLOAT32_VEC3, &origin),
        "orthographic" => set(dev, camera, "height", ANARI_FLOAT32, &4.0f32),
        "offAxis" => {
            set(dev, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, &LL);
            set(dev, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, &LR);
            set(dev, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, &UR);
            set(dev, camera, "position", ANARI_FLOAT32_VEC3, &EYE);
        }
        "matrix" => {
            let (view, proj) = matrices();
            set(dev, camera, "view", ANARI_FLOAT32_MAT4, &view);
            set(dev, camera, "proj", ANARI_FLOAT32_MAT4, &proj);
        }
        "fisheye" => {
            let forward = [0.0f32, 0.0, -1.0];
            set(dev, camera, "dome.direction", ANARI_FLOAT32_VEC3, &forward);
            set(
                dev,
                camera,
                "dome.up",
                ANARI_FLOAT32_VEC3,
                &[0.0f32, 1.0, 0.0],
            );
        }
        _ => unreachable!("{kind}"),
    }
    commit(dev, camera);
    camera
}

fn set_region(dev: ANARIDevice, camera: ANARICamera, region: [f32; 4]) {
    set(dev, camera, "imageRegion", ANARI_FLOAT32_BOX2, &region);
    commit(dev, camera);
}

/// A rendered primitive-id image, rows bottom to top.
struct Ids {
    ids: Vec<u32>,
    width: u32,
}

impl Ids {
    fn at(&self, x: u32, y: u32) -> u32 {
        self.ids[(y * self.width + x) as usize]
    }
}

fn render(dev: ANARIDevice, world: ANARIWorld, camera: ANARICamera, size: [u32; 2]) -> Ids {
    let renderer = plain_renderer(dev, "fast");
    let frame = frame_for(dev, world, camera, renderer, size);
    let (ids, width, height) = render_channel::<u32>(dev, frame, "channel.primitiveId");
    assert_eq!([width, height], size);
    release_all(dev, &[frame, renderer]);
    Ids { ids, width }
}

#[test]
fn reversed_regions_mirror_the_frame_pixel_for_pixel() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let [w, h] = SIZE;
    for kind in CAMERAS {
        let camera = camera(dev, kind);
        let default = render(dev, world, camera, SIZE);
        let hits = default.ids.iter().filter(|id| **id != NO_ID).count();
        assert!(
            hits > 40,
            "{kind}: the default view must show the scene: {hits}"
        );
        let asymmetric = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| default.at(x, y) != default.at(w - 1 - x, y))
            .count();
        assert!(asymmetric > 20, "{kind}: a mirror must change the image");

        set_region(dev, camera, [1.0, 0.0, 0.0, 1.0]);
        let mirrored = render(dev, world, camera, SIZE);
        set_region(dev, camera, [0.0, 1.0, 1.0, 0.0]);
        let upside_down = render(dev, world, camera, SIZE);
        for y in 0..h {
            for x in 0..w {
                let want = default.at(w - 1 - x, y);
                assert_eq!(mirrored.at(x, y), want, "{kind} mirrored pixel {x},{y}");
                let want = default.at(x, h - 1 - y);
                assert_eq!(upside_down.at(x, y), want, "{kind} upside-down {x},{y}");
            }
        }
        anariRelease(dev, camera);
    }
    anariRelease(dev, world);
    release_device(lib, dev);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
}

#[test]
fn regions_beyond_the_unit_square_extend_the_image_plane() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let [w, h] = SIZE;
    for kind in CAMERAS {
        let camera = camera(dev, kind);
        let default = render(dev, world, camera, SIZE);
        // Twice the default region on both axes, centred: the default image lies in the middle
        // half of a frame twice as large, pixel for pixel.
        set_region(dev, camera, [-0.5, -0.5, 1.5, 1.5]);
        let wide = render(dev, world, camera, [2 * w, 2 * h]);
        let (mut outside, mut outside_hits) = (0, 0);
        for y in 0..2 * h {
            for x in 0..2 * w {
                let (dx, dy) = (x.wrapping_sub(w / 2), y.wrapping_sub(h / 2));
                if dx < w && dy < h {
                    let want = default.at(dx, dy);
                    assert_eq!(wide.at(x, y), want, "{kind} middle pixel {x},{y}");
                } else {
                    outside += 1;
                    outside_hits += u32::from(wide.at(x, y) != NO_ID);
                }
            }
        }
        assert_eq!(outside, 3 * w * h);
        if kind == "fisheye" {
            // The image circle is the whole image's: nothing lies beyond it.
            assert_eq!(outside_hits, 0, "{kind}: beyond the image circle");
        } else {
            assert!(
                outside_hits > w * h / 8,
                "{kind}: the border must show more of the scene: {outside_hits}"
            );
        }
        // Shifted by half the image: the frame's left half is the default's right half.
        set_region(dev, camera, [0.5, 0.0, 1.5, 1.0]);
        let shifted = render(dev, world, camera, SIZE);
        for y in 0..h {
            for x in 0..w / 2 {
                let want = default.at(x + w / 2, y);
                assert_eq!(shifted.at(x, y), want, "{kind} shifted pixel {x},{y}");
            }
        }
        anariRelease(dev, camera);
    }
    anariRelease(dev, world);
    release_device(lib, dev);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
}

/// The screen point the ray through the centre of pixel (x, y) of a `size`×`size` frame must
/// cross: LL + s'(LR−LL) + t'(UR−LR), (s', t') the pixel centre mapped through `region`.
fn expected_screen_point(region: [f32; 4], x: u32, y: u32, size: u32) -> glam::DVec3 {
    let [lo_x, lo_y, hi_x, hi_y] = region.map(f64::from);
    let s = lo_x + (f64::from(x) + 0.5) / f64::from(size) * (hi_x - lo_x);
    let t = lo_y + (f64::from(y) + 0.5) / f64::from(size) * (hi_y - lo_y);
    let [ll, lr, ur] = [LL, LR, UR].map(|p| glam::Vec3::from(p).as_dvec3());
    ll + s * (lr - ll) + t * (ur - lr)
}

#[test]
fn off_axis_and_matrix_rays_cross_the_screen_where_the_region_puts_them() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let size = 16;
    for kind in ["offAxis", "matrix"] {
        let camera = camera(dev, kind);
        for region in [
            [1.0f32, 0.0, 0.0, 1.0],
            [-0.7, 1.4, 1.9, -0.2],
            [0.2, -1.5, 0.6, 2.5],
        ] {
            set_region(dev, camera, region);
            let rays = camera_rays_with_pixels(dev, camera, size);
            assert_eq!(rays.len(), (size * size) as usize);
            for ((x, y), ray) in rays {
                let origin = ray.origin.as_dvec3();
                let direction = ray.direction.as_dvec3();
                let along = (f64::from(LL[2]) - origin.z) / direction.z;
                assert!(along > 0.0, "{kind} {region:?} pixel {x},{y}");
                let crossing = origin + along * direction;
                let want = expected_screen_point(region, x, y, size);
                assert!(
                    (crossing - want).length() < 1e-4,
                    "{kind} {region:?} pixel {x},{y}: crosses {crossing}, not {want}"
                );
            }
        }
        anariRelease(dev, camera);
    }
    release_device(lib, dev);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
}

#[test]
fn non_finite_and_empty_regions_are_reported_at_commit() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    for kind in CAMERAS {
        let camera = camera(dev, kind);
        for (region, expected) in [
            ([0.0, f32::NAN, 1.0, 1.0], "must be finite"),
            ([f32::NEG_INFINITY, 0.0, 1.0, 1.0], "must be finite"),
            ([0.3, 0.0, 0.3, 1.0], "must not be empty"),
            ([0.0, 2.0, 1.0, 2.0], "must not be empty"),
        ] {
            set_region(dev, camera, region);
            let errors = log.errors();
            assert_eq!(errors.len(), 1, "{kind} {region:?}: {errors:?}");
            let message = &errors[0].1;
            for part in [
                "anariCommitParameters",
                &format!("camera '{kind}'"),
                "'imageRegion'",
                expected,
            ] {
                assert!(message.contains(part), "{kind} {region:?}: {message}");
            }
            let image = render(dev, world, camera, [8, 8]);
            assert!(image.ids.iter().all(|id| *id == NO_ID), "{kind} {region:?}");
            log.take();
        }
        anariRelease(dev, camera);
    }
    anariRelease(dev, world);
    release_device(lib, dev);
}
