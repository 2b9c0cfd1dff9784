//! The omnidirectional (equirectangular, ODS stereo) and fisheye (dome) cameras through the C
//! API: spheres at known directions appear at the pixels the closed forms give, imageRegion
//! crops, ODS eyes see the disparity of their circle, a tracked viewer keeps dome points in
//! place, and bad parameters are reported.
mod common;
use common::*;
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

/// The renderer's background, seen where no object is and outside a dome's image circle.
const BACKGROUND: [f32; 4] = [0.2, 0.4, 0.6, 1.0];
/// channel.objectId where nothing was hit.
const NO_ID: u32 = u32::MAX;

struct Image {
    width: u32,
    height: u32,
    ids: Vec<u32>,
    color: Vec<[f32; 4]>,
}

impl Image {
    fn id(&self, x: u32, y: u32) -> u32 {
        self.ids[(y * self.width + x) as usize]
    }

    /// Mean pixel centre (x+½, y+½) of the pixels showing `id` in columns `[x0, x1)`.
    fn centroid(&self, id: u32, x0: u32, x1: u32) -> Option<(f32, f32)> {
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
        for y in 0..self.height {
            for x in x0..x1 {
                if self.id(x, y) == id {
                    sx += x as f32 + 0.5;
                    sy += y as f32 + 0.5;
                    n += 1.0;
                }
            }
        }
        (n > 0.0).then(|| (sx / n, sy / n))
    }
}

/// Unit vector at `longitude` (towards +x from −z) and `latitude` (towards +y).
fn direction(longitude: f32, latitude: f32) -> [f32; 3] {
    [
        longitude.sin() * latitude.cos(),
        latitude.sin(),
        -longitude.cos() * latitude.cos(),
    ]
}

fn along(origin: [f32; 3], direction: [f32; 3], distance: f32) -> [f32; 3] {
    std::array::from_fn(|k| origin[k] + direction[k] * distance)
}

/// Spheres of `radius` at `centers`, the i-th with surface id i.
fn world_of_spheres(dev: ANARIDevice, centers: &[[f32; 3]], radius: f32) -> ANARIWorld {
    let spheres: Vec<([f32; 3], f32)> = centers.iter().map(|c| (*c, radius)).collect();
    world_of_sized_spheres(dev, &spheres)
}

fn render(dev: ANARIDevice, world: ANARIWorld, camera: ANARICamera, size: [u32; 2]) -> Image {
    let renderer = anariNewRenderer(dev, c("fast").as_ptr());
    set(dev, renderer, "background", ANARI_FLOAT32_VEC4, &BACKGROUND);
    commit(dev, renderer);
    let frame = frame_for(dev, world, camera, renderer, size);
    let (ids, width, height) = render_channel::<u32>(dev, frame, "channel.objectId");
    let (color, _, _) = read_channel::<[f32; 4]>(dev, frame, "channel.color");
    release_all(dev, &[frame, renderer]);
    Image {
        width,
        height,
        ids,
        color,
    }
}

fn omnidirectional(dev: ANARIDevice, position: [f32; 3], stereo: &str, ipd: f32) -> ANARICamera {
    let camera = anariNewCamera(dev, c("omnidirectional").as_ptr());
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &position);
    set_string(dev, camera, "layout", "equirectangular");
    set_string(dev, camera, "stereoMode", stereo);
    set(dev, camera, "interpupillaryDistance", ANARI_FLOAT32, &ipd);
    commit(dev, camera);
    camera
}

/// The pixel centre (x+½, y+½) of a W×H equirectangular image that looks at `longitude`,
/// `latitude`.
fn equirectangular_pixel(longitude: f32, latitude: f32, width: u32, height: u32) -> (f32, f32) {
    (
        (longitude / TAU + 0.5) * width as f32,
        (latitude / PI + 0.5) * height as f32,
    )
}

#[test]
fn spheres_appear_at_their_longitude_and_latitude_and_across_the_seam() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let eye = [0.3, 1.5, -0.4];
    let (width, height) = (96, 48);
    let places = [
        (0.0, 0.0),
        (FRAC_PI_2, 0.0),
        (-FRAC_PI_2, 0.3),
        (2.5, -0.6),
        (-2.0, 1.1),
        (0.7, 0.5),
    ];
    let mut centers: Vec<[f32; 3]> = places
        .iter()
        .map(|&(lon, lat)| along(eye, direction(lon, lat), 6.0))
        .collect();
    // Straight behind the camera: on the seam, half at each edge.
    centers.push(along(eye, direction(PI, 0.0), 6.0));
    let world = world_of_spheres(dev, &centers, 0.5);
    let camera = omnidirectional(dev, eye, "none", 0.0);
    let image = render(dev, world, camera, [width, height]);
    for (i, &(lon, lat)) in places.iter().enumerate() {
        let (x, y) = equirectangular_pixel(lon, lat, width, height);
        assert_eq!(
            image.id(x as u32, y as u32),
            i as u32,
            "sphere {i} not at pixel ({x}, {y})"
        );
        // The sphere's image is symmetric about its longitude: the mean column is its centre.
        let (cx, cy) = image.centroid(i as u32, 0, width).unwrap();
        assert!(
            (cx - x).abs() < 0.25,
            "sphere {i}: mean column {cx}, expected {x}"
        );
        if lat == 0.0 {
            assert!(
                (cy - y).abs() < 0.25,
                "sphere {i}: mean row {cy}, expected {y}"
            );
        }
    }
    // The seam sphere covers the first and the last column of the middle rows, as mirror
    // images of each other.
    let seam = places.len() as u32;
    for y in [height / 2 - 1, height / 2] {
        assert_eq!(image.id(0, y), seam);
        assert_eq!(image.id(width - 1, y), seam);
    }
    let left_half = image
        .ids
        .iter()
        .enumerate()
        .filter(|(i, id)| **id == seam && (*i as u32 % width) < width / 2);
    let right_half = image
        .ids
        .iter()
        .enumerate()
        .filter(|(i, id)| **id == seam && (*i as u32 % width) >= width / 2);
    assert_eq!(left_half.count(), right_half.count());
    // Where no sphere is, the background.
    let empty = image.ids.iter().position(|id| *id == NO_ID).unwrap();
    assert_eq!(image.color[empty], BACKGROUND);
    release_all(dev, &[camera, world]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

/// `part` shows the ids of `full` from pixel `offset` on; returns how many show an object.
fn assert_part(part: &Image, full: &Image, offset: (u32, u32), what: &str) -> u32 {
    let mut hits = 0;
    for y in 0..part.height {
        for x in 0..part.width {
            let want = full.id(x + offset.0, y + offset.1);
            assert_eq!(part.id(x, y), want, "{what} pixel ({x}, {y})");
            hits += u32::from(want != NO_ID);
        }
    }
    hits
}

#[test]
fn image_region_renders_exactly_the_part_of_the_panorama() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let eye = [0.0, 1.6, 0.0];
    let centers: Vec<[f32; 3]> = (0..12)
        .map(|k| {
            along(
                eye,
                direction(k as f32 * 0.5 - 2.9, (k as f32 * 0.7).sin()),
                4.0,
            )
        })
        .collect();
    let world = world_of_spheres(dev, &centers, 0.6);
    let camera = omnidirectional(dev, eye, "none", 0.0);
    let full = render(dev, world, camera, [128, 64]);
    let region = [0.25f32, 0.125, 0.75, 0.625];
    set(dev, camera, "imageRegion", ANARI_FLOAT32_BOX2, &region);
    commit(dev, camera);
    let part = render(dev, world, camera, [64, 32]);
    let hits = assert_part(&part, &full, (32, 8), "panorama");
    assert!(hits > 50, "the region must show spheres: {hits}");
    anariRelease(dev, camera);
    // The dome's image circle belongs to the whole image, whatever the region's aspect.
    let camera = fisheye(dev, eye, 0.0, 0.0, PI);
    let full = render(dev, world, camera, [64, 64]);
    let region = [0.5f32, 0.25, 1.0, 1.0];
    set(dev, camera, "imageRegion", ANARI_FLOAT32_BOX2, &region);
    commit(dev, camera);
    let part = render(dev, world, camera, [32, 48]);
    let hits = assert_part(&part, &full, (32, 16), "dome");
    assert!(hits > 20, "the dome region must show spheres: {hits}");
    release_all(dev, &[camera, world]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

/// What each pixel of a `width`×`height` image must show: the id of the nearest of `spheres`
/// (center, radius) that the pixel's closed-form ray hits, NO_ID for none or for no ray;
/// `None` where the ray grazes a sphere (within 1e-3 of its radius), which rounding may decide
/// either way.
fn expected_ids(
    width: u32,
    height: u32,
    spheres: &[([f32; 3], f32)],
    ray: impl Fn(u32, u32) -> Option<(glam::DVec3, glam::DVec3)>,
) -> Vec<Option<u32>> {
    let mut ids = Vec::new();
    for y in 0..height {
        for x in 0..width {
            let Some((origin, direction)) = ray(x, y) else {
                ids.push(Some(NO_ID));
                continue;
            };
            let direction = direction.normalize();
            let mut nearest = (f64::INFINITY, Some(NO_ID));
            for (i, (center, radius)) in spheres.iter().enumerate() {
                let to_center = glam::Vec3::from(*center).as_dvec3() - origin;
                let along = to_center.dot(direction);
                let miss = (to_center - direction * along).length();
                let radius = f64::from(*radius);
                if along <= 0.0 {
                    continue;
                }
                if (miss - radius).abs() < 1e-3 * radius {
                    nearest = (nearest.0.min(along), None);
                } else if miss < radius && along < nearest.0 {
                    nearest = (along, Some(i as u32));
                }
            }
            ids.push(nearest.1);
        }
    }
    ids
}

/// Every pixel shows the expected id; returns how many pixels show a sphere.
fn assert_ids(image: &Image, expected: &[Option<u32>], what: &str) -> usize {
    let mut shown = 0;
    for (i, (got, want)) in image.ids.iter().zip(expected).enumerate() {
        let (x, y) = (i as u32 % image.width, i as u32 / image.width);
        if let Some(want) = want {
            assert_eq!(got, want, "{what}: pixel ({x}, {y})");
        }
        if *got != NO_ID {
            shown += 1;
        }
        if *got == NO_ID && *want == Some(NO_ID) {
            assert_eq!(image.color[i], BACKGROUND, "{what}: pixel ({x}, {y})");
        }
    }
    shown
}

#[test]
fn ods_eyes_see_what_rays_from_their_circle_see() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let eye = glam::DVec3::new(0.0, 1.5, 0.0);
    let ipd = 0.4f32;
    // Near and far spheres: the near ones shift between the eyes, the far ones hardly.
    let spheres = [
        (along(eye.as_vec3().into(), direction(1.0, 0.0), 1.2), 0.25),
        (along(eye.as_vec3().into(), direction(-0.4, -0.3), 0.8), 0.2),
        (along(eye.as_vec3().into(), direction(2.8, 0.2), 9.0), 1.0),
    ];
    let world = world_of_sized_spheres(dev, &spheres);
    let camera = omnidirectional(dev, eye.as_vec3().into(), "topBottom", ipd);
    let (width, half) = (160, 80);
    let image = render(dev, world, camera, [width, 2 * half]);
    // topBottom: the left eye in the upper half (rows count from the bottom).
    let mut shown = [0; 2];
    for (k, (offset, fraction)) in [(half, -0.5f64), (0, 0.5)].into_iter().enumerate() {
        let expected = expected_ids(width, half, &spheres, |x, y| {
            let longitude = TAU as f64 * ((f64::from(x) + 0.5) / f64::from(width) - 0.5);
            let latitude = PI as f64 * ((f64::from(y) + 0.5) / f64::from(half) - 0.5);
            // Looking along −z with right +x: the column's tangent is (cos λ, 0, sin λ).
            let tangent = glam::DVec3::new(longitude.cos(), 0.0, longitude.sin());
            let origin = eye + tangent * (fraction * f64::from(ipd));
            let direction = glam::DVec3::new(
                longitude.sin() * latitude.cos(),
                latitude.sin(),
                -longitude.cos() * latitude.cos(),
            );
            Some((origin, direction))
        });
        let eye_image = Image {
            width,
            height: half,
            ids: image.ids[(offset * width) as usize..((offset + half) * width) as usize].to_vec(),
            color: image.color[(offset * width) as usize..((offset + half) * width) as usize]
                .to_vec(),
        };
        shown[k] = assert_ids(&eye_image, &expected, if k == 0 { "left" } else { "right" });
        assert!(shown[k] > 150, "{shown:?}");
    }
    // The near sphere straight ahead-right: the left eye sees it further right than the right
    // eye (crossed disparity), by the closed form sin(λ₀ − λ) = f·ipd/d at its centre.
    let left = Image {
        width,
        height: half,
        ids: image.ids[(half * width) as usize..].to_vec(),
        color: Vec::new(),
    };
    let right = Image {
        width,
        height: half,
        ids: image.ids[..(half * width) as usize].to_vec(),
        color: Vec::new(),
    };
    let (l, _) = left.centroid(0, 0, width).unwrap();
    let (r, _) = right.centroid(0, 0, width).unwrap();
    let disparity = 2.0 * (0.5 * ipd / 1.2).asin() / TAU * width as f32;
    assert!((l - r - disparity).abs() < 1.0, "{l} − {r} vs {disparity}");
    release_all(dev, &[camera, world]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

/// A fisheye camera with the given dome parameters (radius ≤ 0: unset).
fn fisheye(dev: ANARIDevice, position: [f32; 3], radius: f32, tilt: f32, fov: f32) -> ANARICamera {
    let camera = anariNewCamera(dev, c("fisheye").as_ptr());
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &position);
    if radius > 0.0 {
        set(dev, camera, "dome.radius", ANARI_FLOAT32, &radius);
    }
    set(dev, camera, "dome.tilt", ANARI_FLOAT32, &tilt);
    set(dev, camera, "fov", ANARI_FLOAT32, &fov);
    commit(dev, camera);
    camera
}

/// The closed form of the default dome (axis +y, image up +z, image right +x) after `tilt`:
/// the unit direction from the dome's centre of pixel (x, y) of a width×height image, `None`
/// outside the image circle.
fn dome_direction(
    x: u32,
    y: u32,
    width: u32,
    height: u32,
    fov: f32,
    tilt: f32,
) -> Option<glam::DVec3> {
    let px = f64::from(x) + 0.5 - 0.5 * f64::from(width);
    let py = f64::from(y) + 0.5 - 0.5 * f64::from(height);
    let circle = 0.5 * f64::from(width.min(height));
    let r = px.hypot(py) / circle;
    if r > 1.0 {
        return None;
    }
    let (sin_t, cos_t) = f64::from(tilt).sin_cos();
    let axis = glam::DVec3::new(0.0, cos_t, -sin_t);
    let up = glam::DVec3::new(0.0, sin_t, cos_t);
    let angle = r * 0.5 * f64::from(fov);
    let azimuth = py.atan2(px);
    Some(axis * angle.cos() + (glam::DVec3::X * azimuth.cos() + up * azimuth.sin()) * angle.sin())
}

/// Spheres of `spheres` (center, radius), the i-th with surface id i.
fn world_of_sized_spheres(dev: ANARIDevice, spheres: &[([f32; 3], f32)]) -> ANARIWorld {
    let surfaces: Vec<ANARISurface> = spheres
        .iter()
        .enumerate()
        .map(|(i, (center, radius))| {
            let geometry = sphere_geometry(dev, &[*center], *radius);
            let surface = matte_surface(dev, geometry, [0.9, 0.9, 0.9]);
            set(dev, surface, "id", ANARI_UINT32, &(i as u32));
            commit(dev, surface);
            anariRelease(dev, geometry);
            surface
        })
        .collect();
    let world = world_of(dev, &surfaces);
    release_all(dev, &surfaces);
    world
}

#[test]
fn dome_pixels_see_along_their_angle_from_the_axis_and_background_outside_the_circle() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let (width, height) = (72, 64);
    let spheres = [
        (along([0.0; 3], direction(0.0, FRAC_PI_2 - 0.001), 8.0), 1.0),
        (along([0.0; 3], direction(FRAC_PI_2, FRAC_PI_4), 8.0), 1.2),
        (along([0.0; 3], direction(0.0, 0.5), 7.0), 1.5),
        (along([0.0; 3], direction(-2.2, 0.9), 6.0), 1.0),
        (along([0.0; 3], direction(PI, -0.2), 8.0), 2.0),
        (along([0.0; 3], direction(0.6, -0.9), 5.0), 1.4),
    ];
    let world = world_of_sized_spheres(dev, &spheres);
    for (fov, tilt) in [(PI, 0.0f32), (TAU, 0.0), (PI, 0.5), (2.0, -0.3)] {
        let camera = fisheye(dev, [0.0; 3], 0.0, tilt, fov);
        let image = render(dev, world, camera, [width, height]);
        let expected = expected_ids(width, height, &spheres, |x, y| {
            dome_direction(x, y, width, height, fov, tilt).map(|d| (glam::DVec3::ZERO, d))
        });
        let what = format!("fov {fov}, tilt {tilt}");
        let shown = assert_ids(&image, &expected, &what);
        assert!(shown > 100, "{what}: {shown}");
        // Outside the image circle: the background, no id.
        for (x, y) in [(0, 0), (71, 0), (0, 63), (71, 63), (3, 32)] {
            assert_eq!(image.id(x, y), NO_ID, "{what}");
            assert_eq!(image.color[(y * width + x) as usize], BACKGROUND, "{what}");
        }
        anariRelease(dev, camera);
    }
    anariRelease(dev, world);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn a_tracked_viewer_sees_through_the_dome_point_of_each_pixel() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let (size, radius) = (80, 6.0f32);
    let spheres = [
        // Against the dome: every viewer sees them at about the same pixels.
        (along([0.0; 3], direction(0.0, 1.2), 5.2), 0.7),
        (along([0.0; 3], direction(1.0, 0.6), 5.0), 0.8),
        (along([0.0; 3], direction(-2.4, 0.4), 5.1), 0.8),
        // Near the viewers: they move.
        ([0.4, 2.4, -0.3], 0.5),
        ([-1.0, 1.5, 1.0], 0.3),
    ];
    let world = world_of_sized_spheres(dev, &spheres);
    let (tilt, fov) = (0.35, 3.4);
    let mut images = Vec::new();
    for viewer in [[0.0f32; 3], [1.5, 1.2, 2.0], [-2.0, 0.3, -1.0]] {
        let camera = fisheye(dev, viewer, radius, tilt, fov);
        let image = render(dev, world, camera, [size, size]);
        let origin = glam::Vec3::from(viewer).as_dvec3();
        let expected = expected_ids(size, size, &spheres, |x, y| {
            dome_direction(x, y, size, size, fov, tilt)
                .map(|d| (origin, d * f64::from(radius) - origin))
        });
        let shown = assert_ids(&image, &expected, &format!("viewer {viewer:?}"));
        assert!(shown > 150, "{shown}");
        images.push(image);
        anariRelease(dev, camera);
    }
    // The near sphere moved between the centre and the first viewer by pixels.
    let a = images[0].centroid(3, 0, size).unwrap();
    let b = images[1].centroid(3, 0, size).unwrap();
    assert!((a.0 - b.0).hypot(a.1 - b.1) > 5.0, "{a:?} {b:?}");
    anariRelease(dev, world);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn dome_stereo_halves_see_from_each_eye_through_the_same_dome_points() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let (size, radius, ipd) = (64, 5.0f32, 0.5f32);
    let spheres = [
        (along([0.0; 3], direction(0.3, 1.0), 4.5), 0.6),
        ([0.3, 2.2, -0.8], 0.35),
        ([-0.9, 1.4, 0.6], 0.3),
    ];
    let world = world_of_sized_spheres(dev, &spheres);
    let (tilt, fov) = (0.2, 3.0);
    let head = [0.4f32, 1.1, 0.5];
    let right = glam::DVec3::new(1.0, 0.0, -1.0).normalize();
    let camera = fisheye(dev, head, radius, tilt, fov);
    set(
        dev,
        camera,
        "right",
        ANARI_FLOAT32_VEC3,
        &[2.0f32, 0.0, -2.0],
    );
    set(dev, camera, "interpupillaryDistance", ANARI_FLOAT32, &ipd);
    set_string(dev, camera, "stereoMode", "sideBySide");
    commit(dev, camera);
    let pair = render(dev, world, camera, [2 * size, size]);
    for (half, fraction) in [(0u32, -0.5f64), (1, 0.5)] {
        let eye = glam::Vec3::from(head).as_dvec3() + right * (fraction * f64::from(ipd));
        let expected = expected_ids(size, size, &spheres, |x, y| {
            dome_direction(x, y, size, size, fov, tilt).map(|d| (eye, d * f64::from(radius) - eye))
        });
        let columns =
            |row: &[u32]| row[(half * size) as usize..((half + 1) * size) as usize].to_vec();
        let colors =
            |row: &[[f32; 4]]| row[(half * size) as usize..((half + 1) * size) as usize].to_vec();
        let image = Image {
            width: size,
            height: size,
            ids: pair
                .ids
                .chunks(2 * size as usize)
                .flat_map(columns)
                .collect(),
            color: pair
                .color
                .chunks(2 * size as usize)
                .flat_map(colors)
                .collect(),
        };
        let shown = assert_ids(&image, &expected, &format!("eye {fraction}"));
        assert!(shown > 150, "{shown}");
    }
    release_all(dev, &[camera, world]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn both_cameras_are_advertised_and_bad_parameters_are_reported() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let extensions = device_extensions(dev);
    for name in [
        "ANARI_KHR_CAMERA_OMNIDIRECTIONAL",
        "ANARI_CAVETRACE_CAMERA_FISHEYE",
        "ANARI_KHR_CAMERA_STEREO",
    ] {
        assert!(extensions.iter().any(|e| e == name), "{name} missing");
    }
    let camera = anariNewCamera(dev, c("omnidirectional").as_ptr());
    set_string(dev, camera, "layout", "cubemap");
    commit(dev, camera);
    let errors = log.errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(
        errors[0].1.contains("'layout'") && errors[0].1.contains("cubemap"),
        "{}",
        errors[0].1
    );
    anariRelease(dev, camera);
    let camera = fisheye(dev, [0.0, 0.0, 7.0], 5.0, 0.0, PI);
    let errors = log.errors();
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(
        errors[0].1.contains("'position'") && errors[0].1.contains("inside the dome"),
        "{}",
        errors[0].1
    );
    anariRelease(dev, camera);
    release_device(lib, dev);
}
