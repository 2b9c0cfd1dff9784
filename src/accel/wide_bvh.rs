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
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};

use crate::accel::MAX_COORDINATE;
use rayon::iter::{IntoParallelRefIterator, ParallelIterator};

/// CWBVH leaves hold at most three primitives.
const MAX_PRIMS_PER_LEAF: u32 = 3;

/// Builds a wide BVH over `boxes`. Returns the nodes and, for every primitive slot the leaves
/// refer to, the index into `boxes` it stands for (callers reorder their primitives by it).
/// `boxes` must be finite; an empty input gives no nodes.
///
/// obvhs builds the binary BVH (PLOC with search distance 2 plus 1% reinsertion, parallel
/// through rayon with obvhs' `parallel` feature); [`collapse_to_wide`] then packs it into
/// obvhs' CWBVH node format. obvhs' own converter optimizes the collapse by dynamic
/// programming and costs about as much as the binary build (~300 ms for 1M triangles, single
/// threaded); the greedy collapse runs in parallel and takes roughly half that, for a BVH that
/// traces single rays a few percent slower.
pub(crate) fn build_wide_bvh(boxes: &[Aabb]) -> (Vec<CwBvhNode>, Vec<u32>) {
    if boxes.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let indices: Vec<u32> = (0..boxes.len() as u32).collect();
    let mut bvh2 = PlocBuilder::with_capacity(boxes.len()).build(
        PlocSearchDistance::VeryLow,
        boxes,
        indices,
        SortPrecision::U64,
        1,
    );
    ReinsertionOptimizer::default().run(&mut bvh2, 0.01, None);
    collapse_to_wide(&bvh2)
}

/// Packs a binary BVH (one primitive per leaf) into CWBVH nodes: each wide node takes its
/// binary node's two children and keeps opening the child with the largest surface area
/// until it has eight; subtrees of at most three primitives become leaves. The subtrees
/// below the root are collapsed in parallel on the current rayon pool.
pub(crate) fn collapse_to_wide(bvh2: &Bvh2) -> (Vec<CwBvhNode>, Vec<u32>) {
    if bvh2.nodes.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let mut primitive_order = Vec::new();
    let (mut root, inner_children) = wide_node(bvh2, 0, &mut primitive_order);
    let subtrees: Vec<(Vec<CwBvhNode>, Vec<u32>)> = inner_children
        .par_iter()
        .map(|&child| collapse_subtree(bvh2, child))
        .collect();

    // Layout: root, its inner children's roots side by side (CWBVH addresses inner children
    // as `child_base_idx + rank`), then each child's descendants.
    let total_nodes = 1 + subtrees.iter().map(|(nodes, _)| nodes.len()).sum::<usize>();
    let mut nodes = Vec::with_capacity(total_nodes);
    root.child_base_idx = 1;
    root.primitive_base_idx = 0;
    nodes.push(root);
    nodes.extend(subtrees.iter().map(|(sub_nodes, _)| sub_nodes[0]));
    primitive_order.reserve(bvh2.primitive_indices.len());
    for (rank, (sub_nodes, sub_primitives)) in subtrees.iter().enumerate() {
        // Subtree node j >= 1 moves to descendant_base + j - 1.
        let descendant_base = nodes.len() as u32;
        let primitive_base = primitive_order.len() as u32;
        let relocate = |mut node: CwBvhNode| {
            node.child_base_idx = (node.child_base_idx + descendant_base).saturating_sub(1);
            node.primitive_base_idx += primitive_base;
            node
        };
        nodes[1 + rank] = relocate(sub_nodes[0]);
        nodes.extend(sub_nodes[1..].iter().map(|node| relocate(*node)));
        primitive_order.extend_from_slice(sub_primitives);
    }
    (nodes, primitive_order)
}

/// Collapses the binary subtree at `binary_root` into a node array with its root at 0.
fn collapse_subtree(bvh2: &Bvh2, binary_root: usize) -> (Vec<CwBvhNode>, Vec<u32>) {
    let mut nodes = vec![CwBvhNode::default()];
    let mut primitive_order = Vec::new();
    // (wide node index, binary node it stands for)
    let mut pending = vec![(0usize, binary_root)];
    while let Some((wide_index, binary_index)) = pending.pop() {
        let (mut node, inner_children) = wide_node(bvh2, binary_index, &mut primitive_order);
        // Inner children get consecutive nodes in slot order.
        node.child_base_idx = nodes.len() as u32;
        for child in inner_children {
            pending.push((nodes.len(), child));
            nodes.push(CwBvhNode::default());
        }
        nodes[wide_index] = node;
    }
    (nodes, primitive_order)
}

/// One wide node for `binary_index`: child boxes, leaves (their primitives are appended to
/// `primitive_order`, starting at the node's `primitive_base_idx`) and, in slot order, the
/// binary nodes of its inner children. `child_base_idx` is left for the caller.
fn wide_node(
    bvh2: &Bvh2,
    binary_index: usize,
    primitive_order: &mut Vec<u32>,
) -> (CwBvhNode, Vec<usize>) {
    let binary = &bvh2.nodes;
    let children = wide_children(bvh2, binary_index);
    let parent_box = *binary[binary_index].aabb();
    let slots = assign_slots(bvh2, &children, &parent_box);
    let (p, exponent, step) = quantization_frame(&parent_box);
    let mut node = CwBvhNode {
        p,
        e: exponent,
        primitive_base_idx: primitive_order.len() as u32,
        ..CwBvhNode::default()
    };
    let mut inner_children = Vec::with_capacity(8);
    let mut leaf_offset = 0u32;
    for (slot, child) in slots.iter().enumerate() {
        let Some((child, leaf_count)) = *child else {
            continue;
        };
        let child_box = binary[child].aabb();
        let quantize = |axis: usize| {
            // Exact in f64: f32 differences and power-of-two divisions do not round.
            let origin = node.p[axis] as f64;
            let low = ((child_box.min[axis] as f64 - origin) / step[axis])
                .clamp(0.0, MAX_QUANTIZED as f64);
            let high = ((child_box.max[axis] as f64 - origin) / step[axis])
                .clamp(0.0, MAX_QUANTIZED as f64);
            // Truncation is floor for these non-negative values (and avoids a libm call).
            let low_q = low as u8;
            let high_q = high as u8;
            let high_q = if (high_q as f64) < high {
                high_q + 1
            } else {
                high_q
            };
            (low_q, high_q)
        };
        (node.child_min_x[slot], node.child_max_x[slot]) = quantize(0);
        (node.child_min_y[slot], node.child_max_y[slot]) = quantize(1);
        (node.child_min_z[slot], node.child_max_z[slot]) = quantize(2);
        if leaf_count.is_some() {
            let before = primitive_order.len();
            collect_primitives(bvh2, child, primitive_order);
            let count = (primitive_order.len() - before) as u32;
            node.child_meta[slot] = (leaf_offset | (((1 << count) - 1) << 5)) as u8;
            leaf_offset += count;
        } else {
            node.imask |= 1 << slot;
            node.child_meta[slot] = (24 + slot as u8) | 0b0010_0000;
            inner_children.push(child);
        }
    }
    (node, inner_children)
}

/// The number of primitives below binary node `index` if it fits in one leaf (at most
/// three), found by looking at no more than a handful of nodes; `None` for larger subtrees.
fn leaf_sized_count(bvh2: &Bvh2, index: usize) -> Option<u32> {
    let mut stack = [0usize; 8];
    stack[0] = index;
    let mut len = 1;
    let mut count = 0;
    while len > 0 {
        len -= 1;
        let node = &bvh2.nodes[stack[len]];
        if node.is_leaf() {
            count += node.prim_count;
            if count > MAX_PRIMS_PER_LEAF {
                return None;
            }
        } else {
            // Each pending subtree holds at least one primitive, so more than three pending
            // entries already mean too many.
            if len + 2 > MAX_PRIMS_PER_LEAF as usize {
                return None;
            }
            stack[len] = node.first_index as usize;
            stack[len + 1] = node.first_index as usize + 1;
            len += 2;
        }
    }
    Some(count)
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

/// Up to eight binary descendants that become the children of one wide node, each with its
/// primitive count if it is small enough to be a leaf.
fn wide_children(bvh2: &Bvh2, index: usize) -> Vec<(usize, Option<u32>)> {
    let binary = &bvh2.nodes;
    let node = &binary[index];
    if let Some(count) = leaf_sized_count(bvh2, index) {
        // Only for a tiny root: a single leaf child.
        return vec![(index, Some(count))];
    }
    // (binary index, surface area, primitive count if leaf-sized)
    let entry = |child: usize| {
        (
            child,
            binary[child].aabb().half_area(),
            leaf_sized_count(bvh2, child),
        )
    };
    let first = node.first_index as usize;
    let mut children = vec![entry(first), entry(first + 1)];
    while children.len() < 8 {
        // Open subtrees too large for a leaf first, then use spare slots on small ones.
        let mut best: Option<(usize, bool, f32)> = None;
        for (position, &(child, area, leaf_count)) in children.iter().enumerate() {
            if binary[child].is_leaf() {
                continue;
            }
            let must_open = leaf_count.is_none();
            let better = match best {
                None => true,
                Some((_, best_must, best_area)) => {
                    (must_open && !best_must) || (must_open == best_must && area > best_area)
                }
            };
            if better {
                best = Some((position, must_open, area));
            }
        }
        let Some((position, _, _)) = best else {
            break;
        };
        let opened = binary[children[position].0].first_index as usize;
        children[position] = entry(opened);
        children.push(entry(opened + 1));
    }
    children
        .into_iter()
        .map(|(child, _, leaf_count)| (child, leaf_count))
        .collect()
}

/// Assigns children to the eight slots so that, for a ray of octant `o`, the traversal order
/// `slot ^ (7 - o)` visits near children first: slot `s` prefers the child that comes first
/// along the direction whose signs are the bits of `s` (set = negative).
fn assign_slots<T: Copy>(
    bvh2: &Bvh2,
    children: &[(usize, T)],
    parent: &Aabb,
) -> [Option<(usize, T)>; 8] {
    let centre = parent.center();
    // costs[child][slot]: how far along slot's direction the child's centre lies.
    let mut costs = [[f32::INFINITY; 8]; 8];
    for (i, &(child, _)) in children.iter().enumerate().take(8) {
        let offset = bvh2.nodes[child].aabb().center() - centre;
        for (slot, cost) in costs[i].iter_mut().enumerate() {
            let direction = Vec3A::new(
                if slot & 4 != 0 { -1.0 } else { 1.0 },
                if slot & 2 != 0 { -1.0 } else { 1.0 },
                if slot & 1 != 0 { -1.0 } else { 1.0 },
            );
            *cost = offset.dot(direction);
        }
    }
    // Greedy: repeatedly place the (child, slot) pair with the lowest cost.
    let mut slots = [None; 8];
    let mut placed = [false; 8];
    for _ in 0..children.len().min(8) {
        let mut best = (f32::INFINITY, 0, 0);
        for (i, row) in costs.iter().enumerate().take(children.len()) {
            if placed[i] {
                continue;
            }
            for (slot, &cost) in row.iter().enumerate() {
                if slots[slot].is_none() && (cost < best.0 || best.0 == f32::INFINITY) {
                    best = (cost, i, slot);
                }
            }
        }
        let (_, i, slot) = best;
        slots[slot] = Some(children[i]);
        placed[i] = true;
    }
    slots
}

/// Node origin, exponent bytes and the power-of-two step they encode (so that 255 steps
/// span the box on every axis).
fn quantization_frame(parent: &Aabb) -> (Vec3, [u8; 3], [f64; 3]) {
    let mut exponent = [0u8; 3];
    let mut step = [0.0f64; 3];
    for axis in 0..3 {
        let extent = (parent.max[axis] as f64 - parent.min[axis] as f64).max(1.0e-30);
        let mut power = (extent / MAX_QUANTIZED as f64).log2().ceil().max(-126.0);
        if extent / power.exp2() > MAX_QUANTIZED as f64 {
            power += 1.0;
        }
        step[axis] = power.exp2();
        // Biased f32 exponent, the only non-zero bits of a power of two.
        exponent[axis] = (power as i32 + 127) as u8;
    }
    (parent.min.into(), exponent, step)
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
        // SAFETY: SSE2 is part of the x86_64 baseline, so the target feature is always present.
        unsafe { sse2::child_box_hits(node, ray) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        child_box_hits_portable(node, ray)
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
