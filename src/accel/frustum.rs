//! Frustum packets: up to 64 primary rays of one 8x8 pixel block (sixteen [`RayPacket`]
//! groups of four) walk the wide BVH together. Inner nodes are culled once for the whole block
//! with interval arithmetic over the rays' inverse directions and origins (one shared eye
//! point, or each ray its own: several viewers, a matrix camera's near plane), inner nodes and
//! leaf boxes also per quadrant of four groups the same way; only then are leaf boxes tested
//! per group, each lane with its own origin (`packet`'s test), and triangles per group.

use crate::accel::Ray;
use crate::accel::geometry::prepare as prepare_one;
use crate::accel::packet::{LANES, PlaneRows, RayPacket, child_lane_masks, lane_mask};
use crate::accel::walk::{ORDER, SLAB_ERROR, TraversalRay, TraversalStack, prefetch_node};
use crate::accel::wide_bvh::{LEAF_BIT, WideNode};
use glam::{Vec3A, Vec4};

#[cfg(target_arch = "x86_64")]
mod fill_avx2;

/// Most rays in a frustum packet (an 8x8 block of primary rays).
pub const FRUSTUM_RAYS: usize = 64;
const FRUSTUM_GROUPS: usize = FRUSTUM_RAYS / LANES;
/// The packet's groups of four as four quadrants of four groups (4x4 pixels of the 8x8 block
/// when the groups are 2x2 quads in row order). Leaf boxes are culled per quadrant before
/// groups test them: a leaf usually covers a few pixels, so most groups are spared.
const QUADRANTS: usize = 4;
pub(crate) const QUADRANT_GROUPS: [[usize; 4]; QUADRANTS] =
    [[0, 1, 4, 5], [2, 3, 6, 7], [8, 9, 12, 13], [10, 11, 14, 15]];

/// Range of the inverse direction components and of the origins of a set of rays, and their
/// smallest `t_min`: a conservative stand-in for all of them in box tests.
#[derive(Clone, Copy, Debug)]
struct RayBounds {
    inv_low: Vec3A,
    inv_high: Vec3A,
    origin_low: Vec3A,
    origin_high: Vec3A,
    t_min_low: f32,
    /// Set by [`RayBounds::finished`]: the origins' centre, and per axis how far another origin
    /// can move a slab distance from the centre's (spread times the largest |inverse direction|;
    /// exactly 0 for one shared origin).
    origin_centre: Vec3A,
    widening: Vec3A,
}

impl RayBounds {
    const EMPTY: RayBounds = RayBounds {
        inv_low: Vec3A::INFINITY,
        inv_high: Vec3A::NEG_INFINITY,
        origin_low: Vec3A::INFINITY,
        origin_high: Vec3A::NEG_INFINITY,
        t_min_low: f32::INFINITY,
        origin_centre: Vec3A::ZERO,
        widening: Vec3A::ZERO,
    };

    fn union(self, other: RayBounds) -> RayBounds {
        RayBounds {
            inv_low: self.inv_low.min(other.inv_low),
            inv_high: self.inv_high.max(other.inv_high),
            origin_low: self.origin_low.min(other.origin_low),
            origin_high: self.origin_high.max(other.origin_high),
            t_min_low: self.t_min_low.min(other.t_min_low),
            ..RayBounds::EMPTY
        }
    }

    /// Computes the origins' centre and the widening of slab distances it needs.
    fn finished(mut self) -> RayBounds {
        let (low, high) = (self.origin_low, self.origin_high);
        if low == high {
            self.origin_centre = low;
            self.widening = Vec3A::ZERO;
        } else if low.cmple(high).all() {
            let centre = low + 0.5 * (high - low);
            let spread = (high - centre).max(centre - low) * (1.0 + SLAB_ERROR);
            let largest_inv = self.inv_low.abs().max(self.inv_high.abs());
            self.origin_centre = centre;
            self.widening = spread * largest_inv;
        }
        self
    }

    /// Whether every ray starts at the same point.
    fn shared_origin(&self) -> bool {
        self.origin_low == self.origin_high
    }
}

/// Ray bounds of the `active` lanes of `groups`, per quadrant and over all of them, written in
/// place (they are large, and this runs for every packet).
#[inline]
fn bounds_into(
    groups: &[RayPacket],
    active: &[u32; FRUSTUM_GROUPS],
    shared_origin: Option<Vec3A>,
    quadrants: &mut [RayBounds; QUADRANTS],
    whole: &mut RayBounds,
) {
    *whole = RayBounds::EMPTY;
    for (quadrant, members) in quadrants.iter_mut().zip(QUADRANT_GROUPS) {
        *quadrant = quadrant_bounds(groups, members, active, shared_origin);
        *whole = whole.union(*quadrant);
        *quadrant = quadrant.finished();
    }
    *whole = whole.finished();
}

/// Ray bounds of the `active` lanes of the `members` groups (unfinished). The groups' vectors
/// are reduced lane by lane first and across lanes once at the end: a minimum or maximum does
/// not depend on the order it is taken in, so these are the bounds group by group would give.
#[inline(always)]
fn quadrant_bounds(
    groups: &[RayPacket],
    members: [usize; 4],
    active: &[u32; FRUSTUM_GROUPS],
    shared_origin: Option<Vec3A>,
) -> RayBounds {
    let mut inv_low = [Vec4::INFINITY; 3];
    let mut inv_high = [Vec4::NEG_INFINITY; 3];
    let mut origin_low = [Vec4::INFINITY; 3];
    let mut origin_high = [Vec4::NEG_INFINITY; 3];
    let mut t_min_low = Vec4::INFINITY;
    let mut any = false;
    for group in members {
        let Some(packet) = groups.get(group) else {
            continue;
        };
        let lanes = packet.lanes & active[group];
        if lanes == 0 {
            continue;
        }
        any = true;
        let mask = lane_mask(lanes);
        let low = |values: Vec4| Vec4::select(mask, values, Vec4::INFINITY);
        let high = |values: Vec4| Vec4::select(mask, values, Vec4::NEG_INFINITY);
        for axis in 0..3 {
            inv_low[axis] = inv_low[axis].min(low(packet.inv_direction[axis]));
            inv_high[axis] = inv_high[axis].max(high(packet.inv_direction[axis]));
            if shared_origin.is_none() {
                origin_low[axis] = origin_low[axis].min(low(packet.origin[axis]));
                origin_high[axis] = origin_high[axis].max(high(packet.origin[axis]));
            }
        }
        t_min_low = t_min_low.min(low(packet.t_min));
    }
    if !any {
        return RayBounds::EMPTY;
    }
    let lows = |values: [Vec4; 3]| values.map(Vec4::min_element).into();
    let highs = |values: [Vec4; 3]| values.map(Vec4::max_element).into();
    let (origin_low, origin_high) = match shared_origin {
        Some(origin) => (origin, origin),
        None => (lows(origin_low), highs(origin_high)),
    };
    RayBounds {
        inv_low: lows(inv_low),
        inv_high: highs(inv_high),
        origin_low,
        origin_high,
        t_min_low: t_min_low.min_element(),
        ..RayBounds::EMPTY
    }
}

/// Whether the rays added so far all start at one point.
#[derive(Default)]
struct SharedOrigin {
    first: Option<Vec3A>,
    differ: bool,
}

impl SharedOrigin {
    fn add(&mut self, origin: Vec3A) {
        if *self.first.get_or_insert(origin) != origin {
            self.differ = true;
        }
    }

    /// Adds the active lanes of `group`.
    fn add_group(&mut self, group: &RayPacket) {
        if self.differ || group.lanes == 0 {
            return;
        }
        let lane = group.lanes.trailing_zeros() as usize;
        let origin = Vec3A::new(
            group.origin[0][lane],
            group.origin[1][lane],
            group.origin[2][lane],
        );
        let first = *self.first.get_or_insert(origin);
        let inactive = !lane_mask(group.lanes);
        self.differ = !(0..3)
            .all(|axis| (group.origin[axis].cmpeq(Vec4::splat(first[axis])) | inactive).all());
    }

    fn shared(&self) -> Option<Vec3A> {
        self.first.filter(|_| !self.differ)
    }
}

/// Bit `c` of `bits` (c < 8) moved to bit `4c`.
#[inline(always)]
fn spread_bits(bits: u32) -> u32 {
    let bits = (bits | (bits << 12)) & 0x000f_000f;
    let bits = (bits | (bits << 6)) & 0x0303_0303;
    (bits | (bits << 3)) & 0x1111_1111
}

/// Bit `4c` of `bits` moved to bit `c` (`spread_bits` undone); other bits are ignored.
#[inline(always)]
fn gather_bits(bits: u32) -> u32 {
    let bits = bits & 0x1111_1111;
    let bits = (bits | (bits >> 3)) & 0x0303_0303;
    let bits = (bits | (bits >> 6)) & 0x000f_000f;
    (bits | (bits >> 12)) & 0xff
}

/// A block of 64 rays as lane arrays: ray `i` is lane `i` of each array (as a camera makes an
/// 8x8 block of pixels, sixteen 2x2 blocks of four consecutive lanes).
#[derive(Clone, Copy)]
pub struct RayArrays<'a> {
    pub origin: &'a [[f32; FRUSTUM_RAYS]; 3],
    pub direction: &'a [[f32; FRUSTUM_RAYS]; 3],
    pub t_min: &'a [f32; FRUSTUM_RAYS],
    pub t_max: &'a [f32; FRUSTUM_RAYS],
}

impl RayArrays<'_> {
    /// Ray `lane`.
    #[inline]
    pub fn ray(&self, lane: usize) -> Ray {
        let at = |v: &[[f32; FRUSTUM_RAYS]; 3]| glam::Vec3::new(v[0][lane], v[1][lane], v[2][lane]);
        Ray {
            origin: at(self.origin),
            direction: at(self.direction),
            t_min: self.t_min[lane],
            t_max: self.t_max[lane],
        }
    }
}

/// A block's lane arrays, owned ([`RayArrays`] borrows them).
#[derive(Clone)]
pub(crate) struct LaneArrays {
    pub origin: [[f32; FRUSTUM_RAYS]; 3],
    pub direction: [[f32; FRUSTUM_RAYS]; 3],
    pub t_min: [f32; FRUSTUM_RAYS],
    pub t_max: [f32; FRUSTUM_RAYS],
}

impl Default for LaneArrays {
    fn default() -> LaneArrays {
        LaneArrays {
            origin: [[0.0; FRUSTUM_RAYS]; 3],
            direction: [[0.0; FRUSTUM_RAYS]; 3],
            t_min: [0.0; FRUSTUM_RAYS],
            t_max: [0.0; FRUSTUM_RAYS],
        }
    }
}

impl LaneArrays {
    /// A copy of `arrays`.
    pub fn of(arrays: &RayArrays) -> LaneArrays {
        LaneArrays {
            origin: *arrays.origin,
            direction: *arrays.direction,
            t_min: *arrays.t_min,
            t_max: *arrays.t_max,
        }
    }

    /// The lanes of 64 rays.
    pub fn of_rays(rays: &[Ray]) -> LaneArrays {
        let mut lanes = LaneArrays::default();
        for (lane, ray) in rays.iter().take(FRUSTUM_RAYS).enumerate() {
            for axis in 0..3 {
                lanes.origin[axis][lane] = ray.origin[axis];
                lanes.direction[axis][lane] = ray.direction[axis];
            }
            lanes.t_min[lane] = ray.t_min;
            lanes.t_max[lane] = ray.t_max;
        }
        lanes
    }

    pub fn arrays(&self) -> RayArrays<'_> {
        RayArrays {
            origin: &self.origin,
            direction: &self.direction,
            t_min: &self.t_min,
            t_max: &self.t_max,
        }
    }
}

/// Working memory for tracing packets of primary rays, reusable from one tile to the next.
pub struct PacketScratch {
    pub(crate) frustum: FrustumPacket,
}

impl PacketScratch {
    pub fn new() -> PacketScratch {
        PacketScratch {
            frustum: FrustumPacket::empty(),
        }
    }
}

impl Default for PacketScratch {
    fn default() -> PacketScratch {
        PacketScratch::new()
    }
}

/// Up to 64 rays sharing a direction octant, as groups of four. Upper BVH levels are culled
/// once for the whole packet with interval arithmetic over the rays' inverse directions and
/// origins (a box no ray can reach is skipped for all of them); leaf boxes are culled per
/// quadrant the same way, then tested per group of four, and primitives per group.
pub(crate) struct FrustumPacket {
    pub groups: [RayPacket; FRUSTUM_GROUPS],
    pub group_count: usize,
    whole: RayBounds,
    quadrants: [RayBounds; QUADRANTS],
    octant_inv: u32,
}

impl FrustumPacket {
    /// A packet without rays, to be filled by [`Self::fill`].
    pub fn empty() -> FrustumPacket {
        let blank = TraversalRay::new(Vec3A::ZERO, Vec3A::X, 0.0, 0.0)
            .map(|ray| RayPacket::pack(&[None; LANES], &ray));
        FrustumPacket {
            // The blank ray is valid, so `pack` always runs; the fallback is never used.
            groups: [blank.unwrap_or(RayPacket::blank(0, [0, 1, 2])); FRUSTUM_GROUPS],
            group_count: 0,
            whole: RayBounds::EMPTY,
            quadrants: [RayBounds::EMPTY; QUADRANTS],
            octant_inv: 0,
        }
    }

    /// Refills the packet with up to 64 world rays (same conditions as [`Self::fill`]),
    /// preparing four at a time.
    pub fn fill_from_rays(&mut self, rays: &[Ray]) -> bool {
        if rays.is_empty() || rays.len() > FRUSTUM_RAYS {
            return false;
        }
        self.fill_groups(
            rays.len(),
            |group| {
                RayPacket::prepare(&rays[group * LANES..(group * LANES + LANES).min(rays.len())])
            },
            |index| prepare_one(&rays[index]).is_some(),
        )
    }

    /// [`Self::fill_from_rays`] of the 64 rays of `arrays`, read straight from their lanes:
    /// the same packet, value for value.
    pub fn fill_from_arrays(&mut self, arrays: &RayArrays) -> bool {
        self.fill_groups(
            FRUSTUM_RAYS,
            |group| RayPacket::prepare_arrays(arrays, group),
            |index| prepare_one(&arrays.ray(index)).is_some(),
        )
    }

    /// [`Self::fill_from_arrays`]; `AVX2`: eight lanes at a time, writing the groups in place
    /// (only inside an AVX2 or AVX-512 function): the same packet, value for value.
    #[inline(always)]
    pub fn fill_from_arrays_on<const AVX2: bool>(&mut self, arrays: &RayArrays) -> bool {
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            // SAFETY: `AVX2` is set only by functions compiled for AVX2 or AVX-512, entered
            // only on CPUs with them.
            return unsafe { fill_avx2::fill_from_arrays(self, arrays) };
        }
        self.fill_from_arrays(arrays)
    }

    /// [`Self::fill_from_rays`]; `AVX2`: a full packet's rays turned into lanes eight at a time
    /// and filled as [`Self::fill_from_arrays_on`] does (only inside an AVX2 or AVX-512
    /// function): the same packet, value for value.
    #[inline(always)]
    pub fn fill_from_rays_on<const AVX2: bool>(&mut self, rays: &[Ray]) -> bool {
        #[cfg(target_arch = "x86_64")]
        if AVX2 && let Ok(rays) = <&[Ray; FRUSTUM_RAYS]>::try_from(rays) {
            // SAFETY: `AVX2` is set only by functions compiled for AVX2 or AVX-512, entered
            // only on CPUs with them.
            return unsafe { fill_avx2::fill_from_rays(self, rays) };
        }
        self.fill_from_rays(rays)
    }

    /// Fills `count` rays group by group: `prepare_group(g)` prepares group `g`, and when it
    /// cannot, `valid(i)` tells whether ray `i` could be traced alone (then the rays cannot be
    /// a frustum packet).
    #[inline(always)]
    fn fill_groups(
        &mut self,
        count: usize,
        mut prepare_group: impl FnMut(usize) -> Option<RayPacket>,
        mut valid: impl FnMut(usize) -> bool,
    ) -> bool {
        let mut octant: Option<u32> = None;
        let mut origins = SharedOrigin::default();
        self.group_count = count.div_ceil(LANES);
        for (index, group) in self.groups[..self.group_count].iter_mut().enumerate() {
            let Some(packet) = prepare_group(index) else {
                // Either no valid ray in this group, or a group that cannot be a packet.
                let rays = index * LANES..(index * LANES + LANES).min(count);
                if rays.into_iter().any(&mut valid) {
                    return false;
                }
                group.reset();
                continue;
            };
            if *octant.get_or_insert(packet.octant_inv) != packet.octant_inv {
                return false;
            }
            origins.add_group(&packet);
            *group = packet;
        }
        let Some(octant_inv) = octant else {
            return false;
        };
        self.finish(octant_inv, origins.shared());
        true
    }

    /// Refills the packet with `count` (at most 64) rays, ray `i` given by `ray_at(i)`
    /// (`None` for rays that cannot be traced). Returns false, leaving the packet unusable,
    /// unless at least one ray is valid, all valid rays share their direction octant, and each
    /// group of four shares its dominant axis.
    pub fn fill(
        &mut self,
        count: usize,
        mut ray_at: impl FnMut(usize) -> Option<TraversalRay>,
    ) -> bool {
        if count > FRUSTUM_RAYS {
            return false;
        }
        let mut octant: Option<u32> = None;
        let mut origins = SharedOrigin::default();
        self.group_count = count.div_ceil(LANES);
        for (group_index, group) in self.groups[..self.group_count].iter_mut().enumerate() {
            group.reset();
            let mut group_axes = None;
            for lane in 0..LANES {
                let index = group_index * LANES + lane;
                let Some(ray) = (index < count).then(|| ray_at(index)).flatten() else {
                    continue;
                };
                if *octant.get_or_insert(ray.octant_inv) != ray.octant_inv {
                    return false;
                }
                origins.add(ray.origin);
                match group_axes {
                    None => group_axes = Some(ray.shear_axes),
                    Some(axes) if axes != ray.shear_axes => return false,
                    Some(_) => {}
                }
                group.set_lane(lane, &ray);
            }
        }
        let Some(octant_inv) = octant else {
            return false;
        };
        self.finish(octant_inv, origins.shared());
        true
    }

    /// Records the octant and the ray bounds of each quadrant and of the whole packet.
    fn finish(&mut self, octant_inv: u32, shared_origin: Option<Vec3A>) {
        self.octant_inv = octant_inv;
        let all = std::array::from_fn(|group| self.groups[group].lanes);
        bounds_into(
            &self.groups[..self.group_count],
            &all,
            shared_origin,
            &mut self.quadrants,
            &mut self.whole,
        );
    }

    /// Ray bounds of the `active` lanes per quadrant and over all of them.
    fn bounds(&self, active: &[u32; FRUSTUM_GROUPS]) -> ([RayBounds; QUADRANTS], RayBounds) {
        let mut quadrants = [RayBounds::EMPTY; QUADRANTS];
        let mut whole = RayBounds::EMPTY;
        bounds_into(
            &self.groups[..self.group_count],
            active,
            None,
            &mut quadrants,
            &mut whole,
        );
        (quadrants, whole)
    }

    /// The `active` lanes split by origin, if they start from at most [`MAX_ORIGINS`] points
    /// (zones of several viewers, the edge of a viewer's cone): one frustum per origin culls
    /// far better than one frustum over origins centimetres or metres apart.
    fn split_by_origin(
        &self,
        active: &[u32; FRUSTUM_GROUPS],
    ) -> Option<([[u32; FRUSTUM_GROUPS]; MAX_ORIGINS], usize)> {
        let mut origins = [[0.0f32; 3]; MAX_ORIGINS];
        let mut subsets = [[0u32; FRUSTUM_GROUPS]; MAX_ORIGINS];
        let mut count = 0;
        for (group_index, group) in self.groups[..self.group_count].iter().enumerate() {
            let mut lanes = group.lanes & active[group_index];
            while lanes != 0 {
                let lane = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                let origin = [0, 1, 2].map(|axis| group.origin[axis][lane]);
                let subset = match origins[..count].iter().position(|o| *o == origin) {
                    Some(known) => known,
                    None if count < MAX_ORIGINS => {
                        origins[count] = origin;
                        count += 1;
                        count - 1
                    }
                    None => return None,
                };
                subsets[subset][group_index] |= 1 << lane;
            }
        }
        Some((subsets, count))
    }

    /// Per quadrant, the largest `t_max` over every lane of its groups that have an active lane
    /// (-inf for a quadrant without one). Lanes that are not active have `t_max` -inf or a
    /// value of their own ray, so this may only overestimate: safe for culling.
    #[inline(always)]
    fn t_max_high(&self, active: &[u32; FRUSTUM_GROUPS]) -> [f32; QUADRANTS] {
        QUADRANT_GROUPS.map(|groups| {
            let mut high = Vec4::NEG_INFINITY;
            for group in groups {
                if group < self.group_count && active[group] != 0 {
                    high = high.max(self.groups[group].t_max);
                }
            }
            high.max_element()
        })
    }
}

/// Children of a node that some ray within `bounds` may reach within
/// `[bounds.t_min_low, t_max_high]`. Conservative: a ray's slab distance
/// `(plane − origin)·inv` is linear in its inverse direction component, so for the centre of
/// the origins it lies between the values at the two ends of the inverse direction range, and
/// another origin within `r` of that centre moves it by at most `r·|inv|` (the widening).
/// Each end is widened by twice the single-ray test's relative error of its magnitude plus
/// the widening, and the result like the single-ray test's, so every child any of the rays
/// reaches on its own is kept. `SPREAD` false: every ray starts at `bounds.origin_centre`.
/// `AVX2`: all eight children in one vector, the same operations per lane (only inside an
/// AVX2 or AVX-512 function).
#[inline(always)]
fn frustum_child_hits<const SPREAD: bool, const AVX2: bool>(
    node: &WideNode,
    rows: &PlaneRows,
    bounds: &RayBounds,
    t_max_high: f32,
) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: `AVX2` is set only by walks compiled for AVX2 or AVX-512, entered only on
        // CPUs with them.
        return unsafe { avx2::frustum_child_hits::<SPREAD>(node, rows, bounds, t_max_high) };
    }
    let widening = if SPREAD { bounds.widening } else { Vec3A::ZERO };
    let mut mask = 0;
    for half in 0..2 {
        let lanes = 4 * half..4 * half + 4;
        let plane = |row: usize| Vec4::from_slice(&node.planes[row][lanes.clone()]);
        let entry = rows.entry.map(plane);
        let exit = rows.exit.map(plane);
        let reached = frustum_box_hits::<SPREAD>(
            &entry,
            &exit,
            bounds,
            widening,
            bounds.t_min_low,
            t_max_high,
        );
        mask |= reached << (4 * half);
    }
    mask
}

/// [`frustum_child_hits`] for four boxes given by their entry and exit planes per axis, with
/// `widening` for the spread of the origins (zero when they all start at the centre).
#[inline(always)]
fn frustum_box_hits<const SPREAD: bool>(
    entry: &[Vec4; 3],
    exit: &[Vec4; 3],
    bounds: &RayBounds,
    widening: Vec3A,
    t_low: f32,
    t_high: f32,
) -> u32 {
    let mut near = Vec4::splat(t_low);
    let mut far = Vec4::splat(t_high);
    let error = Vec4::splat(SLAB_ERROR);
    let twice_error = Vec4::splat(2.0 * SLAB_ERROR);
    for axis in 0..3 {
        let (inv_low, inv_high) = (
            Vec4::splat(bounds.inv_low[axis]),
            Vec4::splat(bounds.inv_high[axis]),
        );
        let origin = Vec4::splat(bounds.origin_centre[axis]);
        let widening = Vec4::splat(widening[axis]);
        let entry = entry[axis] - origin;
        let exit = exit[axis] - origin;
        let (entry_low, entry_high) = (entry * inv_low, entry * inv_high);
        let (exit_low, exit_high) = (exit * inv_low, exit * inv_high);
        let (entry_margin, exit_margin) = if SPREAD {
            (
                (entry_low.abs().max(entry_high.abs()) + widening) * twice_error + widening,
                (exit_low.abs().max(exit_high.abs()) + widening) * twice_error + widening,
            )
        } else {
            // The same values with a zero widening, without adding it.
            (
                entry_low.abs().max(entry_high.abs()) * twice_error,
                exit_low.abs().max(exit_high.abs()) * twice_error,
            )
        };
        near = near.max(entry_low.min(entry_high) - entry_margin);
        far = far.min(exit_low.max(exit_high) + exit_margin);
    }
    let near = near - near.abs() * error;
    let far = far + far.abs() * error;
    near.cmple(far).bitmask()
}

/// [`frustum_child_hits`] with AVX2.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{PlaneRows, RayBounds};
    use crate::accel::lanes8::abs;
    use crate::accel::walk::SLAB_ERROR;
    use crate::accel::wide_bvh::WideNode;
    use std::arch::x86_64::*;

    /// The operations of `frustum_box_hits`, in the same order, on eight children.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn frustum_child_hits<const SPREAD: bool>(
        node: &WideNode,
        rows: &PlaneRows,
        bounds: &RayBounds,
        t_max_high: f32,
    ) -> u32 {
        let mut near = _mm256_set1_ps(bounds.t_min_low);
        let mut far = _mm256_set1_ps(t_max_high);
        let twice_error = _mm256_set1_ps(2.0 * SLAB_ERROR);
        for axis in 0..3 {
            let inv_low = _mm256_set1_ps(bounds.inv_low[axis]);
            let inv_high = _mm256_set1_ps(bounds.inv_high[axis]);
            let origin = _mm256_set1_ps(bounds.origin_centre[axis]);
            // SAFETY: every plane row is eight floats, 32-byte aligned (`WideNode` is).
            let (entry, exit) = unsafe {
                (
                    _mm256_load_ps(node.planes[rows.entry[axis]].as_ptr()),
                    _mm256_load_ps(node.planes[rows.exit[axis]].as_ptr()),
                )
            };
            let entry = _mm256_sub_ps(entry, origin);
            let exit = _mm256_sub_ps(exit, origin);
            let (entry_low, entry_high) = (
                _mm256_mul_ps(entry, inv_low),
                _mm256_mul_ps(entry, inv_high),
            );
            let (exit_low, exit_high) =
                (_mm256_mul_ps(exit, inv_low), _mm256_mul_ps(exit, inv_high));
            let entry_abs = _mm256_max_ps(abs(entry_low), abs(entry_high));
            let exit_abs = _mm256_max_ps(abs(exit_low), abs(exit_high));
            let (entry_margin, exit_margin) = if SPREAD {
                let widening = _mm256_set1_ps(bounds.widening[axis]);
                (
                    _mm256_add_ps(
                        _mm256_mul_ps(_mm256_add_ps(entry_abs, widening), twice_error),
                        widening,
                    ),
                    _mm256_add_ps(
                        _mm256_mul_ps(_mm256_add_ps(exit_abs, widening), twice_error),
                        widening,
                    ),
                )
            } else {
                (
                    _mm256_mul_ps(entry_abs, twice_error),
                    _mm256_mul_ps(exit_abs, twice_error),
                )
            };
            near = _mm256_max_ps(
                near,
                _mm256_sub_ps(_mm256_min_ps(entry_low, entry_high), entry_margin),
            );
            far = _mm256_min_ps(
                far,
                _mm256_add_ps(_mm256_max_ps(exit_low, exit_high), exit_margin),
            );
        }
        let error = _mm256_set1_ps(SLAB_ERROR);
        let near = _mm256_sub_ps(near, _mm256_mul_ps(abs(near), error));
        let far = _mm256_add_ps(far, _mm256_mul_ps(abs(far), error));
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32
    }
}

/// Most distinct ray origins a frustum packet is split into before it is traced as one frustum
/// over all of them.
const MAX_ORIGINS: usize = 4;

/// Walks the BVH with a frustum packet. `active[g]` are the lanes of group `g` taking part.
/// For every leaf some ray reaches, `test_leaf(leaf_code, lanes, frustum)` is called
/// with, per group, the lanes whose own box test reaches the leaf; it must shrink the `t_max`
/// of lanes that hit. Lanes from a few distinct origins are walked one origin at a time.
#[inline(always)]
pub(crate) fn traverse_frustum<const AVX2: bool, F, P>(
    nodes: &[WideNode],
    frustum: &mut FrustumPacket,
    active: &[u32; FRUSTUM_GROUPS],
    prefetch_leaf: P,
    mut test_leaf: F,
) where
    F: FnMut(u32, &[u32; FRUSTUM_GROUPS], &mut FrustumPacket),
    P: Fn(u32),
{
    if nodes.is_empty() || active.iter().all(|lanes| *lanes == 0) {
        return;
    }
    crate::accel::counters::add(|counts| {
        counts.packets += 1;
        counts.packet_rays += u64::from(active.iter().map(|lanes| lanes.count_ones()).sum::<u32>());
    });
    // Lanes from a few origins are walked one origin at a time; otherwise the packet's own
    // bounds hold every lane's.
    let split = match frustum.whole.shared_origin() {
        true => None,
        false => frustum.split_by_origin(active),
    };
    let Some((subsets, count)) = split else {
        if frustum.whole.shared_origin() {
            walk_frustum::<false, AVX2, _, _>(
                nodes,
                frustum,
                active,
                None,
                &prefetch_leaf,
                &mut test_leaf,
            );
            return;
        }
        walk_frustum::<true, AVX2, _, _>(
            nodes,
            frustum,
            active,
            None,
            &prefetch_leaf,
            &mut test_leaf,
        );
        return;
    };
    for subset in &subsets[..count] {
        let (quadrants, whole) = frustum.bounds(subset);
        walk_frustum::<false, AVX2, _, _>(
            nodes,
            frustum,
            subset,
            Some((&quadrants, &whole)),
            &prefetch_leaf,
            &mut test_leaf,
        );
    }
}

/// [`traverse_frustum`] with the ray bounds (per quadrant, whole) of the `active` lanes: its own,
/// or, with `None`, the packet's (read in place: they are too large to copy per packet).
#[inline(always)]
fn walk_frustum<const SPREAD: bool, const AVX2: bool, F, P>(
    nodes: &[WideNode],
    frustum: &mut FrustumPacket,
    active: &[u32; FRUSTUM_GROUPS],
    own_bounds: Option<(&[RayBounds; QUADRANTS], &RayBounds)>,
    prefetch_leaf: &P,
    test_leaf: &mut F,
) where
    F: FnMut(u32, &[u32; FRUSTUM_GROUPS], &mut FrustumPacket),
    P: Fn(u32),
{
    let rows = PlaneRows::new(frustum.octant_inv);
    let order = (7 ^ frustum.octant_inv) as usize;
    let quadrant_bounds = *own_bounds.map_or(&frustum.quadrants, |bounds| bounds.0);
    let mut active_quadrants = 0u32;
    for (quadrant, groups) in QUADRANT_GROUPS.iter().enumerate() {
        if groups
            .iter()
            .any(|group| *group < frustum.group_count && active[*group] != 0)
        {
            active_quadrants |= 1 << quadrant;
        }
    }
    // Nodes with the quadrants whose frustum reaches them: a subtree only some quadrants
    // reach is culled with their (narrower) frusta alone.
    let mut stack: TraversalStack<(u32, u32)> = TraversalStack::new();
    stack.push((0, active_quadrants));
    let mut t_max_high = frustum.t_max_high(active);
    while let Some((index, quadrants)) = stack.pop() {
        let node = &nodes[index as usize];
        // The node's own visiting order for the packet's octant.
        let order = usize::from(node.orders[order]);
        crate::accel::counters::add(|counts| counts.packet_nodes += 1);
        // Per child slot (4 bits each, as `child_lane_masks`), the quadrants reaching it.
        let mut quadrant_masks = 0u32;
        if quadrants.count_ones() > 1 {
            let whole_high = t_max_high.into_iter().fold(f32::NEG_INFINITY, f32::max);
            let whole = own_bounds.map_or(&frustum.whole, |bounds| bounds.1);
            if frustum_child_hits::<SPREAD, AVX2>(node, &rows, whole, whole_high) == 0 {
                continue;
            }
        }
        let mut hits = 0u32;
        let mut remaining = quadrants;
        while remaining != 0 {
            let quadrant = remaining.trailing_zeros() as usize;
            remaining &= remaining - 1;
            let reached = frustum_child_hits::<SPREAD, AVX2>(
                node,
                &rows,
                &quadrant_bounds[quadrant],
                t_max_high[quadrant],
            );
            hits |= reached;
            quadrant_masks |= spread_bits(reached) << quadrant;
        }
        let mut leaves = 0u32;
        let mut inner = 0u32;
        let mut remaining = hits;
        while remaining != 0 {
            let slot = remaining.trailing_zeros();
            remaining &= remaining - 1;
            if node.children[slot as usize] & LEAF_BIT != 0 {
                leaves |= 1 << slot;
                prefetch_leaf(node.children[slot as usize]);
            } else {
                inner |= 1 << slot;
                prefetch_node(&nodes[node.children[slot as usize] as usize]);
            }
        }
        if leaves != 0 {
            let mut masks = [0u32; FRUSTUM_GROUPS];
            for (quadrant, groups) in QUADRANT_GROUPS.iter().enumerate() {
                let quadrant_leaves = leaves & gather_bits(quadrant_masks >> quadrant);
                if quadrant_leaves == 0 {
                    continue;
                }
                for &group in groups {
                    if group < frustum.group_count && active[group] != 0 {
                        masks[group] = child_lane_masks(
                            node,
                            &rows,
                            &frustum.groups[group],
                            active[group],
                            quadrant_leaves,
                        );
                    }
                }
            }
            let mut remaining = u32::from(ORDER[order][leaves as usize]);
            while remaining != 0 {
                let i = remaining.trailing_zeros();
                remaining &= remaining - 1;
                let slot = i as usize ^ order;
                let lanes = masks.map(|mask| (mask >> (4 * slot)) & 0xf);
                if lanes.iter().fold(0, |any, lanes| any | lanes) != 0 {
                    test_leaf(node.children[slot], &lanes, frustum);
                }
            }
            t_max_high = frustum.t_max_high(active);
        }
        let mut remaining = u32::from(ORDER[order][inner as usize]);
        while remaining != 0 {
            let i = 31 - remaining.leading_zeros();
            remaining &= !(1 << i);
            let slot = i as usize ^ order;
            stack.push((node.children[slot], (quadrant_masks >> (4 * slot)) & 0xf));
        }
    }
}
