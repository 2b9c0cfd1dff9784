//! [`FrustumPacket::fill_from_arrays`] with AVX2, for the frame's blocks: two groups of four per
//! vector, written straight into the packet's groups, and the quadrants' bounds reduced while
//! the lanes are in registers. Lane by lane the operations of `RayPacket::prepare_lanes`, in
//! the same order and with the same operand order (no fused multiply-add), so every value of
//! the packet is the one the four-lane fill gives; the bounds are minima and maxima of the same
//! values, which do not depend on the order they are taken in.

use super::{
    FRUSTUM_GROUPS, FRUSTUM_RAYS, FrustumPacket, LaneArrays, QUADRANTS, RayArrays, RayBounds,
};
use crate::accel::geometry::prepare as prepare_one;
use crate::accel::lanes8::{abs, half, lane_mask, select};
use crate::accel::packet::{LANES, RayPacket};
use crate::accel::walk::MAX_INV_DIRECTION;
use crate::accel::{MAX_COORDINATE, Ray};
use glam::{Vec3A, Vec4};
use std::arch::x86_64::*;

/// The two pairs of groups (eight lanes each) making quadrant `q`: groups 2p and 2p + 1.
const QUADRANT_PAIRS: [[usize; 2]; QUADRANTS] = [[0, 2], [1, 3], [4, 6], [5, 7]];

/// Eight lanes of a block's value array, from lane `8 * pair`.
#[target_feature(enable = "avx2")]
#[inline]
fn lanes_of(values: &[f32; 64], pair: usize) -> __m256 {
    let lanes = &values[8 * pair..8 * pair + 8];
    // SAFETY: `lanes` holds eight floats (the slice above is bounds-checked).
    unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
}

#[target_feature(enable = "avx2")]
#[inline]
fn smallest(values: __m256) -> f32 {
    let four = _mm_min_ps(
        _mm256_castps256_ps128(values),
        _mm256_extractf128_ps::<1>(values),
    );
    Vec4::from(four).min_element()
}

#[target_feature(enable = "avx2")]
#[inline]
fn largest(values: __m256) -> f32 {
    let four = _mm_max_ps(
        _mm256_castps256_ps128(values),
        _mm256_extractf128_ps::<1>(values),
    );
    Vec4::from(four).max_element()
}

/// [`FrustumPacket::fill_from_rays`] of a full packet on the AVX2 path: each eight rays'
/// floats transposed into lanes, then [`fill_from_arrays`] (which makes the packet the
/// four-lane fill makes of the same rays).
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn fill_from_rays(packet: &mut FrustumPacket, rays: &[Ray; FRUSTUM_RAYS]) -> bool {
    let mut lanes = LaneArrays::default();
    for (pair, eight) in rays.as_chunks::<8>().0.iter().enumerate() {
        // SAFETY: `Ray` is `repr(C)`, eight `f32`s (asserted below), so each ray is one
        // unaligned 32-byte load.
        let rows = eight
            .each_ref()
            .map(|ray| unsafe { _mm256_loadu_ps(std::ptr::from_ref(ray).cast::<f32>()) });
        let columns = transposed(rows);
        let lanes_at = 8 * pair..8 * pair + 8;
        let store = |target: &mut [f32; FRUSTUM_RAYS], column: __m256| {
            let target = &mut target[lanes_at.clone()];
            // SAFETY: `target` holds eight floats (the slice above is bounds-checked).
            unsafe { _mm256_storeu_ps(target.as_mut_ptr(), column) };
        };
        for axis in 0..3 {
            store(&mut lanes.origin[axis], columns[axis]);
            store(&mut lanes.direction[axis], columns[3 + axis]);
        }
        store(&mut lanes.t_min, columns[6]);
        store(&mut lanes.t_max, columns[7]);
    }
    fill_from_arrays(packet, &lanes.arrays())
}

const _: () = assert!(
    size_of::<Ray>() == 32
        && std::mem::offset_of!(Ray, direction) == 12
        && std::mem::offset_of!(Ray, t_min) == 24
        && std::mem::offset_of!(Ray, t_max) == 28
);

/// An 8×8 block of floats transposed: column `k` of the result holds float `k` of each row.
#[target_feature(enable = "avx2")]
#[inline]
fn transposed(rows: [__m256; 8]) -> [__m256; 8] {
    let [r0, r1, r2, r3, r4, r5, r6, r7] = rows;
    // Pairs of rows interleaved, then quarters of four rows, then halves across 128-bit lanes.
    let (a0, a1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpackhi_ps(r0, r1));
    let (a2, a3) = (_mm256_unpacklo_ps(r2, r3), _mm256_unpackhi_ps(r2, r3));
    let (a4, a5) = (_mm256_unpacklo_ps(r4, r5), _mm256_unpackhi_ps(r4, r5));
    let (a6, a7) = (_mm256_unpacklo_ps(r6, r7), _mm256_unpackhi_ps(r6, r7));
    let b0 = _mm256_shuffle_ps::<0x44>(a0, a2);
    let b1 = _mm256_shuffle_ps::<0xee>(a0, a2);
    let b2 = _mm256_shuffle_ps::<0x44>(a1, a3);
    let b3 = _mm256_shuffle_ps::<0xee>(a1, a3);
    let b4 = _mm256_shuffle_ps::<0x44>(a4, a6);
    let b5 = _mm256_shuffle_ps::<0xee>(a4, a6);
    let b6 = _mm256_shuffle_ps::<0x44>(a5, a7);
    let b7 = _mm256_shuffle_ps::<0xee>(a5, a7);
    [
        _mm256_permute2f128_ps::<0x20>(b0, b4),
        _mm256_permute2f128_ps::<0x20>(b1, b5),
        _mm256_permute2f128_ps::<0x20>(b2, b6),
        _mm256_permute2f128_ps::<0x20>(b3, b7),
        _mm256_permute2f128_ps::<0x31>(b0, b4),
        _mm256_permute2f128_ps::<0x31>(b1, b5),
        _mm256_permute2f128_ps::<0x31>(b2, b6),
        _mm256_permute2f128_ps::<0x31>(b3, b7),
    ]
}

/// Per lane, lows and highs of what a quadrant's bounds take (inactive lanes ±∞). The
/// origins' bounds are reduced only for blocks of several origins ([`origin_bounds`]).
struct LaneBounds {
    inv_low: [__m256; 3],
    inv_high: [__m256; 3],
    t_min_low: __m256,
}

/// The octant code (`octant_inv`) of rays whose direction components are negative where
/// `negative_bits` (per axis, bit per lane) are set; all lanes agree.
#[inline]
fn octant_of(negative_bits: [u32; 3]) -> u32 {
    (if negative_bits[0] != 0 { 0 } else { 4 })
        | (if negative_bits[1] != 0 { 0 } else { 2 })
        | (if negative_bits[2] != 0 { 0 } else { 1 })
}

/// Two groups' lanes as loaded and prepared (intervals of invalid lanes already empty).
struct PairLanes {
    origin: [__m256; 3],
    direction: [__m256; 3],
    inverse: [__m256; 3],
    t_min: __m256,
    t_max: __m256,
}

/// The values of the watertight test for a dominant axis: the shear and the origin in sheared
/// axis order.
struct Sheared {
    shear: [__m256; 3],
    permuted_origin: [__m256; 3],
}

impl PairLanes {
    /// The shear and permuted origin of the lanes for dominant axis `kz` (per lane what
    /// `RayPacket::prepare_lanes` computes).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn sheared(&self, kz: usize) -> Sheared {
        // The axes in sheared order by constant indices (indexing by `kz` put the vectors
        // through memory and stalled on reading half of one back).
        let in_order = |values: &[__m256; 3]| match kz {
            0 => [values[1], values[2], values[0]],
            1 => [values[2], values[0], values[1]],
            _ => *values,
        };
        let [direction_x, direction_y, _] = in_order(&self.direction);
        let inv_dominant = in_order(&self.inverse)[2];
        Sheared {
            shear: [
                _mm256_mul_ps(direction_x, inv_dominant),
                _mm256_mul_ps(direction_y, inv_dominant),
                inv_dominant,
            ],
            permuted_origin: in_order(&self.origin),
        }
    }

    /// Writes half `h` of the lanes into `group`, field by field from the registers
    /// (building the arrays first and copying them stalled on every copy: wide loads of narrow
    /// stores).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn store(
        &self,
        group: &mut RayPacket,
        h: usize,
        lanes: u32,
        octant_inv: u32,
        kz: usize,
        sheared: &Sheared,
    ) {
        for axis in 0..3 {
            group.origin[axis] = half(self.origin[axis], h);
            group.direction[axis] = half(self.direction[axis], h);
            group.inv_direction[axis] = half(self.inverse[axis], h);
            group.shear[axis] = half(sheared.shear[axis], h);
            group.permuted_origin[axis] = half(sheared.permuted_origin[axis], h);
        }
        group.t_min = half(self.t_min, h);
        group.t_max = half(self.t_max, h);
        group.hit_uv = [Vec4::ZERO; 2];
        group.hit_normal = [Vec4::ZERO; 3];
        group.octant_inv = octant_inv;
        let kx = (kz + 1) % 3;
        group.shear_axes = [kx, (kx + 1) % 3, kz];
        group.lanes = lanes;
    }
}

/// [`FrustumPacket::fill_from_arrays`] on the AVX2 path: the same packet, value for value, and
/// the same answer.
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn fill_from_arrays(packet: &mut FrustumPacket, arrays: &RayArrays) -> bool {
    let infinity = _mm256_set1_ps(f32::INFINITY);
    let negative_infinity = _mm256_set1_ps(f32::NEG_INFINITY);
    let max_coordinate = _mm256_set1_ps(MAX_COORDINATE);
    let tiny = _mm256_set1_ps(1.0 / MAX_INV_DIRECTION);
    let zero = _mm256_setzero_ps();
    let one = _mm256_set1_ps(1.0);
    let all_ones = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    let mut octant: Option<u32> = None;
    let mut valid_lanes = 0u64;
    let mut quadrants = [RayBounds::EMPTY; QUADRANTS];
    let mut holds_rays = [false; QUADRANTS];
    let candidate_origin = arrays.origin.each_ref().map(|axis| _mm256_set1_ps(axis[0]));
    // Valid lanes whose origin differs from lane 0's.
    let mut other_origins = 0u32;
    packet.group_count = FRUSTUM_GROUPS;
    for ((quadrant, holds_rays), pairs) in quadrants
        .iter_mut()
        .zip(&mut holds_rays)
        .zip(QUADRANT_PAIRS)
    {
        let mut lane_bounds = LaneBounds {
            inv_low: [infinity; 3],
            inv_high: [negative_infinity; 3],
            t_min_low: infinity,
        };
        for pair in pairs {
            let origin = arrays.origin.each_ref().map(|axis| lanes_of(axis, pair));
            let direction = arrays.direction.each_ref().map(|axis| lanes_of(axis, pair));
            let t_min = lanes_of(arrays.t_min, pair);
            let t_max = lanes_of(arrays.t_max, pair);
            let finite = |v: &[__m256; 3]| {
                let each = v.map(|axis| _mm256_cmp_ps::<_CMP_LT_OQ>(abs(axis), infinity));
                _mm256_and_ps(_mm256_and_ps(each[0], each[1]), each[2])
            };
            let abs_origin = origin.map(|v| abs(v));
            let abs_direction = direction.map(|v| abs(v));
            let longest = _mm256_max_ps(
                _mm256_max_ps(abs_direction[0], abs_direction[1]),
                abs_direction[2],
            );
            let nearest_origin =
                _mm256_max_ps(_mm256_max_ps(abs_origin[0], abs_origin[1]), abs_origin[2]);
            let valid = _mm256_and_ps(
                _mm256_and_ps(
                    _mm256_and_ps(
                        _mm256_and_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_min, t_max), finite(&origin)),
                        _mm256_cmp_ps::<_CMP_LE_OQ>(nearest_origin, max_coordinate),
                    ),
                    finite(&direction),
                ),
                _mm256_cmp_ps::<_CMP_GE_OQ>(longest, tiny),
            );
            let valid_bits = _mm256_movemask_ps(valid) as u32;
            valid_lanes |= u64::from(valid_bits) << (8 * pair);
            let same = [0, 1, 2]
                .map(|axis| _mm256_cmp_ps::<_CMP_EQ_OQ>(origin[axis], candidate_origin[axis]));
            let same_bits =
                _mm256_movemask_ps(_mm256_and_ps(_mm256_and_ps(same[0], same[1]), same[2])) as u32;
            other_origins |= valid_bits & !same_bits;
            let negative = direction.map(|d| _mm256_cmp_ps::<_CMP_LT_OQ>(d, zero));
            let inverse = [0, 1, 2].map(|axis| {
                let clamped = select(
                    negative[axis],
                    _mm256_set1_ps(-MAX_INV_DIRECTION),
                    _mm256_set1_ps(MAX_INV_DIRECTION),
                );
                select(
                    _mm256_cmp_ps::<_CMP_LT_OQ>(abs_direction[axis], tiny),
                    clamped,
                    _mm256_div_ps(one, direction[axis]),
                )
            });
            let negative_bits = negative.map(|mask| _mm256_movemask_ps(mask) as u32);
            let [ax, ay, az] = abs_direction;
            let x_dominant = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(ax, ay),
                _mm256_cmp_ps::<_CMP_GE_OQ>(ax, az),
            );
            let y_dominant = _mm256_and_ps(
                _mm256_xor_ps(x_dominant, all_ones),
                _mm256_cmp_ps::<_CMP_GE_OQ>(ay, az),
            );
            let (x_bits, y_bits) = (
                _mm256_movemask_ps(x_dominant) as u32,
                _mm256_movemask_ps(y_dominant) as u32,
            );
            let lanes8 = PairLanes {
                origin,
                direction,
                inverse,
                t_min: select(valid, t_min, infinity),
                t_max: select(valid, t_max, negative_infinity),
            };
            // Usually both groups hold four valid rays of one octant and one dominant axis:
            // then they are classified, and their shear made, once for both.
            let uniform = valid_bits == 0xff
                && negative_bits.iter().all(|&bits| bits == 0 || bits == 0xff)
                && (x_bits == 0xff || (x_bits == 0 && (y_bits == 0xff || y_bits == 0)));
            if uniform {
                let octant_inv = octant_of(negative_bits);
                let kz = if x_bits != 0 {
                    0
                } else if y_bits != 0 {
                    1
                } else {
                    2
                };
                if *octant.get_or_insert(octant_inv) != octant_inv {
                    return false;
                }
                let sheared = lanes8.sheared(kz);
                for h in 0..2 {
                    lanes8.store(
                        &mut packet.groups[2 * pair + h],
                        h,
                        0xf,
                        octant_inv,
                        kz,
                        &sheared,
                    );
                }
            }
            for h in (0..2).filter(|_| !uniform) {
                let group_index = 2 * pair + h;
                let lanes = (valid_bits >> (LANES * h)) & 0xf;
                if lanes == 0 {
                    // No valid ray: as in the four-lane fill, the group is left out unless a
                    // ray of it could be traced alone (then there is no frustum packet).
                    let first = LANES * group_index;
                    if (first..first + LANES).any(|index| prepare_one(&arrays.ray(index)).is_some())
                    {
                        return false;
                    }
                    packet.groups[group_index].reset();
                    continue;
                }
                let negative_bits = negative_bits.map(|bits| (bits >> (LANES * h)) & lanes);
                if negative_bits
                    .iter()
                    .any(|bits| *bits != 0 && *bits != lanes)
                {
                    return false;
                }
                let octant_inv = octant_of(negative_bits);
                let (x_lanes, y_lanes) = (
                    (x_bits >> (LANES * h)) & lanes,
                    (y_bits >> (LANES * h)) & lanes,
                );
                let kz = if x_lanes == lanes {
                    0
                } else if y_lanes == lanes {
                    1
                } else if x_lanes | y_lanes == 0 {
                    2
                } else {
                    return false;
                };
                if *octant.get_or_insert(octant_inv) != octant_inv {
                    return false;
                }
                let sheared = lanes8.sheared(kz);
                lanes8.store(
                    &mut packet.groups[group_index],
                    h,
                    lanes,
                    octant_inv,
                    kz,
                    &sheared,
                );
            }
            // Bounds over the valid lanes (groups without one were reset: no lane of theirs
            // is valid either).
            let b = &mut lane_bounds;
            for ((low, high), inverse) in b.inv_low.iter_mut().zip(&mut b.inv_high).zip(inverse) {
                *low = _mm256_min_ps(*low, select(valid, inverse, infinity));
                *high = _mm256_max_ps(*high, select(valid, inverse, negative_infinity));
            }
            lane_bounds.t_min_low =
                _mm256_min_ps(lane_bounds.t_min_low, select(valid, t_min, infinity));
        }
        let quadrant_lanes = pairs.iter().fold(0, |lanes, pair| {
            lanes | ((valid_lanes >> (8 * pair)) & 0xff)
        });
        if quadrant_lanes != 0 {
            *holds_rays = true;
            let b = &lane_bounds;
            *quadrant = RayBounds {
                inv_low: Vec3A::from(b.inv_low.map(|v| smallest(v))),
                inv_high: Vec3A::from(b.inv_high.map(|v| largest(v))),
                t_min_low: smallest(b.t_min_low),
                ..RayBounds::EMPTY
            };
        }
    }
    let Some(octant_inv) = octant else {
        return false;
    };
    packet.octant_inv = octant_inv;
    // One shared origin: every valid lane's equals the first valid lane's (compared as the
    // four-lane fill does, `==` per axis), which is then each quadrant's origin bounds. Lane 0
    // is the first valid lane of nearly every block, so the lanes were compared with it while
    // loaded; `==` is transitive on the valid (finite) origins, so "all equal lane 0's" means
    // "all equal the first valid lane's", and only where that fails are the lanes compared
    // with the first valid lane's and the bounds reduced over them.
    let first = valid_lanes.trailing_zeros() as usize;
    let first_origin = arrays.origin.each_ref().map(|axis| axis[first]);
    let shared = if other_origins == 0 {
        Some(Vec3A::from(first_origin))
    } else {
        origin_bounds(
            arrays,
            valid_lanes,
            first_origin,
            &mut quadrants,
            &holds_rays,
        )
    };
    let mut whole = RayBounds::EMPTY;
    for (quadrant, holds_rays) in quadrants.iter_mut().zip(holds_rays) {
        if let Some(origin) = shared
            && holds_rays
        {
            quadrant.origin_low = origin;
            quadrant.origin_high = origin;
        }
        whole = whole.union(*quadrant);
        *quadrant = quadrant.finished();
    }
    packet.whole = whole.finished();
    packet.quadrants = quadrants;
    true
}

/// For a block whose valid lanes do not all share lane 0's origin: whether they all share the
/// first valid lane's (`first_origin`, compared as the four-lane fill does), and if not, each
/// quadrant's origin bounds over its valid lanes (`valid_lanes`, bit per lane).
#[target_feature(enable = "avx2")]
#[inline(never)]
fn origin_bounds(
    arrays: &RayArrays,
    valid_lanes: u64,
    first_origin: [f32; 3],
    quadrants: &mut [RayBounds; QUADRANTS],
    holds_rays: &[bool; QUADRANTS],
) -> Option<Vec3A> {
    let valid_of = |pair: usize| ((valid_lanes >> (8 * pair)) & 0xff) as u32;
    // With lane 0 valid it is the first valid lane, and its origin was the one compared.
    let differ = valid_lanes & 1 != 0
        || (0..8).any(|pair| {
            let same = arrays.origin.iter().enumerate().fold(
                _mm256_castsi256_ps(_mm256_set1_epi32(-1)),
                |same, (axis, values)| {
                    let first = _mm256_set1_ps(first_origin[axis]);
                    _mm256_and_ps(
                        same,
                        _mm256_cmp_ps::<_CMP_EQ_OQ>(lanes_of(values, pair), first),
                    )
                },
            );
            valid_of(pair) & !(_mm256_movemask_ps(same) as u32) != 0
        });
    if !differ {
        return Some(Vec3A::from(first_origin));
    }
    let (infinity, negative_infinity) = (
        _mm256_set1_ps(f32::INFINITY),
        _mm256_set1_ps(f32::NEG_INFINITY),
    );
    for ((quadrant, holds_rays), pairs) in quadrants.iter_mut().zip(holds_rays).zip(QUADRANT_PAIRS)
    {
        if !holds_rays {
            continue;
        }
        let (mut low, mut high) = ([infinity; 3], [negative_infinity; 3]);
        for pair in pairs {
            let valid = lane_mask(valid_of(pair));
            for axis in 0..3 {
                let origin = lanes_of(&arrays.origin[axis], pair);
                low[axis] = _mm256_min_ps(low[axis], select(valid, origin, infinity));
                high[axis] = _mm256_max_ps(high[axis], select(valid, origin, negative_infinity));
            }
        }
        quadrant.origin_low = Vec3A::from(low.map(|v| smallest(v)));
        quadrant.origin_high = Vec3A::from(high.map(|v| largest(v)));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::packet::RayPacket;
    use crate::accel::tests::Rng;
    use glam::Vec3;

    impl LaneArrays {
        fn set(&mut self, lane: usize, origin: Vec3, direction: Vec3) {
            for axis in 0..3 {
                self.origin[axis][lane] = origin[axis];
                self.direction[axis][lane] = direction[axis];
            }
        }
    }

    /// A block of kind `kind % 8`: a pinhole's rays, several origins, mixed octants, invalid
    /// lanes and groups, tiny and zero direction components, dominant-axis ties, nothing valid.
    fn random_block(rng: &mut Rng, kind: u32) -> LaneArrays {
        let mut block = LaneArrays {
            origin: [[0.0; FRUSTUM_RAYS]; 3],
            direction: [[0.0; FRUSTUM_RAYS]; 3],
            t_min: [0.0; FRUSTUM_RAYS],
            t_max: [f32::INFINITY; FRUSTUM_RAYS],
        };
        let eye = rng.point(-3.0, 3.0);
        let centre = rng.direction();
        for lane in 0..FRUSTUM_RAYS {
            let spread = if kind % 8 == 2 { 2.0 } else { 0.05 };
            let direction = centre + spread * rng.point(-1.0, 1.0);
            let origin = match kind % 8 {
                1 => eye + rng.point(-0.1, 0.1),
                _ => eye,
            };
            block.set(lane, origin, direction);
            block.t_min[lane] = if kind % 8 == 1 {
                rng.range(0.0, 0.5)
            } else {
                0.0
            };
        }
        let invalid = [
            (Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X),
            (Vec3::new(0.0, f32::INFINITY, 0.0), Vec3::X),
            (Vec3::splat(2.0e12), Vec3::X),
            (Vec3::ZERO, Vec3::new(0.0, f32::NAN, 1.0)),
            (Vec3::ZERO, Vec3::ZERO),
            (Vec3::ZERO, Vec3::splat(1.0e-20)),
        ];
        match kind % 8 {
            3 => {
                for _ in 0..1 + rng.next_u64() % 12 {
                    let lane = (rng.next_u64() % 64) as usize;
                    let (origin, direction) = invalid[(rng.next_u64() % 6) as usize];
                    block.set(lane, origin, direction);
                    if rng.next_u64().is_multiple_of(4) {
                        block.t_min[lane] = 2.0;
                        block.t_max[lane] = 1.0;
                    }
                }
            }
            4 => {
                // Components below the clamp (or zero), keeping the centre's octant.
                let axis = (0..3)
                    .min_by(|a, b| centre[*a].abs().total_cmp(&centre[*b].abs()))
                    .unwrap_or(0);
                for _ in 0..1 + rng.next_u64() % 16 {
                    let lane = (rng.next_u64() % 64) as usize;
                    let tiny = [0.0, 1.0e-19, 3.0e-18, 1.0 / MAX_INV_DIRECTION]
                        [(rng.next_u64() % 4) as usize];
                    block.direction[axis][lane] = match centre[axis] < 0.0 {
                        true if tiny == 0.0 => -1.0e-30,
                        true => -tiny,
                        false => tiny,
                    };
                }
            }
            5 => {
                // Every ray's two largest components tie in magnitude.
                let dominant = (0..3)
                    .max_by(|a, b| centre[*a].abs().total_cmp(&centre[*b].abs()))
                    .unwrap_or(0);
                let other = (dominant + 1 + (rng.next_u64() % 2) as usize) % 3;
                for lane in 0..FRUSTUM_RAYS {
                    block.direction[other][lane] =
                        block.direction[dominant][lane].copysign(centre[other]);
                }
            }
            6 => {
                let group = (rng.next_u64() % 16) as usize;
                for lane in 4 * group..4 * group + 4 {
                    let (origin, direction) = invalid[(rng.next_u64() % 6) as usize];
                    block.set(lane, origin, direction);
                }
            }
            7 => {
                for lane in 0..FRUSTUM_RAYS {
                    block.set(lane, Vec3::ZERO, Vec3::ZERO);
                }
            }
            _ => {}
        }
        block
    }

    fn bits(values: &[Vec4]) -> Vec<u32> {
        values
            .iter()
            .flat_map(|v| v.to_array().map(f32::to_bits))
            .collect()
    }

    /// Equal bounds (compared as floats: a bound may be +0 where the other has −0, which no
    /// box test tells apart).
    fn same_bounds(a: &RayBounds, b: &RayBounds) -> bool {
        a.inv_low == b.inv_low
            && a.inv_high == b.inv_high
            && a.origin_low == b.origin_low
            && a.origin_high == b.origin_high
            && a.t_min_low == b.t_min_low
            && a.origin_centre == b.origin_centre
            && a.widening == b.widening
    }

    fn differences(a: &FrustumPacket, b: &FrustumPacket) -> Vec<String> {
        let mut found = Vec::new();
        if (a.group_count, a.octant_inv) != (b.group_count, b.octant_inv) {
            found.push("group count or octant".to_string());
        }
        for (index, (x, y)) in a.groups.iter().zip(&b.groups).enumerate() {
            let scalars = |p: &RayPacket| (p.lanes, bits(&[p.t_min, p.t_max]));
            if scalars(x) != scalars(y) {
                found.push(format!("group {index}: lanes or interval"));
            }
            if x.lanes == 0 {
                continue;
            }
            let vectors = |p: &RayPacket| {
                let mut all = vec![p.octant_inv, p.shear_axes[0] as u32, p.shear_axes[1] as u32];
                all.extend(bits(&p.origin));
                all.extend(bits(&p.direction));
                all.extend(bits(&p.inv_direction));
                all.extend(bits(&p.hit_uv));
                all.extend(bits(&p.hit_normal));
                all.extend(bits(&p.shear));
                all.extend(bits(&p.permuted_origin));
                all
            };
            if vectors(x) != vectors(y) {
                found.push(format!("group {index}: rays"));
            }
        }
        for (quadrant, (x, y)) in a.quadrants.iter().zip(&b.quadrants).enumerate() {
            if !same_bounds(x, y) {
                found.push(format!("quadrant {quadrant}: {x:?} against {y:?}"));
            }
        }
        if !same_bounds(&a.whole, &b.whole) {
            found.push(format!("whole: {:?} against {:?}", a.whole, b.whole));
        }
        found
    }

    #[test]
    fn the_avx2_fills_make_the_packets_of_the_four_lane_fills() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = Rng::new(31);
        // Reused from block to block, as a frame's scratch is.
        let (mut plain, mut wide) = (FrustumPacket::empty(), FrustumPacket::empty());
        let (mut filled, mut refused) = ([0; 8], 0);
        for case in 0..4000 {
            let block = random_block(&mut rng, case);
            let expected = plain.fill_from_arrays(&block.arrays());
            // SAFETY: the CPU has AVX2 (checked above).
            let answer = unsafe { fill_from_arrays(&mut wide, &block.arrays()) };
            assert_eq!(answer, expected, "block {case} (kind {})", case % 8);
            if !expected {
                refused += 1;
                continue;
            }
            filled[case as usize % 8] += 1;
            let found = differences(&plain, &wide);
            assert!(
                found.is_empty(),
                "block {case} (kind {}): {found:?}",
                case % 8
            );
            // The same rays as `Ray`s, transposed eight at a time.
            let rays: [Ray; FRUSTUM_RAYS] = std::array::from_fn(|lane| block.arrays().ray(lane));
            assert!(plain.fill_from_rays(&rays), "block {case}");
            // SAFETY: as above.
            assert!(unsafe { fill_from_rays(&mut wide, &rays) }, "block {case}");
            let found = differences(&plain, &wide);
            assert!(
                found.is_empty(),
                "rays of block {case} (kind {}): {found:?}",
                case % 8
            );
            assert!(
                found.is_empty(),
                "block {case} (kind {}): {found:?}",
                case % 8
            );
        }
        // Both answers occur often, and filled packets of every kind but the empty one.
        assert!(
            refused > 700 && filled[7] == 0,
            "{filled:?} filled, {refused} refused"
        );
        let every_kind = [0, 1, 3, 4, 5, 6].iter().all(|kind| filled[*kind] > 100);
        assert!(every_kind, "{filled:?} filled, {refused} refused");
    }
}
