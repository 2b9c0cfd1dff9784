//! Tests of the public acceleration API against analytic answers and brute force: shared
//! helpers and references here, one file per topic.

mod brute_force;
mod eights;
mod instances;
mod internals;
mod invalid_input;
mod isa_paths;
mod packets;
mod primitives;
mod scan_chunks;
mod ties;
mod watertight;

use crate::accel::geometry::BUILDS_ON_THIS_THREAD;
use crate::accel::primitives::{PackedSphere, PackedTriangle, sphere_t, triangle_t};
use crate::accel::tube::{PackedTube, tube_hit};
use crate::accel::walk::TraversalRay;
use crate::accel::wide_bvh::{LeafAlignment, LeafSizing};
use crate::accel::*;
use glam::{Affine3A, Quat, UVec3, UVec4, Vec3, Vec3A, vec3};
use std::sync::Arc;

/// Small deterministic generator (xorshift64*), so failures reproduce.
pub(super) struct Rng(u64);

impl Rng {
    pub(super) fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub(super) fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub(super) fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    pub(super) fn range(&mut self, low: f32, high: f32) -> f32 {
        low + (high - low) * self.unit()
    }
    pub(super) fn point(&mut self, low: f32, high: f32) -> Vec3 {
        vec3(
            self.range(low, high),
            self.range(low, high),
            self.range(low, high),
        )
    }
    pub(super) fn direction(&mut self) -> Vec3 {
        loop {
            let v = self.point(-1.0, 1.0);
            let length = v.length();
            if length > 0.05 && length <= 1.0 {
                return v / length;
            }
        }
    }
}

fn ray(origin: Vec3, direction: Vec3) -> Ray {
    Ray::new(origin, direction.normalize(), 0.0, f32::INFINITY)
}

fn assert_close(actual: f32, expected: f32, tolerance: f32) {
    assert!(
        (actual - expected).abs() <= tolerance,
        "{actual} differs from {expected} by more than {tolerance}"
    );
}

fn assert_vec_close(actual: Vec3, expected: Vec3, tolerance: f32) {
    assert!(
        actual.distance(expected) <= tolerance,
        "{actual} differs from {expected} by more than {tolerance}"
    );
}

fn unit_triangle() -> GeometryBvh {
    GeometryBvh::build(GeometryPrims::Triangles {
        positions: vec![
            vec3(0.0, 0.0, 0.0),
            vec3(1.0, 0.0, 0.0),
            vec3(0.0, 1.0, 0.0),
        ],
        indices: vec![UVec3::new(0, 1, 2)],
    })
}

/// A random placement: a scale of 0.3–2 per axis, a turn about a random axis and a shift
/// within `spread` of the origin per axis (the random numbers drawn in that order).
fn random_transform(rng: &mut Rng, spread: f32) -> Affine3A {
    Affine3A::from_scale_rotation_translation(
        vec3(
            rng.range(0.3, 2.0),
            rng.range(0.3, 2.0),
            rng.range(0.3, 2.0),
        ),
        Quat::from_axis_angle(rng.direction(), rng.range(0.0, 6.0)),
        rng.point(-spread, spread),
    )
}

fn identity_instance(geometries: Vec<Arc<GeometryBvh>>) -> InstanceDesc {
    InstanceDesc {
        transform: Affine3A::IDENTITY,
        geometries,
    }
}

// ---------------------------------------------------------------------------------------------
// Brute force references: every primitive tested with the same primitive routines, no BVH.

/// One test geometry: primitives for [`GeometryBvh::build`], or tube segments (cylinders,
/// cones, curve segments) for [`GeometryBvh::build_tubes`], as the scene layer builds them.
#[derive(Clone, Debug)]
enum TestGeometry {
    Prims(GeometryPrims),
    Tubes(Vec<TubeSegment>),
}

impl TestGeometry {
    fn build(&self) -> GeometryBvh {
        match self {
            TestGeometry::Prims(prims) => GeometryBvh::build(prims.clone()),
            TestGeometry::Tubes(segments) => GeometryBvh::build_tubes(segments),
        }
    }
}

impl From<GeometryPrims> for TestGeometry {
    fn from(prims: GeometryPrims) -> TestGeometry {
        TestGeometry::Prims(prims)
    }
}

/// Closest `(t, primitive id)` over all primitives of `geometry`.
fn brute_force(geometry: &TestGeometry, ray: &TraversalRay) -> Option<(f32, u32)> {
    let mut ray = *ray;
    let mut best = None;
    let mut offer = |hit: Option<f32>, id: u32, ray: &mut TraversalRay| {
        if let Some(t) = hit {
            ray.t_max = t;
            best = Some((t, id));
        }
    };
    let prims = match geometry {
        TestGeometry::Prims(prims) => prims,
        TestGeometry::Tubes(segments) => {
            for (id, segment) in segments.iter().enumerate() {
                if let Some(tube) = PackedTube::new(segment) {
                    let hit = tube_hit(&tube, &ray).map(|(t, _)| t);
                    offer(hit, id as u32, &mut ray);
                }
            }
            return best;
        }
    };
    match prims {
        GeometryPrims::Triangles { positions, indices } => {
            for (id, corners) in indices.iter().enumerate() {
                let vertex = |i: u32| positions.get(i as usize).copied();
                if let (Some(a), Some(b), Some(c)) =
                    (vertex(corners.x), vertex(corners.y), vertex(corners.z))
                    && let Some(triangle) = PackedTriangle::new(a, b, c)
                {
                    offer(triangle_t(&triangle, &ray), id as u32, &mut ray);
                }
            }
        }
        GeometryPrims::Quads { positions, indices } => {
            for (id, quad) in indices.iter().enumerate() {
                let vertex = |i: u32| positions[i as usize];
                for corners in [[quad.x, quad.y, quad.z], [quad.x, quad.z, quad.w]] {
                    if let Some(triangle) = PackedTriangle::new(
                        vertex(corners[0]),
                        vertex(corners[1]),
                        vertex(corners[2]),
                    ) {
                        offer(triangle_t(&triangle, &ray), id as u32, &mut ray);
                    }
                }
            }
        }
        GeometryPrims::Spheres { centers, radii } => {
            for (id, (center, radius)) in centers.iter().zip(radii).enumerate() {
                if let Some(sphere) = PackedSphere::new(*center, *radius) {
                    offer(sphere_t(&sphere, &ray), id as u32, &mut ray);
                }
            }
        }
    }
    best
}

fn traversal_ray(ray: &Ray) -> TraversalRay {
    TraversalRay::new(
        ray.origin.into(),
        ray.direction.into(),
        ray.t_min,
        ray.t_max,
    )
    .unwrap()
}

/// Checks a BVH answer against the brute-force answer: equal `t`, and the same primitive
/// unless another primitive is hit at exactly the same `t`.
fn check_against_brute_force(
    prims: &TestGeometry,
    found: Option<(f32, u32)>,
    ray: &TraversalRay,
    context: &str,
) {
    let expected = brute_force(prims, ray);
    match (found, expected) {
        (None, None) => {}
        (Some((t, id)), Some((expected_t, expected_id))) => {
            assert_eq!(t, expected_t, "{context}: t differs");
            if id != expected_id {
                // A tie: the reported primitive must itself be hit at that same t.
                let mut tied = *ray;
                tied.t_min = t;
                tied.t_max = t;
                let only = single_primitive(prims, id);
                assert_eq!(
                    brute_force(&only, &tied).map(|hit| hit.0),
                    Some(t),
                    "{context}: primitive {id} reported instead of {expected_id}"
                );
            }
        }
        (found, expected) => panic!("{context}: BVH gave {found:?}, brute force {expected:?}"),
    }
}

/// The primitive `id` alone (ids of the result restart at 0).
fn single_primitive(geometry: &TestGeometry, id: u32) -> TestGeometry {
    let i = id as usize;
    let prims = match geometry {
        TestGeometry::Prims(prims) => prims,
        TestGeometry::Tubes(segments) => return TestGeometry::Tubes(vec![segments[i]]),
    };
    let single = match prims {
        GeometryPrims::Triangles { positions, indices } => GeometryPrims::Triangles {
            positions: positions.clone(),
            indices: vec![indices[i]],
        },
        GeometryPrims::Quads { positions, indices } => GeometryPrims::Quads {
            positions: positions.clone(),
            indices: vec![indices[i]],
        },
        GeometryPrims::Spheres { centers, radii } => GeometryPrims::Spheres {
            centers: vec![centers[i]],
            radii: vec![radii[i]],
        },
    };
    single.into()
}

fn random_triangles(rng: &mut Rng, count: usize, extent: f32, size: f32) -> GeometryPrims {
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for i in 0..count as u32 {
        let anchor = rng.point(-extent, extent);
        positions.push(anchor);
        positions.push(anchor + rng.point(-size, size));
        positions.push(anchor + rng.point(-size, size));
        indices.push(UVec3::new(3 * i, 3 * i + 1, 3 * i + 2));
    }
    GeometryPrims::Triangles { positions, indices }
}

fn random_quads(rng: &mut Rng, count: usize, extent: f32, size: f32) -> GeometryPrims {
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for i in 0..count as u32 {
        let anchor = rng.point(-extent, extent);
        let u = rng.point(-size, size);
        let v = rng.point(-size, size);
        // Slightly non-planar quads exercise both halves independently.
        let bend = rng.point(-0.1 * size, 0.1 * size);
        positions.extend([anchor, anchor + u, anchor + u + v + bend, anchor + v]);
        indices.push(UVec4::new(4 * i, 4 * i + 1, 4 * i + 2, 4 * i + 3));
    }
    GeometryPrims::Quads { positions, indices }
}

fn random_spheres(rng: &mut Rng, count: usize, extent: f32, size: f32) -> GeometryPrims {
    GeometryPrims::Spheres {
        centers: (0..count).map(|_| rng.point(-extent, extent)).collect(),
        radii: (0..count).map(|_| rng.range(0.05 * size, size)).collect(),
    }
}

/// Capped cylinders, open cylinders, cones capped at their start (some with a pointed end)
/// and round curve segments, in turn.
fn random_tubes(rng: &mut Rng, count: usize, extent: f32, size: f32) -> TestGeometry {
    let segments = (0..count)
        .map(|i| {
            let start = rng.point(-extent, extent);
            let end = start + rng.point(-size, size);
            let start_radius = rng.range(0.02 * size, 0.3 * size);
            let cone = |start_cap, end_cap| TubeKind::Cone { start_cap, end_cap };
            let (end_radius, kind) = match i % 4 {
                0 => (start_radius, cone(true, true)),
                1 => (start_radius, cone(false, false)),
                2 => (rng.range(0.0, 0.3 * size), cone(true, false)),
                _ => (rng.range(0.02 * size, 0.3 * size), TubeKind::Round),
            };
            TubeSegment {
                start,
                end,
                start_radius,
                end_radius,
                kind,
            }
        })
        .collect();
    TestGeometry::Tubes(segments)
}

/// Rays from outside and inside the primitive cloud, some with finite windows.
fn random_rays(rng: &mut Rng, count: usize, extent: f32) -> Vec<Ray> {
    (0..count)
        .map(|i| {
            let origin = rng.point(-1.5 * extent, 1.5 * extent);
            let direction = if i % 2 == 0 {
                rng.direction()
            } else {
                // Aim at the cloud so most rays hit something.
                (rng.point(-extent, extent) - origin).normalize()
            };
            let (t_min, t_max) = match i % 4 {
                0 => (0.0, f32::INFINITY),
                1 => (rng.range(0.0, extent), f32::INFINITY),
                2 => (0.0, rng.range(0.0, 2.0 * extent)),
                _ => (1.0e-3, 3.0 * extent),
            };
            Ray::new(origin, direction, t_min, t_max)
        })
        .collect()
}

fn compare_geometry_with_brute_force(prims: TestGeometry, rays: &[Ray], name: &str) {
    let bvh = prims.build();
    let mut hits = 0;
    for (i, ray) in rays.iter().enumerate() {
        let found = bvh.intersect(ray).map(|hit| (hit.t, hit.primitive));
        let context = format!("{name} ray {i} {ray:?}");
        check_against_brute_force(&prims, found, &traversal_ray(ray), &context);
        assert_eq!(bvh.occluded(ray), found.is_some(), "{context}: occluded");
        hits += usize::from(found.is_some());
    }
    // The comparison is only meaningful if a good share of rays hit something.
    assert!(hits > rays.len() / 5, "{name}: only {hits} hits");
}

// ---------------------------------------------------------------------------------------------
// Test scenes and rays shared by several topics

fn one_sphere(center: Vec3, radius: f32) -> GeometryBvh {
    GeometryBvh::build(GeometryPrims::Spheres {
        centers: vec![center],
        radii: vec![radius],
    })
}

/// The triangles of a grid of `cells`×`cells` squares over `(cells + 1)²` vertices in rows,
/// two per square.
fn grid_indices(cells: u32) -> Vec<UVec3> {
    let corner = |x: u32, y: u32| y * (cells + 1) + x;
    let mut indices = Vec::new();
    for y in 0..cells {
        for x in 0..cells {
            indices.push(UVec3::new(
                corner(x, y),
                corner(x + 1, y),
                corner(x + 1, y + 1),
            ));
            indices.push(UVec3::new(
                corner(x, y),
                corner(x + 1, y + 1),
                corner(x, y + 1),
            ));
        }
    }
    indices
}

fn bumpy_grid(cells: u32) -> (Vec<Vec3>, GeometryPrims) {
    let height = |x: u32, y: u32| ((x * 7 + y * 3) % 5) as f32 * 0.125;
    let mut positions = Vec::new();
    for y in 0..=cells {
        for x in 0..=cells {
            positions.push(vec3(x as f32, y as f32, height(x, y)));
        }
    }
    let indices = grid_indices(cells);
    let prims = GeometryPrims::Triangles {
        positions: positions.clone(),
        indices,
    };
    (positions, prims)
}

/// Groups of four rays: coherent 2x2 camera-like blocks, then incoherent groups, plus a tail
/// that is not a multiple of four.
fn packet_rays(rng: &mut Rng, groups: usize, extent: f32) -> Vec<Ray> {
    let mut rays = Vec::new();
    for group in 0..groups {
        let origin = rng.point(-1.5 * extent, 1.5 * extent);
        let aim = (rng.point(-extent, extent) - origin).normalize();
        let (t_min, t_max) = if group % 3 == 0 {
            (0.0, f32::INFINITY)
        } else {
            (
                rng.range(0.0, 0.3 * extent),
                rng.range(extent, 4.0 * extent),
            )
        };
        for lane in 0..4 {
            let direction = if group % 5 == 4 {
                rng.direction()
            } else {
                let spread = 0.004 * (1 + group % 7) as f32;
                let offset = vec3((lane % 2) as f32, (lane / 2) as f32, 0.0) * spread;
                (aim + offset).normalize()
            };
            rays.push(Ray::new(origin, direction, t_min, t_max));
        }
    }
    rays.truncate(rays.len() - 1);
    rays
}

/// Primary rays of a pinhole camera in 8x8 tiles, each tile as 2x2 blocks (the order
/// `intersect_packet` expects), with a few per-ray windows and broken rays mixed in.
fn camera_tiles(rng: &mut Rng, eye: Vec3, target: Vec3, size: usize) -> Vec<Ray> {
    let forward = (target - eye).normalize();
    let right = forward.cross(Vec3::Z).normalize();
    let up = right.cross(forward);
    let mut rays = Vec::new();
    for tile_row in (0..size).step_by(8) {
        for tile_column in (0..size).step_by(8) {
            for block_row in (tile_row..tile_row + 8).step_by(2) {
                for block_column in (tile_column..tile_column + 8).step_by(2) {
                    for (row, column) in [
                        (block_row, block_column),
                        (block_row, block_column + 1),
                        (block_row + 1, block_column),
                        (block_row + 1, block_column + 1),
                    ] {
                        let u = (column as f32 + 0.5) / size as f32 * 2.0 - 1.0;
                        let v = 1.0 - (row as f32 + 0.5) / size as f32 * 2.0;
                        let direction = (forward + (right * u + up * v) * 0.6).normalize();
                        let mut ray = Ray::new(eye, direction, 0.0, f32::INFINITY);
                        match rng.next_u64() % 16 {
                            0 => ray.t_max = rng.range(1.0, 30.0),
                            1 => ray.t_min = rng.range(0.0, 20.0),
                            2 => ray.direction = Vec3::ZERO,
                            _ => {}
                        }
                        rays.push(ray);
                    }
                }
            }
        }
    }
    rays
}
