//! The physicallyBased material's GGX microfacet lobes in the default renderer (glTF 2.0
//! Appendix B): a highlight under a directional light against F·D·V·(n·l)·E, its width by
//! roughness, rough reflections converging over samples, and the white furnace with
//! multiple-scattering compensation.

mod common;
use std::f64::consts::PI;

use common::*;

const SIZE: u32 = 48;
const VIEW: f32 = 2.4;

/// A metal of `base` colour and `roughness`.
fn metal(dev: ANARIDevice, base: f32, roughness: f32) -> ANARIMaterial {
    let material = anariNewMaterial(dev, c("physicallyBased").as_ptr());
    set(dev, material, "metallic", ANARI_FLOAT32, &1.0f32);
    set(dev, material, "roughness", ANARI_FLOAT32, &roughness);
    set(dev, material, "baseColor", ANARI_FLOAT32_VEC3, &[base; 3]);
    commit(dev, material);
    material
}

struct Setup {
    ambient: f32,
    background: [f32; 4],
    samples: i32,
    size: u32,
}

/// The default renderer's colour image of `surfaces` with `lights`, seen along −z by an
/// orthographic camera `VIEW` high.
fn image(
    dev: ANARIDevice,
    surfaces: &[ANARISurface],
    lights: &[ANARILight],
    s: &Setup,
) -> Vec<[f32; 4]> {
    let world = world_of(dev, surfaces);
    if !lights.is_empty() {
        let array = object_array(dev, ANARI_LIGHT, lights);
        set_object(dev, world, "light", ANARI_ARRAY1D, array);
        anariRelease(dev, array);
        commit(dev, world);
    }
    let camera = orthographic_camera(dev, [0.0, 0.0, 5.0], VIEW);
    let renderer = anariNewRenderer(dev, c("default").as_ptr());
    set(dev, renderer, "ambientRadiance", ANARI_FLOAT32, &s.ambient);
    set(
        dev,
        renderer,
        "background",
        ANARI_FLOAT32_VEC4,
        &s.background,
    );
    set(dev, renderer, "pixelSamples", ANARI_INT32, &s.samples);
    commit(dev, renderer);
    let frame = frame_for(dev, world, camera, renderer, [s.size, s.size]);
    let (colors, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    release_all(dev, &[world, camera, renderer, frame]);
    colors
}

/// The unit sphere's normal seen at the centre of pixel (i, j), if the pixel's ray hits it.
fn sphere_normal(i: u32, j: u32, size: u32) -> Option<[f64; 3]> {
    let step = f64::from(VIEW) / f64::from(size);
    let x = -f64::from(VIEW) / 2.0 + (f64::from(i) + 0.5) * step;
    let y = -f64::from(VIEW) / 2.0 + (f64::from(j) + 0.5) * step;
    let r2 = x * x + y * y;
    (r2 < 1.0).then(|| [x, y, (1.0 - r2).sqrt()])
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    a.map(|v| v / l)
}

fn ggx(alpha: f64, cos_h: f64) -> f64 {
    let a2 = alpha * alpha;
    let d = cos_h * cos_h * (a2 - 1.0) + 1.0;
    a2 / (PI * d * d)
}

fn visibility(alpha: f64, cos_l: f64, cos_v: f64) -> f64 {
    let a2 = alpha * alpha;
    let gv = cos_l * (cos_v * cos_v * (1.0 - a2) + a2).sqrt();
    let gl = cos_v * (cos_l * cos_l * (1.0 - a2) + a2).sqrt();
    0.5 / (gv + gl)
}

/// ∫ D V (n·l) dω by quadrature (double precision): the lobe's single-scattering albedo.
fn albedo(alpha: f64, cos_v: f64) -> f64 {
    let v = [(1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v];
    let (rings, sectors) = (800, 800);
    let mut sum = 0.0;
    for i in 0..rings {
        let cos_l = (f64::from(i) + 0.5) / f64::from(rings);
        let sin_l = (1.0 - cos_l * cos_l).sqrt();
        for k in 0..sectors {
            let phi = 2.0 * PI * (f64::from(k) + 0.5) / f64::from(sectors);
            let l = [sin_l * phi.cos(), sin_l * phi.sin(), cos_l];
            let h = normalize([v[0] + l[0], v[1] + l[1], v[2] + l[2]]);
            sum += ggx(alpha, h[2]) * visibility(alpha, cos_l, cos_v) * cos_l;
        }
    }
    sum / f64::from(rings) * 2.0 * PI / f64::from(sectors)
}

/// A directional light arriving from `to_light` with irradiance 1.
fn light_from(dev: ANARIDevice, to_light: [f32; 3]) -> ANARILight {
    directional_light(dev, to_light.map(|v| -v))
}

/// The highlight of a metal sphere of `roughness` and grey `base` under a directional light
/// from `to_light`, black surroundings: the image's red channel.
fn highlight(dev: ANARIDevice, base: f32, roughness: f32, to_light: [f32; 3]) -> Vec<f32> {
    let ball = sphere_geometry(dev, &[[0.0, 0.0, 0.0]], 1.0);
    let material = metal(dev, base, roughness);
    let surface = surface_of(dev, ball, material);
    let light = light_from(dev, to_light);
    let setup = Setup {
        ambient: 0.0,
        background: [0.0, 0.0, 0.0, 1.0],
        samples: 1,
        size: SIZE,
    };
    let pixels = image(dev, &[surface], &[light], &setup);
    release_all(dev, &[ball, material, surface, light]);
    pixels.iter().map(|p| p[0]).collect()
}

#[test]
fn a_highlight_peaks_at_f_d_v_cos_where_the_half_vector_is_the_normal() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let (base, roughness) = (0.6f64, 0.3f64);
    let to_light = normalize([0.4, 0.25, 1.0]);
    let view = [0.0, 0.0, 1.0];
    let half = normalize([to_light[0], to_light[1], to_light[2] + 1.0]);
    let red = highlight(
        dev,
        base as f32,
        roughness as f32,
        to_light.map(|v| v as f32),
    );
    let alpha = roughness * roughness;
    // F·D·V·(n·l)·E with glTF's conductor Fresnel (Schlick from the base colour at v·h) and the
    // multiple-scattering compensation 1 + F0 (1 − E_ss)/E_ss.
    let expected = |n: [f64; 3]| {
        let cos_l = dot(n, to_light);
        let cos_v = dot(n, view);
        if cos_l <= 0.0 {
            return 0.0;
        }
        let h = half;
        let cos_vh = dot(view, h);
        let fresnel = base + (1.0 - base) * (1.0 - cos_vh).powi(5);
        let e = albedo(alpha, cos_v);
        let compensation = 1.0 + base * (1.0 - e) / e;
        fresnel * ggx(alpha, dot(n, h)) * visibility(alpha, cos_l, cos_v) * cos_l * compensation
    };
    // The pixel whose normal is nearest the half vector: there D = 1/(π α²).
    let (mut best, mut best_cos) = (0usize, -1.0);
    for j in 0..SIZE {
        for i in 0..SIZE {
            if let Some(n) = sphere_normal(i, j, SIZE) {
                let cos = dot(n, half);
                if cos > best_cos {
                    (best, best_cos) = ((j * SIZE + i) as usize, cos);
                }
            }
        }
    }
    let n = sphere_normal(best as u32 % SIZE, best as u32 / SIZE, SIZE).unwrap();
    assert!(best_cos > 0.999, "{best_cos}");
    let peak = expected(n);
    assert!(
        (f64::from(red[best]) - peak).abs() < 0.01 * peak,
        "peak: rendered {}, closed form {peak} (D at h = n: {})",
        red[best],
        1.0 / (PI * alpha * alpha)
    );
    // The brightest pixel is that one, and the closed form holds across the highlight.
    let brightest = (0..red.len())
        .max_by(|&a, &b| red[a].total_cmp(&red[b]))
        .unwrap();
    assert_eq!(brightest, best);
    for j in (0..SIZE).step_by(5) {
        for i in (0..SIZE).step_by(5) {
            if let Some(n) = sphere_normal(i, j, SIZE) {
                let k = (j * SIZE + i) as usize;
                let e = expected(n);
                assert!(
                    (f64::from(red[k]) - e).abs() < 0.01 * e + 1e-4,
                    "pixel ({i}, {j}): rendered {}, closed form {e}",
                    red[k]
                );
            }
        }
    }
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn the_highlight_widens_and_dims_with_roughness() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let to_light = [0.3f32, 0.2, 1.0];
    let mut previous: Option<(f32, usize)> = None;
    for roughness in [0.15f32, 0.3, 0.5] {
        let red = highlight(dev, 1.0, roughness, to_light);
        let peak = red.iter().copied().fold(0.0, f32::max);
        let wide = red.iter().filter(|&&v| v > 0.5 * peak).count();
        if let Some((last_peak, last_wide)) = previous {
            assert!(
                peak < last_peak,
                "roughness {roughness}: peak {peak} vs {last_peak}"
            );
            assert!(
                wide > last_wide,
                "roughness {roughness}: {wide} vs {last_wide} pixels"
            );
        }
        previous = Some((peak, wide));
    }
    // Roughness 0 is a mirror: a directional light leaves no highlight.
    let mirror = highlight(dev, 1.0, 0.0, to_light);
    assert!(mirror.iter().all(|&v| v == 0.0));
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn a_rough_metal_returns_all_light_of_a_white_furnace() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let ball = sphere_geometry(dev, &[[0.0, 0.0, 0.0]], 1.0);
    let furnace = Setup {
        ambient: 1.0,
        background: [1.0; 4],
        samples: 1,
        size: 32,
    };
    for roughness in [0.2f32, 0.5, 1.0] {
        let material = metal(dev, 1.0, roughness);
        let surface = surface_of(dev, ball, material);
        let pixels = image(dev, &[surface], &[], &furnace);
        for (k, p) in pixels.iter().enumerate() {
            // Each sample carries the compensated lobe's whole albedo, 1; a few rim samples
            // find no reflection within their draws.
            let inside =
                sphere_normal(k as u32 % 32, k as u32 / 32, 32).is_some_and(|n| n[2] > 0.3);
            assert!(p[0] <= 1.0 + 1e-4, "roughness {roughness}: {p:?}");
            if inside {
                assert!(p[0] >= 0.999, "roughness {roughness}, pixel {k}: {p:?}");
            }
        }
        release_all(dev, &[material, surface]);
    }
    anariRelease(dev, ball);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn rough_reflections_converge_over_samples() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // A rough white metal floor facing the camera; behind the camera a white emitter over
    // the half of the sky towards +x, which the floor's lobe reflects in part.
    let floor = triangle_geometry(
        dev,
        &[[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [0.0, 10.0, 0.0]],
    );
    let material = metal(dev, 1.0, 0.5);
    let floor_surface = surface_of(dev, floor, material);
    let emitter = triangle_geometry(
        dev,
        &[[0.0, -50.0, 6.0], [50.0, 0.0, 6.0], [0.0, 50.0, 6.0]],
    );
    let glow = anariNewMaterial(dev, c("physicallyBased").as_ptr());
    set(dev, glow, "baseColor", ANARI_FLOAT32_VEC3, &[0.0f32; 3]);
    set(dev, glow, "emissive", ANARI_FLOAT32_VEC3, &[1.0f32; 3]);
    commit(dev, glow);
    let emitter_surface = surface_of(dev, emitter, glow);
    let surfaces = [floor_surface, emitter_surface];
    let at = |samples: i32| {
        let setup = Setup {
            ambient: 0.0,
            background: [0.0, 0.0, 0.0, 1.0],
            samples,
            size: 8,
        };
        image(dev, &surfaces, &[], &setup)
    };
    let reference = at(1024);
    let error = |samples: i32| {
        let pixels = at(samples);
        pixels
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a[0] - b[0]).abs())
            .sum::<f32>()
            / pixels.len() as f32
    };
    // Half the lobe sees the emitter somewhere on the floor: a value between 0 and 1.
    let middle = reference[(4 * 8 + 4) as usize][0];
    assert!(middle > 0.1 && middle < 0.9, "{middle}");
    let (e1, e16, e256) = (error(1), error(16), error(256));
    assert!(e16 < 0.5 * e1 && e256 < 0.5 * e16, "{e1} {e16} {e256}");
    assert!(e256 < 0.01, "{e256}");
    release_all(
        dev,
        &[
            floor,
            material,
            floor_surface,
            emitter,
            glow,
            emitter_surface,
        ],
    );
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}
