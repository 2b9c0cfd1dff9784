//! Surfaces pair a geometry with a material.

use crate::device::datatype::*;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};

pub const SURFACE: ObjectSpec = ObjectSpec::new(
    ANARI_SURFACE,
    "",
    "a geometry with a material",
    &[
        ParamSpec::new("geometry", &[ANARI_GEOMETRY], "the surface's shape").required(),
        ParamSpec::new("material", &[ANARI_MATERIAL], "the surface's appearance").required(),
        ParamSpec::new("visible", &[ANARI_BOOL], "whether the surface is rendered")
            .default(SpecValue::Bool(true)),
        ParamSpec::new("id", &[ANARI_UINT32], "user id written to channel.objectId")
            .default(SpecValue::UInt(u32::MAX)),
    ],
)
.extensions(&["ANARI_KHR_FRAME_CHANNEL_OBJECT_ID"]);
