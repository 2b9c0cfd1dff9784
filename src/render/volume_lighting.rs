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
pub const LIGHTING_POINTS: u32 = 8;

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
    transmittance(&scene.volumes, origin, direction, t_min, t_max, jitter).0
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
/// what reaches the point past surfaces and volumes. `samples` counts field samples.
fn in_scattered(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    point: Vec3,
    sampling: &LightSampling,
    samples: &mut u32,
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
            if scene.bvh.occluded(&ray) {
                continue;
            }
            let (through, taken) = transmittance(
                &scene.volumes,
                ray.origin,
                ray.direction,
                ray.t_min,
                ray.t_max,
                step_jitter(sampling),
            );
            *samples += taken;
            visibility = through;
        }
        sum += incoming.radiance * visibility;
    }
    sum * ISOTROPIC_PHASE
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
    let mut shadow_samples = 0u32;
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
                        &mut shadow_samples,
                    );
                next += 1;
            }
            through = after;
            next < LIGHTING_POINTS
        },
    )
    .unwrap_or(0);
    result.color += gathered * (taken_out / LIGHTING_POINTS as f32);
    Some((result, samples + shadow_samples))
}

/// The scramble-free sampling of sample `index` (tests and benchmarks).
pub fn sample_index(index: u32) -> LightSampling {
    LightSampling {
        index,
        scramble: Vec2::ZERO,
    }
}
