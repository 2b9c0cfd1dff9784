//! Groups collect surfaces and lights that instances place in the world.

use crate::device::datatype::*;
use crate::device::spec::{ObjectSpec, ParamSpec};

pub const GROUP: ObjectSpec = ObjectSpec::new(
    ANARI_GROUP,
    "",
    "surfaces and lights placed together by instances",
    &[
        ParamSpec::new("surface", &[ANARI_ARRAY1D], "array of surfaces").elements(&[ANARI_SURFACE]),
        ParamSpec::new("light", &[ANARI_ARRAY1D], "array of lights").elements(&[ANARI_LIGHT]),
    ],
);
