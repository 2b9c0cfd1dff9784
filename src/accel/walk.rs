//! The generic single-ray walk over [`WideNode`]s, and what every walk shares.
//!
//! [`TraversalRay`] is a ray prepared for traversal (inverse direction, octant, the watertight
//! triangle test's shear). The box test computes each slab distance as
//! `(plane - origin) * inverse_direction`: two roundings of a value, so its relative error is
//! bounded (three half-ulps with the rounded inverse), and widening a child's entry and exit
//! distances by [`SLAB_ERROR`] of their own magnitude keeps every box that holds a primitive
//! hit in `[t_min, t_max]`, also for rays that meet it exactly on a face, edge or corner or
//! run almost parallel to an axis. Every instruction-set path performs the same operations in
//! the same order (no fused multiply-adds), so each finds the same children, in the same
//! order, and the same hits. [`traverse`] is the reference walk every primitive kind can use;
//! the single-ray and packet walks (`single_ray`, `packet`) share its ray, tables, stack and
//! prefetches.

use glam::{Vec3, Vec3A, Vec3Swizzles, Vec4};

use crate::accel::MAX_COORDINATE;
use crate::accel::wide_bvh::{LEAF_BIT, WideNode};

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
/// `MAX_COORDINATE` (which also bounds ray origins) and `wide_bvh::EMPTY_PLANE` it keeps every slab
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
    /// Children are visited nearest-first in slots `i ^ node.orders[order]`, `i = 0..8`.
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
    use crate::accel::isa::Isa;
    use crate::accel::isa::selected;
    match selected() {
        // SAFETY: a path is selected only on CPUs that have it.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { avx2::child_hits_avx512(node, ray, t_min, t_max) },
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { avx2::child_hits_avx2(node, ray, t_min, t_max) },
        _ => child_hits_four_wide(node, ray, t_min, t_max),
    }
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

/// The box test with AVX2 (compiled for AVX-512 too), chosen at run time (`crate::isa`): a
/// node's eight children in one vector, in the same operations as the four-wide test (no fused
/// multiply-adds), so it reaches the same children.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    use super::{BoxRay, SLAB_ERROR, WideNode};
    use std::arch::x86_64::*;

    /// The lanes whose interval `[near, far]` holds something once both ends are widened by
    /// `SLAB_ERROR` of their magnitude, and the widened entries: the end of this walk's box
    /// test, shared with the walk of eight rays over a top level (`top_eights`), which must
    /// reach the boxes this walk reaches.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn widened_hits(near: __m256, far: __m256) -> (u32, __m256) {
        let error = _mm256_set1_ps(SLAB_ERROR);
        let sign = _mm256_set1_ps(-0.0);
        let near = _mm256_sub_ps(near, _mm256_mul_ps(_mm256_andnot_ps(sign, near), error));
        let far = _mm256_add_ps(far, _mm256_mul_ps(_mm256_andnot_ps(sign, far), error));
        let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
        (mask, near)
    }

    crate::isa::avx2_and_avx512! {
        #[inline]
        pub(crate) fn [child_hits_avx2, child_hits_avx512](
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
            let (mask, near) = widened_hits(near, far);
            let mut nears = [0.0f32; 8];
            // SAFETY: `nears` holds eight floats.
            unsafe { _mm256_storeu_ps(nears.as_mut_ptr(), near) };
            (mask, nears)
        }
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
/// the ray reaches within `[t_min, t_max]` (see `wide_bvh::leaf_range`). The callback returns whether it
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

/// The closest-hit [`traverse`] of the subtree at inner node `root` (the walk of eights over a
/// scene's top level hands a subtree that few of its rays reach to each of them alone).
#[inline(always)]
pub(crate) fn traverse_from<F>(nodes: &[WideNode], ray: &mut TraversalRay, root: u32, test_leaf: F)
where
    F: FnMut(u32, &mut TraversalRay) -> bool,
{
    let mut test_leaf = test_leaf;
    walk_from::<RuntimeBoxTest, false, F>(nodes, ray, root, &mut test_leaf);
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
    walk_from::<B, ANY_HIT, L>(nodes, ray, 0, test_leaf)
}

/// [`traverse_with`] from the node `root` of a non-empty `nodes`.
#[inline(always)]
fn walk_from<B: BoxTest, const ANY_HIT: bool, L: LeafTest>(
    nodes: &[WideNode],
    ray: &mut TraversalRay,
    root: u32,
    test_leaf: &mut L,
) -> bool {
    let box_ray = BoxRay::new(ray);
    let order = box_ray.order;
    let mut stack: TraversalStack<(u32, f32)> = TraversalStack::new();
    let mut found = false;
    let mut code = root;
    loop {
        if code & LEAF_BIT == 0 {
            let node = &nodes[code as usize];
            let (mask, nears) = B::child_hits(node, &box_ray, ray.t_min, ray.t_max);
            if mask != 0 {
                let order = usize::from(node.orders[order]);
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

/// Starts loading every cache line of a node: 256 bytes aligned to 64, four lines at bytes 0,
/// 64, 128 and 192 (plane rows 0, 2 and 4, the child codes and orders).
#[inline(always)]
pub(crate) fn prefetch_node(node: &WideNode) {
    prefetch(&node.planes[0]);
    prefetch(&node.planes[2]);
    prefetch(&node.planes[4]);
    prefetch(&node.children);
}

/// Hints the CPU to start loading the cache line of `address`, which may point anywhere (a
/// prefetch never faults; no-op off x86_64).
#[inline(always)]
pub(crate) fn prefetch_address(address: *const u8) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // SAFETY: SSE is part of the x86_64 baseline, and a prefetch never faults or changes
        // memory, whatever the address.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(address.cast::<i8>()) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = address;
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
