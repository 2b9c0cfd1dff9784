//! The CPU layout of the BVH and its single-ray traversal.
//!
//! A binary BVH (binned SAH for whole leaves, else obvhs' PLOC) is laid out by
//! [`collapse_to_wide`] as [`WideNode`]s: eight children per node with their boxes as plain
//! floats, structure of arrays (per axis the eight minima, then the eight maxima), so that one
//! vector instruction tests one plane of all children with nothing to decode. Children are
//! placed in slots so that a ray visits them nearest-first by taking slot `i ^ octant` for
//! `i = 0..8`, where `octant` has a bit set for each negative direction component. Leaves
//! hold at most four primitives; with [`LeafAlignment::Group`] a leaf is a run of lanes
//! within one group of four slots, the leaves of a node sharing groups (so spare child slots
//! split them at no memory cost), and a triangle leaf is tested as one SIMD group (see
//! `primitives::TriangleGroup`).
//!
//! The box test computes each slab distance as `(plane - origin) * inverse_direction`: two
//! roundings of a value, so its relative error is bounded (three half-ulps with the rounded
//! inverse), and widening a child's entry and exit distances by [`SLAB_ERROR`] of their own
//! magnitude keeps every box that holds a primitive hit in `[t_min, t_max]`, also for rays
//! that meet it exactly on a face, edge or corner or run almost parallel to an axis. Every
//! instruction-set path performs the same operations in the same order (no fused
//! multiply-adds), so each finds the same children, in the same order, and the same hits.

use glam::{Vec3, Vec3A, Vec3Swizzles, Vec4};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::ploc::{PlocBuilder, SortPrecision};

use crate::accel::binned_sah;
pub(crate) use crate::accel::collapse::collapse_to_wide;
use crate::accel::{EMPTY_BOUNDS, MAX_COORDINATE};
use rayon::iter::{
    IndexedParallelIterator, IntoParallelIterator, IntoParallelRefIterator, ParallelIterator,
};

/// Leaves hold at most four primitives (one SIMD group of triangles).
pub(crate) const MAX_PRIMS_PER_LEAF: u32 = 4;

/// How far PLOC looks for a node's nearest neighbour (obvhs' `PlocSearchDistance::VeryLow`).
const PLOC_SEARCH_DISTANCE: usize = 2;

/// A node's children can be at most this many.
pub(crate) const WIDTH: usize = 8;

/// Set in a child code for a leaf; the code of an inner child is its node index.
pub(crate) const LEAF_BIT: u32 = 1 << 31;
/// Leaf codes keep `count - 1` in the two bits below [`LEAF_BIT`].
const LEAF_COUNT_SHIFT: u32 = 29;
/// Leaf codes keep the first primitive slot (its group with [`LeafAlignment::Group`]) in the
/// low 29 bits.
const LEAF_FIRST_MASK: u32 = (1 << LEAF_COUNT_SHIFT) - 1;
/// Geometries and scenes address at most this many primitives; the rest are skipped.
pub(crate) const MAX_PRIMITIVES: usize = 1 << LEAF_COUNT_SHIFT;

/// Planes of an empty child slot: a box beyond every ray origin whose entry and exit distances
/// have opposite signs for every ray, so it is never hit, and whose slab distances stay finite.
const EMPTY_PLANE: f32 = 1.0e20;

/// Marks a padding slot in a grouped primitive order.
pub(crate) const PADDING: u32 = u32::MAX;

/// Eight children: their boxes per axis as minima then maxima (`planes[2 * axis]`,
/// `planes[2 * axis + 1]`), and their codes (inner: node index; leaf: [`LEAF_BIT`], count,
/// first slot). 224 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct WideNode {
    pub planes: [[f32; WIDTH]; 6],
    pub children: [u32; WIDTH],
}

impl Default for WideNode {
    fn default() -> WideNode {
        let mut planes = [[EMPTY_PLANE; WIDTH]; 6];
        for axis in 0..3 {
            planes[2 * axis + 1] = [-EMPTY_PLANE; WIDTH];
        }
        WideNode {
            planes,
            children: [0; WIDTH],
        }
    }
}

/// A leaf's primitives: `count` slots from `first` (with [`LeafAlignment::Group`] they lie
/// within one group of four: `first / 4` is the group, `first % 4` the first lane).
#[inline(always)]
pub(crate) fn leaf_range(code: u32) -> (u32, u32) {
    (code & LEAF_FIRST_MASK, ((code >> LEAF_COUNT_SHIFT) & 3) + 1)
}

/// A [`LeafAlignment::Group`] leaf: its group and its lanes in the group (bit per lane).
#[inline(always)]
pub(crate) fn group_leaf(code: u32) -> (usize, u32) {
    let (first, count) = leaf_range(code);
    let lanes = MAX_PRIMS_PER_LEAF;
    (
        (first / lanes) as usize,
        ((1 << count) - 1) << (first % lanes),
    )
}

pub(crate) fn leaf_code(first: u32, count: u32) -> u32 {
    debug_assert!((1..=MAX_PRIMS_PER_LEAF).contains(&count) && first <= LEAF_FIRST_MASK);
    LEAF_BIT | ((count - 1) << LEAF_COUNT_SHIFT) | first
}

/// Whether child `slot` of `node` is occupied.
#[inline(always)]
pub(crate) fn occupied(node: &WideNode, slot: usize) -> bool {
    node.planes[0][slot] <= node.planes[1][slot]
}

/// A wide BVH built over boxes.
pub(crate) struct WideBvh {
    pub nodes: Vec<WideNode>,
    /// For every primitive slot the leaves refer to, the index into the boxes it stands for,
    /// or [`PADDING`] (callers reorder their primitives by it).
    pub order: Vec<u32>,
    /// The union of the boxes ([`EMPTY_BOUNDS`] for none).
    pub bounds: (Vec3, Vec3),
}

/// How leaves are laid out in the primitive order.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) enum LeafAlignment {
    /// Leaves follow one another.
    Packed,
    /// Every leaf starts a group of four slots, padded with [`PADDING`].
    Group,
}

/// Builds a wide BVH over `boxes`, which must be finite; an empty input gives no nodes.
///
/// The binary BVH comes from [`binned_sah::build_binned_sah`] for whole leaves (leaves of up
/// to four, filled toward four by its cost) and from obvhs' PLOC otherwise ([`ploc_bvh2`]);
/// [`collapse_to_wide`] then lays it out as [`WideNode`]s, in parallel. On the benchmark's
/// 1M-triangle height field the binned-SAH tree takes 19 % fewer node visits per ray than
/// PLOC's with 1 % reinsertion and builds no slower in wall time, for 12 % more CPU
/// (`docs/kernel.md`, "A binned-SAH binary tree").
pub(crate) fn build_wide_bvh(
    boxes: Vec<Aabb>,
    sizing: LeafSizing,
    alignment: LeafAlignment,
) -> WideBvh {
    if boxes.is_empty() {
        return WideBvh {
            nodes: Vec::new(),
            order: Vec::new(),
            bounds: EMPTY_BOUNDS,
        };
    }
    let bvh2 = match sizing {
        LeafSizing::Whole => binned_sah::build_binned_sah(boxes),
        LeafSizing::Split => ploc_bvh2(&boxes),
    };
    let total = *bvh2.nodes[0].aabb();
    let (nodes, order) = collapse_to_wide(&bvh2, sizing, alignment);
    #[cfg(feature = "kernel-counters")]
    if std::env::var_os("CAVETRACE_TREE_STATISTICS").is_some() {
        let shape = TreeShape::of(&nodes, (total.min.into(), total.max.into()));
        eprintln!(
            "tree: {} inner nodes ({:.1} % of slots filled), {} leaves ({:.2} primitives each), \
             node SAH {:.3}, leaf SAH {:.3}; nodes with only leaves, by groups of four \
             primitives they hold: {:?}",
            shape.nodes,
            100.0 * shape.children as f64 / (WIDTH * shape.nodes) as f64,
            shape.leaves,
            shape.primitives as f64 / shape.leaves as f64,
            shape.node_cost,
            shape.leaf_cost,
            shape.bottom_nodes,
        );
    }
    WideBvh {
        nodes,
        order,
        bounds: (total.min.into(), total.max.into()),
    }
}

/// obvhs' PLOC (search distance 2) plus 1% reinsertion, parallel through rayon with obvhs'
/// `parallel` feature, over one leaf per box. Measured on a 1M-triangle mesh (2 cores, when
/// the whole build took ~300 ms): the 1% reinsertion cost 15 ms and gained 4% on the default
/// renderer's shadow rays; search distance 6 or 5% reinsertion cost another 40-50 ms for at
/// most 2%.
pub(crate) fn ploc_bvh2(boxes: &[Aabb]) -> Bvh2 {
    let leaves: Vec<Bvh2Node> = boxes
        .par_iter()
        .enumerate()
        .map(|(index, aabb)| Bvh2Node::new(*aabb, 1, index as u32))
        .collect();
    let total = leaves
        .par_iter()
        .map(|leaf| *leaf.aabb())
        .reduce(Aabb::empty, |a, b| a.union(&b));
    // Sized for PLOC, which writes every node.
    let mut bvh2 = Bvh2::zeroed(leaves.len());
    bvh2.primitive_indices = (0..boxes.len() as u32).into_par_iter().collect();
    let mut builder = PlocBuilder {
        current_nodes: leaves,
        ..PlocBuilder::default()
    };
    builder.build_ploc_from_leaves::<PLOC_SEARCH_DISTANCE, false>(
        &mut bvh2,
        total,
        SortPrecision::U64,
        1,
    );
    ReinsertionOptimizer::default().run(&mut bvh2, 0.01, None);
    bvh2
}

/// A wide tree's shape and surface-area costs in the terms of Embree's BVH statistics.
#[cfg(any(test, feature = "kernel-counters"))]
#[derive(Debug)]
pub(crate) struct TreeShape {
    pub nodes: usize,
    /// Occupied child slots, inner and leaf.
    pub children: usize,
    pub leaves: usize,
    pub primitives: usize,
    /// Σ inner node half areas / the root's: node visits per ray, for rays spread evenly
    /// over the root's box.
    pub node_cost: f64,
    /// Σ leaf half areas / the root's: leaf (group) tests per ray, the same way.
    pub leaf_cost: f64,
    /// Nodes whose children are all leaves, by the groups of four primitives they hold
    /// (`[k]`: 4k - 3 to 4k primitives; the last entry 29 and more).
    pub bottom_nodes: [usize; 9],
}

#[cfg(any(test, feature = "kernel-counters"))]
impl TreeShape {
    pub fn of(nodes: &[WideNode], bounds: (Vec3, Vec3)) -> TreeShape {
        let half_area = |extent: Vec3| {
            f64::from(extent.x * extent.y + extent.y * extent.z + extent.z * extent.x)
        };
        let root_area = half_area(bounds.1 - bounds.0);
        let mut shape = TreeShape {
            nodes: nodes.len(),
            children: 0,
            leaves: 0,
            primitives: 0,
            node_cost: if nodes.is_empty() { 0.0 } else { 1.0 },
            leaf_cost: 0.0,
            bottom_nodes: [0; 9],
        };
        for node in nodes {
            let mut node_primitives = 0;
            let mut only_leaves = true;
            for slot in (0..WIDTH).filter(|&slot| occupied(node, slot)) {
                shape.children += 1;
                let min = Vec3::new(
                    node.planes[0][slot],
                    node.planes[2][slot],
                    node.planes[4][slot],
                );
                let max = Vec3::new(
                    node.planes[1][slot],
                    node.planes[3][slot],
                    node.planes[5][slot],
                );
                let area = half_area(max - min) / root_area;
                if node.children[slot] & LEAF_BIT != 0 {
                    let count = leaf_range(node.children[slot]).1 as usize;
                    shape.leaves += 1;
                    shape.primitives += count;
                    node_primitives += count;
                    shape.leaf_cost += area;
                } else {
                    only_leaves = false;
                    shape.node_cost += area;
                }
            }
            if only_leaves {
                shape.bottom_nodes[node_primitives.div_ceil(4).min(8)] += 1;
            }
        }
        shape
    }
}

/// Number of leaves in `nodes`.
#[cfg(test)]
pub(crate) fn leaf_count(nodes: &[WideNode]) -> usize {
    nodes
        .iter()
        .map(|node| {
            (0..WIDTH)
                .filter(|&slot| occupied(node, slot) && node.children[slot] & LEAF_BIT != 0)
                .count()
        })
        .sum()
}

/// Whether spare child slots of a wide node split subtrees that would fit one leaf.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) enum LeafSizing {
    /// Subtrees of up to four primitives stay one leaf: for cheap primitive tests
    /// (triangles, tested four at a time), fewer box tests win. The binned-SAH builder makes
    /// every such range a leaf of the binary tree, so spare slots no longer split them; the
    /// collapse plan still can, with [`LeafAlignment::Group`], for binary trees that hold
    /// leaf-sized inner subtrees (PLOC's, in the tests).
    Whole,
    /// Spare slots split small subtrees into smaller leaves: for costly primitive tests
    /// (spheres and tubes in f64, instances), tighter boxes win.
    Split,
}

/// A ray prepared for traversal and primitive tests, in the space of the BVH being traversed.
/// `direction` need not be unit length (object-space rays of scaled instances are not).
#[derive(Clone, Copy, Debug)]
pub(crate) struct TraversalRay {
    pub origin: Vec3A,
    pub direction: Vec3A,
    pub inv_direction: Vec3A,
    pub t_min: f32,
    /// Shrinks to the closest hit found so far.
    pub t_max: f32,
    /// 3 bits (x: 4, y: 2, z: 1), set for each axis whose direction is not negative.
    pub octant_inv: u32,
    /// Watertight triangle test: axes permuted so that `axes[2]` is the dominant direction axis.
    pub shear_axes: [usize; 3],
    /// `(d[x]/d[z], d[y]/d[z], 1/d[z])` over the permuted axes.
    pub shear: Vec3,
    /// Origin components in permuted order.
    pub permuted_origin: Vec3,
}

impl TraversalRay {
    /// Prepares a ray; `None` for non-finite directions or ones shorter than 1e-18, origins
    /// that are not finite or beyond `MAX_COORDINATE`, or an empty/NaN interval.
    #[inline]
    pub fn new(origin: Vec3A, direction: Vec3A, t_min: f32, t_max: f32) -> Option<TraversalRay> {
        // Comparisons that are false for NaN reject it; `!(a <= b)` too.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        let bad_interval = !(t_min <= t_max);
        let abs = direction.abs();
        let too_short = Vec3A::splat(1.0 / MAX_INV_DIRECTION);
        if bad_interval
            || !origin.abs().cmple(Vec3A::splat(MAX_COORDINATE)).all()
            || !abs.cmplt(Vec3A::INFINITY).all()
            || !abs.cmpge(too_short).any()
        {
            return None;
        }
        // Components too short to invert are clamped, their sign agreeing with the octant's
        // `< 0.0` test, also for -0.0. A vector division rounds each lane as a scalar one.
        let negative = direction.cmplt(Vec3A::ZERO);
        let clamped = Vec3A::select(
            negative,
            Vec3A::splat(-MAX_INV_DIRECTION),
            Vec3A::splat(MAX_INV_DIRECTION),
        );
        let inv_direction = Vec3A::select(abs.cmplt(too_short), clamped, Vec3A::ONE / direction);
        let octant_inv = OCTANT_INV[negative.bitmask() as usize & 7];
        // The dominant axis last (ties to the lower axis), the others in cyclic order.
        let (shear_axes, [d, inv, o]) = if abs.x >= abs.y && abs.x >= abs.z {
            (
                [1, 2, 0],
                [direction, inv_direction, origin].map(Vec3A::yzx),
            )
        } else if abs.y >= abs.z {
            (
                [2, 0, 1],
                [direction, inv_direction, origin].map(Vec3A::zxy),
            )
        } else {
            ([0, 1, 2], [direction, inv_direction, origin])
        };
        // The dominant component is never clamped, so this is exactly 1 / d[kz].
        let inv_dominant = inv.z;
        Some(TraversalRay {
            origin,
            direction,
            inv_direction,
            t_min,
            t_max,
            octant_inv,
            shear_axes,
            shear: Vec3::new(d.x * inv_dominant, d.y * inv_dominant, inv_dominant),
            permuted_origin: o.into(),
        })
    }
}

/// `OCTANT_INV[negative]`: [`TraversalRay::octant_inv`] for the direction components that are
/// negative (x: 1, y: 2, z: 4).
static OCTANT_INV: [u32; 8] = {
    let mut table = [0; 8];
    let mut negative = 0;
    while negative < 8 {
        table[negative] =
            7 ^ (((negative & 1) << 2) | (negative & 2) | ((negative >> 2) & 1)) as u32;
        negative += 1;
    }
    table
};

/// Inverse direction components are clamped to this magnitude. Together with
/// `MAX_COORDINATE` (which also bounds ray origins) and [`EMPTY_PLANE`] it keeps every slab
/// distance finite, so the box test never sees infinities or NaN.
pub(crate) const MAX_INV_DIRECTION: f32 = 1.0e18;

/// Relative widening of a child's entry and exit distances: a slab distance
/// `(plane - origin) * inverse_direction` is off by at most three half-ulps of itself (the
/// subtraction, the rounded inverse, the product), and the larger of three entries (smaller of
/// three exits) by no more, relative to the result; this covers that twice over, plus the
/// rounding of the widening itself.
pub(crate) const SLAB_ERROR: f32 = 4.0 * f32::EPSILON;

/// `ORDER[order][mask]`: bit `i` set when bit `i ^ order` of the child mask `mask` is, so that
/// the set bits, lowest first, are the hit children nearest-first.
pub(crate) static ORDER: [[u8; 256]; 8] = {
    let mut table = [[0u8; 256]; 8];
    let mut order = 0;
    while order < 8 {
        let mut mask = 0;
        while mask < 256 {
            let mut permuted = 0u8;
            let mut i = 0;
            while i < 8 {
                if mask & (1 << (i ^ order)) != 0 {
                    permuted |= 1 << i;
                }
                i += 1;
            }
            table[order][mask] = permuted;
            mask += 1;
        }
        order += 1;
    }
    table
};

/// What the box test needs of one ray, set up once per traversal.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BoxRay {
    pub origin: [f32; 3],
    pub inv: [f32; 3],
    /// Per axis, the plane row through which the ray enters children, and the one it leaves by.
    pub entry: [usize; 3],
    pub exit: [usize; 3],
    /// Children are visited nearest-first in slots `i ^ order`, `i = 0..8`.
    pub order: usize,
}

impl BoxRay {
    #[inline(always)]
    pub fn new(ray: &TraversalRay) -> BoxRay {
        let octant = (ray.octant_inv & 7) as usize;
        let [entry, exit] = PLANE_ROWS[octant];
        BoxRay {
            origin: ray.origin.to_array(),
            inv: ray.inv_direction.to_array(),
            entry,
            exit,
            order: 7 ^ octant,
        }
    }
}

/// `PLANE_ROWS[octant_inv]`: per axis the plane rows through which a ray of that octant enters
/// children (minima along a non-negative direction, maxima along a negative one) and leaves
/// them; a table, because working them out showed in profiles of single rays.
static PLANE_ROWS: [[[usize; 3]; 2]; 8] = {
    let mut table = [[[0; 3]; 2]; 8];
    let mut octant = 0;
    while octant < 8 {
        let mut axis = 0;
        while axis < 3 {
            let negative = (octant >> (2 - axis)) & 1 == 0;
            let (entry, exit) = if negative {
                (2 * axis + 1, 2 * axis)
            } else {
                (2 * axis, 2 * axis + 1)
            };
            table[octant][0][axis] = entry;
            table[octant][1][axis] = exit;
            axis += 1;
        }
        octant += 1;
    }
    table
};

/// Which children a ray reaches within `[t_min, t_max]` (bit per slot) and, per slot, the
/// widened entry distance (meaningful for the children hit).
#[inline(always)]
pub(crate) fn child_hits(node: &WideNode, ray: &BoxRay, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
    #[cfg(target_arch = "x86_64")]
    if crate::accel::isa::avx2_selected() {
        // SAFETY: AVX2 is selected only on CPUs that have it.
        return unsafe { avx2::child_hits(node, ray, t_min, t_max) };
    }
    child_hits_four_wide(node, ray, t_min, t_max)
}

/// The box test four children at a time (SSE2 on x86_64 through glam).
#[inline(always)]
pub(crate) fn child_hits_four_wide(
    node: &WideNode,
    ray: &BoxRay,
    t_min: f32,
    t_max: f32,
) -> (u32, [f32; 8]) {
    let mut nears = [0.0f32; 8];
    let mut mask = 0;
    for half in 0..2 {
        let lanes = 4 * half..4 * half + 4;
        let mut near = Vec4::splat(t_min);
        let mut far = Vec4::splat(t_max);
        for axis in 0..3 {
            let origin = Vec4::splat(ray.origin[axis]);
            let inv = Vec4::splat(ray.inv[axis]);
            let entry = Vec4::from_slice(&node.planes[ray.entry[axis]][lanes.clone()]);
            let exit = Vec4::from_slice(&node.planes[ray.exit[axis]][lanes.clone()]);
            near = near.max((entry - origin) * inv);
            far = far.min((exit - origin) * inv);
        }
        let (near, hit) = widened(near, far);
        mask |= hit << (4 * half);
        near.write_to_slice(&mut nears[lanes]);
    }
    (mask, nears)
}

/// Four children's entry and exit distances widened by [`SLAB_ERROR`] of their magnitude: the
/// widened entries, and which children are hit (bit per lane).
#[inline(always)]
pub(crate) fn widened(near: Vec4, far: Vec4) -> (Vec4, u32) {
    let error = Vec4::splat(SLAB_ERROR);
    let near = near - near.abs() * error;
    let far = far + far.abs() * error;
    (near, near.cmple(far).bitmask())
}

/// Reference box test, one child at a time, in the same operations.
#[cfg(test)]
pub(crate) fn child_hits_scalar(
    node: &WideNode,
    ray: &BoxRay,
    t_min: f32,
    t_max: f32,
) -> (u32, [f32; 8]) {
    let mut nears = [0.0f32; 8];
    let mut mask = 0;
    for (slot, slot_near) in nears.iter_mut().enumerate() {
        let mut near = t_min;
        let mut far = t_max;
        for axis in 0..3 {
            near =
                near.max((node.planes[ray.entry[axis]][slot] - ray.origin[axis]) * ray.inv[axis]);
            far = far.min((node.planes[ray.exit[axis]][slot] - ray.origin[axis]) * ray.inv[axis]);
        }
        let near = near - near.abs() * SLAB_ERROR;
        let far = far + far.abs() * SLAB_ERROR;
        mask |= u32::from(near <= far) << slot;
        *slot_near = near;
    }
    (mask, nears)
}

/// The box test with AVX2, chosen at run time (`crate::isa`): a node's eight children in one
/// vector, in the same operations as the four-wide test (no fused multiply-adds), so it
/// reaches the same children.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    use super::{BoxRay, SLAB_ERROR, WideNode};
    use std::arch::x86_64::*;

    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn child_hits(
        node: &WideNode,
        ray: &BoxRay,
        t_min: f32,
        t_max: f32,
    ) -> (u32, [f32; 8]) {
        let mut near = _mm256_set1_ps(t_min);
        let mut far = _mm256_set1_ps(t_max);
        for axis in 0..3 {
            let origin = _mm256_set1_ps(ray.origin[axis]);
            let inv = _mm256_set1_ps(ray.inv[axis]);
            // SAFETY: every plane row is eight floats, 32-byte aligned (`WideNode` is).
            let (entry, exit) = unsafe {
                (
                    _mm256_load_ps(node.planes[ray.entry[axis]].as_ptr()),
                    _mm256_load_ps(node.planes[ray.exit[axis]].as_ptr()),
                )
            };
            near = _mm256_max_ps(near, _mm256_mul_ps(_mm256_sub_ps(entry, origin), inv));
            far = _mm256_min_ps(far, _mm256_mul_ps(_mm256_sub_ps(exit, origin), inv));
        }
        let error = _mm256_set1_ps(SLAB_ERROR);
        let sign = _mm256_set1_ps(-0.0);
        let near = _mm256_sub_ps(near, _mm256_mul_ps(_mm256_andnot_ps(sign, near), error));
        let far = _mm256_add_ps(far, _mm256_mul_ps(_mm256_andnot_ps(sign, far), error));
        let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
        let mut nears = [0.0f32; 8];
        // SAFETY: `nears` holds eight floats.
        unsafe { _mm256_storeu_ps(nears.as_mut_ptr(), near) };
        (mask, nears)
    }
}

/// Entries of the traversal stack kept inline; deeper stacks spill to the heap.
const INLINE_STACK: usize = 64;

/// Traversal stack: what to visit, with its widened entry distance. The inline entries start
/// uninitialised: clearing them for every ray showed in profiles, and only entries below `len`
/// are ever read. Entries beyond the inline ones go to `spill`, which is only looked at while
/// the inline part is full, so the common push and pop are one compare each.
pub(crate) struct TraversalStack<T> {
    inline: [std::mem::MaybeUninit<T>; INLINE_STACK],
    len: usize,
    spill: Vec<T>,
}

impl<T: Copy> TraversalStack<T> {
    #[inline(always)]
    pub fn new() -> TraversalStack<T> {
        TraversalStack {
            inline: [const { std::mem::MaybeUninit::uninit() }; INLINE_STACK],
            len: 0,
            spill: Vec::new(),
        }
    }

    #[inline(always)]
    pub fn push(&mut self, entry: T) {
        if self.len < INLINE_STACK {
            self.inline[self.len].write(entry);
            self.len += 1;
        } else {
            spill_push(&mut self.spill, entry);
        }
    }

    #[inline(always)]
    pub fn pop(&mut self) -> Option<T> {
        if self.len == INLINE_STACK
            && let Some(entry) = self.spill.pop()
        {
            return Some(entry);
        }
        if self.len > 0 {
            self.len -= 1;
            // SAFETY: every entry below the old `len` was written by `push`, and `T: Copy`.
            Some(unsafe { self.inline[self.len].assume_init() })
        } else {
            None
        }
    }
}

/// Out of line and taking only the spill, so that the rest of the stack (its length above
/// all) can stay in registers.
#[cold]
#[inline(never)]
fn spill_push<T>(spill: &mut Vec<T>, entry: T) {
    spill.push(entry);
}

/// A box test of a node's eight children (see [`child_hits`]) for [`traverse_with`]. (Triangle
/// and quad BVHs take the walks of `single_ray`, compiled per instruction set.)
pub(crate) trait BoxTest {
    fn child_hits(node: &WideNode, ray: &BoxRay, t_min: f32, t_max: f32) -> (u32, [f32; 8]);
}

/// The box test chosen per node at run time ([`child_hits`]).
pub(crate) struct RuntimeBoxTest;

impl BoxTest for RuntimeBoxTest {
    #[inline(always)]
    fn child_hits(node: &WideNode, ray: &BoxRay, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
        child_hits(node, ray, t_min, t_max)
    }
}

/// Walks the BVH nearest-first and calls `test_leaf(leaf_code, ray)` for every leaf whose box
/// the ray reaches within `[t_min, t_max]` (see [`leaf_range`]). The callback returns whether it
/// accepted a hit; for closest-hit use it must then shrink `ray.t_max` to the hit, and
/// subtrees entered beyond it are skipped. With `ANY_HIT` the walk stops at the first accepted
/// hit. Returns whether any hit was accepted.
#[inline(always)]
pub(crate) fn traverse<const ANY_HIT: bool, F>(
    nodes: &[WideNode],
    ray: &mut TraversalRay,
    mut test_leaf: F,
) -> bool
where
    F: FnMut(u32, &mut TraversalRay) -> bool,
{
    traverse_with::<RuntimeBoxTest, ANY_HIT, F>(nodes, ray, &mut test_leaf)
}

/// What [`traverse_with`] calls for a leaf: `test(leaf_code, ray)` as `traverse`'s callback.
pub(crate) trait LeafTest {
    fn test(&mut self, code: u32, ray: &mut TraversalRay) -> bool;
}

impl<F: FnMut(u32, &mut TraversalRay) -> bool> LeafTest for F {
    #[inline(always)]
    fn test(&mut self, code: u32, ray: &mut TraversalRay) -> bool {
        self(code, ray)
    }
}

/// [`traverse`] with the box test `B`.
#[inline(always)]
pub(crate) fn traverse_with<B: BoxTest, const ANY_HIT: bool, L: LeafTest>(
    nodes: &[WideNode],
    ray: &mut TraversalRay,
    test_leaf: &mut L,
) -> bool {
    if nodes.is_empty() {
        return false;
    }
    let box_ray = BoxRay::new(ray);
    let order = box_ray.order;
    let mut stack: TraversalStack<(u32, f32)> = TraversalStack::new();
    let mut found = false;
    let mut code = 0u32;
    loop {
        if code & LEAF_BIT == 0 {
            let node = &nodes[code as usize];
            let (mask, nears) = B::child_hits(node, &box_ray, ray.t_min, ray.t_max);
            if mask != 0 {
                let ordered = u32::from(ORDER[order][mask as usize]);
                let mut farther = ordered & (ordered - 1);
                while farther != 0 {
                    let i = 31 - farther.leading_zeros();
                    farther &= !(1 << i);
                    let slot = i as usize ^ order;
                    stack.push((node.children[slot], nears[slot]));
                }
                code = node.children[ordered.trailing_zeros() as usize ^ order];
                if code & LEAF_BIT == 0 {
                    prefetch(&nodes[code as usize]);
                }
                continue;
            }
        } else if test_leaf.test(code, ray) {
            found = true;
            if ANY_HIT {
                return true;
            }
        }
        loop {
            let Some((next, near)) = stack.pop() else {
                return found;
            };
            if near <= ray.t_max {
                code = next;
                break;
            }
        }
    }
}

/// Starts loading every cache line of a node: 224 bytes aligned to 32 span four lines, one
/// each around bytes 0, 64, 128 and 192 (plane rows 0, 2 and 4, the child codes).
#[inline(always)]
pub(crate) fn prefetch_node(node: &WideNode) {
    prefetch(&node.planes[0]);
    prefetch(&node.planes[2]);
    prefetch(&node.planes[4]);
    prefetch(&node.children);
}

/// Hints the CPU to start loading `value`'s cache line (no-op off x86_64).
#[inline(always)]
pub(crate) fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // SAFETY: SSE is part of the x86_64 baseline, and a prefetch never faults or changes
        // memory; the pointer comes from a live reference anyway.
        unsafe { _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast::<i8>()) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
