//! Blocks the frustum fill refuses because their rays straddle a direction octant or a
//! dominant axis (a block on the line where a ray direction's component changes sign, or where
//! two components are equally long): each (octant, dominant axis) class of enough rays is
//! traced as a frustum packet of its own, the other lanes made empty, and only the rest as
//! packets of four or ray by ray. Every ray's hit is its own traversal's, whichever packet it
//! is traced in, so the hits are those of the small packets this replaces.

use super::SceneBvh;
use crate::accel::SceneHit;
use crate::accel::frustum::{FRUSTUM_RAYS, LaneArrays, PacketScratch, RayArrays};
use crate::accel::geometry::prepare;

/// A class traced as a frustum packet of its own needs at least this many rays; fewer go with
/// the rest (a frustum packet's fixed cost is about that of a few packets of four).
const FEWEST_RAYS_PER_SPLIT: u32 = 8;

/// Classes: octant (0–7) × dominant axis (0–2).
const CLASSES: usize = 24;

impl SceneBvh {
    /// Closest hits of a block whose rays do not make one frustum packet.
    #[inline(never)]
    pub(super) fn split_block_hits<const AVX2: bool>(
        &self,
        scratch: &mut PacketScratch,
        arrays: &RayArrays,
        hits: &mut [Option<SceneHit>; FRUSTUM_RAYS],
    ) {
        let mut classes = [0u64; CLASSES];
        // Lanes not traced in a frustum packet of their class (rays that cannot be traced
        // included: they get what the small packets give them).
        let mut rest = 0u64;
        for lane in 0..FRUSTUM_RAYS {
            match prepare(&arrays.ray(lane)) {
                Some(ray) => classes[ray.octant_inv as usize * 3 + ray.shear_axes[2]] |= 1 << lane,
                None => rest |= 1 << lane,
            }
        }
        // When one class holds every traceable ray, the fill refused the block for another
        // reason, and would refuse that class again.
        let traceable = classes.iter().fold(0, |all, class| all | class);
        let mut lanes = LaneArrays::of(arrays);
        let mut class_hits = [None; FRUSTUM_RAYS];
        for class in classes {
            if class == 0 {
                continue;
            }
            if class.count_ones() < FEWEST_RAYS_PER_SPLIT || class == traceable {
                rest |= class;
                continue;
            }
            only_lanes(&mut lanes, arrays, class);
            if scratch.frustum.fill_from_arrays_on::<AVX2>(&lanes.arrays()) {
                self.frustum_hits(&mut scratch.frustum, &mut class_hits);
                take_lanes(hits, &class_hits, class);
            } else {
                rest |= class;
            }
        }
        if rest != 0 {
            only_lanes(&mut lanes, arrays, rest);
            let rays = std::array::from_fn::<_, FRUSTUM_RAYS, _>(|lane| lanes.arrays().ray(lane));
            self.small_packet_hits(&rays, &mut class_hits);
            take_lanes(hits, &class_hits, rest);
        }
    }
}

/// `lanes` as `arrays` with only the rays of `keep` (bit per lane): the others' intervals
/// empty (`t_min = +inf`, `t_max = -inf`), so that no packet holds them.
fn only_lanes(lanes: &mut LaneArrays, arrays: &RayArrays, keep: u64) {
    for lane in 0..FRUSTUM_RAYS {
        let kept = keep & (1 << lane) != 0;
        lanes.t_min[lane] = if kept {
            arrays.t_min[lane]
        } else {
            f32::INFINITY
        };
        lanes.t_max[lane] = if kept {
            arrays.t_max[lane]
        } else {
            f32::NEG_INFINITY
        };
    }
}

/// Copies the hits of the lanes in `lanes` (bit per lane).
fn take_lanes(
    hits: &mut [Option<SceneHit>; FRUSTUM_RAYS],
    from: &[Option<SceneHit>; FRUSTUM_RAYS],
    lanes: u64,
) {
    let mut rest = lanes;
    while rest != 0 {
        let lane = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        hits[lane] = from[lane];
    }
}
