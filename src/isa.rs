//! Which instruction set the hot kernels use. The library is built for baseline x86-64 so that
//! it loads on any x86-64 CPU; the hot kernels also have AVX2 builds, chosen when the CPU has
//! AVX2: the BVH walks (the single-ray triangle walks and the generic walk test a node's eight
//! child boxes in one vector — light-field rays, shadow and secondary rays, sparse progressive
//! lattices; the frustum walk of primary-ray packets culls them per frustum the same way; no
//! fused multiply-adds, so each path computes the same values), a block of a pinhole camera's
//! primary rays (four f64 lanes per instruction), the blend of several viewers' camera
//! positions for a block (eight f32 lanes) and a stereo block's cyclopean shading. Each of
//! those AVX2 builds is compiled a second time with AVX-512F/VL/BW/DQ enabled as well (one
//! source, [`avx2_and_avx512`]), taken when asked for (`avx512`) on a CPU with AVX-512
//! (`auto` keeps AVX2 there: [`Isa::best`]); the walk of eight rays (`accel::eights`) has an
//! AVX2 build only, which both paths take. The choice is the process's: made when a device is
//! created (the environment variable `CAVETRACE_ISA`, else `auto`) and whenever a device
//! commits its `isa` parameter. Every path finds the same hits and makes the same rays.

use std::sync::atomic::{AtomicU8, Ordering};

/// The selected path, as [`Isa`]'s discriminant (never a path this CPU lacks).
static SELECTED: AtomicU8 = AtomicU8::new(Isa::Baseline as u8);

/// Selects the path the process's kernels take: `isa` if this CPU has it, else the widest
/// narrower one it has ([`Isa::usable`]). Returns the path selected.
pub fn select(isa: Isa) -> Isa {
    let usable = Isa::usable(isa);
    SELECTED.store(usable as u8, Ordering::Relaxed);
    usable
}

/// The path the kernels take now: read for every node by the generic walk, so one load.
#[inline(always)]
pub fn selected() -> Isa {
    match SELECTED.load(Ordering::Relaxed) {
        2 => Isa::Avx512,
        1 => Isa::Avx2,
        _ => Isa::Baseline,
    }
}

/// A ray-kernel instruction set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum Isa {
    /// SSE2, four lanes: every x86-64 CPU (and the portable code elsewhere).
    #[default]
    Baseline = 0,
    /// AVX2 with FMA (x86-64-v3): a node's eight child boxes in one vector, a block's rays
    /// and viewer blend in 256-bit vectors.
    Avx2 = 1,
    /// The AVX2 kernels compiled with AVX-512F/VL/BW/DQ enabled as well (x86-64-v4): the same
    /// operations in the same order, encoded with EVEX (32 vector registers, compares into
    /// mask registers). The walk of eight rays (`accel::eights`) keeps its AVX2 build.
    Avx512 = 2,
}

impl Isa {
    /// Values of the device parameter `isa` and of `CAVETRACE_ISA`.
    pub const VALUES: [&'static str; 4] = ["auto", "baseline", "avx2", "avx512"];

    /// Every path, narrowest first (a function, not an associated constant, so that cbindgen
    /// leaves it out of the C header).
    pub const fn all() -> [Isa; 3] {
        [Isa::Baseline, Isa::Avx2, Isa::Avx512]
    }

    /// The path `auto` picks: the fastest this CPU has as measured, AVX2 where the CPU has it,
    /// also where it has AVX-512 (on Zen 4 the AVX-512 build was never faster and its packets
    /// about 1 % slower at 4M triangles: docs/kernel.md, "AVX-512 path"), else the baseline.
    pub fn best() -> Isa {
        if Isa::Avx2.supported() {
            Isa::Avx2
        } else {
            Isa::Baseline
        }
    }

    /// Whether this CPU can run the path.
    pub fn supported(self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            let avx2 = has!("avx2") && has!("fma");
            match self {
                Isa::Baseline => true,
                Isa::Avx2 => avx2,
                Isa::Avx512 => {
                    avx2 && has!("avx512f")
                        && has!("avx512vl")
                        && has!("avx512bw")
                        && has!("avx512dq")
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            self == Isa::Baseline
        }
    }

    /// `auto` is the best path of this CPU; `None` for names not in [`Isa::VALUES`].
    pub fn parse(name: &str) -> Option<Isa> {
        match name {
            "auto" => Some(Isa::best()),
            _ => Isa::all().into_iter().find(|isa| isa.name() == name),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "baseline",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// Whether the path runs the AVX2 kernels (compiled for AVX2, or for AVX-512 as well).
    #[inline(always)]
    pub fn has_avx2(self) -> bool {
        self != Isa::Baseline
    }

    /// The path to use when `requested`: itself if this CPU has it, else the widest narrower
    /// path this CPU has.
    pub fn usable(requested: Isa) -> Isa {
        Isa::all()[..=requested as usize]
            .iter()
            .rev()
            .copied()
            .find(|isa| isa.supported())
            .unwrap_or(Isa::Baseline)
    }

    /// `CAVETRACE_ISA` (unset or unknown: `auto`), as a path this CPU has.
    pub fn from_environment() -> Isa {
        std::env::var("CAVETRACE_ISA")
            .ok()
            .and_then(|name| Isa::parse(name.trim()))
            .map_or_else(Isa::best, Isa::usable)
    }
}

/// Compiles one function twice, `[name_avx2, name_avx512]`: for the AVX2 path
/// (`target_feature(enable = "avx2")`) and for the AVX-512 one (AVX-512F/VL/BW/DQ enabled as
/// well). The same source, so the same operations in the same order (the compiler never fuses
/// multiply-adds on its own): both builds compute the same bits. Helpers marked
/// `#[target_feature(enable = "avx2")] #[inline]` are inlined into both. Written
/// `[$(#[attr])*] [pub(..)] [unsafe] fn [name_avx2, name_avx512]<generics>(args) -> T { body }`,
/// also as a method in an `impl`.
macro_rules! avx2_and_avx512 {
    ($(#[$attr:meta])* $vis:vis unsafe fn [$avx2:ident, $avx512:ident] $($rest:tt)*) => {
        #[cfg(target_arch = "x86_64")]
        $(#[$attr])*
        #[target_feature(enable = "avx2")]
        $vis unsafe fn $avx2 $($rest)*

        #[cfg(target_arch = "x86_64")]
        $(#[$attr])*
        #[target_feature(enable = "avx2,avx512f,avx512vl,avx512bw,avx512dq")]
        $vis unsafe fn $avx512 $($rest)*
    };
    ($(#[$attr:meta])* $vis:vis fn [$avx2:ident, $avx512:ident] $($rest:tt)*) => {
        #[cfg(target_arch = "x86_64")]
        $(#[$attr])*
        #[target_feature(enable = "avx2")]
        $vis fn $avx2 $($rest)*

        #[cfg(target_arch = "x86_64")]
        $(#[$attr])*
        #[target_feature(enable = "avx2,avx512f,avx512vl,avx512bw,avx512dq")]
        $vis fn $avx512 $($rest)*
    };
}
pub(crate) use avx2_and_avx512;

/// The paths a test runs a kernel on: the baseline, and each wider one this CPU has.
#[cfg(test)]
pub(crate) fn test_paths() -> Vec<Isa> {
    Isa::all()
        .into_iter()
        .filter(|isa| isa.supported())
        .collect()
}

/// `run`'s answer with the process's kernels on path `isa` (one this CPU has), for tests that
/// compare paths. The path is the process's, so tests that select one take turns; a device
/// created meanwhile by another test selects the environment's path, so `run` is repeated
/// until the path is still `isa` when it ends. Afterwards the path is the environment's again.
#[cfg(test)]
pub(crate) fn on_path<T>(isa: Isa, mut run: impl FnMut() -> T) -> T {
    static TURNS: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _turn = TURNS.lock().unwrap_or_else(|e| e.into_inner());
    assert!(isa.supported(), "{isa:?} asked for on a CPU without it");
    for _ in 0..100 {
        assert_eq!(select(isa), isa);
        let answer = run();
        if selected() == isa {
            select(Isa::from_environment());
            return answer;
        }
    }
    panic!("the path never stayed {isa:?} (now {:?})", selected());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_auto_is_the_best_path() {
        for isa in Isa::all() {
            assert_eq!(Isa::parse(isa.name()), Some(isa));
            assert_eq!(Isa::VALUES[1 + isa as usize], isa.name());
        }
        assert_eq!(Isa::parse("auto"), Some(Isa::best()));
        assert_eq!(Isa::parse("sse9"), None);
        assert!(Isa::best().supported());
        assert_eq!(Isa::usable(Isa::Baseline), Isa::Baseline);
        // A wider path needs the narrower ones' features too.
        assert!(!Isa::Avx512.supported() || Isa::Avx2.supported());
        for isa in Isa::all() {
            let usable = Isa::usable(isa);
            assert!(usable.supported() && usable as u8 <= isa as u8);
            assert_eq!(usable == isa, isa.supported());
            assert_eq!(on_path(usable, selected), usable);
        }
        assert_eq!(select(Isa::from_environment()), Isa::from_environment());
    }
}
