//! Ray packets for coherent primary rays.
//!
//! * [`RayPacket`]: four rays (a 2x2 pixel block) in SIMD lanes. They walk the wide BVH
//!   together: each node is fetched and decoded once and its eight child boxes are tested
//!   against all four rays, each child remembering which rays reach it.
//! * [`FrustumPacket`]: up to sixteen such groups (an 8x8 tile). Inner nodes are culled once
//!   for the whole tile with interval arithmetic over the rays' inverse directions and origins
//!   (one shared eye point, or each ray its own: several viewers, a matrix camera's near
//!   plane), inner nodes and leaf boxes also per quadrant of four groups the same way; only
//!   then are leaf boxes tested per group, each lane with its own origin.
//!
//! Triangles are tested against four rays with the same watertight arithmetic as the
//! single-ray path, lane by lane in the same operation order, so every ray gets a
//! bit-identical `t`. Rays that do not fit a packet (other octant or dominant axis) are traced
//! ray by ray by the callers.

use crate::accel::geometry::prepare as prepare_one;
use crate::accel::primitives::{TriangleGroup, triangle_t_uv};
use crate::accel::walk::{
    BoxRay, MAX_INV_DIRECTION, ORDER, SLAB_ERROR, TraversalRay, TraversalStack, child_hits,
    prefetch_node,
};
use crate::accel::wide_bvh::{LEAF_BIT, WideNode};
use crate::accel::{MAX_COORDINATE, Ray};
use glam::{BVec4A, Vec3A, Vec4};

/// Number of rays in a packet.
pub(crate) const LANES: usize = 4;

/// Four rays in structure-of-arrays form (lane `i` = ray `i`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayPacket {
    origin: [Vec4; 3],
    direction: [Vec4; 3],
    inv_direction: [Vec4; 3],
    t_min: Vec4,
    /// Per-lane closest hit so far.
    pub t_max: Vec4,
    /// Barycentrics `(b1, b2)` of the triangle hit at `t_max` (meaningless for other
    /// primitive kinds, which recompute their details).
    pub hit_uv: [Vec4; 2],
    /// Unit normal (x, y, z) of that triangle in the packet's space.
    pub hit_normal: [Vec4; 3],
    octant_inv: u32,
    shear_axes: [usize; 3],
    shear: [Vec4; 3],
    permuted_origin: [Vec4; 3],
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

    /// Packs the rays without checking that they agree; missing lanes copy `filler`'s
    /// geometry with an empty interval, so they never hit.
    fn pack(rays: &[Option<TraversalRay>; LANES], filler: &TraversalRay) -> RayPacket {
        let mut packet = RayPacket {
            origin: [Vec4::ZERO; 3],
            direction: [Vec4::ZERO; 3],
            inv_direction: [Vec4::ZERO; 3],
            t_min: Vec4::INFINITY,
            t_max: Vec4::NEG_INFINITY,
            hit_uv: [Vec4::ZERO; 2],
            hit_normal: [Vec4::ZERO; 3],
            octant_inv: filler.octant_inv,
            shear_axes: filler.shear_axes,
            shear: [Vec4::ZERO; 3],
            permuted_origin: [Vec4::ZERO; 3],
            lanes: 0,
        };
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
    fn prepare_lanes(
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
    fn reset(&mut self) {
        self.lanes = 0;
        self.t_min = Vec4::INFINITY;
        self.t_max = Vec4::NEG_INFINITY;
    }

    /// Puts `ray` into `lane`; the packet takes its octant and dominant axis.
    fn set_lane(&mut self, lane: usize, ray: &TraversalRay) {
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
struct PlaneRows {
    entry: [usize; 3],
    exit: [usize; 3],
}

impl PlaneRows {
    #[inline(always)]
    fn new(octant_inv: u32) -> PlaneRows {
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
fn child_lane_masks(
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

    /// Bounds of the `lanes` of `group` (active ones only); `shared_origin`, when every ray
    /// starts there, spares the origins' reduction.
    fn of_group(group: &RayPacket, lanes: u32, shared_origin: Option<Vec3A>) -> RayBounds {
        let active = lane_mask(group.lanes & lanes);
        let low = |values: Vec4| Vec4::select(active, values, Vec4::INFINITY).min_element();
        let high = |values: Vec4| Vec4::select(active, values, Vec4::NEG_INFINITY).max_element();
        let lows = |values: &[Vec4; 3]| Vec3A::new(low(values[0]), low(values[1]), low(values[2]));
        let highs =
            |values: &[Vec4; 3]| Vec3A::new(high(values[0]), high(values[1]), high(values[2]));
        let (origin_low, origin_high) = match shared_origin {
            Some(origin) => (origin, origin),
            None => (lows(&group.origin), highs(&group.origin)),
        };
        RayBounds {
            inv_low: lows(&group.inv_direction),
            inv_high: highs(&group.inv_direction),
            origin_low,
            origin_high,
            t_min_low: low(group.t_min),
            ..RayBounds::EMPTY
        }
    }

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
        *quadrant = RayBounds::EMPTY;
        for group in members {
            if let Some(packet) = groups.get(group)
                && packet.lanes & active[group] != 0
            {
                *quadrant =
                    quadrant.union(RayBounds::of_group(packet, active[group], shared_origin));
            }
        }
        *whole = whole.union(*quadrant);
        *quadrant = quadrant.finished();
    }
    *whole = whole.finished();
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

/// Lanes of a 4-bit mask as a SIMD mask.
#[inline(always)]
fn lane_mask(lanes: u32) -> BVec4A {
    BVec4A::new(
        lanes & 1 != 0,
        lanes & 2 != 0,
        lanes & 4 != 0,
        lanes & 8 != 0,
    )
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
            groups: [blank.unwrap_or(RayPacket {
                origin: [Vec4::ZERO; 3],
                direction: [Vec4::ZERO; 3],
                inv_direction: [Vec4::ZERO; 3],
                t_min: Vec4::INFINITY,
                t_max: Vec4::NEG_INFINITY,
                hit_uv: [Vec4::ZERO; 2],
                hit_normal: [Vec4::ZERO; 3],
                octant_inv: 0,
                shear_axes: [0, 1, 2],
                shear: [Vec4::ZERO; 3],
                permuted_origin: [Vec4::ZERO; 3],
                lanes: 0,
            }); FRUSTUM_GROUPS],
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
/// AVX2 function).
#[inline(always)]
fn frustum_child_hits<const SPREAD: bool, const AVX2: bool>(
    node: &WideNode,
    rows: &PlaneRows,
    bounds: &RayBounds,
    t_max_high: f32,
) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: `AVX2` is set only by walks compiled for AVX2, entered only on CPUs with it.
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
    use crate::accel::walk::SLAB_ERROR;
    use crate::accel::wide_bvh::WideNode;
    use std::arch::x86_64::*;

    #[target_feature(enable = "avx2")]
    #[inline]
    fn abs(values: __m256) -> __m256 {
        _mm256_andnot_ps(_mm256_set1_ps(-0.0), values)
    }

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
