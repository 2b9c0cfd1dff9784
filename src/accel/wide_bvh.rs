//! Building obvhs compressed wide BVHs (8 children per node, quantized child boxes, up to three
//! primitives per leaf) and our own single-ray traversal of them.
//!
//! The traversal follows the CWBVH node format: a node's children are visited nearest-first by
//! pairing a slot ordering chosen at build time with the ray's direction octant. It differs from
//! obvhs' own traversal in that the box test honours the ray's `t_min` (obvhs uses a fixed
//! 1e-4) and widens every slab by a bound on its rounding error, so that hits close to the
//! origin or exactly on box faces, edges and corners are never culled, also for rays running
//! almost parallel to an axis.

use glam::{Vec3, Vec3A, Vec4};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ploc::{PlocBuilder, SortPrecision};

use crate::accel::{EMPTY_BOUNDS, MAX_COORDINATE};
use rayon::iter::{
    IndexedParallelIterator, IntoParallelIterator, IntoParallelRefIterator, ParallelIterator,
};
use rayon::slice::ParallelSlice;

/// CWBVH leaves hold at most three primitives.
const MAX_PRIMS_PER_LEAF: u32 = 3;

/// How far PLOC looks for a node's nearest neighbour (obvhs' `PlocSearchDistance::VeryLow`).
const PLOC_SEARCH_DISTANCE: usize = 2;

/// A wide BVH built over boxes.
pub(crate) struct WideBvh {
    pub nodes: Vec<CwBvhNode>,
    /// For every primitive slot the leaves refer to, the index into the boxes it stands for
    /// (callers reorder their primitives by it).
    pub order: Vec<u32>,
    /// The union of the boxes ([`EMPTY_BOUNDS`] for none).
    pub bounds: (Vec3, Vec3),
}

/// Builds a wide BVH over `boxes`, which must be finite; an empty input gives no nodes.
///
/// obvhs builds the binary BVH (PLOC with search distance 2 plus 1% reinsertion, parallel
/// through rayon with obvhs' `parallel` feature), for whole leaves starting from the runs of
/// [`neighbour_clusters`]; [`collapse_to_wide`] then packs it into
/// obvhs' CWBVH node format. obvhs' own converter optimizes the collapse by dynamic
/// programming and costs about as much as obvhs' binary build (~300 ms for 1M triangles,
/// single threaded); the greedy collapse runs in parallel and takes a fraction of that, for a
/// BVH that traces single rays a few percent slower. Measured on a 1M-triangle mesh (2 cores,
/// before the runs, when the whole build took ~300 ms): the 1% reinsertion cost 15 ms and
/// gained 4% on the default renderer's shadow rays (none on packets of primary rays), so it
/// stays; search distance 6 or 5% reinsertion cost another 40-50 ms for at most 2%, search
/// distance 1 lost 2%.
pub(crate) fn build_wide_bvh(boxes: &[Aabb], sizing: LeafSizing) -> WideBvh {
    if boxes.is_empty() {
        return WideBvh {
            nodes: Vec::new(),
            order: Vec::new(),
            bounds: EMPTY_BOUNDS,
        };
    }
    // obvhs' PLOC merges the leaves it is given: runs of neighbours for whole leaves, else one
    // per box (what its `build` would make).
    let leaves: Vec<Bvh2Node> = match sizing {
        LeafSizing::Whole => neighbour_clusters(boxes),
        LeafSizing::Split => boxes
            .par_iter()
            .enumerate()
            .map(|(index, aabb)| Bvh2Node::new(*aabb, 1, index as u32))
            .collect(),
    };
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
    let (nodes, order) = collapse_to_wide(&bvh2, sizing);
    WideBvh {
        nodes,
        order,
        bounds: (total.min.into(), total.max.into()),
    }
}

/// Binary leaves for a build over `boxes`: runs of up to three consecutive primitives whose
/// boxes touch one after the other and stay compact together (in a mesh: neighbouring
/// triangles, such as the two halves of a quad), else single primitives. Meshes list
/// neighbours next to each other, so the binary build starts from about half as many leaves.
/// On the benchmark's 1M-triangle height field (2 cores) the BVH build went from 290 to 215 ms
/// and packets of primary rays got 6 % faster; single rays were about 4 % slower. Runs of three
/// regardless of shape built in 200 ms but cost single rays 8 %. Boxes are scanned in chunks in
/// parallel; a run never crosses a chunk boundary.
pub(crate) fn neighbour_clusters(boxes: &[Aabb]) -> Vec<Bvh2Node> {
    const CHUNK: usize = 1 << 12;
    let joins = |cluster: &Aabb, last: &Aabb, next: &Aabb| {
        let touch = last.min.cmple(next.max).all() && next.min.cmple(last.max).all();
        let mut union = *cluster;
        union.extend(next.min);
        union.extend(next.max);
        // A run grows only while the union stays smaller than the parts side by side.
        touch && union.half_area() <= 0.75 * (cluster.half_area() + next.half_area())
    };
    let chunks: Vec<Vec<Bvh2Node>> = boxes
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(chunk, boxes)| {
            let base = chunk * CHUNK;
            let mut clusters = Vec::with_capacity(boxes.len() / 2 + 1);
            let mut first = 0;
            let mut cluster = boxes[0];
            for i in 1..=boxes.len() {
                if i < boxes.len()
                    && i - first < MAX_PRIMS_PER_LEAF as usize
                    && joins(&cluster, &boxes[i - 1], &boxes[i])
                {
                    cluster.extend(boxes[i].min);
                    cluster.extend(boxes[i].max);
                    continue;
                }
                clusters.push(Bvh2Node::new(
                    cluster,
                    (i - first) as u32,
                    (base + first) as u32,
                ));
                if i < boxes.len() {
                    first = i;
                    cluster = boxes[i];
                }
            }
            clusters
        })
        .collect();
    chunks.concat()
}

/// Number of leaves (occupied child slots that are not inner nodes) in `nodes`.
#[cfg(test)]
pub(crate) fn leaf_count(nodes: &[CwBvhNode]) -> usize {
    nodes
        .iter()
        .map(|node| {
            (node.child_meta.iter().filter(|meta| **meta != 0).count())
                - node.imask.count_ones() as usize
        })
        .sum()
}

/// Whether spare child slots of a wide node split subtrees that would fit one leaf.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) enum LeafSizing {
    /// Subtrees of up to three primitives stay one leaf: for cheap primitive tests
    /// (triangles), fewer box tests win. Measured on a 1M-triangle mesh: primary-ray packets
    /// 10 % faster, the default renderer 2 %.
    Whole,
    /// Spare slots split small subtrees into smaller leaves: for costly primitive tests
    /// (spheres and tubes in f64, instances), tighter boxes win. Measured: 100k spheres 5 %
    /// faster, the CAVE demo's sphere cloud with shadows and a mirror 15-20 %.
    Split,
}

/// A wide node's children can be at most this many.
const WIDTH: usize = 8;

/// Marks an empty slot in [`assign_slots`]' result.
const EMPTY_SLOT: u8 = u8::MAX;

/// Binary descendant chosen as a child of a wide node.
#[derive(Clone, Copy)]
struct Candidate {
    /// Index into the binary BVH's nodes.
    index: u32,
    half_area: f32,
    /// Number of primitives below, if small enough for one leaf.
    leaf_count: Option<u32>,
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

/// Binary indices of a wide node's inner children, in slot order.
type InnerChildren = WideList<u32>;

/// The collapsed form of one binary subtree: its wide root at node 0, node indices and
/// primitive bases relative to this subtree.
struct Subtree {
    nodes: Vec<CwBvhNode>,
    primitives: Vec<u32>,
}

/// Packs a binary BVH (leaves of at most three primitives) into CWBVH nodes: each wide node
/// takes its binary node's two children and keeps opening the largest child (by surface area)
/// that is too big for a leaf until it has eight or none is left (then, with
/// `LeafSizing::Split`, the largest that fits a leaf); subtrees of at most three primitives
/// become leaves. The subtrees below the root are collapsed in parallel on the current rayon
/// pool.
pub(crate) fn collapse_to_wide(bvh2: &Bvh2, sizing: LeafSizing) -> (Vec<CwBvhNode>, Vec<u32>) {
    if bvh2.nodes.is_empty() {
        return (Vec::new(), Vec::new());
    }
    // A binary leaf too large for a wide leaf would be taken for an inner node (leaves come
    // from `neighbour_clusters` or hold one primitive, and reinsertion keeps them whole).
    debug_assert!(
        bvh2.nodes
            .iter()
            .all(|node| node.prim_count <= MAX_PRIMS_PER_LEAF)
    );
    let mut root_primitives = Vec::new();
    let (mut root, inner_children) = wide_node(bvh2, 0, true, sizing, &mut root_primitives);
    let subtrees: Vec<Subtree> = inner_children
        .as_slice()
        .par_iter()
        .map(|&child| collapse_subtree(bvh2, child as usize, sizing))
        .collect();

    // Layout: root, its inner children's roots side by side (CWBVH addresses inner children
    // as `child_base_idx + rank`), then each child's descendants; primitives: the root's
    // leaves, then each child's primitives.
    root.child_base_idx = 1;
    root.primitive_base_idx = 0;
    let root = [root];
    let mut node_parts: Vec<&[CwBvhNode]> = vec![&root];
    node_parts.extend(subtrees.iter().map(|subtree| &subtree.nodes[..1]));
    node_parts.extend(subtrees.iter().map(|subtree| &subtree.nodes[1..]));
    let mut primitive_parts: Vec<&[u32]> = vec![&root_primitives];
    primitive_parts.extend(subtrees.iter().map(|subtree| &subtree.primitives[..]));

    // Per subtree: subtree node j >= 1 moves to descendant_base + j - 1, its primitives move
    // up by primitive_base.
    let mut relocations = Vec::with_capacity(subtrees.len());
    let mut descendant_base = 1 + subtrees.len() as u32;
    let mut primitive_base = root_primitives.len() as u32;
    for subtree in &subtrees {
        relocations.push((descendant_base, primitive_base));
        descendant_base += subtree.nodes.len() as u32 - 1;
        primitive_base += subtree.primitives.len() as u32;
    }
    let subtree_count = subtrees.len();
    let relocate = |part: usize, mut node: CwBvhNode| {
        if part == 0 {
            return node;
        }
        let (descendant_base, primitive_base) = relocations[(part - 1) % subtree_count];
        node.child_base_idx = (node.child_base_idx + descendant_base).saturating_sub(1);
        node.primitive_base_idx += primitive_base;
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
fn collapse_subtree(bvh2: &Bvh2, binary_root: usize, sizing: LeafSizing) -> Subtree {
    let mut nodes = vec![CwBvhNode::default()];
    let mut primitives = Vec::new();
    // (wide node index, binary node it stands for)
    let mut pending = vec![(0usize, binary_root)];
    while let Some((wide_index, binary_index)) = pending.pop() {
        let (mut node, inner_children) =
            wide_node(bvh2, binary_index, false, sizing, &mut primitives);
        // Inner children get consecutive nodes in slot order.
        node.child_base_idx = nodes.len() as u32;
        for &child in inner_children.as_slice() {
            pending.push((nodes.len(), child as usize));
            nodes.push(CwBvhNode::default());
        }
        nodes[wide_index] = node;
    }
    Subtree { nodes, primitives }
}

/// One wide node for `binary_index`: child boxes, leaves (their primitives are appended to
/// `primitive_order`, starting at the node's `primitive_base_idx`) and, in slot order, the
/// binary nodes of its inner children. `child_base_idx` is left for the caller. Only the
/// root may be small enough to be a leaf itself (`may_be_leaf`): every other node passed
/// here is an inner child, already known to hold more than three primitives.
fn wide_node(
    bvh2: &Bvh2,
    binary_index: usize,
    may_be_leaf: bool,
    sizing: LeafSizing,
    primitive_order: &mut Vec<u32>,
) -> (CwBvhNode, InnerChildren) {
    let binary = &bvh2.nodes;
    let children = wide_children(bvh2, binary_index, may_be_leaf, sizing);
    let children = children.as_slice();
    let parent_box = *binary[binary_index].aabb();
    let slots = assign_slots(bvh2, children, &parent_box);
    let (p, exponent, inverse_step) = quantization_frame(&parent_box);
    let mut node = CwBvhNode {
        p,
        e: exponent,
        primitive_base_idx: primitive_order.len() as u32,
        ..CwBvhNode::default()
    };
    let mut inner_children = InnerChildren::new(0);
    let mut leaf_offset = 0u32;
    for (slot, &position) in slots.iter().enumerate() {
        if position == EMPTY_SLOT {
            continue;
        }
        let child = children[position as usize];
        let child_box = binary[child.index as usize].aabb();
        let quantize = |axis: usize| {
            // Exact in f64: f32 differences and power-of-two scalings do not round.
            let origin = node.p[axis] as f64;
            let low = ((child_box.min[axis] as f64 - origin) * inverse_step[axis])
                .clamp(0.0, MAX_QUANTIZED as f64);
            let high = ((child_box.max[axis] as f64 - origin) * inverse_step[axis])
                .clamp(0.0, MAX_QUANTIZED as f64);
            // Truncation is floor for these non-negative values (and avoids a libm call).
            let low_q = low as u8;
            let high_q = high as u8;
            let high_q = high_q + u8::from((high_q as f64) < high);
            (low_q, high_q)
        };
        (node.child_min_x[slot], node.child_max_x[slot]) = quantize(0);
        (node.child_min_y[slot], node.child_max_y[slot]) = quantize(1);
        (node.child_min_z[slot], node.child_max_z[slot]) = quantize(2);
        if child.leaf_count.is_some() {
            let before = primitive_order.len();
            collect_primitives(bvh2, child.index as usize, primitive_order);
            let count = (primitive_order.len() - before) as u32;
            node.child_meta[slot] = (leaf_offset | (((1 << count) - 1) << 5)) as u8;
            leaf_offset += count;
        } else {
            node.imask |= 1 << slot;
            node.child_meta[slot] = (24 + slot as u8) | 0b0010_0000;
            inner_children.push(child.index);
        }
    }
    (node, inner_children)
}

/// The number of primitives below binary node `index` if it fits in one leaf (at most
/// three); `None` for larger subtrees. Every subtree holds at least one primitive and every
/// inner node at least two, so a lower bound decides most nodes after loading their two
/// children, and at most one inner node can be left to open while the bound stays at three.
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
        // Within the bound, at most one child is an inner node.
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

fn collect_primitives(bvh2: &Bvh2, index: usize, out: &mut Vec<u32>) {
    let node = &bvh2.nodes[index];
    if node.is_leaf() {
        let first = node.first_index as usize;
        out.extend_from_slice(&bvh2.primitive_indices[first..first + node.prim_count as usize]);
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
    let candidates = [first, first + 1].map(|index| Candidate {
        index: index as u32,
        half_area: binary[index].aabb().half_area(),
        leaf_count: leaf_sized_count(bvh2, index),
    });
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
fn wide_children(bvh2: &Bvh2, index: usize, may_be_leaf: bool, sizing: LeafSizing) -> Candidates {
    let binary = &bvh2.nodes;
    let node = &binary[index];
    let mut children = Candidates::new(Candidate {
        index: 0,
        half_area: 0.0,
        leaf_count: None,
    });
    if may_be_leaf && let Some(count) = leaf_sized_count(bvh2, index) {
        // Only for a tiny root: a single leaf child.
        children.push(Candidate {
            index: index as u32,
            half_area: 0.0,
            leaf_count: Some(count),
        });
        return children;
    }
    let [first, second] = candidate_pair(bvh2, node.first_index as usize);
    children.push(first);
    children.push(second);
    while children.len < WIDTH {
        // Open the largest subtree too large for a leaf; with spare slots and
        // `LeafSizing::Split`, then the largest one that fits a leaf.
        let mut best: Option<(usize, bool, f32)> = None;
        for (position, child) in children.as_slice().iter().enumerate() {
            let must_open = child.leaf_count.is_none();
            if binary[child.index as usize].is_leaf() || (!must_open && sizing == LeafSizing::Whole)
            {
                continue;
            }
            let better = best.is_none_or(|(_, best_must, best_area)| {
                (must_open && !best_must) || (must_open == best_must && child.half_area > best_area)
            });
            if better {
                best = Some((position, must_open, child.half_area));
            }
        }
        let Some((position, _, _)) = best else {
            break;
        };
        let opened = binary[children.entries[position].index as usize].first_index as usize;
        let [first, second] = candidate_pair(bvh2, opened);
        children.entries[position] = first;
        children.push(second);
    }
    children
}

/// Assigns children to the eight slots so that, for a ray of octant `o`, the traversal order
/// `slot ^ (7 - o)` visits near children first: slot `s` prefers the child that comes first
/// along the direction whose signs are the bits of `s` (set = negative). Returns, per slot,
/// the position of its child in `children` or [`EMPTY_SLOT`].
fn assign_slots(bvh2: &Bvh2, children: &[Candidate], parent: &Aabb) -> [u8; WIDTH] {
    let centre = parent.center();
    // costs[child][slot]: how far along slot's direction the child's centre lies, i.e. the dot
    // product of the offset with (+-1, +-1, +-1) summed as (x + y) + z, as `Vec3A::dot`
    // rounds it (the negations are exact).
    let mut costs = [[f32::INFINITY; WIDTH]; WIDTH];
    for (child, row) in children.iter().zip(costs.iter_mut()) {
        let offset = bvh2.nodes[child.index as usize].aabb().center() - centre;
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

/// Node origin, exponent bytes and the inverse of the power-of-two step they encode: the
/// smallest step for which 255 steps span the box on every axis.
fn quantization_frame(parent: &Aabb) -> (Vec3, [u8; 3], [f64; 3]) {
    let mut exponent = [0u8; 3];
    let mut inverse_step = [0.0f64; 3];
    for axis in 0..3 {
        let extent = (parent.max[axis] as f64 - parent.min[axis] as f64).max(1.0e-30);
        // extent = m * 2^e with 1 <= m < 2 (a normal f64), so extent / 2^(e - 7) = 128 m lies
        // in [128, 256) and extent / 2^(e - 8) exceeds 255: the step is 2^(e - 7), or 2^(e - 6)
        // if 128 m > 255. Exact, unlike log2/ceil/exp2, and cheaper.
        let extent_exponent = ((extent.to_bits() >> 52) & 0x7ff) as i32 - 1023;
        let mut power = extent_exponent - 7;
        if extent * power_of_two(-power) > MAX_QUANTIZED as f64 {
            power += 1;
        }
        let power = power.max(-126);
        inverse_step[axis] = power_of_two(-power);
        // Biased f32 exponent, the only non-zero bits of a power of two.
        exponent[axis] = (power + 127) as u8;
    }
    (parent.min.into(), exponent, inverse_step)
}

/// `2^power` for `power` within the normal f64 range.
fn power_of_two(power: i32) -> f64 {
    f64::from_bits(((1023 + power) as u64) << 52)
}

/// Inverse direction components are clamped to this magnitude. Together with
/// `MAX_COORDINATE` (which also bounds ray origins) it keeps every slab distance finite, so
/// the box test never sees infinities or NaN.
pub(crate) const MAX_INV_DIRECTION: f32 = 1.0e18;

/// Bound on the relative rounding error of a slab distance `q * step * inv + (p - o) * inv`,
/// taken relative to the magnitudes of its two terms. Box tests widen every slab by it (plus
/// the half-ulp by which obvhs' quantization can miss a primitive), so rays that meet a
/// primitive exactly on a box face, edge or corner are never culled, however parallel to an
/// axis they run.
pub(crate) const SLAB_ERROR: f32 = 4.0 * f32::EPSILON;

/// Largest quantized plane value.
pub(crate) const MAX_QUANTIZED: f32 = 255.0;

/// Per-axis slab parameters of one node for one ray: `t = q * step + entry_offset` (or
/// `exit_offset`), where the offsets already include the error widening.
#[inline(always)]
pub(crate) fn slab_parameters(
    node: &CwBvhNode,
    origin: Vec3A,
    inv_direction: Vec3A,
) -> (Vec3A, Vec3A, Vec3A) {
    let step = quantization_step(node) * inv_direction;
    let offset = (Vec3A::from(node.p) - origin) * inv_direction;
    let error = (offset.abs() + step.abs() * MAX_QUANTIZED) * SLAB_ERROR;
    (step, offset - error, offset + error)
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
    /// 3 bits, set for each axis whose direction is not negative (CWBVH child-order octant).
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
        // `!(a <= b)` also rejects NaN.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        let bad_interval = !(t_min <= t_max);
        if bad_interval
            || !origin.is_finite()
            || origin.abs().max_element() > MAX_COORDINATE
            || !direction.is_finite()
            || direction.abs().max_element() < 1.0 / MAX_INV_DIRECTION
        {
            return None;
        }
        let inv = |d: f32| {
            // The sign must agree with the `< 0.0` octant test below, also for -0.0.
            if d.abs() < 1.0 / MAX_INV_DIRECTION {
                if d < 0.0 {
                    -MAX_INV_DIRECTION
                } else {
                    MAX_INV_DIRECTION
                }
            } else {
                1.0 / d
            }
        };
        let inv_direction = Vec3A::new(inv(direction.x), inv(direction.y), inv(direction.z));
        let octant_inv = (if direction.x < 0.0 { 0 } else { 4 })
            | (if direction.y < 0.0 { 0 } else { 2 })
            | (if direction.z < 0.0 { 0 } else { 1 });
        let abs = direction.abs();
        let kz = if abs.x >= abs.y && abs.x >= abs.z {
            0
        } else if abs.y >= abs.z {
            1
        } else {
            2
        };
        let kx = (kz + 1) % 3;
        let ky = (kx + 1) % 3;
        let d = direction.to_array();
        let o = origin.to_array();
        // The dominant component is never clamped, so this is exactly 1 / d[kz].
        let inv_dominant = inv_direction[kz];
        Some(TraversalRay {
            origin,
            direction,
            inv_direction,
            t_min,
            t_max,
            octant_inv,
            shear_axes: [kx, ky, kz],
            shear: Vec3::new(d[kx] * inv_dominant, d[ky] * inv_dominant, inv_dominant),
            permuted_origin: Vec3::new(o[kx], o[ky], o[kz]),
        })
    }
}

/// Per axis, the quantized entry and exit planes of all eight children: which of a child's two
/// planes a ray crosses first depends only on the direction's sign (the octant).
#[inline(always)]
pub(crate) fn entry_exit_planes(node: &CwBvhNode, octant_inv: u32) -> [(&[u8; 8], &[u8; 8]); 3] {
    let order = |non_negative: bool, min, max| if non_negative { (min, max) } else { (max, min) };
    [
        order(octant_inv & 4 != 0, &node.child_min_x, &node.child_max_x),
        order(octant_inv & 2 != 0, &node.child_min_y, &node.child_max_y),
        order(octant_inv & 1 != 0, &node.child_min_z, &node.child_max_z),
    ]
}

/// Eight plane bytes as floats.
#[inline(always)]
pub(crate) fn unpack_planes(planes: &[u8; 8]) -> [Vec4; 2] {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE2 is part of the x86_64 baseline, so the target feature is always present.
        unsafe { sse2::unpack(planes) }.map(Vec4::from)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let p = planes.map(f32::from);
        [
            Vec4::new(p[0], p[1], p[2], p[3]),
            Vec4::new(p[4], p[5], p[6], p[7]),
        ]
    }
}

/// Size of one quantization step per axis (a power of two stored as its exponent).
#[inline(always)]
pub(crate) fn quantization_step(node: &CwBvhNode) -> Vec3A {
    Vec3A::new(
        f32::from_bits((node.e[0] as u32) << 23),
        f32::from_bits((node.e[1] as u32) << 23),
        f32::from_bits((node.e[2] as u32) << 23),
    )
}

/// Bit `i` is set if child box `i` overlaps the ray's `[t_min, t_max]` (bits of empty child
/// slots are meaningless and must be ignored by the caller).
#[inline(always)]
pub(crate) fn child_box_hits(node: &CwBvhNode, ray: &TraversalRay) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::accel::isa::avx2_selected() {
            // SAFETY: AVX2 is selected only on CPUs that have AVX2 and FMA.
            return unsafe { avx2::child_box_hits(node, ray) };
        }
        // SAFETY: SSE2 is part of the x86_64 baseline, so the target feature is always present.
        unsafe { sse2::child_box_hits(node, ray) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        child_box_hits_portable(node, ray)
    }
}

/// The single-ray box test with AVX2 and FMA (selected at run time, `crate::accel::isa`): a
/// node's eight children in one vector instead of two. Conservative like the baseline's (a
/// fused multiply-add rounds once where the baseline rounds twice, inside the same error
/// margins), so every box the baseline reaches with a hit is reached here, and the same leaves
/// give the same hits.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use crate::accel::wide_bvh::{TraversalRay, entry_exit_planes, slab_parameters};
    use obvhs::cwbvh::node::CwBvhNode;
    use std::arch::x86_64::*;

    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub(crate) fn child_box_hits(node: &CwBvhNode, ray: &TraversalRay) -> u32 {
        let (step, entry_offset, exit_offset) =
            slab_parameters(node, ray.origin, ray.inv_direction);
        let planes = entry_exit_planes(node, ray.octant_inv);
        let mut near = _mm256_set1_ps(ray.t_min);
        let mut far = _mm256_set1_ps(ray.t_max);
        let eight = |planes: &[u8; 8]| {
            _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_set_epi64x(
                0,
                i64::from_le_bytes(*planes),
            )))
        };
        for (axis, (entry, exit)) in planes.iter().enumerate() {
            let axis_step = _mm256_set1_ps(step[axis]);
            let t_entry =
                _mm256_fmadd_ps(eight(entry), axis_step, _mm256_set1_ps(entry_offset[axis]));
            let t_exit = _mm256_fmadd_ps(eight(exit), axis_step, _mm256_set1_ps(exit_offset[axis]));
            near = _mm256_max_ps(near, t_entry);
            far = _mm256_min_ps(far, t_exit);
        }
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32
    }
}

/// Reference implementation of [`child_box_hits`] without intrinsics (used off x86_64 and in tests).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
pub(crate) fn child_box_hits_portable(node: &CwBvhNode, ray: &TraversalRay) -> u32 {
    let (step, entry_offset, exit_offset) = slab_parameters(node, ray.origin, ray.inv_direction);
    let planes = entry_exit_planes(node, ray.octant_inv);
    let mut mask = 0;
    for child in 0..8 {
        let mut near = ray.t_min;
        let mut far = ray.t_max;
        for (axis, (entry, exit)) in planes.iter().enumerate() {
            near = near.max(entry[child] as f32 * step[axis] + entry_offset[axis]);
            far = far.min(exit[child] as f32 * step[axis] + exit_offset[axis]);
        }
        if near <= far {
            mask |= 1 << child;
        }
    }
    mask
}

#[cfg(target_arch = "x86_64")]
mod sse2 {
    use crate::accel::wide_bvh::{TraversalRay, entry_exit_planes, slab_parameters};
    use obvhs::cwbvh::node::CwBvhNode;
    use std::arch::x86_64::*;

    /// Eight quantized plane positions as two vectors of four floats.
    #[target_feature(enable = "sse2")]
    #[inline]
    pub(crate) fn unpack(planes: &[u8; 8]) -> [__m128; 2] {
        let bytes = _mm_set_epi64x(0, i64::from_le_bytes(*planes));
        let zero = _mm_setzero_si128();
        let words = _mm_unpacklo_epi8(bytes, zero);
        [
            _mm_cvtepi32_ps(_mm_unpacklo_epi16(words, zero)),
            _mm_cvtepi32_ps(_mm_unpackhi_epi16(words, zero)),
        ]
    }

    #[target_feature(enable = "sse2")]
    #[inline]
    pub(crate) fn child_box_hits(node: &CwBvhNode, ray: &TraversalRay) -> u32 {
        let (step, entry_offset, exit_offset) =
            slab_parameters(node, ray.origin, ray.inv_direction);
        let planes = entry_exit_planes(node, ray.octant_inv);
        let mut near = [_mm_set1_ps(ray.t_min); 2];
        let mut far = [_mm_set1_ps(ray.t_max); 2];
        for (axis, (entry, exit)) in planes.iter().enumerate() {
            let axis_step = _mm_set1_ps(step[axis]);
            let axis_entry_offset = _mm_set1_ps(entry_offset[axis]);
            let axis_exit_offset = _mm_set1_ps(exit_offset[axis]);
            let entry = unpack(entry);
            let exit = unpack(exit);
            for half in 0..2 {
                let t_entry = _mm_add_ps(_mm_mul_ps(entry[half], axis_step), axis_entry_offset);
                let t_exit = _mm_add_ps(_mm_mul_ps(exit[half], axis_step), axis_exit_offset);
                near[half] = _mm_max_ps(near[half], t_entry);
                far[half] = _mm_min_ps(far[half], t_exit);
            }
        }
        let low = _mm_movemask_ps(_mm_cmple_ps(near[0], far[0])) as u32;
        let high = _mm_movemask_ps(_mm_cmple_ps(near[1], far[1])) as u32;
        low | (high << 4)
    }
}

/// Splits the box hits of a node into the CWBVH group encoding: bits 24..32 mark hit inner
/// children (bit `24 + (slot ^ octant)`, so the highest bit is the nearest child), bits 0..24
/// mark the primitive slots (relative to `primitive_base_idx`) of hit leaves.
#[inline(always)]
fn classify_hits(node: &CwBvhNode, box_hits: u32, octant_inv: u32) -> (u32, u32) {
    let mut inner = 0;
    let mut primitives = 0;
    let mut remaining = box_hits & 0xff;
    while remaining != 0 {
        let slot = remaining.trailing_zeros();
        remaining &= remaining - 1;
        let meta = node.child_meta[slot as usize] as u32;
        if node.imask & (1 << slot) != 0 {
            inner |= 1 << (24 + (slot ^ octant_inv));
        } else {
            // Leaf: unary primitive count in the top three bits, first primitive in the low five.
            primitives |= (meta >> 5) << (meta & 31);
        }
    }
    (inner, primitives)
}

/// Children of one node still to visit: `bits` 24..32 as in [`classify_hits`], bits 0..8 the
/// node's inner-child mask (needed to turn a slot into a node index).
#[derive(Clone, Copy, Default)]
pub(crate) struct NodeGroup {
    pub first_child: u32,
    pub bits: u32,
}

const INLINE_STACK: usize = 32;

/// Traversal stack; a well-formed CWBVH needs one entry per level, so the heap is only touched
/// for pathologically deep trees.
pub(crate) struct GroupStack<T> {
    inline: [T; INLINE_STACK],
    len: usize,
    spill: Vec<T>,
}

impl<T: Copy + Default> GroupStack<T> {
    #[inline(always)]
    pub fn new() -> GroupStack<T> {
        GroupStack {
            inline: [T::default(); INLINE_STACK],
            len: 0,
            spill: Vec::new(),
        }
    }

    #[inline(always)]
    pub fn push(&mut self, group: T) {
        if self.len < INLINE_STACK {
            self.inline[self.len] = group;
            self.len += 1;
        } else {
            self.spill.push(group);
        }
    }

    #[inline(always)]
    pub fn pop(&mut self) -> Option<T> {
        if let Some(group) = self.spill.pop() {
            Some(group)
        } else if self.len > 0 {
            self.len -= 1;
            Some(self.inline[self.len])
        } else {
            None
        }
    }
}

/// Walks the BVH and calls `test_primitive(slot, ray)` for every primitive slot in a leaf whose
/// box the ray overlaps. The callback returns whether it accepted a hit; for closest-hit use it
/// must then shrink `ray.t_max` to the hit. With `ANY_HIT` the walk stops at the first accepted
/// hit. Returns whether any hit was accepted.
#[inline(always)]
pub(crate) fn traverse<const ANY_HIT: bool, F>(
    nodes: &[CwBvhNode],
    ray: &mut TraversalRay,
    mut test_primitive: F,
) -> bool
where
    F: FnMut(u32, &mut TraversalRay) -> bool,
{
    if nodes.is_empty() {
        return false;
    }
    let octant_inv = ray.octant_inv;
    let mut stack: GroupStack<NodeGroup> = GroupStack::new();
    // The root is the only "child" of a virtual group whose inner mask is empty.
    let mut group = NodeGroup {
        first_child: 0,
        bits: 1 << 31,
    };
    let mut found = false;
    loop {
        if group.bits & 0xff00_0000 == 0 {
            match stack.pop() {
                Some(next) => group = next,
                None => break,
            }
        }
        let bit = 31 - group.bits.leading_zeros();
        group.bits &= !(1 << bit);
        let slot = (bit - 24) ^ octant_inv;
        let inner_before_slot = group.bits & 0xff & ((1 << slot) - 1);
        let node = &nodes[(group.first_child + inner_before_slot.count_ones()) as usize];
        if group.bits & 0xff00_0000 != 0 {
            stack.push(group);
        }

        let (inner, mut primitives) = classify_hits(node, child_box_hits(node, ray), octant_inv);
        if inner != 0 {
            // The children are fetched next; start loading them while the leaves are tested.
            prefetch(&nodes[node.child_base_idx as usize]);
        }
        group = NodeGroup {
            first_child: node.child_base_idx,
            bits: inner | node.imask as u32,
        };
        while primitives != 0 {
            let offset = 31 - primitives.leading_zeros();
            primitives &= !(1 << offset);
            if test_primitive(node.primitive_base_idx + offset, ray) {
                found = true;
                if ANY_HIT {
                    return true;
                }
            }
        }
    }
    found
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
