//! [`SceneBvh::intersect8_with`] on a scene of several placements: the rays of one direction
//! octant walk the top level together (`top_eights.rs`), and at each leaf the lanes that reach
//! it test its placements in slot order, as each lane's single-ray walk does
//! (`SceneBvh::closest_in_leaf`): a placement of triangles or quads is walked by its object
//! rays of one octant together (`eights.rs`), a lone lane, and every lane on other primitive
//! kinds, by the single-ray path (`GeometryBvh::closest_slot`). Each lane thus meets the same
//! placements in the same order with the same `t_max` as alone, so it finds the same hit, ties
//! between placements included (the one its single walk keeps), and its record is finished by
//! the same code (`SceneBvh::record_of_closest`).

use glam::{Vec2, Vec3A};

use super::{Placement, SceneBvh};
use crate::accel::eights::{Found, RAYS, closest8};
use crate::accel::geometry::prepare;
use crate::accel::top_eights::{TopLevelVisits, walk_top8};
use crate::accel::walk::{TraversalRay, traverse_from};
use crate::accel::wide_bvh::leaf_range;
use crate::accel::{Ray, SceneHit};

/// A placement slot, a primitive slot and barycentrics: a lane's closest hit so far.
type Closest = Option<(u32, u32, Vec2)>;

impl SceneBvh {
    /// Whether eight rays walk this scene's top level together: the AVX2 or AVX-512 path is
    /// selected, traversal is not being counted (see `walk_of_eights`), and some placement of
    /// several holds triangles or quads (on other primitive kinds every lane is tested alone
    /// anyway, and grouping rays for that gains nothing).
    pub(super) fn walks_placements_in_eights(&self) -> bool {
        !crate::accel::counters::ENABLED
            && crate::isa::selected().has_avx2()
            && self.placements.len() > 1
            && self
                .placements
                .iter()
                .any(|placement| placement.geometry.triangle_walk_data().is_some())
    }

    /// [`Self::intersect8_with`] on several placements (see the module's comment), the walks of
    /// eights with stacks of `ENTRIES` entries: a lone ray of its octant, a ray with
    /// `t_min < 0` (the single-ray walk's generic path) and the rays of a top-level walk whose
    /// stack would overflow go ray by ray (a placement's walk that would overflow, lane by lane).
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[target_feature(enable = "avx2")]
    #[inline(never)]
    pub(super) unsafe fn intersect8_placements_avx2<const ENTRIES: usize>(
        &self,
        rays: &[Ray; 8],
        hits: &mut [Option<SceneHit>; 8],
        single_up_to: u32,
    ) {
        let filler = filler_ray();
        let mut pending = 0u32;
        let worlds: [TraversalRay; RAYS] = std::array::from_fn(|lane| match prepare(&rays[lane]) {
            Some(world) => {
                pending |= 1 << lane;
                world
            }
            None => filler,
        });
        for (lane, world) in worlds.iter().enumerate() {
            if pending & (1 << lane) == 0 {
                // Not a usable ray: no hit (as in `closest_hit`).
                hits[lane] = None;
            } else if world.t_min < 0.0 {
                // (A prepared ray's `t_min` is never NaN.)
                pending &= !(1 << lane);
                self.intersect_into(&rays[lane], &mut hits[lane]);
            }
        }
        while pending != 0 {
            let octant = worlds[pending.trailing_zeros() as usize].octant_inv;
            let mut lanes = 0u32;
            for (lane, world) in worlds.iter().enumerate() {
                if pending & (1 << lane) != 0 && world.octant_inv == octant {
                    lanes |= 1 << lane;
                }
            }
            pending &= !lanes;
            let mut visits = PlacementVisits::<ENTRIES> {
                scene: self,
                worlds: &worlds,
                closest: [None; RAYS],
                single_up_to,
            };
            let mut t_max = worlds.map(|world| world.t_max);
            let walked = lanes.count_ones() >= 2
                && walk_top8::<ENTRIES>(
                    &self.nodes,
                    &worlds,
                    lanes,
                    single_up_to,
                    &mut t_max,
                    &mut visits,
                );
            for lane in (0..RAYS).filter(|lane| lanes & (1 << lane) != 0) {
                if !walked {
                    self.intersect_into(&rays[lane], &mut hits[lane]);
                    continue;
                }
                let mut world = worlds[lane];
                world.t_max = t_max[lane];
                hits[lane] = self.record_of_closest(visits.closest[lane], &world);
            }
        }
    }
}

/// A ray for lanes that hold none; never walked.
#[inline]
fn filler_ray() -> TraversalRay {
    TraversalRay::new(Vec3A::ZERO, Vec3A::X, 0.0, 0.0).expect("a unit direction makes a ray")
}

/// The walk of eights' visits on a scene's placements: per lane its closest hit so far.
/// `ENTRIES`: the stack of a placement's walk of eights.
struct PlacementVisits<'a, const ENTRIES: usize> {
    scene: &'a SceneBvh,
    /// The lanes' world rays as prepared (their `t_max` is the walk's).
    worlds: &'a [TraversalRay; RAYS],
    closest: [Closest; RAYS],
    single_up_to: u32,
}

impl<const ENTRIES: usize> TopLevelVisits for PlacementVisits<'_, ENTRIES> {
    #[inline]
    fn leaf(&mut self, code: u32, lanes: u32, t_max: &mut [f32; RAYS]) {
        let (first, count) = leaf_range(code);
        for slot in first..first + count {
            // SAFETY: this runs only inside `intersect8_placements_avx2`, compiled for AVX2
            // and called only on CPUs that have it.
            unsafe { self.placement(slot, lanes, t_max) };
        }
    }

    #[inline]
    fn alone(&mut self, root: u32, lane: usize, t_max: &mut f32) {
        let mut world = self.worlds[lane];
        world.t_max = *t_max;
        let mut closest = self.closest[lane];
        let scene = self.scene;
        traverse_from(&scene.nodes, &mut world, root, |code, world| {
            scene.closest_in_leaf(code, world, &mut closest)
        });
        self.closest[lane] = closest;
        *t_max = world.t_max;
    }
}

impl<const ENTRIES: usize> PlacementVisits<'_, ENTRIES> {
    /// Placement `slot` for the rays in `lanes`, each from its `t_max[lane]`: what
    /// `SceneBvh::closest_in_leaf` does for one ray, for each lane.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn placement(&mut self, slot: u32, lanes: u32, t_max: &mut [f32; RAYS]) {
        let placement = &self.scene.placements[slot as usize];
        let mut usable = 0u32;
        let mut objects: [TraversalRay; RAYS] = std::array::from_fn(|lane| {
            if lanes & (1 << lane) == 0 {
                return filler_ray();
            }
            let mut world = self.worlds[lane];
            world.t_max = t_max[lane];
            match placement.object_ray(&world) {
                Some(object) => {
                    usable |= 1 << lane;
                    object
                }
                None => filler_ray(),
            }
        });
        let Some((nodes, groups)) = placement
            .geometry
            .triangle_walk_data()
            .filter(|(nodes, _)| !nodes.is_empty())
        else {
            for lane in (0..RAYS).filter(|lane| usable & (1 << lane) != 0) {
                self.alone_in(placement, slot, &mut objects[lane], lane, t_max);
            }
            return;
        };
        let mut found = Found {
            hits: [None; RAYS],
            t: [0.0; RAYS],
        };
        let mut rest = usable;
        while rest != 0 {
            // A transform may part the lanes' octants: each octant walks on its own.
            let together = crate::accel::eights::lanes_of_first_octant(&objects, rest);
            rest &= !together;
            // SAFETY: AVX2 is enabled here; triangle and quad BVHs are checked with
            // `codes_in_range` when built; `nodes` is not empty; object rays keep the world
            // rays' `t_min >= 0`.
            let walked = together.count_ones() >= 2
                && unsafe {
                    closest8::<ENTRIES>(
                        nodes,
                        groups,
                        &mut objects,
                        together,
                        self.single_up_to,
                        &mut found,
                    )
                };
            for lane in (0..RAYS).filter(|lane| together & (1 << lane) != 0) {
                if !walked {
                    // The walk may have lowered the object ray's `t_max`: from the lane's.
                    objects[lane].t_max = t_max[lane];
                    self.alone_in(placement, slot, &mut objects[lane], lane, t_max);
                    continue;
                }
                if let Some(hit) = found.hits[lane] {
                    let (primitive_slot, bary) = hit.slot_and_barycentrics();
                    t_max[lane] = found.t[lane];
                    self.closest[lane] = Some((slot, primitive_slot, bary));
                }
            }
        }
    }

    /// Placement `slot` for lane `lane` alone, its ray `object` in the placement's space.
    #[inline]
    fn alone_in(
        &mut self,
        placement: &Placement,
        slot: u32,
        object: &mut TraversalRay,
        lane: usize,
        t_max: &mut [f32; RAYS],
    ) {
        if let Some((primitive_slot, bary)) = placement.geometry.closest_slot(object) {
            t_max[lane] = object.t_max;
            self.closest[lane] = Some((slot, primitive_slot, bary));
        }
    }
}
