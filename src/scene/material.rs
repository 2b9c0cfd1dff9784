//! Materials: matte and physicallyBased. Each colour or scalar input is a constant, a geometry
//! attribute ("color", "attribute0"…), or a sampler.

use std::sync::Arc;

use glam::{Vec3, Vec4};

use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::params::ParamSet;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
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
        ParamSpec::new(
            "ior",
            SCALAR_INPUT,
            "index of refraction (≥ 1): of the glass, and of the reflection over the diffuse base",
        )
        .default(SpecValue::Float(1.5))
        .range(SpecValue::Float(1.0), SpecValue::None)
        .values(ATTRIBUTES),
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
        ParamSpec::new(
            "specular",
            SCALAR_INPUT,
            "strength of the reflection over the diffuse base (glTF KHR_materials_specular); \
             0: none",
        )
        .default(SpecValue::Float(0.0))
        .values(ATTRIBUTES),
        ParamSpec::new(
            "specularColor",
            COLOR_INPUT,
            "colour of that reflection at normal incidence, times ((ior−1)/(ior+1))²",
        )
        .default(SpecValue::Floats(&[1.0, 1.0, 1.0]))
        .values(ATTRIBUTES),
        ParamSpec::new(
            "clearcoat",
            SCALAR_INPUT,
            "strength of a clear lacquer (index 1.5) over everything (glTF \
             KHR_materials_clearcoat)",
        )
        .default(SpecValue::Float(0.0))
        .values(ATTRIBUTES),
        ParamSpec::new(
            "clearcoatRoughness",
            SCALAR_INPUT,
            "roughness of the lacquer",
        )
        .default(SpecValue::Float(0.0))
        .values(ATTRIBUTES),
        ParamSpec::new(
            "clearcoatNormal",
            &[ANARI_SAMPLER],
            "normal map of the lacquer (tangent space, components 2·value − 1); absent: the \
             surface's own normal without its normal map",
        ),
        ParamSpec::new(
            "sheenColor",
            COLOR_INPUT,
            "colour of a velvet-like sheen over the base (glTF KHR_materials_sheen, Charlie \
             distribution); black: none",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, 0.0]))
        .values(ATTRIBUTES),
        ParamSpec::new("sheenRoughness", SCALAR_INPUT, "roughness of the sheen")
            .default(SpecValue::Float(0.0))
            .values(ATTRIBUTES),
        ParamSpec::new(
            "iridescence",
            SCALAR_INPUT,
            "strength of a thin-film interference layer (glTF KHR_materials_iridescence)",
        )
        .default(SpecValue::Float(0.0))
        .values(ATTRIBUTES),
        ParamSpec::new(
            "iridescenceIor",
            &[ANARI_FLOAT32],
            "index of refraction of the thin film (≥ 1)",
        )
        .default(SpecValue::Float(1.3))
        .range(SpecValue::Float(1.0), SpecValue::None),
        ParamSpec::new(
            "iridescenceThickness",
            SCALAR_INPUT,
            "thickness of the thin film in nanometres",
        )
        .default(SpecValue::Float(0.0))
        .values(ATTRIBUTES),
        ParamSpec::new(
            "normal",
            &[ANARI_SAMPLER],
            "normal map (tangent space, components 2·value − 1) along the geometry's \
             vertex.tangent, else a frame from the object's x axis",
        ),
        ParamSpec::new(
            "occlusion",
            &[ANARI_SAMPLER],
            "ambient occlusion (its first component) scaling the ambient light only",
        ),
        ALPHA_MODE,
        ALPHA_CUTOFF,
    ],
)
.extensions(&["ANARI_KHR_MATERIAL_PHYSICALLY_BASED"]);

/// The clear dielectric part of a physicallyBased material (glTF KHR_materials_transmission
/// and _volume; its index is the material's `ior`).
#[derive(Clone, Debug)]
pub struct Transmission {
    pub weight: Input,
    pub thickness: Input,
    /// Per unit distance inside the volume, ln of the colour kept (≤ 0; 0: clear).
    pub log_attenuation: Vec3,
}

/// What glTF layers over the metallic-roughness base (KHR_materials_specular, _clearcoat,
/// _sheen, _iridescence) and the normal and occlusion maps. A material has none of it when
/// all are at their defaults, so plain materials pay nothing for it.
#[derive(Clone, Debug)]
pub struct Layers {
    pub specular: Input,
    pub specular_color: Input,
    pub clearcoat: Input,
    pub clearcoat_roughness: Input,
    pub clearcoat_normal: Option<Arc<Sampler>>,
    pub sheen_color: Input,
    pub sheen_roughness: Input,
    pub iridescence: Input,
    pub iridescence_ior: f32,
    pub iridescence_thickness: Input,
    pub normal: Option<Arc<Sampler>>,
    pub occlusion: Option<Arc<Sampler>>,
}

impl Layers {
    fn inputs(&self) -> [&Input; 8] {
        [
            &self.specular,
            &self.specular_color,
            &self.clearcoat,
            &self.clearcoat_roughness,
            &self.sheen_color,
            &self.sheen_roughness,
            &self.iridescence,
            &self.iridescence_thickness,
        ]
    }

    fn uses_attributes(&self) -> bool {
        self.inputs().iter().any(|i| i.uses_attributes())
            || self.clearcoat_normal.is_some()
            || self.normal.is_some()
            || self.occlusion.is_some()
    }
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

    /// Whether the input is a constant that is zero in every component it has.
    fn is_zero(&self) -> bool {
        matches!(self, Input::Constant(v) if v.truncate() == Vec3::ZERO)
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
    /// Index of refraction of the glass and of the reflection over the diffuse base.
    pub ior: Input,
    /// `None` where there is no transmission.
    pub transmission: Option<Transmission>,
    /// `None` where every layer and map is at its default.
    pub layers: Option<Box<Layers>>,
    /// Whether any input needs the geometry's attribute values at a hit (decided once here,
    /// as every shaded hit asks).
    pub uses_attributes: bool,
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
            ior: Input::Constant(Vec4::splat(1.5)),
            transmission: None,
            layers: None,
            uses_attributes: false,
        }
    }

    /// Whether the material lets light through anywhere (transmission, or an alpha mode that
    /// is not opaque).
    pub fn lets_light_through(&self) -> bool {
        self.transmission.is_some() || self.alpha != AlphaMode::Opaque
    }

    fn with_uses_attributes(mut self) -> Material {
        self.uses_attributes = [
            &self.base_color,
            &self.opacity,
            &self.metallic,
            &self.roughness,
            &self.emissive,
        ]
        .iter()
        .any(|i| i.uses_attributes())
            || (self.transmission.is_some() || self.layers.is_some()) && self.ior.uses_attributes()
            || self
                .transmission
                .as_ref()
                .is_some_and(|t| t.weight.uses_attributes() || t.thickness.uses_attributes())
            || self.layers.as_ref().is_some_and(|l| l.uses_attributes());
        self
    }
}

fn read_transmission(params: &ParamSet) -> Option<Transmission> {
    let weight = read_input(params, "transmission", Vec4::ZERO);
    if matches!(weight, Input::Constant(v) if v.x <= 0.0) {
        return None;
    }
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
        thickness: read_input(params, "thickness", Vec4::ZERO),
        log_attenuation: if distance.is_finite() {
            Vec3::new(color.x.ln(), color.y.ln(), color.z.ln()) / distance
        } else {
            Vec3::ZERO
        },
    })
}

fn read_sampler(params: &ParamSet, name: &str) -> Option<Arc<Sampler>> {
    params
        .get_object(name)
        .and_then(|o| o.derived_as::<Sampler>())
}

fn read_layers(params: &ParamSet) -> Option<Box<Layers>> {
    let layers = Layers {
        specular: read_input(params, "specular", Vec4::ZERO),
        specular_color: read_input(params, "specularColor", Vec4::ONE),
        clearcoat: read_input(params, "clearcoat", Vec4::ZERO),
        clearcoat_roughness: read_input(params, "clearcoatRoughness", Vec4::ZERO),
        clearcoat_normal: read_sampler(params, "clearcoatNormal"),
        sheen_color: read_input(params, "sheenColor", Vec4::new(0.0, 0.0, 0.0, 1.0)),
        sheen_roughness: read_input(params, "sheenRoughness", Vec4::ZERO),
        iridescence: read_input(params, "iridescence", Vec4::ZERO),
        iridescence_ior: params
            .get_f32("iridescenceIor")
            .filter(|ior| ior.is_finite() && *ior >= 1.0)
            .unwrap_or(1.3),
        iridescence_thickness: read_input(params, "iridescenceThickness", Vec4::ZERO),
        normal: read_sampler(params, "normal"),
        occlusion: read_sampler(params, "occlusion"),
    };
    let off = layers.specular.is_zero()
        && layers.clearcoat.is_zero()
        && layers.sheen_color.is_zero()
        && layers.iridescence.is_zero()
        && layers.normal.is_none()
        && layers.occlusion.is_none();
    (!off).then(|| Box::new(layers))
}

/// Builds the material from its committed parameters. Cheap, so it runs when a frame starts and
/// always sees the samplers' latest commits.
pub fn build(object: &Object) -> Option<Material> {
    let params = object.committed();
    let material = match object.subtype.as_str() {
        "matte" => Material {
            kind: MaterialKind::Matte,
            base_color: read_input(&params, "color", Vec4::new(0.8, 0.8, 0.8, 1.0)),
            opacity: read_input(&params, "opacity", Vec4::ONE),
            alpha: AlphaMode::read(&params),
            ..Material::fallback()
        },
        "physicallyBased" => Material {
            kind: MaterialKind::PhysicallyBased,
            base_color: read_input(&params, "baseColor", Vec4::ONE),
            opacity: read_input(&params, "opacity", Vec4::ONE),
            metallic: read_input(&params, "metallic", Vec4::ONE),
            roughness: read_input(&params, "roughness", Vec4::ONE),
            emissive: read_input(&params, "emissive", Vec3::ZERO.extend(1.0)),
            alpha: AlphaMode::read(&params),
            ior: match read_input(&params, "ior", Vec4::splat(1.5)) {
                Input::Constant(v) if !(v.x.is_finite() && v.x >= 1.0) => {
                    Input::Constant(Vec4::splat(1.5))
                }
                ior => ior,
            },
            transmission: read_transmission(&params),
            layers: read_layers(&params),
            uses_attributes: false,
        },
        _ => return None,
    };
    Some(material.with_uses_attributes())
}

/// Constant physicallyBased parameters that must lie in a range: (name, minimum, maximum,
/// what is used instead).
const CHECKED: &[(&str, f32, f32, &str)] = &[
    ("metallic", 0.0, 1.0, "clamped to [0, 1]"),
    ("roughness", 0.0, 1.0, "clamped to [0, 1]"),
    ("transmission", 0.0, 1.0, "clamped to [0, 1]"),
    ("ior", 1.0, f32::INFINITY, "1.5 is used"),
    ("thickness", 0.0, f32::INFINITY, "0 (a thin wall) is used"),
    ("attenuationDistance", 0.0, f32::INFINITY, "no absorption"),
    ("specular", 0.0, 1.0, "clamped to [0, 1]"),
    ("clearcoat", 0.0, 1.0, "clamped to [0, 1]"),
    ("clearcoatRoughness", 0.0, 1.0, "clamped to [0, 1]"),
    ("sheenRoughness", 0.0, 1.0, "clamped to [0, 1]"),
    ("iridescence", 0.0, 1.0, "clamped to [0, 1]"),
    ("iridescenceIor", 1.0, f32::INFINITY, "1.3 is used"),
    (
        "iridescenceThickness",
        0.0,
        f32::INFINITY,
        "0 (no film) is used",
    ),
];

/// Constant colours whose components must lie in [0, 1] (beyond, a layer would return more
/// light than arrives).
const CHECKED_COLORS: &[&str] = &["specularColor", "sheenColor", "attenuationColor"];

/// Reports constant physicallyBased parameters out of their range, naming the object, the
/// parameter, the range and what is used instead.
pub fn commit(device: &Device, object: &Object) {
    if object.subtype != "physicallyBased" {
        return;
    }
    let params = object.committed();
    let report = |name: &str, given: String, expected: String, instead: &str| {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!(
                "anariCommitParameters: {} parameter '{name}' is {given}, expected {expected}; \
                 {instead}",
                object.describe()
            ),
        );
    };
    for (name, minimum, maximum, instead) in CHECKED {
        let Some(value) = params.get_f32(name) else {
            continue;
        };
        // attenuationDistance must be positive; the others may sit on their minimum.
        let low = if *name == "attenuationDistance" {
            value <= *minimum
        } else {
            value < *minimum
        };
        if value.is_nan() || low || value > *maximum {
            let expected = match (*name, maximum.is_finite()) {
                ("attenuationDistance", _) => "a value > 0".to_string(),
                (_, true) => format!("a value in [{minimum}, {maximum}]"),
                (_, false) => format!("a value ≥ {minimum}"),
            };
            report(name, value.to_string(), expected, instead);
        }
    }
    for name in CHECKED_COLORS {
        if let Some(color) = params.get_vec3(name)
            && !(color.cmpge(Vec3::ZERO).all() && color.cmple(Vec3::ONE).all())
        {
            report(
                name,
                format!("{color}"),
                "components in [0, 1]".into(),
                "clamped to [0, 1]",
            );
        }
    }
}
