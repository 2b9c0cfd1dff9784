//! Small AVX2 helpers on eight `f32` lanes shared by the kernels that work eight lanes wide
//! (the frustum fill, the eight-ray leaf test, the top-level walk of eights, the frustum box
//! test). Each is `#[inline]` with AVX2 enabled, for callers compiled for AVX2 or AVX-512.

use glam::Vec4;
use std::arch::x86_64::*;

/// `|values|` lane by lane (the sign bit cleared).
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) fn abs(values: __m256) -> __m256 {
    _mm256_andnot_ps(_mm256_set1_ps(-0.0), values)
}

/// `Vec4::select`'s bit operations on eight lanes: `if_true` where `mask` is set.
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) fn select(mask: __m256, if_true: __m256, if_false: __m256) -> __m256 {
    _mm256_or_ps(
        _mm256_andnot_ps(mask, if_false),
        _mm256_and_ps(if_true, mask),
    )
}

/// The lanes of an 8-bit mask (bit per lane) as a vector mask.
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) fn lane_mask(lanes: u32) -> __m256 {
    let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    let set = _mm256_and_si256(_mm256_set1_epi32(lanes as i32), bits);
    _mm256_castsi256_ps(_mm256_cmpeq_epi32(set, bits))
}

/// Two four-lane vectors as one eight-lane vector (`low` in lanes 0–3).
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) fn joined(low: Vec4, high: Vec4) -> __m256 {
    _mm256_set_m128(high.into(), low.into())
}

/// Lanes 4h … 4h + 3 of `values` (h is 0 or 1).
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) fn half(values: __m256, h: usize) -> Vec4 {
    Vec4::from(match h {
        0 => _mm256_castps256_ps128(values),
        _ => _mm256_extractf128_ps::<1>(values),
    })
}

/// The stack of a walk of eight rays: per entry a node code, the lanes that reach it (bit per
/// lane) and their entry distances. Fixed capacity (`ENTRIES`), no heap.
pub(crate) struct LaneStack<const ENTRIES: usize> {
    codes: [std::mem::MaybeUninit<u32>; ENTRIES],
    masks: [std::mem::MaybeUninit<u32>; ENTRIES],
    nears: [std::mem::MaybeUninit<__m256>; ENTRIES],
    /// Entries below `len` are written.
    len: usize,
}

impl<const ENTRIES: usize> LaneStack<ENTRIES> {
    /// A stack holding the root (code 0) for `lanes`, entered at −∞.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn with_root(lanes: u32) -> LaneStack<ENTRIES> {
        let mut stack = LaneStack {
            codes: [std::mem::MaybeUninit::uninit(); ENTRIES],
            masks: [std::mem::MaybeUninit::uninit(); ENTRIES],
            nears: [std::mem::MaybeUninit::uninit(); ENTRIES],
            len: 0,
        };
        stack.push(0, lanes, _mm256_set1_ps(f32::NEG_INFINITY));
        stack
    }

    /// Whether `count` more entries fit.
    #[inline(always)]
    pub(crate) fn has_room(&self, count: usize) -> bool {
        self.len + count <= ENTRIES
    }

    /// Pushes an entry (panics when full: callers check [`Self::has_room`] first).
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn push(&mut self, code: u32, mask: u32, near: __m256) {
        self.codes[self.len].write(code);
        self.masks[self.len].write(mask);
        self.nears[self.len].write(near);
        self.len += 1;
    }

    /// The last entry pushed, removed.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn pop(&mut self) -> Option<(u32, u32, __m256)> {
        self.len = self.len.checked_sub(1)?;
        let len = self.len;
        // SAFETY: entries below the old `len` were written (`push` is the only writer).
        Some(unsafe {
            (
                self.codes[len].assume_init(),
                self.masks[len].assume_init(),
                self.nears[len].assume_init(),
            )
        })
    }
}
