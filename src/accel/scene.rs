//! Top-level BVH over instanced geometries.
//!
//! Every (instance, geometry) pair becomes one top-level primitive bounded by the geometry's box
//! transformed to world space, so an instance with several geometries is culled per geometry.
//! Rays enter object space as `inverse(transform) * origin` and `inverse(linear) * direction`
//! without renormalizing, which keeps the ray parameter `t` identical in both spaces.

use crate::accel::frustum::{
    FRUSTUM_RAYS, FrustumPacket, LaneArrays, PacketScratch, RayArrays, traverse_frustum,
};
use crate::accel::geometry::{GeometryBvh, prepare};
use crate::accel::packet::{LANES, RayPacket, traverse_packet};
#[cfg(target_arch = "x86_64")]
use crate::accel::primitives::TriangleGroup;
use crate::accel::walk::{TraversalRay, traverse};
use crate::accel::wide_bvh::{
    LeafAlignment, LeafSizing, MAX_PRIMITIVES, WideBvh, WideNode, build_wide_bvh, leaf_range,
};
use crate::accel::{EMPTY_BOUNDS, InstanceDesc, PrimHit, Ray, SceneHit, bounds_are_empty};
use glam::{Affine3A, Mat3A, Vec2, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use std::sync::Arc;

#[cfg(target_arch = "x86_64")]
mod placements8;
mod split_block;

/// One geometry of one instance.
struct Placement {
    geometry: Arc<GeometryBvh>,
    instance: u32,
    geometry_index: u32,
    /// `None` for the identity transform (rays are used as they are).
    world_to_object: Option<Affine3A>,
    /// Inverse transpose of the linear part: maps object normals to world normals.
    normal_to_world: Mat3A,
}

impl Placement {
    /// The world ray in this geometry's object space; `None` if it degenerates there.
    #[inline(always)]
    fn object_ray(&self, world: &TraversalRay) -> Option<TraversalRay> {
        match &self.world_to_object {
            None => Some(*world),
            Some(inverse) => TraversalRay::new(
                inverse.transform_point3a(world.origin),
                inverse.transform_vector3a(world.direction),
                world.t_min,
                world.t_max,
            ),
        }
    }
}

/// [`SceneBvh::intersect8`]: a subtree that at most this many of the eight rays reach is walked
/// by each of them alone (the single-ray walk; fewer box tests than the walk of eights there).
/// 3, 4 and 5 measured alike on light-field frames grouped by eye, 2 and 6 slower
/// (docs/light-field.md).
const SINGLE_UP_TO: u32 = 4;

/// A BVH over instance placements; cheap to rebuild, never rebuilds geometry BVHs.
pub struct SceneBvh {
    nodes: Vec<WideNode>,
    /// In top-level BVH slot order.
    placements: Vec<Placement>,
    bounds: (Vec3, Vec3),
}

impl std::fmt::Debug for SceneBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SceneBvh")
            .field("placements", &self.placements.len())
            .field("bounds", &self.bounds)
            .finish()
    }
}

/// World box of an object-space box under `transform` (through its eight corners).
fn transform_box(transform: &Affine3A, (min, max): (Vec3, Vec3)) -> (Vec3, Vec3) {
    let mut world = EMPTY_BOUNDS;
    for corner in 0..8 {
        let point = Vec3::new(
            if corner & 1 == 0 { min.x } else { max.x },
            if corner & 2 == 0 { min.y } else { max.y },
            if corner & 4 == 0 { min.z } else { max.z },
        );
        let point = transform.transform_point3(point);
        world = (world.0.min(point), world.1.max(point));
    }
    world
}

/// Whether a transform can be used: finite with a finite, non-singular inverse.
fn usable_inverse(transform: &Affine3A) -> Option<Affine3A> {
    let determinant = transform.matrix3.determinant();
    if !transform.is_finite() || !determinant.is_finite() || determinant == 0.0 {
        return None;
    }
    let inverse = transform.inverse();
    inverse.is_finite().then_some(inverse)
}

impl SceneBvh {
    /// Builds the top level. Instances with unusable transforms and empty geometries are left
    /// out; `SceneHit::instance`/`geometry` still index the given vectors.
    pub fn build(instances: Vec<InstanceDesc>) -> SceneBvh {
        let mut placements = Vec::new();
        let mut boxes = Vec::new();
        for (instance_index, instance) in instances.into_iter().enumerate() {
            let Some(inverse) = usable_inverse(&instance.transform) else {
                continue;
            };
            let identity = instance.transform == Affine3A::IDENTITY;
            let normal_to_world = instance.transform.matrix3.inverse().transpose();
            for (geometry_index, geometry) in instance.geometries.into_iter().enumerate() {
                if geometry.is_empty()
                    || bounds_are_empty(geometry.bounds())
                    || placements.len() == MAX_PRIMITIVES
                {
                    continue;
                }
                let world = transform_box(&instance.transform, geometry.bounds());
                if !world.0.is_finite() || !world.1.is_finite() {
                    continue;
                }
                boxes.push(Aabb::new(world.0.into(), world.1.into()));
                placements.push(Placement {
                    geometry,
                    instance: instance_index as u32,
                    geometry_index: geometry_index as u32,
                    world_to_object: (!identity).then_some(inverse),
                    normal_to_world,
                });
            }
        }
        let WideBvh {
            nodes,
            order,
            bounds,
        } = build_wide_bvh(boxes, LeafSizing::Split, LeafAlignment::Packed);
        let mut slots: Vec<Option<Placement>> = placements.into_iter().map(Some).collect();
        let placements = order
            .iter()
            .filter_map(|&i| slots[i as usize].take())
            .collect();
        SceneBvh {
            nodes,
            placements,
            bounds,
        }
    }

    /// Closest hit with world `t` in `[t_min, t_max]`.
    pub fn intersect(&self, ray: &Ray) -> Option<SceneHit> {
        self.closest_hit::<false>(ray)
    }

    /// [`Self::intersect`] written into `hit`, for loops that keep hits in an array: the
    /// record is stored where it is kept, not returned through a temporary that the caller
    /// copies with wider loads than its stores (a stall per ray).
    #[inline(never)]
    pub fn intersect_into(&self, ray: &Ray, hit: &mut Option<SceneHit>) {
        #[cfg(target_arch = "x86_64")]
        use crate::isa::Isa;
        use crate::isa::selected;
        match selected() {
            // SAFETY: a path is selected only on CPUs that have it (`crate::isa`).
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe { self.intersect_into_avx512(ray, hit) },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { self.intersect_into_avx2(ray, hit) },
            _ => self.intersect_into_baseline(ray, hit),
        }
    }

    /// [`Self::intersect_into`] on the baseline path, out of line like the AVX2 one (inlined
    /// beside the dispatch it compiled to ~20 more instructions per ray).
    #[inline(never)]
    fn intersect_into_baseline(&self, ray: &Ray, hit: &mut Option<SceneHit>) {
        *hit = self.closest_hit::<false>(ray);
    }

    crate::isa::avx2_and_avx512! {
        /// [`Self::intersect_into`] compiled for AVX2 (or AVX-512) as a whole: the single-ray
        /// walk (an AVX2 function) can then be inlined, so a ray pays for one call's set-up
        /// instead of two, and passes its prepared ray and its hit within one frame. The same
        /// operations in the same order (no fused multiply-adds), so the same hit record.
        ///
        /// # Safety
        /// The CPU has the path's features.
        #[inline(never)]
        unsafe fn [intersect_into_avx2, intersect_into_avx512](
            &self,
            ray: &Ray,
            hit: &mut Option<SceneHit>,
        ) {
            *hit = self.closest_hit::<true>(ray);
        }
    }

    /// The body of [`Self::intersect`] and [`Self::intersect_into`]; `INLINE_AVX2`: inside a
    /// function compiled for AVX2 or AVX-512, with the single-ray walk inlined.
    #[inline(always)]
    fn closest_hit<const INLINE_AVX2: bool>(&self, ray: &Ray) -> Option<SceneHit> {
        let mut world = prepare(ray)?;
        // (placement slot, primitive slot, barycentrics)
        let mut closest: Option<(u32, u32, Vec2)> = None;
        if let [placement] = self.placements.as_slice() {
            // A single placement needs no top level: its box test culls no more than the
            // geometry's own root node does.
            // Without a transform the world ray is the object ray (no copy).
            let mut transformed;
            let object = match placement.world_to_object {
                None => &mut world,
                Some(_) => {
                    transformed = placement.object_ray(&world)?;
                    &mut transformed
                }
            };
            let geometry = &placement.geometry;
            #[cfg(target_arch = "x86_64")]
            let (primitive_slot, bary) = if INLINE_AVX2 {
                // SAFETY: `INLINE_AVX2` is set only inside functions compiled for AVX2 or AVX-512.
                unsafe { geometry.closest_slot_avx2(object) }?
            } else {
                geometry.closest_slot(object)?
            };
            #[cfg(not(target_arch = "x86_64"))]
            let (primitive_slot, bary) = geometry.closest_slot(object)?;
            let t = object.t_max;
            return Some(self.single_placement_record(placement, primitive_slot, bary, t, object));
        }
        traverse::<false, _>(self.top_level_nodes(), &mut world, |code, world| {
            self.closest_in_leaf(code, world, &mut closest)
        });
        self.record_of_closest(closest, &world)
    }

    /// The single-ray walk's test of top-level leaf `code`: its placements in slot order, each
    /// with the world ray's current `t_max`; a hit lowers it and becomes `closest` (placement
    /// slot, primitive slot, barycentrics). Whether any placement was hit.
    #[inline(always)]
    fn closest_in_leaf(
        &self,
        code: u32,
        world: &mut TraversalRay,
        closest: &mut Option<(u32, u32, Vec2)>,
    ) -> bool {
        let (first, count) = leaf_range(code);
        let mut found = false;
        for slot in first..first + count {
            let placement = &self.placements[slot as usize];
            let Some(mut object) = placement.object_ray(world) else {
                continue;
            };
            let Some((primitive_slot, bary)) = placement.geometry.closest_slot(&mut object) else {
                continue;
            };
            world.t_max = object.t_max;
            *closest = Some((slot, primitive_slot, bary));
            found = true;
        }
        found
    }

    /// The record of the closest hit a walk of the top level found (`world.t_max` is its `t`).
    #[inline(always)]
    fn record_of_closest(
        &self,
        closest: Option<(u32, u32, Vec2)>,
        world: &TraversalRay,
    ) -> Option<SceneHit> {
        let (slot, primitive_slot, bary) = closest?;
        let placement = &self.placements[slot as usize];
        let object = placement.object_ray(world)?;
        let hit = placement
            .geometry
            .hit_with_barycentrics(primitive_slot, bary, &object);
        Some(self.scene_hit(placement, hit))
    }

    /// The record of the closest hit found on a scene's only placement: primitive
    /// `primitive_slot` at `t` (triangles: barycentrics `bary`; other primitives recompute
    /// their details from `object`, the ray in the placement's space, its `t_max` set to `t`).
    #[inline(always)]
    fn single_placement_record(
        &self,
        placement: &Placement,
        primitive_slot: u32,
        bary: Vec2,
        t: f32,
        object: &mut TraversalRay,
    ) -> SceneHit {
        let geometry = &placement.geometry;
        let normal = geometry.triangle_normal(primitive_slot);
        // Each branch finishes its own record: a merged one went through memory and was
        // reloaded with a wider load than its stores (a stall on every ray).
        match geometry.triangle_hit_from_uv(primitive_slot, t, bary, normal) {
            Some(hit) => self.scene_hit(placement, hit),
            None => {
                object.t_max = t;
                self.scene_hit(placement, geometry.hit_details(primitive_slot, object))
            }
        }
    }

    /// Closest hits of eight rays with any origins (light-field subpixels, interleaved stereo
    /// lattices): `hits[i]` receives exactly what [`Self::intersect_into`] writes for `rays[i]`.
    /// Pays when the eight rays start close together (one eye, or neighbouring eyes): rays
    /// sharing a direction octant walk a scene of one triangle (or quad) geometry together
    /// (`eights.rs`, AVX2), with or without a transform; on a scene of several placements they
    /// walk the top level together (`top_eights.rs`) and each placement of triangles or quads
    /// as on one (`scene/placements8.rs`). Everything else goes ray by ray.
    pub fn intersect8(&self, rays: &[Ray; 8], hits: &mut [Option<SceneHit>; 8]) {
        self.intersect8_with(rays, hits, SINGLE_UP_TO);
    }

    /// [`Self::intersect8`]; subtrees that at most `single_up_to` lanes reach are walked by
    /// each of them alone (0: never).
    pub fn intersect8_with(
        &self,
        rays: &[Ray; 8],
        hits: &mut [Option<SceneHit>; 8],
        single_up_to: u32,
    ) {
        #[cfg(target_arch = "x86_64")]
        if let Some((placement, nodes, groups)) = self.walk_of_eights() {
            // SAFETY: `walk_of_eights` answers only where AVX2 or AVX-512 is selected, which
            // they are only on CPUs that have them (`crate::isa`).
            unsafe {
                self.intersect8_avx2::<{ crate::accel::eights::STACK }>(
                    placement,
                    nodes,
                    groups,
                    rays,
                    hits,
                    single_up_to,
                )
            };
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if self.walks_placements_in_eights() {
            // SAFETY: as above (`walks_placements_in_eights`).
            unsafe {
                self.intersect8_placements_avx2::<{ crate::accel::eights::STACK }>(
                    rays,
                    hits,
                    single_up_to,
                )
            };
            return;
        }
        let _ = single_up_to;
        for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
            self.intersect_into(ray, hit);
        }
    }

    /// Whether [`Self::intersect8`] walks eight rays together here (else it takes them one by
    /// one, and grouping rays for it gains nothing).
    pub fn walks_eights_together(&self) -> bool {
        #[cfg(target_arch = "x86_64")]
        return self.walk_of_eights().is_some() || self.walks_placements_in_eights();
        #[cfg(not(target_arch = "x86_64"))]
        false
    }

    /// The placement, nodes and triangle groups that eight rays can walk together: the AVX2
    /// or AVX-512 path is selected (the walk of eights has an AVX2 build only, which both
    /// take), the scene is one triangle or quad placement, and traversal is not being counted
    /// (a counting build walks rays one by one with the generic walk, whose records the walk of
    /// eights does not follow step by step).
    #[cfg(target_arch = "x86_64")]
    #[inline]
    fn walk_of_eights(&self) -> Option<(&Placement, &[WideNode], &[TriangleGroup])> {
        if crate::accel::counters::ENABLED || !crate::isa::selected().has_avx2() {
            return None;
        }
        let [placement] = self.placements.as_slice() else {
            return None;
        };
        let (nodes, groups) = placement.geometry.triangle_walk_data()?;
        (!nodes.is_empty()).then_some((placement, nodes, groups))
    }

    /// [`Self::intersect8_with`] with a walk of eights whose stack holds `ENTRIES` entries (a
    /// small one in tests, so that the overflow path runs).
    #[cfg(all(test, target_arch = "x86_64"))]
    pub(crate) fn intersect8_with_stack<const ENTRIES: usize>(
        &self,
        rays: &[Ray; 8],
        hits: &mut [Option<SceneHit>; 8],
        single_up_to: u32,
    ) {
        if self.walks_placements_in_eights() {
            // SAFETY: as in `intersect8_with`.
            unsafe { self.intersect8_placements_avx2::<ENTRIES>(rays, hits, single_up_to) };
            return;
        }
        let (placement, nodes, groups) = self
            .walk_of_eights()
            .expect("a scene that eight rays walk together, AVX2 or AVX-512 selected");
        // SAFETY: as in `intersect8_with`.
        unsafe {
            self.intersect8_avx2::<ENTRIES>(placement, nodes, groups, rays, hits, single_up_to)
        };
    }

    /// [`Self::intersect8_with`] through `placement`'s triangle walk `nodes`/`groups`: the
    /// object rays of each direction octant walk together ([`crate::accel::eights`]); a lone
    /// ray of its octant, a ray with `t_min < 0` (the single-ray walk's generic path) and the
    /// rays of a walk whose stack would overflow go ray by ray. Hits are finished as
    /// `closest_hit` finishes them.
    ///
    /// # Safety
    /// The CPU has AVX2; `nodes`/`groups` are `placement`'s triangle walk data, `nodes` not
    /// empty.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    unsafe fn intersect8_avx2<const ENTRIES: usize>(
        &self,
        placement: &Placement,
        nodes: &[WideNode],
        groups: &[TriangleGroup],
        rays: &[Ray; 8],
        hits: &mut [Option<SceneHit>; 8],
        single_up_to: u32,
    ) {
        use crate::accel::eights::{Found, RAYS, closest8};
        // Lanes without an object ray hold a filler and are never walked.
        let filler = TraversalRay::new(Vec3A::ZERO, Vec3A::X, 0.0, 0.0)
            .expect("a unit direction makes a ray");
        let mut usable = 0u32;
        let mut object_rays: [TraversalRay; RAYS] = std::array::from_fn(|lane| {
            match prepare(&rays[lane]).and_then(|world| placement.object_ray(&world)) {
                Some(ray) => {
                    usable |= 1 << lane;
                    ray
                }
                None => filler,
            }
        });
        // Lanes the walk of eights may take: usable with `t_min >= 0`; a ray that is not
        // usable has no hit (as in `closest_hit`).
        let mut pending = 0u32;
        for (lane, ray) in object_rays.iter().enumerate() {
            if usable & (1 << lane) == 0 {
                hits[lane] = None;
            } else if ray.t_min >= 0.0 {
                pending |= 1 << lane;
            } else {
                self.intersect_into(&rays[lane], &mut hits[lane]);
            }
        }
        let mut found = Found {
            hits: [None; RAYS],
            t: [0.0; RAYS],
        };
        while pending != 0 {
            let lanes = crate::accel::eights::lanes_of_first_octant(&object_rays, pending);
            pending &= !lanes;
            // SAFETY: AVX2 is enabled here; triangle and quad BVHs are checked with
            // `codes_in_range` when built; `nodes` is not empty (the caller's promise).
            let walked = lanes.count_ones() >= 2
                && unsafe {
                    closest8::<ENTRIES>(
                        nodes,
                        groups,
                        &mut object_rays,
                        lanes,
                        single_up_to,
                        &mut found,
                    )
                };
            if !walked {
                for lane in (0..RAYS).filter(|lane| lanes & (1 << lane) != 0) {
                    self.intersect_into(&rays[lane], &mut hits[lane]);
                }
                continue;
            }
            for lane in (0..RAYS).filter(|lane| lanes & (1 << lane) != 0) {
                let Some(hit) = found.hits[lane] else {
                    hits[lane] = None;
                    continue;
                };
                let (primitive_slot, bary) = hit.slot_and_barycentrics();
                hits[lane] = Some(self.single_placement_record(
                    placement,
                    primitive_slot,
                    bary,
                    found.t[lane],
                    &mut object_rays[lane],
                ));
            }
        }
    }

    /// Closest hits of many rays: `hits[i]` receives what `intersect(&rays[i])` would return
    /// (the same `t`; only among surfaces hit at exactly the same `t` the reported one may
    /// differ). Meant for primary rays: every 64 consecutive rays should be one 8x8 pixel tile
    /// from one eye point, ordered as sixteen 2x2 blocks of four consecutive rays. Such a
    /// chunk is traced as a frustum packet when its rays share their direction octant,
    /// otherwise as 2x2 packets, otherwise ray by ray; any order is correct, only slower.
    /// Extra entries of the longer slice are ignored.
    pub fn intersect_packet(&self, rays: &[Ray], hits: &mut [Option<SceneHit>]) {
        self.intersect_packet_with(&mut PacketScratch::new(), rays, hits);
    }

    /// [`Self::intersect_packet`] with working memory kept by the caller, for callers that
    /// trace one tile after another (setting up a packet's 6.4 KB costs a few percent of a frame).
    pub fn intersect_packet_with(
        &self,
        scratch: &mut PacketScratch,
        rays: &[Ray],
        hits: &mut [Option<SceneHit>],
    ) {
        #[cfg(target_arch = "x86_64")]
        use crate::isa::Isa;
        match crate::isa::selected() {
            // SAFETY: a path is selected only on CPUs that have it (`crate::isa`).
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe { self.intersect_rays_avx512(scratch, rays, hits) },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { self.intersect_rays_avx2(scratch, rays, hits) },
            _ => self.intersect_rays_on::<false>(scratch, rays, hits),
        }
    }

    crate::isa::avx2_and_avx512! {
        /// [`Self::intersect_packet_with`] compiled for AVX2 (or AVX-512) as a whole, as
        /// [`Self::intersect_arrays_avx2`].
        ///
        /// # Safety
        /// The CPU has the path's features.
        #[inline(never)]
        unsafe fn [intersect_rays_avx2, intersect_rays_avx512](
            &self,
            scratch: &mut PacketScratch,
            rays: &[Ray],
            hits: &mut [Option<SceneHit>],
        ) {
            self.intersect_rays_on::<true>(scratch, rays, hits);
        }
    }

    /// The body of [`Self::intersect_packet_with`]; `AVX2`: inside a function compiled for AVX2
    /// or AVX-512.
    #[inline(always)]
    fn intersect_rays_on<const AVX2: bool>(
        &self,
        scratch: &mut PacketScratch,
        rays: &[Ray],
        hits: &mut [Option<SceneHit>],
    ) {
        for (rays, hits) in rays.chunks(FRUSTUM_RAYS).zip(hits.chunks_mut(FRUSTUM_RAYS)) {
            if scratch.frustum.fill_from_rays_on::<AVX2>(rays) {
                self.frustum_hits(&mut scratch.frustum, hits);
            } else if let Ok(block_hits) =
                <&mut [Option<SceneHit>; FRUSTUM_RAYS]>::try_from(&mut *hits)
            {
                let lanes = LaneArrays::of_rays(rays);
                self.split_block_hits::<AVX2>(scratch, &lanes.arrays(), block_hits);
            } else {
                self.small_packet_hits(rays, hits);
            }
        }
    }

    /// [`Self::intersect_packet_with`] of the 64 rays of a block given as lane arrays
    /// (`hits[i]` for lane `i`); the frustum packet is filled straight from the lanes.
    pub fn intersect_arrays_with(
        &self,
        scratch: &mut PacketScratch,
        arrays: &RayArrays,
        hits: &mut [Option<SceneHit>; FRUSTUM_RAYS],
    ) {
        #[cfg(target_arch = "x86_64")]
        use crate::isa::Isa;
        match crate::isa::selected() {
            // SAFETY: a path is selected only on CPUs that have it (`crate::isa`).
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe { self.intersect_arrays_avx512(scratch, arrays, hits) },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { self.intersect_arrays_avx2(scratch, arrays, hits) },
            _ => self.intersect_arrays_on::<false>(scratch, arrays, hits),
        }
    }

    crate::isa::avx2_and_avx512! {
        /// [`Self::intersect_arrays_with`] compiled for AVX2 (or AVX-512) as a whole: the
        /// packet's fill, bounds and hit records in VEX code. The same operations in the same
        /// order (no fused multiply-adds), so the same hits.
        ///
        /// # Safety
        /// The CPU has the path's features.
        #[inline(never)]
        unsafe fn [intersect_arrays_avx2, intersect_arrays_avx512](
            &self,
            scratch: &mut PacketScratch,
            arrays: &RayArrays,
            hits: &mut [Option<SceneHit>; FRUSTUM_RAYS],
        ) {
            self.intersect_arrays_on::<true>(scratch, arrays, hits);
        }
    }

    /// The body of [`Self::intersect_arrays_with`]; `AVX2`: inside a function compiled for AVX2
    /// or AVX-512.
    #[inline(always)]
    fn intersect_arrays_on<const AVX2: bool>(
        &self,
        scratch: &mut PacketScratch,
        arrays: &RayArrays,
        hits: &mut [Option<SceneHit>; FRUSTUM_RAYS],
    ) {
        if scratch.frustum.fill_from_arrays_on::<AVX2>(arrays) {
            self.frustum_hits(&mut scratch.frustum, hits);
        } else {
            self.split_block_hits::<AVX2>(scratch, arrays, hits);
        }
    }

    /// Closest hits of the rays of a filled frustum packet.
    fn frustum_hits(&self, frustum: &mut FrustumPacket, hits: &mut [Option<SceneHit>]) {
        let closest = self.closest_frustum(frustum);
        for (index, hit) in hits.iter_mut().enumerate() {
            let group = &frustum.groups[index / LANES];
            *hit = closest[index].and_then(|found| self.packet_hit(found, group, index % LANES));
        }
    }

    /// Closest hits of rays that do not make a frustum packet: as 2x2 packets where they
    /// can, otherwise ray by ray.
    fn small_packet_hits(&self, rays: &[Ray], hits: &mut [Option<SceneHit>]) {
        for (rays, hits) in rays.chunks(LANES).zip(hits.chunks_mut(LANES)) {
            let prepared = std::array::from_fn(|lane| rays.get(lane).and_then(prepare));
            let Some(mut packet) = RayPacket::new(&prepared) else {
                for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
                    self.intersect_into(ray, hit);
                }
                continue;
            };
            let closest = self.closest_packet(&mut packet);
            for (lane, hit) in hits.iter_mut().enumerate() {
                *hit = closest[lane].and_then(|found| self.packet_hit(found, &packet, lane));
            }
        }
    }

    /// The full hit of a (placement slot, primitive slot) found for `lane` of a packet (its
    /// `t_max` is the hit; triangle barycentrics come from the packet test). Inlined, so that
    /// the record is written where the caller keeps it, not into a temporary copied with wider
    /// loads than its stores (a stall per lane).
    #[inline(always)]
    fn packet_hit(
        &self,
        (slot, primitive_slot): (u32, u32),
        packet: &RayPacket,
        lane: usize,
    ) -> Option<SceneHit> {
        let placement = &self.placements[slot as usize];
        let uv = Vec2::new(packet.hit_uv[0][lane], packet.hit_uv[1][lane]);
        let (t, normal) = (packet.t_max[lane], packet.hit_normal(lane));
        match placement
            .geometry
            .triangle_hit_from_uv(primitive_slot, t, uv, normal)
        {
            Some(hit) => Some(self.scene_hit(placement, hit)),
            None => {
                let object = placement.object_ray(&packet.ray(lane))?;
                let hit = placement.geometry.hit_details(primitive_slot, &object);
                Some(self.scene_hit(placement, hit))
            }
        }
    }

    /// Per ray of a frustum packet, the closest (placement slot, primitive slot).
    fn closest_frustum(&self, frustum: &mut FrustumPacket) -> [Option<(u32, u32)>; FRUSTUM_RAYS] {
        let mut closest = [None; FRUSTUM_RAYS];
        let active = std::array::from_fn(|group| frustum.groups[group].lanes);
        let mut visit =
            |slot: u32, lanes: &[u32; FRUSTUM_RAYS / LANES], frustum: &mut FrustumPacket| {
                let placement = &self.placements[slot as usize];
                let mut found = [None; FRUSTUM_RAYS];
                if placement.world_to_object.is_none() {
                    placement
                        .geometry
                        .closest_slots_frustum(frustum, lanes, &mut found);
                } else {
                    Self::closest_in_placement_frustum(placement, frustum, lanes, &mut found);
                }
                for (index, primitive_slot) in found.iter().enumerate() {
                    if let Some(primitive_slot) = primitive_slot {
                        closest[index] = Some((slot, *primitive_slot));
                    }
                }
            };
        if self.placements.len() == 1 {
            // As in `intersect`: a single placement is visited without a top level.
            visit(0, &active, frustum);
        } else {
            let no_prefetch = |_| {};
            traverse_frustum::<false, _, _>(
                &self.nodes,
                frustum,
                &active,
                no_prefetch,
                |code, lanes, frustum| {
                    let (first, count) = leaf_range(code);
                    for slot in first..first + count {
                        visit(slot, lanes, frustum);
                    }
                },
            );
        }
        closest
    }

    /// Frustum packet version of [`Self::closest_in_placement`]: the rays keep one origin in
    /// object space, so they stay a frustum packet unless the transform splits their octant.
    fn closest_in_placement_frustum(
        placement: &Placement,
        frustum: &mut FrustumPacket,
        lanes: &[u32; FRUSTUM_RAYS / LANES],
        found: &mut [Option<u32>; FRUSTUM_RAYS],
    ) {
        let object_ray = |frustum: &FrustumPacket, index: usize| {
            let (group, lane) = (index / LANES, index % LANES);
            if lanes[group] & (1 << lane) == 0 {
                return None;
            }
            placement.object_ray(&frustum.groups[group].ray(lane))
        };
        let used = LANES * frustum.group_count;
        let mut object_frustum = FrustumPacket::empty();
        if object_frustum.fill(used, |index| object_ray(frustum, index)) {
            let object_lanes = std::array::from_fn(|group| object_frustum.groups[group].lanes);
            placement
                .geometry
                .closest_slots_frustum(&mut object_frustum, &object_lanes, found);
            for (index, primitive_slot) in found.iter().enumerate() {
                if primitive_slot.is_some() {
                    let (group, lane) = (index / LANES, index % LANES);
                    frustum.groups[group].copy_hit(lane, &object_frustum.groups[group], lane);
                }
            }
            return;
        }
        for (index, found) in found.iter_mut().enumerate().take(used) {
            let Some(mut object) = object_ray(frustum, index) else {
                continue;
            };
            if let Some((primitive_slot, bary)) = placement.geometry.closest_slot(&mut object) {
                let normal = placement.geometry.triangle_normal(primitive_slot);
                frustum.groups[index / LANES].record_hit(index % LANES, object.t_max, bary, normal);
                *found = Some(primitive_slot);
            }
        }
    }

    /// Per lane of a 2x2 packet, the closest (placement slot, primitive slot).
    fn closest_packet(&self, packet: &mut RayPacket) -> [Option<(u32, u32)>; LANES] {
        let mut closest = [None; LANES];
        let mut visit = |slot: u32, lanes: u32, packet: &mut RayPacket| {
            let placement = &self.placements[slot as usize];
            let mut slots = [None; LANES];
            if placement.world_to_object.is_none() {
                placement
                    .geometry
                    .closest_slots_packet(packet, lanes, &mut slots);
            } else {
                self.closest_in_placement(placement, packet, lanes, &mut slots);
            }
            for (lane, found) in slots.iter().enumerate() {
                if let Some(primitive_slot) = found {
                    closest[lane] = Some((slot, *primitive_slot));
                }
            }
        };
        let lanes = packet.lanes;
        if self.placements.len() == 1 {
            // As in `intersect`: a single placement is visited without a top level.
            visit(0, lanes, packet);
        } else {
            traverse_packet(&self.nodes, packet, lanes, |code, lanes, packet| {
                let (first, count) = leaf_range(code);
                for slot in first..first + count {
                    visit(slot, lanes, packet);
                }
            });
        }
        closest
    }

    /// Moves the packet's `lanes` into the placement's object space and finds their closest
    /// hits there; world `t_max` follows the object-space one (the parameter is shared).
    fn closest_in_placement(
        &self,
        placement: &Placement,
        packet: &mut RayPacket,
        lanes: u32,
        slots: &mut [Option<u32>; LANES],
    ) {
        let object_rays: [Option<TraversalRay>; LANES] = std::array::from_fn(|lane| {
            if lanes & (1 << lane) == 0 {
                return None;
            }
            placement.object_ray(&packet.ray(lane))
        });
        if let Some(mut object_packet) = RayPacket::new(&object_rays) {
            let object_lanes = object_packet.lanes;
            placement
                .geometry
                .closest_slots_packet(&mut object_packet, object_lanes, slots);
            for (lane, found) in slots.iter().enumerate() {
                if found.is_some() {
                    packet.copy_hit(lane, &object_packet, lane);
                }
            }
        } else {
            for (lane, object_ray) in object_rays.iter().enumerate() {
                let Some(mut object) = *object_ray else {
                    continue;
                };
                if let Some((primitive_slot, bary)) = placement.geometry.closest_slot(&mut object) {
                    let normal = placement.geometry.triangle_normal(primitive_slot);
                    packet.record_hit(lane, object.t_max, bary, normal);
                    slots[lane] = Some(primitive_slot);
                }
            }
        }
    }

    /// Whether anything is hit with world `t` in `[t_min, t_max]`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        let Some(mut world) = prepare(ray) else {
            return false;
        };
        if let [placement] = self.placements.as_slice() {
            return placement
                .object_ray(&world)
                .is_some_and(|mut object| placement.geometry.any_hit(&mut object));
        }
        traverse::<true, _>(&self.nodes, &mut world, |code, world| {
            let (first, count) = leaf_range(code);
            (first..first + count).any(|slot| {
                let placement = &self.placements[slot as usize];
                placement
                    .object_ray(world)
                    .is_some_and(|mut object| placement.geometry.any_hit(&mut object))
            })
        })
    }

    /// World box of everything in the scene; [`EMPTY_BOUNDS`] when empty.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.bounds
    }

    /// The top-level nodes to traverse; none when a single placement is visited directly.
    fn top_level_nodes(&self) -> &[WideNode] {
        if self.placements.len() == 1 {
            &[]
        } else {
            &self.nodes
        }
    }

    /// The scene's record of `hit` in `placement`. Inlined, and an untransformed placement's
    /// record is finished before any normal is transformed: the object normal then stays in
    /// registers (read back through memory, a 16-byte load over three 4-byte stores stalled
    /// every hit).
    #[inline(always)]
    fn scene_hit(&self, placement: &Placement, hit: PrimHit) -> SceneHit {
        let record = |normal: Vec3| SceneHit {
            t: hit.t,
            instance: placement.instance,
            geometry: placement.geometry_index,
            primitive: hit.primitive,
            uv: hit.uv,
            normal,
            object_normal: hit.normal,
        };
        if placement.world_to_object.is_none() {
            return record(hit.normal);
        }
        let world = (placement.normal_to_world * Vec3A::from(hit.normal)).normalize_or_zero();
        record(if world == Vec3A::ZERO {
            hit.normal
        } else {
            world.into()
        })
    }
}
