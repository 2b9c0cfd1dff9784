//! The CPU layout of the BVH: its node format and its build.
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
//! Walking it: `walk` (the generic walk, shared ray, tables and stack), `single_ray`,
//! `packet`.

use glam::Vec3;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::ploc::{PlocBuilder, SortPrecision};

use crate::accel::EMPTY_BOUNDS;
use crate::accel::binned_sah;
pub(crate) use crate::accel::collapse::collapse_to_wide;
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
/// `planes[2 * axis + 1]`), their codes (inner: node index; leaf: [`LEAF_BIT`], count, first
/// slot) and the node's visiting orders. 256 bytes, aligned to a cache line: exactly four lines,
/// and a node index becomes an address by a shift (the single-ray walk's chain).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct WideNode {
    pub planes: [[f32; WIDTH]; 6],
    pub children: [u32; WIDTH],
    /// `orders[order]`: the mask by which a ray of visiting order `order` (`walk::BoxRay::order`,
    /// from its direction octant) visits this node's children: slots `i ^ orders[order]`,
    /// `i = 0..8`, every walk alike (`collapse::assign_slots`).
    pub orders: [u8; WIDTH],
    /// Unused (the node's size stays a power of two).
    pub spare: [u32; 6],
}

/// The visiting orders of a node whose slot bits 2, 1, 0 follow the x, y, z axes.
pub(crate) const IDENTITY_ORDERS: [u8; WIDTH] = [0, 1, 2, 3, 4, 5, 6, 7];

impl Default for WideNode {
    fn default() -> WideNode {
        let mut planes = [[EMPTY_PLANE; WIDTH]; 6];
        for axis in 0..3 {
            planes[2 * axis + 1] = [-EMPTY_PLANE; WIDTH];
        }
        WideNode {
            planes,
            children: [0; WIDTH],
            orders: IDENTITY_ORDERS,
            spare: [0; 6],
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
