//! Bottom-level BVH: one wide BVH over the primitives of one geometry.

use crate::accel::frustum::{FRUSTUM_RAYS, FrustumPacket, traverse_frustum};
use crate::accel::packet::{LANES, RayPacket, group_packet, traverse_packet};
use crate::accel::primitives::{
    GROUP_LANES, PackedSphere, PackedTriangle, TriangleGroup, group_closest, is_usable_box,
    sphere_surface, sphere_t, triangle_t_uv,
};
use crate::accel::procedural::{ProceduralPrimitives, ProceduralSlots};
use crate::accel::single_ray;
use crate::accel::tube::{PackedTube, TubePart, TubeSegment, tube_hit, tube_surface};
use crate::accel::walk::{TraversalRay, prefetch, traverse};
use crate::accel::wide_bvh::{
    LeafAlignment, LeafSizing, MAX_PRIMITIVES, PADDING, WideBvh, WideNode, build_wide_bvh,
    group_leaf, leaf_range,
};
use crate::accel::{GeometryPrims, PrimHit, Ray};
use glam::{Vec2, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use rayon::iter::{
    IndexedParallelIterator, IntoParallelIterator, IntoParallelRefIterator, ParallelIterator,
};
use rayon::slice::ParallelSlice;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

static GEOMETRY_BUILDS: AtomicU64 = AtomicU64::new(0);

#[cfg(test)]
thread_local! {
    /// Builds started on this thread, so tests running in parallel can count their own builds.
    pub(crate) static BUILDS_ON_THIS_THREAD: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Total number of [`GeometryBvh::build`] calls in this process.
pub fn geometry_build_count() -> u64 {
    GEOMETRY_BUILDS.load(Ordering::Relaxed)
}

/// Marks, in a quad geometry's primitive ids, the second triangle `(v0, v2, v3)` of a quad.
const QUAD_SECOND_HALF: u32 = 1 << 31;

/// Primitive data in BVH slot order: triangles (and quads' halves) in groups of four slots, one
/// group per leaf, each group holding its triangles' source ids; spheres and tubes one per
/// slot, each tested by its own intersector.
enum PrimitiveData {
    Triangles(Vec<TriangleGroup>),
    Quads(Vec<TriangleGroup>),
    Spheres(Vec<PackedSphere>),
    Tubes(Vec<PackedTube>),
    Procedural(ProceduralSlots),
}

/// A BVH over the primitives of one geometry, in object space.
pub struct GeometryBvh {
    nodes: Vec<WideNode>,
    primitives: PrimitiveData,
    /// Per BVH slot of spheres, tubes and procedural primitives, the index of the source
    /// primitive; empty for triangles and quads, whose ids sit in their groups
    /// ([`GeometryBvh::source_id`]).
    source_ids: Vec<u32>,
    bounds: (Vec3, Vec3),
    primitive_count: usize,
    skipped_primitive_count: usize,
}

#[cfg(test)]
impl GeometryBvh {
    /// Number of leaves in the BVH.
    pub(crate) fn leaf_count(&self) -> usize {
        crate::accel::wide_bvh::leaf_count(&self.nodes)
    }

    /// The tree's shape and surface-area costs.
    pub(crate) fn tree_shape(&self) -> crate::accel::wide_bvh::TreeShape {
        crate::accel::wide_bvh::TreeShape::of(&self.nodes, self.bounds)
    }

    /// For triangles and quads: the closest hit's slot and `t` and the any-hit answer of the
    /// single-ray walks with an inline stack of eight entries (restarting on the heap).
    pub(crate) fn walks_with_small_stack(&self, ray: &TraversalRay) -> (Option<(u32, f32)>, bool) {
        let (PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups)) = &self.primitives
        else {
            panic!("only triangle and quad BVHs have these walks");
        };
        // SAFETY: checked at build (`checked`).
        unsafe { single_ray::test_paths::with_small_stack(&self.nodes, groups, ray) }
    }

    /// For triangles and quads: the closest hit's slot and `t` of the walk of large trees
    /// (`single_ray::LARGE_TREE_NODES`) run on this one, with the inline stack and with a
    /// stack of eight entries.
    pub(crate) fn walks_of_large_trees(&self, ray: &TraversalRay) -> [Option<(u32, f32)>; 2] {
        let (PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups)) = &self.primitives
        else {
            panic!("only triangle and quad BVHs have these walks");
        };
        // SAFETY: checked at build (`checked`).
        unsafe { single_ray::test_paths::with_always_push(&self.nodes, groups, ray) }
    }

    /// The wide nodes (tests inspect their visiting orders).
    #[cfg(test)]
    pub(crate) fn wide_nodes(&self) -> &[WideNode] {
        &self.nodes
    }

    /// FNV-1a over the layout: every node's planes (bits), child codes and visiting orders,
    /// the source ids per slot (quads: with `QUAD_SECOND_HALF`; padding slots repeat their
    /// group's first) and, for triangles and quads, every group's vertex coordinates (bits).
    pub(crate) fn layout_fingerprint(&self) -> u64 {
        let mut hash = 0xcbf2_9ce4_8422_2325u64;
        let mut add = |word: u32| {
            for byte in word.to_le_bytes() {
                hash = (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3);
            }
        };
        for node in &self.nodes {
            node.planes
                .iter()
                .flatten()
                .for_each(|plane| add(plane.to_bits()));
            node.children.iter().for_each(|&code| add(code));
            node.orders.iter().for_each(|&order| add(u32::from(order)));
        }
        if let PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) = &self.primitives {
            groups.iter().flat_map(|group| group.ids).for_each(&mut add);
            for group in groups {
                let coordinates = group
                    .vertices
                    .iter()
                    .flatten()
                    .flat_map(|row| row.to_array());
                coordinates.for_each(|coordinate| add(coordinate.to_bits()));
            }
        } else {
            self.source_ids.iter().for_each(|&id| add(id));
        }
        hash
    }

    /// Closest hit's slot and `t` of the single-ray walk ([`Self::closest_slot`]).
    pub(crate) fn closest_slot_and_t(&self, ray: &TraversalRay) -> Option<(u32, f32)> {
        let mut ray = *ray;
        self.closest_slot(&mut ray)
            .map(|(slot, _)| (slot, ray.t_max))
    }
}

impl std::fmt::Debug for GeometryBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GeometryBvh")
            .field("primitive_count", &self.primitive_count)
            .field("skipped_primitive_count", &self.skipped_primitive_count)
            .field("nodes", &self.nodes.len())
            .field("bounds", &self.bounds)
            .finish()
    }
}

/// Usable primitives in input order with their source ids.
struct Collected<P> {
    primitives: Vec<P>,
    source_ids: Vec<u32>,
}

impl<P> Collected<P> {
    fn with_capacity(capacity: usize) -> Collected<P> {
        Collected {
            primitives: Vec::with_capacity(capacity),
            source_ids: Vec::with_capacity(capacity),
        }
    }

    fn push(&mut self, primitive: P, source_id: u32) {
        self.primitives.push(primitive);
        self.source_ids.push(source_id);
    }
}

fn vertex(positions: &[Vec3], index: u32) -> Option<Vec3> {
    positions.get(index as usize).copied()
}

fn triangle_from(positions: &[Vec3], corners: [u32; 3]) -> Option<PackedTriangle> {
    PackedTriangle::new(
        vertex(positions, corners[0])?,
        vertex(positions, corners[1])?,
        vertex(positions, corners[2])?,
    )
}

/// Boxes of the usable primitives among `count` inputs, in input order, with their source ids;
/// `None` when every input is usable (the ids are then `0..count`, the common case, which
/// needs neither a filter nor an id array). `bounds_of` returns `None` for unusable inputs.
fn usable_boxes(
    count: usize,
    bounds_of: impl Fn(usize) -> Option<Aabb> + Send + Sync,
) -> (Vec<Aabb>, Option<Vec<u32>>) {
    let rejected = AtomicUsize::new(0);
    // Indexed collects write straight into the result; usable boxes are finite and never
    // inverted, so `Aabb::INVALID` marks the rejected ones.
    let boxes: Vec<Aabb> = (0..count)
        .into_par_iter()
        .map(|id| {
            bounds_of(id).unwrap_or_else(|| {
                rejected.fetch_add(1, Ordering::Relaxed);
                Aabb::INVALID
            })
        })
        .collect();
    if rejected.into_inner() == 0 {
        return (boxes, None);
    }
    let source_ids: Vec<u32> = (0..count as u32)
        .into_par_iter()
        .filter(|&id| boxes[id as usize].valid())
        .collect();
    let usable = source_ids
        .par_iter()
        .map(|&id| boxes[id as usize])
        .collect();
    (usable, Some(source_ids))
}

/// `value(index)` for every slot of a BVH's primitive `order`; padding slots take the value
/// of their group's first slot (which every leaf fills).
fn in_slot_order<T: Send>(order: &[u32], value: impl Fn(u32) -> T + Send + Sync) -> Vec<T> {
    order
        .par_iter()
        .enumerate()
        .map(|(slot, &index)| {
            let index = if index == PADDING {
                order[slot - slot % GROUP_LANES]
            } else {
                index
            };
            value(index)
        })
        .collect()
}

/// Triangles in slot order as groups of four, with their source ids.
fn triangle_groups(triangles: &[PackedTriangle], source_ids: &[u32]) -> Vec<TriangleGroup> {
    triangles
        .par_chunks(GROUP_LANES)
        .zip(source_ids.par_chunks(GROUP_LANES))
        .map(|(triangles, ids)| TriangleGroup::new(triangles, ids))
        .collect()
}

/// Builds the BVH over the collected primitives, stores them in BVH slot order (wrapped by
/// `wrap`, which also gets their source ids in slot order) and counts
/// `input_count - accepted` primitives as skipped.
fn bvh_over_collected<P: Copy + Send + Sync>(
    collected: Collected<P>,
    bounds_of: impl Fn(&P) -> Aabb + Send + Sync,
    (sizing, alignment): (LeafSizing, LeafAlignment),
    wrap: impl FnOnce(Vec<P>, &[u32]) -> PrimitiveData,
    (accepted, input_count): (usize, usize),
) -> GeometryBvh {
    let boxes: Vec<Aabb> = collected.primitives.par_iter().map(bounds_of).collect();
    let WideBvh {
        nodes,
        order,
        bounds,
    } = build_wide_bvh(boxes, sizing, alignment);
    let primitives = in_slot_order(&order, |i| collected.primitives[i as usize]);
    let source_ids = in_slot_order(&order, |i| collected.source_ids[i as usize]);
    let primitives = wrap(primitives, &source_ids);
    let source_ids = match primitives {
        PrimitiveData::Triangles(_) | PrimitiveData::Quads(_) => Vec::new(),
        _ => source_ids,
    };
    GeometryBvh {
        nodes,
        primitives,
        source_ids,
        bounds,
        primitive_count: accepted,
        skipped_primitive_count: input_count - accepted,
    }
}

impl GeometryBvh {
    /// Builds the BVH; invalid primitives are skipped (see the module documentation of
    /// `accel`). Increments [`geometry_build_count`].
    pub fn build(prims: GeometryPrims) -> GeometryBvh {
        GEOMETRY_BUILDS.fetch_add(1, Ordering::Relaxed);
        #[cfg(test)]
        BUILDS_ON_THIS_THREAD.with(|count| count.set(count.get() + 1));

        match prims {
            GeometryPrims::Triangles { positions, indices } => {
                let input_count = indices.len();
                let candidates = &indices[..input_count.min(MAX_PRIMITIVES)];
                // Only boxes are gathered before the build; the triangles are packed once, in
                // BVH slot order, straight from the mesh.
                let (boxes, usable_ids) = usable_boxes(candidates.len(), |id| {
                    triangle_from(&positions, candidates[id].to_array()).map(|t| t.bounds())
                });
                let accepted = boxes.len();
                let WideBvh {
                    nodes,
                    order,
                    bounds,
                } = build_wide_bvh(boxes, LeafSizing::Whole, LeafAlignment::Group);
                let source_ids = match usable_ids {
                    None => in_slot_order(&order, |i| i),
                    Some(ids) => in_slot_order(&order, |i| ids[i as usize]),
                };
                // Straight into groups: a grouped order fills whole groups of four slots.
                let groups = source_ids
                    .par_chunks(GROUP_LANES)
                    .map(|ids| {
                        let triangles: [PackedTriangle; GROUP_LANES] =
                            std::array::from_fn(|lane| {
                                let id = ids.get(lane).unwrap_or(&ids[0]);
                                let [v0, v1, v2] = candidates[*id as usize]
                                    .to_array()
                                    .map(|corner| positions[corner as usize]);
                                PackedTriangle::from_usable(v0, v1, v2)
                            });
                        TriangleGroup::new(&triangles[..ids.len()], ids)
                    })
                    .collect();
                GeometryBvh {
                    nodes,
                    primitives: PrimitiveData::Triangles(groups),
                    source_ids: Vec::new(),
                    bounds,
                    primitive_count: accepted,
                    skipped_primitive_count: input_count - accepted,
                }
                .checked()
            }
            GeometryPrims::Quads { positions, indices } => {
                let mut collected = Collected::with_capacity(indices.len() * 2);
                let mut accepted = 0;
                for (id, quad) in indices.iter().enumerate().take(MAX_PRIMITIVES / 2) {
                    let first = triangle_from(&positions, [quad.x, quad.y, quad.z]);
                    let second = triangle_from(&positions, [quad.x, quad.z, quad.w]);
                    accepted += usize::from(first.is_some() || second.is_some());
                    if let Some(triangle) = first {
                        collected.push(triangle, id as u32);
                    }
                    if let Some(triangle) = second {
                        collected.push(triangle, id as u32 | QUAD_SECOND_HALF);
                    }
                }
                bvh_over_collected(
                    collected,
                    PackedTriangle::bounds,
                    (LeafSizing::Whole, LeafAlignment::Group),
                    |triangles, ids| PrimitiveData::Quads(triangle_groups(&triangles, ids)),
                    (accepted, indices.len()),
                )
                .checked()
            }
            GeometryPrims::Spheres { centers, radii } => {
                let mut collected = Collected::with_capacity(centers.len());
                for (id, center) in centers.iter().enumerate().take(MAX_PRIMITIVES) {
                    let sphere = radii
                        .get(id)
                        .and_then(|&radius| PackedSphere::new(*center, radius));
                    if let Some(sphere) = sphere {
                        collected.push(sphere, id as u32);
                    }
                }
                let accepted = collected.primitives.len();
                bvh_over_collected(
                    collected,
                    PackedSphere::bounds,
                    (LeafSizing::Split, LeafAlignment::Packed),
                    |spheres, _| PrimitiveData::Spheres(spheres),
                    (accepted, centers.len()),
                )
            }
        }
    }

    /// Builds the BVH over cones, cylinders and round curve segments; unusable segments are
    /// skipped (see [`PackedTube`]). Increments [`geometry_build_count`].
    pub fn build_tubes(segments: &[TubeSegment]) -> GeometryBvh {
        GEOMETRY_BUILDS.fetch_add(1, Ordering::Relaxed);
        #[cfg(test)]
        BUILDS_ON_THIS_THREAD.with(|count| count.set(count.get() + 1));

        let mut collected = Collected::with_capacity(segments.len());
        for (id, segment) in segments.iter().enumerate().take(MAX_PRIMITIVES) {
            if let Some(tube) = PackedTube::new(segment) {
                collected.push(tube, id as u32);
            }
        }
        let accepted = collected.primitives.len();
        bvh_over_collected(
            collected,
            PackedTube::bounds,
            (LeafSizing::Split, LeafAlignment::Packed),
            |tubes, _| PrimitiveData::Tubes(tubes),
            (accepted, segments.len()),
        )
    }

    /// Builds the BVH over procedural primitives; those without a usable box are skipped.
    /// Increments [`geometry_build_count`].
    pub fn build_procedural(primitives: Arc<dyn ProceduralPrimitives>) -> GeometryBvh {
        GEOMETRY_BUILDS.fetch_add(1, Ordering::Relaxed);
        let count = primitives.count().min(u32::MAX as usize);
        let boxes: Vec<Aabb> = (0..count as u32)
            .map(|id| match primitives.bounds(id) {
                Some((lo, hi)) if lo.cmple(hi).all() => Aabb::new(lo.into(), hi.into()),
                _ => Aabb::INVALID,
            })
            .collect();
        let mut collected = Collected::with_capacity(count);
        for (id, aabb) in boxes.iter().enumerate() {
            if aabb.valid() && is_usable_box(aabb) {
                collected.push(id as u32, id as u32);
            }
        }
        let accepted = collected.primitives.len();
        bvh_over_collected(
            collected,
            |&id| boxes[id as usize],
            (LeafSizing::Split, LeafAlignment::Packed),
            |indices, _| {
                PrimitiveData::Procedural(ProceduralSlots {
                    primitives,
                    indices,
                })
            },
            (accepted, count),
        )
    }

    /// Closest hit with `t` in `[t_min, t_max]`.
    pub fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        let mut ray = prepare(ray)?;
        let (slot, bary) = self.closest_slot(&mut ray)?;
        Some(self.hit_with_barycentrics(slot, bary, &ray))
    }

    /// Whether anything is hit with `t` in `[t_min, t_max]`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        prepare(ray).is_some_and(|mut ray| self.any_hit(&mut ray))
    }

    /// Closest hits of many rays: `hits[i]` receives what `intersect(&rays[i])` would return
    /// (the same `t`; only among primitives hit at exactly the same `t` the reported one may
    /// differ). Ray order and packet forming are as for [`crate::accel::SceneBvh::intersect_packet`].
    /// Extra entries of the longer slice are ignored.
    pub fn intersect_packet(&self, rays: &[Ray], hits: &mut [Option<PrimHit>]) {
        let mut frustum = FrustumPacket::empty();
        for (rays, hits) in rays.chunks(FRUSTUM_RAYS).zip(hits.chunks_mut(FRUSTUM_RAYS)) {
            if frustum.fill_from_rays(rays) {
                let active = std::array::from_fn(|group| frustum.groups[group].lanes);
                let mut closest = [None; FRUSTUM_RAYS];
                self.closest_slots_frustum(&mut frustum, &active, &mut closest);
                for (index, hit) in hits.iter_mut().enumerate() {
                    let group = &frustum.groups[index / LANES];
                    *hit = closest[index].map(|slot| self.packet_hit(slot, group, index % LANES));
                }
                continue;
            }
            for (rays, hits) in rays.chunks(LANES).zip(hits.chunks_mut(LANES)) {
                let prepared = std::array::from_fn(|lane| rays.get(lane).and_then(prepare));
                let Some(mut packet) = RayPacket::new(&prepared) else {
                    for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
                        *hit = self.intersect(ray);
                    }
                    continue;
                };
                let mut closest = [None; LANES];
                let lanes = packet.lanes;
                self.closest_slots_packet(&mut packet, lanes, &mut closest);
                for (lane, hit) in hits.iter_mut().enumerate() {
                    *hit = closest[lane].map(|slot| self.packet_hit(slot, &packet, lane));
                }
            }
        }
    }

    /// Object-space box of all usable primitives; [`EMPTY_BOUNDS`] when there are none.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.bounds
    }

    /// Number of primitives that can be hit (for quads: quads with at least one usable half).
    pub fn primitive_count(&self) -> usize {
        self.primitive_count
    }

    /// Number of input primitives left out as invalid.
    pub fn skipped_primitive_count(&self) -> usize {
        self.skipped_primitive_count
    }

    /// Heap bytes owned: BVH nodes, packed primitives and primitive ids.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        let primitive_bytes = match &self.primitives {
            PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) => {
                groups.capacity() * size_of::<TriangleGroup>()
            }
            PrimitiveData::Spheres(spheres) => spheres.capacity() * size_of::<PackedSphere>(),
            PrimitiveData::Tubes(tubes) => tubes.capacity() * size_of::<PackedTube>(),
            PrimitiveData::Procedural(slots) => slots.memory_bytes(),
        };
        self.nodes.capacity() * size_of::<WideNode>()
            + self.source_ids.capacity() * size_of::<u32>()
            + primitive_bytes
    }

    /// Asserts that a triangle or quad BVH's codes are in range, which the single-ray walks
    /// rely on instead of bounds checks.
    fn checked(self) -> GeometryBvh {
        if let PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) = &self.primitives {
            assert!(single_ray::codes_in_range(&self.nodes, groups.len()));
        }
        self
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Closest hit; shrinks `ray.t_max` to it and returns its BVH slot with, for triangles
    /// and quads, the barycentrics `(b1, b2)` of the hit (zero for other kinds).
    #[inline(always)]
    pub(crate) fn closest_slot(&self, ray: &mut TraversalRay) -> Option<(u32, Vec2)> {
        match &self.primitives {
            PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) => {
                closest_triangle_slot(&self.nodes, groups, ray)
            }
            _ => self.closest_other_slot(ray),
        }
    }

    /// [`Self::closest_slot`] for callers compiled for AVX2 (or AVX-512) as a whole: the
    /// triangle walk is inlined into them.
    ///
    /// # Safety
    /// The caller is compiled for AVX2 or AVX-512 (so the CPU has AVX2).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(crate) unsafe fn closest_slot_avx2(&self, ray: &mut TraversalRay) -> Option<(u32, Vec2)> {
        match &self.primitives {
            #[cfg(not(feature = "kernel-counters"))]
            PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) => {
                // SAFETY: triangle and quad BVHs are checked with `codes_in_range` when built
                // (`GeometryBvh::checked`) and never change afterwards; the caller's promise.
                unsafe { single_ray::closest_triangle_slot_avx2(&self.nodes, groups, ray) }
            }
            _ => self.closest_slot(ray),
        }
    }

    /// The nodes and triangle groups of a triangle or quad BVH (for the walk of eight rays,
    /// `eights.rs`).
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn triangle_walk_data(&self) -> Option<(&[WideNode], &[TriangleGroup])> {
        match &self.primitives {
            PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) => {
                Some((&self.nodes, groups))
            }
            _ => None,
        }
    }

    /// [`Self::closest_slot`] for spheres, tubes and procedural primitives.
    #[inline(never)]
    fn closest_other_slot(&self, ray: &mut TraversalRay) -> Option<(u32, Vec2)> {
        let mut closest = None;
        match &self.primitives {
            PrimitiveData::Triangles(_) | PrimitiveData::Quads(_) => {
                unreachable!("triangle walks are taken by closest_slot")
            }
            PrimitiveData::Spheres(spheres) => {
                traverse::<false, _>(&self.nodes, ray, |code, ray| {
                    let (first, count) = leaf_range(code);
                    let mut found = false;
                    for slot in first..first + count {
                        if let Some(t) = sphere_t(&spheres[slot as usize], ray) {
                            ray.t_max = t;
                            closest = Some((slot, Vec2::ZERO));
                            found = true;
                        }
                    }
                    found
                });
            }
            PrimitiveData::Tubes(tubes) => {
                traverse::<false, _>(&self.nodes, ray, |code, ray| {
                    let (first, count) = leaf_range(code);
                    let mut found = false;
                    for slot in first..first + count {
                        if let Some((t, _)) = tube_hit(&tubes[slot as usize], ray) {
                            ray.t_max = t;
                            closest = Some((slot, Vec2::ZERO));
                            found = true;
                        }
                    }
                    found
                });
            }
            PrimitiveData::Procedural(slots) => {
                traverse::<false, _>(&self.nodes, ray, |code, ray| {
                    let (first, count) = leaf_range(code);
                    let mut found = false;
                    for slot in first..first + count {
                        if let Some(hit) = slots.hit(slot, ray) {
                            ray.t_max = hit.t;
                            closest = Some((slot, Vec2::ZERO));
                            found = true;
                        }
                    }
                    found
                });
            }
        }
        closest
    }

    /// Frustum version of [`Self::closest_slot`] for the `active` lanes of every group;
    /// `closest[4 * group + lane]` receives the slots.
    #[inline]
    pub(crate) fn closest_slots_frustum(
        &self,
        frustum: &mut FrustumPacket,
        active: &[u32; FRUSTUM_RAYS / LANES],
        closest: &mut [Option<u32>; FRUSTUM_RAYS],
    ) {
        #[cfg(target_arch = "x86_64")]
        use crate::isa::Isa;
        use crate::isa::selected;
        match selected() {
            // SAFETY: a path is selected only on CPUs that have it (`crate::isa`).
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe {
                avx2_walks::closest_slots_frustum_avx512(self, frustum, active, closest)
            },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe {
                avx2_walks::closest_slots_frustum_avx2(self, frustum, active, closest)
            },
            _ => self.closest_slots_frustum_on::<false>(frustum, active, closest),
        }
    }

    /// [`Self::closest_slots_frustum`]; `AVX2`: a node's eight child boxes culled in one
    /// vector (only inside an AVX2 or AVX-512 function).
    #[inline(always)]
    fn closest_slots_frustum_on<const AVX2: bool>(
        &self,
        frustum: &mut FrustumPacket,
        active: &[u32; FRUSTUM_RAYS / LANES],
        closest: &mut [Option<u32>; FRUSTUM_RAYS],
    ) {
        let prefetch_leaf = |code: u32| self.prefetch_leaf(code);
        traverse_frustum::<AVX2, _, _>(
            &self.nodes,
            frustum,
            active,
            prefetch_leaf,
            |code, lanes, frustum| {
                // Usually one or two of the sixteen groups reach a leaf: visit just those.
                let mut groups = 0u32;
                for (group, lanes) in lanes.iter().enumerate() {
                    groups |= u32::from(*lanes != 0) << group;
                }
                let (closest_by_group, _) = closest.as_chunks_mut::<LANES>();
                // Two neighbouring groups reaching a triangle leaf together: one eight-ray test.
                let mut pairs = groups & (groups >> 1) & 0x5555;
                while AVX2 && pairs != 0 {
                    let first = pairs.trailing_zeros() as usize;
                    pairs &= pairs - 1;
                    let pair = first..first + 2;
                    if let (Ok(packets), Ok(closest_pair)) = (
                        <&mut [RayPacket; 2]>::try_from(&mut frustum.groups[pair.clone()]),
                        <&mut [[Option<u32>; LANES]; 2]>::try_from(&mut closest_by_group[pair]),
                    ) && self.test_leaf_pair::<AVX2>(
                        code,
                        packets,
                        [lanes[first], lanes[first + 1]],
                        closest_pair,
                    ) {
                        groups &= !(3 << first);
                    }
                }
                while groups != 0 {
                    let group = groups.trailing_zeros() as usize;
                    groups &= groups - 1;
                    self.test_leaf_packet(
                        code,
                        &mut frustum.groups[group],
                        lanes[group],
                        &mut closest_by_group[group],
                    );
                }
            },
        );
    }

    /// Packet version of [`Self::closest_slot`] for the packet's `lanes`: lanes that hit get
    /// their `t_max` shrunk and their slot written to `closest`.
    #[inline]
    pub(crate) fn closest_slots_packet(
        &self,
        packet: &mut RayPacket,
        lanes: u32,
        closest: &mut [Option<u32>; LANES],
    ) {
        traverse_packet(&self.nodes, packet, lanes, |code, lanes, packet| {
            self.test_leaf_packet(code, packet, lanes, closest);
        });
    }

    /// Starts loading the primitives of a leaf.
    #[inline(always)]
    fn prefetch_leaf(&self, code: u32) {
        let (first, _) = leaf_range(code);
        let first = first as usize;
        match &self.primitives {
            PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) => {
                if let Some(group) = groups.get(group_leaf(code).0) {
                    // Bytes 0, 64 and 128 of the 32-aligned group: each of its three lines.
                    prefetch(group);
                    prefetch(&group.vertices[1][1]);
                    prefetch(&group.vertices[2][2]);
                }
            }
            PrimitiveData::Spheres(spheres) => {
                if let Some(sphere) = spheres.get(first) {
                    prefetch(sphere);
                }
            }
            PrimitiveData::Tubes(tubes) => {
                if let Some(tube) = tubes.get(first) {
                    prefetch(tube);
                }
            }
            PrimitiveData::Procedural(_) => {}
        }
    }

    /// [`Self::test_leaf_packet`] of a triangle leaf for two neighbouring groups of a frustum
    /// packet at once (`AVX2`: only inside an AVX2 or AVX-512 function), when both take its
    /// triangles one by one over their rays (at least as many rays as triangles) and share
    /// their shear axes; false, with nothing done, otherwise. The same hits.
    #[inline(always)]
    fn test_leaf_pair<const AVX2: bool>(
        &self,
        code: u32,
        packets: &mut [RayPacket; 2],
        lanes: [u32; 2],
        closest: &mut [[Option<u32>; LANES]; 2],
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            let (PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups)) =
                &self.primitives
            else {
                return false;
            };
            let (group_index, triangles) = group_leaf(code);
            if !lanes
                .iter()
                .all(|lanes| tests_triangle_by_triangle(*lanes, triangles))
                || packets[0].shear_axes != packets[1].shear_axes
            {
                return false;
            }
            for lanes in lanes {
                count_triangle_leaf_test(lanes, triangles);
            }
            let base = group_index as u32 * GROUP_LANES as u32;
            let write = |triangle_lane: usize, hits: [u32; 2]| {
                for (closest, hits) in closest.iter_mut().zip(hits) {
                    record_slot(closest, base + triangle_lane as u32, hits);
                }
            };
            // SAFETY: `AVX2` is set only by walks compiled for AVX2 or AVX-512, entered only on
            // CPUs with them.
            unsafe {
                crate::accel::packet::pair_avx2::group_pair(
                    &groups[group_index],
                    triangles,
                    packets,
                    lanes,
                    write,
                )
            };
            return true;
        }
        let _ = (code, packets, lanes, closest);
        false
    }

    /// Tests a leaf's primitives against the packet's `lanes`; lanes that hit get their
    /// `t_max` shrunk and their slot written to `closest`. Triangles: with fewer rays than the
    /// leaf has triangles each ray tests the leaf's lanes of the group at once, else each
    /// triangle the four rays, in slot order (the same hits either way); spheres and tubes
    /// lane by lane with the single-ray routines.
    #[inline(always)]
    fn test_leaf_packet(
        &self,
        code: u32,
        packet: &mut RayPacket,
        lanes: u32,
        closest: &mut [Option<u32>; LANES],
    ) {
        let (first, count) = leaf_range(code);
        let per_lane = |packet: &mut RayPacket,
                        closest: &mut [Option<u32>; LANES],
                        slot: u32,
                        test: &dyn Fn(&TraversalRay) -> Option<f32>| {
            let mut remaining = lanes;
            while remaining != 0 {
                let lane = remaining.trailing_zeros() as usize;
                remaining &= remaining - 1;
                if let Some(t) = test(&packet.ray(lane)) {
                    packet.t_max[lane] = t;
                    closest[lane] = Some(slot);
                }
            }
        };
        match &self.primitives {
            PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) => {
                let (group_index, leaf_lanes) = group_leaf(code);
                let group = &groups[group_index];
                let base = group_index as u32 * GROUP_LANES as u32;
                let triangles = leaf_lanes;
                count_triangle_leaf_test(lanes, triangles);
                if !tests_triangle_by_triangle(lanes, triangles) {
                    // Fewer rays than triangles: each ray takes the whole group in one pass
                    // (lanes = triangles), the single-ray test with the same hits.
                    let mut remaining = lanes;
                    while remaining != 0 {
                        let lane = remaining.trailing_zeros() as usize;
                        remaining &= remaining - 1;
                        if let Some((hit_lane, t, bary)) =
                            group_closest(group, leaf_lanes, &packet.ray(lane))
                        {
                            packet.record_hit(lane, t, bary, group.triangle(hit_lane).normal());
                            closest[lane] = Some(base + hit_lane as u32);
                        }
                    }
                    return;
                }
                group_packet(group, triangles, packet, lanes, |triangle_lane, hits| {
                    record_slot(closest, base + triangle_lane as u32, hits)
                });
            }
            PrimitiveData::Spheres(spheres) => {
                for slot in first..first + count {
                    let sphere = &spheres[slot as usize];
                    per_lane(packet, closest, slot, &|ray| sphere_t(sphere, ray));
                }
            }
            PrimitiveData::Tubes(tubes) => {
                for slot in first..first + count {
                    let tube = &tubes[slot as usize];
                    per_lane(packet, closest, slot, &|ray| {
                        tube_hit(tube, ray).map(|hit| hit.0)
                    });
                }
            }
            PrimitiveData::Procedural(slots) => {
                for slot in first..first + count {
                    per_lane(packet, closest, slot, &|ray| {
                        slots.hit(slot, ray).map(|hit| hit.t)
                    });
                }
            }
        }
    }

    /// Whether any primitive is hit in the ray's interval.
    #[inline]
    pub(crate) fn any_hit(&self, ray: &mut TraversalRay) -> bool {
        match &self.primitives {
            PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) => {
                any_triangle_hit(&self.nodes, groups, ray)
            }
            PrimitiveData::Spheres(spheres) => {
                traverse::<true, _>(&self.nodes, ray, |code, ray| {
                    let (first, count) = leaf_range(code);
                    (first..first + count)
                        .any(|slot| sphere_t(&spheres[slot as usize], ray).is_some())
                })
            }
            PrimitiveData::Tubes(tubes) => traverse::<true, _>(&self.nodes, ray, |code, ray| {
                let (first, count) = leaf_range(code);
                (first..first + count).any(|slot| tube_hit(&tubes[slot as usize], ray).is_some())
            }),
            PrimitiveData::Procedural(slots) => {
                traverse::<true, _>(&self.nodes, ray, |code, ray| {
                    let (first, count) = leaf_range(code);
                    (first..first + count).any(|slot| slots.hit(slot, ray).is_some())
                })
            }
        }
    }

    /// The source id of the primitive in `slot` (quads: with `QUAD_SECOND_HALF`).
    #[inline(always)]
    fn source_id(&self, slot: u32) -> u32 {
        match &self.primitives {
            PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) => {
                Self::triangle_source_id(groups, slot)
            }
            _ => self.source_ids[slot as usize],
        }
    }

    /// The source id of a triangle or quad slot (quads: with `QUAD_SECOND_HALF`).
    #[inline(always)]
    fn triangle_source_id(groups: &[TriangleGroup], slot: u32) -> u32 {
        let lanes = GROUP_LANES as u32;
        groups[(slot / lanes) as usize].ids[(slot % lanes) as usize]
    }

    /// The triangle in a triangle or quad slot.
    #[inline]
    fn triangle(groups: &[TriangleGroup], slot: u32) -> PackedTriangle {
        let lanes = GROUP_LANES as u32;
        groups[(slot / lanes) as usize].triangle((slot % lanes) as usize)
    }

    /// Full hit record for the primitive in `slot`, found for `lane` of a packet.
    pub(crate) fn packet_hit(&self, slot: u32, packet: &RayPacket, lane: usize) -> PrimHit {
        let uv = Vec2::new(packet.hit_uv[0][lane], packet.hit_uv[1][lane]);
        self.triangle_hit_from_uv(slot, packet.t_max[lane], uv, packet.hit_normal(lane))
            .unwrap_or_else(|| self.hit_details(slot, &packet.ray(lane)))
    }

    /// Full hit record for `slot` found by [`Self::closest_slot`] with `ray` (whose `t_max`
    /// is now the hit) and the barycentrics it returned. Inline, so that the record's normal
    /// reaches the caller in registers (a record returned through memory was reloaded with a
    /// wider load than its stores, which stalls).
    #[inline]
    pub(crate) fn hit_with_barycentrics(
        &self,
        slot: u32,
        bary: Vec2,
        ray: &TraversalRay,
    ) -> PrimHit {
        self.triangle_hit_from_uv(slot, ray.t_max, bary, self.triangle_normal(slot))
            .unwrap_or_else(|| self.hit_details(slot, ray))
    }

    /// The unit normal of the triangle in a triangle or quad slot; zero for other primitives.
    pub(crate) fn triangle_normal(&self, slot: u32) -> Vec3 {
        match &self.primitives {
            PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups) => {
                let lanes = GROUP_LANES as u32;
                groups[(slot / lanes) as usize].normal((slot % lanes) as usize)
            }
            PrimitiveData::Spheres(_) | PrimitiveData::Tubes(_) | PrimitiveData::Procedural(_) => {
                Vec3::ZERO
            }
        }
    }

    /// The hit record of a triangle or quad slot from the `t`, barycentrics and normal its test
    /// produced (bit-identical to what [`Self::hit_details`] recomputes); `None` for spheres
    /// and tubes. The normal comes from the test so that the triangle is not loaded again.
    pub(crate) fn triangle_hit_from_uv(
        &self,
        slot: u32,
        t: f32,
        bary: Vec2,
        normal: Vec3,
    ) -> Option<PrimHit> {
        let (PrimitiveData::Triangles(groups) | PrimitiveData::Quads(groups)) = &self.primitives
        else {
            return None;
        };
        let source_id = Self::triangle_source_id(groups, slot);
        Some(match &self.primitives {
            PrimitiveData::Quads(_) => PrimHit {
                t,
                primitive: source_id & !QUAD_SECOND_HALF,
                uv: quad_coordinates(bary, source_id),
                normal,
            },
            _ => PrimHit {
                t,
                primitive: source_id,
                uv: bary,
                normal,
            },
        })
    }

    /// Full hit record for the primitive in `slot`, found by [`Self::closest_slot`] with this
    /// `ray` (whose `t_max` now equals the hit). The primitive test is repeated: it is
    /// deterministic, so it finds the same `t`.
    pub(crate) fn hit_details(&self, slot: u32, ray: &TraversalRay) -> PrimHit {
        let source_id = self.source_id(slot);
        let slot = slot as usize;
        let miss = || PrimHit {
            t: ray.t_max,
            primitive: source_id & !QUAD_SECOND_HALF,
            uv: Vec2::ZERO,
            normal: Vec3::Z,
        };
        match &self.primitives {
            PrimitiveData::Triangles(groups) => {
                let triangle = &Self::triangle(groups, slot as u32);
                let Some((t, uv)) = triangle_t_uv(triangle, ray) else {
                    return miss();
                };
                PrimHit {
                    t,
                    primitive: source_id,
                    uv,
                    normal: triangle.normal(),
                }
            }
            PrimitiveData::Quads(groups) => {
                let triangle = &Self::triangle(groups, slot as u32);
                let Some((t, bary)) = triangle_t_uv(triangle, ray) else {
                    return miss();
                };
                PrimHit {
                    t,
                    primitive: source_id & !QUAD_SECOND_HALF,
                    uv: quad_coordinates(bary, source_id),
                    normal: triangle.normal(),
                }
            }
            PrimitiveData::Spheres(spheres) => {
                let sphere = &spheres[slot];
                let Some(t) = sphere_t(sphere, ray) else {
                    return miss();
                };
                let (normal, uv) = sphere_surface(sphere, ray, t);
                PrimHit {
                    t,
                    primitive: source_id,
                    uv,
                    normal,
                }
            }
            PrimitiveData::Tubes(tubes) => {
                let tube = &tubes[slot];
                let (t, part) = tube_hit(tube, ray).unwrap_or((ray.t_max, TubePart::Side));
                let (normal, uv) = tube_surface(tube, ray, t, part);
                PrimHit {
                    t,
                    primitive: source_id,
                    uv,
                    normal,
                }
            }
            PrimitiveData::Procedural(slots) => {
                let Some(hit) = slots.hit(slot as u32, ray) else {
                    return miss();
                };
                PrimHit {
                    t: hit.t,
                    primitive: source_id,
                    uv: hit.uv,
                    normal: hit.normal,
                }
            }
        }
    }
}

/// [`GeometryBvh::closest_slot`] over triangle groups (see `single_ray`).
#[cfg(not(feature = "kernel-counters"))]
#[inline]
fn closest_triangle_slot(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &mut TraversalRay,
) -> Option<(u32, Vec2)> {
    // SAFETY: triangle and quad BVHs are checked with `codes_in_range` when built
    // (`GeometryBvh::checked`) and never change afterwards.
    unsafe { single_ray::closest_triangle_slot(nodes, groups, ray) }
}

/// [`GeometryBvh::closest_slot`] over triangle groups through the generic walk, counting its
/// inner nodes, leaves and triangles (`accel::counters`).
#[cfg(feature = "kernel-counters")]
fn closest_triangle_slot(
    nodes: &[WideNode],
    groups: &[TriangleGroup],
    ray: &mut TraversalRay,
) -> Option<(u32, Vec2)> {
    use crate::accel::counters;
    use crate::accel::walk::{BoxRay, BoxTest, child_hits, traverse_with};
    struct CountingBoxTest;
    impl BoxTest for CountingBoxTest {
        fn child_hits(node: &WideNode, ray: &BoxRay, t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
            counters::add(|counts| counts.nodes += 1);
            child_hits(node, ray, t_min, t_max)
        }
    }
    // The per-octant walk stays compiled (not taken while counting), without dead-code
    // warnings.
    let _per_octant_walk: unsafe fn(&[WideNode], &[TriangleGroup], &mut TraversalRay) -> _ =
        single_ray::closest_triangle_slot;
    #[cfg(target_arch = "x86_64")]
    let _inlined_avx2_walk: unsafe fn(&[WideNode], &[TriangleGroup], &mut TraversalRay) -> _ =
        single_ray::closest_triangle_slot_avx2;
    counters::add(|counts| counts.rays += 1);
    let mut closest = None;
    let mut test_leaf = |code: u32, ray: &mut TraversalRay| {
        let (group_index, lanes) = group_leaf(code);
        counters::add(|counts| {
            counts.leaves += 1;
            counts.triangles += u64::from(lanes.count_ones());
        });
        let hit = group_closest(&groups[group_index], lanes, ray);
        if let Some((lane, t, uv)) = hit {
            ray.t_max = t;
            closest = Some(((group_index * GROUP_LANES + lane) as u32, uv));
        }
        hit.is_some()
    };
    traverse_with::<CountingBoxTest, false, _>(nodes, ray, &mut test_leaf);
    closest
}

/// [`GeometryBvh::any_hit`] over triangle groups (see `single_ray`).
#[inline]
fn any_triangle_hit(nodes: &[WideNode], groups: &[TriangleGroup], ray: &TraversalRay) -> bool {
    // SAFETY: as in `closest_triangle_slot`.
    unsafe { single_ray::any_triangle_hit(nodes, groups, ray) }
}

/// The frustum walk compiled for AVX2, and for AVX-512 too: a node's eight child boxes culled
/// per frustum in one vector (the same operations per lane as the four-wide test).
#[cfg(target_arch = "x86_64")]
mod avx2_walks {
    use super::*;

    crate::isa::avx2_and_avx512! {
        pub(super) fn [closest_slots_frustum_avx2, closest_slots_frustum_avx512](
            bvh: &GeometryBvh,
            frustum: &mut FrustumPacket,
            active: &[u32; FRUSTUM_RAYS / LANES],
            closest: &mut [Option<u32>; FRUSTUM_RAYS],
        ) {
            bvh.closest_slots_frustum_on::<true>(frustum, active, closest);
        }
    }
}

/// Maps barycentrics of one half of a quad onto the quad's unit square.
fn quad_coordinates(bary: Vec2, source_id: u32) -> Vec2 {
    let uv = if source_id & QUAD_SECOND_HALF == 0 {
        Vec2::new(bary.x + bary.y, bary.y)
    } else {
        Vec2::new(bary.x, bary.x + bary.y)
    };
    uv.clamp(Vec2::ZERO, Vec2::ONE)
}

pub(crate) fn prepare(ray: &Ray) -> Option<TraversalRay> {
    TraversalRay::new(
        Vec3A::from(ray.origin),
        Vec3A::from(ray.direction),
        ray.t_min,
        ray.t_max,
    )
}

/// Whether a group of four rays (`lanes`, bit per lane) takes a leaf's `triangles` one by one
/// over its rays; with fewer rays than triangles each ray takes the whole group instead (the
/// single-ray test, lanes = triangles). The same hits either way.
#[inline(always)]
fn tests_triangle_by_triangle(lanes: u32, triangles: u32) -> bool {
    lanes.count_ones() >= triangles.count_ones()
}

/// Counts one (group of four rays, triangle leaf) test (`--features kernel-counters`).
#[inline(always)]
fn count_triangle_leaf_test(lanes: u32, triangles: u32) {
    crate::accel::counters::add(|counts| {
        counts.packet_leaf_groups += 1;
        counts.packet_leaf_rays += u64::from(lanes.count_ones());
        counts.packet_triangle_rays += u64::from(lanes.count_ones() * triangles.count_ones());
    });
}

/// Records `slot` as the closest primitive of the rays in `hits` (bit per lane).
#[inline(always)]
fn record_slot(closest: &mut [Option<u32>; LANES], slot: u32, mut hits: u32) {
    while hits != 0 {
        closest[hits.trailing_zeros() as usize] = Some(slot);
        hits &= hits - 1;
    }
}
