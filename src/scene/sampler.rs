//! Samplers: image1D, image2D and transform. A sampler maps a geometry attribute through
//! inTransform/inOffset, looks up the image (nearest or linear, per-axis wrap mode) and applies
//! outTransform/outOffset.

use glam::{Mat4, Vec4};

use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::spec::{ATTRIBUTE_ELEMENT_TYPES, ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::attributes::{ATTRIBUTE_DEFAULT, attribute_slot};

const IDENTITY: &[f32] = &[
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];
const ZERO4: &[f32] = &[0.0, 0.0, 0.0, 0.0];
const ATTRIBUTES: &[&str] = &[
    "attribute0",
    "attribute1",
    "attribute2",
    "attribute3",
    "color",
];
const WRAP: &[&str] = &["clampToEdge", "repeat", "mirrorRepeat"];

const IN_ATTRIBUTE: ParamSpec = ParamSpec::new(
    "inAttribute",
    &[ANARI_STRING],
    "geometry attribute used as texture coordinate",
)
.default(SpecValue::Str("attribute0"))
.values(ATTRIBUTES);
const FILTER: ParamSpec = ParamSpec::new("filter", &[ANARI_STRING], "image filter")
    .default(SpecValue::Str("linear"))
    .values(&["nearest", "linear"]);
const IN_TRANSFORM: ParamSpec = ParamSpec::new(
    "inTransform",
    &[ANARI_FLOAT32_MAT4],
    "transform applied to the input attribute",
)
.default(SpecValue::Floats(IDENTITY));
const IN_OFFSET: ParamSpec = ParamSpec::new(
    "inOffset",
    &[ANARI_FLOAT32_VEC4],
    "offset added to the transformed input",
)
.default(SpecValue::Floats(ZERO4));
const OUT_TRANSFORM: ParamSpec = ParamSpec::new(
    "outTransform",
    &[ANARI_FLOAT32_MAT4],
    "transform applied to the sampled value",
)
.default(SpecValue::Floats(IDENTITY));
const OUT_OFFSET: ParamSpec = ParamSpec::new(
    "outOffset",
    &[ANARI_FLOAT32_VEC4],
    "offset added to the transformed output",
)
.default(SpecValue::Floats(ZERO4));

pub const IMAGE1D: ObjectSpec = ObjectSpec::new(
    ANARI_SAMPLER,
    "image1D",
    "1D texture lookup, e.g. a colour map over a scalar attribute",
    &[
        ParamSpec::new("image", &[ANARI_ARRAY1D], "texel array")
            .required()
            .elements(ATTRIBUTE_ELEMENT_TYPES),
        IN_ATTRIBUTE,
        FILTER,
        ParamSpec::new("wrapMode", &[ANARI_STRING], "wrap mode")
            .default(SpecValue::Str("clampToEdge"))
            .values(WRAP),
        IN_TRANSFORM,
        IN_OFFSET,
        OUT_TRANSFORM,
        OUT_OFFSET,
    ],
)
.extensions(&["ANARI_KHR_SAMPLER_IMAGE1D"]);

pub const IMAGE2D: ObjectSpec = ObjectSpec::new(
    ANARI_SAMPLER,
    "image2D",
    "2D texture lookup",
    &[
        ParamSpec::new("image", &[ANARI_ARRAY2D], "texel array")
            .required()
            .elements(ATTRIBUTE_ELEMENT_TYPES),
        IN_ATTRIBUTE,
        FILTER,
        ParamSpec::new(
            "wrapMode1",
            &[ANARI_STRING],
            "wrap mode along the first axis",
        )
        .default(SpecValue::Str("clampToEdge"))
        .values(WRAP),
        ParamSpec::new(
            "wrapMode2",
            &[ANARI_STRING],
            "wrap mode along the second axis",
        )
        .default(SpecValue::Str("clampToEdge"))
        .values(WRAP),
        IN_TRANSFORM,
        IN_OFFSET,
        OUT_TRANSFORM,
        OUT_OFFSET,
    ],
)
.extensions(&["ANARI_KHR_SAMPLER_IMAGE2D"]);

pub const TRANSFORM: ObjectSpec = ObjectSpec::new(
    ANARI_SAMPLER,
    "transform",
    "affine transform of a geometry attribute",
    &[IN_ATTRIBUTE, OUT_TRANSFORM, OUT_OFFSET],
)
.extensions(&["ANARI_KHR_SAMPLER_TRANSFORM"]);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    ClampToEdge,
    Repeat,
    MirrorRepeat,
}

impl Wrap {
    fn parse(s: Option<&str>) -> Wrap {
        match s {
            Some("repeat") => Wrap::Repeat,
            Some("mirrorRepeat") => Wrap::MirrorRepeat,
            _ => Wrap::ClampToEdge,
        }
    }

    /// Maps an integer texel coordinate into [0, n).
    fn texel(self, i: i64, n: usize) -> usize {
        let n = n as i64;
        let wrapped = match self {
            Wrap::ClampToEdge => i.clamp(0, n - 1),
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::MirrorRepeat => {
                let period = i.rem_euclid(2 * n);
                if period < n {
                    period
                } else {
                    2 * n - 1 - period
                }
            }
        };
        wrapped as usize
    }
}

#[derive(Debug)]
pub struct Image {
    pub texels: Vec<Vec4>,
    pub width: usize,
    pub height: usize,
    pub linear: bool,
    pub wrap: [Wrap; 2],
}

impl Image {
    fn fetch(&self, x: i64, y: i64) -> Vec4 {
        let xi = self.wrap[0].texel(x, self.width);
        let yi = self.wrap[1].texel(y, self.height);
        self.texels[yi * self.width + xi]
    }

    /// Samples at normalised coordinates (texel centres at (i+½)/n).
    pub fn sample(&self, u: f32, v: f32) -> Vec4 {
        let x = u * self.width as f32;
        let y = v * self.height as f32;
        if !self.linear {
            return self.fetch(x.floor() as i64, y.floor() as i64);
        }
        let (fx, fy) = (x - 0.5, y - 0.5);
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        if self.height == 1 {
            return self.fetch(x0, 0).lerp(self.fetch(x0 + 1, 0), tx);
        }
        let bottom = self.fetch(x0, y0).lerp(self.fetch(x0 + 1, y0), tx);
        let top = self.fetch(x0, y0 + 1).lerp(self.fetch(x0 + 1, y0 + 1), tx);
        bottom.lerp(top, ty)
    }
}

#[derive(Debug)]
pub struct Sampler {
    /// Attribute slot (see `attributes::ATTRIBUTE_NAMES`) read as the input.
    pub input: usize,
    pub in_transform: Mat4,
    pub in_offset: Vec4,
    pub out_transform: Mat4,
    pub out_offset: Vec4,
    /// None for the transform sampler.
    pub image: Option<Image>,
}

impl Sampler {
    /// Evaluates the sampler for the attribute values at a hit.
    pub fn evaluate(&self, attributes: &[Option<Vec4>; 5]) -> Vec4 {
        let input = attributes[self.input].unwrap_or(ATTRIBUTE_DEFAULT);
        let value = match &self.image {
            Some(image) => {
                let coordinate = self.in_transform * input + self.in_offset;
                image.sample(coordinate.x, coordinate.y)
            }
            None => input,
        };
        self.out_transform * value + self.out_offset
    }
}

pub fn commit(device: &Device, object: &Object) -> Option<Sampler> {
    let params = object.committed();
    let input =
        attribute_slot(params.get_string("inAttribute").unwrap_or("attribute0")).unwrap_or(1);
    let image = match object.subtype.as_str() {
        "image1D" | "image2D" => {
            let texels = params.get_object("image").and_then(|o| {
                let store = o.array.as_ref()?;
                Some((store.read_attribute()?, store.dims))
            });
            let Some((texels, dims)) = texels else {
                device.error(
                    ANARI_STATUS_INVALID_ARGUMENT,
                    Some(object),
                    format!(
                        "anariCommitParameters: {} has no readable 'image' array; it samples nothing",
                        object.describe()
                    ),
                );
                return None;
            };
            if texels.is_empty() {
                device.error(
                    ANARI_STATUS_INVALID_ARGUMENT,
                    Some(object),
                    format!(
                        "anariCommitParameters: {} has an empty 'image'",
                        object.describe()
                    ),
                );
                return None;
            }
            let wrap = if object.subtype == "image1D" {
                [
                    Wrap::parse(params.get_string("wrapMode")),
                    Wrap::ClampToEdge,
                ]
            } else {
                [
                    Wrap::parse(params.get_string("wrapMode1")),
                    Wrap::parse(params.get_string("wrapMode2")),
                ]
            };
            Some(Image {
                texels,
                width: dims[0] as usize,
                height: if object.subtype == "image1D" {
                    1
                } else {
                    dims[1] as usize
                },
                linear: params.get_string("filter") != Some("nearest"),
                wrap,
            })
        }
        "transform" => None,
        _ => return None,
    };
    Some(Sampler {
        input,
        in_transform: params.get_mat4("inTransform").unwrap_or(Mat4::IDENTITY),
        in_offset: params.get_vec4("inOffset").unwrap_or(Vec4::ZERO),
        out_transform: params.get_mat4("outTransform").unwrap_or(Mat4::IDENTITY),
        out_offset: params.get_vec4("outOffset").unwrap_or(Vec4::ZERO),
        image,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(linear: bool, wrap: Wrap) -> Image {
        Image {
            texels: vec![
                Vec4::splat(0.0),
                Vec4::splat(1.0),
                Vec4::splat(2.0),
                Vec4::splat(3.0),
            ],
            width: 4,
            height: 1,
            linear,
            wrap: [wrap, Wrap::ClampToEdge],
        }
    }

    #[test]
    fn nearest_and_linear_lookups() {
        let nearest = ramp(false, Wrap::ClampToEdge);
        assert_eq!(nearest.sample(0.1, 0.0).x, 0.0);
        assert_eq!(nearest.sample(0.6, 0.0).x, 2.0);
        let linear = ramp(true, Wrap::ClampToEdge);
        // Halfway between texel centres 1 (0.375) and 2 (0.625).
        assert!((linear.sample(0.5, 0.0).x - 1.5).abs() < 1e-6);
        assert_eq!(linear.sample(0.0, 0.0).x, 0.0);
        assert_eq!(linear.sample(1.0, 0.0).x, 3.0);
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(ramp(false, Wrap::Repeat).sample(1.1, 0.0).x, 0.0);
        assert_eq!(ramp(false, Wrap::MirrorRepeat).sample(1.1, 0.0).x, 3.0);
        assert_eq!(ramp(false, Wrap::ClampToEdge).sample(-3.0, 0.0).x, 0.0);
    }
}
