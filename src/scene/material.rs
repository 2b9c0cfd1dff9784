//! Materials: matte and physicallyBased. Each colour or scalar input is a constant, a geometry
//! attribute ("color", "attribute0"…), or a sampler.

use std::sync::Arc;

use glam::{Vec3, Vec4};

use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::params::ParamSet;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::scene::attributes::attribute_slot;
use crate::scene::sampler::Sampler;

const COLOR_INPUT: &[ANARIDataType] = &[ANARI_FLOAT32_VEC3, ANARI_SAMPLER, ANARI_STRING];
const SCALAR_INPUT: &[ANARIDataType] = &[ANARI_FLOAT32, ANARI_SAMPLER, ANARI_STRING];
const ATTRIBUTES: &[&str] = &[
    "color",
    "attribute0",
    "attribute1",
    "attribute2",
    "attribute3",
];
const ALPHA_MODE: ParamSpec = ParamSpec::new(
    "alphaMode",
    &[ANARI_STRING],
    "opaque: ignore opacity; blend: see-through by opacity; mask: cut out below alphaCutoff",
)
.default(SpecValue::Str("opaque"))
.values(&["opaque", "blend", "mask"]);
const ALPHA_CUTOFF: ParamSpec = ParamSpec::new(
    "alphaCutoff",
    &[ANARI_FLOAT32],
    "opacity threshold of alphaMode mask",
)
.default(SpecValue::Float(0.5));

pub const MATTE: ObjectSpec = ObjectSpec::new(
    ANARI_MATERIAL,
    "matte",
    "diffuse material",
    &[
        ParamSpec::new(
            "color",
            COLOR_INPUT,
            "diffuse colour: constant, attribute name or sampler",
        )
        .default(SpecValue::Floats(&[0.8, 0.8, 0.8]))
        .values(ATTRIBUTES),
        ParamSpec::new(
            "opacity",
            SCALAR_INPUT,
            "opacity: constant, attribute name or sampler",
        )
        .default(SpecValue::Float(1.0))
        .values(ATTRIBUTES),
        ALPHA_MODE,
        ALPHA_CUTOFF,
    ],
)
.extensions(&["ANARI_KHR_MATERIAL_MATTE"]);

pub const PHYSICALLY_BASED: ObjectSpec = ObjectSpec::new(
    ANARI_MATERIAL,
    "physicallyBased",
    "metallic-roughness material (base colour, metallic, roughness, opacity, emissive); \
     metallic 1 with roughness 0 is a perfect mirror",
    &[
        ParamSpec::new("baseColor", COLOR_INPUT, "base colour")
            .default(SpecValue::Floats(&[1.0, 1.0, 1.0]))
            .values(ATTRIBUTES),
        ParamSpec::new("opacity", SCALAR_INPUT, "opacity")
            .default(SpecValue::Float(1.0))
            .values(ATTRIBUTES),
        ParamSpec::new("metallic", SCALAR_INPUT, "metalness")
            .default(SpecValue::Float(1.0))
            .values(ATTRIBUTES),
        ParamSpec::new("roughness", SCALAR_INPUT, "roughness")
            .default(SpecValue::Float(1.0))
            .values(ATTRIBUTES),
        ParamSpec::new("emissive", COLOR_INPUT, "emitted radiance")
            .default(SpecValue::Floats(&[0.0, 0.0, 0.0]))
            .values(ATTRIBUTES),
        ParamSpec::new(
            "transmission",
            SCALAR_INPUT,
            "share of the non-metallic part that is a clear dielectric (glass): Fresnel \
             reflection and refraction, total internal reflection",
        )
        .default(SpecValue::Float(0.0))
        .values(ATTRIBUTES),
        ParamSpec::new("ior", &[ANARI_FLOAT32], "index of refraction")
            .default(SpecValue::Float(1.5))
            .range(SpecValue::Float(1.0), SpecValue::None),
        ParamSpec::new(
            "thickness",
            SCALAR_INPUT,
            "0: a thin wall (light passes straight through); more: the surface bounds a volume \
             that refracts and absorbs",
        )
        .default(SpecValue::Float(0.0))
        .values(ATTRIBUTES),
        ParamSpec::new(
            "attenuationDistance",
            &[ANARI_FLOAT32],
            "distance inside the volume after which light keeps attenuationColor of itself",
        )
        .default(SpecValue::Float(f32::INFINITY)),
        ParamSpec::new(
            "attenuationColor",
            &[ANARI_FLOAT32_VEC3],
            "colour light inside the volume tends to over attenuationDistance",
        )
        .default(SpecValue::Floats(&[1.0, 1.0, 1.0])),
        ALPHA_MODE,
        ALPHA_CUTOFF,
    ],
);
// KHR_MATERIAL_PHYSICALLY_BASED is not advertised: clearcoat, sheen, specular, iridescence,
// normal and occlusion maps are not implemented.

/// The clear dielectric part of a physicallyBased material (glTF KHR_materials_transmission,
/// _ior and _volume).
#[derive(Clone, Debug)]
pub struct Transmission {
    pub weight: Input,
    pub ior: f32,
    pub thickness: Input,
    /// Per unit distance inside the volume, ln of the colour kept (≤ 0; 0: clear).
    pub log_attenuation: Vec3,
}

/// How opacity is used.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    Opaque,
    Blend,
    Mask(f32),
}

impl AlphaMode {
    fn read(params: &ParamSet) -> AlphaMode {
        match params.get_string("alphaMode") {
            Some("blend") => AlphaMode::Blend,
            Some("mask") => AlphaMode::Mask(params.get_f32("alphaCutoff").unwrap_or(0.5)),
            _ => AlphaMode::Opaque,
        }
    }

    /// The effective opacity in [0,1] for an evaluated opacity.
    pub fn apply(self, opacity: f32) -> f32 {
        match self {
            AlphaMode::Opaque => 1.0,
            AlphaMode::Blend => opacity.clamp(0.0, 1.0),
            AlphaMode::Mask(cutoff) => {
                if opacity >= cutoff {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }
}

/// Where a material input comes from.
#[derive(Clone, Debug)]
pub enum Input {
    Constant(Vec4),
    Attribute(usize),
    Sampler(Arc<Sampler>),
}

impl Input {
    /// Evaluates the input given the hit's attribute values.
    pub fn evaluate(&self, attributes: &[Option<Vec4>; 5]) -> Option<Vec4> {
        match self {
            Input::Constant(v) => Some(*v),
            Input::Attribute(slot) => attributes[*slot],
            Input::Sampler(sampler) => Some(sampler.evaluate(attributes)),
        }
    }

    /// Whether evaluating needs attribute values from the geometry.
    pub fn uses_attributes(&self) -> bool {
        !matches!(self, Input::Constant(_))
    }
}

fn read_input(params: &ParamSet, name: &str, default: Vec4) -> Input {
    if let Some(v) = params.get_vec3(name) {
        return Input::Constant(v.extend(1.0));
    }
    if let Some(v) = params.get_f32(name) {
        return Input::Constant(Vec4::splat(v));
    }
    if let Some(slot) = params.get_string(name).and_then(attribute_slot) {
        return Input::Attribute(slot);
    }
    if let Some(sampler) = params
        .get_object(name)
        .and_then(|o| o.derived_as::<Sampler>())
    {
        return Input::Sampler(sampler);
    }
    Input::Constant(default)
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialKind {
    Matte,
    PhysicallyBased,
}

#[derive(Clone, Debug)]
pub struct Material {
    pub kind: MaterialKind,
    pub base_color: Input,
    pub opacity: Input,
    pub metallic: Input,
    pub roughness: Input,
    pub emissive: Input,
    pub alpha: AlphaMode,
    /// `None` where there is no transmission.
    pub transmission: Option<Transmission>,
}

impl Material {
    /// Grey matte, used where a surface has no (valid) material.
    pub fn fallback() -> Material {
        Material {
            kind: MaterialKind::Matte,
            base_color: Input::Constant(Vec4::new(0.8, 0.8, 0.8, 1.0)),
            opacity: Input::Constant(Vec4::ONE),
            metallic: Input::Constant(Vec4::ZERO),
            roughness: Input::Constant(Vec4::ONE),
            emissive: Input::Constant(Vec4::ZERO),
            alpha: AlphaMode::Opaque,
            transmission: None,
        }
    }

    pub fn uses_attributes(&self) -> bool {
        [
            &self.base_color,
            &self.opacity,
            &self.metallic,
            &self.roughness,
            &self.emissive,
        ]
        .iter()
        .any(|i| i.uses_attributes())
            || self
                .transmission
                .as_ref()
                .is_some_and(|t| t.weight.uses_attributes() || t.thickness.uses_attributes())
    }
}

fn read_transmission(params: &ParamSet) -> Option<Transmission> {
    let weight = read_input(params, "transmission", Vec4::ZERO);
    if matches!(weight, Input::Constant(v) if v.x <= 0.0) {
        return None;
    }
    let ior = params
        .get_f32("ior")
        .filter(|ior| ior.is_finite() && *ior >= 1.0)
        .unwrap_or(1.5);
    let distance = params
        .get_f32("attenuationDistance")
        .filter(|d| *d > 0.0)
        .unwrap_or(f32::INFINITY);
    let color = params
        .get_vec3("attenuationColor")
        .unwrap_or(Vec3::ONE)
        .clamp(Vec3::splat(1e-6), Vec3::ONE);
    Some(Transmission {
        weight,
        ior,
        thickness: read_input(params, "thickness", Vec4::ZERO),
        log_attenuation: if distance.is_finite() {
            Vec3::new(color.x.ln(), color.y.ln(), color.z.ln()) / distance
        } else {
            Vec3::ZERO
        },
    })
}

/// Builds the material from its committed parameters. Cheap, so it runs when a frame starts and
/// always sees the samplers' latest commits.
pub fn build(object: &Object) -> Option<Material> {
    let params = object.committed();
    Some(match object.subtype.as_str() {
        "matte" => Material {
            kind: MaterialKind::Matte,
            base_color: read_input(&params, "color", Vec4::new(0.8, 0.8, 0.8, 1.0)),
            opacity: read_input(&params, "opacity", Vec4::ONE),
            metallic: Input::Constant(Vec4::ZERO),
            roughness: Input::Constant(Vec4::ONE),
            emissive: Input::Constant(Vec4::ZERO),
            alpha: AlphaMode::read(&params),
            transmission: None,
        },
        "physicallyBased" => Material {
            kind: MaterialKind::PhysicallyBased,
            base_color: read_input(&params, "baseColor", Vec4::ONE),
            opacity: read_input(&params, "opacity", Vec4::ONE),
            metallic: read_input(&params, "metallic", Vec4::ONE),
            roughness: read_input(&params, "roughness", Vec4::ONE),
            emissive: read_input(&params, "emissive", Vec3::ZERO.extend(1.0)),
            alpha: AlphaMode::read(&params),
            transmission: read_transmission(&params),
        },
        _ => return None,
    })
}
