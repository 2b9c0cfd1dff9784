//! Lit volumes (the default renderer): single scattering of the scene's lights and the
//! renderer's ambient light by the volumes' particles. At each marching sample the transfer
//! function's opacity gives the extinction and its colour the share of it that scatters (the
//! albedo); the phase function is isotropic, as `transferFunction1D` has no anisotropy. Light
//! is gathered at a few points per ray drawn from the opacity along it: from each of the
//! scene's lights through one shadow ray, blocked by surfaces and attenuated by the volumes it
//! crosses; and from the ambient light, radiance A from every direction, through one ray in a
//! uniformly drawn direction, attenuated the same way within the renderer's
//! `ambientOcclusionDistance`. With that distance 0 the ambient light is not occluded: every
//! particle scatters A × colour per unit of opacity, as the emission–absorption model draws it.
//! Sample positions, lighting points and directions follow the frame's sample index, so
//! pixelSamples and accumulation converge to the integral.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use crate::accel::{Ray, surface_epsilon};
use crate::render::ambient::reaches_ambient;
use crate::render::renderer::RendererSettings;
use crate::scene::light::{Incoming, LightSampling, radical_inverse};
use crate::scene::volume::{Stepping, VolumeIntegral, march, transmittance};
use crate::scene::world::SceneSnapshot;

/// Points per ray where the scene's lights are gathered. They split the light the ray's
/// volumes scatter into equal parts (see [`lit_volumes_with`]).
pub(crate) const LIGHTING_POINTS: u32 = 8;

/// The isotropic phase function: 1 / 4π per steradian.
const ISOTROPIC_PHASE: f32 = 1.0 / (4.0 * PI);

/// How far into its stretch each marching sample is taken for this sample index: 0 for the
/// first sample, then Roberts' R1 sequence (the golden ratio's additive recurrence), the same
/// in every pixel, so any number of samples covers the stretch evenly.
pub fn step_jitter(sampling: &LightSampling) -> f32 {
    // 2³² / φ in fixed point.
    let bits = sampling.index.wrapping_mul(2_654_435_769);
    (bits >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Offset in [0, 1) of the lighting points along the ray's opacity: a base-2 radical inverse
/// of the sample index, rotated per pixel.
fn lighting_offset(sampling: &LightSampling) -> f32 {
    let u = (radical_inverse(sampling.index, 2) + sampling.scramble.y).fract();
    u.min(1.0 - f32::EPSILON)
}

/// The volumes' transmittance along a shadow ray from `origin` towards a light, for `t` in
/// [`t_min`, `t_max`]: what reaches a surface or a volume's particle through the volumes.
pub fn shadow_transmittance(
    scene: &SceneSnapshot,
    origin: Vec3,
    direction: Vec3,
    t_min: f32,
    t_max: f32,
    sampling: &LightSampling,
) -> f32 {
    if scene.volumes.is_empty() {
        return 1.0;
    }
    let jitter = step_jitter(sampling);
    transmittance(
        &scene.volumes,
        origin,
        direction,
        (t_min, t_max),
        jitter,
        Stepping::DEFAULT,
    )
    .0
}

/// Where a shadow ray from `point` towards `incoming` ends: short of the light's point, or
/// nowhere for a light at infinity.
fn shadow_ray_end(point: Vec3, incoming: &Incoming) -> f32 {
    if incoming.distance.is_finite() {
        let light_point = point + incoming.to_light * incoming.distance;
        incoming.distance - surface_epsilon(light_point)
    } else {
        f32::INFINITY
    }
}

/// Light scattered towards the viewer per unit of scattering at `point` inside a volume: each
/// light's radiance (a sample of it for lights with extent) times the phase function, times
/// what reaches the point past surfaces and volumes.
fn in_scattered(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    point: Vec3,
    sampling: &LightSampling,
    cost: &mut Cost,
) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for light in &scene.lights {
        let Some(incoming) = light.incoming_sampled(point, sampling) else {
            continue;
        };
        let mut visibility = 1.0;
        if settings.shadows {
            let ray = Ray {
                origin: point,
                direction: incoming.to_light,
                t_min: surface_epsilon(point),
                t_max: shadow_ray_end(point, &incoming),
            };
            // Cluster hook: shadow rays are tested on every rank.
            if crate::render::cluster::occluded(scene, &ray) {
                continue;
            }
            let (through, taken) = transmittance(
                &scene.volumes,
                ray.origin,
                ray.direction,
                (ray.t_min, ray.t_max),
                step_jitter(sampling),
                cost.stepping,
            );
            cost.samples += taken;
            visibility = through;
        }
        sum += incoming.radiance * visibility;
    }
    sum * ISOTROPIC_PHASE
}

/// Whether the ambient light scattered inside volumes is occluded by the scene.
fn ambient_occluded(settings: &RendererSettings) -> bool {
    settings.ambient != Vec3::ZERO && settings.ambient_occlusion_distance > 0.0
}

/// The share of the ambient light that reaches `point` inside a volume: one ray in a direction
/// drawn uniformly over the sphere (the isotropic phase function's own distribution), blocked
/// by opaque surfaces and attenuated by the volumes within `ambientOcclusionDistance`. Its
/// mean over samples is the sphere's mean transmittance.
fn ambient_reaching(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    point: Vec3,
    sampling: &LightSampling,
    cost: &mut Cost,
) -> f32 {
    let u = sampling.ambient_point(0);
    let z = 1.0 - 2.0 * u.x;
    let radius = (1.0 - z * z).max(0.0).sqrt();
    let angle = 2.0 * PI * u.y;
    let direction = Vec3::new(radius * angle.cos(), radius * angle.sin(), z);
    let ray = Ray {
        origin: point,
        direction,
        t_min: surface_epsilon(point),
        t_max: settings.ambient_occlusion_distance,
    };
    if !reaches_ambient(scene, &ray) {
        return 0.0;
    }
    let (through, taken) = transmittance(
        &scene.volumes,
        ray.origin,
        ray.direction,
        (ray.t_min, ray.t_max),
        step_jitter(sampling),
        cost.stepping,
    );
    cost.samples += taken;
    through
}

/// How shadow and ambient rays are marched, and the field samples taken so far.
struct Cost {
    stepping: Stepping,
    samples: u32,
}

/// The lit volumes between `ray`'s start and `t_end` (the default renderer); `None` when no
/// volume overlaps that stretch.
pub fn lit_volumes(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    t_end: f32,
    sampling: &LightSampling,
) -> Option<VolumeIntegral> {
    lit_volumes_with(scene, settings, ray, t_end, sampling, Stepping::DEFAULT)
        .map(|(integral, _)| integral)
}

/// [`lit_volumes`], its samples placed by `stepping`, and the number of field samples taken
/// (camera, shadow and ambient rays).
///
/// The march runs twice. The first pass finds the transmittance, the ambient light scattered
/// where it is not occluded, and the fraction W of the light from behind that the volumes take
/// out. The second places `LIGHTING_POINTS` points where the fraction taken out so far,
/// 1 − T(s), reaches
/// W·(k + u)/K: points drawn in proportion to T·σ (stratified, offset u per sample), so each
/// stands for W/K of the scattering integral ∫ T(s)·σ(s)·colour(s)·L_in(s) ds. Within a
/// marching stretch the optical depth grows linearly, so the point is placed exactly. Where
/// the ambient light is occluded, each point also gathers it (the light term L_in holds both).
pub fn lit_volumes_with(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    t_end: f32,
    sampling: &LightSampling,
    stepping: Stepping,
) -> Option<(VolumeIntegral, u32)> {
    let volumes = &scene.volumes;
    let (origin, direction) = (ray.origin, ray.direction);
    let jitter = step_jitter(sampling);
    let mut result = VolumeIntegral::default();
    // The fraction taken out before marching stopped (the transmittance is then set to 0).
    let mut taken_out = 0.0f32;
    let occluded_ambient = ambient_occluded(settings);
    let unoccluded_ambient = if occluded_ambient {
        Vec3::ZERO
    } else {
        settings.ambient
    };
    let mut samples = march(
        volumes,
        origin,
        direction,
        ray.t_min,
        t_end,
        jitter,
        stepping,
        |step| {
            taken_out = 1.0 - result.transmittance * step.transmittance();
            result.absorb(step, step.color * unoccluded_ambient)
        },
    )?;
    if (scene.lights.is_empty() && !occluded_ambient) || taken_out <= 0.0 {
        return Some((result, samples));
    }
    let offset = lighting_offset(sampling);
    let target = |k: u32| taken_out * (k as f32 + offset) / LIGHTING_POINTS as f32;
    let mut next = 0u32;
    let mut through = 1.0f32;
    let mut gathered = Vec3::ZERO;
    let mut shadow = Cost {
        stepping,
        samples: 0,
    };
    samples += march(
        volumes,
        origin,
        direction,
        ray.t_min,
        t_end,
        jitter,
        stepping,
        |step| {
            let after = through * step.transmittance();
            while next < LIGHTING_POINTS && target(next) <= 1.0 - after {
                // Solve 1 − through·exp(−τ·x) = target for the fraction x of the stretch.
                let remaining = 1.0 - target(next);
                let x = if step.optical_depth.is_finite() && step.optical_depth > 0.0 {
                    ((through / remaining).ln() / step.optical_depth).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let t = step.begin + step.dt * x;
                let point_sampling = LightSampling {
                    index: sampling
                        .index
                        .wrapping_mul(LIGHTING_POINTS)
                        .wrapping_add(next),
                    scramble: sampling.scramble,
                };
                let point = origin + direction * t;
                let mut light = in_scattered(scene, settings, point, &point_sampling, &mut shadow);
                if occluded_ambient {
                    light += settings.ambient
                        * ambient_reaching(scene, settings, point, &point_sampling, &mut shadow);
                }
                gathered += step.color * light;
                next += 1;
            }
            through = after;
            next < LIGHTING_POINTS
        },
    )
    .unwrap_or(0);
    result.color += gathered * (taken_out / LIGHTING_POINTS as f32);
    Some((result, samples + shadow.samples))
}

/// The scramble-free sampling of sample `index` (tests and benchmarks).
pub fn sample_index(index: u32) -> LightSampling {
    LightSampling {
        index,
        scramble: Vec2::ZERO,
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::time::Instant;

    use glam::{Affine3A, Vec4};

    use super::*;
    use crate::scene::light::Light;
    use crate::scene::spatial_field::StructuredRegularField;
    use crate::scene::unstructured_field::from_cells;
    use crate::scene::volume::{PlacedVolume, TransferFunction};

    /// Transparent below 0.5, then opaque towards 1; orange.
    fn ramp() -> Arc<TransferFunction> {
        let colors = vec![Vec4::new(1.0, 0.6, 0.2, 1.0)];
        let opacities = vec![0.0, 0.0, 0.3, 0.9];
        Arc::new(TransferFunction::new(1, (0.0, 1.0), colors, opacities, 0.05).unwrap())
    }

    /// A 64³ grid over [0, 1]³ whose values exceed 0.5 only in a ball of radius 0.2 around
    /// (0.7, 0.3, 0.6): mostly empty space.
    fn mostly_empty_grid() -> PlacedVolume {
        ball_grid(0.0)
    }

    /// [`mostly_empty_grid`]'s ball in a fog whose values wave between 0 and `fog` (period
    /// about a quarter of the box, 16 cells).
    fn ball_grid(fog: f32) -> PlacedVolume {
        let n = 64;
        let spacing = 1.0 / (n - 1) as f32;
        let centre = Vec3::new(0.7, 0.3, 0.6);
        let values = (0..n * n * n)
            .map(|i| {
                let p = Vec3::new((i % n) as f32, ((i / n) % n) as f32, (i / (n * n)) as f32);
                let d = (p * spacing - centre).length();
                let ball = (1.0 - d / 0.4).max(0.0);
                if fog == 0.0 {
                    return ball;
                }
                let q = p * spacing;
                let wave = (25.0 * q.x).sin() * (21.0 * q.y).sin() * (29.0 * q.z).sin();
                ball + fog * (0.5 + 0.5 * wave)
            })
            .collect();
        let field = StructuredRegularField::from_floats(
            [n; 3],
            values,
            Vec3::ZERO,
            Vec3::splat(spacing),
            false,
        )
        .unwrap();
        PlacedVolume::new(ramp(), Arc::new(field), Affine3A::IDENTITY, 0)
    }

    /// Two hexahedra at opposite corners of [0, 4]³ and one tiny tetrahedron at the far corner
    /// (which sets the bounds); values from 0 to 1 over each hexahedron.
    fn sparse_cells() -> PlacedVolume {
        let cube = |o: Vec3, s: f32| {
            [
                (0.0, 0.0, 0.0),
                (1.0, 0.0, 0.0),
                (1.0, 1.0, 0.0),
                (0.0, 1.0, 0.0),
                (0.0, 0.0, 1.0),
                (1.0, 0.0, 1.0),
                (1.0, 1.0, 1.0),
                (0.0, 1.0, 1.0),
            ]
            .map(|(x, y, z)| o + Vec3::new(x, y, z) * s)
        };
        let mut positions = cube(Vec3::ZERO, 1.0).to_vec();
        positions.extend(cube(Vec3::new(2.5, 2.5, 0.2), 1.0));
        positions.extend([
            Vec3::splat(4.0),
            Vec3::new(3.9, 4.0, 4.0),
            Vec3::new(4.0, 3.9, 4.0),
            Vec3::new(4.0, 4.0, 3.9),
        ]);
        let ramp_values = [0.0, 0.2, 0.6, 0.4, 0.7, 0.9, 1.0, 0.8];
        let mut values = ramp_values.to_vec();
        values.extend(ramp_values);
        values.extend([1.0; 4]);
        let indices = (0..20).collect();
        let field = from_cells(positions, indices, &[12, 12, 10], values, false).unwrap();
        PlacedVolume::new(ramp(), Arc::new(field), Affine3A::IDENTITY, 0)
    }

    fn lit_scene(volume: PlacedVolume) -> SceneSnapshot {
        let mut scene = SceneSnapshot::empty();
        scene.volumes.push(volume);
        scene.lights.push(Light::Directional {
            direction: Vec3::new(-0.3, -1.0, -0.5).normalize(),
            irradiance: Vec3::splat(3.0),
            cos_half_angle: 1.0,
            visible: true,
        });
        scene
    }

    /// Opacity rising from 0 to 0.03 per unit distance over the first third of the range (a
    /// thin fog), then to 0.3 and 0.9 (dense); colours from blue to orange.
    fn foggy_ramp() -> Arc<TransferFunction> {
        let colors = vec![Vec4::new(0.2, 0.4, 1.0, 1.0), Vec4::new(1.0, 0.6, 0.2, 1.0)];
        let opacities = vec![0.0, 0.03, 0.3, 0.9];
        Arc::new(TransferFunction::new(1, (0.0, 1.0), colors, opacities, 0.05).unwrap())
    }

    /// Opacity 0.3 to 0.9 per unit distance 0.05 everywhere: dense.
    fn dense_ramp() -> Arc<TransferFunction> {
        let colors = vec![Vec4::new(1.0, 0.6, 0.2, 1.0)];
        Arc::new(TransferFunction::new(1, (0.0, 1.0), colors, vec![0.3, 0.9], 0.05).unwrap())
    }

    /// `volume` with another transfer function.
    fn recoloured(volume: PlacedVolume, transfer: Arc<TransferFunction>) -> PlacedVolume {
        PlacedVolume::new(transfer, volume.field, Affine3A::IDENTITY, 0)
    }

    /// Rays from a point outside the box `[0, size]³` to a 48 × 48 grid over its face z = 0,
    /// for sample indices 0..3.
    fn rays(size: f32) -> Vec<(Ray, LightSampling)> {
        let eye = Vec3::new(-0.7, 1.9, 2.6) * size;
        (0..48 * 48 * 3)
            .map(|i| {
                let (x, y, index) = (i % 48, (i / 48) % 48, i / (48 * 48));
                let target = Vec3::new(x as f32 + 0.5, y as f32 + 0.5, 0.0) * (size / 48.0);
                let ray = Ray {
                    origin: eye,
                    direction: (target - eye).normalize(),
                    t_min: 0.0,
                    t_max: f32::INFINITY,
                };
                (ray, LightSampling::for_pixel(index, x, y))
            })
            .collect()
    }

    /// Every ray's lit integral marched by `stepping`, the field samples all took (camera,
    /// shadow and ambient rays) and the seconds they took.
    fn march_all(
        scene: &SceneSnapshot,
        settings: &RendererSettings,
        rays: &[(Ray, LightSampling)],
        stepping: Stepping,
    ) -> (Vec<Option<VolumeIntegral>>, u32, f64) {
        let start = Instant::now();
        let mut count = 0u32;
        let results = rays
            .iter()
            .map(|(ray, sampling)| {
                let lit = lit_volumes_with(scene, settings, ray, ray.t_max, sampling, stepping);
                count += lit.map_or(0, |(_, samples)| samples);
                lit.map(|(integral, _)| integral)
            })
            .collect();
        (results, count, start.elapsed().as_secs_f64())
    }

    /// Lit by a light and occluded ambient light.
    fn lit_settings() -> RendererSettings {
        RendererSettings {
            ambient: Vec3::splat(0.2),
            ..RendererSettings::default()
        }
    }

    /// Every lit integral with and without skipping (asserted equal), the field samples each
    /// took and the seconds each took.
    fn skip_and_plain(scene: &SceneSnapshot, size: f32) -> (u32, u32, f64, f64) {
        let rays = rays(size);
        let settings = lit_settings();
        let (skipped, fast_count, fast) = march_all(scene, &settings, &rays, Stepping::SkipEmpty);
        let (plain, slow_count, slow) = march_all(scene, &settings, &rays, Stepping::Fixed);
        // Bit for bit: the samples skipped are exactly ones whose opacity is 0.
        assert_eq!(skipped, plain);
        let visible = skipped
            .iter()
            .filter(|r| r.is_some_and(|r| r.transmittance < 1.0))
            .count();
        assert!(visible > 100, "the test sees too little volume: {visible}");
        (fast_count, slow_count, fast, slow)
    }

    #[test]
    fn empty_space_skipping_gives_the_same_image_for_fewer_samples() {
        for (name, scene, size) in [
            (
                "structured 64³, one ball",
                lit_scene(mostly_empty_grid()),
                1.0,
            ),
            (
                "unstructured, two hexahedra",
                lit_scene(sparse_cells()),
                4.0,
            ),
        ] {
            let (skipping, plain, fast, slow) = skip_and_plain(&scene, size);
            println!(
                "{name}: field samples {skipping} with skipping, {plain} without ({:.1}× fewer); \
                 {:.1} ms vs {:.1} ms (unoptimised test build, shared machine)",
                plain as f64 / skipping as f64,
                fast * 1e3,
                slow * 1e3
            );
            assert!(skipping * 2 < plain, "{name}: {skipping} vs {plain}");
        }
    }

    /// Largest difference of colour (any channel) and of transmittance between two lists of
    /// integrals over the same rays, and the mean colour difference.
    fn differences(a: &[Option<VolumeIntegral>], b: &[Option<VolumeIntegral>]) -> (f32, f32, f32) {
        let none = VolumeIntegral::default();
        let (mut color, mut through, mut sum) = (0.0f32, 0.0f32, 0.0f32);
        for (x, y) in a.iter().zip(b) {
            let (x, y) = (x.unwrap_or(none), y.unwrap_or(none));
            let d = (x.color - y.color).abs().max_element();
            color = color.max(d);
            sum += d;
            through = through.max((x.transmittance - y.transmittance).abs());
        }
        (color, through, sum / a.len() as f32)
    }

    #[test]
    fn adaptive_steps_keep_a_foggy_volume_within_tolerance_for_fewer_samples() {
        let foggy = lit_scene(recoloured(ball_grid(0.3), foggy_ramp()));
        let rays = rays(1.0);
        // Unoccluded ambient light and no lights: the march alone decides each pixel, so the
        // difference is the stepping's, not another draw of lighting points.
        let mut unlit = SceneSnapshot::empty();
        unlit.volumes.push(recoloured(ball_grid(0.3), foggy_ramp()));
        let settings = RendererSettings {
            ambient: Vec3::ONE,
            ambient_occlusion_distance: 0.0,
            ..RendererSettings::default()
        };
        let (fine, fine_count, _) = march_all(&unlit, &settings, &rays, Stepping::SkipEmpty);
        let (coarse, coarse_count, _) = march_all(&unlit, &settings, &rays, Stepping::Adaptive);
        let (color, through, mean) = differences(&fine, &coarse);
        let foggiest = fine
            .iter()
            .map(|r| r.map_or(0.0, |r| r.color.x))
            .fold(0.0, f32::max);
        println!(
            "foggy ball, emission–absorption: field samples {coarse_count} adaptive, \
             {fine_count} fixed ({:.1}× fewer); largest difference {color:.5} in colour \
             (brightest {foggiest:.3}), {through:.5} in transmittance; mean {mean:.6}",
            fine_count as f64 / coarse_count as f64
        );
        assert!(
            coarse_count * 5 < fine_count * 2,
            "{coarse_count} vs {fine_count}"
        );
        assert!(color < 0.01 && through < 0.01, "{color} {through}");
        // Lit, with shadow and occluded ambient rays: fewer samples again, and the same image
        // on average (each ray's lighting points differ, so rays differ by their noise).
        let settings = lit_settings();
        let (fine, fine_count, fine_seconds) =
            march_all(&foggy, &settings, &rays, Stepping::SkipEmpty);
        let (coarse, coarse_count, coarse_seconds) =
            march_all(&foggy, &settings, &rays, Stepping::Adaptive);
        let mean_color = |all: &[Option<VolumeIntegral>]| {
            all.iter()
                .map(|r| r.map_or(Vec3::ZERO, |r| r.color))
                .sum::<Vec3>()
                / all.len() as f32
        };
        let (fine_mean, coarse_mean) = (mean_color(&fine), mean_color(&coarse));
        println!(
            "foggy ball, lit: field samples {coarse_count} adaptive, {fine_count} fixed \
             ({:.1}× fewer), {:.1} ms vs {:.1} ms (unoptimised test build, shared machine); \
             mean colour {coarse_mean} vs {fine_mean}",
            fine_count as f64 / coarse_count as f64,
            coarse_seconds * 1e3,
            fine_seconds * 1e3
        );
        assert!(
            coarse_count * 2 < fine_count,
            "{coarse_count} vs {fine_count}"
        );
        let relative = ((coarse_mean - fine_mean) / fine_mean).abs().max_element();
        assert!(relative < 0.01, "{coarse_mean} vs {fine_mean}");
    }

    #[test]
    fn adaptive_steps_leave_a_dense_volume_unchanged() {
        let dense = lit_scene(recoloured(mostly_empty_grid(), dense_ramp()));
        let rays = rays(1.0);
        let settings = lit_settings();
        let (fine, fine_count, _) = march_all(&dense, &settings, &rays, Stepping::SkipEmpty);
        let (coarse, coarse_count, _) = march_all(&dense, &settings, &rays, Stepping::Adaptive);
        assert_eq!(fine_count, coarse_count);
        assert_eq!(fine, coarse);
    }
}
