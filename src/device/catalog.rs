//! Every object subtype the device implements, gathered from the tables that live beside each
//! implementation. The extension list is derived from these tables, never written twice.

use crate::device::datatype::*;
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
        "instruction set of the ray kernels, for the whole process: auto (the best this CPU \
         has), baseline (SSE2) or avx2 (AVX2 and FMA); default: the environment variable \
         CAVETRACE_ISA, else auto",
    )
    .default(SpecValue::Str("auto"))
    .values(&crate::accel::isa::Isa::VALUES),
];

pub const DEVICE: ObjectSpec = ObjectSpec::new(
    ANARI_DEVICE,
    "",
    "cavetrace device: CPU ray tracing for CAVEs, powerwalls and head-tracked stereo",
    DEVICE_PARAMS,
);

/// Every implemented object subtype.
pub fn all() -> impl Iterator<Item = &'static ObjectSpec> {
    std::iter::once(&DEVICE)
        .chain(crate::scene::SPECS.iter())
        .chain(crate::camera::SPECS.iter())
        .chain(crate::render::SPECS.iter())
}

pub fn find(kind: ANARIDataType, subtype: &str) -> Option<&'static ObjectSpec> {
    let kind = if is_array(kind) { ANARI_ARRAY1D } else { kind };
    all().find(|s| s.kind == kind && s.subtype == subtype)
}

/// Subtype names of a kind, in table order ("default" first for renderers).
pub fn subtype_names(kind: ANARIDataType) -> Vec<&'static str> {
    all()
        .filter(|s| s.kind == kind && !s.subtype.is_empty())
        .map(|s| s.subtype)
        .collect()
}

/// The extensions the device implements in full, sorted, without duplicates.
pub fn extensions() -> Vec<&'static str> {
    let mut names: Vec<&'static str> = all().flat_map(|s| s.extensions.iter().copied()).collect();
    names.sort_unstable();
    names.dedup();
    names
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_spec_is_unique_and_every_parameter_has_types() {
        let specs: Vec<_> = all().collect();
        for (i, a) in specs.iter().enumerate() {
            for b in &specs[i + 1..] {
                assert!(
                    !(a.kind == b.kind && a.subtype == b.subtype),
                    "duplicate spec {} '{}'",
                    a.kind,
                    a.subtype
                );
            }
            for p in a.params {
                assert!(!p.types.is_empty(), "{} has no types", p.name);
                for t in p.types {
                    assert!(is_valid(*t), "{}: bad type {t}", p.name);
                }
            }
        }
    }
}
