//! Lit volumes (the default renderer): single scattering of the scene's lights and the
//! renderer's ambient light by the volumes' particles. At each marching sample the transfer
//! function's opacity gives the extinction and its colour the share of it that scatters (the
//! albedo); the phase function is isotropic, as `transferFunction1D` has no anisotropy. Ambient
//! light, radiance A from every direction, scatters A × colour per unit of opacity and is not
//! occluded, so a volume under ambient light alone looks as the emission–absorption model
//! draws it. Light from the scene's lights is gathered at a few points per ray drawn from the
//! opacity along it, each with one shadow ray per light: blocked by surfaces and attenuated by
//! the volumes it crosses. Sample positions and lighting points follow the frame's sample
//! index, so pixelSamples and accumulation converge to the integral.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use crate::accel::{Ray, surface_epsilon};
use crate::render::renderer::RendererSettings;
use crate::scene::light::{Incoming, LightSampling, radical_inverse};
use crate::scene::volume::{VolumeIntegral, march, transmittance};
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
        true,
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
                cost.skip,
            );
            cost.samples += taken;
            visibility = through;
        }
        sum += incoming.radiance * visibility;
    }
    sum * ISOTROPIC_PHASE
}

/// How shadow rays are marched, and the field samples taken so far.
struct Cost {
    skip: bool,
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
    lit_volumes_with(scene, settings, ray, t_end, sampling, true).map(|(integral, _)| integral)
}

/// [`lit_volumes`], with or without empty-space skipping, and the number of field samples
/// taken (camera and shadow rays).
///
/// The march runs twice. The first pass finds the transmittance, the ambient light scattered
/// and the fraction W of the light from behind that the volumes take out. The second places
/// `LIGHTING_POINTS` points where the fraction taken out so far, 1 − T(s), reaches
/// W·(k + u)/K: points drawn in proportion to T·σ (stratified, offset u per sample), so each
/// stands for W/K of the scattering integral ∫ T(s)·σ(s)·colour(s)·L_in(s) ds. Within a
/// marching stretch the optical depth grows linearly, so the point is placed exactly.
pub fn lit_volumes_with(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    t_end: f32,
    sampling: &LightSampling,
    skip: bool,
) -> Option<(VolumeIntegral, u32)> {
    let volumes = &scene.volumes;
    let (origin, direction) = (ray.origin, ray.direction);
    let jitter = step_jitter(sampling);
    let mut result = VolumeIntegral::default();
    // The fraction taken out before marching stopped (the transmittance is then set to 0).
    let mut taken_out = 0.0f32;
    let mut samples = march(
        volumes,
        origin,
        direction,
        ray.t_min,
        t_end,
        jitter,
        skip,
        |step| {
            taken_out = 1.0 - result.transmittance * step.transmittance();
            result.absorb(step, step.color * settings.ambient)
        },
    )?;
    if scene.lights.is_empty() || taken_out <= 0.0 {
        return Some((result, samples));
    }
    let offset = lighting_offset(sampling);
    let target = |k: u32| taken_out * (k as f32 + offset) / LIGHTING_POINTS as f32;
    let mut next = 0u32;
    let mut through = 1.0f32;
    let mut gathered = Vec3::ZERO;
    let mut shadow = Cost { skip, samples: 0 };
    samples += march(
        volumes,
        origin,
        direction,
        ray.t_min,
        t_end,
        jitter,
        skip,
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
                gathered += step.color
                    * in_scattered(
                        scene,
                        settings,
                        origin + direction * t,
                        &point_sampling,
                        &mut shadow,
                    );
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
        let n = 64;
        let spacing = 1.0 / (n - 1) as f32;
        let centre = Vec3::new(0.7, 0.3, 0.6);
        let values = (0..n * n * n)
            .map(|i| {
                let p = Vec3::new((i % n) as f32, ((i / n) % n) as f32, (i / (n * n)) as f32);
                let d = (p * spacing - centre).length();
                (1.0 - d / 0.4).max(0.0)
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

    /// Rays from a point outside the box `[0, size]³` to a 48 × 48 grid over its face z = 0, for sample indices 0..3: every lit integral with and without skipping, the
    /// field samples each took and the seconds each took.
    fn skip_and_plain(scene: &SceneSnapshot, size: f32) -> (u32, u32, f64, f64) {
        let settings = RendererSettings {
            ambient: Vec3::splat(0.2),
            ..RendererSettings::default()
        };
        let eye = Vec3::new(-0.7, 1.9, 2.6) * size;
        let rays: Vec<(Ray, LightSampling)> = (0..48 * 48 * 3)
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
            .collect();
        let mut counts = [0u32; 2];
        let mut seconds = [0.0f64; 2];
        let mut results = [Vec::new(), Vec::new()];
        for (which, skip) in [true, false].into_iter().enumerate() {
            let start = Instant::now();
            for (ray, sampling) in &rays {
                let lit = lit_volumes_with(scene, &settings, ray, ray.t_max, sampling, skip);
                if let Some((_, samples)) = lit {
                    counts[which] += samples;
                }
                results[which].push(lit.map(|(integral, _)| integral));
            }
            seconds[which] = start.elapsed().as_secs_f64();
        }
        // Bit for bit: the samples skipped are exactly ones whose opacity is 0.
        for (skipped, plain) in results[0].iter().zip(&results[1]) {
            assert_eq!(skipped, plain);
        }
        let visible = results[0]
            .iter()
            .filter(|r| r.is_some_and(|r| r.transmittance < 1.0))
            .count();
        assert!(visible > 100, "the test sees too little volume: {visible}");
        (counts[0], counts[1], seconds[0], seconds[1])
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
}
