//! Samplers: image1D, image2D, image3D, primitive and transform. An image sampler maps a
//! geometry attribute through inTransform/inOffset, looks the result up in its image (nearest or
//! linear, per-axis wrap mode) and applies outTransform/outOffset; the primitive sampler reads
//! one value per primitive; the transform sampler transforms the attribute itself.

use glam::{Mat4, Vec3, Vec4};

use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::attributes::{
    ATTRIBUTE_DEFAULT, ATTRIBUTE_NAMES, VALUE_ELEMENT_TYPES, attribute_slot, read_values,
};

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

const fn wrap_mode(name: &'static str, description: &'static str) -> ParamSpec {
    ParamSpec::new(name, &[ANARI_STRING], description)
        .default(SpecValue::Str("clampToEdge"))
        .values(WRAP)
}

/// An image sampler's texel array, of ANARI array type `array`.
const fn image(array: &'static [ANARIDataType]) -> ParamSpec {
    ParamSpec::new("image", array, "texel array")
        .required()
        .elements(VALUE_ELEMENT_TYPES)
}

/// What every image sampler applies before and after its lookup, listed after its own
/// parameters.
const IMAGE_TRANSFORMS: &[ParamSpec] = &[IN_TRANSFORM, IN_OFFSET, OUT_TRANSFORM, OUT_OFFSET];

pub const IMAGE1D: ObjectSpec = ObjectSpec::new(
    ANARI_SAMPLER,
    "image1D",
    "1D texture lookup, e.g. a colour map over a scalar attribute",
    &[
        image(&[ANARI_ARRAY1D]),
        IN_ATTRIBUTE,
        FILTER,
        wrap_mode("wrapMode", "wrap mode"),
    ],
)
.shared(IMAGE_TRANSFORMS)
.extensions(&["ANARI_KHR_SAMPLER_IMAGE1D"]);

pub const IMAGE2D: ObjectSpec = ObjectSpec::new(
    ANARI_SAMPLER,
    "image2D",
    "2D texture lookup",
    &[
        image(&[ANARI_ARRAY2D]),
        IN_ATTRIBUTE,
        FILTER,
        wrap_mode("wrapMode1", "wrap mode along the first axis"),
        wrap_mode("wrapMode2", "wrap mode along the second axis"),
    ],
)
.shared(IMAGE_TRANSFORMS)
.extensions(&["ANARI_KHR_SAMPLER_IMAGE2D"]);

pub const IMAGE3D: ObjectSpec = ObjectSpec::new(
    ANARI_SAMPLER,
    "image3D",
    "3D texture lookup (trilinear with filter linear)",
    &[
        image(&[ANARI_ARRAY3D]),
        IN_ATTRIBUTE,
        FILTER,
        wrap_mode("wrapMode1", "wrap mode along the first axis"),
        wrap_mode("wrapMode2", "wrap mode along the second axis"),
        wrap_mode("wrapMode3", "wrap mode along the third axis"),
    ],
)
.shared(IMAGE_TRANSFORMS)
.extensions(&["ANARI_KHR_SAMPLER_IMAGE3D"]);

pub const PRIMITIVE: ObjectSpec = ObjectSpec::new(
    ANARI_SAMPLER,
    "primitive",
    "one value per primitive: array[primitive index + inOffset]",
    &[
        ParamSpec::new("array", &[ANARI_ARRAY1D], "values indexed by primitive")
            .required()
            .elements(VALUE_ELEMENT_TYPES),
        ParamSpec::new(
            "inOffset",
            &[ANARI_UINT64, ANARI_UINT32],
            "offset added to the primitive index",
        )
        .default(SpecValue::UInt(0)),
    ],
)
.extensions(&["ANARI_KHR_SAMPLER_PRIMITIVE"]);

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

/// The texels one axis of a lookup blends: `weight` of `upper`, 1 − `weight` of `lower`.
#[derive(Clone, Copy, Debug)]
struct AxisLookup {
    lower: usize,
    upper: usize,
    weight: f32,
}

impl AxisLookup {
    fn blends(&self) -> bool {
        self.upper != self.lower && self.weight != 0.0
    }
}

/// A 1D, 2D or 3D image (unused axes have size 1), stored x fastest, then y, then z.
#[derive(Debug, PartialEq)]
pub struct Image {
    pub texels: Vec<Vec4>,
    pub size: [usize; 3],
    pub linear: bool,
    pub wrap: [Wrap; 3],
}

impl Image {
    /// An image of `size` texels; `None` when the texel count does not match or is zero.
    pub fn new(
        texels: Vec<Vec4>,
        size: [usize; 3],
        linear: bool,
        wrap: [Wrap; 3],
    ) -> Option<Image> {
        let count = size.iter().try_fold(1usize, |n, s| n.checked_mul(*s))?;
        (count > 0 && count == texels.len()).then_some(Image {
            texels,
            size,
            linear,
            wrap,
        })
    }

    fn axis(&self, axis: usize, coordinate: f32) -> AxisLookup {
        let n = self.size[axis];
        let wrap = self.wrap[axis];
        // Texel i covers [i/n, (i+1)/n); non-finite coordinates read texel 0.
        let scaled = coordinate * n as f32;
        let scaled = if scaled.is_finite() { scaled } else { 0.0 };
        if !self.linear || n == 1 {
            let i = wrap.texel(scaled.floor() as i64, n);
            return AxisLookup {
                lower: i,
                upper: i,
                weight: 0.0,
            };
        }
        // Linear: blend the two texels whose centres (i + ½)/n surround the coordinate.
        let from_centre = scaled - 0.5;
        let lower = from_centre.floor();
        AxisLookup {
            lower: wrap.texel(lower as i64, n),
            upper: wrap.texel((lower as i64).saturating_add(1), n),
            weight: from_centre - lower,
        }
    }

    fn texel(&self, x: usize, y: usize, z: usize) -> Vec4 {
        self.texels[(z * self.size[1] + y) * self.size[0] + x]
    }

    /// Samples at normalised coordinates (texel centres at (i+½)/n on each axis; coordinates of
    /// axes the image does not have are ignored).
    pub fn sample(&self, coordinate: Vec3) -> Vec4 {
        let [x, y, z] = [
            self.axis(0, coordinate.x),
            self.axis(1, coordinate.y),
            self.axis(2, coordinate.z),
        ];
        // Each axis blends two texels only when they differ, so 1D and 2D lookups stay cheap.
        let row = |j: usize, k: usize| {
            let low = self.texel(x.lower, j, k);
            if x.blends() {
                low.lerp(self.texel(x.upper, j, k), x.weight)
            } else {
                low
            }
        };
        let slice = |k: usize| {
            let low = row(y.lower, k);
            if y.blends() {
                low.lerp(row(y.upper, k), y.weight)
            } else {
                low
            }
        };
        let low = slice(z.lower);
        if z.blends() {
            low.lerp(slice(z.upper), z.weight)
        } else {
            low
        }
    }
}

/// Where a sampler's value comes from.
#[derive(Debug)]
pub enum Lookup {
    /// image1D/2D/3D: the transformed attribute is a texture coordinate into the image.
    Image(Image),
    /// transform: the attribute itself.
    Transform,
    /// primitive: `values[primitive index + offset]`.
    Primitive { values: Vec<Vec4>, offset: u64 },
}

#[derive(Debug)]
pub struct Sampler {
    /// Attribute slot (see `attributes::ATTRIBUTE_NAMES`) read as the input.
    pub input: usize,
    pub in_transform: Mat4,
    pub in_offset: Vec4,
    pub out_transform: Mat4,
    pub out_offset: Vec4,
    pub lookup: Lookup,
}

impl Sampler {
    /// Evaluates the sampler for the attribute values at a hit on ANARI primitive `primitive`.
    pub fn evaluate_at(&self, attributes: &[Option<Vec4>; 5], primitive: u32) -> Vec4 {
        let input = || attributes[self.input].unwrap_or(ATTRIBUTE_DEFAULT);
        let value = match &self.lookup {
            Lookup::Image(image) => {
                let coordinate = self.in_transform * input() + self.in_offset;
                image.sample(coordinate.truncate())
            }
            Lookup::Transform => input(),
            // No transforms: the primitive sampler has none.
            Lookup::Primitive { values, offset } => {
                return usize::try_from(u64::from(primitive).saturating_add(*offset))
                    .ok()
                    .and_then(|i| values.get(i))
                    .copied()
                    .unwrap_or(ATTRIBUTE_DEFAULT);
            }
        };
        self.out_transform * value + self.out_offset
    }

    /// Evaluates the sampler for the attribute values at a hit, as if on primitive 0: correct for
    /// every sampler but `primitive`, which needs `evaluate_at`.
    pub fn evaluate(&self, attributes: &[Option<Vec4>; 5]) -> Vec4 {
        self.evaluate_at(attributes, 0)
    }
}

/// The array object a sampler parameter refers to, read as values with its dimensions; reports
/// (and returns `None`) when it is missing, unreadable or empty.
fn read_array(
    device: &Device,
    object: &Object,
    name: &str,
    expected: ANARIDataType,
) -> Option<(Vec<Vec4>, [usize; 3])> {
    let params = object.committed();
    let fail = |what: String| {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!(
                "anariCommitParameters: {} parameter '{name}' {what}; the sampler is not used",
                object.describe()
            ),
        );
        None
    };
    let Some(array) = params.get_object(name) else {
        return fail(format!("is not set (required: {})", type_name(expected)));
    };
    let Some(store) = array.array.as_ref().filter(|_| array.kind == expected) else {
        return fail(format!(
            "is a {}, expected {}",
            array.describe(),
            type_name(expected)
        ));
    };
    let Some(values) = read_values(store) else {
        return fail(format!(
            "has elements of {}, which cannot be read as values",
            type_name(store.element_type)
        ));
    };
    if values.is_empty() {
        return fail("is an empty array".into());
    }
    let size = store.dims.map(|d| d as usize);
    Some((values, size))
}

/// `inOffset` of the primitive sampler (UINT64 or UINT32).
fn primitive_offset(object: &Object) -> u64 {
    match object.committed().get_raw("inOffset") {
        Some((ANARI_UINT64, bytes)) => u64::from_ne_bytes(bytes.try_into().unwrap_or([0; 8])),
        Some((ANARI_UINT32, bytes)) => {
            u64::from(u32::from_ne_bytes(bytes.try_into().unwrap_or([0; 4])))
        }
        _ => 0,
    }
}

pub fn commit(device: &Device, object: &Object) -> Option<Sampler> {
    let params = object.committed();
    let input_name = params.get_string("inAttribute").unwrap_or("attribute0");
    let input = attribute_slot(input_name).unwrap_or_else(|| {
        device.warning(
            Some(object),
            format!(
                "anariCommitParameters: {} parameter 'inAttribute' '{input_name}' is not one of \
                 {}; attribute0 is used",
                object.describe(),
                ATTRIBUTE_NAMES.join(", ")
            ),
        );
        1
    });
    let image_kind = match object.subtype.as_str() {
        "image1D" => Some(ANARI_ARRAY1D),
        "image2D" => Some(ANARI_ARRAY2D),
        "image3D" => Some(ANARI_ARRAY3D),
        _ => None,
    };
    let lookup = match (object.subtype.as_str(), image_kind) {
        (_, Some(kind)) => {
            let (texels, size) = read_array(device, object, "image", kind)?;
            let wrap = if object.subtype == "image1D" {
                [
                    Wrap::parse(params.get_string("wrapMode")),
                    Wrap::ClampToEdge,
                    Wrap::ClampToEdge,
                ]
            } else {
                ["wrapMode1", "wrapMode2", "wrapMode3"]
                    .map(|name| Wrap::parse(params.get_string(name)))
            };
            let linear = params.get_string("filter") != Some("nearest");
            Lookup::Image(Image::new(texels, size, linear, wrap)?)
        }
        ("primitive", None) => {
            let (values, _) = read_array(device, object, "array", ANARI_ARRAY1D)?;
            Lookup::Primitive {
                values,
                offset: primitive_offset(object),
            }
        }
        ("transform", None) => Lookup::Transform,
        _ => return None,
    };
    Some(Sampler {
        input,
        in_transform: params.get_mat4("inTransform").unwrap_or(Mat4::IDENTITY),
        in_offset: params.get_vec4("inOffset").unwrap_or(Vec4::ZERO),
        out_transform: params.get_mat4("outTransform").unwrap_or(Mat4::IDENTITY),
        out_offset: params.get_vec4("outOffset").unwrap_or(Vec4::ZERO),
        lookup,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(linear: bool, wrap: Wrap) -> Image {
        Image::new(
            (0..4).map(|i| Vec4::splat(i as f32)).collect(),
            [4, 1, 1],
            linear,
            [wrap, Wrap::ClampToEdge, Wrap::ClampToEdge],
        )
        .unwrap()
    }

    fn at(image: &Image, u: f32) -> f32 {
        image.sample(Vec3::new(u, 0.0, 0.0)).x
    }

    #[test]
    fn nearest_and_linear_lookups() {
        let nearest = ramp(false, Wrap::ClampToEdge);
        assert_eq!(at(&nearest, 0.1), 0.0);
        assert_eq!(at(&nearest, 0.6), 2.0);
        let linear = ramp(true, Wrap::ClampToEdge);
        // Halfway between texel centres 1 (0.375) and 2 (0.625).
        assert!((at(&linear, 0.5) - 1.5).abs() < 1e-6);
        assert_eq!(at(&linear, 0.0), 0.0);
        assert_eq!(at(&linear, 1.0), 3.0);
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(at(&ramp(false, Wrap::Repeat), 1.1), 0.0);
        assert_eq!(at(&ramp(false, Wrap::MirrorRepeat), 1.1), 3.0);
        assert_eq!(at(&ramp(false, Wrap::ClampToEdge), -3.0), 0.0);
        // Linear across the repeat seam: halfway between texel 3 and texel 0.
        assert!((at(&ramp(true, Wrap::Repeat), 1.0) - 1.5).abs() < 1e-6);
    }

    #[test]
    fn trilinear_blends_the_eight_surrounding_texels() {
        // 2×2×2 image whose texel (i, j, k) holds i + 2j + 4k.
        let texels = (0..8).map(|n| Vec4::splat(n as f32)).collect();
        let clamp = [Wrap::ClampToEdge; 3];
        let linear = Image::new(texels, [2, 2, 2], true, clamp).unwrap();
        // Texel centres are at 0.25 and 0.75; (0.5, 0.5, 0.5) is the mean of all eight.
        assert!((linear.sample(Vec3::splat(0.5)).x - 3.5).abs() < 1e-6);
        // A quarter of the way from centre (0,0,0) to (1,1,1) on each axis: 0.25·(1+2+4).
        assert!((linear.sample(Vec3::splat(0.375)).x - 1.75).abs() < 1e-6);
        let texels = (0..8).map(|n| Vec4::splat(n as f32)).collect();
        let nearest = Image::new(texels, [2, 2, 2], false, clamp).unwrap();
        assert_eq!(nearest.sample(Vec3::new(0.9, 0.1, 0.6)).x, 5.0);
    }

    #[test]
    fn odd_coordinates_and_sizes_do_not_panic() {
        assert!(Image::new(vec![Vec4::ONE; 3], [2, 2, 1], true, [Wrap::Repeat; 3]).is_none());
        assert!(Image::new(Vec::new(), [0, 1, 1], true, [Wrap::Repeat; 3]).is_none());
        for wrap in [Wrap::ClampToEdge, Wrap::Repeat, Wrap::MirrorRepeat] {
            for linear in [false, true] {
                let image = ramp(linear, wrap);
                for u in [
                    f32::NAN,
                    f32::INFINITY,
                    -f32::INFINITY,
                    1e30,
                    -1e30,
                    f32::MAX,
                ] {
                    let v = at(&image, u);
                    assert!((0.0..=3.0).contains(&v), "{wrap:?} {linear} {u}: {v}");
                }
            }
        }
    }

    #[test]
    fn the_primitive_sampler_indexes_by_primitive_plus_offset() {
        let sampler = Sampler {
            input: 1,
            in_transform: Mat4::IDENTITY,
            in_offset: Vec4::ZERO,
            out_transform: Mat4::IDENTITY,
            out_offset: Vec4::ZERO,
            lookup: Lookup::Primitive {
                values: vec![Vec4::X, Vec4::Y, Vec4::Z],
                offset: 1,
            },
        };
        let attributes = [None; 5];
        assert_eq!(sampler.evaluate_at(&attributes, 0), Vec4::Y);
        assert_eq!(sampler.evaluate_at(&attributes, 1), Vec4::Z);
        assert_eq!(sampler.evaluate_at(&attributes, 2), ATTRIBUTE_DEFAULT);
        assert_eq!(
            sampler.evaluate_at(&attributes, u32::MAX),
            ATTRIBUTE_DEFAULT
        );
    }
}
