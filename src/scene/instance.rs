//! Instances place a group in the world with a transform.

use crate::device::datatype::*;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};

const IDENTITY: &[f32] = &[
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];

const VEC4: &[ANARIDataType] = &[ANARI_FLOAT32_VEC4];

pub const TRANSFORM: ObjectSpec = ObjectSpec::new(
    ANARI_INSTANCE,
    "transform",
    "a group placed with an affine transform",
    &[
        ParamSpec::new("group", &[ANARI_GROUP], "the instanced group").required(),
        ParamSpec::new(
            "transform",
            &[ANARI_FLOAT32_MAT4],
            "object-to-world transform, column-major",
        )
        .default(SpecValue::Floats(IDENTITY)),
        ParamSpec::new(
            "id",
            &[ANARI_UINT32],
            "user id written to channel.instanceId",
        )
        .default(SpecValue::UInt(u32::MAX)),
        ParamSpec::new("color", VEC4, "colour for geometries without one"),
        ParamSpec::new("attribute0", VEC4, "attribute0 for geometries without one"),
        ParamSpec::new("attribute1", VEC4, "attribute1 for geometries without one"),
        ParamSpec::new("attribute2", VEC4, "attribute2 for geometries without one"),
        ParamSpec::new("attribute3", VEC4, "attribute3 for geometries without one"),
    ],
)
.extensions(&[
    "ANARI_KHR_INSTANCE_TRANSFORM",
    "ANARI_KHR_FRAME_CHANNEL_INSTANCE_ID",
]);
