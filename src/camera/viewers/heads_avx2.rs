//! The blended camera positions of a block's points with AVX2, eight points per vector: each
//! point's cone tests, angles, weights and blend stay in registers from the first pass to the
//! last (the generic code writes every pass over the whole block to memory and reads it back).
//! The operations are those of [`ViewerSet::weights_of`] and [`ViewerSet::cameras_with`], in
//! the same order and without fused multiply-adds, so every lane gets the same bits; the
//! selects pick what the generic code's selects and branches pick.

use std::arch::x86_64::*;

use glam::DVec3;

use super::{
    ACOS_POLYNOMIAL, COS_POLYNOMIAL, CameraLanes, MAX_VIEWERS, ViewerF32, ViewerMode, ViewerSet,
    ViewerWeighting,
};

/// Points per vector.
const LANES: usize = 8;

impl ViewerSet {
    /// Whether [`Self::heads_avx2`] makes these cameras: the mono eye's per-pixel blend with the
    /// linear or cosine fall-off, for blocks of whole vectors.
    pub(super) fn blends_heads_eight_at_a_time(&self, points: usize, needs_right: bool) -> bool {
        points % LANES == 0
            && !needs_right
            && self.mode == ViewerMode::PerPixel
            && self.weighting != ViewerWeighting::Gaussian
    }

    /// [`Self::cameras_at_points`] (right vectors not blended) where
    /// [`Self::blends_heads_eight_at_a_time`] holds.
    #[target_feature(enable = "avx2")]
    pub(super) fn heads_avx2<const N: usize>(
        &self,
        points: &[DVec3; N],
        cameras: &mut CameraLanes<N>,
    ) {
        // Registers for the viewers there are (they are set up for every vector).
        match self.heads.len() {
            0..=4 => self.heads_with::<4, N>(points, cameras),
            5..=16 => self.heads_with::<16, N>(points, cameras),
            _ => self.heads_with::<MAX_VIEWERS, N>(points, cameras),
        }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    fn heads_with<const V: usize, const N: usize>(
        &self,
        points: &[DVec3; N],
        cameras: &mut CameraLanes<N>,
    ) {
        let axis_lanes =
            |axis: usize| -> [f32; N] { std::array::from_fn(|l| points[l][axis] as f32) };
        let p = [axis_lanes(0), axis_lanes(1), axis_lanes(2)];
        let viewers = &self.viewers_f32[..self.heads.len()];
        for start in (0..N).step_by(LANES) {
            let p = p.map(|lanes| load(&lanes[start..start + LANES]));
            let mut weights = [_mm256_setzero_ps(); V];
            let any = self.weights8(viewers, p, &mut weights[..viewers.len()]);
            let weights = &weights[..viewers.len()];
            let mut blended = [_mm256_setzero_ps(); 3];
            for (weight, viewer) in weights.iter().zip(viewers) {
                for (sum, component) in blended.iter_mut().zip(viewer.head) {
                    *sum = _mm256_add_ps(*sum, _mm256_mul_ps(*weight, _mm256_set1_ps(component)));
                }
            }
            // Per half of the vector (four f64 lanes): the blend in f64, the head of a viewer
            // whose weight is 1, the mean where no viewer has a say.
            let alone: [__m256; V] = std::array::from_fn(|v| match weights.get(v) {
                Some(weight) => _mm256_cmp_ps::<_CMP_EQ_OQ>(*weight, _mm256_set1_ps(1.0)),
                None => _mm256_setzero_ps(),
            });
            // Usually no point is one viewer's alone: one test spares the selects.
            let any_alone = alone[..weights.len()]
                .iter()
                .fold(_mm256_setzero_ps(), |found, mask| _mm256_or_ps(found, *mask));
            let any_alone = _mm256_movemask_ps(any_alone) != 0;
            for half in 0..2 {
                let lanes = start + 4 * half..start + 4 * half + 4;
                let any = half_mask(any, half);
                for axis in 0..3 {
                    let mut head = _mm256_cvtps_pd(half_of(blended[axis], half));
                    let mut right = _mm256_set1_pd(self.screen.x[axis]);
                    if any_alone {
                        for (v, mask) in alone[..weights.len()].iter().enumerate() {
                            let take = half_mask(*mask, half);
                            head = _mm256_blendv_pd(head, _mm256_set1_pd(self.heads[v][axis]), take);
                            right =
                                _mm256_blendv_pd(right, _mm256_set1_pd(self.rights[v][axis]), take);
                        }
                    }
                    head = _mm256_blendv_pd(_mm256_set1_pd(self.mean_head[axis]), head, any);
                    right = _mm256_blendv_pd(_mm256_set1_pd(self.mean_right[axis]), right, any);
                    store(&mut cameras.head[axis][lanes.clone()], head);
                    store(&mut cameras.right[axis][lanes.clone()], right);
                }
            }
        }
    }

    /// [`Self::weights_of`] for eight points (`p`: x, y, z): the viewers' normalised weights
    /// into `weights`, and the mask of points where some viewer has a say.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn weights8(&self, viewers: &[ViewerF32], p: [__m256; 3], weights: &mut [__m256]) -> __m256 {
        let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
        // Cone membership without a square root: cos a > cos c, squared with its sign.
        let reach = self.cos_reach;
        let reach_squared = _mm256_set1_ps(reach * reach);
        let mut members = zero;
        for (weight, viewer) in weights.iter_mut().zip(viewers) {
            let (dot, length_squared) = to_point8(viewer, p);
            let ahead = _mm256_cmp_ps::<_CMP_GT_OQ>(dot, zero);
            let wide = _mm256_cmp_ps::<_CMP_LT_OQ>(
                _mm256_mul_ps(dot, dot),
                _mm256_mul_ps(reach_squared, length_squared),
            );
            let inside = if reach >= 0.0 {
                _mm256_andnot_ps(wide, ahead)
            } else {
                _mm256_or_ps(ahead, wide)
            };
            *weight = _mm256_and_ps(inside, one);
            members = _mm256_add_ps(members, *weight);
        }
        let several = _mm256_cmp_ps::<_CMP_GT_OQ>(members, one);
        if _mm256_movemask_ps(several) == 0 {
            // Weights of 0 and 1, already normalised.
            return _mm256_cmp_ps::<_CMP_GT_OQ>(members, zero);
        }
        // Points in several cones: weights from the angles.
        let inv_cutoff = _mm256_set1_ps(self.inv_cutoff);
        let mut total = zero;
        for (weight, viewer) in weights.iter_mut().zip(viewers) {
            let (dot, length_squared) = to_point8(viewer, p);
            let cosine = _mm256_div_ps(dot, _mm256_sqrt_ps(length_squared));
            let cosine = _mm256_min_ps(_mm256_max_ps(cosine, _mm256_set1_ps(-1.0)), one);
            let a = _mm256_mul_ps(acos8(cosine), inv_cutoff);
            let raw = match self.weighting {
                ViewerWeighting::Cosine => cos8(a),
                _ => _mm256_sub_ps(one, a),
            };
            let blended = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GT_OQ>(*weight, zero),
                _mm256_max_ps(raw, zero),
            );
            *weight = _mm256_blendv_ps(*weight, blended, several);
            total = _mm256_add_ps(total, *weight);
        }
        let any = _mm256_cmp_ps::<_CMP_GT_OQ>(total, zero);
        let divisor = _mm256_blendv_ps(one, total, any);
        for weight in weights.iter_mut() {
            *weight = _mm256_div_ps(*weight, divisor);
        }
        any
    }
}

/// [`super::to_point`] for eight points.
#[target_feature(enable = "avx2")]
#[inline]
fn to_point8(viewer: &ViewerF32, p: [__m256; 3]) -> (__m256, __m256) {
    let [vx, vy, vz] = [0, 1, 2].map(|axis| _mm256_sub_ps(p[axis], _mm256_set1_ps(viewer.head[axis])));
    let [gx, gy, gz] = viewer.gaze.map(|g| _mm256_set1_ps(g));
    let dot = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(gx, vx), _mm256_mul_ps(gy, vy)),
        _mm256_mul_ps(gz, vz),
    );
    let length_squared = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(vx, vx), _mm256_mul_ps(vy, vy)),
        _mm256_mul_ps(vz, vz),
    );
    (dot, length_squared)
}

/// [`super::acos`] for eight values.
#[target_feature(enable = "avx2")]
#[inline]
fn acos8(x: __m256) -> __m256 {
    let one = _mm256_set1_ps(1.0);
    let a = _mm256_min_ps(_mm256_andnot_ps(_mm256_set1_ps(-0.0), x), one);
    let mut poly = _mm256_set1_ps(ACOS_POLYNOMIAL[0]);
    for coefficient in &ACOS_POLYNOMIAL[1..] {
        poly = _mm256_add_ps(_mm256_mul_ps(poly, a), _mm256_set1_ps(*coefficient));
    }
    let root = _mm256_sqrt_ps(_mm256_max_ps(_mm256_sub_ps(one, a), _mm256_setzero_ps()));
    let positive = _mm256_mul_ps(root, poly);
    let mirrored = _mm256_sub_ps(_mm256_set1_ps(std::f32::consts::PI), positive);
    let negative = _mm256_cmp_ps::<_CMP_LT_OQ>(x, _mm256_setzero_ps());
    _mm256_blendv_ps(positive, mirrored, negative)
}

/// [`super::cos`] for eight values.
#[target_feature(enable = "avx2")]
#[inline]
fn cos8(x: __m256) -> __m256 {
    let y = _mm256_mul_ps(x, x);
    let mut sum = _mm256_set1_ps(COS_POLYNOMIAL[0]);
    for coefficient in &COS_POLYNOMIAL[1..] {
        sum = _mm256_add_ps(_mm256_mul_ps(sum, y), _mm256_set1_ps(*coefficient));
    }
    sum
}

/// Half `half` (0: lanes 0–3) of eight f32 lanes.
#[target_feature(enable = "avx2")]
#[inline]
fn half_of(values: __m256, half: usize) -> __m128 {
    if half == 0 {
        _mm256_castps256_ps128(values)
    } else {
        _mm256_extractf128_ps::<1>(values)
    }
}

/// Half `half` of an eight-lane f32 mask as a four-lane f64 mask.
#[target_feature(enable = "avx2")]
#[inline]
fn half_mask(mask: __m256, half: usize) -> __m256d {
    _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm_castps_si128(half_of(mask, half))))
}

/// Eight f32 lanes from `lanes` (eight long).
#[target_feature(enable = "avx2")]
#[inline]
fn load(lanes: &[f32]) -> __m256 {
    assert_eq!(lanes.len(), LANES);
    // SAFETY: `lanes` holds eight f32 (checked just above); unaligned load.
    unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
}

/// Four f64 lanes into `lanes` (four long).
#[target_feature(enable = "avx2")]
#[inline]
fn store(lanes: &mut [f64], values: __m256d) {
    assert_eq!(lanes.len(), 4);
    // SAFETY: `lanes` holds four f64 (checked just above); unaligned store.
    unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), values) }
}
