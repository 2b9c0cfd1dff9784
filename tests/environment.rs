//! The environment in the default renderer: an hdri light seen by camera rays where it is
//! `visible` (KHR_LIGHT_PRIMARY_VISIBILITY) and in a mirror, against directions computed here
//! in f64; a rough and a near-mirror metal converging under a small bright sun without
//! fireflies (reflections and light samples combined by multiple importance sampling); and the
//! renderer's ambient light occluded by the scene, against the closed form for a plane under a
//! sphere.
mod common;
use common::*;

use std::f64::consts::PI;

/// The synthetic environment: `WIDTH`×`HEIGHT` texels, each a different colour (red by column,
/// green by row, blue in bands of 8 columns), so a pixel's colour names its texel.
const WIDTH: usize = 64;
const HEIGHT: usize = 32;

fn texel(column: usize, row: usize) -> [f32; 3] {
    [
        (column as f32 + 0.5) / WIDTH as f32,
        (row as f32 + 0.5) / HEIGHT as f32,
        ((column / 8) % 2) as f32,
    ]
}

fn environment_texels() -> Vec<[f32; 3]> {
    (0..WIDTH * HEIGHT)
        .map(|k| texel(k % WIDTH, k / WIDTH))
        .collect()
}

type V = [f64; 3];

fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: V) -> V {
    let l = dot(a, a).sqrt();
    a.map(|v| v / l)
}

/// The environment's frame here: image centre along −z (`direction`), first row around +y
/// (`up`), so the column angle runs from −z towards direction × up = +x.
const DIRECTION: [f32; 3] = [0.0, 0.0, -1.0];
const UP: [f32; 3] = [0.0, 1.0, 0.0];

/// The texels a direction may show: the one it falls in, and its neighbours when it lies
/// within `slack` (in texels) of their edge (f32 rounding of the renderer's directions).
fn texels_towards(d: V, slack: f64) -> Vec<(usize, usize)> {
    let (x, y, z) = (-d[2], d[1], d[0]);
    let s = (z.atan2(x) / (2.0 * PI) + 0.5) * WIDTH as f64;
    let t = y.clamp(-1.0, 1.0).acos() / PI * HEIGHT as f64;
    let around = |v: f64, n: usize, wrap: bool| {
        let mut out = Vec::new();
        for candidate in [v - slack, v, v + slack] {
            let i = candidate.floor() as i64;
            let i = if wrap {
                i.rem_euclid(n as i64)
            } else {
                i.clamp(0, n as i64 - 1)
            } as usize;
            if !out.contains(&i) {
                out.push(i);
            }
        }
        out
    };
    let mut out = Vec::new();
    for column in around(s, WIDTH, true) {
        for row in around(t, HEIGHT, false) {
            out.push((column, row));
        }
    }
    out
}

/// An hdri light of `texels` (`width`×`height`) in the frame above.
fn hdri(
    dev: ANARIDevice,
    texels: &[[f32; 3]],
    size: [u64; 2],
    visible: Option<bool>,
) -> ANARILight {
    let image = array2d(dev, ANARI_FLOAT32_VEC3, texels, size);
    let light = anariNewLight(dev, c("hdri").as_ptr());
    set_object(dev, light, "radiance", ANARI_ARRAY2D, image);
    set(dev, light, "direction", ANARI_FLOAT32_VEC3, &DIRECTION);
    set(dev, light, "up", ANARI_FLOAT32_VEC3, &UP);
    if let Some(visible) = visible {
        set(dev, light, "visible", ANARI_BOOL, &u8::from(visible));
    }
    commit(dev, light);
    anariRelease(dev, image);
    light
}

fn metal(dev: ANARIDevice, roughness: f32) -> ANARIMaterial {
    let material = anariNewMaterial(dev, c("physicallyBased").as_ptr());
    set(dev, material, "metallic", ANARI_FLOAT32, &1.0f32);
    set(dev, material, "roughness", ANARI_FLOAT32, &roughness);
    set(dev, material, "baseColor", ANARI_FLOAT32_VEC3, &[1.0f32; 3]);
    commit(dev, material);
    material
}

fn world_with_lights(
    dev: ANARIDevice,
    surfaces: &[ANARISurface],
    lights: &[ANARILight],
) -> ANARIWorld {
    let world = world_of(dev, surfaces);
    let array = object_array(dev, ANARI_LIGHT, lights);
    set_object(dev, world, "light", ANARI_ARRAY1D, array);
    anariRelease(dev, array);
    commit(dev, world);
    world
}

/// Renders `frames` accumulated frames of `samples` pixel samples (`passes`) with the default
/// renderer (background `background` and float parameters `renderer_floats`).
fn render(
    dev: ANARIDevice,
    world: ANARIWorld,
    camera: ANARICamera,
    size: u32,
    passes: (i32, u32),
    background: [f32; 4],
    renderer_floats: &[(&str, f32)],
) -> Vec<[f32; 4]> {
    let (samples, frames) = passes;
    let renderer = anariNewRenderer(dev, c("default").as_ptr());
    set(dev, renderer, "background", ANARI_FLOAT32_VEC4, &background);
    set(dev, renderer, "pixelSamples", ANARI_INT32, &samples);
    for (name, value) in renderer_floats {
        set(dev, renderer, name, ANARI_FLOAT32, value);
    }
    commit(dev, renderer);
    let frame = frame_for(dev, world, camera, renderer, [size, size]);
    set(dev, frame, "accumulation", ANARI_BOOL, &1u8);
    commit(dev, frame);
    let mut color = Vec::new();
    for _ in 0..frames {
        color = render_channel::<[f32; 4]>(dev, frame, "channel.color").0;
    }
    release_all(dev, &[renderer, frame]);
    color
}

const BACKGROUND: [f32; 4] = [0.25, 0.5, 0.75, 1.0];

/// What the camera at the origin looking along −z (fovy 60°, aspect 1) sees through the centre
/// of pixel (i, j) of a `size`² frame when a mirror sphere of radius 1 sits at (0, 0, −4): the
/// direction it looks along after the mirror (if it hits it) and whether it hit it; `None`
/// when the ray grazes the silhouette too closely to tell.
fn mirror_view(i: u32, j: u32, size: u32) -> Option<(V, bool)> {
    let half = (PI / 6.0).tan();
    let u = (2.0 * (f64::from(i) + 0.5) / f64::from(size) - 1.0) * half;
    let v = (2.0 * (f64::from(j) + 0.5) / f64::from(size) - 1.0) * half;
    let d = normalize([u, v, -1.0]);
    let centre = [0.0, 0.0, -4.0];
    // |t d − c|² = 1: t² − 2 t (d·c) + |c|² − 1 = 0.
    let b = dot(d, centre);
    let discriminant = b * b - (dot(centre, centre) - 1.0);
    if discriminant.abs() < 1e-4 {
        return None;
    }
    if discriminant < 0.0 {
        return Some((d, false));
    }
    let t = b - discriminant.sqrt();
    let p = d.map(|x| x * t);
    let n = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
    let k = 2.0 * dot(d, n);
    Some((
        normalize([d[0] - k * n[0], d[1] - k * n[1], d[2] - k * n[2]]),
        true,
    ))
}

#[test]
fn a_mirror_sphere_shows_the_environment_where_its_reflections_point() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let ball = sphere_geometry(dev, &[[0.0, 0.0, -4.0]], 1.0);
    let mirror = metal(dev, 0.0);
    let surface = surface_of(dev, ball, mirror);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], (PI / 3.0) as f32);
    let size = 64;
    for visible in [None, Some(true), Some(false)] {
        let light = hdri(
            dev,
            &environment_texels(),
            [WIDTH as u64, HEIGHT as u64],
            visible,
        );
        let world = world_with_lights(dev, &[surface], &[light]);
        let image = render(dev, world, camera, size, (1, 1), BACKGROUND, &[]);
        let shows_map = visible != Some(false);
        let (mut mirrored, mut seen_directly) = (0, 0);
        for j in 0..size {
            for i in 0..size {
                let Some((direction, on_sphere)) = mirror_view(i, j, size) else {
                    continue;
                };
                let p = image[(j * size + i) as usize];
                let pixel = [p[0], p[1], p[2]];
                if !on_sphere && !shows_map {
                    assert_eq!(p, BACKGROUND, "visible false: pixel ({i}, {j})");
                    continue;
                }
                // Texels are constant: the pixel is its texel exactly, or a neighbour's
                // where the direction lies within f32 rounding of their edge.
                let candidates = texels_towards(direction, 1e-3);
                assert!(
                    candidates
                        .iter()
                        .any(|&(col, row)| texel(col, row) == pixel),
                    "{visible:?}: pixel ({i}, {j}) {pixel:?}, expected texel {:?} = {:?}",
                    candidates[0],
                    texel(candidates[0].0, candidates[0].1)
                );
                assert_eq!(p[3], 1.0);
                if on_sphere {
                    mirrored += 1;
                } else {
                    seen_directly += 1;
                }
            }
        }
        // The sphere covers about a tenth of the frame (radius 1 at 4: sin⁻¹ ¼ of 30°).
        assert!(mirrored > 300, "{mirrored}");
        assert!(!shows_map || seen_directly > 3000, "{seen_directly}");
        release_all(dev, &[light, world]);
    }
    release_all(dev, &[ball, mirror, surface, camera]);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
    release_device(lib, dev);
}

/// A dim sky (0.2) with a small sun of radiance `SUN` (4 texels of 64×32, about 0.2 % of the
/// sphere, high above the horizon in front of the camera's mirror image).
const SUN: f32 = 50.0;

fn sky_with_sun() -> Vec<[f32; 3]> {
    (0..WIDTH * HEIGHT)
        .map(|k| {
            let (column, row) = (k % WIDTH, k / WIDTH);
            // Row 8 is 45°–50.6° from up; columns 30–31 are just left of the centre
            // (−z): the sun stands above and behind the sphere as the camera sees it.
            if (8..10).contains(&row) && (30..32).contains(&column) {
                [SUN; 3]
            } else {
                [0.2; 3]
            }
        })
        .collect()
}

#[test]
fn rough_and_near_mirror_metals_converge_under_a_small_sun_without_fireflies() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let ball = sphere_geometry(dev, &[[0.0, 0.0, -4.0]], 1.0);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], (PI / 3.0) as f32);
    // The sun is behind the camera's view of the sphere... seen reflected: turn the
    // environment so its centre (−z) is behind the camera (+z).
    let light = {
        let image = array2d(
            dev,
            ANARI_FLOAT32_VEC3,
            &sky_with_sun(),
            [WIDTH as u64, HEIGHT as u64],
        );
        let light = anariNewLight(dev, c("hdri").as_ptr());
        set_object(dev, light, "radiance", ANARI_ARRAY2D, image);
        set(
            dev,
            light,
            "direction",
            ANARI_FLOAT32_VEC3,
            &[0.0f32, 0.0, 1.0],
        );
        set(dev, light, "up", ANARI_FLOAT32_VEC3, &UP);
        set(dev, light, "visible", ANARI_BOOL, &0u8);
        commit(dev, light);
        anariRelease(dev, image);
        light
    };
    let size = 32;
    for roughness in [0.05f32, 0.4] {
        let material = metal(dev, roughness);
        let surface = surface_of(dev, ball, material);
        let world = world_with_lights(dev, &[surface], &[light]);
        let at = |samples: i32, frames: u32| {
            render(
                dev,
                world,
                camera,
                size,
                (samples, frames),
                [0.0, 0.0, 0.0, 1.0],
                &[],
            )
        };
        let mean = |image: &[[f32; 4]]| {
            image.iter().map(|p| f64::from(p[0])).sum::<f64>() / image.len() as f64
        };
        let reference = at(64, 16);
        let reference_mean = mean(&reference);
        // The sun shows in the sphere: its highlight lifts the mean well above the sky's.
        let sky_only = 0.2 * 0.1;
        assert!(
            reference_mean > 1.2 * sky_only,
            "{roughness}: {reference_mean}"
        );
        let mut errors = Vec::new();
        for samples in [1, 4, 16, 64] {
            let image = at(samples, 1);
            // No firefly: one sample of a pixel is at most the sun's radiance (a reflection
            // carries the lobe's albedo 1 of what it finds; a light sample of the sun is
            // weighed down where the lobe would have found it).
            for (k, p) in image.iter().enumerate() {
                assert!(
                    p[0] <= SUN,
                    "roughness {roughness}, {samples} samples: pixel {k} is {}",
                    p[0]
                );
            }
            errors.push((mean(&image) - reference_mean).abs() / reference_mean);
        }
        // The mean over the frame approaches the reference as samples grow.
        assert!(errors[3] < 0.03, "roughness {roughness}: {errors:?}");
        assert!(
            errors[3] < errors[0].max(0.01),
            "roughness {roughness}: {errors:?}"
        );
        release_all(dev, &[material, surface, world]);
    }
    release_all(dev, &[ball, camera, light]);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
    release_device(lib, dev);
}

/// The share of uniform light a plane point at horizontal distance `d` from the contact point
/// of a sphere of radius `r` resting on the plane receives (cosine-weighted unoccluded
/// fraction of its hemisphere). The sphere's centre is at distance D = √(d² + r²), seen at
/// elevation θ with sin θ = r/D, and subtends a cap of half-angle α with sin α = r/D that
/// touches the horizon (θ = α). A cap above the horizon of half-angle α whose axis is at angle
/// β from the normal blocks the cosine-weighted share sin²α·cos β (its projected solid angle
/// over π); here cos β = sin θ = r/D, so 1 − (r/D)³ arrives.
fn unoccluded_share(d: f64, r: f64) -> f64 {
    let ratio = r / (d * d + r * r).sqrt();
    1.0 - ratio.powi(3)
}

/// The same share by quadrature over the hemisphere (cosine-weighted directions on a fine
/// stratified grid, each tested against the sphere), to check the closed form.
fn unoccluded_share_by_quadrature(d: f64, r: f64) -> f64 {
    let n = 600;
    let centre = [-d, r, 0.0];
    let mut open = 0usize;
    for a in 0..n {
        for b in 0..n {
            let (u1, u2) = ((a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64);
            let (radius, angle) = (u1.sqrt(), 2.0 * PI * u2);
            let dir = [
                radius * angle.cos(),
                (1.0 - u1).sqrt(),
                radius * angle.sin(),
            ];
            let along = dot(dir, centre);
            let blocked = along > 0.0 && dot(centre, centre) - along * along < r * r;
            open += usize::from(!blocked);
        }
    }
    open as f64 / (n * n) as f64
}

#[test]
fn the_closed_form_of_a_sphere_occluding_a_plane_matches_quadrature() {
    for d in [1.0, 1.3, 2.0, 4.0] {
        let (closed, numeric) = (
            unoccluded_share(d, 1.0),
            unoccluded_share_by_quadrature(d, 1.0),
        );
        assert!(
            (closed - numeric).abs() < 2e-3,
            "d {d}: {closed} vs {numeric}"
        );
    }
}

/// A white floor (y = 0) with a unit sphere resting on it at the origin, under ambient light
/// alone, seen from straight above by an orthographic camera `VIEW` wide: pixel (i, j) sees
/// the floor point x = −VIEW/2 + (i+½)·VIEW/size, z = VIEW/2 − (j+½)·VIEW/size.
const VIEW: f64 = 6.0;

struct FloorScene {
    objects: Vec<ANARIObject>,
    world: ANARIWorld,
    camera: ANARICamera,
}

fn floor_and_sphere(dev: ANARIDevice) -> FloorScene {
    let h = 50.0f32;
    let floor = triangle_geometry(
        dev,
        &[
            [-h, 0.0, -h],
            [h, 0.0, h],
            [h, 0.0, -h],
            [-h, 0.0, -h],
            [-h, 0.0, h],
            [h, 0.0, h],
        ],
    );
    let floor_surface = matte_surface(dev, floor, [1.0; 3]);
    let ball = sphere_geometry(dev, &[[0.0, 1.0, 0.0]], 1.0);
    let ball_surface = matte_surface(dev, ball, [1.0; 3]);
    let world = world_of(dev, &[floor_surface, ball_surface]);
    let camera = anariNewCamera(dev, c("orthographic").as_ptr());
    set(
        dev,
        camera,
        "position",
        ANARI_FLOAT32_VEC3,
        &[0.0f32, 5.0, 0.0],
    );
    set(
        dev,
        camera,
        "direction",
        ANARI_FLOAT32_VEC3,
        &[0.0f32, -1.0, 0.0],
    );
    set(dev, camera, "up", ANARI_FLOAT32_VEC3, &[0.0f32, 0.0, -1.0]);
    set(dev, camera, "height", ANARI_FLOAT32, &(VIEW as f32));
    set(dev, camera, "aspect", ANARI_FLOAT32, &1.0f32);
    commit(dev, camera);
    FloorScene {
        objects: vec![floor, floor_surface, ball, ball_surface],
        world,
        camera,
    }
}

/// The floor point's horizontal distance from the contact point over pixel (i, j), at the
/// sub-pixel position (fx, fy) in [0, 1)².
fn floor_distance(i: u32, j: u32, fx: f64, fy: f64, size: u32) -> f64 {
    let step = VIEW / f64::from(size);
    let x = -VIEW / 2.0 + (f64::from(i) + fx) * step;
    let z = VIEW / 2.0 - (f64::from(j) + fy) * step;
    (x * x + z * z).sqrt()
}

#[test]
fn a_sphere_on_a_plane_under_ambient_light_matches_the_closed_form_occlusion() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let scene = floor_and_sphere(dev);
    let size = 48;
    let ambient = [("ambientRadiance", 1.0f32)];
    let image = render(
        dev,
        scene.world,
        scene.camera,
        size,
        (64, 8),
        [0.0, 0.0, 0.0, 1.0],
        &ambient,
    );
    let step = VIEW / f64::from(size);
    let (mut checked, mut worst) = (0, 0.0f64);
    for j in 0..size {
        for i in 0..size {
            // Floor pixels clear of the sphere's outline (radius 1 seen from above).
            if floor_distance(i, j, 0.5, 0.5, size) < 1.0 + step {
                continue;
            }
            // The pixel's samples spread over its area: the closed form averaged over it.
            let n = 8;
            let expected = (0..n * n)
                .map(|k| {
                    let (fx, fy) = ((k % n) as f64 + 0.5, (k / n) as f64 + 0.5);
                    unoccluded_share(
                        floor_distance(i, j, fx / n as f64, fy / n as f64, size),
                        1.0,
                    )
                })
                .sum::<f64>()
                / (n * n) as f64;
            let value = f64::from(image[(j * size + i) as usize][0]);
            let error = (value - expected).abs() / expected;
            worst = worst.max(error);
            assert!(
                error < 0.02,
                "pixel ({i}, {j}) at d = {:.3}: {value} vs {expected}",
                floor_distance(i, j, 0.5, 0.5, size)
            );
            checked += 1;
        }
    }
    assert!(checked > 1500, "{checked}");
    // Contact shading is there: next to the sphere the floor is visibly darker.
    let near = (1.0 - unoccluded_share(1.0 + step, 1.0)) > 0.25;
    assert!(near, "the test's floor pixels include the dark ring");
    eprintln!(
        "ambient occlusion: worst pixel error {:.4} over {checked} pixels",
        worst
    );
    release_all(dev, &scene.objects);
    release_all(dev, &[scene.world, scene.camera]);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
    release_device(lib, dev);
}

#[test]
fn ambient_occlusion_distance_bounds_what_occludes() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let scene = floor_and_sphere(dev);
    let size = 32;
    let render_with = |floats: &[(&str, f32)]| {
        let mut all = vec![("ambientRadiance", 1.0f32)];
        all.extend_from_slice(floats);
        render(
            dev,
            scene.world,
            scene.camera,
            size,
            (16, 1),
            [0.0, 0.0, 0.0, 1.0],
            &all,
        )
    };
    let step = VIEW / f64::from(size);
    let bounded = render_with(&[("ambientOcclusionDistance", 1.0)]);
    let unbounded = render_with(&[]);
    let (mut far, mut near_bounded, mut near_unbounded, mut near_count) = (0, 0.0, 0.0, 0);
    for j in 0..size {
        for i in 0..size {
            let k = (j * size + i) as usize;
            let d_min = floor_distance(i, j, 0.5, 0.5, size) - step;
            if d_min < 1.0 {
                continue;
            }
            // The sphere's nearest point lies √(d² + 1) − 1 away: beyond 1 (d > √3), nothing
            // occludes within reach, and the floor shows the whole ambient light.
            if (d_min * d_min + 1.0).sqrt() - 1.0 > 1.0 {
                assert_eq!(bounded[k][0], 1.0, "pixel ({i}, {j})");
                far += 1;
            } else {
                near_bounded += bounded[k][0];
                near_unbounded += unbounded[k][0];
                near_count += 1;
            }
        }
    }
    assert!(far > 300 && near_count > 20, "{far} {near_count}");
    // Nearer, the part of the sphere within reach still shades the floor, less than all of it.
    let (near_bounded, near_unbounded) = (
        near_bounded / near_count as f32,
        near_unbounded / near_count as f32,
    );
    assert!(near_bounded < 0.97, "{near_bounded}");
    assert!(
        near_unbounded < near_bounded,
        "{near_unbounded} vs {near_bounded}"
    );
    // Distance 0: no occlusion at all, every floor and sphere point as under an open sky.
    let open = render_with(&[("ambientOcclusionDistance", 0.0)]);
    for (k, p) in open.iter().enumerate() {
        assert_eq!(p[0], 1.0, "pixel {k}");
    }
    assert!(log.errors().is_empty());
    // A negative distance is reported and ignored (every surface occludes).
    let reported = render_with(&[("ambientOcclusionDistance", -1.0)]);
    let errors = log.errors();
    assert!(
        errors
            .iter()
            .any(|(code, text)| *code == ANARI_STATUS_INVALID_ARGUMENT
                && text.contains("'ambientOcclusionDistance'")
                && text.contains("-1")),
        "{errors:?}"
    );
    assert_eq!(reported, unbounded);
    release_all(dev, &scene.objects);
    release_all(dev, &[scene.world, scene.camera]);
    release_device(lib, dev);
}

/// Sets float and vector parameters on a new light of `subtype` and commits it.
fn light_with(
    dev: ANARIDevice,
    subtype: &str,
    floats: &[(&str, f32)],
    vectors: &[(&str, [f32; 3])],
    visible: bool,
) -> ANARILight {
    let light = anariNewLight(dev, c(subtype).as_ptr());
    for (name, value) in floats {
        set(dev, light, name, ANARI_FLOAT32, value);
    }
    for (name, value) in vectors {
        set(dev, light, name, ANARI_FLOAT32_VEC3, value);
    }
    set(dev, light, "visible", ANARI_BOOL, &u8::from(visible));
    commit(dev, light);
    light
}

/// Whether `d` (unit) is within `angle` − `margin` of `axis` (Some(true)), beyond `angle` +
/// `margin` (Some(false)) or too near the edge to tell (None); alike for the other shapes.
fn classify(inside_by: f64, margin: f64) -> Option<bool> {
    if inside_by > margin {
        Some(true)
    } else if inside_by < -margin {
        Some(false)
    } else {
        None
    }
}

/// Checks every pixel of a `size`² `image` from the camera at the origin looking along −z
/// (fovy 60°) against `expected` of the pixel centre's unit direction: `Ok(Some((light,
/// radiance)))` where a light shows (in every colour channel), `Ok(None)` where the background
/// does, `Err(())` where it is too near an edge to tell. Returns how many pixels showed each light
/// and the background.
fn check_lights_seen<const N: usize>(
    image: &[[f32; 4]],
    size: u32,
    expected: impl Fn(V) -> Result<Option<(usize, f64)>, ()>,
) -> ([usize; N], usize) {
    let mut seen = [0; N];
    let mut background = 0;
    let half = (PI / 6.0).tan();
    for j in 0..size {
        for i in 0..size {
            let u = (2.0 * (f64::from(i) + 0.5) / f64::from(size) - 1.0) * half;
            let v = (2.0 * (f64::from(j) + 0.5) / f64::from(size) - 1.0) * half;
            let Ok(expected) = expected(normalize([u, v, -1.0])) else {
                continue;
            };
            let p = image[(j * size + i) as usize];
            match expected {
                Some((light, radiance)) => {
                    seen[light] += 1;
                    for value in &p[..3] {
                        let error = (f64::from(*value) - radiance).abs() / radiance;
                        assert!(error < 1e-4, "pixel ({i}, {j}): {p:?} vs {radiance}");
                    }
                    assert_eq!(p[3], 1.0);
                }
                None => {
                    background += 1;
                    assert_eq!(p, BACKGROUND, "pixel ({i}, {j})");
                }
            }
        }
    }
    (seen, background)
}

#[test]
fn visible_lights_with_extent_are_seen_by_camera_rays_with_their_radiance() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // Every light takes `visible`, so the extension is advertised.
    let extensions = device_extensions(dev);
    assert!(
        extensions
            .iter()
            .any(|e| e == "ANARI_KHR_LIGHT_PRIMARY_VISIBILITY"),
        "{extensions:?}"
    );
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], (PI / 3.0) as f32);
    let sun = normalize([-0.3, 0.35, -1.0]);
    let (ring_inner, ring_outer, ring_intensity) = (0.3f64, 0.6f64, 2.0f64);
    let lights = |visible: bool| {
        vec![
            light_with(
                dev,
                "quad",
                &[("radiance", 3.0)],
                &[
                    ("position", [-2.5, -0.5, -5.0]),
                    ("edge1", [1.0, 0.0, 0.0]),
                    ("edge2", [0.0, 1.0, 0.0]),
                ],
                visible,
            ),
            light_with(
                dev,
                "point",
                &[("radius", 0.5), ("radiance", 4.0)],
                &[("position", [1.5, 1.0, -5.0])],
                visible,
            ),
            light_with(
                dev,
                "ring",
                &[
                    ("radius", ring_outer as f32),
                    ("innerRadius", ring_inner as f32),
                    ("intensity", ring_intensity as f32),
                ],
                &[
                    ("position", [1.5, -1.2, -5.0]),
                    ("direction", [0.0, 0.0, 1.0]),
                ],
                visible,
            ),
            light_with(
                dev,
                "directional",
                &[("angularDiameter", 0.2), ("radiance", 5.0)],
                &[("direction", sun.map(|v| -v as f32))],
                visible,
            ),
            // Without extent: never seen.
            light_with(
                dev,
                "point",
                &[],
                &[("position", [0.0, 0.0, -3.0])],
                visible,
            ),
            light_with(
                dev,
                "spot",
                &[],
                &[
                    ("position", [0.0, 0.0, -3.0]),
                    ("direction", [0.0, 0.0, 1.0]),
                ],
                visible,
            ),
        ]
    };
    let size = 64;
    for visible in [true, false] {
        let lights = lights(visible);
        let world = world_with_lights(dev, &[], &lights);
        let image = render(dev, world, camera, size, (1, 1), BACKGROUND, &[]);
        let (seen, _) = check_lights_seen::<4>(&image, size, |d| {
            // Where the ray crosses the lights' plane z = −5.
            let p = d.map(|x| x * 5.0 / -d[2]);
            let m = 0.05;
            let quad = classify(
                (p[0] + 2.5)
                    .min(-1.5 - p[0])
                    .min(p[1] + 0.5)
                    .min(0.5 - p[1]),
                m,
            );
            let centre = [1.5, 1.0, -5.0];
            let along = dot(centre, d);
            let miss = (dot(centre, centre) - along * along).sqrt();
            let sphere = classify(0.5 - miss, m / 5.0);
            let rho = ((p[0] - 1.5).powi(2) + (p[1] + 1.2).powi(2)).sqrt();
            let ring = classify((rho - ring_inner).min(ring_outer - rho), m);
            let disk = classify(0.1 - dot(d, sun).clamp(-1.0, 1.0).acos(), 0.01);
            if [quad, sphere, ring, disk].contains(&None) {
                return Err(());
            }
            Ok(if !visible {
                None
            } else if quad == Some(true) {
                Some((0, 3.0))
            } else if sphere == Some(true) {
                Some((1, 4.0))
            } else if ring == Some(true) {
                // The ring's intensity per area over the projected area.
                let area = PI * (ring_outer.powi(2) - ring_inner.powi(2));
                Some((2, ring_intensity / (area * -d[2])))
            } else if disk == Some(true) {
                Some((3, 5.0))
            } else {
                None
            })
        });
        if visible {
            assert!(seen.iter().all(|&n| n >= 8), "{seen:?}");
        }
        release_all(dev, &lights);
        anariRelease(dev, world);
    }
    anariRelease(dev, camera);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
    release_device(lib, dev);
}

/// Which of the mirrored lights of the test below a camera ray along unit `d` sees, and its
/// radiance there (None: the background); `Err(())` too near an edge to tell. A mirror in the
/// plane z = −4 shows a point (x, y, z) at (x, y, −8 − z), so each light is looked up where the
/// ray meets its mirror image.
fn mirrored_light_towards(d: V, ring: (f64, f64, f64)) -> Result<Option<(usize, f64)>, ()> {
    let at_depth = |z: f64| d.map(|x| x * z / d[2]);
    let m = 0.05;
    // The front-facing quad: x ∈ [−2, −1], y ∈ [−1.5, −0.5] at z = 1, seen at z = −9.
    let p = at_depth(-9.0);
    let quad = classify(
        (p[0] + 2.0)
            .min(-1.0 - p[0])
            .min(p[1] + 1.5)
            .min(-0.5 - p[1]),
        m,
    );
    // The back-facing quad: x ∈ [0, 1], y ∈ [−1.5, −0.5], also at z = 1: never seen.
    let away = classify(p[0].min(1.0 - p[0]).min(p[1] + 1.5).min(-0.5 - p[1]), m);
    // The sphere light of radius 0.5 at (1.5, 1, 2), seen at (1.5, 1, −10).
    let centre = [1.5, 1.0, -10.0];
    let along = dot(centre, d);
    let miss = (dot(centre, centre) - along * along).sqrt();
    let sphere = classify(0.5 - miss, m / 10.0);
    // The ring around (−1.5, 1.2, 1.5) facing −z, seen at z = −9.5.
    let (inner, outer, intensity) = ring;
    let p = at_depth(-9.5);
    let rho = ((p[0] + 1.5).powi(2) + (p[1] - 1.2).powi(2)).sqrt();
    let annulus = classify((rho - inner).min(outer - rho), m);
    if [quad, away, sphere, annulus].contains(&None) {
        return Err(());
    }
    Ok(if quad == Some(true) {
        Some((0, 3.0))
    } else if sphere == Some(true) {
        Some((1, 4.0))
    } else if annulus == Some(true) {
        // The reflected ray meets the ring at the angle the camera ray meets the mirror.
        let area = PI * (outer * outer - inner * inner);
        Some((2, intensity / (area * -d[2])))
    } else {
        None
    })
}

#[test]
fn a_flat_mirror_shows_quad_sphere_and_ring_lights_where_their_images_are() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], (PI / 3.0) as f32);
    // A perfect mirror filling the view at z = −4, facing the camera.
    let s = 10.0f32;
    let mirror = triangle_geometry(
        dev,
        &[
            [-s, -s, -4.0],
            [s, -s, -4.0],
            [s, s, -4.0],
            [-s, -s, -4.0],
            [s, s, -4.0],
            [-s, s, -4.0],
        ],
    );
    let material = metal(dev, 0.0);
    let surface = surface_of(dev, mirror, material);
    let ring = (0.3f64, 0.6f64, 2.0f64);
    // Behind the camera, facing the mirror, so only the mirror can show them.
    let lights = |visible: bool| {
        vec![
            // edge1 × edge2 = −z: its front faces the mirror.
            light_with(
                dev,
                "quad",
                &[("radiance", 3.0)],
                &[
                    ("position", [-2.0, -1.5, 1.0]),
                    ("edge1", [0.0, 1.0, 0.0]),
                    ("edge2", [1.0, 0.0, 0.0]),
                ],
                visible,
            ),
            // edge1 × edge2 = +z: its front faces away from the mirror.
            light_with(
                dev,
                "quad",
                &[("radiance", 7.0)],
                &[
                    ("position", [0.0, -1.5, 1.0]),
                    ("edge1", [1.0, 0.0, 0.0]),
                    ("edge2", [0.0, 1.0, 0.0]),
                ],
                visible,
            ),
            light_with(
                dev,
                "point",
                &[("radius", 0.5), ("radiance", 4.0)],
                &[("position", [1.5, 1.0, 2.0])],
                visible,
            ),
            light_with(
                dev,
                "ring",
                &[
                    ("radius", ring.1 as f32),
                    ("innerRadius", ring.0 as f32),
                    ("intensity", ring.2 as f32),
                ],
                &[
                    ("position", [-1.5, 1.2, 1.5]),
                    ("direction", [0.0, 0.0, -1.0]),
                ],
                visible,
            ),
        ]
    };
    let size = 96;
    // `visible` is primary visibility: the mirror shows the lights either way.
    for visible in [true, false] {
        let lights = lights(visible);
        let world = world_with_lights(dev, &[surface], &lights);
        let image = render(dev, world, camera, size, (1, 1), BACKGROUND, &[]);
        let (seen, background) =
            check_lights_seen::<3>(&image, size, |d| mirrored_light_towards(d, ring));
        assert!(seen.iter().all(|&n| n >= 8), "{seen:?}");
        assert!(background > (size * size / 2) as usize, "{background}");
        release_all(dev, &lights);
        anariRelease(dev, world);
    }
    release_all(dev, &[surface, material, mirror, camera]);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
    release_device(lib, dev);
}
