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
use crate::accel::{EMPTY_BOUNDS, MAX_COORDINATE};
use rayon::iter::{
    IndexedParallelIterator, IntoParallelIterator, IntoParallelRefIterator, ParallelIterator,
};
use std::sync::atomic::AtomicU64;
use std::sync::atomic::Ordering::Relaxed;

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

fn leaf_code(first: u32, count: u32) -> u32 {
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
/// PLOC's with 1 % reinsertion and builds no slower (`docs/kernel.md`, "A binned-SAH binary
/// tree").
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
    /// (triangles, tested four at a time), fewer box tests win. With
    /// [`LeafAlignment::Group`] spare slots still split them: the node's leaves share their
    /// groups, so a split costs no memory, and a packet's group of rays then tests only the
    /// triangles under the smaller boxes it reaches (frustum packets 5 % faster at 968 and
    /// 100k triangles, single rays unchanged).
    Whole,
    /// Spare slots split small subtrees into smaller leaves: for costly primitive tests
    /// (spheres and tubes in f64, instances), tighter boxes win.
    Split,
}

/// Marks an empty slot in [`assign_slots`]' result.
const EMPTY_SLOT: u8 = u8::MAX;

/// Surface-area cost of a leaf (group) test relative to a wide node visit, in
/// [`slot_costs`]: a group of up to four triangles is tested together in SIMD lanes, so the
/// cost is the same whatever the count. Tuned on the kernel bench (2, 3, 4 and 6 tried, each
/// with [`NODE_MEMORY_COST`] holding memory level); it stands for more than the test itself,
/// as a leaf hit also ends in the hit's bookkeeping.
const LEAF_TEST_COST: f32 = 4.0;

/// A wide node's 224 bytes as a surface-area cost in [`slot_costs`], in half areas of the
/// root's box per primitive (about the area a bottom node spends per triangle on a surface):
/// without it, leaf costs alone spread leaf-sized subtrees over more nodes (1M triangles,
/// leaf test cost 2: +12 % nodes, +1.9 bytes per triangle).
const NODE_MEMORY_COST: f32 = 24.0;

/// Surface-area cost of the node visits and leaf tests below binary subtree `index` when it
/// is laid out in at most `i` child slots of a wide node (`costs[i - 1]`, `i = 1..=8`), as the
/// dynamic programme of Ylitie et al., "Efficient incoherent ray traversal on GPUs through
/// compressed wide BVHs" (HPG 2017): a leaf-sized subtree either takes one slot as one leaf
/// (its area times [`LEAF_TEST_COST`]) or spreads its two children over the slots, as leaves
/// with smaller boxes; a larger one either takes one slot as a wide node of its own (its area:
/// the rays that visit it, plus [`NODE_MEMORY_COST`] for its memory, plus its children spread over
/// eight slots) or spreads its two children over the slots. Opening the largest child first,
/// the greedy collapse this replaces, left many small subtrees (5–8 triangles) as wide nodes
/// of their own: 94,223 nodes at 1M triangles against 64,215 with node visits only, and a
/// node cost 4 % higher; weighing the leaf tests splits leaves where slots are left
/// (`docs/kernel.md`, "The tree beside Embree's").
///
/// Also returns the subtree's primitive count if it fits a leaf, as [`leaf_sized_count`] has
/// it. The choices go to `plan[index]` (see [`Plan`]).
fn slot_costs(
    bvh2: &Bvh2,
    index: usize,
    plan: &[AtomicU64],
    model: CostModel,
    depth: u32,
) -> ([f32; WIDTH], Option<u32>) {
    let node = &bvh2.nodes[index];
    if node.is_leaf() {
        let cost = node.aabb().half_area() * LEAF_TEST_COST;
        return ([cost; WIDTH], Some(node.prim_count));
    }
    let first = node.first_index as usize;
    // The walk is bound by memory latency: the grandchildren's loads start before the
    // children's subtrees are walked.
    for child in &bvh2.nodes[first..first + 2] {
        if !child.is_leaf() {
            prefetch_pair(&bvh2.nodes, child.first_index as usize);
        }
    }
    // Rayon tasks for the top levels only: below, the subtrees are plenty.
    let ((left, left_count), (right, right_count)) = if depth < 8 {
        rayon::join(
            || slot_costs(bvh2, first, plan, model, depth + 1),
            || slot_costs(bvh2, first + 1, plan, model, depth + 1),
        )
    } else {
        (
            slot_costs(bvh2, first, plan, model, depth + 1),
            slot_costs(bvh2, first + 1, plan, model, depth + 1),
        )
    };
    let both_inner = !bvh2.nodes[first].is_leaf() && !bvh2.nodes[first + 1].is_leaf();
    let leaf_sized = match (left_count, right_count, both_inner) {
        (Some(left_count), Some(right_count), false)
            if left_count + right_count <= MAX_PRIMS_PER_LEAF =>
        {
            Some(left_count + right_count)
        }
        _ => None,
    };
    if !model.split_leaves && leaf_sized.is_some() {
        let one_leaf = node.aabb().half_area() * LEAF_TEST_COST;
        return ([one_leaf; WIDTH], leaf_sized);
    }
    // spread[j - 1]: both children over at most j slots.
    let mut spread = [f32::INFINITY; WIDTH];
    let mut packed = 0u64;
    // A leaf-sized subtree of `c` primitives has at most `c` leaves: more slots cost the same,
    // and a share above them never costs less (the other child's cost only grows), so the
    // first best share is found among the smaller ones.
    let most_slots = leaf_sized.map_or(WIDTH, |count| count as usize);
    let most_left = left_count.map_or(WIDTH, |count| count as usize);
    for budget in 2..=most_slots {
        let mut best = (f32::INFINITY, 1);
        for left_slots in 1..budget.min(most_left + 1) {
            let cost = left[left_slots - 1] + right[budget - left_slots - 1];
            if cost < best.0 {
                best = (cost, left_slots);
            }
        }
        spread[budget - 1] = best.0;
        packed |= (best.1 as u64) << Plan::share_shift(budget);
    }
    // In one slot: a leaf, or a wide node of its own (the rays that visit it, its memory, and
    // its children spread over eight slots).
    let one_slot = match leaf_sized {
        Some(_) => node.aabb().half_area() * LEAF_TEST_COST,
        None => node.aabb().half_area() + model.node_penalty + spread[WIDTH - 1],
    };
    let mut costs = [0.0f32; WIDTH];
    let mut best = (one_slot, 0u64);
    costs[0] = best.0;
    for budget in 2..=most_slots {
        if spread[budget - 1] < best.0 {
            best = (spread[budget - 1], budget as u64);
        }
        costs[budget - 1] = best.0;
        packed |= best.1 << Plan::spread_shift(budget);
    }
    // More slots than a leaf-sized subtree's primitives: the same choice.
    for budget in most_slots + 1..=WIDTH {
        costs[budget - 1] = best.0;
        packed |= best.1 << Plan::spread_shift(budget);
    }
    // Shares are read only for a subtree spread: most leaf-sized ones stay one leaf, and
    // skipping their stores saves the cache misses of writing the plan.
    if packed & Plan::SPREADS != 0 {
        plan[index].store(packed, Relaxed);
    }
    (costs, leaf_sized)
}

/// What [`slot_costs`] weighs besides surface areas.
#[derive(Clone, Copy)]
struct CostModel {
    /// [`NODE_MEMORY_COST`] in this tree's areas.
    node_penalty: f32,
    /// Whether leaf-sized subtrees may spread over several slots: with
    /// [`LeafAlignment::Group`] (a node's leaves share groups, so it costs no memory); packed
    /// leaves stay whole.
    split_leaves: bool,
}

/// Per binary node, [`slot_costs`]' choices, packed into 64 bits (zero for a binary leaf):
/// for a slot budget `i = 2..=8`, in a nibble at [`Plan::spread_shift`], 0 for one slot (a
/// wide node of its own, or one leaf) or the budget `j <= i` its children spread over; for a budget `j = 2..=8`, the left child's share in a nibble at
/// [`Plan::share_shift`].
struct Plan;

impl Plan {
    /// The nibbles of the spreads.
    const SPREADS: u64 = (1 << 32) - 1;

    fn spread_shift(budget: usize) -> u32 {
        4 * (budget as u32 - 1)
    }

    fn share_shift(budget: usize) -> u32 {
        32 + 4 * (budget as u32 - 1)
    }
}

/// Binary descendant chosen as a child of a wide node.
#[derive(Clone, Copy)]
struct Candidate {
    /// Index into the binary BVH's nodes.
    index: u32,
    half_area: f32,
    /// Number of primitives below, if small enough for one leaf (with the partners').
    leaf_count: Option<u32>,
    /// The box (with the partners').
    aabb: Aabb,
    /// Binary subtrees sharing its leaf (see [`pair_small_leaves`]).
    partners: Partners,
    /// The slots of this wide node its two children spread over ([`slot_costs`]' plan), or 0
    /// if it stays one child: a leaf or a wide node of its own.
    spread: usize,
}

impl Candidate {
    fn of(bvh2: &Bvh2, index: usize, leaf_count: Option<u32>) -> Candidate {
        let aabb = *bvh2.nodes[index].aabb();
        Candidate {
            index: index as u32,
            half_area: aabb.half_area(),
            leaf_count,
            aabb,
            partners: Partners::default(),
            spread: 0,
        }
    }
}

/// Up to eight values (a wide node's children) without heap allocation.
struct WideList<T: Copy> {
    entries: [T; WIDTH],
    len: usize,
}

impl<T: Copy> WideList<T> {
    fn new(filler: T) -> WideList<T> {
        WideList {
            entries: [filler; WIDTH],
            len: 0,
        }
    }

    fn push(&mut self, value: T) {
        self.entries[self.len] = value;
        self.len += 1;
    }

    fn as_slice(&self) -> &[T] {
        &self.entries[..self.len]
    }
}

/// Binary descendants chosen as the children of one wide node.
type Candidates = WideList<Candidate>;

/// (slot, binary index) of a wide node's inner children.
type InnerChildren = WideList<(u8, u32)>;

/// The collapsed form of one binary subtree: its wide root at node 0, inner child codes
/// relative to this subtree, leaf codes relative to its primitives.
struct Subtree {
    nodes: Vec<WideNode>,
    primitives: Vec<u32>,
}

/// Lays a binary BVH (leaves of at most four primitives) out as wide nodes. With
/// `LeafSizing::Whole`, which binary subtrees become wide nodes of their own and which leaves
/// are split is chosen for the least surface-area cost of node visits and leaf tests
/// ([`slot_costs`]), and each wide node opens every child that the plan spreads over its
/// slots (at most eight result); with
/// `LeafSizing::Split`, each wide node keeps opening the largest child too big for a leaf until
/// it has eight or none is left. Then, with spare slots and `LeafSizing::Split` or
/// `LeafAlignment::Group`, the largest child that fits a leaf is opened; subtrees of at most
/// four primitives become leaves. The subtrees below the root are collapsed in parallel on the
/// current rayon pool.
pub(crate) fn collapse_to_wide(
    bvh2: &Bvh2,
    sizing: LeafSizing,
    alignment: LeafAlignment,
) -> (Vec<WideNode>, Vec<u32>) {
    if bvh2.nodes.is_empty() {
        return (Vec::new(), Vec::new());
    }
    debug_assert!(
        bvh2.nodes
            .iter()
            .all(|node| node.prim_count <= MAX_PRIMS_PER_LEAF)
    );
    let mut root_primitives = Vec::new();
    let plan: Vec<AtomicU64> = (0..bvh2.nodes.len())
        .into_par_iter()
        .map(|_| AtomicU64::new(0))
        .collect();
    // Leaves of costly primitives are split over spare slots instead (`LeafSizing::Split`),
    // which the plan does not weigh: their nodes open the largest child first.
    if sizing == LeafSizing::Whole {
        let model = CostModel {
            node_penalty: NODE_MEMORY_COST * bvh2.nodes[0].aabb().half_area()
                / bvh2.primitive_indices.len() as f32,
            split_leaves: alignment == LeafAlignment::Group,
        };
        slot_costs(bvh2, 0, &plan, model, 0);
    }
    let plan = &plan[..];
    let (mut root, inner_children) =
        wide_node(bvh2, 0, true, sizing, alignment, &mut root_primitives, plan);
    let subtrees: Vec<Subtree> = inner_children
        .as_slice()
        .par_iter()
        .map(|&(_, child)| collapse_subtree(bvh2, child as usize, sizing, alignment, plan))
        .collect();

    // Layout: root, its inner children's roots side by side, then each child's descendants;
    // primitives: the root's leaves, then each child's primitives.
    for (rank, &(slot, _)) in inner_children.as_slice().iter().enumerate() {
        root.children[slot as usize] = 1 + rank as u32;
    }
    let root = [root];
    let mut node_parts: Vec<&[WideNode]> = vec![&root];
    node_parts.extend(subtrees.iter().map(|subtree| &subtree.nodes[..1]));
    node_parts.extend(subtrees.iter().map(|subtree| &subtree.nodes[1..]));
    let mut primitive_parts: Vec<&[u32]> = vec![&root_primitives];
    primitive_parts.extend(subtrees.iter().map(|subtree| &subtree.primitives[..]));

    // Per subtree: subtree node j >= 1 moves to descendant_base + j - 1, its leaves' first
    // slots move up by primitive_base (a multiple of four with `LeafAlignment::Group`).
    let mut relocations = Vec::with_capacity(subtrees.len());
    let mut descendant_base = 1 + subtrees.len() as u32;
    let mut primitive_base = root_primitives.len() as u32;
    for subtree in &subtrees {
        relocations.push((descendant_base, primitive_base));
        descendant_base += subtree.nodes.len() as u32 - 1;
        primitive_base += subtree.primitives.len() as u32;
    }
    let subtree_count = subtrees.len();
    let relocate = |part: usize, mut node: WideNode| {
        if part == 0 {
            return node;
        }
        let (descendant_base, primitive_base) = relocations[(part - 1) % subtree_count];
        for slot in 0..WIDTH {
            if !occupied(&node, slot) {
                continue;
            }
            let code = &mut node.children[slot];
            if *code & LEAF_BIT != 0 {
                *code += primitive_base;
            } else {
                // Inner children of a subtree are never its root (index 0).
                *code += descendant_base - 1;
            }
        }
        node
    };
    let nodes = concat_parallel(&node_parts, relocate);
    let primitive_order = primitive_parts.concat();
    (nodes, primitive_order)
}

/// Concatenates `parts` in parallel, passing every element through `map` with the index of
/// its part.
fn concat_parallel<T: Copy + Sync, U: Send>(
    parts: &[&[T]],
    map: impl Fn(usize, T) -> U + Sync + Send,
) -> Vec<U> {
    let mut starts = Vec::with_capacity(parts.len());
    let mut total = 0;
    for part in parts {
        starts.push(total);
        total += part.len();
    }
    (0..total)
        .into_par_iter()
        .with_min_len(4096)
        .map(|position| {
            // The last part starting at or before `position` (an empty part shares its start
            // with the next one).
            let part = starts.partition_point(|&start| start <= position) - 1;
            map(part, parts[part][position - starts[part]])
        })
        .collect()
}

/// Collapses the binary subtree at `binary_root` into a node array with its root at 0.
fn collapse_subtree(
    bvh2: &Bvh2,
    binary_root: usize,
    sizing: LeafSizing,
    alignment: LeafAlignment,
    plan: &[AtomicU64],
) -> Subtree {
    let mut nodes = vec![WideNode::default()];
    let mut primitives = Vec::new();
    // (wide node index, binary node it stands for)
    let mut pending = vec![(0usize, binary_root)];
    while let Some((wide_index, binary_index)) = pending.pop() {
        let (mut node, inner_children) = wide_node(
            bvh2,
            binary_index,
            false,
            sizing,
            alignment,
            &mut primitives,
            plan,
        );
        for &(slot, child) in inner_children.as_slice() {
            node.children[slot as usize] = nodes.len() as u32;
            pending.push((nodes.len(), child as usize));
            nodes.push(WideNode::default());
        }
        nodes[wide_index] = node;
    }
    Subtree { nodes, primitives }
}

/// One wide node for `binary_index`: child boxes, leaves (their primitives are appended to
/// `primitive_order`; with `LeafAlignment::Group` the node's leaves share groups of four, see
/// [`share_groups`]) and the
/// slots and binary nodes of its inner children, whose codes are left for the caller. Only
/// the root may be small enough to be a leaf itself (`may_be_leaf`).
fn wide_node(
    bvh2: &Bvh2,
    binary_index: usize,
    may_be_leaf: bool,
    sizing: LeafSizing,
    alignment: LeafAlignment,
    primitive_order: &mut Vec<u32>,
    plan: &[AtomicU64],
) -> (WideNode, InnerChildren) {
    let binary = &bvh2.nodes;
    let children = wide_children(bvh2, binary_index, may_be_leaf, sizing, alignment, plan);
    let children = children.as_slice();
    let parent_box = *binary[binary_index].aabb();
    let slots = assign_slots(children, &parent_box);
    let mut node = WideNode::default();
    let mut inner_children = InnerChildren::new((0, 0));
    // Grouped leaves: (slot, count, primitives), packed into shared groups below.
    let mut group_leaves = WideList::new((0u8, 0u32, [0u32; MAX_PRIMS_PER_LEAF as usize]));
    for (slot, &position) in slots.iter().enumerate() {
        if position == EMPTY_SLOT {
            continue;
        }
        let child = children[position as usize];
        let child_box = child.aabb;
        for axis in 0..3 {
            node.planes[2 * axis][slot] = child_box.min[axis];
            node.planes[2 * axis + 1][slot] = child_box.max[axis];
        }
        if child.leaf_count.is_some() {
            // Gathered on the stack: a leaf holds at most four primitives.
            let mut leaf = LeafPrimitives::new(0);
            collect_primitives(bvh2, child.index as usize, &mut leaf);
            for &partner in &child.partners.indices[..child.partners.len] {
                collect_primitives(bvh2, partner as usize, &mut leaf);
            }
            let count = leaf.len as u32;
            match alignment {
                LeafAlignment::Packed => {
                    node.children[slot] = leaf_code(primitive_order.len() as u32, count);
                    primitive_order.extend_from_slice(leaf.as_slice());
                }
                LeafAlignment::Group => {
                    let mut primitives = [0u32; MAX_PRIMS_PER_LEAF as usize];
                    primitives.copy_from_slice(&leaf.entries[..MAX_PRIMS_PER_LEAF as usize]);
                    group_leaves.push((slot as u8, count, primitives));
                }
            }
        } else {
            inner_children.push((slot as u8, child.index));
        }
    }
    share_groups(&mut node, group_leaves, primitive_order);
    (node, inner_children)
}

/// Packs a node's grouped leaves into groups of four slots, several leaves to a group where
/// they fit (largest first, each into the first group with room; padding with [`PADDING`]
/// after the last lane used), and sets their codes.
fn share_groups(
    node: &mut WideNode,
    mut leaves: WideList<(u8, u32, [u32; MAX_PRIMS_PER_LEAF as usize])>,
    primitive_order: &mut Vec<u32>,
) {
    let group = MAX_PRIMS_PER_LEAF as usize;
    leaves.entries[..leaves.len].sort_by_key(|&(slot, count, _)| (std::cmp::Reverse(count), slot));
    // (first slot, lanes used) of the node's groups.
    let mut groups = WideList::new((0usize, 0usize));
    for &(slot, count, primitives) in leaves.as_slice() {
        let count = count as usize;
        let position = match groups
            .as_slice()
            .iter()
            .position(|&(_, used)| used + count <= group)
        {
            Some(position) => position,
            None => {
                groups.push((primitive_order.len(), 0));
                primitive_order.resize(primitive_order.len() + group, PADDING);
                groups.len - 1
            }
        };
        let (start, used) = &mut groups.entries[position];
        let first = *start + *used;
        primitive_order[first..first + count].copy_from_slice(&primitives[..count]);
        *used += count;
        node.children[slot as usize] = leaf_code(first as u32, count as u32);
    }
}

/// Binary subtrees sharing a leaf with a candidate (see [`pair_small_leaves`]): each leaf
/// holds at least one primitive, so at most three join a candidate's.
#[derive(Clone, Copy, Default)]
struct Partners {
    indices: [u32; MAX_PRIMS_PER_LEAF as usize - 1],
    len: usize,
}

/// Joins the two sibling leaves whose primitives fit one group of four and whose union has the
/// smallest surface area into one leaf (box: their union), so that a slot is freed. Returns
/// whether a pair was found.
fn pair_small_leaves(children: &mut Candidates) -> bool {
    let list = children.as_slice();
    let mut best: Option<(usize, usize, f32)> = None;
    for i in 0..list.len() {
        let Some(first) = list[i].leaf_count else {
            continue;
        };
        for j in i + 1..list.len() {
            let Some(second) = list[j].leaf_count else {
                continue;
            };
            if first + second > MAX_PRIMS_PER_LEAF {
                continue;
            }
            let area = list[i].aabb.union(&list[j].aabb).half_area();
            if best.is_none_or(|(_, _, best_area)| area < best_area) {
                best = Some((i, j, area));
            }
        }
    }
    let Some((i, j, area)) = best else {
        return false;
    };
    let second = list[j];
    let first = &mut children.entries[i];
    first.aabb = first.aabb.union(&second.aabb);
    first.half_area = area;
    first.leaf_count = Some(first.leaf_count.unwrap_or(0) + second.leaf_count.unwrap_or(0));
    let joined = &mut first.partners;
    for index in std::iter::once(second.index).chain(
        second.partners.indices[..second.partners.len]
            .iter()
            .copied(),
    ) {
        joined.indices[joined.len] = index;
        joined.len += 1;
    }
    // The last candidate takes `j`'s place.
    children.len -= 1;
    children.entries[j] = children.entries[children.len];
    true
}

/// The number of primitives below binary node `index` if it fits in one leaf (at most
/// [`MAX_PRIMS_PER_LEAF`]); `None` for larger subtrees. Every subtree holds at least one
/// primitive and every inner node at least two, so a lower bound decides most nodes after
/// loading their two children. A node with two inner children is taken as too large (at most
/// four primitives only if both hold two; opening it instead is as correct).
fn leaf_sized_count(bvh2: &Bvh2, index: usize) -> Option<u32> {
    let nodes = &bvh2.nodes;
    let mut node = &nodes[index];
    if node.is_leaf() {
        return (node.prim_count <= MAX_PRIMS_PER_LEAF).then_some(node.prim_count);
    }
    let at_least = |node: &Bvh2Node| if node.is_leaf() { node.prim_count } else { 2 };
    // Primitives in the leaves seen so far, outside `node`.
    let mut counted = 0u32;
    loop {
        let first = node.first_index as usize;
        let (left, right) = (&nodes[first], &nodes[first + 1]);
        let bound = counted
            .saturating_add(at_least(left))
            .saturating_add(at_least(right));
        if bound > MAX_PRIMS_PER_LEAF {
            return None;
        }
        match (left.is_leaf(), right.is_leaf()) {
            (true, true) => return Some(bound),
            (true, false) => {
                counted += left.prim_count;
                node = right;
            }
            (false, true) => {
                counted += right.prim_count;
                node = left;
            }
            (false, false) => return None,
        }
    }
}

/// The primitives of one leaf (at most [`MAX_PRIMS_PER_LEAF`]).
type LeafPrimitives = WideList<u32>;

fn collect_primitives(bvh2: &Bvh2, index: usize, out: &mut LeafPrimitives) {
    let node = &bvh2.nodes[index];
    if node.is_leaf() {
        let first = node.first_index as usize;
        for &primitive in &bvh2.primitive_indices[first..first + node.prim_count as usize] {
            out.push(primitive);
        }
    } else {
        collect_primitives(bvh2, node.first_index as usize, out);
        collect_primitives(bvh2, node.first_index as usize + 1, out);
    }
}

/// Starts loading the sibling pair `first`, `first + 1` of binary nodes (up to three cache
/// lines), which the collapse visits next.
#[inline(always)]
fn prefetch_pair(nodes: &[Bvh2Node], first: usize) {
    if let Some([left, right]) = nodes.get(first..first + 2) {
        prefetch(left);
        prefetch(right);
        prefetch(&right.prim_count);
    }
}

/// Candidates for the sibling pair `first`, `first + 1`. The collapse is bound by memory
/// latency: for a sibling too large for a leaf, opening it (often the next step) reads its
/// children, which `leaf_sized_count` has just loaded, and sizes their children, whose loads
/// are requested here so that they overlap with the work before.
#[inline(always)]
fn candidate_pair(bvh2: &Bvh2, first: usize) -> [Candidate; 2] {
    let binary = &bvh2.nodes;
    let candidates =
        [first, first + 1].map(|index| Candidate::of(bvh2, index, leaf_sized_count(bvh2, index)));
    for candidate in &candidates {
        if candidate.leaf_count.is_none() {
            let children = binary[candidate.index as usize].first_index as usize;
            for child in &binary[children..children + 2] {
                if !child.is_leaf() {
                    prefetch_pair(binary, child.first_index as usize);
                }
            }
        }
    }
    candidates
}

/// Up to eight binary descendants that become the children of one wide node, each with its
/// primitive count if it is small enough to be a leaf.
fn wide_children(
    bvh2: &Bvh2,
    index: usize,
    may_be_leaf: bool,
    sizing: LeafSizing,
    alignment: LeafAlignment,
    plan: &[AtomicU64],
) -> Candidates {
    let binary = &bvh2.nodes;
    let mut children = Candidates::new(Candidate::of(bvh2, 0, None));
    if may_be_leaf && let Some(count) = leaf_sized_count(bvh2, index) {
        // Only for a tiny root: a single leaf child.
        children.push(Candidate::of(bvh2, index, Some(count)));
        return children;
    }
    // Grouped leaves: small sibling leaves are joined only to free a slot for a subtree still
    // to open. Joining more to fill groups is not needed (siblings share groups) and loosens
    // the leaf boxes: the frustum packets were 2-5 % slower with it.
    let join_leaves = alignment == LeafAlignment::Group;
    // Children spread as the plan has it: over eight slots below this node, then each opened
    // subtree's children over the slots it was given.
    let spread_of = |candidate: &Candidate, budget: usize| match budget {
        _ if sizing == LeafSizing::Split => {
            if candidate.leaf_count.is_none() {
                WIDTH
            } else {
                0
            }
        }
        0 | 1 => 0,
        budget => {
            ((plan[candidate.index as usize].load(Relaxed) >> Plan::spread_shift(budget)) & 15)
                as usize
        }
    };
    let opened_pair = |index: usize, spread: usize| {
        let share = ((plan[index].load(Relaxed) >> Plan::share_shift(spread)) & 15) as usize;
        let mut pair = candidate_pair(bvh2, binary[index].first_index as usize);
        pair[0].spread = spread_of(&pair[0], share);
        pair[1].spread = spread_of(&pair[1], spread - share);
        pair
    };
    let fill_spare = sizing == LeafSizing::Split || alignment == LeafAlignment::Group;
    let [first, second] = opened_pair(index, WIDTH);
    children.push(first);
    children.push(second);
    loop {
        // Open every subtree the plan spreads (too large for a leaf or not); with spare slots
        // and `LeafSizing::Split` or `LeafAlignment::Group`, then the largest one that fits a
        // leaf.
        let mut best: Option<(usize, bool, f32)> = None;
        for (position, child) in children.as_slice().iter().enumerate() {
            let planned = child.spread > 0;
            if !planned && child.leaf_count.is_none() {
                // A wide node of its own.
                continue;
            }
            if binary[child.index as usize].is_leaf()
                || child.partners.len > 0
                || (!planned && !fill_spare)
            {
                continue;
            }
            let better = best.is_none_or(|(_, best_planned, best_area)| {
                (planned && !best_planned)
                    || (planned == best_planned && child.half_area > best_area)
            });
            if better {
                best = Some((position, planned, child.half_area));
            }
        }
        let Some((mut position, planned, _)) = best else {
            break;
        };
        if children.len == WIDTH {
            let chosen = children.entries[position].index;
            let must_open = children.entries[position].leaf_count.is_none();
            if !(planned && must_open && join_leaves && pair_small_leaves(&mut children)) {
                break;
            }
            // Joining moved candidates (never the chosen one, which is no leaf).
            let Some(moved) = children
                .as_slice()
                .iter()
                .position(|child| child.index == chosen)
            else {
                break;
            };
            position = moved;
        }
        let chosen = &children.entries[position];
        let [first, second] = if planned {
            opened_pair(chosen.index as usize, chosen.spread)
        } else {
            // A leaf-sized subtree split over spare slots.
            candidate_pair(bvh2, binary[chosen.index as usize].first_index as usize)
        };
        children.entries[position] = first;
        children.push(second);
    }
    children
}

/// Assigns children to the eight slots so that, for a ray of octant `o`, the traversal order
/// `slot ^ (7 - o)` visits near children first: slot `s` prefers the child that comes first
/// along the direction whose signs are the bits of `s` (set = negative). Returns, per slot,
/// the position of its child in `children` or [`EMPTY_SLOT`].
fn assign_slots(children: &[Candidate], parent: &Aabb) -> [u8; WIDTH] {
    let centre = parent.center();
    // costs[child][slot]: how far along slot's direction the child's centre lies, i.e. the dot
    // product of the offset with (+-1, +-1, +-1) summed as (x + y) + z, as `Vec3A::dot`
    // rounds it (the negations are exact).
    let mut costs = [[f32::INFINITY; WIDTH]; WIDTH];
    for (child, row) in children.iter().zip(costs.iter_mut()) {
        let offset = child.aabb.center() - centre;
        let y = Vec4::new(offset.y, offset.y, -offset.y, -offset.y);
        let z = Vec4::new(offset.z, -offset.z, offset.z, -offset.z);
        (Vec4::splat(offset.x) + y + z).write_to_slice(&mut row[..4]);
        (Vec4::splat(-offset.x) + y + z).write_to_slice(&mut row[4..]);
    }
    // Greedy: repeatedly place the (child, slot) pair with the lowest cost, the first in
    // (child, slot) order among equal ones. Taken slots cost infinity (real costs are finite);
    // every child keeps its cheapest slot, recomputed only when another child takes it.
    let mut cheapest = [(f32::INFINITY, 0u8); WIDTH];
    for (row, best) in costs.iter().zip(cheapest.iter_mut()).take(children.len()) {
        *best = first_minimum(row);
    }
    let mut placed = 0u32;
    let mut slots = [EMPTY_SLOT; WIDTH];
    for _ in 0..children.len() {
        // Placed children and unused rows have infinite costs.
        let (_, position) = first_minimum(&cheapest.map(|(cost, _)| cost));
        let position = position as usize;
        let slot = cheapest[position].1 as usize;
        slots[slot] = position as u8;
        placed |= 1 << position;
        cheapest[position].0 = f32::INFINITY;
        for row in costs.iter_mut().take(children.len()) {
            row[slot] = f32::INFINITY;
        }
        for (other, best) in cheapest.iter_mut().enumerate().take(children.len()) {
            if placed & (1 << other) == 0 && best.1 as usize == slot {
                *best = first_minimum(&costs[other]);
            }
        }
    }
    slots
}

/// The smallest of eight values and the first index holding it.
#[inline(always)]
fn first_minimum(values: &[f32; WIDTH]) -> (f32, u8) {
    let low = Vec4::from_slice(&values[..4]);
    let high = Vec4::from_slice(&values[4..]);
    let minimum = Vec4::splat(low.min(high).min_element());
    let at = low.cmpeq(minimum).bitmask() | (high.cmpeq(minimum).bitmask() << 4);
    (minimum.x, at.trailing_zeros() as u8)
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
