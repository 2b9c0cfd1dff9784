//! Packets of four rays (a 2x2 pixel block) in SIMD lanes ([`RayPacket`]) for coherent
//! primary rays. They walk the wide BVH together: each node is fetched once and its eight
//! child boxes are tested against all four rays, each child remembering which rays reach it;
//! a subtree only one ray reaches is walked by that ray alone. Sixteen of them make a frustum
//! packet (`frustum.rs`).
//!
//! Triangles are tested against four rays with the same watertight arithmetic as the
//! single-ray path, lane by lane in the same operation order, so every ray gets a
//! bit-identical `t`. Rays that do not fit a packet (other octant or dominant axis) are traced
//! ray by ray by the callers.

use crate::accel::frustum::{FRUSTUM_RAYS, RayArrays};
use crate::accel::primitives::{TriangleGroup, triangle_t_uv};
use crate::accel::walk::{
    BoxRay, MAX_INV_DIRECTION, ORDER, SLAB_ERROR, TraversalRay, TraversalStack, child_hits,
};
use crate::accel::wide_bvh::{LEAF_BIT, WideNode};
use crate::accel::{MAX_COORDINATE, Ray};
use glam::{BVec4A, Vec3A, Vec4};

#[cfg(target_arch = "x86_64")]
pub(crate) mod pair_avx2;

/// Number of rays in a packet.
pub(crate) const LANES: usize = 4;

/// Four rays in structure-of-arrays form (lane `i` = ray `i`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayPacket {
    pub(super) origin: [Vec4; 3],
    pub(super) direction: [Vec4; 3],
    pub(super) inv_direction: [Vec4; 3],
    pub(super) t_min: Vec4,
    /// Per-lane closest hit so far.
    pub t_max: Vec4,
    /// Barycentrics `(b1, b2)` of the triangle hit at `t_max` (meaningless for other
    /// primitive kinds, which recompute their details).
    pub hit_uv: [Vec4; 2],
    /// Unit normal (x, y, z) of that triangle in the packet's space.
    pub hit_normal: [Vec4; 3],
    pub(super) octant_inv: u32,
    pub(super) shear_axes: [usize; 3],
    pub(super) shear: [Vec4; 3],
    pub(super) permuted_origin: [Vec4; 3],
    /// Lanes holding a valid ray.
    pub lanes: u32,
}

impl RayPacket {
    /// Packs up to four prepared rays (`None` lanes stay inactive). Returns `None` if the
    /// active rays disagree on direction octant or dominant axis.
    pub fn new(rays: &[Option<TraversalRay>; LANES]) -> Option<RayPacket> {
        let first = rays.iter().flatten().next()?;
        let consistent = rays
            .iter()
            .flatten()
            .all(|ray| ray.octant_inv == first.octant_inv && ray.shear_axes == first.shear_axes);
        consistent.then(|| RayPacket::pack(rays, first))
    }

    /// A packet of no rays (every lane's interval empty) for `octant_inv` and `shear_axes`.
    pub(super) const fn blank(octant_inv: u32, shear_axes: [usize; 3]) -> RayPacket {
        RayPacket {
            origin: [Vec4::ZERO; 3],
            direction: [Vec4::ZERO; 3],
            inv_direction: [Vec4::ZERO; 3],
            t_min: Vec4::INFINITY,
            t_max: Vec4::NEG_INFINITY,
            hit_uv: [Vec4::ZERO; 2],
            hit_normal: [Vec4::ZERO; 3],
            octant_inv,
            shear_axes,
            shear: [Vec4::ZERO; 3],
            permuted_origin: [Vec4::ZERO; 3],
            lanes: 0,
        }
    }

    /// Packs the rays without checking that they agree; missing lanes copy `filler`'s
    /// geometry with an empty interval, so they never hit.
    pub(super) fn pack(rays: &[Option<TraversalRay>; LANES], filler: &TraversalRay) -> RayPacket {
        let mut packet = RayPacket::blank(filler.octant_inv, filler.shear_axes);
        for (lane, ray) in rays.iter().enumerate() {
            packet.set_lane(lane, ray.as_ref().unwrap_or(filler));
        }
        packet.reset();
        for (lane, ray) in rays.iter().enumerate() {
            if let Some(ray) = ray {
                packet.set_lane(lane, ray);
            }
        }
        packet
    }

    /// Prepares up to four rays at once; lane by lane the same arithmetic, and so the same
    /// values, as [`TraversalRay::new`]. Invalid rays leave their lane inactive. `None` if the
    /// valid rays disagree on octant or dominant axis, or none is valid.
    pub fn prepare(rays: &[Ray]) -> Option<RayPacket> {
        let mut origin = [Vec4::ZERO; 3];
        let mut direction = [Vec4::X; 3];
        let mut t_min = Vec4::INFINITY;
        let mut t_max = Vec4::NEG_INFINITY;
        let mut present = 0;
        if let [r0, r1, r2, r3, ..] = rays {
            // A full group (the usual case) is transposed straight into vectors.
            let lanes = |of: fn(&Ray) -> f32| Vec4::new(of(r0), of(r1), of(r2), of(r3));
            origin = [
                lanes(|r| r.origin.x),
                lanes(|r| r.origin.y),
                lanes(|r| r.origin.z),
            ];
            direction = [
                lanes(|r| r.direction.x),
                lanes(|r| r.direction.y),
                lanes(|r| r.direction.z),
            ];
            t_min = lanes(|r| r.t_min);
            t_max = lanes(|r| r.t_max);
            present = 0b1111;
        } else {
            for (lane, ray) in rays.iter().enumerate() {
                present |= 1 << lane;
                for axis in 0..3 {
                    origin[axis][lane] = ray.origin[axis];
                    direction[axis][lane] = ray.direction[axis];
                }
                t_min[lane] = ray.t_min;
                t_max[lane] = ray.t_max;
            }
        }
        RayPacket::prepare_lanes(origin, direction, t_min, t_max, present)
    }

    /// [`Self::prepare`] of rays `4 * group ..` of `arrays`, loaded straight from the lanes.
    #[inline(always)]
    pub fn prepare_arrays(arrays: &RayArrays, group: usize) -> Option<RayPacket> {
        let lanes = group * LANES..group * LANES + LANES;
        let load = |values: &[f32; FRUSTUM_RAYS]| Vec4::from_slice(&values[lanes.clone()]);
        RayPacket::prepare_lanes(
            arrays.origin.each_ref().map(load),
            arrays.direction.each_ref().map(load),
            load(arrays.t_min),
            load(arrays.t_max),
            0b1111,
        )
    }

    /// The arithmetic of [`Self::prepare`] on rays already in lanes (`present`: the lanes
    /// holding a ray).
    #[inline(always)]
    pub(super) fn prepare_lanes(
        origin: [Vec4; 3],
        direction: [Vec4; 3],
        t_min: Vec4,
        t_max: Vec4,
        present: u32,
    ) -> Option<RayPacket> {
        let finite =
            |v: &[Vec4; 3]| v[0].is_finite_mask() & v[1].is_finite_mask() & v[2].is_finite_mask();
        let abs_origin = origin.map(Vec4::abs);
        let abs_direction = direction.map(Vec4::abs);
        let max_coordinate = Vec4::splat(MAX_COORDINATE);
        let tiny = Vec4::splat(1.0 / MAX_INV_DIRECTION);
        let longest = abs_direction[0].max(abs_direction[1]).max(abs_direction[2]);
        let valid = t_min.cmple(t_max)
            & finite(&origin)
            & abs_origin[0]
                .max(abs_origin[1])
                .max(abs_origin[2])
                .cmple(max_coordinate)
            & finite(&direction)
            & longest.cmpge(tiny);
        let lanes = valid.bitmask() & present;
        if lanes == 0 {
            return None;
        }
        let negative = direction.map(|d| d.cmplt(Vec4::ZERO));
        let inv_direction = [0, 1, 2].map(|axis| {
            let clamped = Vec4::select(
                negative[axis],
                Vec4::splat(-MAX_INV_DIRECTION),
                Vec4::splat(MAX_INV_DIRECTION),
            );
            Vec4::select(
                abs_direction[axis].cmplt(tiny),
                clamped,
                Vec4::ONE / direction[axis],
            )
        });
        // Octant and dominant axis must agree over the valid lanes.
        let negative_bits = negative.map(|mask| mask.bitmask() & lanes);
        if negative_bits
            .iter()
            .any(|bits| *bits != 0 && *bits != lanes)
        {
            return None;
        }
        let octant_inv = (if negative_bits[0] != 0 { 0 } else { 4 })
            | (if negative_bits[1] != 0 { 0 } else { 2 })
            | (if negative_bits[2] != 0 { 0 } else { 1 });
        let [ax, ay, az] = abs_direction;
        let x_dominant = ax.cmpge(ay) & ax.cmpge(az);
        let y_dominant = !x_dominant & ay.cmpge(az);
        let kz = if x_dominant.bitmask() & lanes == lanes {
            0
        } else if y_dominant.bitmask() & lanes == lanes {
            1
        } else if (x_dominant | y_dominant).bitmask() & lanes == 0 {
            2
        } else {
            return None;
        };
        let kx = (kz + 1) % 3;
        let ky = (kx + 1) % 3;
        let inv_dominant = inv_direction[kz];
        let active = lane_mask(lanes);
        Some(RayPacket {
            origin,
            direction,
            inv_direction,
            t_min: Vec4::select(active, t_min, Vec4::INFINITY),
            t_max: Vec4::select(active, t_max, Vec4::NEG_INFINITY),
            hit_uv: [Vec4::ZERO; 2],
            hit_normal: [Vec4::ZERO; 3],
            octant_inv,
            shear_axes: [kx, ky, kz],
            shear: [
                direction[kx] * inv_dominant,
                direction[ky] * inv_dominant,
                inv_dominant,
            ],
            permuted_origin: [origin[kx], origin[ky], origin[kz]],
            lanes,
        })
    }

    /// Records a hit found for `lane` outside the packet tests (`normal`: the triangle's, or
    /// zero for other primitives).
    pub fn record_hit(&mut self, lane: usize, t: f32, bary: glam::Vec2, normal: glam::Vec3) {
        self.t_max[lane] = t;
        self.hit_uv[0][lane] = bary.x;
        self.hit_uv[1][lane] = bary.y;
        for axis in 0..3 {
            self.hit_normal[axis][lane] = normal[axis];
        }
    }

    /// Takes over the hit of `from`'s lane `from_lane` (same ray in another space).
    pub fn copy_hit(&mut self, lane: usize, from: &RayPacket, from_lane: usize) {
        self.t_max[lane] = from.t_max[from_lane];
        self.hit_uv[0][lane] = from.hit_uv[0][from_lane];
        self.hit_uv[1][lane] = from.hit_uv[1][from_lane];
        for axis in 0..3 {
            self.hit_normal[axis][lane] = from.hit_normal[axis][from_lane];
        }
    }

    /// The normal recorded with `lane`'s hit.
    #[inline]
    pub fn hit_normal(&self, lane: usize) -> glam::Vec3 {
        glam::Vec3::new(
            self.hit_normal[0][lane],
            self.hit_normal[1][lane],
            self.hit_normal[2][lane],
        )
    }

    /// Deactivates every lane (their stale ray data stays finite and is never used).
    pub(super) fn reset(&mut self) {
        self.lanes = 0;
        self.t_min = Vec4::INFINITY;
        self.t_max = Vec4::NEG_INFINITY;
    }

    /// Puts `ray` into `lane`; the packet takes its octant and dominant axis.
    pub(super) fn set_lane(&mut self, lane: usize, ray: &TraversalRay) {
        self.lanes |= 1 << lane;
        self.octant_inv = ray.octant_inv;
        self.shear_axes = ray.shear_axes;
        self.t_min[lane] = ray.t_min;
        self.t_max[lane] = ray.t_max;
        for axis in 0..3 {
            self.origin[axis][lane] = ray.origin[axis];
            self.direction[axis][lane] = ray.direction[axis];
            self.inv_direction[axis][lane] = ray.inv_direction[axis];
            self.shear[axis][lane] = ray.shear[axis];
            self.permuted_origin[axis][lane] = ray.permuted_origin[axis];
        }
    }

    /// Lane `lane` as a single ray, with its current `t_max`.
    #[inline(always)]
    pub fn ray(&self, lane: usize) -> TraversalRay {
        let lane_of =
            |values: &[Vec4; 3]| Vec3A::new(values[0][lane], values[1][lane], values[2][lane]);
        TraversalRay {
            origin: lane_of(&self.origin),
            direction: lane_of(&self.direction),
            inv_direction: lane_of(&self.inv_direction),
            t_min: self.t_min[lane],
            t_max: self.t_max[lane],
            octant_inv: self.octant_inv,
            shear_axes: self.shear_axes,
            shear: lane_of(&self.shear).into(),
            permuted_origin: lane_of(&self.permuted_origin).into(),
        }
    }
}

/// Per axis, the plane rows (`WideNode::planes`) through which rays of the octant enter and
/// leave children.
#[derive(Clone, Copy)]
pub(crate) struct PlaneRows {
    pub(super) entry: [usize; 3],
    pub(super) exit: [usize; 3],
}

impl PlaneRows {
    #[inline(always)]
    pub(super) fn new(octant_inv: u32) -> PlaneRows {
        let negative = [4, 2, 1].map(|bit| usize::from(octant_inv & bit == 0));
        PlaneRows {
            entry: [0, 1, 2].map(|axis| 2 * axis + negative[axis]),
            exit: [0, 1, 2].map(|axis| 2 * axis + 1 - negative[axis]),
        }
    }
}

/// Per child slot, a 4-bit mask of the packet lanes whose `[t_min, t_max]` overlaps the child
/// box (child `c` in bits `4c..4c+4`), restricted to `lanes` and to the slots in `children`.
/// Lane by lane the operations of the single-ray box test, so a lane reaches exactly the
/// children its ray would alone.
#[inline(always)]
pub(super) fn child_lane_masks(
    node: &WideNode,
    rows: &PlaneRows,
    packet: &RayPacket,
    lanes: u32,
    children: u32,
) -> u32 {
    let error = Vec4::splat(SLAB_ERROR);
    let mut masks = 0;
    let mut present = children;
    while present != 0 {
        let child = present.trailing_zeros() as usize;
        present &= present - 1;
        let mut near = packet.t_min;
        let mut far = packet.t_max;
        for axis in 0..3 {
            let entry = Vec4::splat(node.planes[rows.entry[axis]][child]);
            let exit = Vec4::splat(node.planes[rows.exit[axis]][child]);
            near = near.max((entry - packet.origin[axis]) * packet.inv_direction[axis]);
            far = far.min((exit - packet.origin[axis]) * packet.inv_direction[axis]);
        }
        let near = near - near.abs() * error;
        let far = far + far.abs() * error;
        let hit = near.cmple(far).bitmask() & lanes;
        masks |= hit << (4 * child);
    }
    masks
}

/// Bit `c` set for every occupied child slot `c`.
#[inline(always)]
fn occupied_children(node: &WideNode) -> u32 {
    let low = Vec4::from_slice(&node.planes[0][..4]).cmple(Vec4::from_slice(&node.planes[1][..4]));
    let high = Vec4::from_slice(&node.planes[0][4..]).cmple(Vec4::from_slice(&node.planes[1][4..]));
    low.bitmask() | (high.bitmask() << 4)
}

/// Walks the BVH with the packet's `lanes`. `test_leaf(leaf_code, lanes, packet)` is called
/// for every leaf some lane reaches, with the lanes that reach it (see
/// [`crate::accel::wide_bvh::leaf_range`]); it tests the leaf's primitives and shrinks
/// `packet.t_max` of lanes that hit. Children are visited nearest-first for the octant. A
/// subtree only one lane reaches is walked by that lane alone, with the single-ray box test
/// (hybrid traversal): the same boxes its lane mask would give, at an eighth of the work.
#[inline(always)]
pub(crate) fn traverse_packet<F>(
    nodes: &[WideNode],
    packet: &mut RayPacket,
    lanes: u32,
    mut test_leaf: F,
) where
    F: FnMut(u32, u32, &mut RayPacket),
{
    let lanes = lanes & packet.lanes;
    if nodes.is_empty() || lanes == 0 {
        return;
    }
    let rows = PlaneRows::new(packet.octant_inv);
    let order = (7 ^ packet.octant_inv) as usize;
    let mut stack: TraversalStack<(u32, u32)> = TraversalStack::new();
    stack.push((0, lanes));
    while let Some((index, lanes)) = stack.pop() {
        if lanes.count_ones() == 1 {
            walk_lane(
                nodes,
                index,
                packet,
                lanes.trailing_zeros() as usize,
                &mut test_leaf,
            );
            continue;
        }
        let node = &nodes[index as usize];
        let masks = child_lane_masks(node, &rows, packet, lanes, occupied_children(node));
        let mut hit = 0u32;
        for child in 0..8 {
            hit |= u32::from((masks >> (4 * child)) & 0xf != 0) << child;
        }
        // The node's own visiting order for the packet's octant.
        let order = usize::from(node.orders[order]);
        let ordered = u32::from(ORDER[order][hit as usize]);
        let mut inner = 0u32;
        let mut remaining = ordered;
        while remaining != 0 {
            let i = remaining.trailing_zeros();
            remaining &= remaining - 1;
            let slot = i as usize ^ order;
            let code = node.children[slot];
            let child_lanes = (masks >> (4 * slot)) & 0xf;
            if code & LEAF_BIT != 0 {
                test_leaf(code, child_lanes, packet);
            } else {
                inner |= 1 << i;
            }
        }
        while inner != 0 {
            let i = 31 - inner.leading_zeros();
            inner &= !(1 << i);
            let slot = i as usize ^ order;
            stack.push((node.children[slot], (masks >> (4 * slot)) & 0xf));
        }
    }
}

/// The subtree at node `root` for one lane of a packet, nearest-first, with that lane's
/// shrinking `t_max`: [`traverse_packet`]'s hybrid part.
#[inline(always)]
fn walk_lane<F>(
    nodes: &[WideNode],
    root: u32,
    packet: &mut RayPacket,
    lane: usize,
    test_leaf: &mut F,
) where
    F: FnMut(u32, u32, &mut RayPacket),
{
    let ray = packet.ray(lane);
    let box_ray = BoxRay::new(&ray);
    let order = box_ray.order;
    let mut stack: TraversalStack<(u32, f32)> = TraversalStack::new();
    stack.push((root, f32::NEG_INFINITY));
    while let Some((code, near)) = stack.pop() {
        if near > packet.t_max[lane] {
            continue;
        }
        if code & LEAF_BIT != 0 {
            test_leaf(code, 1 << lane, packet);
            continue;
        }
        let node = &nodes[code as usize];
        let (mask, nears) = child_hits(node, &box_ray, ray.t_min, packet.t_max[lane]);
        let order = usize::from(node.orders[order]);
        let mut remaining = u32::from(ORDER[order][mask as usize]);
        while remaining != 0 {
            let i = 31 - remaining.leading_zeros();
            remaining &= !(1 << i);
            let slot = i as usize ^ order;
            stack.push((node.children[slot], nears[slot]));
        }
    }
}

/// A triangle group's vertex coordinates in a packet's sheared axis order (`kx`, `ky`, `kz`):
/// `coordinates[vertex][axis]`, one lane per triangle, loaded once per (packet, leaf).
#[derive(Clone, Copy)]
pub(crate) struct PermutedGroup {
    coordinates: [[Vec4; 3]; 3],
}

impl PermutedGroup {
    #[inline(always)]
    pub fn new(group: &TriangleGroup, packet: &RayPacket) -> PermutedGroup {
        let [kx, ky, kz] = packet.shear_axes;
        PermutedGroup {
            coordinates: group
                .vertices
                .map(|vertex| [vertex[kx], vertex[ky], vertex[kz]]),
        }
    }
}

/// Lane `L` of `values` in every lane (a constant shuffle, no load).
#[inline(always)]
fn broadcast<const L: usize>(values: Vec4) -> Vec4 {
    match L {
        0 => Vec4::splat(values.x),
        1 => Vec4::splat(values.y),
        2 => Vec4::splat(values.z),
        _ => Vec4::splat(values.w),
    }
}

/// Watertight test of the triangle in lane `L` of `group` (`permuted`: its coordinates for
/// this packet) against the `lanes` of a packet; lanes that hit get their `t_max` shrunk and
/// their bit set in the returned mask. Lane by lane the single-ray test's arithmetic.
#[inline(always)]
pub(crate) fn triangle_packet<const L: usize>(
    group: &TriangleGroup,
    permuted: &PermutedGroup,
    packet: &mut RayPacket,
    lanes: u32,
) -> u32 {
    let [shear_x, shear_y, shear_z] = packet.shear;
    let [origin_x, origin_y, origin_z] = packet.permuted_origin;
    let vertex = |i: usize| {
        let [px, py, pz] = permuted.coordinates[i];
        let z = broadcast::<L>(pz) - origin_z;
        let x = (broadcast::<L>(px) - origin_x) - shear_x * z;
        let y = (broadcast::<L>(py) - origin_y) - shear_y * z;
        (x, y, z)
    };
    let (x0, y0, z0) = vertex(0);
    let (x1, y1, z1) = vertex(1);
    let (x2, y2, z2) = vertex(2);
    // Same expressions and order as the single-ray test, lane by lane.
    let u = x2 * y1 - y2 * x1;
    let v = x0 * y2 - y0 * x2;
    let w = x1 * y0 - y1 * x0;
    let zero = Vec4::ZERO;
    let on_edge = (u.cmpeq(zero) | v.cmpeq(zero) | w.cmpeq(zero)).bitmask() & lanes;
    // Off the edges (u, v, w all nonzero) the single-ray test's "no two signs differ and the
    // determinant is nonzero" is "u, v and w have one sign bit": a sum of nonzero values of
    // one sign is never zero. (A NaN lane fails the `t` comparisons either way.)
    let (sign_u, sign_v, sign_w) = (
        u.is_negative_bitmask(),
        v.is_negative_bitmask(),
        w.is_negative_bitmask(),
    );
    let candidates = !((sign_u ^ sign_v) | (sign_u ^ sign_w)) & lanes & !on_edge;
    let mut hits = 0;
    // Most groups miss most triangles of a leaf they reach: skip the division for them.
    if candidates != 0 {
        let determinant = u + v + w;
        let scaled_t = u * (z0 * shear_z) + v * (z1 * shear_z) + w * (z2 * shear_z);
        let t = scaled_t / determinant;
        let accepted = t.cmpge(packet.t_min) & t.cmple(packet.t_max);
        hits = accepted.bitmask() & candidates;
        if hits != 0 {
            let hit = lane_mask(hits);
            packet.t_max = Vec4::select(hit, t, packet.t_max);
            // Barycentrics exactly as the single-ray test computes them.
            let inv = Vec4::ONE / determinant;
            packet.hit_uv[0] = Vec4::select(hit, v * inv, packet.hit_uv[0]);
            packet.hit_uv[1] = Vec4::select(hit, w * inv, packet.hit_uv[1]);
            let normal = group.triangle(L).normal();
            for axis in 0..3 {
                packet.hit_normal[axis] =
                    Vec4::select(hit, Vec4::splat(normal[axis]), packet.hit_normal[axis]);
            }
        }
    }
    if on_edge != 0 {
        hits |= triangle_on_edges(group, L, packet, on_edge);
    }
    hits
}

/// Rays through an edge or vertex of the triangle in lane `triangle` take the single-ray path
/// with its f64 edge functions; returns the lanes among `on_edge` that hit.
#[cold]
#[inline(never)]
fn triangle_on_edges(
    group: &TriangleGroup,
    triangle: usize,
    packet: &mut RayPacket,
    on_edge: u32,
) -> u32 {
    let triangle = group.triangle(triangle);
    let mut hits = 0;
    let mut remaining = on_edge;
    while remaining != 0 {
        let lane = remaining.trailing_zeros() as usize;
        remaining &= remaining - 1;
        if let Some((t, uv)) = triangle_t_uv(&triangle, &packet.ray(lane)) {
            packet.record_hit(lane, t, uv, triangle.normal());
            hits |= 1 << lane;
        }
    }
    hits
}

/// Tests the triangles of `group` in `triangles` (bit per lane), in lane order, against the
/// `lanes` of a packet, calling `hit(lane, rays)` with the rays that hit each.
#[inline(always)]
pub(crate) fn group_packet(
    group: &TriangleGroup,
    triangles: u32,
    packet: &mut RayPacket,
    lanes: u32,
    mut hit: impl FnMut(usize, u32),
) {
    let permuted = PermutedGroup::new(group, packet);
    if triangles & 1 != 0 {
        hit(0, triangle_packet::<0>(group, &permuted, packet, lanes));
    }
    if triangles & 2 != 0 {
        hit(1, triangle_packet::<1>(group, &permuted, packet, lanes));
    }
    if triangles & 4 != 0 {
        hit(2, triangle_packet::<2>(group, &permuted, packet, lanes));
    }
    if triangles & 8 != 0 {
        hit(3, triangle_packet::<3>(group, &permuted, packet, lanes));
    }
}

/// Lanes of a 4-bit mask as a SIMD mask (bits above the fourth are ignored): one load from a
/// table, where building the mask from four bits took about twenty instructions.
#[inline(always)]
pub(super) fn lane_mask(lanes: u32) -> BVec4A {
    LANE_MASKS[(lanes & 0xf) as usize]
}

/// [`lane_mask`] of every 4-bit mask.
const LANE_MASKS: [BVec4A; 16] = {
    let mut masks = [BVec4A::FALSE; 16];
    let mut lanes = 0;
    while lanes < 16 {
        masks[lanes] = BVec4A::new(
            lanes & 1 != 0,
            lanes & 2 != 0,
            lanes & 4 != 0,
            lanes & 8 != 0,
        );
        lanes += 1;
    }
    masks
};
