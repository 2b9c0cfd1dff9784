//! The device's own parameters, and the table of object kinds every device serves. The specs of
//! the kinds live beside each implementation; the extension list is derived from them, never
//! written twice.

use std::sync::Arc;

use crate::device::Device;
use crate::device::datatype::*;
use crate::device::frame::Frame;
use crate::device::object::Object;
use crate::device::property::PropertyValue;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};

pub const DEVICE_PARAMS: &[ParamSpec] = &[
    ParamSpec::new(
        "statusCallback",
        &[ANARI_STATUS_CALLBACK],
        "callback used to report information to the application",
    ),
    ParamSpec::new(
        "statusCallbackUserData",
        &[ANARI_VOID_POINTER],
        "optional pointer passed as the first argument of the status callback",
    ),
    ParamSpec::new(
        "numThreads",
        &[ANARI_UINT32, ANARI_INT32],
        "number of render threads (default: one per core); takes effect at the device's commit",
    )
    .range(SpecValue::UInt(1), SpecValue::UInt(1024)),
    ParamSpec::new(
        "isa",
        &[ANARI_STRING],
        "instruction set of the ray kernels, for the whole process: auto (avx2 where this CPU \
         has it, else baseline; avx512 measured no faster), baseline (SSE2), avx2 (AVX2 and \
         FMA) or avx512 (AVX-512F/VL/BW/DQ as well); a path this CPU lacks falls back to the \
         widest it has; default: the environment variable CAVETRACE_ISA, else auto",
    )
    .default(SpecValue::Str("auto"))
    .values(&crate::isa::Isa::VALUES),
];

pub const DEVICE: ObjectSpec = ObjectSpec::new(
    ANARI_DEVICE,
    "",
    "cavetrace device: CPU ray tracing for CAVEs, powerwalls and head-tracked stereo",
    DEVICE_PARAMS,
);

/// The table of object kinds a device serves: which subtypes exist (their specs), what a commit
/// builds, the properties kinds compute and the state a frame renders with. The base layer
/// names no kind; the layer above those that define the kinds implements this (see
/// `crate::kinds`), and every device holds it.
pub trait Kinds: Send + Sync {
    /// Every implemented object subtype, the device's own (`DEVICE`) included.
    fn specs(&self) -> &[&'static ObjectSpec];

    /// Kind-specific work after an object's parameters were committed (validation, derived
    /// state).
    fn commit(&self, device: &Device, object: &Object);

    /// A property an object's kind computes from its committed state (not the frame's own,
    /// which [`crate::device::frame::Frame`] answers).
    fn property(&self, device: &Device, object: &Object, name: &str) -> Option<PropertyValue>;

    /// The render state of a new frame object.
    fn new_frame(&self) -> Arc<dyn Frame>;

    fn find(&self, kind: ANARIDataType, subtype: &str) -> Option<&'static ObjectSpec> {
        let kind = if is_array(kind) { ANARI_ARRAY1D } else { kind };
        self.specs()
            .iter()
            .copied()
            .find(|s| s.kind == kind && s.subtype == subtype)
    }

    /// Subtype names of a kind, in table order ("default" first for renderers).
    fn subtype_names(&self, kind: ANARIDataType) -> Vec<&'static str> {
        self.specs()
            .iter()
            .filter(|s| s.kind == kind && !s.subtype.is_empty())
            .map(|s| s.subtype)
            .collect()
    }

    /// The extensions the device implements in full, sorted, without duplicates.
    fn extensions(&self) -> Vec<&'static str> {
        let mut names: Vec<&'static str> = self
            .specs()
            .iter()
            .flat_map(|s| s.extensions.iter().copied())
            .collect();
        names.sort_unstable();
        names.dedup();
        names
    }
}
