//! Eight rays with any origins (light-field subpixels, interleaved stereo lattices) walked
//! together through a BVH of triangle groups, one ray per AVX2 lane.
//!
//! A node's occupied children are tested one at a time against the eight rays, lane by lane
//! in the single-ray walk's arithmetic (`single_ray`'s box test: `(origin - plane) * scale`,
//! then the maximum with `t_min` and minimum with `t_max`), so a lane reaches exactly the
//! children its own walk would with the same `t_max`. The rays share their direction octant,
//! so children are pushed in the single-ray walk's order (slots `i ^ order`) with each lane's
//! entry distance, popped with each lane's `near <= t_max` test, and leaves tested lane by lane
//! with the single-ray group test: each lane's sequence of leaf tests is its single-ray walk's,
//! so it finds the same hit, ties between surfaces included. A subtree that at most
//! `single_up_to` lanes reach is walked by the single-ray walk itself, lane after lane (lanes
//! are independent, so each keeps its own order): past the first levels, rays from different
//! eyes part, and a lone ray's walk tests a node's eight children in one vector where this
//! walk spends one vector per child.
//!
//! Pays only for rays that start close together (one eye, neighbouring eyes): eight rays of
//! eyes centimetres apart cost what they cost one by one (docs/light-field.md). The caller
//! (`SceneBvh::intersect8_with`, on several placements per placement after a top-level walk of
//! eights, `top_eights.rs`) takes the rays this walk does not: other instruction sets, lone
//! rays of an octant, `t_min < 0`, a full stack.

use std::arch::x86_64::*;

use crate::accel::lanes8::LaneStack;
use crate::accel::primitives::{GroupRayValues, SplatOnUse, TriangleGroup, closest_lane};
use crate::accel::single_ray::{self, Hit, rows};
use crate::accel::walk::{ORDER as ORDERED, TraversalRay};
use crate::accel::wide_bvh::{LEAF_BIT, WIDTH, WideNode, group_leaf};

/// Rays walked together.
pub(crate) const RAYS: usize = 8;

/// Stack entries of the walk; a walk that would need more gives up (its rays are then traced
/// alone). 256 entries hold 36 levels of full nodes, far more than a built tree has.
pub(crate) const STACK: usize = 256;

/// The box test's values of the eight rays, one per lane.
struct BoxRays {
    origin: [__m256; 3],
    /// `-inverse_direction * (1 - SLAB_ERROR)`, as the single-ray walk scales entries
    /// (`single_ray::slab_scales`).
    entry_scale: [__m256; 3],
    /// `-inverse_direction * (1 + SLAB_ERROR)`, as it scales exits.
    exit_scale: [__m256; 3],
    t_min: __m256,
}

/// What a walk of eight rays found: per lane the hit (if any) and its `t` (the lane's `t_max`
/// if none).
pub(crate) struct Found {
    pub hits: [Option<Hit>; RAYS],
    pub t: [f32; RAYS],
}

/// The closest hits of the rays in `lanes` (bit per lane), which must share their direction
/// octant and have `t_min >= 0`, into `found` (lanes in `lanes` only); false if the walk would
/// need more than `ENTRIES` stack entries (then `found` is unspecified). The rays' `t_max` may
/// change.
///
/// # Safety
/// The CPU has AVX2; `single_ray::codes_in_range(nodes, groups.len())`; `nodes` not empty.
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn closest8<const ENTRIES: usize>(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    rays: &mut [TraversalRay; RAYS],
    lanes: u32,
    single_up_to: u32,
    found: &mut Found,
) -> bool {
    let first = &rays[lanes.trailing_zeros() as usize];
    debug_assert!((0..RAYS).all(|lane| lanes & (1 << lane) == 0
        || (rays[lane].octant_inv == first.octant_inv && rays[lane].t_min >= 0.0)));
    // The single-ray walk's scales, lane by lane, transposed through arrays.
    let mut values = [[0.0f32; RAYS]; 10];
    for (lane, ray) in rays.iter().enumerate() {
        let [entry, exit] = single_ray::slab_scales(ray);
        for axis in 0..3 {
            values[axis][lane] = ray.origin[axis];
            values[3 + axis][lane] = entry[axis];
            values[6 + axis][lane] = exit[axis];
        }
        values[9][lane] = ray.t_min;
    }
    // SAFETY: eight floats per row.
    let row = |index: usize| unsafe { _mm256_loadu_ps(values[index].as_ptr()) };
    let box_rays = BoxRays {
        origin: [row(0), row(1), row(2)],
        entry_scale: [row(3), row(4), row(5)],
        exit_scale: [row(6), row(7), row(8)],
        t_min: row(9),
    };
    let order = (7 ^ (first.octant_inv & 7)) as usize;
    macro_rules! octants {
        ($($order:literal)*) => {
            match order {
                // SAFETY: the caller's promise.
                $($order => unsafe { walk::<$order, ENTRIES>(nodes, groups, &mut *rays, &box_rays, lanes, single_up_to, found) },)*
                _ => unreachable!(),
            }
        };
    }
    octants!(0 1 2 3 4 5 6 7)
}

/// The lanes of `pending` (bit per lane) whose rays share the direction octant of its first
/// lane: the rays [`closest8`] can walk together next.
pub(crate) fn lanes_of_first_octant(rays: &[TraversalRay; RAYS], pending: u32) -> u32 {
    let octant = rays[pending.trailing_zeros() as usize].octant_inv;
    let mut lanes = 0u32;
    for (lane, ray) in rays.iter().enumerate() {
        if pending & (1 << lane) != 0 && ray.octant_inv == octant {
            lanes |= 1 << lane;
        }
    }
    lanes
}

/// `LANE[lane]`: all bits set in lane `lane` only (a blend mask).
static LANE: [[u32; RAYS]; RAYS] = {
    let mut table = [[0; RAYS]; RAYS];
    let mut lane = 0;
    while lane < RAYS {
        table[lane][lane] = u32::MAX;
        lane += 1;
    }
    table
};

/// Sets lane `lane` of `values` to `value`.
#[target_feature(enable = "avx2")]
#[inline]
fn set_lane(values: __m256, lane: usize, value: f32) -> __m256 {
    // SAFETY: eight u32 per table row.
    let mask = unsafe { _mm256_loadu_ps(LANE[lane].as_ptr().cast()) };
    _mm256_blendv_ps(values, _mm256_set1_ps(value), mask)
}

/// Child `slot` of `node` against the eight rays: the lanes that reach it within their
/// `[t_min, t_max]` (bit per lane) and their entry distances; per lane the operations of
/// `single_ray`'s AVX2 box test in the same order.
#[target_feature(enable = "avx2")]
#[inline]
fn child_lanes<const ORDER: usize>(
    node: &WideNode,
    slot: usize,
    rays: &BoxRays,
    t_max: __m256,
) -> (u32, __m256) {
    let distances = |axis: usize| {
        let (entry, exit) = rows(ORDER, axis);
        let entry = _mm256_set1_ps(node.planes[entry][slot]);
        let exit = _mm256_set1_ps(node.planes[exit][slot]);
        let origin = rays.origin[axis];
        (
            _mm256_mul_ps(_mm256_sub_ps(origin, entry), rays.entry_scale[axis]),
            _mm256_mul_ps(_mm256_sub_ps(origin, exit), rays.exit_scale[axis]),
        )
    };
    let (near_x, far_x) = distances(0);
    let (near_y, far_y) = distances(1);
    let (near_z, far_z) = distances(2);
    let near = _mm256_max_ps(
        _mm256_max_ps(near_x, near_y),
        _mm256_max_ps(near_z, rays.t_min),
    );
    let far = _mm256_min_ps(_mm256_min_ps(far_x, far_y), _mm256_min_ps(far_z, t_max));
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
    (mask, near)
}

/// The walk of one octant (children in slots `i ^ ORDER`).
///
/// # Safety
/// As [`closest8`].
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn walk<const ORDER: usize, const ENTRIES: usize>(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    rays: &mut [TraversalRay; RAYS],
    box_rays: &BoxRays,
    lanes: u32,
    single_up_to: u32,
    found: &mut Found,
) -> bool {
    let t_max_lanes = &mut found.t;
    for (t, ray) in t_max_lanes.iter_mut().zip(rays.iter()) {
        *t = ray.t_max;
    }
    // SAFETY: eight floats.
    let mut t_max = unsafe { _mm256_loadu_ps(t_max_lanes.as_ptr()) };
    let found = &mut found.hits;
    let mut rest = lanes;
    while rest != 0 {
        found[rest.trailing_zeros() as usize] = None;
        rest &= rest - 1;
    }
    let mut stack = LaneStack::<ENTRIES>::with_root(lanes);
    while let Some((code, mask, near)) = stack.pop() {
        let active = mask & _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, t_max)) as u32;
        if active == 0 {
            continue;
        }
        if code & LEAF_BIT != 0 {
            let (group_index, group_lanes) = group_leaf(code);
            // SAFETY: leaf codes address existing groups (the caller's promise).
            let group = unsafe { groups.get_unchecked(group_index) };
            let mut rest = active;
            while rest != 0 {
                let lane = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let (hits, t, [v, w, determinant]) =
                    SplatOnUse::new(&rays[lane]).hits(group, group_lanes, t_max_lanes[lane]);
                if hits != 0 {
                    let (hit_lane, t) = closest_lane(hits, t);
                    t_max_lanes[lane] = t;
                    t_max = set_lane(t_max, lane, t);
                    found[lane] = Some(Hit {
                        group: group_index,
                        lane: hit_lane,
                        v,
                        w,
                        determinant,
                    });
                }
            }
            continue;
        }
        if active.count_ones() <= single_up_to {
            // Lanes are independent: each walks the subtree alone, in its own order.
            let mut rest = active;
            while rest != 0 {
                let lane = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                // The lane's own ray with its current `t_max` (no copy of the ray).
                rays[lane].t_max = t_max_lanes[lane];
                // SAFETY: the caller's promise; inner codes index `nodes`; AVX2 is enabled
                // here.
                let (hit, t) = unsafe { walk_alone(nodes, groups, &rays[lane], code) };
                if hit.is_some() {
                    found[lane] = hit;
                    t_max_lanes[lane] = t;
                    t_max = set_lane(t_max, lane, t);
                }
            }
            continue;
        }
        if !stack.has_room(WIDTH) {
            return false;
        }
        // SAFETY: inner codes index `nodes` (the caller's promise).
        let node = unsafe { nodes.get_unchecked(code as usize) };
        // SAFETY: plane rows are eight floats, 32-byte aligned (`WideNode` is).
        let occupied = unsafe {
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(
                _mm256_load_ps(node.planes[0].as_ptr()),
                _mm256_load_ps(node.planes[1].as_ptr()),
            ))
        } as usize;
        // Farthest first, so that the nearest is popped first.
        // The node's own visiting order for the octant (the plane rows stay the octant's).
        let order = usize::from(node.orders[ORDER]);
        let mut ordered = u32::from(ORDERED[order][occupied]);
        while ordered != 0 {
            let i = 31 - ordered.leading_zeros();
            ordered &= !(1 << i);
            let slot = i as usize ^ order;
            let (hit, child_near) = child_lanes::<ORDER>(node, slot, box_rays, t_max);
            let hit = hit & active;
            if hit != 0 {
                stack.push(node.children[slot], hit, child_near);
            }
        }
    }
    true
}

/// One lane's subtree walk, out of line: one copy of the single-ray walk instead of one
/// inlined into each octant's walk.
///
/// # Safety
/// As `single_ray::closest_from_avx2`.
#[target_feature(enable = "avx2")]
#[inline(never)]
unsafe fn walk_alone(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &TraversalRay,
    root: u32,
) -> (Option<Hit>, f32) {
    // SAFETY: the caller's promise.
    unsafe { single_ray::closest_from_avx2(nodes, groups, ray, root) }
}
