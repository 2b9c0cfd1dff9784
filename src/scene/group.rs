//! Groups collect surfaces, volumes and lights that instances place in the world.

use crate::device::datatype::*;
use crate::device::spec::{ObjectSpec, ParamSpec};

pub const GROUP: ObjectSpec = ObjectSpec::new(
    ANARI_GROUP,
    "",
    "surfaces, volumes and lights placed together by instances",
    &[
        ParamSpec::new("surface", &[ANARI_ARRAY1D], "array of surfaces").elements(&[ANARI_SURFACE]),
        ParamSpec::new("volume", &[ANARI_ARRAY1D], "array of volumes").elements(&[ANARI_VOLUME]),
        ParamSpec::new("light", &[ANARI_ARRAY1D], "array of lights").elements(&[ANARI_LIGHT]),
    ],
);
