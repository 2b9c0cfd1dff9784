//! Single rays through a BVH of triangle groups: the closest-hit and any-hit walks, compiled
//! once per instruction set and per direction octant.
//!
//! The walk visits the children in the order of `walk::traverse_with` and tests leaves with
//! the same arithmetic, so it finds the same hits, ids included; what differs is the work per
//! node and per ray:
//!
//! - compiled per octant, the plane rows a ray enters and leaves children by are constant
//!   offsets into the node; the visiting order is the node's own for the octant
//!   (`WideNode::orders`, a table row chosen by a byte loaded beside the planes, off the chain);
//! - one table entry per hit mask ([`VISIT`]) holds the nearest child's slot and the other hit
//!   children's slots farthest first, so the walk descends without sorting and, with AVX2,
//!   pushes all the others with one permutation of the node's codes and one of the entry
//!   distances (two stores);
//! - the stack is two fixed arrays (codes, entry distances) checked once per node; a walk
//!   that would overflow them restarts with a larger stack on the heap (the same walk, so the
//!   same hits);
//! - the ray's values for the box test and for the triangle test are set up once per ray: on
//!   the baseline path as splats, with AVX2 as scalars broadcast where they are used (a
//!   broadcast load costs what a vector load does); the scene's ray query compiled for AVX2
//!   inlines the whole walk (`closest_triangle_slot_avx2`). The AVX-512 path is the AVX2 walks
//!   compiled with AVX-512 enabled as well (`crate::isa::avx2_and_avx512`).
//!
//! The box test computes each slab distance as `(origin - plane) * scale`, the plane being the
//! instruction's memory operand, with the widening folded into the scale: entries are scaled by
//! `-inverse_direction * (1 - SLAB_ERROR)`, exits by `-inverse_direction * (1 + SLAB_ERROR)`
//! (each rounded once, per ray). Four roundings (difference, inverse, scale, product) move a
//! distance by less than `2.1 ε` of itself and the scale by `4 ε` the other way, so positive
//! entries come out below their exact value and positive exits above it: a box holding a hit
//! within `[t_min, t_max]` is never culled, also when the ray meets it on a face, edge or
//! corner. A negative distance stays negative (its sign is exact), so with `t_min >= 0` it never
//! decides an entry (the maximum with `t_min` does) and a negative exit culls only boxes behind
//! `t_min`. Rays with `t_min < 0` take the generic walk (`walk::traverse`, the widened
//! reference test). Against `walk::child_hits` this test costs four operations fewer per
//! node and is shorter on the walk's dependency chain (node, box test, next node); it may reach
//! a few more or fewer boxes that hold no hit, so the hits are the same.

use crate::accel::primitives::{
    GROUP_LANES, GroupRay, GroupRayValues, SplatOnUse, TriangleGroup, closest_lane, group_closest,
};
use crate::accel::walk::{SLAB_ERROR, TraversalRay, prefetch_address, traverse};
use crate::accel::wide_bvh::{LEAF_BIT, WIDTH, WideNode, group_leaf};
use glam::{Vec2, Vec3, Vec3A, Vec4, Vec4Swizzles};
use std::mem::MaybeUninit;

/// `VISIT[order][mask]` for the hit children `mask` (bit per slot) of a ray whose children
/// are visited nearest-first in slots `i ^ order`: the nearest hit child's slot alone in the
/// low byte (so the walk loads it with one byte load, nothing to mask on its chain), the other
/// hit children's slots three bits each from bit [`OTHERS_SLOTS`] on, farthest first, and their
/// number from bit [`OTHERS_SHIFT`] on.
pub(crate) static VISIT: [[u32; 256]; 8] = {
    let mut table = [[0u32; 256]; 8];
    let mut order = 0;
    while order < 8 {
        let mut mask = 1;
        while mask < 256 {
            let mut nearest = 0;
            while mask & (1 << (nearest ^ order)) == 0 {
                nearest += 1;
            }
            let mut entry = (nearest ^ order) as u32;
            let mut others = 0;
            let mut position = 7;
            while position > nearest {
                if mask & (1 << (position ^ order)) != 0 {
                    entry |= ((position ^ order) as u32) << (OTHERS_SLOTS + 3 * others);
                    others += 1;
                }
                position -= 1;
            }
            table[order][mask] = entry | (others << OTHERS_SHIFT);
            mask += 1;
        }
        order += 1;
    }
    table
};

/// Where a [`VISIT`] entry keeps the slots of the children to push (seven at most, 21 bits).
const OTHERS_SLOTS: u32 = 8;

/// Where a [`VISIT`] entry keeps the number of children to push.
const OTHERS_SHIFT: u32 = 29;

/// `VISIT[order][mask]`'s address.
///
/// # Safety
/// `order < 8`, `mask < 256`.
#[inline(always)]
unsafe fn visit_entry(order: usize, mask: u32) -> *const u32 {
    // SAFETY: the caller's promise: within the table.
    unsafe {
        VISIT
            .as_ptr()
            .cast::<u32>()
            .add(order * 256 + mask as usize)
    }
}

/// The nearest hit child's slot of `VISIT[order][mask]`, read as the entry's low byte.
///
/// # Safety
/// `order < 8`, `mask < 256`.
#[inline(always)]
unsafe fn nearest_slot(order: usize, mask: u32) -> usize {
    // SAFETY: the caller's promise; the low byte of a `u32` lies at its address on
    // little-endian targets, at its last byte on big-endian ones.
    unsafe {
        let entry = visit_entry(order, mask).cast::<u8>();
        let low = if cfg!(target_endian = "little") { 0 } else { 3 };
        usize::from(*entry.add(low))
    }
}

/// Entries of the stack kept inline (the walk restarts with a larger one if it needs more).
const INLINE_STACK: usize = 128;

/// The walk's stack: codes and entry distances in two arrays of `capacity` entries. A push
/// writes eight entries at once, so a node's children are pushed only while `len + WIDTH <=
/// capacity`.
struct Stack {
    codes: *mut u32,
    nears: *mut f32,
    len: usize,
    /// The largest `len` a node's children may be pushed at.
    last_push: usize,
}

/// The stack was about to overflow; the walk must be redone with a larger one.
struct Overflow;

/// A hit: its group and lane, and the group's edge functions `V`, `W` and determinants its
/// barycentrics come from (lanes are picked once the walk is over).
#[derive(Clone, Copy)]
pub(crate) struct Hit {
    pub group: usize,
    pub lane: usize,
    pub v: Vec4,
    pub w: Vec4,
    pub determinant: Vec4,
}

impl Hit {
    /// The triangle's slot and its barycentrics `(b1, b2)`.
    #[inline(always)]
    pub(crate) fn slot_and_barycentrics(&self) -> (u32, Vec2) {
        // Lanes read from arrays (an indexed load), not by `Vec4`'s index, which branches on
        // the lane through a jump table (a mispredicted jump per hit).
        let lane_of = |lanes: Vec4| lanes.to_array()[self.lane];
        let inv = 1.0 / lane_of(self.determinant);
        let slot = (self.group * GROUP_LANES + self.lane) as u32;
        // Both products in one vector (each lane the scalar product), so that the pair is
        // written with one store: the caller may read it back as one 8-byte load, which two
        // 4-byte stores could not forward (a stall per hit).
        let bary = (Vec4::new(lane_of(self.v), lane_of(self.w), 0.0, 0.0) * inv).xy();
        (slot, bary)
    }
}

/// An instruction set's box test and push.
trait Lanes {
    /// What the box test needs of the ray.
    type BoxRay: Copy;
    /// The widened entry distances of a node's children.
    type Nears: Copy;
    /// What the triangle test needs of the ray.
    type GroupRay<'a>: GroupRayValues;
    /// Whether the walk reads the caller's ray field by field into a copy first (see
    /// [`field_by_field`]); a path that reads each field once at most, no wider than it was
    /// written, needs no copy.
    const COPIES_RAY: bool;

    fn box_ray(ray: &TraversalRay) -> Self::BoxRay;

    fn group_ray(ray: &TraversalRay) -> Self::GroupRay<'_>;

    /// The children hit within `[t_min, t_max]` (bit per slot) and their entry distances, for a
    /// ray whose children are visited in slots `i ^ ORDER`.
    fn child_hits<const ORDER: usize>(
        node: &WideNode,
        ray: &Self::BoxRay,
        t_max: f32,
    ) -> (u32, Self::Nears);

    /// Pushes `count` children (slots three bits each in `slots`, first pushed first).
    ///
    /// # Safety
    /// `stack.len <= stack.last_push`.
    unsafe fn push(node: &WideNode, slots: u32, count: u32, nears: Self::Nears, stack: &mut Stack);
}

/// The plane rows of axis `axis` through which a ray of visiting order `order` enters and
/// leaves children (`order` has bit `2 - axis` set for a negative direction).
#[inline(always)]
pub(crate) const fn rows(order: usize, axis: usize) -> (usize, usize) {
    if (order >> (2 - axis)) & 1 != 0 {
        (2 * axis + 1, 2 * axis)
    } else {
        (2 * axis, 2 * axis + 1)
    }
}

/// The baseline path: the box test four children at a time (SSE2 on x86_64 through glam).
struct FourWide;

#[derive(Clone, Copy)]
struct FourWideRay {
    origin: [Vec4; 3],
    /// `-inverse_direction` scaled by `1 - SLAB_ERROR` (entries) and `1 + SLAB_ERROR` (exits).
    entry_scale: [Vec4; 3],
    exit_scale: [Vec4; 3],
    t_min: Vec4,
}

/// Per axis the scales of a ray's entry and exit distances (see the module's notes).
#[inline(always)]
pub(crate) fn slab_scales(ray: &TraversalRay) -> [[f32; 3]; 2] {
    let negated_inverse = -ray.inv_direction;
    [
        (negated_inverse * (1.0 - SLAB_ERROR)).to_array(),
        (negated_inverse * (1.0 + SLAB_ERROR)).to_array(),
    ]
}

impl Lanes for FourWide {
    type BoxRay = FourWideRay;
    type Nears = [f32; WIDTH];
    type GroupRay<'a> = GroupRay;
    const COPIES_RAY: bool = true;

    #[inline(always)]
    fn group_ray(ray: &TraversalRay) -> GroupRay {
        GroupRay::new(ray)
    }

    #[inline(always)]
    fn box_ray(ray: &TraversalRay) -> FourWideRay {
        let [entry_scale, exit_scale] = slab_scales(ray);
        FourWideRay {
            origin: ray.origin.to_array().map(Vec4::splat),
            entry_scale: entry_scale.map(Vec4::splat),
            exit_scale: exit_scale.map(Vec4::splat),
            t_min: Vec4::splat(ray.t_min),
        }
    }

    #[inline(always)]
    fn child_hits<const ORDER: usize>(
        node: &WideNode,
        ray: &FourWideRay,
        t_max: f32,
    ) -> (u32, [f32; WIDTH]) {
        let mut nears = [0.0f32; WIDTH];
        let mut mask = 0;
        for half in 0..2 {
            let lanes = 4 * half..4 * half + 4;
            let distances = |axis: usize| {
                let (entry, exit) = rows(ORDER, axis);
                let plane = |row: usize| Vec4::from_slice(&node.planes[row][lanes.clone()]);
                let origin = ray.origin[axis];
                (
                    (origin - plane(entry)) * ray.entry_scale[axis],
                    (origin - plane(exit)) * ray.exit_scale[axis],
                )
            };
            let (near_x, far_x) = distances(0);
            let (near_y, far_y) = distances(1);
            let (near_z, far_z) = distances(2);
            let near = near_x.max(near_y).max(near_z.max(ray.t_min));
            let far = far_x.min(far_y).min(far_z.min(Vec4::splat(t_max)));
            mask |= near.cmple(far).bitmask() << (4 * half);
            near.write_to_slice(&mut nears[lanes]);
        }
        (mask, nears)
    }

    #[inline(always)]
    unsafe fn push(
        node: &WideNode,
        slots: u32,
        count: u32,
        nears: [f32; WIDTH],
        stack: &mut Stack,
    ) {
        for index in 0..count as usize {
            let slot = ((slots >> (3 * index)) & 7) as usize;
            // SAFETY: `count < WIDTH` and `stack.len + WIDTH <= capacity` (the caller's
            // promise).
            unsafe {
                *stack.codes.add(stack.len + index) = node.children[slot];
                *stack.nears.add(stack.len + index) = nears[slot];
            }
        }
        stack.len += count as usize;
    }
}

/// The AVX2 path: the box test eight children at a time and pushes by permutation. Only walks
/// compiled for AVX2 or AVX-512 (entered only when that path is selected) use it.
#[cfg(target_arch = "x86_64")]
struct Avx2;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{SLAB_ERROR, Stack, TraversalRay, Vec3A, WideNode, rows};
    use std::arch::x86_64::*;

    /// The box test's per-ray values as scalars: the test broadcasts each where it uses it (a
    /// broadcast load costs what a vector load does), so setting a ray up takes four stores
    /// instead of ten broadcasts and ten stores.
    #[derive(Clone, Copy)]
    #[repr(C, align(16))]
    pub(super) struct Avx2Ray {
        origin: [f32; 4],
        entry_scale: [f32; 4],
        exit_scale: [f32; 4],
        t_min: f32,
    }

    #[inline(always)]
    pub(super) fn box_ray(ray: &TraversalRay) -> Avx2Ray {
        // The arithmetic of `slab_scales`, kept in vectors.
        let negated_inverse = -ray.inv_direction;
        let lanes = |v: Vec3A| v.extend(0.0).to_array();
        Avx2Ray {
            origin: lanes(ray.origin),
            entry_scale: lanes(negated_inverse * (1.0 - SLAB_ERROR)),
            exit_scale: lanes(negated_inverse * (1.0 + SLAB_ERROR)),
            // SAFETY: a reference is valid and aligned for reads. Volatile: never merged with
            // its neighbours into a wider load than the caller's stores (see `field_by_field`).
            t_min: unsafe { std::ptr::read_volatile(&ray.t_min) },
        }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    fn distances(node: &WideNode, ray: &Avx2Ray, axis: usize, rows: (usize, usize)) -> [__m256; 2] {
        let origin = _mm256_broadcast_ss(&ray.origin[axis]);
        let (entry_scale, exit_scale) = (
            _mm256_broadcast_ss(&ray.entry_scale[axis]),
            _mm256_broadcast_ss(&ray.exit_scale[axis]),
        );
        // SAFETY: every plane row is eight floats, 32-byte aligned (`WideNode` is).
        let (entry, exit) = unsafe {
            (
                _mm256_load_ps(node.planes[rows.0].as_ptr()),
                _mm256_load_ps(node.planes[rows.1].as_ptr()),
            )
        };
        [
            _mm256_mul_ps(_mm256_sub_ps(origin, entry), entry_scale),
            _mm256_mul_ps(_mm256_sub_ps(origin, exit), exit_scale),
        ]
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn child_hits<const ORDER: usize>(
        node: &WideNode,
        ray: &Avx2Ray,
        t_max: f32,
    ) -> (u32, __m256) {
        let [near_x, far_x] = distances(node, ray, 0, rows(ORDER, 0));
        let [near_y, far_y] = distances(node, ray, 1, rows(ORDER, 1));
        let [near_z, far_z] = distances(node, ray, 2, rows(ORDER, 2));
        let near = _mm256_max_ps(
            _mm256_max_ps(near_x, near_y),
            _mm256_max_ps(near_z, _mm256_broadcast_ss(&ray.t_min)),
        );
        let far = _mm256_min_ps(
            _mm256_min_ps(far_x, far_y),
            _mm256_min_ps(far_z, _mm256_set1_ps(t_max)),
        );
        let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
        (mask, near)
    }

    /// Writes all eight permuted entries; `count` of them are kept.
    ///
    /// # Safety
    /// `stack.len + 8` entries fit the stack.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn push(
        node: &WideNode,
        slots: u32,
        count: u32,
        nears: __m256,
        stack: &mut Stack,
    ) {
        let shifts = _mm256_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21);
        // The permutations read the low three bits of each lane: the slot.
        let slots = _mm256_srlv_epi32(_mm256_set1_epi32(slots as i32), shifts);
        // SAFETY: the codes are eight u32, 32-byte aligned (`WideNode` is, and they follow six
        // plane rows of 32 bytes); the stores stay within the stack (the caller's promise).
        unsafe {
            let codes = _mm256_load_si256(node.children.as_ptr().cast());
            _mm256_storeu_si256(
                stack.codes.add(stack.len).cast(),
                _mm256_permutevar8x32_epi32(codes, slots),
            );
            _mm256_storeu_ps(
                stack.nears.add(stack.len),
                _mm256_permutevar8x32_ps(nears, slots),
            );
        }
        stack.len += count as usize;
    }
}

#[cfg(target_arch = "x86_64")]
impl Lanes for Avx2 {
    type BoxRay = avx2::Avx2Ray;
    type Nears = std::arch::x86_64::__m256;
    type GroupRay<'a> = SplatOnUse<'a>;
    const COPIES_RAY: bool = false;

    #[inline(always)]
    fn box_ray(ray: &TraversalRay) -> avx2::Avx2Ray {
        avx2::box_ray(ray)
    }

    #[inline(always)]
    fn group_ray(ray: &TraversalRay) -> SplatOnUse<'_> {
        SplatOnUse::new(ray)
    }

    #[inline(always)]
    fn child_hits<const ORDER: usize>(
        node: &WideNode,
        ray: &avx2::Avx2Ray,
        t_max: f32,
    ) -> (u32, Self::Nears) {
        // SAFETY: only walks entered when AVX2 or AVX-512 is selected (so the CPU has AVX2) use
        // this path.
        unsafe { avx2::child_hits::<ORDER>(node, ray, t_max) }
    }

    #[inline(always)]
    unsafe fn push(node: &WideNode, slots: u32, count: u32, nears: Self::Nears, stack: &mut Stack) {
        // SAFETY: as in `child_hits`; the stack has room (the caller's promise).
        unsafe { avx2::push(node, slots, count, nears, stack) }
    }
}

/// Whether every code of `nodes` is in range: inner codes index `nodes`, leaf codes address
/// slots within `group_count` groups; and every node's visiting orders are below 8. The walks
/// rely on it (no bounds checks); builds assert it.
pub(crate) fn codes_in_range(nodes: &[WideNode], group_count: usize) -> bool {
    nodes.iter().all(|node| {
        node.orders.iter().all(|&order| usize::from(order) < WIDTH)
            && (0..WIDTH).all(|slot| {
                let code = node.children[slot];
                if !crate::accel::wide_bvh::occupied(node, slot) {
                    true
                } else if code & LEAF_BIT == 0 {
                    (code as usize) < nodes.len()
                } else {
                    group_leaf(code).0 < group_count
                }
            })
    })
}

/// The walk of one octant (children visited in slots `i ^ ORDER`): the closest hit within
/// `[t_min, t_max]` (with `ANY_HIT`, the first hit found), and the `t` it was found at.
///
/// `ALWAYS_PUSH` (trees larger than the last-level cache, [`LARGE_TREE_NODES`]): a node with
/// hit children pushes and prefetches whether or not it has children to push (a push of none
/// writes entries it does not keep; the prefetch then loads the child descended into), so the
/// walk does not branch on how many children were hit. That branch is mispredicted often; at
/// 4M triangles, where every node visit waits on memory, the mispredictions avoided cost more
/// than the ~30 instructions added at each node with nothing to push, on small trees they do
/// not (docs/kernel.md, 2026-11-27 21:30–22:10 UTC).
///
/// # Safety
/// `codes_in_range(nodes, groups.len())`, `nodes` not empty, and `stack.last_push + WIDTH`
/// entries behind the stack's pointers.
#[inline(always)]
unsafe fn walk<I: Lanes, const ORDER: usize, const ANY_HIT: bool, const ALWAYS_PUSH: bool>(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    box_ray: &I::BoxRay,
    group_ray: &impl GroupRayValues,
    mut t_max: f32,
    stack: &mut Stack,
    root: u32,
) -> Result<(Option<Hit>, f32), Overflow> {
    let mut found = None;
    let mut code = root;
    loop {
        if code & LEAF_BIT == 0 {
            // SAFETY: inner codes index `nodes` (the caller's promise).
            let node = unsafe { nodes.get_unchecked(code as usize) };
            let (mask, nears) = I::child_hits::<ORDER>(node, box_ray, t_max);
            if mask != 0 {
                // The node's own visiting order for this octant (loaded beside the planes, off
                // the walk's chain).
                let order = usize::from(node.orders[ORDER]);
                // The nearest child's code by its own byte load: on the walk's chain (box test,
                // mask, slot, code, next node) neither the mask nor the slot is masked first.
                // SAFETY: a mask of eight children is below 256; node orders are below 8
                // (the caller's promise, `codes_in_range`).
                code = unsafe { *node.children.get_unchecked(nearest_slot(order, mask)) };
                // SAFETY: as above.
                let visit = unsafe { *visit_entry(order, mask) };
                let others = visit >> OTHERS_SHIFT;
                if ALWAYS_PUSH {
                    if stack.len > stack.last_push {
                        return Err(Overflow);
                    }
                    // SAFETY: just checked.
                    unsafe { I::push(node, visit >> OTHERS_SLOTS, others, nears, stack) };
                    // The child popped next, or with none pushed the nearest (loading anyway).
                    let next =
                        node.children[((visit >> (OTHERS_SLOTS - 3 + 3 * others)) & 7) as usize];
                    prefetch_either(nodes, groups, next);
                } else if others != 0 {
                    if stack.len > stack.last_push {
                        return Err(Overflow);
                    }
                    // SAFETY: just checked.
                    unsafe { I::push(node, visit >> OTHERS_SLOTS, others, nears, stack) };
                    // The child popped next (the last pushed: the nearest of the others) starts
                    // loading while the walk descends into the nearest; node or group chosen
                    // without a branch (one on the leaf bit was mispredicted at ~0.15 per ray).
                    let next =
                        node.children[((visit >> (OTHERS_SLOTS - 3 + 3 * others)) & 7) as usize];
                    prefetch_either(nodes, groups, next);
                }
                continue;
            }
        } else {
            let (group_index, lanes) = group_leaf(code);
            // SAFETY: leaf codes address existing groups (the caller's promise).
            let group = unsafe { groups.get_unchecked(group_index) };
            let (hits, t, [v, w, determinant]) = group_ray.hits(group, lanes, t_max);
            if hits != 0 {
                let (lane, t) = if ANY_HIT {
                    (0, t_max)
                } else {
                    closest_lane(hits, t)
                };
                t_max = t;
                found = Some(Hit {
                    group: group_index,
                    lane,
                    v,
                    w,
                    determinant,
                });
                if ANY_HIT {
                    return Ok((found, t_max));
                }
            }
        }
        loop {
            if stack.len == 0 {
                return Ok((found, t_max));
            }
            stack.len -= 1;
            // SAFETY: entries below `len` were written by pushes.
            let near = unsafe { *stack.nears.add(stack.len) };
            if near <= t_max {
                // SAFETY: as above.
                code = unsafe { *stack.codes.add(stack.len) };
                break;
            }
        }
    }
}

/// Trees of at least this many nodes (28 MB of them, near a last-level cache) take the walk
/// with `ALWAYS_PUSH` (see [`walk`]): on the kernel bench's 4M triangles (195,302 nodes) it
/// measured 3–5 % faster; on every tree, 968 triangles took up to ~3 % longer and 1M triangles
/// (49,232 nodes) were level.
pub(crate) const LARGE_TREE_NODES: usize = 1 << 17;

/// Starts loading four cache lines from child `code`'s node (all of its lines) or group (its
/// three and the next), the address chosen without a branch. Nothing is read: the address not
/// chosen may point anywhere, and a prefetch never faults.
#[inline(always)]
fn prefetch_either(nodes: &[WideNode], groups: &[TriangleGroup], code: u32) {
    let node = nodes.as_ptr().wrapping_add(code as usize).cast::<u8>();
    let group = groups
        .as_ptr()
        .wrapping_add(group_leaf(code).0)
        .cast::<u8>();
    let start = if code & LEAF_BIT == 0 { node } else { group };
    for line in 0..4 {
        prefetch_address(start.wrapping_add(64 * line));
    }
}

/// A copy of `ray` read one field at a time. The caller wrote the ray field by field, and a
/// load spanning several of those stores waits until they reach the cache (the processor
/// cannot forward it); left alone, the compiler merged neighbouring scalar fields into such
/// vector loads. Volatile reads are never merged.
#[inline(always)]
fn field_by_field(ray: &TraversalRay) -> TraversalRay {
    fn read<T: Copy>(field: &T) -> T {
        // SAFETY: a reference is valid and aligned for reads.
        unsafe { std::ptr::read_volatile(field) }
    }
    TraversalRay {
        origin: read(&ray.origin),
        // Not read by the walk.
        direction: ray.direction,
        inv_direction: read(&ray.inv_direction),
        t_min: read(&ray.t_min),
        t_max: read(&ray.t_max),
        octant_inv: read(&ray.octant_inv),
        shear_axes: ray.shear_axes.each_ref().map(read),
        shear: Vec3::new(read(&ray.shear.x), read(&ray.shear.y), read(&ray.shear.z)),
        permuted_origin: Vec3::new(
            read(&ray.permuted_origin.x),
            read(&ray.permuted_origin.y),
            read(&ray.permuted_origin.z),
        ),
    }
}

/// [`walk`] for the ray's octant, with the inline stack and, should it overflow, again with
/// ever larger ones on the heap.
///
/// # Safety
/// `codes_in_range(nodes, groups.len())` and `nodes` not empty.
#[inline(always)]
unsafe fn walk_ray<I: Lanes, const ANY_HIT: bool, const INLINE: usize, const ALWAYS_PUSH: bool>(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &TraversalRay,
    root: u32,
) -> (Option<Hit>, f32) {
    const { assert!(INLINE >= WIDTH) };
    let copy;
    let ray = if I::COPIES_RAY {
        copy = field_by_field(ray);
        &copy
    } else {
        ray
    };
    // Both kept in memory (opaque to the optimiser), the box test's values too: the walk's
    // instructions read them as memory operands, where otherwise the compiler kept copies in
    // registers, spilled them at the start and reloaded them after every leaf (fewer cycles per
    // ray at 968 triangles, 214 -> 199, for a few more instructions).
    let box_ray = I::box_ray(ray);
    let box_ray: &I::BoxRay = std::hint::black_box(&box_ray);
    // Kept in memory (opaque to the optimiser): the leaf test then reads its values as memory
    // operands, where otherwise copies of them were spilled for the whole walk (13 fewer
    // instructions per ray at 968 triangles).
    // (A path that reads the ray in place keeps only the pointer to it opaque.)
    let group_ray = if I::COPIES_RAY {
        I::group_ray(ray)
    } else {
        I::group_ray(std::hint::black_box(ray))
    };
    let group_ray = if I::COPIES_RAY {
        std::hint::black_box(&group_ray)
    } else {
        &group_ray
    };
    // Read in place: volatile, as in `field_by_field`; a copy is read as it is.
    let (octant_inv, t_max_start) = if I::COPIES_RAY {
        (ray.octant_inv, ray.t_max)
    } else {
        // SAFETY: a reference is valid and aligned for reads.
        unsafe {
            (
                std::ptr::read_volatile(&ray.octant_inv),
                std::ptr::read_volatile(&ray.t_max),
            )
        }
    };
    let order = (7 ^ (octant_inv & 7)) as usize;
    let mut codes = [MaybeUninit::<u32>::uninit(); INLINE];
    let mut nears = [MaybeUninit::<f32>::uninit(); INLINE];
    let mut stack = Stack {
        codes: codes.as_mut_ptr().cast(),
        nears: nears.as_mut_ptr().cast(),
        len: 0,
        last_push: INLINE - WIDTH,
    };
    // Holds the stack once it has outgrown the inline one.
    let mut heap: (Vec<u32>, Vec<f32>);
    loop {
        macro_rules! octants {
            ($($order:literal)*) => {
                match order {
                    $($order => unsafe {
                        walk::<I, $order, ANY_HIT, ALWAYS_PUSH>(nodes, groups, box_ray, group_ray, t_max_start, &mut stack, root)
                    },)*
                    _ => unreachable!(),
                }
            };
        }
        // SAFETY: the caller's promise; the stack has `last_push + WIDTH` entries.
        if let Ok(done) = octants!(0 1 2 3 4 5 6 7) {
            return done;
        }
        let capacity = 4 * (stack.last_push + WIDTH);
        heap = (vec![0; capacity], vec![0.0; capacity]);
        stack = Stack {
            codes: heap.0.as_mut_ptr(),
            nears: heap.1.as_mut_ptr(),
            len: 0,
            last_push: capacity - WIDTH,
        };
    }
}

/// The AVX2 closest-hit walk of one ray through the subtree at inner node `root`, from
/// `ray.t_max` on: the hit it finds and its `t` (`ray.t_max` if none). The walk of eight rays
/// (`eights.rs`) walks a subtree that only a few of its rays reach with it, ray by ray.
///
/// # Safety
/// `codes_in_range(nodes, groups.len())`, `root` indexes `nodes`, `ray.t_min >= 0`; the caller
/// is compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) unsafe fn closest_from_avx2(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &TraversalRay,
    root: u32,
) -> (Option<Hit>, f32) {
    // SAFETY: the caller's promise.
    unsafe { walk_ray::<Avx2, false, INLINE_STACK, false>(nodes, groups, ray, root) }
}

/// The closest hit among `groups` under `nodes`: its slot and barycentrics `(b1, b2)`;
/// `ray.t_max` shrinks to it.
///
/// # Safety
/// `codes_in_range(nodes, groups.len())`.
#[inline]
pub(crate) unsafe fn closest_triangle_slot(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &mut TraversalRay,
) -> Option<(u32, Vec2)> {
    // SAFETY: the caller's promise.
    unsafe { closest_slot_on::<false>(nodes, groups, ray) }
}

/// [`closest_triangle_slot`] with the AVX2 walk inlined, for callers compiled for AVX2 (or
/// AVX-512) as a whole (one call's set-up per ray instead of two).
///
/// # Safety
/// `codes_in_range(nodes, groups.len())`; the caller is compiled for AVX2 or AVX-512 (so the
/// CPU has AVX2).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) unsafe fn closest_triangle_slot_avx2(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &mut TraversalRay,
) -> Option<(u32, Vec2)> {
    // SAFETY: the caller's promise.
    unsafe { closest_slot_on::<true>(nodes, groups, ray) }
}

/// [`closest_triangle_slot`]; `INLINE_AVX2`: the AVX2 walk inlined (only inside functions
/// compiled for AVX2 or AVX-512), else the instruction set chosen at run time.
///
/// # Safety
/// `codes_in_range(nodes, groups.len())`; with `INLINE_AVX2` the caller is compiled for AVX2
/// or AVX-512.
#[inline(always)]
unsafe fn closest_slot_on<const INLINE_AVX2: bool>(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &mut TraversalRay,
) -> Option<(u32, Vec2)> {
    if nodes.is_empty() {
        return None;
    }
    // Negative distances decide entries only for rays that may hit before their origin.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    if !(ray.t_min >= 0.0) {
        return closest_by_generic_walk(nodes, groups, ray);
    }
    #[cfg(target_arch = "x86_64")]
    use crate::isa::Isa;
    use crate::isa::selected;
    // SAFETY (each branch): the caller's promise; a path is selected only on CPUs that have it.
    let (hit, t) = if INLINE_AVX2 {
        // Large trees take their own walk (see `LARGE_TREE_NODES`; measured on this path, the
        // scene query of one placement, only).
        #[cfg(target_arch = "x86_64")]
        unsafe {
            if nodes.len() >= LARGE_TREE_NODES {
                walk_ray::<Avx2, false, INLINE_STACK, true>(nodes, groups, ray, 0)
            } else {
                walk_ray::<Avx2, false, INLINE_STACK, false>(nodes, groups, ray, 0)
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        unreachable!("the AVX2 walk is inlined only on x86-64")
    } else {
        match selected() {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe { avx2_walks::closest_avx512(nodes, groups, ray) },
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { avx2_walks::closest_avx2(nodes, groups, ray) },
            _ => unsafe { closest_baseline(nodes, groups, ray) },
        }
    };
    let hit = hit?;
    ray.t_max = t;
    Some(hit.slot_and_barycentrics())
}

/// Whether any of `groups` under `nodes` is hit.
///
/// # Safety
/// `codes_in_range(nodes, groups.len())`.
#[inline]
pub(crate) unsafe fn any_triangle_hit(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &TraversalRay,
) -> bool {
    if nodes.is_empty() {
        return false;
    }
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    if !(ray.t_min >= 0.0) {
        return any_by_generic_walk(nodes, groups, ray);
    }
    #[cfg(target_arch = "x86_64")]
    use crate::isa::Isa;
    use crate::isa::selected;
    // SAFETY (each arm): the caller's promise; a path is selected only on CPUs that have it.
    match selected() {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { avx2_walks::any_avx512(nodes, groups, ray) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { avx2_walks::any_avx2(nodes, groups, ray) },
        _ => unsafe { any_baseline(nodes, groups, ray) },
    }
}

/// The baseline path's closest-hit walk, out of line like the AVX2 one, so that its callers
/// stay small enough to be inlined into the scene's ray query.
///
/// # Safety
/// `codes_in_range(nodes, groups.len())`; `nodes` not empty.
#[inline(never)]
unsafe fn closest_baseline(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &TraversalRay,
) -> (Option<Hit>, f32) {
    // SAFETY: the caller's promise.
    unsafe { walk_ray::<FourWide, false, INLINE_STACK, false>(nodes, groups, ray, 0) }
}

/// The baseline path's any-hit walk (as [`closest_baseline`]).
///
/// # Safety
/// As [`closest_baseline`].
#[inline(never)]
unsafe fn any_baseline(nodes: &[WideNode], groups: &[TriangleGroup], ray: &TraversalRay) -> bool {
    // SAFETY: the caller's promise.
    unsafe { walk_ray::<FourWide, true, INLINE_STACK, false>(nodes, groups, ray, 0) }
        .0
        .is_some()
}

/// [`closest_triangle_slot`] for rays with `t_min < 0`: the generic walk, whose widened box
/// test holds for negative distances too (the same hits: both tests keep every box that holds
/// one, and both walks visit children in the same order).
#[cold]
#[inline(never)]
fn closest_by_generic_walk(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &mut TraversalRay,
) -> Option<(u32, Vec2)> {
    let mut closest = None;
    traverse::<false, _>(nodes, ray, |code, ray| {
        let (group, lanes) = group_leaf(code);
        let Some((lane, t, bary)) = group_closest(&groups[group], lanes, ray) else {
            return false;
        };
        ray.t_max = t;
        closest = Some(((group * GROUP_LANES + lane) as u32, bary));
        true
    });
    closest
}

/// [`any_triangle_hit`] for rays with `t_min < 0` (as [`closest_by_generic_walk`]).
#[cold]
#[inline(never)]
fn any_by_generic_walk(nodes: &[WideNode], groups: &[TriangleGroup], ray: &TraversalRay) -> bool {
    let mut ray = *ray;
    traverse::<true, _>(nodes, &mut ray, |code, ray| {
        let (group, lanes) = group_leaf(code);
        GroupRay::new(ray).hits(&groups[group], lanes, ray.t_max).0 != 0
    })
}

/// The walks compiled for AVX2, and for AVX-512 too: the eight-wide box test and push
/// inlined, the triangle test the same four-wide operations (VEX- or EVEX-encoded, no fused
/// multiply-adds).
#[cfg(target_arch = "x86_64")]
mod avx2_walks {
    use super::*;

    crate::isa::avx2_and_avx512! {
        /// # Safety
        /// The CPU has the path's features; `codes_in_range(nodes, groups.len())`; `nodes` not
        /// empty.
        pub(super) unsafe fn [closest_avx2, closest_avx512](
            nodes: &[WideNode],
            groups: &[TriangleGroup],
            ray: &TraversalRay,
        ) -> (Option<Hit>, f32) {
            // SAFETY: the caller's promise.
            unsafe { walk_ray::<Avx2, false, INLINE_STACK, false>(nodes, groups, ray, 0) }
        }
    }

    crate::isa::avx2_and_avx512! {
        /// # Safety
        /// As [`closest_avx2`].
        pub(super) unsafe fn [any_avx2, any_avx512](
            nodes: &[WideNode],
            groups: &[TriangleGroup],
            ray: &TraversalRay,
        ) -> bool {
            // SAFETY: the caller's promise.
            unsafe { walk_ray::<Avx2, true, INLINE_STACK, false>(nodes, groups, ray, 0) }
                .0
                .is_some()
        }
    }
}

/// Test hooks: the box test of every path this CPU has, and the walks with a small inline
/// stack (so that they restart on the heap).
#[cfg(test)]
pub(crate) mod test_paths {
    use super::*;
    #[cfg(target_arch = "x86_64")]
    use crate::isa::Isa;

    /// The single-ray box test of each path for `ray` (its octant's code), as
    /// `(mask, entry distances)`.
    pub(crate) fn child_hits(node: &WideNode, ray: &TraversalRay) -> Vec<(u32, [f32; WIDTH])> {
        macro_rules! octants {
            ($($order:literal)*) => {
                match (7 ^ (ray.octant_inv & 7)) as usize {
                    $($order => of_order::<$order>(node, ray),)*
                    _ => unreachable!(),
                }
            };
        }
        octants!(0 1 2 3 4 5 6 7)
    }

    fn of_order<const ORDER: usize>(
        node: &WideNode,
        ray: &TraversalRay,
    ) -> Vec<(u32, [f32; WIDTH])> {
        let mut paths = vec![FourWide::child_hits::<ORDER>(
            node,
            &FourWide::box_ray(ray),
            ray.t_max,
        )];
        #[cfg(target_arch = "x86_64")]
        for isa in crate::isa::test_paths() {
            // SAFETY: the CPU has the path (`test_paths`).
            paths.extend(unsafe {
                match isa {
                    Isa::Avx512 => Some(box_test_avx512::<ORDER>(node, ray)),
                    Isa::Avx2 => Some(box_test_avx2::<ORDER>(node, ray)),
                    Isa::Baseline => None,
                }
            });
        }
        paths
    }

    crate::isa::avx2_and_avx512! {
        /// The AVX2 box test compiled for the path, as `(mask, entry distances)`.
        fn [box_test_avx2, box_test_avx512]<const ORDER: usize>(
            node: &WideNode,
            ray: &TraversalRay,
        ) -> (u32, [f32; WIDTH]) {
            let (mask, near) = Avx2::child_hits::<ORDER>(node, &Avx2::box_ray(ray), ray.t_max);
            let mut nears = [0.0f32; WIDTH];
            // SAFETY: `nears` holds eight floats.
            unsafe { std::arch::x86_64::_mm256_storeu_ps(nears.as_mut_ptr(), near) };
            (mask, nears)
        }
    }

    crate::isa::avx2_and_avx512! {
        /// [`with_small_stack`] on the AVX2 walk compiled for the path.
        ///
        /// # Safety
        /// The CPU has the path's features; `codes_in_range(nodes, groups.len())`; `nodes` not
        /// empty.
        unsafe fn [small_stack_avx2, small_stack_avx512](
            nodes: &[WideNode],
            groups: &[TriangleGroup],
            ray: &TraversalRay,
        ) -> (Option<(u32, f32)>, bool) {
            // SAFETY: the caller's promise.
            unsafe {
                (
                    slot(walk_ray::<Avx2, false, WIDTH, false>(nodes, groups, ray, 0)),
                    walk_ray::<Avx2, true, WIDTH, false>(nodes, groups, ray, 0)
                        .0
                        .is_some(),
                )
            }
        }
    }

    crate::isa::avx2_and_avx512! {
        /// [`with_always_push`] on the AVX2 walk compiled for the path.
        ///
        /// # Safety
        /// The CPU has the path's features; `codes_in_range(nodes, groups.len())`; `nodes` not
        /// empty.
        unsafe fn [always_push_avx2, always_push_avx512](
            nodes: &[WideNode],
            groups: &[TriangleGroup],
            ray: &TraversalRay,
        ) -> [Option<(u32, f32)>; 2] {
            // SAFETY: the caller's promise.
            unsafe {
                [
                    slot(walk_ray::<Avx2, false, INLINE_STACK, true>(nodes, groups, ray, 0)),
                    slot(walk_ray::<Avx2, false, WIDTH, true>(nodes, groups, ray, 0)),
                ]
            }
        }
    }

    /// The closest hit of the walk of large trees (`ALWAYS_PUSH`) on any tree, with the inline
    /// stack and with one of eight entries (restarting on the heap), on the selected path
    /// (the baseline path has no such walk: its answers are those of its own walk).
    ///
    /// # Safety
    /// `codes_in_range(nodes, groups.len())`.
    pub(crate) unsafe fn with_always_push(
        nodes: &[WideNode],
        groups: &[TriangleGroup],
        ray: &TraversalRay,
    ) -> [Option<(u32, f32)>; 2] {
        if nodes.is_empty() {
            return [None, None];
        }
        // SAFETY (each arm): the caller's promise; a path is selected only on CPUs that have
        // it.
        match crate::isa::selected() {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe { always_push_avx512(nodes, groups, ray) },
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { always_push_avx2(nodes, groups, ray) },
            _ => unsafe {
                [
                    slot(walk_ray::<FourWide, false, INLINE_STACK, true>(
                        nodes, groups, ray, 0,
                    )),
                    slot(walk_ray::<FourWide, false, WIDTH, true>(
                        nodes, groups, ray, 0,
                    )),
                ]
            },
        }
    }

    /// A walk's hit as (slot, t).
    fn slot((hit, t): (Option<Hit>, f32)) -> Option<(u32, f32)> {
        hit.map(|hit| ((hit.group * GROUP_LANES + hit.lane) as u32, t))
    }

    /// Closest hit and any-hit answer of the selected path's walk with an inline stack of
    /// eight entries.
    ///
    /// # Safety
    /// `codes_in_range(nodes, groups.len())`.
    pub(crate) unsafe fn with_small_stack(
        nodes: &[WideNode],
        groups: &[TriangleGroup],
        ray: &TraversalRay,
    ) -> (Option<(u32, f32)>, bool) {
        if nodes.is_empty() {
            return (None, false);
        }
        // SAFETY (each arm): the caller's promise; a path is selected only on CPUs that have
        // it.
        match crate::isa::selected() {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe { small_stack_avx512(nodes, groups, ray) },
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { small_stack_avx2(nodes, groups, ray) },
            _ => unsafe {
                (
                    slot(walk_ray::<FourWide, false, WIDTH, false>(
                        nodes, groups, ray, 0,
                    )),
                    walk_ray::<FourWide, true, WIDTH, false>(nodes, groups, ray, 0)
                        .0
                        .is_some(),
                )
            },
        }
    }

    #[test]
    fn the_visit_table_lists_hit_children_in_the_walks_order() {
        use crate::accel::walk::ORDER;
        for order in 0..8 {
            for mask in 1..256usize {
                // The reference: positions of the ordered mask, nearest first, as slots.
                let ordered = u32::from(ORDER[order][mask]);
                let slots: Vec<u32> = (0..8)
                    .filter(|i| ordered & (1 << i) != 0)
                    .map(|i| i ^ order as u32)
                    .collect();
                let entry = VISIT[order][mask];
                assert_eq!(entry & 0xff, slots[0], "order {order} mask {mask:#b}");
                // SAFETY: `mask < 256`.
                let nearest = unsafe { nearest_slot(order, mask as u32) };
                assert_eq!(nearest as u32, slots[0], "order {order} mask {mask:#b}");
                let others = (entry >> OTHERS_SHIFT) as usize;
                assert_eq!(others, slots.len() - 1, "order {order} mask {mask:#b}");
                let pushed: Vec<u32> = (0..others)
                    .map(|k| (entry >> (OTHERS_SLOTS as usize + 3 * k)) & 7)
                    .collect();
                let farthest_first: Vec<u32> = slots[1..].iter().rev().copied().collect();
                assert_eq!(pushed, farthest_first, "order {order} mask {mask:#b}");
            }
        }
    }
}
