//! Procedural primitives: kinds whose boxes and exact ray tests are supplied by the scene layer
//! (isosurface cells), kept in a geometry BVH like spheres and tubes. The tests must be
//! deterministic: the closest hit is found once during traversal and found again for its
//! details.

use std::sync::Arc;

use glam::{Vec2, Vec3};

use crate::accel::Ray;
use crate::accel::walk::TraversalRay;

/// A hit on one procedural primitive, in object space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProceduralHit {
    pub t: f32,
    /// Unit geometric normal (not faced towards the ray).
    pub normal: Vec3,
    pub uv: Vec2,
}

/// A set of primitives the accel layer knows only by their boxes and ray tests.
pub trait ProceduralPrimitives: Send + Sync + std::fmt::Debug {
    /// Number of primitives.
    fn count(&self) -> usize;
    /// Object-space box of primitive `index`; `None` leaves it out of the BVH.
    fn bounds(&self, index: u32) -> Option<(Vec3, Vec3)>;
    /// The closest hit of primitive `index` with `ray.t_min <= t <= ray.t_max`.
    fn intersect(&self, index: u32, ray: &Ray) -> Option<ProceduralHit>;
    /// Heap bytes owned.
    fn memory_bytes(&self) -> usize;
}

/// The primitives of one procedural geometry and, per BVH slot, the index tested there.
pub(crate) struct ProceduralSlots {
    pub primitives: Arc<dyn ProceduralPrimitives>,
    pub indices: Vec<u32>,
}

impl ProceduralSlots {
    /// The hit of the primitive in `slot`.
    #[inline]
    pub fn hit(&self, slot: u32, ray: &TraversalRay) -> Option<ProceduralHit> {
        let ray = Ray::new(
            ray.origin.into(),
            ray.direction.into(),
            ray.t_min,
            ray.t_max,
        );
        self.primitives
            .intersect(self.indices[slot as usize], &ray)
            .filter(|hit| hit.t >= ray.t_min && hit.t <= ray.t_max)
    }

    pub fn memory_bytes(&self) -> usize {
        self.indices.capacity() * 4 + self.primitives.memory_bytes()
    }
}
