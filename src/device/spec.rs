//! Object and parameter tables. Each object subtype declares one `ObjectSpec`; the same table
//! drives parameter type checking, introspection (anariGetObjectInfo / anariGetParameterInfo)
//! and the device's extension list, so there is no second list to keep in sync.

use crate::device::datatype::*;

/// A compile-time value for parameter defaults, minima and maxima.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpecValue {
    None,
    Bool(bool),
    Int(i32),
    UInt(u32),
    Float(f32),
    Floats(&'static [f32]),
    UInts(&'static [u32]),
    Str(&'static str),
    DataType(ANARIDataType),
}

/// One parameter an object subtype accepts.
#[derive(Clone, Copy, Debug)]
pub struct ParamSpec {
    pub name: &'static str,
    /// Accepted data types; the first is the preferred one.
    pub types: &'static [ANARIDataType],
    pub description: &'static str,
    pub required: bool,
    pub default: SpecValue,
    pub minimum: SpecValue,
    pub maximum: SpecValue,
    /// Allowed string values (for ANARI_STRING parameters with a fixed vocabulary) or data type
    /// names (for ANARI_DATA_TYPE parameters such as frame channels).
    pub values: &'static [&'static str],
    /// Accepted element types for array parameters (empty: any).
    pub element_types: &'static [ANARIDataType],
}

impl ParamSpec {
    pub const fn new(
        name: &'static str,
        types: &'static [ANARIDataType],
        description: &'static str,
    ) -> ParamSpec {
        ParamSpec {
            name,
            types,
            description,
            required: false,
            default: SpecValue::None,
            minimum: SpecValue::None,
            maximum: SpecValue::None,
            values: &[],
            element_types: &[],
        }
    }
    pub const fn required(mut self) -> ParamSpec {
        self.required = true;
        self
    }
    pub const fn default(mut self, value: SpecValue) -> ParamSpec {
        self.default = value;
        self
    }
    pub const fn range(mut self, minimum: SpecValue, maximum: SpecValue) -> ParamSpec {
        self.minimum = minimum;
        self.maximum = maximum;
        self
    }
    pub const fn values(mut self, values: &'static [&'static str]) -> ParamSpec {
        self.values = values;
        self
    }
    pub const fn elements(mut self, element_types: &'static [ANARIDataType]) -> ParamSpec {
        self.element_types = element_types;
        self
    }
}

/// The optional "name" parameter every object accepts.
pub const NAME_PARAM: ParamSpec = ParamSpec::new("name", &[ANARI_STRING], "optional object name");

/// Everything the device knows about one object subtype.
#[derive(Clone, Copy, Debug)]
pub struct ObjectSpec {
    /// ANARI_GEOMETRY, ANARI_CAMERA, …
    pub kind: ANARIDataType,
    /// "triangle", "perspective", …; "" for kinds without subtypes (surface, group, world, frame).
    pub subtype: &'static str,
    pub description: &'static str,
    pub params: &'static [ParamSpec],
    /// A second group of parameters shared between subtypes (e.g. geometry attributes).
    pub shared_params: &'static [ParamSpec],
    /// ANARI extensions this subtype implements in full (reported by the device).
    pub extensions: &'static [&'static str],
    /// Frame channels (frame spec only).
    pub channels: &'static [&'static str],
    /// Parameters of its extensions that cavetrace does not implement: setting one is reported
    /// as such, not as an unknown name.
    pub unsupported: &'static [&'static str],
}

impl ObjectSpec {
    pub const fn new(
        kind: ANARIDataType,
        subtype: &'static str,
        description: &'static str,
        params: &'static [ParamSpec],
    ) -> ObjectSpec {
        ObjectSpec {
            kind,
            subtype,
            description,
            params,
            shared_params: &[],
            extensions: &[],
            channels: &[],
            unsupported: &[],
        }
    }
    pub const fn shared(mut self, shared_params: &'static [ParamSpec]) -> ObjectSpec {
        self.shared_params = shared_params;
        self
    }
    pub const fn extensions(mut self, extensions: &'static [&'static str]) -> ObjectSpec {
        self.extensions = extensions;
        self
    }
    pub const fn channels(mut self, channels: &'static [&'static str]) -> ObjectSpec {
        self.channels = channels;
        self
    }
    pub const fn unsupported(mut self, names: &'static [&'static str]) -> ObjectSpec {
        self.unsupported = names;
        self
    }

    /// The parameter called `name`, including the implicit "name" parameter.
    pub fn param(&self, name: &str) -> Option<&'static ParamSpec> {
        if name == NAME_PARAM.name {
            return Some(&NAME_PARAM);
        }
        self.all_params().find(|p| p.name == name)
    }

    /// Every declared parameter (without the implicit "name").
    pub fn all_params(&self) -> impl Iterator<Item = &'static ParamSpec> + use<> {
        self.params.iter().chain(self.shared_params.iter())
    }
}

/// The specification's Color element types: geometry `*.color` arrays, sampler images,
/// primitive-sampler arrays, volume colours and the background image. Fixed point is normalised
/// to [0, 1] and sRGB components decoded to linear when read.
pub const ATTRIBUTE_ELEMENT_TYPES: &[ANARIDataType] = &[
    ANARI_UFIXED8,
    ANARI_UFIXED8_VEC2,
    ANARI_UFIXED8_VEC3,
    ANARI_UFIXED8_VEC4,
    ANARI_UFIXED8_R_SRGB,
    ANARI_UFIXED8_RA_SRGB,
    ANARI_UFIXED8_RGB_SRGB,
    ANARI_UFIXED8_RGBA_SRGB,
    ANARI_UFIXED16,
    ANARI_UFIXED16_VEC2,
    ANARI_UFIXED16_VEC3,
    ANARI_UFIXED16_VEC4,
    ANARI_UFIXED32,
    ANARI_UFIXED32_VEC2,
    ANARI_UFIXED32_VEC3,
    ANARI_UFIXED32_VEC4,
    ANARI_FLOAT32,
    ANARI_FLOAT32_VEC2,
    ANARI_FLOAT32_VEC3,
    ANARI_FLOAT32_VEC4,
];
