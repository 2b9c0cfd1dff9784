//! Eight rays with any origins walked together through a scene's top level (the BVH over its
//! placements), one ray per AVX2 lane.
//!
//! A single ray walks the top level with `walk::traverse`, so each occupied child is tested
//! here against the eight rays in that walk's own box arithmetic (`walk::avx2::child_hits`:
//! `(plane - origin) * inverse_direction`, the maximum with `t_min` and the minimum with
//! `t_max` first, then both ends widened by `SLAB_ERROR` of their magnitude), children are
//! pushed in its order (slots `i ^ order`: the rays share their direction octant) with each
//! lane's widened entry distance and popped with each lane's `near <= t_max`. `traverse`
//! descends into a node's nearest hit child without that test (a widened exit may leave a hit
//! child's widened entry just above `t_max`), so a lane's entry for its own nearest child is
//! pushed as `-inf`. Each lane therefore reaches the same leaves in the same order, with the
//! same `t_max`, as its own walk; the caller tests a leaf's placements for the lanes that reach
//! it ([`TopLevelVisits::leaf`]) in the order of its single-ray walk, and a subtree that at
//! most `single_up_to` lanes reach goes to each of them alone ([`TopLevelVisits::alone`]).

use std::arch::x86_64::*;

use crate::accel::eights::RAYS;
use crate::accel::lanes8::{LaneStack, lane_mask};
use crate::accel::walk::{BoxRay, ORDER, TraversalRay};
use crate::accel::wide_bvh::{LEAF_BIT, WIDTH, WideNode};

/// What the walk hands back to its caller.
pub(crate) trait TopLevelVisits {
    /// The placements of leaf `code` for the rays in `lanes` (bit per lane), each from its
    /// `t_max[lane]`, which a hit lowers.
    fn leaf(&mut self, code: u32, lanes: u32, t_max: &mut [f32; RAYS]);
    /// The subtree at inner node `root` walked by ray `lane` alone from `t_max`, which a hit
    /// lowers.
    fn alone(&mut self, root: u32, lane: usize, t_max: &mut f32);
}

/// The box test's values of the eight rays, one per lane.
struct BoxRays {
    origin: [__m256; 3],
    inverse: [__m256; 3],
    t_min: __m256,
}

/// Walks `nodes` (a top level of several placements) with the rays in `lanes` (bit per lane),
/// which must share their direction octant, from their `t_max` (lowered by the visits); false
/// if the walk would need more than `ENTRIES` stack entries (then the visits made so far are
/// to be forgotten).
#[target_feature(enable = "avx2")]
pub(crate) fn walk_top8<const ENTRIES: usize>(
    nodes: &[WideNode],
    rays: &[TraversalRay; RAYS],
    lanes: u32,
    single_up_to: u32,
    t_max: &mut [f32; RAYS],
    visits: &mut impl TopLevelVisits,
) -> bool {
    let first = &rays[lanes.trailing_zeros() as usize];
    debug_assert!(
        (0..RAYS).all(|lane| lanes & (1 << lane) == 0 || rays[lane].octant_inv == first.octant_inv)
    );
    // The plane rows and the visiting order are the octant's, shared by every lane.
    let rows = BoxRay::new(first);
    let mut values = [[0.0f32; RAYS]; 7];
    for (lane, ray) in rays.iter().enumerate() {
        for axis in 0..3 {
            values[axis][lane] = ray.origin[axis];
            values[3 + axis][lane] = ray.inv_direction[axis];
        }
        values[6][lane] = ray.t_min;
    }
    // SAFETY: eight floats per row.
    let row = |index: usize| unsafe { _mm256_loadu_ps(values[index].as_ptr()) };
    let box_rays = BoxRays {
        origin: [row(0), row(1), row(2)],
        inverse: [row(3), row(4), row(5)],
        t_min: row(6),
    };
    // SAFETY: eight floats.
    let load = |t_max: &[f32; RAYS]| unsafe { _mm256_loadu_ps(t_max.as_ptr()) };
    let mut t_max_lanes = load(t_max);
    let mut stack = LaneStack::<ENTRIES>::with_root(lanes);
    while let Some((code, mask, near)) = stack.pop() {
        let active =
            mask & _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, t_max_lanes)) as u32;
        if active == 0 {
            continue;
        }
        if code & LEAF_BIT != 0 {
            visits.leaf(code, active, t_max);
            t_max_lanes = load(t_max);
            continue;
        }
        if active.count_ones() <= single_up_to {
            // Lanes are independent: each walks the subtree alone, in its own order.
            let mut rest = active;
            while rest != 0 {
                let lane = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                visits.alone(code, lane, &mut t_max[lane]);
            }
            t_max_lanes = load(t_max);
            continue;
        }
        let node = &nodes[code as usize];
        // SAFETY: plane rows are eight floats, 32-byte aligned (`WideNode` is).
        let occupied = unsafe {
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(
                _mm256_load_ps(node.planes[0].as_ptr()),
                _mm256_load_ps(node.planes[1].as_ptr()),
            ))
        } as usize;
        // The hit children nearest first, each lane's own nearest entered unconditionally.
        let mut children = [(0u32, 0u32, _mm256_setzero_ps()); WIDTH];
        let mut count = 0;
        let mut unclaimed = active;
        let order = usize::from(node.orders[rows.order]);
        let mut ordered = u32::from(ORDER[order][occupied]);
        while ordered != 0 {
            let slot = ordered.trailing_zeros() as usize ^ order;
            ordered &= ordered - 1;
            let (hit, child_near) = child_lanes(node, slot, &rows, &box_rays, t_max_lanes);
            let hit = hit & active;
            if hit != 0 {
                let nearest = lane_mask(hit & unclaimed);
                unclaimed &= !hit;
                let child_near =
                    _mm256_blendv_ps(child_near, _mm256_set1_ps(f32::NEG_INFINITY), nearest);
                children[count] = (node.children[slot], hit, child_near);
                count += 1;
            }
        }
        if !stack.has_room(count) {
            return false;
        }
        // Farthest first, so that the nearest is popped first.
        for &(child, hit, child_near) in children[..count].iter().rev() {
            stack.push(child, hit, child_near);
        }
    }
    true
}

/// Child `slot` of `node` against the eight rays: the lanes that reach it within their
/// `[t_min, t_max]` (bit per lane) and their widened entry distances; per lane the operations
/// of `walk::avx2::child_hits` in the same order.
#[target_feature(enable = "avx2")]
#[inline]
fn child_lanes(
    node: &WideNode,
    slot: usize,
    rows: &BoxRay,
    rays: &BoxRays,
    t_max: __m256,
) -> (u32, __m256) {
    let mut near = rays.t_min;
    let mut far = t_max;
    for axis in 0..3 {
        let entry = _mm256_set1_ps(node.planes[rows.entry[axis]][slot]);
        let exit = _mm256_set1_ps(node.planes[rows.exit[axis]][slot]);
        let (origin, inverse) = (rays.origin[axis], rays.inverse[axis]);
        near = _mm256_max_ps(near, _mm256_mul_ps(_mm256_sub_ps(entry, origin), inverse));
        far = _mm256_min_ps(far, _mm256_mul_ps(_mm256_sub_ps(exit, origin), inverse));
    }
    crate::accel::walk::avx2::widened_hits(near, far)
}
