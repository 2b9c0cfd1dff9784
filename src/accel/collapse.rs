//! The collapse of a binary BVH into [`WideNode`]s: a plan by surface-area cost of which
//! binary subtrees become wide nodes and leaves ([`slot_costs`], after Ylitie et al. 2017), the
//! collapse that follows it in parallel, and the placement of children in slots for
//! nearest-first visits (slots `i ^ orders[octant]`, [`WideNode::orders`]).

use glam::Vec4;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use rayon::iter::{
    IndexedParallelIterator, IntoParallelIterator, IntoParallelRefIterator, ParallelIterator,
};
use std::sync::atomic::AtomicU64;
use std::sync::atomic::Ordering::Relaxed;

use crate::accel::walk::prefetch;
use crate::accel::wide_bvh::{
    IDENTITY_ORDERS, LEAF_BIT, LeafAlignment, LeafSizing, MAX_PRIMS_PER_LEAF, PADDING, WIDTH,
    WideNode, leaf_code, occupied,
};

/// Marks an empty slot in [`assign_slots`]' and [`assign_slots_by_octant`]'s results.
const EMPTY_SLOT: u8 = u8::MAX;

/// Surface-area cost of a leaf (group) test relative to a wide node visit, in
/// [`slot_costs`]: a group of up to four triangles is tested together in SIMD lanes, so the
/// cost is the same whatever the count. Tuned on the kernel bench (2, 3, 4 and 6 tried, each
/// with [`NODE_MEMORY_COST`] holding memory level); it stands for more than the test itself,
/// as a leaf hit also ends in the hit's bookkeeping.
const LEAF_TEST_COST: f32 = 4.0;

/// A wide node's memory (224 bytes when this was tuned, 256 since 2026-11-28) as a
/// surface-area cost in [`slot_costs`], in half areas of the root's box per primitive (about
/// the area a bottom node spends per triangle on a surface): without it, leaf costs alone
/// spread leaf-sized subtrees over more nodes (1M triangles, leaf test cost 2: +12 % nodes,
/// +1.9 bytes per triangle).
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
    let mut node = WideNode::default();
    // Trees of whole leaves (triangles, quads) take the nodes' own orders; the others (top
    // levels, spheres, tubes, procedural primitives) keep the octant's, so that exact ties
    // between placements or such primitives resolve as before 2026-11-28.
    let (slots, orders) = match sizing {
        LeafSizing::Whole => assign_slots(children),
        LeafSizing::Split => (
            assign_slots_by_octant(children, binary[binary_index].aabb()),
            IDENTITY_ORDERS,
        ),
    };
    node.orders = orders;
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

/// Assigns children to the eight slots of a node visited in the octant's order (slots
/// `i ^ (7 - o)` for a ray of octant `o`, [`IDENTITY_ORDERS`]) so that near children come
/// first: slot `s` prefers the child that comes first along the direction whose signs are the
/// bits of `s` (set = negative). Returns, per slot,
/// the position of its child in `children` or [`EMPTY_SLOT`].
fn assign_slots_by_octant(children: &[Candidate], parent: &Aabb) -> [u8; WIDTH] {
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

/// Places children in slots for nearest-first visits and returns, per slot, the position of
/// its child in `children` (or [`EMPTY_SLOT`]) and the node's visiting orders
/// ([`WideNode::orders`]).
///
/// A three-level split of the children's centres: slot bit 2 halves them along the axis they
/// spread most, bit 1 halves each half along the axis the halves spread most, bit 0 each pair
/// likewise; a ray then visits, at every level, the half nearer along that level's axis first
/// (slot `i ^ orders[order]`). The order `i ^ octant` of slot bits tied to x, y, z (before
/// 2026-11-28) wasted a bit on nodes whose children spread in two axes only, such as a height
/// field's (docs/kernel.md, "Single rays, 2026-11-27 23:15").
fn assign_slots(children: &[Candidate]) -> ([u8; WIDTH], [u8; WIDTH]) {
    let centres: [[f32; 3]; WIDTH] = std::array::from_fn(|position| {
        children
            .get(position)
            .map_or([0.0; 3], |child| child.aabb.center().to_array())
    });
    // Positions in slot order; the parts of level `level` are runs of `2^level` slots, each
    // holding its children first, then empty slots.
    let mut positions = [EMPTY_SLOT; WIDTH];
    for (position, slot) in positions.iter_mut().enumerate().take(children.len()) {
        *slot = position as u8;
    }
    let mut axes = [0usize; 3];
    for level in (0..3).rev() {
        let part = 2 << level;
        // The parts' spreads of centres per axis, summed.
        let mut spread = [0.0f32; 3];
        for run in positions.chunks(part) {
            let filled = &run[..run.iter().take_while(|&&p| p != EMPTY_SLOT).count()];
            for (axis, spread) in spread.iter_mut().enumerate() {
                let (low, high) =
                    filled
                        .iter()
                        .fold((f32::INFINITY, f32::NEG_INFINITY), |(low, high), &p| {
                            let c = centres[p as usize][axis];
                            (low.min(c), high.max(c))
                        });
                if filled.len() > 1 {
                    *spread += high - low;
                }
            }
        }
        let axis = (1..3).fold(0, |best, axis| {
            if spread[axis] > spread[best] {
                axis
            } else {
                best
            }
        });
        axes[level] = axis;
        let half = 1 << level;
        for run in positions.chunks_mut(part) {
            let count = run.iter().take_while(|&&p| p != EMPTY_SLOT).count();
            run[..count]
                .sort_by(|&a, &b| centres[a as usize][axis].total_cmp(&centres[b as usize][axis]));
            // The lower half first; neither half larger than its slots.
            let lower = count.div_ceil(2).max(count.saturating_sub(half));
            let mut split = [EMPTY_SLOT; WIDTH];
            split[..lower].copy_from_slice(&run[..lower]);
            split[half..half + count - lower].copy_from_slice(&run[lower..count]);
            run.copy_from_slice(&split[..part]);
        }
    }
    let mut orders = [0u8; WIDTH];
    for (order, mask) in orders.iter_mut().enumerate() {
        for (level, &axis) in axes.iter().enumerate() {
            // Order bit `2 - axis` is set for rays going down `axis`: the upper half first.
            *mask |= (((order >> (2 - axis)) & 1) as u8) << level;
        }
    }
    (positions, orders)
}
