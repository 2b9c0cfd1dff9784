//! The light subtypes' parameters as the device advertises and checks them.

use std::f32::consts::PI;

use crate::device::datatype::*;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};

const COLOR: ParamSpec = ParamSpec::new("color", &[ANARI_FLOAT32_VEC3], "light colour")
    .default(SpecValue::Floats(&[1.0, 1.0, 1.0]))
    .range(
        SpecValue::Floats(&[0.0, 0.0, 0.0]),
        SpecValue::Floats(&[1.0, 1.0, 1.0]),
    );

const INTENSITY: ParamSpec =
    ParamSpec::new("intensity", &[ANARI_FLOAT32], "radiant intensity (W/sr)")
        .default(SpecValue::Float(1.0))
        .range(SpecValue::Float(0.0), SpecValue::None);
const POWER: ParamSpec = ParamSpec::new(
    "power",
    &[ANARI_FLOAT32],
    "total emitted power (W); overrides intensity",
)
.range(SpecValue::Float(0.0), SpecValue::None);

const RADIANCE: ParamSpec = ParamSpec::new(
    "radiance",
    &[ANARI_FLOAT32],
    "radiance of the light's surface (W/sr/m²); overrides the other strengths when the light \
     has extent",
)
.range(SpecValue::Float(0.0), SpecValue::None);

/// KHR_LIGHT_PRIMARY_VISIBILITY's parameter, on every light subtype.
const VISIBLE: ParamSpec = ParamSpec::new(
    "visible",
    &[ANARI_BOOL],
    "whether camera rays see the light (where it has extent: a disk, a sphere, a quad, a ring, \
     an environment; a point or spot light is never seen)",
)
.default(SpecValue::Bool(true));

// The emission cone of spot and ring lights.
const OPENING_ANGLE: ParamSpec = ParamSpec::new(
    "openingAngle",
    &[ANARI_FLOAT32],
    "full opening angle of the cone (radians)",
)
.default(SpecValue::Float(PI));
const FALLOFF_ANGLE: ParamSpec = ParamSpec::new(
    "falloffAngle",
    &[ANARI_FLOAT32],
    "angle over which intensity falls to zero inside the cone edge (radians)",
)
.default(SpecValue::Float(0.1));

pub const DIRECTIONAL: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "directional",
    "light from one direction, at infinity; a disk of angularDiameter casts soft shadows",
    &[
        COLOR,
        ParamSpec::new(
            "direction",
            &[ANARI_FLOAT32_VEC3],
            "direction the light travels",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, -1.0])),
        ParamSpec::new(
            "irradiance",
            &[ANARI_FLOAT32],
            "power per area arriving at a surface facing the light",
        )
        .default(SpecValue::Float(1.0))
        .range(SpecValue::Float(0.0), SpecValue::None),
        ParamSpec::new(
            "angularDiameter",
            &[ANARI_FLOAT32],
            "apparent diameter of the light's disk (radians)",
        )
        .default(SpecValue::Float(0.0))
        .range(SpecValue::Float(0.0), SpecValue::Float(PI)),
        RADIANCE,
        VISIBLE,
    ],
)
.extensions(&[
    "ANARI_KHR_LIGHT_DIRECTIONAL",
    "ANARI_KHR_LIGHT_PRIMARY_VISIBILITY",
]);

pub const POINT: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "point",
    "point light; a radius makes it a sphere light with soft shadows",
    &[
        COLOR,
        ParamSpec::new("position", &[ANARI_FLOAT32_VEC3], "light position")
            .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        INTENSITY,
        POWER,
        ParamSpec::new("radius", &[ANARI_FLOAT32], "radius of the sphere light")
            .default(SpecValue::Float(0.0))
            .range(SpecValue::Float(0.0), SpecValue::None),
        RADIANCE,
        VISIBLE,
    ],
)
.extensions(&[
    "ANARI_KHR_LIGHT_POINT",
    "ANARI_KHR_LIGHT_PRIMARY_VISIBILITY",
]);

pub const SPOT: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "spot",
    "spot light with a smooth falloff at the edge of its cone",
    &[
        COLOR,
        ParamSpec::new("position", &[ANARI_FLOAT32_VEC3], "light position")
            .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new(
            "direction",
            &[ANARI_FLOAT32_VEC3],
            "main emission direction",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, -1.0])),
        OPENING_ANGLE,
        FALLOFF_ANGLE,
        INTENSITY,
        POWER,
        VISIBLE,
    ],
)
.extensions(&["ANARI_KHR_LIGHT_SPOT", "ANARI_KHR_LIGHT_PRIMARY_VISIBILITY"]);

pub const QUAD: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "quad",
    "a parallelogram emitting like a diffuse surface (the same radiance in every direction) \
     from one side or both; soft shadows",
    &[
        COLOR,
        ParamSpec::new("position", &[ANARI_FLOAT32_VEC3], "a corner of the quad")
            .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new("edge1", &[ANARI_FLOAT32_VEC3], "vector of the first edge")
            .default(SpecValue::Floats(&[1.0, 0.0, 0.0])),
        ParamSpec::new("edge2", &[ANARI_FLOAT32_VEC3], "vector of the second edge")
            .default(SpecValue::Floats(&[0.0, 1.0, 0.0])),
        ParamSpec::new(
            "intensity",
            &[ANARI_FLOAT32],
            "radiant intensity (W/sr) along the quad's normal: radiance × area",
        )
        .default(SpecValue::Float(1.0))
        .range(SpecValue::Float(0.0), SpecValue::None),
        POWER,
        RADIANCE,
        ParamSpec::new(
            "side",
            &[ANARI_STRING],
            "emitting sides: front (the side edge1 × edge2 points to), back or both",
        )
        .default(SpecValue::Str("front"))
        .values(&["front", "back", "both"]),
        VISIBLE,
    ],
)
.extensions(&["ANARI_KHR_LIGHT_QUAD", "ANARI_KHR_LIGHT_PRIMARY_VISIBILITY"])
.unsupported(&["intensityDistribution"]);

pub const RING: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "ring",
    "a spot light spread over a ring (an annulus facing direction): each of its points \
     emits as the spot would; soft shadows",
    &[
        COLOR,
        ParamSpec::new("position", &[ANARI_FLOAT32_VEC3], "centre of the ring")
            .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new(
            "direction",
            &[ANARI_FLOAT32_VEC3],
            "the ring's axis, the main emission direction",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, -1.0])),
        OPENING_ANGLE,
        FALLOFF_ANGLE,
        ParamSpec::new(
            "intensity",
            &[ANARI_FLOAT32],
            "radiant intensity (W/sr) of the whole ring along its axis",
        )
        .default(SpecValue::Float(1.0))
        .range(SpecValue::Float(0.0), SpecValue::None),
        POWER,
        ParamSpec::new("radius", &[ANARI_FLOAT32], "outer radius of the ring")
            .default(SpecValue::Float(0.0))
            .range(SpecValue::Float(0.0), SpecValue::None),
        ParamSpec::new("innerRadius", &[ANARI_FLOAT32], "inner radius of the ring")
            .default(SpecValue::Float(0.0))
            .range(SpecValue::Float(0.0), SpecValue::None),
        ParamSpec::new(
            "radiance",
            &[ANARI_FLOAT32],
            "radiance of the ring along its axis (W/sr/m²): intensity = radiance × area; \
             overrides the other strengths when the ring has area",
        )
        .range(SpecValue::Float(0.0), SpecValue::None),
        VISIBLE,
    ],
)
.extensions(&["ANARI_KHR_LIGHT_RING", "ANARI_KHR_LIGHT_PRIMARY_VISIBILITY"])
.unsupported(&["intensityDistribution", "c0"]);

pub const HDRI: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "hdri",
    "light from an environment image around the scene (equirectangular), sampled by \
     luminance and combined with reflections that reach it; seen by camera rays (in the \
     background's place) unless not visible, and by reflections and refractions",
    &[
        COLOR,
        ParamSpec::new(
            "up",
            &[ANARI_FLOAT32_VEC3],
            "direction of the image's first row (its top edge)",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, 1.0])),
        ParamSpec::new(
            "direction",
            &[ANARI_FLOAT32_VEC3],
            "direction the image's centre is seen in",
        )
        .default(SpecValue::Floats(&[1.0, 0.0, 0.0])),
        ParamSpec::new(
            "radiance",
            &[ANARI_ARRAY2D],
            "radiance image (W/sr/m²); columns run around up from direction towards \
             direction × up, rows from up down",
        )
        .elements(&[ANARI_FLOAT32_VEC3])
        .required(),
        ParamSpec::new("layout", &[ANARI_STRING], "image layout")
            .default(SpecValue::Str("equirectangular"))
            .values(&["equirectangular"]),
        ParamSpec::new("scale", &[ANARI_FLOAT32], "factor on the radiance")
            .default(SpecValue::Float(1.0))
            .range(SpecValue::Float(0.0), SpecValue::None),
        VISIBLE,
    ],
)
.extensions(&["ANARI_KHR_LIGHT_HDRI", "ANARI_KHR_LIGHT_PRIMARY_VISIBILITY"]);
