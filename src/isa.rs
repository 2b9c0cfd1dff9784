//! Which instruction set the hot kernels use. The library is built for baseline x86-64 so that
//! it loads on any x86-64 CPU; the hot kernels also have AVX2 builds, chosen when the CPU has
//! AVX2: the BVH walks (the single-ray triangle walks and the generic walk test a node's eight
//! child boxes in one vector — light-field rays, shadow and secondary rays, sparse progressive
//! lattices; the frustum walk of primary-ray packets culls them per frustum the same way; no
//! fused multiply-adds, so each path computes the same values), a block of a pinhole camera's
//! primary rays (four f64 lanes per instruction) and the blend of several viewers' camera
//! positions for a block (eight f32 lanes). The choice is the process's: made
//! when a device is created (the environment variable `CAVETRACE_ISA`, else the best the CPU
//! has) and whenever a device commits its `isa` parameter. Every path finds the same hits and
//! makes the same rays.

use std::sync::atomic::{AtomicBool, Ordering};

/// Whether the AVX2 path is selected (never on a CPU without it).
static AVX2_SELECTED: AtomicBool = AtomicBool::new(false);

/// Whether the kernels take their AVX2 paths: read for every node, so kept to one load.
#[inline(always)]
pub(crate) fn avx2_selected() -> bool {
    AVX2_SELECTED.load(Ordering::Relaxed)
}

/// Selects the path the process's kernels take: `isa` if this CPU has it, else the baseline.
/// Returns the path selected.
pub fn select(isa: Isa) -> Isa {
    let usable = Isa::usable(isa);
    AVX2_SELECTED.store(usable == Isa::Avx2, Ordering::Relaxed);
    usable
}

/// The path the kernels take now.
pub fn selected() -> Isa {
    if avx2_selected() {
        Isa::Avx2
    } else {
        Isa::Baseline
    }
}

/// A ray-kernel instruction set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Isa {
    /// SSE2, four lanes: every x86-64 CPU (and the portable code elsewhere).
    #[default]
    Baseline,
    /// AVX2 with FMA (x86-64-v3): a node's eight child boxes in one vector, a block's rays
    /// and viewer blend in 256-bit vectors.
    Avx2,
}

impl Isa {
    /// Values of the device parameter `isa` and of `CAVETRACE_ISA`.
    pub const VALUES: [&'static str; 3] = ["auto", "baseline", "avx2"];

    /// The widest path this CPU runs.
    pub fn best() -> Isa {
        if Isa::Avx2.supported() {
            Isa::Avx2
        } else {
            Isa::Baseline
        }
    }

    /// Whether this CPU can run the path.
    pub fn supported(self) -> bool {
        match self {
            Isa::Baseline => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"),
            #[cfg(not(target_arch = "x86_64"))]
            Isa::Avx2 => false,
        }
    }

    /// `auto` is the best path of this CPU; `None` for names not in [`Isa::VALUES`].
    pub fn parse(name: &str) -> Option<Isa> {
        match name {
            "auto" => Some(Isa::best()),
            "baseline" => Some(Isa::Baseline),
            "avx2" => Some(Isa::Avx2),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "baseline",
            Isa::Avx2 => "avx2",
        }
    }

    /// The path to use when `requested`: itself if this CPU has it, else the baseline.
    pub fn usable(requested: Isa) -> Isa {
        if requested.supported() {
            requested
        } else {
            Isa::Baseline
        }
    }

    /// `CAVETRACE_ISA` (unset or unknown: `auto`), as a path this CPU has.
    pub fn from_environment() -> Isa {
        std::env::var("CAVETRACE_ISA")
            .ok()
            .and_then(|name| Isa::parse(name.trim()))
            .map_or_else(Isa::best, Isa::usable)
    }
}

/// The paths a test runs a kernel on, as "uses AVX2": the baseline, and AVX2 where this CPU
/// has it.
#[cfg(test)]
pub(crate) fn test_paths() -> &'static [bool] {
    if Isa::Avx2.supported() {
        &[false, true]
    } else {
        &[false]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_auto_is_the_best_path() {
        for isa in [Isa::Baseline, Isa::Avx2] {
            assert_eq!(Isa::parse(isa.name()), Some(isa));
        }
        assert_eq!(Isa::parse("auto"), Some(Isa::best()));
        assert_eq!(Isa::parse("sse9"), None);
        assert!(Isa::best().supported());
        assert_eq!(Isa::usable(Isa::Baseline), Isa::Baseline);
        assert_eq!(select(Isa::Baseline), Isa::Baseline);
        assert_eq!(selected(), Isa::Baseline);
        let best = select(Isa::Avx2);
        assert_eq!(selected(), best);
        assert_eq!(best == Isa::Avx2, Isa::Avx2.supported());
        select(Isa::from_environment());
    }
}
