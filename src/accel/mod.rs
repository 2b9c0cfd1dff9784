//! Ray-tracing acceleration structures: one wide BVH per geometry ([`GeometryBvh`]) and a
//! top-level BVH over instanced geometries ([`SceneBvh`]), built by obvhs and laid out for the
//! CPU (eight float child boxes per node, triangles four to a leaf group; see `wide_bvh`).
//!
//! # Conventions callers must follow
//!
//! * **Hit interval.** A hit at parameter `t` is reported only if `t_min <= t <= t_max`; both ends
//!   are inclusive. Among equally distant hits any one may be reported.
//! * **Ray validity.** `origin` and `direction` must be finite, `origin` within
//!   [`MAX_COORDINATE`] and `direction` non-zero (it should be unit length so that `t` is a
//!   distance; lengths from 1e-18 up still give correct ray parameters). `t_min`/`t_max` must
//!   not be NaN and `t_min <= t_max`; `t_max` may be `f32::INFINITY`. Invalid rays never hit and
//!   are never occluded. `t_min` may be 0 or even negative: unlike obvhs' own traversal, no hit
//!   is culled for being close to the origin. An instance whose transform takes a ray outside
//!   these limits (absurd scales) is skipped for that ray.
//! * **Self-intersection.** The layer does not know which primitive a secondary ray starts on.
//!   Start secondary rays at the hit point with `t_min = surface_epsilon(hit_point)` (shadow rays
//!   may also end at `t_max = distance_to_light - surface_epsilon(light_position)`). The epsilon is
//!   relative to the magnitude of the coordinates because float rounding of the hit point is.
//!   Sphere and tube tests run in f64, so rays leaving such a surface at 0.6 degrees or more
//!   above the tangent plane do not re-hit it (tested); more grazing ones may.
//! * **Normals** are geometric, unit length and not flipped towards the ray: triangles use
//!   `(v1 - v0) x (v2 - v0)`, quads the normal of the half that was hit, spheres and the sides
//!   and end balls of tubes point outwards, tube caps point away from the tube along its axis.
//! * **Empty boxes.** Bounds of empty geometries and scenes are [`EMPTY_BOUNDS`]: `min = +inf`,
//!   `max = -inf`, so that a union with any other box yields that box.
//! * **Skipped primitives.** Primitives with non-finite data, coordinates beyond
//!   [`MAX_COORDINATE`], out-of-range indices, zero area, a non-positive sphere radius, tube
//!   radii that are negative or both zero, or cones of zero length are left out of the BVH and
//!   can never be hit; they are counted by [`GeometryBvh::skipped_primitive_count`]. Instances
//!   whose transform is not finite or not invertible are left out of the scene.
//! * **Threads.** Builds are parallel through rayon (obvhs' `parallel` feature for the binary
//!   BVH, rayon iterators for packing and collapsing) and use the pool of the calling thread:
//!   call them inside the device pool's `ThreadPool::install`, or they fall back to rayon's
//!   global pool. Traversal is read-only and single-threaded per call; the structures are
//!   `Send + Sync`, so render threads share them.
//! * **Primary rays.** Trace them with `intersect_packet`, 64 rays per 8x8 pixel tile from one
//!   eye point, the tile ordered as sixteen 2x2 blocks; it returns the same hits as `intersect`
//!   (bit-identical `t`, `uv` and normals; only exact ties between surfaces may resolve
//!   differently) at a fraction of the cost. Secondary rays use `intersect`/`occluded`.
//! * **Rebuilds.** [`SceneBvh::build`] only reads the `Arc<GeometryBvh>`s it is given; rebuild a
//!   [`GeometryBvh`] only when its primitives change ([`geometry_build_count`] counts builds).

pub mod counters;
#[cfg(target_arch = "x86_64")]
mod eights;
mod geometry;
pub use crate::isa;
mod binned_sah;
mod collapse;
mod frustum;
#[cfg(target_arch = "x86_64")]
mod lanes8;
mod packet;
mod primitives;
mod procedural;
mod scene;
mod single_ray;
#[cfg(target_arch = "x86_64")]
mod top_eights;
mod tube;
mod walk;
mod wide_bvh;

#[cfg(test)]
mod tests;

#[cfg(test)]
pub(crate) use frustum::QUADRANT_GROUPS;
pub use frustum::{FRUSTUM_RAYS, PacketScratch, RayArrays};
pub use geometry::{GeometryBvh, geometry_build_count};
pub use procedural::{ProceduralHit, ProceduralPrimitives};
pub use scene::SceneBvh;
pub use tube::{TubeKind, TubeSegment};

use glam::{Vec2, Vec3};
use std::sync::Arc;

/// A ray segment `origin + t * direction` for `t` in `[t_min, t_max]` (both inclusive).
/// Laid out as eight floats in this order, so packets load rays eight floats at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Ray {
    pub origin: Vec3,
    /// Unit length, so that `t` is a distance.
    pub direction: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}

impl Ray {
    /// A ray over `[t_min, t_max]`.
    pub fn new(origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Ray {
        Ray {
            origin,
            direction,
            t_min,
            t_max,
        }
    }
}

/// Primitives of one ANARI triangle, quad or sphere geometry, already validated by the scene
/// layer, for [`GeometryBvh::build`]; cylinders, cones and curves are [`TubeSegment`]s for
/// [`GeometryBvh::build_tubes`]. Anything still invalid is skipped during the build (see the
/// module documentation).
#[derive(Clone, Debug)]
pub enum GeometryPrims {
    Triangles {
        positions: Vec<Vec3>,
        indices: Vec<glam::UVec3>,
    },
    /// ANARI quads: quad `(v0, v1, v2, v3)` is split into triangles `(v0, v1, v2)` and
    /// `(v0, v2, v3)`; the reported primitive id is the quad index.
    Quads {
        positions: Vec<Vec3>,
        indices: Vec<glam::UVec4>,
    },
    Spheres {
        centers: Vec<Vec3>,
        radii: Vec<f32>,
    },
}

/// Closest hit against one geometry, in the geometry's object space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimHit {
    pub t: f32,
    /// Index of the primitive in the `GeometryPrims` arrays (the quad index for quads).
    pub primitive: u32,
    /// Triangles: barycentrics `(b1, b2)` of `v1` and `v2`. Quads: local coordinates with
    /// `v0 = (0,0)`, `v1 = (1,0)`, `v2 = (1,1)`, `v3 = (0,1)` (exact for parallelograms).
    /// Spheres: `(longitude / 2pi in [0,1), colatitude / pi in [0,1])` of the object normal
    /// around +z. Tubes (cylinders, cones, curve segments): `(axial position / length in [0,1],
    /// 0)` on the side and end balls; caps give `(0 or 1, distance from axis / radius)`.
    pub uv: Vec2,
    /// Geometric normal in object space, unit length, not faced towards the ray.
    pub normal: Vec3,
}

/// One instance: a transform and the geometries it places.
#[derive(Clone)]
pub struct InstanceDesc {
    /// Object to world.
    pub transform: glam::Affine3A,
    pub geometries: Vec<Arc<GeometryBvh>>,
}

/// Closest hit against a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneHit {
    /// World-space ray parameter (a distance for unit directions).
    pub t: f32,
    /// Index into the `instances` passed to [`SceneBvh::build`].
    pub instance: u32,
    /// Index into that instance's `geometries`.
    pub geometry: u32,
    pub primitive: u32,
    /// Same meaning as [`PrimHit::uv`].
    pub uv: Vec2,
    /// Geometric normal in world space, unit length.
    pub normal: Vec3,
    /// Geometric normal in object space, unit length.
    pub object_normal: Vec3,
}

/// Bounds of anything empty: `min = +inf`, `max = -inf`.
pub const EMPTY_BOUNDS: (Vec3, Vec3) = (Vec3::INFINITY, Vec3::NEG_INFINITY);

/// Primitives with any coordinate (or bound) beyond this magnitude are skipped, and rays whose
/// origin lies beyond it are invalid. Keeps every intermediate of the box and triangle tests
/// finite (the watertight triangle test multiplies three coordinate differences).
pub const MAX_COORDINATE: f32 = 1.0e12;

/// Relative epsilon of [`surface_epsilon`].
pub const SURFACE_EPSILON_SCALE: f32 = 1.0e-4;

/// `t_min` to use for a ray leaving a surface at `point` (shadow, reflection and bounce rays).
/// Equals `SURFACE_EPSILON_SCALE * max(1, largest |coordinate| of point)`.
pub fn surface_epsilon(point: Vec3) -> f32 {
    SURFACE_EPSILON_SCALE * point.abs().max_element().max(1.0)
}

/// Returns whether a box is empty (min > max on some axis, as for [`EMPTY_BOUNDS`]).
pub fn bounds_are_empty(bounds: (Vec3, Vec3)) -> bool {
    bounds.0.cmpgt(bounds.1).any()
}
