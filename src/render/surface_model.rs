//! The physically based material's inputs beyond base colour and emission, evaluated at a hit
//! for the default renderer only: the fast renderer's colour path reads none of them.

use glam::{Vec3, Vec4};

use crate::render::bsdf::mapped_normal;
use crate::scene::material::{Input, Material};

/// A material input at a hit: like `Input::evaluate`, but samplers also see the primitive index
/// (the primitive sampler reads by it).
#[inline(always)]
pub fn evaluate_input(
    input: &Input,
    attributes: &[Option<Vec4>; 5],
    primitive: u32,
) -> Option<Vec4> {
    match input {
        Input::Sampler(sampler) => Some(sampler.evaluate_at(attributes, primitive)),
        other => other.evaluate(attributes),
    }
}

/// The layers of a physically based surface at one hit (their glTF meaning is in
/// `scene::material`), each factor clamped to where it conserves energy.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceModel {
    /// The shading normal after the normal map, and the clearcoat's (its own map, or the
    /// normal without the base's map).
    pub normal: Vec3,
    pub coat_normal: Vec3,
    /// The clear dielectric share of the non-metallic part (0: none), whether it bounds a
    /// volume (else a thin wall), and the volume's absorption per unit distance (ln of the
    /// colour kept).
    pub transmission: f32,
    pub volume: bool,
    pub log_attenuation: Vec3,
    pub ior: f32,
    pub specular: f32,
    pub specular_color: Vec3,
    pub clearcoat: f32,
    pub clearcoat_roughness: f32,
    pub sheen_color: Vec3,
    pub sheen_roughness: f32,
    pub iridescence: f32,
    pub iridescence_ior: f32,
    pub iridescence_thickness: f32,
    /// Share of the ambient light that reaches the surface.
    pub occlusion: f32,
}

/// Where a hit is, for evaluating inputs there.
pub struct HitInputs<'a> {
    pub attributes: &'a [Option<Vec4>; 5],
    pub primitive: u32,
    /// The shading normal facing the ray.
    pub normal: Vec3,
}

impl SurfaceModel {
    /// Evaluates `material`'s inputs at the hit; `tangent` gives the world-space tangent (w:
    /// handedness) when a normal map needs it.
    pub fn evaluate(material: &Material, hit: &HitInputs, tangent: impl Fn() -> Vec4) -> Self {
        let scalar = |input: &Input, default: f32| {
            evaluate_input(input, hit.attributes, hit.primitive).map_or(default, |v| v.x)
        };
        let color = |input: &Input, default: Vec3| {
            evaluate_input(input, hit.attributes, hit.primitive)
                .map_or(default, |v| v.truncate())
                .clamp(Vec3::ZERO, Vec3::ONE)
        };
        let unit = |input: &Input, default: f32| scalar(input, default).clamp(0.0, 1.0);
        let map = |sampler: &Option<std::sync::Arc<crate::scene::sampler::Sampler>>| {
            sampler.as_ref().map(|s| {
                mapped_normal(
                    hit.normal,
                    tangent(),
                    s.evaluate_at(hit.attributes, hit.primitive),
                )
            })
        };
        let mut model = SurfaceModel {
            normal: hit.normal,
            coat_normal: hit.normal,
            transmission: 0.0,
            volume: false,
            log_attenuation: Vec3::ZERO,
            ior: 1.5,
            specular: 0.0,
            specular_color: Vec3::ONE,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            sheen_color: Vec3::ZERO,
            sheen_roughness: 0.0,
            iridescence: 0.0,
            iridescence_ior: 1.3,
            iridescence_thickness: 0.0,
            occlusion: 1.0,
        };
        if material.transmission.is_none() && material.layers.is_none() {
            return model;
        }
        model.ior = scalar(&material.ior, 1.5).max(1.0);
        if let Some(t) = &material.transmission {
            model.transmission = unit(&t.weight, 0.0);
            model.volume = scalar(&t.thickness, 0.0) > 0.0;
            model.log_attenuation = t.log_attenuation;
        }
        if let Some(layers) = &material.layers {
            model.specular = unit(&layers.specular, 0.0);
            model.specular_color =
                evaluate_input(&layers.specular_color, hit.attributes, hit.primitive)
                    .map_or(Vec3::ONE, |v| v.truncate().max(Vec3::ZERO));
            model.clearcoat = unit(&layers.clearcoat, 0.0);
            model.clearcoat_roughness = unit(&layers.clearcoat_roughness, 0.0);
            model.sheen_color = color(&layers.sheen_color, Vec3::ZERO);
            model.sheen_roughness = unit(&layers.sheen_roughness, 0.0);
            model.iridescence = unit(&layers.iridescence, 0.0);
            model.iridescence_ior = layers.iridescence_ior;
            model.iridescence_thickness = scalar(&layers.iridescence_thickness, 0.0).max(0.0);
            if let Some(normal) = map(&layers.normal) {
                model.normal = normal;
            }
            if model.clearcoat > 0.0
                && let Some(normal) = map(&layers.clearcoat_normal)
            {
                model.coat_normal = normal;
            }
            if let Some(occlusion) = &layers.occlusion {
                model.occlusion = occlusion
                    .evaluate_at(hit.attributes, hit.primitive)
                    .x
                    .clamp(0.0, 1.0);
            }
        }
        model
    }
}
