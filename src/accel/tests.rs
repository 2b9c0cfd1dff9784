//! Tests of the public acceleration API against analytic answers and brute force.

use crate::accel::geometry::BUILDS_ON_THIS_THREAD;
use crate::accel::primitives::{PackedSphere, PackedTriangle, sphere_t, triangle_t};
use crate::accel::tube::{PackedTube, tube_hit};
use crate::accel::walk::TraversalRay;
use crate::accel::wide_bvh::{LeafAlignment, LeafSizing};
use crate::accel::*;
use glam::{Affine3A, Quat, UVec3, UVec4, Vec3, Vec3A, vec3};
use std::sync::Arc;

/// Small deterministic generator (xorshift64*), so failures reproduce.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, low: f32, high: f32) -> f32 {
        low + (high - low) * self.unit()
    }
    fn point(&mut self, low: f32, high: f32) -> Vec3 {
        vec3(
            self.range(low, high),
            self.range(low, high),
            self.range(low, high),
        )
    }
    fn direction(&mut self) -> Vec3 {
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
// Triangles and quads

#[test]
fn triangle_hit_has_analytic_t_uv_and_normal() {
    let bvh = unit_triangle();
    let hit = bvh
        .intersect(&ray(vec3(0.25, 0.5, 5.0), vec3(0.0, 0.0, -1.0)))
        .unwrap();
    assert_eq!(hit.t, 5.0);
    assert_eq!(hit.primitive, 0);
    assert_vec_close(hit.uv.extend(0.0), vec3(0.25, 0.5, 0.0), 1e-6);
    assert_eq!(hit.normal, Vec3::Z);
    // From below the normal is not flipped.
    let below = bvh
        .intersect(&ray(vec3(0.25, 0.25, -2.0), Vec3::Z))
        .unwrap();
    assert_eq!(below.t, 2.0);
    assert_eq!(below.normal, Vec3::Z);
    // Oblique ray: t is the distance to the plane point.
    let target = vec3(0.2, 0.3, 0.0);
    let origin = vec3(3.0, -1.0, 4.0);
    let hit = bvh.intersect(&ray(origin, target - origin)).unwrap();
    assert_close(hit.t, origin.distance(target), 1e-5);
    assert_vec_close(hit.uv.extend(0.0), vec3(0.2, 0.3, 0.0), 1e-5);
}

#[test]
fn tilted_triangle_hits_carry_its_unit_normal_on_both_paths() {
    // (v1 - v0) x (v2 - v0) = (1, 0, 1) x (0, 1, 0) = (-1, 0, 1).
    let bvh = Arc::new(GeometryBvh::build(GeometryPrims::Triangles {
        positions: vec![
            vec3(0.0, 0.0, 0.0),
            vec3(1.0, 0.0, 1.0),
            vec3(0.0, 1.0, 0.0),
        ],
        indices: vec![UVec3::new(0, 1, 2)],
    }));
    let expected = vec3(-1.0, 0.0, 1.0).normalize();
    let single = bvh
        .intersect(&ray(vec3(0.25, 0.25, 5.0), -Vec3::Z))
        .unwrap();
    assert_vec_close(single.normal, expected, 1e-7);
    // A packet of primary rays from one eye goes through the packet test and its hit records.
    let scene = SceneBvh::build(vec![identity_instance(vec![bvh])]);
    let eye = vec3(0.2, 0.2, 5.0);
    let rays: Vec<Ray> = (0..64)
        .map(|i| {
            let target = vec3(
                0.1 + 0.05 * (i % 8) as f32,
                0.1 + 0.05 * (i / 8) as f32,
                0.0,
            );
            Ray::new(eye, target - eye, 0.0, f32::INFINITY)
        })
        .collect();
    let mut hits = [None; 64];
    scene.intersect_packet(&rays, &mut hits);
    let mut hit_count = 0;
    for (ray, hit) in rays.iter().zip(&hits) {
        let single = scene.intersect(ray);
        assert_eq!(hit.map(|h| h.t), single.map(|h| h.t));
        if let Some(hit) = hit {
            assert_vec_close(hit.normal, expected, 1e-7);
            hit_count += 1;
        }
    }
    assert!(hit_count > 20, "{hit_count} hits");
}

#[test]
fn triangle_misses() {
    let bvh = unit_triangle();
    assert!(
        bvh.intersect(&ray(vec3(0.75, 0.75, 5.0), -Vec3::Z))
            .is_none()
    );
    assert!(
        bvh.intersect(&ray(vec3(0.25, 0.25, 5.0), Vec3::Z))
            .is_none()
    );
    // Parallel to the plane, inside it.
    assert!(bvh.intersect(&ray(vec3(-1.0, 0.2, 0.0), Vec3::X)).is_none());
    assert!(!bvh.occluded(&ray(vec3(0.75, 0.75, 5.0), -Vec3::Z)));
}

#[test]
fn t_window_is_inclusive_at_both_ends() {
    let bvh = unit_triangle();
    let at = |t_min: f32, t_max: f32| Ray::new(vec3(0.25, 0.25, 4.0), -Vec3::Z, t_min, t_max);
    assert_eq!(bvh.intersect(&at(0.0, 4.0)).map(|hit| hit.t), Some(4.0));
    assert_eq!(bvh.intersect(&at(4.0, 10.0)).map(|hit| hit.t), Some(4.0));
    assert_eq!(bvh.intersect(&at(4.0, 4.0)).map(|hit| hit.t), Some(4.0));
    assert!(bvh.intersect(&at(0.0, 3.999_999_5)).is_none());
    assert!(bvh.intersect(&at(4.000_001, 10.0)).is_none());
    assert!(bvh.occluded(&at(0.0, 4.0)));
    assert!(!bvh.occluded(&at(0.0, 3.9)));
    assert!(!bvh.occluded(&at(4.1, 100.0)));
}

#[test]
fn closest_of_stacked_triangles_wins_and_window_selects_others() {
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for (i, z) in [3.0f32, 1.0, 2.0].into_iter().enumerate() {
        let base = 3 * i as u32;
        positions.extend([vec3(-1.0, -1.0, z), vec3(2.0, -1.0, z), vec3(-1.0, 2.0, z)]);
        indices.push(UVec3::new(base, base + 1, base + 2));
    }
    let bvh = GeometryBvh::build(GeometryPrims::Triangles { positions, indices });
    let down = |t_min: f32, t_max: f32| Ray::new(vec3(0.0, 0.0, 10.0), -Vec3::Z, t_min, t_max);
    let hit = |ray: Ray| bvh.intersect(&ray).map(|hit| (hit.t, hit.primitive));
    assert_eq!(hit(down(0.0, f32::INFINITY)), Some((7.0, 0)));
    assert_eq!(hit(down(7.5, f32::INFINITY)), Some((8.0, 2)));
    assert_eq!(hit(down(8.5, f32::INFINITY)), Some((9.0, 1)));
    assert_eq!(hit(down(9.5, f32::INFINITY)), None);
    assert_eq!(hit(down(0.0, 6.0)), None);
}

#[test]
fn quads_report_quad_index_and_local_coordinates() {
    let positions = vec![
        vec3(10.0, 10.0, 0.0),
        vec3(0.0, 0.0, 0.0),
        vec3(2.0, 0.0, 0.0),
        vec3(2.0, 2.0, 0.0),
        vec3(0.0, 2.0, 0.0),
    ];
    // Quad 0 is degenerate (all corners equal): skipped.
    let indices = vec![UVec4::new(0, 0, 0, 0), UVec4::new(1, 2, 3, 4)];
    let bvh = GeometryBvh::build(GeometryPrims::Quads { positions, indices });
    assert_eq!(bvh.primitive_count(), 1);
    assert_eq!(bvh.skipped_primitive_count(), 1);

    let first_half = bvh.intersect(&ray(vec3(1.5, 0.5, 3.0), -Vec3::Z)).unwrap();
    assert_eq!(first_half.primitive, 1);
    assert_eq!(first_half.t, 3.0);
    assert_vec_close(first_half.uv.extend(0.0), vec3(0.75, 0.25, 0.0), 1e-6);
    assert_eq!(first_half.normal, Vec3::Z);

    let second_half = bvh.intersect(&ray(vec3(0.5, 1.5, 3.0), -Vec3::Z)).unwrap();
    assert_eq!(second_half.primitive, 1);
    assert_vec_close(second_half.uv.extend(0.0), vec3(0.25, 0.75, 0.0), 1e-6);
    assert_eq!(second_half.normal, Vec3::Z);

    assert!(bvh.intersect(&ray(vec3(2.5, 0.5, 3.0), -Vec3::Z)).is_none());
}

#[test]
fn quad_with_one_degenerate_half_keeps_the_other() {
    // v2 == v3: the second triangle (v0, v2, v3) has no area.
    let positions = vec![
        vec3(0.0, 0.0, 0.0),
        vec3(1.0, 0.0, 0.0),
        vec3(1.0, 1.0, 0.0),
    ];
    let bvh = GeometryBvh::build(GeometryPrims::Quads {
        positions,
        indices: vec![UVec4::new(0, 1, 2, 2)],
    });
    assert_eq!(bvh.primitive_count(), 1);
    let hit = bvh
        .intersect(&ray(vec3(0.75, 0.25, 1.0), -Vec3::Z))
        .unwrap();
    assert_eq!(hit.primitive, 0);
    assert!(
        bvh.intersect(&ray(vec3(0.25, 0.75, 1.0), -Vec3::Z))
            .is_none()
    );
}

fn bumpy_grid(cells: u32) -> (Vec<Vec3>, GeometryPrims) {
    let height = |x: u32, y: u32| ((x * 7 + y * 3) % 5) as f32 * 0.125;
    let mut positions = Vec::new();
    for y in 0..=cells {
        for x in 0..=cells {
            positions.push(vec3(x as f32, y as f32, height(x, y)));
        }
    }
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
    let prims = GeometryPrims::Triangles {
        positions: positions.clone(),
        indices,
    };
    (positions, prims)
}

#[test]
fn nearly_axis_parallel_rays_through_box_corners_are_not_culled() {
    // Regression: this ray meets a grid vertex where three box faces meet while running almost
    // parallel to x; slab rounding amplified by 1/dx once culled the box.
    let (positions, prims) = bumpy_grid(16);
    let prims = TestGeometry::from(prims);
    let bvh = prims.build();
    let origin = vec3(14.014053, 3.7264585, 10.0);
    let test_ray = ray(origin, vec3(14.0, 9.0, 0.0) - origin);
    let expected = brute_force(&prims, &traversal_ray(&test_ray));
    assert!(expected.is_some());
    assert_eq!(
        bvh.intersect(&test_ray).map(|hit| (hit.t, hit.primitive)),
        expected
    );
    // The same at every grid vertex, from directions within 1e-3 of an axis-aligned plane.
    let mut rng = Rng::new(77);
    for y in 1..16 {
        for x in 1..16 {
            let position = positions[(y * 17 + x) as usize];
            for _ in 0..4 {
                let mut offset = vec3(rng.range(-8.0, 8.0), rng.range(-8.0, 8.0), 10.0);
                if rng.unit() < 0.5 {
                    offset.x = rng.range(-1e-2, 1e-2);
                } else {
                    offset.y = rng.range(-1e-2, 1e-2);
                }
                let test_ray = ray(position + offset, -offset);
                let expected = brute_force(&prims, &traversal_ray(&test_ray));
                let found = bvh.intersect(&test_ray).map(|hit| (hit.t, hit.primitive));
                check_against_brute_force(&prims, found, &traversal_ray(&test_ray), "corner");
                assert!(expected.is_some(), "{test_ray:?} leaked");
            }
        }
    }
}

#[test]
fn grid_is_watertight_along_shared_edges_and_vertices() {
    // A bumpy 16x16 grid; rays aimed exactly at its vertices and edge midpoints must all hit.
    let cells = 16u32;
    let (positions, prims) = bumpy_grid(cells);
    let corner = |x: u32, y: u32| y * (cells + 1) + x;
    let bvh = GeometryBvh::build(prims);
    let mut rng = Rng::new(7);
    let mut targets = Vec::new();
    for y in 1..cells {
        for x in 1..cells {
            let p = positions[corner(x, y) as usize];
            let right = positions[corner(x + 1, y) as usize];
            let up = positions[corner(x, y + 1) as usize];
            let diagonal = positions[corner(x + 1, y + 1) as usize];
            targets.extend([p, (p + right) * 0.5, (p + up) * 0.5, (p + diagonal) * 0.5]);
        }
    }
    for target in targets {
        for _ in 0..4 {
            let origin = target + vec3(rng.range(-8.0, 8.0), rng.range(-8.0, 8.0), 10.0);
            let hit = bvh.intersect(&ray(origin, target - origin));
            let hit = hit.unwrap_or_else(|| panic!("ray from {origin} to {target} leaked"));
            assert_close(hit.t, origin.distance(target), 1e-3);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Spheres

fn one_sphere(center: Vec3, radius: f32) -> GeometryBvh {
    GeometryBvh::build(GeometryPrims::Spheres {
        centers: vec![center],
        radii: vec![radius],
    })
}

#[test]
fn sphere_hits_from_outside_and_inside() {
    let bvh = one_sphere(vec3(0.0, 0.0, -10.0), 2.0);
    let hit = bvh.intersect(&ray(Vec3::ZERO, -Vec3::Z)).unwrap();
    assert_eq!(hit.t, 8.0);
    assert_eq!(hit.primitive, 0);
    assert_vec_close(hit.normal, Vec3::Z, 1e-6);
    assert_close(hit.uv.y, 0.0, 1e-3);

    let inside = bvh.intersect(&ray(vec3(0.0, 0.0, -10.0), Vec3::X)).unwrap();
    assert_eq!(inside.t, 2.0);
    assert_vec_close(inside.normal, Vec3::X, 1e-6);
    assert_close(inside.uv.x, 0.0, 1e-6);
    assert_close(inside.uv.y, 0.5, 1e-6);

    // Behind the origin, beside the sphere, and outside the window.
    assert!(bvh.intersect(&ray(Vec3::ZERO, Vec3::Z)).is_none());
    assert!(bvh.intersect(&ray(vec3(2.5, 0.0, 0.0), -Vec3::Z)).is_none());
    assert!(
        bvh.intersect(&Ray::new(Vec3::ZERO, -Vec3::Z, 0.0, 7.9))
            .is_none()
    );
    // With t_min past the front, the back is hit.
    let back = bvh
        .intersect(&Ray::new(Vec3::ZERO, -Vec3::Z, 9.0, f32::INFINITY))
        .unwrap();
    assert_eq!(back.t, 12.0);
    assert_vec_close(back.normal, -Vec3::Z, 1e-6);
}

#[test]
fn sphere_oblique_hit_matches_analytic_solution() {
    let center = vec3(1.0, 2.0, -7.0);
    let radius = 1.5;
    let bvh = one_sphere(center, radius);
    let mut rng = Rng::new(11);
    for _ in 0..200 {
        let origin = rng.point(-3.0, 3.0);
        let target = center + rng.direction() * radius * 0.9;
        let direction = (target - origin).normalize();
        let hit = bvh
            .intersect(&Ray::new(origin, direction, 0.0, f32::INFINITY))
            .unwrap();
        // f64 reference on exactly the same (f32) ray.
        let o = origin.as_dvec3() - center.as_dvec3();
        let d = direction.as_dvec3();
        let a = d.length_squared();
        let b = o.dot(d);
        let c = o.length_squared() - (radius as f64).powi(2);
        let t = (-b - (b * b - a * c).sqrt()) / a;
        assert_close(hit.t, t as f32, 1e-5);
        let expected_normal = ((o + d * t) / radius as f64).as_vec3();
        assert_vec_close(hit.normal, expected_normal, 1e-5);
        assert_close(hit.normal.length(), 1.0, 1e-6);
    }
}

#[test]
fn far_away_and_huge_spheres_are_accurate() {
    // A unit sphere a million units away: the naive b^2 - c discriminant cancels completely.
    let far = one_sphere(vec3(0.0, 0.0, -1.0e6), 1.0);
    let hit = far.intersect(&ray(Vec3::ZERO, -Vec3::Z)).unwrap();
    assert_close(hit.t, 1.0e6 - 1.0, 0.07);
    assert_vec_close(hit.normal, Vec3::Z, 1e-3);
    // Off-centre rays at that distance still hit or miss correctly.
    let grazing = Ray::new(vec3(0.9, 0.0, 0.0), -Vec3::Z, 0.0, f32::INFINITY);
    assert!(far.intersect(&grazing).is_some());
    let missing = Ray::new(vec3(1.1, 0.0, 0.0), -Vec3::Z, 0.0, f32::INFINITY);
    assert!(far.intersect(&missing).is_none());

    // A planet-sized sphere whose surface is 10 units away.
    let huge = one_sphere(vec3(0.0, -1.0e5, 0.0), 1.0e5 - 10.0);
    let hit = huge.intersect(&ray(Vec3::ZERO, -Vec3::Y)).unwrap();
    assert_close(hit.t, 10.0, 0.01);
    assert_vec_close(hit.normal, Vec3::Y, 1e-6);

    // A tiny sphere.
    let tiny = one_sphere(vec3(0.0, 0.0, -100.0), 1.0e-3);
    let hit = tiny.intersect(&ray(Vec3::ZERO, -Vec3::Z)).unwrap();
    assert_close(hit.t, 100.0 - 1.0e-3, 1e-5);
}

#[test]
fn rays_leaving_a_sphere_surface_do_not_hit_it_again() {
    let mut rng = Rng::new(3);
    for (center, radius) in [
        (Vec3::ZERO, 1.0f32),
        (vec3(300.0, -200.0, 50.0), 20.0),
        (vec3(0.0, 0.0, -5000.0), 1000.0),
    ] {
        let bvh = one_sphere(center, radius);
        for _ in 0..500 {
            // A surface point as the renderer gets it: from a primary hit.
            let origin = center + rng.direction() * radius * 3.0;
            let target = center + rng.direction() * radius * 0.5;
            let Some(hit) = bvh.intersect(&ray(origin, target - origin)) else {
                continue;
            };
            let point = origin + (target - origin).normalize() * hit.t;
            let epsilon = surface_epsilon(point);
            // Outgoing directions at least ~0.6 degrees above the tangent plane.
            let mut outward = rng.direction();
            if outward.dot(hit.normal) < 0.0 {
                outward = -outward;
            }
            if outward.dot(hit.normal) < 0.01 {
                continue;
            }
            let shadow = Ray::new(point, outward, epsilon, f32::INFINITY);
            assert!(
                !bvh.occluded(&shadow),
                "self-hit leaving {point} along {outward} (eps {epsilon})"
            );
            // Inward rays hit the far side at the chord length.
            let inward = -outward;
            let chord = 2.0 * radius * inward.dot(-hit.normal);
            let through = bvh
                .intersect(&Ray::new(point, inward, epsilon, f32::INFINITY))
                .unwrap();
            assert_close(
                through.t,
                chord,
                1e-4 * radius.max(point.abs().max_element()),
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Tubes (the cylinders, cones and curve segments of the scene layer)

fn one_cylinder(caps: bool) -> GeometryBvh {
    GeometryBvh::build_tubes(&[TubeSegment {
        start: vec3(0.0, 0.0, 0.0),
        end: vec3(0.0, 0.0, 4.0),
        start_radius: 1.0,
        end_radius: 1.0,
        kind: TubeKind::Cone {
            start_cap: caps,
            end_cap: caps,
        },
    }])
}

#[test]
fn cylinder_body_hit_is_analytic() {
    for caps in [false, true] {
        let bvh = one_cylinder(caps);
        let hit = bvh.intersect(&ray(vec3(5.0, 0.0, 1.0), -Vec3::X)).unwrap();
        assert_eq!(hit.t, 4.0);
        assert_eq!(hit.primitive, 0);
        assert_vec_close(hit.normal, Vec3::X, 1e-6);
        assert_close(hit.uv.x, 0.25, 1e-6);
        // Oblique: hits the body at (sqrt(0.5), sqrt(0.5), 2).
        let target = vec3(0.5f32.sqrt(), 0.5f32.sqrt(), 2.0);
        let origin = vec3(4.0, 3.0, 6.0);
        let hit = bvh.intersect(&ray(origin, target - origin)).unwrap();
        assert_close(hit.t, origin.distance(target), 1e-5);
        assert_vec_close(hit.normal, vec3(target.x, target.y, 0.0), 1e-5);
        // Above and beside.
        assert!(bvh.intersect(&ray(vec3(5.0, 0.0, 4.5), -Vec3::X)).is_none());
        assert!(bvh.intersect(&ray(vec3(5.0, 1.5, 1.0), -Vec3::X)).is_none());
    }
}

#[test]
fn cylinder_caps_close_the_tube() {
    let capped = one_cylinder(true);
    let open = one_cylinder(false);
    // Straight down the axis: only the caps can be hit.
    let down = ray(vec3(0.5, 0.0, 10.0), -Vec3::Z);
    let hit = capped.intersect(&down).unwrap();
    assert_eq!(hit.t, 6.0);
    assert_eq!(hit.normal, Vec3::Z);
    assert_close(hit.uv.x, 1.0, 0.0);
    assert_close(hit.uv.y, 0.5, 1e-6);
    assert!(open.intersect(&down).is_none());
    let up = ray(vec3(0.0, 0.5, -3.0), Vec3::Z);
    let hit = capped.intersect(&up).unwrap();
    assert_eq!(hit.t, 3.0);
    assert_eq!(hit.normal, -Vec3::Z);

    // Through the top opening: the open tube is hit on its inner wall at (1, 0, 2).
    let origin = vec3(0.0, 0.0, 6.0);
    let slanted = ray(origin, vec3(1.0, 0.0, -4.0));
    let cap_hit = capped.intersect(&slanted).unwrap();
    assert_close(cap_hit.t, origin.distance(vec3(0.5, 0.0, 4.0)), 1e-6);
    assert_eq!(cap_hit.normal, Vec3::Z);
    let wall_hit = open.intersect(&slanted).unwrap();
    assert_close(wall_hit.t, origin.distance(vec3(1.0, 0.0, 2.0)), 1e-5);
    assert_vec_close(wall_hit.normal, Vec3::X, 1e-6);
    assert_close(wall_hit.uv.x, 0.5, 1e-6);
}

#[test]
fn rays_leaving_a_tube_do_not_hit_it_again() {
    let mut rng = Rng::new(5);
    let capped = TubeKind::Cone {
        start_cap: true,
        end_cap: true,
    };
    // A capped cylinder, a capped cone and a round curve segment.
    for (end_radius, kind) in [(2.0, capped), (0.5, capped), (1.0, TubeKind::Round)] {
        let bvh = GeometryBvh::build_tubes(&[TubeSegment {
            start: vec3(100.0, 20.0, -30.0),
            end: vec3(110.0, 28.0, -20.0),
            start_radius: 2.0,
            end_radius,
            kind,
        }]);
        assert_rays_leaving_do_not_hit_again(&bvh, &mut rng);
    }
}

/// Shadow rays from hit points on the only primitive of `bvh`, at least 0.6 degrees above the
/// tangent plane, must not hit it again.
fn assert_rays_leaving_do_not_hit_again(bvh: &GeometryBvh, rng: &mut Rng) {
    let (min, max) = bvh.bounds();
    let mut tested = 0;
    for _ in 0..2000 {
        let origin = (min + max) * 0.5 + rng.direction() * 30.0;
        let target = min + (max - min) * rng.point(0.0, 1.0);
        let Some(hit) = bvh.intersect(&ray(origin, target - origin)) else {
            continue;
        };
        let point = origin + (target - origin).normalize() * hit.t;
        let mut outward = rng.direction();
        if outward.dot(hit.normal) < 0.0 {
            outward = -outward;
        }
        if outward.dot(hit.normal) < 0.01 {
            continue;
        }
        tested += 1;
        let shadow = Ray::new(point, outward, surface_epsilon(point), f32::INFINITY);
        assert!(
            !bvh.occluded(&shadow),
            "self-hit at {point} along {outward}"
        );
    }
    assert!(tested > 200);
}

// ---------------------------------------------------------------------------------------------
// Brute-force comparisons

#[test]
fn random_triangles_match_brute_force() {
    let mut rng = Rng::new(1);
    let prims = random_triangles(&mut rng, 3000, 10.0, 1.5);
    let rays = random_rays(&mut rng, 3000, 10.0);
    compare_geometry_with_brute_force(prims.into(), &rays, "triangles");
}

#[test]
fn rays_with_negative_t_min_find_the_hits_behind_their_origin() {
    // Single-ray walks over triangles take another box test for these rays; the hits (also
    // those before the origin) must stay the brute-force ones, closest and any hit.
    let mut rng = Rng::new(31);
    let prims = random_triangles(&mut rng, 3000, 10.0, 1.5);
    let rays: Vec<Ray> = random_rays(&mut rng, 2000, 10.0)
        .into_iter()
        .map(|ray| Ray::new(ray.origin, ray.direction, -20.0, ray.t_max))
        .collect();
    compare_geometry_with_brute_force(prims.into(), &rays, "triangles, t_min < 0");
}

#[test]
fn random_quads_match_brute_force() {
    let mut rng = Rng::new(2);
    let prims = random_quads(&mut rng, 1500, 10.0, 1.5);
    let rays = random_rays(&mut rng, 2000, 10.0);
    compare_geometry_with_brute_force(prims.into(), &rays, "quads");
}

#[test]
fn random_spheres_match_brute_force() {
    let mut rng = Rng::new(3);
    let prims = random_spheres(&mut rng, 2000, 10.0, 0.6);
    let rays = random_rays(&mut rng, 3000, 10.0);
    compare_geometry_with_brute_force(prims.into(), &rays, "spheres");
}

#[test]
fn random_tubes_match_brute_force() {
    let mut rng = Rng::new(4);
    for count in [1500, 1501] {
        let prims = random_tubes(&mut rng, count, 10.0, 2.0);
        let rays = random_rays(&mut rng, 2000, 10.0);
        compare_geometry_with_brute_force(prims, &rays, "tubes");
    }
}

#[test]
fn triangle_hits_agree_with_an_independent_f64_reference() {
    // Moeller-Trumbore in f64 as the reference; near edges either answer is acceptable.
    let mut rng = Rng::new(9);
    let prims = random_triangles(&mut rng, 500, 5.0, 2.0);
    let GeometryPrims::Triangles { positions, indices } = &prims else {
        unreachable!()
    };
    let bvh = GeometryBvh::build(prims.clone());
    let mut confident = 0;
    for test_ray in random_rays(&mut rng, 2000, 5.0) {
        let o = test_ray.origin.as_dvec3();
        let d = test_ray.direction.as_dvec3();
        let mut reference: Option<(f64, u32, f64)> = None;
        for (id, corners) in indices.iter().enumerate() {
            let [a, b, c] = corners.to_array().map(|i| positions[i as usize].as_dvec3());
            let (e1, e2) = (b - a, c - a);
            let p = d.cross(e2);
            let det = e1.dot(p);
            if det.abs() < 1e-12 {
                continue;
            }
            let s = o - a;
            let u = s.dot(p) / det;
            let q = s.cross(e1);
            let v = d.dot(q) / det;
            let t = e2.dot(q) / det;
            let margin = u.min(v).min(1.0 - u - v);
            if margin >= 0.0
                && t >= test_ray.t_min as f64
                && t <= test_ray.t_max as f64
                && reference.is_none_or(|(best, _, _)| t < best)
            {
                reference = Some((t, id as u32, margin));
            }
        }
        let found = bvh.intersect(&test_ray);
        match (found, reference) {
            (Some(hit), Some((t, id, margin))) if margin > 1e-4 => {
                confident += 1;
                assert_close(hit.t, t as f32, 1e-4 * (1.0 + t as f32));
                if hit.primitive != id {
                    assert_close(hit.t, t as f32, 1e-4);
                }
            }
            (None, Some((_, _, margin))) => assert!(margin <= 1e-4, "missed {test_ray:?}"),
            (Some(hit), None) => panic!("spurious hit {hit:?} for {test_ray:?}"),
            _ => {}
        }
    }
    assert!(confident > 300);
}

#[test]
fn duplicated_primitives_build_and_traverse() {
    // Thousands of identical triangles stress the builder (equal Morton codes) and the stack.
    let positions = vec![
        vec3(0.0, 0.0, 0.0),
        vec3(1.0, 0.0, 0.0),
        vec3(0.0, 1.0, 0.0),
    ];
    let indices = vec![UVec3::new(0, 1, 2); 5000];
    let bvh = GeometryBvh::build(GeometryPrims::Triangles { positions, indices });
    assert_eq!(bvh.primitive_count(), 5000);
    let hit = bvh.intersect(&ray(vec3(0.2, 0.2, 1.0), -Vec3::Z)).unwrap();
    assert_eq!(hit.t, 1.0);
    assert!(hit.primitive < 5000);
    assert!(bvh.intersect(&ray(vec3(0.8, 0.8, 1.0), -Vec3::Z)).is_none());
}

// ---------------------------------------------------------------------------------------------
// Invalid input

#[test]
fn invalid_primitives_are_skipped_without_affecting_others() {
    let nan = f32::NAN;
    let positions = vec![
        vec3(0.0, 0.0, 0.0),
        vec3(1.0, 0.0, 0.0),
        vec3(0.0, 1.0, 0.0),
        vec3(nan, 0.0, 0.0),
        vec3(0.0, f32::INFINITY, 0.0),
        vec3(2.0, 2.0, 0.0),
        vec3(1.0e30, 0.0, 0.0),
        vec3(0.0, 0.0, 1.0),
        vec3(1.0, 0.0, 1.0),
        vec3(0.0, 1.0, 1.0),
        vec3(0.0, 2.0, 0.0),
    ];
    let indices = vec![
        UVec3::new(0, 1, 3),  // NaN vertex
        UVec3::new(0, 1, 2),  // valid, id 1
        UVec3::new(0, 4, 2),  // infinite vertex
        UVec3::new(0, 1, 99), // index out of range
        UVec3::new(0, 5, 5),  // zero area
        UVec3::new(0, 1, 1),  // zero area
        UVec3::new(0, 6, 2),  // beyond MAX_COORDINATE
        UVec3::new(7, 8, 9),  // valid, id 7
        UVec3::new(0, 2, 10), // collinear
    ];
    let bvh = GeometryBvh::build(GeometryPrims::Triangles {
        positions: positions.clone(),
        indices,
    });
    assert_eq!(bvh.primitive_count(), 2);
    assert_eq!(bvh.skipped_primitive_count(), 7);
    assert_eq!(bvh.bounds(), (Vec3::ZERO, vec3(1.0, 1.0, 1.0)));
    let hit = bvh
        .intersect(&ray(vec3(0.25, 0.25, -1.0), Vec3::Z))
        .unwrap();
    assert_eq!((hit.t, hit.primitive), (1.0, 1));
    let hit = bvh
        .intersect(&ray(vec3(0.25, 0.25, 3.0), -Vec3::Z))
        .unwrap();
    assert_eq!((hit.t, hit.primitive), (2.0, 7));
    // Where only broken triangles would be, nothing is hit.
    assert!(bvh.intersect(&ray(vec3(1.5, 1.2, 5.0), -Vec3::Z)).is_none());

    let spheres = GeometryBvh::build(GeometryPrims::Spheres {
        centers: vec![
            vec3(nan, 0.0, 0.0),
            vec3(0.0, 0.0, -5.0),
            vec3(3.0, 0.0, -5.0),
            vec3(6.0, 0.0, -5.0),
            vec3(9.0, 0.0, -5.0),
            vec3(12.0, 0.0, -5.0),
        ],
        radii: vec![1.0, 1.0, -1.0, 0.0, f32::INFINITY, nan],
    });
    assert_eq!(spheres.primitive_count(), 1);
    assert_eq!(spheres.skipped_primitive_count(), 5);
    assert_eq!(
        spheres
            .intersect(&ray(Vec3::ZERO, -Vec3::Z))
            .map(|hit| (hit.t, hit.primitive)),
        Some((4.0, 1))
    );
    for x in [3.0, 6.0, 9.0, 12.0] {
        assert!(
            spheres
                .intersect(&ray(vec3(x, 0.0, 0.0), -Vec3::Z))
                .is_none()
        );
    }

    let cylinder = |start: Vec3, end: Vec3, radius: f32| TubeSegment {
        start,
        end,
        start_radius: radius,
        end_radius: radius,
        kind: TubeKind::Cone {
            start_cap: true,
            end_cap: true,
        },
    };
    let tubes = GeometryBvh::build_tubes(&[
        cylinder(Vec3::ZERO, vec3(0.0, 0.0, 1.0), 0.5),
        // Zero length, non-finite end point, negative and NaN radius.
        cylinder(vec3(5.0, 0.0, 0.0), vec3(5.0, 0.0, 0.0), 0.5),
        cylinder(vec3(nan, 0.0, 0.0), vec3(10.0, 0.0, 1.0), 0.5),
        cylinder(vec3(15.0, 0.0, 0.0), vec3(15.0, 0.0, 1.0), -0.5),
        cylinder(vec3(20.0, 0.0, 0.0), vec3(20.0, 0.0, 1.0), nan),
    ]);
    assert_eq!(tubes.primitive_count(), 1);
    assert_eq!(tubes.skipped_primitive_count(), 4);
    assert_eq!(
        tubes
            .intersect(&ray(vec3(0.0, 0.0, 3.0), -Vec3::Z))
            .map(|hit| (hit.t, hit.primitive)),
        Some((2.0, 0))
    );
    for x in [5.0, 10.0, 15.0, 20.0] {
        assert!(tubes.intersect(&ray(vec3(x, 0.0, 3.0), -Vec3::Z)).is_none());
    }
}

#[test]
fn empty_geometry_and_scene_have_documented_empty_bounds() {
    let empty = GeometryBvh::build(GeometryPrims::Spheres {
        centers: vec![],
        radii: vec![],
    });
    assert_eq!(empty.bounds(), EMPTY_BOUNDS);
    assert!(bounds_are_empty(empty.bounds()));
    assert_eq!(empty.primitive_count(), 0);
    assert!(empty.intersect(&ray(Vec3::ZERO, Vec3::X)).is_none());
    assert!(!empty.occluded(&ray(Vec3::ZERO, Vec3::X)));

    let all_invalid = Arc::new(GeometryBvh::build(GeometryPrims::Triangles {
        positions: vec![Vec3::NAN; 3],
        indices: vec![UVec3::new(0, 1, 2)],
    }));
    assert_eq!(all_invalid.bounds(), EMPTY_BOUNDS);

    let scene = SceneBvh::build(vec![identity_instance(vec![Arc::new(empty), all_invalid])]);
    assert_eq!(scene.bounds(), EMPTY_BOUNDS);
    assert!(scene.intersect(&ray(Vec3::ZERO, Vec3::X)).is_none());
    assert!(!scene.occluded(&ray(Vec3::ZERO, Vec3::X)));
    let nothing = SceneBvh::build(Vec::new());
    assert_eq!(nothing.bounds(), EMPTY_BOUNDS);
    assert!(nothing.intersect(&ray(Vec3::ZERO, Vec3::X)).is_none());
}

#[test]
fn invalid_rays_never_hit() {
    let bvh = unit_triangle();
    let scene = SceneBvh::build(vec![identity_instance(vec![Arc::new(unit_triangle())])]);
    let good = ray(vec3(0.25, 0.25, 1.0), -Vec3::Z);
    assert!(bvh.intersect(&good).is_some());
    let broken = [
        Ray {
            origin: Vec3::NAN,
            ..good
        },
        Ray {
            direction: Vec3::ZERO,
            ..good
        },
        Ray {
            direction: vec3(0.0, f32::NAN, -1.0),
            ..good
        },
        Ray {
            t_min: f32::NAN,
            ..good
        },
        Ray {
            t_max: f32::NAN,
            ..good
        },
        Ray {
            t_min: 2.0,
            t_max: 1.0,
            ..good
        },
    ];
    for broken in broken {
        assert!(bvh.intersect(&broken).is_none(), "{broken:?}");
        assert!(!bvh.occluded(&broken), "{broken:?}");
        assert!(scene.intersect(&broken).is_none(), "{broken:?}");
        assert!(!scene.occluded(&broken), "{broken:?}");
    }
}

#[test]
fn axis_parallel_rays_with_zero_components_hit() {
    // Directions with exact (and negative) zeros exercise the clamped inverse direction.
    let bvh = GeometryBvh::build(GeometryPrims::Spheres {
        centers: vec![vec3(0.0, 0.0, 0.0), vec3(0.0, 5.0, 0.0)],
        radii: vec![1.0, 1.0],
    });
    for direction in [
        vec3(-0.0, -1.0, 0.0),
        vec3(0.0, -1.0, -0.0),
        vec3(-0.0, -1.0, -0.0),
    ] {
        let hit = bvh
            .intersect(&Ray::new(
                vec3(0.0, 10.0, 0.0),
                direction,
                0.0,
                f32::INFINITY,
            ))
            .unwrap();
        assert_eq!((hit.t, hit.primitive), (4.0, 1));
    }
    // Starting exactly on a box face, travelling along it.
    let hit = bvh
        .intersect(&Ray::new(
            vec3(-1.0, 5.0, -3.0),
            Vec3::Z,
            0.0,
            f32::INFINITY,
        ))
        .unwrap();
    assert_eq!(hit.t, 3.0);
}

#[test]
fn hits_very_close_to_the_origin_are_found() {
    // obvhs' own traversal ignores hits closer than 1e-4; ours honours t_min.
    let bvh = unit_triangle();
    let hit = bvh
        .intersect(&Ray::new(vec3(0.25, 0.25, 1.0e-6), -Vec3::Z, 0.0, 1.0))
        .unwrap();
    assert_close(hit.t, 1.0e-6, 1e-12);
    assert!(
        bvh.intersect(&Ray::new(vec3(0.25, 0.25, 1.0e-6), -Vec3::Z, 2.0e-6, 1.0))
            .is_none()
    );
}

// ---------------------------------------------------------------------------------------------
// Instances

fn unit_sphere() -> Arc<GeometryBvh> {
    Arc::new(one_sphere(Vec3::ZERO, 1.0))
}

#[test]
fn rotated_and_scaled_sphere_instance_gives_world_t_and_normal() {
    // Unit sphere stretched x2 along object x, rotated so object x points along world y.
    let transform = Affine3A::from_scale_rotation_translation(
        vec3(2.0, 1.0, 0.5),
        Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
        vec3(0.0, 0.0, -10.0),
    );
    let scene = SceneBvh::build(vec![InstanceDesc {
        transform,
        geometries: vec![unit_sphere()],
    }]);
    // World semi-axes: 1 along x, 2 along y, 0.5 along z; centre (0, 0, -10).
    let hit = scene
        .intersect(&ray(vec3(0.0, 10.0, -10.0), -Vec3::Y))
        .unwrap();
    assert_close(hit.t, 8.0, 1e-5);
    assert_vec_close(hit.normal, Vec3::Y, 1e-5);
    assert_vec_close(hit.object_normal, Vec3::X, 1e-5);
    assert_eq!((hit.instance, hit.geometry, hit.primitive), (0, 0, 0));
    let hit = scene
        .intersect(&ray(vec3(10.0, 0.0, -10.0), -Vec3::X))
        .unwrap();
    assert_close(hit.t, 9.0, 1e-5);
    assert_vec_close(hit.normal, Vec3::X, 1e-5);
    let hit = scene.intersect(&ray(Vec3::ZERO, -Vec3::Z)).unwrap();
    assert_close(hit.t, 9.5, 1e-5);
    assert_vec_close(hit.normal, Vec3::Z, 1e-5);

    // Oblique rays against the analytic ellipsoid (x/1)^2 + (y/2)^2 + (z/0.5)^2 = 1.
    let semi_axes = vec3(1.0, 2.0, 0.5).as_dvec3();
    let centre = vec3(0.0, 0.0, -10.0);
    let mut rng = Rng::new(21);
    for _ in 0..300 {
        let origin = rng.point(-6.0, 6.0);
        let target = centre + rng.direction() * vec3(0.9, 1.8, 0.45);
        let direction = (target - origin).normalize();
        let hit = scene
            .intersect(&Ray::new(origin, direction, 0.0, f32::INFINITY))
            .unwrap();
        let o = (origin - centre).as_dvec3() / semi_axes;
        let d = direction.as_dvec3() / semi_axes;
        let a = d.length_squared();
        let b = o.dot(d);
        let c = o.length_squared() - 1.0;
        let t = (-b - (b * b - a * c).sqrt()) / a;
        assert_close(hit.t, t as f32, 1e-4);
        let p = (origin - centre).as_dvec3() + direction.as_dvec3() * t;
        let gradient = (p / (semi_axes * semi_axes)).normalize().as_vec3();
        assert_vec_close(hit.normal, gradient, 1e-4);
        assert_close(hit.normal.length(), 1.0, 1e-6);
    }
}

#[test]
fn sheared_triangle_instance_normal_matches_transformed_triangle() {
    let transform = Affine3A::from_scale_rotation_translation(
        vec3(3.0, 0.5, 2.0),
        Quat::from_euler(glam::EulerRot::XYZ, 0.4, -0.7, 1.1),
        vec3(1.0, -2.0, 3.0),
    );
    let vertices = [
        vec3(-1.0, -1.0, 0.2),
        vec3(1.5, -0.5, -0.3),
        vec3(0.0, 1.0, 0.4),
    ];
    let geometry = Arc::new(GeometryBvh::build(GeometryPrims::Triangles {
        positions: vertices.to_vec(),
        indices: vec![UVec3::new(0, 1, 2)],
    }));
    let scene = SceneBvh::build(vec![InstanceDesc {
        transform,
        geometries: vec![geometry],
    }]);
    let world = vertices.map(|v| transform.transform_point3(v));
    let world_normal = (world[1] - world[0]).cross(world[2] - world[0]).normalize();
    let mut rng = Rng::new(8);
    for _ in 0..100 {
        let (b1, b2) = (rng.range(0.05, 0.45), rng.range(0.05, 0.45));
        let target = world[0] + (world[1] - world[0]) * b1 + (world[2] - world[0]) * b2;
        let origin = target + rng.direction() * 7.0;
        let hit = scene.intersect(&ray(origin, target - origin)).unwrap();
        assert_close(hit.t, 7.0, 1e-4);
        assert_vec_close(hit.normal, world_normal, 1e-5);
        assert_vec_close(hit.uv.extend(0.0), vec3(b1, b2, 0.0), 1e-4);
    }
}

#[test]
fn multiple_instances_match_brute_force() {
    let mut rng = Rng::new(12);
    let shapes: [TestGeometry; 4] = [
        random_triangles(&mut rng, 300, 2.0, 0.8).into(),
        random_spheres(&mut rng, 200, 2.0, 0.3).into(),
        random_tubes(&mut rng, 200, 2.0, 0.8),
        random_quads(&mut rng, 200, 2.0, 0.8).into(),
    ];
    let geometries: Vec<Arc<GeometryBvh>> =
        shapes.iter().map(|prims| Arc::new(prims.build())).collect();
    let mut instances = Vec::new();
    for i in 0..40 {
        let transform = Affine3A::from_scale_rotation_translation(
            vec3(
                rng.range(0.3, 2.0),
                rng.range(0.3, 2.0),
                rng.range(0.3, 2.0),
            ),
            Quat::from_axis_angle(rng.direction(), rng.range(0.0, 6.0)),
            rng.point(-12.0, 12.0),
        );
        let first = i % 4;
        let chosen = vec![
            geometries[first].clone(),
            geometries[(first + 1 + i % 3) % 4].clone(),
        ];
        instances.push(InstanceDesc {
            transform,
            geometries: chosen,
        });
    }
    let scene = SceneBvh::build(instances.clone());
    let geometry_index = |geometry: &Arc<GeometryBvh>| {
        geometries
            .iter()
            .position(|candidate| Arc::ptr_eq(candidate, geometry))
            .unwrap()
    };
    let mut hits = 0;
    for test_ray in random_rays(&mut rng, 2000, 12.0) {
        let world = traversal_ray(&test_ray);
        let mut expected: Option<(f32, u32, u32, u32)> = None;
        for (instance_index, instance) in instances.iter().enumerate() {
            let inverse = instance.transform.inverse();
            for (g, geometry) in instance.geometries.iter().enumerate() {
                let Some(mut object) = TraversalRay::new(
                    inverse.transform_point3a(world.origin),
                    inverse.transform_vector3a(world.direction),
                    world.t_min,
                    expected.map_or(world.t_max, |hit| hit.0),
                ) else {
                    continue;
                };
                object.t_max = expected.map_or(world.t_max, |hit| hit.0);
                if let Some((t, primitive)) =
                    brute_force(&shapes[geometry_index(geometry)], &object)
                    && expected.is_none_or(|best| t < best.0)
                {
                    expected = Some((t, instance_index as u32, g as u32, primitive));
                }
            }
        }
        let found = scene.intersect(&test_ray);
        assert_eq!(scene.occluded(&test_ray), found.is_some());
        match (found, expected) {
            (None, None) => {}
            (Some(hit), Some((t, instance, geometry, primitive))) => {
                hits += 1;
                assert_eq!(hit.t, t, "{test_ray:?}");
                if (hit.instance, hit.geometry, hit.primitive) != (instance, geometry, primitive) {
                    // Only acceptable as an exact tie; rare enough to just require equal t.
                    assert_eq!(hit.t, t);
                }
                assert_close(hit.normal.length(), 1.0, 1e-5);
                assert_close(hit.object_normal.length(), 1.0, 1e-5);
            }
            (found, expected) => panic!("{test_ray:?}: scene {found:?}, brute force {expected:?}"),
        }
    }
    assert!(hits > 300, "only {hits} hits");
}

#[test]
fn single_identity_instance_matches_geometry() {
    let mut rng = Rng::new(13);
    let geometry = Arc::new(GeometryBvh::build(random_triangles(
        &mut rng, 2000, 5.0, 1.0,
    )));
    let scene = SceneBvh::build(vec![identity_instance(vec![geometry.clone()])]);
    assert_eq!(scene.bounds(), geometry.bounds());
    for test_ray in random_rays(&mut rng, 2000, 5.0) {
        let direct = geometry.intersect(&test_ray);
        let through_scene = scene.intersect(&test_ray);
        assert_eq!(direct.map(|hit| hit.t), through_scene.map(|hit| hit.t));
        assert_eq!(
            direct.map(|hit| (hit.primitive, hit.uv, hit.normal)),
            through_scene.map(|hit| (hit.primitive, hit.uv, hit.normal))
        );
        assert_eq!(geometry.occluded(&test_ray), scene.occluded(&test_ray));
    }
}

#[test]
fn occlusion_through_instances() {
    let scene = SceneBvh::build(vec![
        InstanceDesc {
            transform: Affine3A::from_translation(vec3(0.0, 0.0, -5.0)),
            geometries: vec![unit_sphere()],
        },
        InstanceDesc {
            transform: Affine3A::from_scale(Vec3::splat(0.0)),
            geometries: vec![unit_sphere()],
        },
    ]);
    let towards = |t_min: f32, t_max: f32| Ray::new(Vec3::ZERO, -Vec3::Z, t_min, t_max);
    assert!(scene.occluded(&towards(0.0, f32::INFINITY)));
    assert!(scene.occluded(&towards(0.0, 4.0)));
    assert!(!scene.occluded(&towards(0.0, 3.99)));
    assert!(scene.occluded(&towards(5.0, 6.0)));
    assert!(!scene.occluded(&towards(6.01, 100.0)));
    assert!(!scene.occluded(&ray(Vec3::ZERO, Vec3::Z)));
    // The singular instance is left out; the sphere still reports instance 0.
    let hit = scene.intersect(&towards(0.0, f32::INFINITY)).unwrap();
    assert_eq!((hit.instance, hit.t), (0, 4.0));
}

#[test]
fn hits_report_instance_and_geometry_indices() {
    let sphere = unit_sphere();
    let triangle = Arc::new(unit_triangle());
    let scene = SceneBvh::build(vec![
        InstanceDesc {
            transform: Affine3A::from_translation(vec3(0.0, 0.0, -5.0)),
            geometries: vec![sphere.clone()],
        },
        InstanceDesc {
            transform: Affine3A::from_translation(vec3(10.0, 0.0, 0.0)),
            geometries: vec![sphere.clone(), triangle.clone()],
        },
    ]);
    let hit = scene
        .intersect(&ray(vec3(10.0, 0.0, 5.0), -Vec3::Z))
        .unwrap();
    assert_eq!((hit.instance, hit.geometry, hit.t), (1, 0, 4.0));
    // The triangle lies inside the sphere of the same instance: start past the sphere's front.
    let hit = scene
        .intersect(&Ray::new(
            vec3(10.25, 0.25, -5.0),
            Vec3::Z,
            4.5,
            f32::INFINITY,
        ))
        .unwrap();
    assert_eq!((hit.instance, hit.geometry, hit.primitive), (1, 1, 0));
    assert_eq!(hit.t, 5.0);
    assert_eq!(hit.normal, Vec3::Z);
    let (min, max) = scene.bounds();
    assert!(min.cmple(vec3(-1.0, -1.0, -6.0)).all());
    assert!(max.cmpge(vec3(11.0, 1.0, 1.0)).all());
}

#[test]
fn mirrored_instance_keeps_normals_on_the_same_side() {
    let scene = SceneBvh::build(vec![InstanceDesc {
        transform: Affine3A::from_scale(vec3(-1.0, 1.0, 1.0)),
        geometries: vec![Arc::new(unit_triangle())],
    }]);
    // The mirrored triangle covers x in [-1, 0]; its object normal +z stays +z in world.
    let hit = scene
        .intersect(&ray(vec3(-0.25, 0.25, 2.0), -Vec3::Z))
        .unwrap();
    assert_eq!(hit.t, 2.0);
    assert_vec_close(hit.normal, Vec3::Z, 1e-6);
}

#[test]
fn scene_rebuild_with_new_transforms_does_not_rebuild_geometry() {
    let geometries: Vec<Arc<GeometryBvh>> = (0..3)
        .map(|i| Arc::new(one_sphere(vec3(i as f32, 0.0, 0.0), 0.5)))
        .collect();
    let instances_at = |offset: f32| -> Vec<InstanceDesc> {
        (0..10)
            .map(|i| InstanceDesc {
                transform: Affine3A::from_rotation_translation(
                    Quat::from_rotation_y(offset + i as f32),
                    vec3(offset, i as f32 * 3.0, 0.0),
                ),
                geometries: geometries.clone(),
            })
            .collect()
    };
    let on_this_thread = || BUILDS_ON_THIS_THREAD.with(|count| count.get());
    let before_here = on_this_thread();
    let first = SceneBvh::build(instances_at(0.0));
    let moved = SceneBvh::build(instances_at(5.0));
    assert_eq!(on_this_thread(), before_here);
    assert_ne!(first.bounds(), moved.bounds());
    // The process-wide counter also moves with builds of tests running concurrently, so look
    // for one quiet window; a scene build that rebuilt geometries would never find one.
    let quiet_window = (0..2000).any(|attempt| {
        let before = geometry_build_count();
        let _scene = SceneBvh::build(instances_at(attempt as f32));
        let unchanged = geometry_build_count() == before;
        if !unchanged {
            std::thread::yield_now();
        }
        unchanged
    });
    assert!(
        quiet_window,
        "geometry_build_count moved on every scene build"
    );
    // And a geometry build is counted.
    let before = on_this_thread();
    let global_before = geometry_build_count();
    let _ = unit_triangle();
    assert_eq!(on_this_thread(), before + 1);
    assert!(geometry_build_count() > global_before);
}

// ---------------------------------------------------------------------------------------------
// Internals

#[test]
fn memory_stays_within_budget_for_a_grid() {
    let cells = 100u32;
    let positions = (0..=cells)
        .flat_map(|y| (0..=cells).map(move |x| vec3(x as f32, y as f32, ((x + y) as f32).sin())))
        .collect();
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
    let bvh = GeometryBvh::build(GeometryPrims::Triangles { positions, indices });
    let per_triangle = bvh.memory_bytes() as f64 / bvh.primitive_count() as f64;
    assert!(
        per_triangle > 48.0 && per_triangle < 120.0,
        "{per_triangle}"
    );
}

/// The nodes of a real BVH over `count` random triangles, for tests of the box tests.
fn random_wide_nodes(rng: &mut Rng, count: usize) -> Vec<crate::accel::wide_bvh::WideNode> {
    let prims = random_triangles(rng, count, 10.0, 1.0);
    let GeometryPrims::Triangles { positions, indices } = &prims else {
        unreachable!()
    };
    let boxes: Vec<obvhs::aabb::Aabb> = indices
        .iter()
        .map(|c| {
            let [a, b, d] = c.to_array().map(|i| positions[i as usize]);
            obvhs::aabb::Aabb::new(a.min(b).min(d).into(), a.max(b).max(d).into())
        })
        .collect();
    crate::accel::wide_bvh::build_wide_bvh(boxes, LeafSizing::Whole, LeafAlignment::Group).nodes
}

#[test]
fn every_box_test_path_matches_the_scalar_reference() {
    use crate::accel::walk::{BoxRay, child_hits, child_hits_four_wide, child_hits_scalar};
    let mut rng = Rng::new(17);
    let nodes = random_wide_nodes(&mut rng, 4000);
    let mut mismatches = 0;
    let mut hits = 0;
    for test_ray in random_rays(&mut rng, 500, 10.0) {
        let prepared = traversal_ray(&test_ray);
        let box_ray = BoxRay::new(&prepared);
        for node in &nodes {
            let (t_min, t_max) = (prepared.t_min, prepared.t_max);
            let reference = child_hits_scalar(node, &box_ray, t_min, t_max);
            hits += reference.0.count_ones();
            // Entry distances compared as values (+0 and -0 may differ).
            let same = |other: (u32, [f32; 8])| other == reference;
            let mut paths = vec![
                child_hits_four_wide(node, &box_ray, t_min, t_max),
                child_hits(node, &box_ray, t_min, t_max),
            ];
            #[cfg(target_arch = "x86_64")]
            if isa::Isa::Avx2.supported() {
                // SAFETY: the CPU has AVX2.
                paths.push(unsafe {
                    crate::accel::walk::avx2::child_hits(node, &box_ray, t_min, t_max)
                });
            }
            mismatches += paths.into_iter().filter(|path| !same(*path)).count();
            // The single-ray walks' tests (scaled distances, per octant) agree with each other;
            // `single_ray_box_tests_keep_every_box_an_exact_test_reaches` checks them.
            let single = crate::accel::single_ray::test_paths::child_hits(node, &prepared);
            mismatches += single.iter().filter(|path| **path != single[0]).count();
        }
    }
    assert!(hits > 1000, "{hits}");
    assert_eq!(mismatches, 0);
}

#[test]
fn single_ray_box_tests_keep_every_box_an_exact_test_reaches() {
    // Rays aimed exactly at box corners (and at random points): the single-ray box test of each
    // path must reach every child whose box the ray meets in exact arithmetic within
    // `[t_min, t_max]`, at an entry distance no later than the exact one.
    let mut rng = Rng::new(29);
    let nodes = random_wide_nodes(&mut rng, 4000);
    // Exact entry and exit of a child's box along the ray (f64: differences of f32 values are
    // exact, one rounding per quotient), within the ray's interval.
    let exact = |node: &crate::accel::wide_bvh::WideNode, slot: usize, ray: &Ray| {
        let (mut near, mut far) = (f64::from(ray.t_min), f64::from(ray.t_max));
        for axis in 0..3 {
            let origin = f64::from(ray.origin[axis]);
            let direction = f64::from(ray.direction[axis]);
            let low = (f64::from(node.planes[2 * axis][slot]) - origin) / direction;
            let high = (f64::from(node.planes[2 * axis + 1][slot]) - origin) / direction;
            near = near.max(low.min(high));
            far = far.min(low.max(high));
        }
        (near, far)
    };
    let (mut reached, mut missed, mut corner_rays) = (0, 0, 0);
    for (n, node) in nodes.iter().enumerate().step_by(3) {
        for slot in 0..8 {
            if !crate::accel::wide_bvh::occupied(node, slot) {
                continue;
            }
            for corner in 0..8 {
                let point = Vec3::from_array(std::array::from_fn(|axis| {
                    node.planes[2 * axis + ((corner >> axis) & 1)][slot]
                }));
                let origin = rng.point(-15.0, 15.0);
                let direction = point - origin;
                let t_min = if (n + corner) % 3 == 0 { 0.0 } else { 1.0e-3 };
                let rays = [
                    Ray::new(origin, direction, t_min, f32::INFINITY),
                    Ray::new(origin, direction, t_min, 1.0),
                    Ray::new(
                        origin,
                        rng.point(-10.0, 10.0) - origin,
                        t_min,
                        f32::INFINITY,
                    ),
                ];
                for ray in rays {
                    if ray.direction.abs().min_element() < 1.0e-3 {
                        continue;
                    }
                    corner_rays += 1;
                    let prepared = traversal_ray(&ray);
                    for (mask, nears) in
                        crate::accel::single_ray::test_paths::child_hits(node, &prepared)
                    {
                        for (child, &found_near) in nears.iter().enumerate() {
                            let (near, far) = exact(node, child, &ray);
                            if near <= far && crate::accel::wide_bvh::occupied(node, child) {
                                reached += 1;
                                if mask & (1 << child) == 0 || f64::from(found_near) > near {
                                    missed += 1;
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    assert!(
        corner_rays > 8_000 && reached > 10_000,
        "{corner_rays} {reached}"
    );
    assert_eq!(missed, 0, "of {reached}");
}

#[test]
fn single_ray_walks_restart_with_a_larger_stack_and_find_the_same_hits() {
    // Eight inline entries overflow on most rays through a few thousand triangles; the walks
    // then restart on the heap and must still give the answers of the inline-stack walk.
    let mut rng = Rng::new(23);
    let geometries = [
        GeometryBvh::build(random_triangles(&mut rng, 3000, 6.0, 1.5)),
        GeometryBvh::build(random_quads(&mut rng, 1500, 6.0, 1.5)),
    ];
    let mut hits = 0;
    for geometry in &geometries {
        for test_ray in random_rays(&mut rng, 2000, 6.0) {
            let ray = traversal_ray(&test_ray);
            let (closest, any) = geometry.walks_with_small_stack(&ray);
            assert_eq!(closest, geometry.closest_slot_and_t(&ray), "{test_ray:?}");
            assert_eq!(any, geometry.occluded(&test_ray), "{test_ray:?}");
            hits += usize::from(closest.is_some());
        }
    }
    assert!(hits > 1000, "{hits}");
}

#[test]
fn traversal_ray_rejects_degenerate_input_and_clamps_inverse() {
    let prepared = TraversalRay::new(Vec3A::ZERO, Vec3A::new(0.0, -0.0, 1.0), 0.0, 1.0).unwrap();
    assert!(prepared.inv_direction.is_finite());
    assert!(prepared.inv_direction.x > 0.0 && prepared.inv_direction.y > 0.0);
    assert_eq!(prepared.octant_inv, 0b111);
    assert_eq!(prepared.shear_axes[2], 2);
    assert!(TraversalRay::new(Vec3A::ZERO, Vec3A::ZERO, 0.0, 1.0).is_none());
    assert!(TraversalRay::new(Vec3A::ZERO, Vec3A::X, 1.0, 0.0).is_none());
}

// ---------------------------------------------------------------------------------------------
// Packets

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

#[test]
fn geometry_packets_match_single_rays() {
    let mut rng = Rng::new(31);
    let shapes: [TestGeometry; 4] = [
        random_triangles(&mut rng, 3000, 10.0, 1.5).into(),
        random_quads(&mut rng, 1000, 10.0, 1.5).into(),
        random_spheres(&mut rng, 1500, 10.0, 0.6).into(),
        random_tubes(&mut rng, 1000, 10.0, 2.0),
    ];
    for prims in shapes {
        let bvh = prims.build();
        let rays = packet_rays(&mut rng, 1500, 10.0);
        let mut hits = vec![None; rays.len()];
        bvh.intersect_packet(&rays, &mut hits);
        let mut hit_count = 0;
        for (ray, packet_hit) in rays.iter().zip(&hits) {
            let single = bvh.intersect(ray);
            assert_eq!(
                single.map(|hit| hit.t),
                packet_hit.map(|hit| hit.t),
                "{ray:?}"
            );
            if let (Some(single), Some(packet_hit)) = (single, packet_hit) {
                hit_count += 1;
                if single.primitive == packet_hit.primitive {
                    assert_eq!(single, *packet_hit);
                } else {
                    // An exact tie between two primitives: both must be hit at that t.
                    let prepared =
                        traversal_ray(&Ray::new(ray.origin, ray.direction, single.t, single.t));
                    let tied = single_primitive(&prims, packet_hit.primitive);
                    assert_eq!(
                        brute_force(&tied, &prepared).map(|hit| hit.0),
                        Some(single.t)
                    );
                }
            }
        }
        assert!(hit_count > rays.len() / 5);
    }
}

#[test]
fn scene_packets_match_single_rays() {
    let mut rng = Rng::new(32);
    let geometries: Vec<Arc<GeometryBvh>> = [
        random_triangles(&mut rng, 500, 2.0, 0.8).into(),
        random_spheres(&mut rng, 300, 2.0, 0.3).into(),
        random_tubes(&mut rng, 300, 2.0, 0.8),
    ]
    .iter()
    .map(|prims: &TestGeometry| Arc::new(prims.build()))
    .collect();
    let mut instances = vec![identity_instance(geometries.clone())];
    for i in 0..30 {
        instances.push(InstanceDesc {
            transform: Affine3A::from_scale_rotation_translation(
                vec3(
                    rng.range(0.3, 2.0),
                    rng.range(0.3, 2.0),
                    rng.range(0.3, 2.0),
                ),
                Quat::from_axis_angle(rng.direction(), rng.range(0.0, 6.0)),
                rng.point(-12.0, 12.0),
            ),
            geometries: vec![geometries[i % 3].clone()],
        });
    }
    let scene = SceneBvh::build(instances);
    let rays = packet_rays(&mut rng, 2000, 12.0);
    let mut hits = vec![None; rays.len()];
    scene.intersect_packet(&rays, &mut hits);
    let mut hit_count = 0;
    for (ray, packet_hit) in rays.iter().zip(&hits) {
        let single = scene.intersect(ray);
        assert_eq!(
            single.map(|hit| hit.t),
            packet_hit.map(|hit| hit.t),
            "{ray:?}"
        );
        if let (Some(single), Some(packet_hit)) = (single, packet_hit) {
            hit_count += 1;
            let same_surface = (single.instance, single.geometry, single.primitive)
                == (
                    packet_hit.instance,
                    packet_hit.geometry,
                    packet_hit.primitive,
                );
            if same_surface {
                assert_eq!(single, *packet_hit);
            }
        }
    }
    assert!(hit_count > rays.len() / 5, "{hit_count}");
}

#[test]
fn packet_with_invalid_and_missing_lanes() {
    let bvh = unit_triangle();
    let good = ray(vec3(0.25, 0.25, 1.0), -Vec3::Z);
    let rays = [
        good,
        Ray {
            origin: Vec3::NAN,
            ..good
        },
        Ray {
            t_min: 5.0,
            t_max: 1.0,
            ..good
        },
        ray(vec3(0.3, 0.2, 2.0), -Vec3::Z),
        good,
    ];
    let mut hits = vec![None; 6];
    bvh.intersect_packet(&rays, &mut hits);
    assert_eq!(hits[0].map(|hit| hit.t), Some(1.0));
    assert!(hits[1].is_none() && hits[2].is_none());
    assert_eq!(hits[3].map(|hit| hit.t), Some(2.0));
    assert_eq!(hits[4].map(|hit| hit.t), Some(1.0));
    assert!(hits[5].is_none());
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

fn assert_same_closest_t(singles: &[Option<f32>], packets: &[Option<f32>], rays: &[Ray]) {
    for ((single, packet), ray) in singles.iter().zip(packets).zip(rays) {
        assert_eq!(single, packet, "{ray:?}");
    }
}

#[test]
fn frustum_packets_match_single_rays() {
    let mut rng = Rng::new(51);
    let shapes: [TestGeometry; 4] = [
        random_triangles(&mut rng, 4000, 10.0, 1.5).into(),
        random_quads(&mut rng, 1500, 10.0, 1.5).into(),
        random_spheres(&mut rng, 2000, 10.0, 0.6).into(),
        random_tubes(&mut rng, 1500, 10.0, 2.0),
    ];
    // Off-axis views (whole tiles share an octant) and an axis-aligned view (tiles straddle
    // octants and fall back to smaller packets or single rays).
    let views = [
        (vec3(-25.0, -18.0, 12.0), Vec3::ZERO),
        (vec3(3.0, 4.0, 30.0), vec3(2.0, 1.0, 0.0)),
        (vec3(0.0, -30.0, 0.0), Vec3::ZERO),
    ];
    for prims in shapes {
        let bvh = prims.build();
        for (eye, target) in views {
            let mut rays = camera_tiles(&mut rng, eye, target, 48);
            // The last packet holds 37 rays: ten groups, two quadrants partly filled.
            rays.truncate(rays.len() - 27);
            let mut hits = vec![None; rays.len()];
            bvh.intersect_packet(&rays, &mut hits);
            let singles: Vec<Option<f32>> = rays
                .iter()
                .map(|ray| bvh.intersect(ray).map(|hit| hit.t))
                .collect();
            let packets: Vec<Option<f32>> = hits.iter().map(|hit| hit.map(|hit| hit.t)).collect();
            assert_same_closest_t(&singles, &packets, &rays);
            assert!(singles.iter().flatten().count() > rays.len() / 4);
            for (ray, hit) in rays.iter().zip(&hits) {
                if let Some(hit) = hit {
                    let single = bvh.intersect(ray).unwrap();
                    if single.primitive == hit.primitive {
                        assert_eq!(single, *hit);
                    }
                }
            }
        }
    }
}

#[test]
fn scene_frustum_packets_match_single_rays() {
    let mut rng = Rng::new(52);
    let geometries: Vec<Arc<GeometryBvh>> = [
        random_triangles(&mut rng, 800, 2.0, 0.8),
        random_spheres(&mut rng, 300, 2.0, 0.3),
        random_quads(&mut rng, 300, 2.0, 0.8),
    ]
    .into_iter()
    .map(|prims| Arc::new(GeometryBvh::build(prims)))
    .collect();
    let mut instances = vec![identity_instance(geometries.clone())];
    for i in 0..40 {
        instances.push(InstanceDesc {
            transform: Affine3A::from_scale_rotation_translation(
                vec3(
                    rng.range(0.3, 2.0),
                    rng.range(0.3, 2.0),
                    rng.range(0.3, 2.0),
                ),
                Quat::from_axis_angle(rng.direction(), rng.range(0.0, 6.0)),
                rng.point(-10.0, 10.0),
            ),
            geometries: vec![geometries[i % 3].clone()],
        });
    }
    let scene = SceneBvh::build(instances);
    for (eye, target) in [
        (vec3(-22.0, -17.0, 9.0), Vec3::ZERO),
        (vec3(0.0, 0.0, 25.0), vec3(0.5, 0.2, 0.0)),
    ] {
        let rays = camera_tiles(&mut rng, eye, target, 64);
        let mut hits = vec![None; rays.len()];
        scene.intersect_packet(&rays, &mut hits);
        let singles: Vec<Option<SceneHit>> = rays.iter().map(|ray| scene.intersect(ray)).collect();
        let single_t: Vec<Option<f32>> = singles.iter().map(|hit| hit.map(|hit| hit.t)).collect();
        let packet_t: Vec<Option<f32>> = hits.iter().map(|hit| hit.map(|hit| hit.t)).collect();
        assert_same_closest_t(&single_t, &packet_t, &rays);
        assert!(single_t.iter().flatten().count() > rays.len() / 5);
        for (single, packet) in singles.iter().zip(&hits) {
            if let (Some(single), Some(packet)) = (single, packet) {
                let key = |hit: &SceneHit| (hit.instance, hit.geometry, hit.primitive);
                if key(single) == key(packet) {
                    assert_eq!(single, packet);
                }
            }
        }
    }
}

#[test]
fn camera_tiles_form_frustum_packets() {
    use crate::accel::frustum::FrustumPacket;
    let mut rng = Rng::new(53);
    let rays = camera_tiles(&mut rng, vec3(-25.0, -18.0, 12.0), Vec3::ZERO, 48);
    let mut formed = 0;
    let mut frustum = FrustumPacket::empty();
    for chunk in rays.chunks(64) {
        formed += usize::from(frustum.fill(chunk.len(), |index| {
            crate::accel::geometry::prepare(&chunk[index])
        }));
    }
    // Tiles straddling a sign change cannot form one; most can.
    assert!(formed * 2 > rays.len() / 64, "{formed}");
    // A ray from another origin joins the packet; one from another octant never does.
    let from_elsewhere = |index: usize| {
        let mut ray = rays[index];
        if index == 5 {
            ray.origin += Vec3::ONE;
        }
        crate::accel::geometry::prepare(&ray)
    };
    assert!(frustum.fill(64, from_elsewhere));
    let stray = Ray::new(rays[5].origin, -rays[5].direction, 0.0, 1.0);
    let mixed = |index: usize| {
        let ray = if index == 5 { &stray } else { &rays[index] };
        crate::accel::geometry::prepare(ray)
    };
    assert!(!frustum.fill(64, mixed));
    // Nor do chunks without a valid ray, or more than 64 rays.
    assert!(!frustum.fill(8, |_| None));
    assert!(!frustum.fill(65, |index| crate::accel::geometry::prepare(&rays[index])));
}

#[test]
fn builds_run_inside_a_caller_owned_pool() {
    fn assert_shareable<T: Send + Sync>() {}
    assert_shareable::<GeometryBvh>();
    assert_shareable::<SceneBvh>();

    let mut rng = Rng::new(61);
    let prims = random_triangles(&mut rng, 3000, 10.0, 1.0);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let (in_pool, scene) = pool.install(|| {
        let geometry = Arc::new(GeometryBvh::build(prims.clone()));
        let scene = SceneBvh::build(vec![identity_instance(vec![geometry.clone()])]);
        (geometry, scene)
    });
    let serial_pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let serial = serial_pool.install(|| GeometryBvh::build(prims.clone()));
    for test_ray in random_rays(&mut rng, 1000, 10.0) {
        let expected = serial.intersect(&test_ray).map(|hit| hit.t);
        assert_eq!(in_pool.intersect(&test_ray).map(|hit| hit.t), expected);
        assert_eq!(scene.intersect(&test_ray).map(|hit| hit.t), expected);
    }
}

#[test]
fn single_transformed_instance_packets_match_single_rays() {
    let mut rng = Rng::new(71);
    let geometry = Arc::new(GeometryBvh::build(random_triangles(
        &mut rng, 2000, 3.0, 1.0,
    )));
    for transform in [
        Affine3A::IDENTITY,
        Affine3A::from_scale_rotation_translation(
            vec3(2.0, 0.5, 1.5),
            Quat::from_rotation_z(0.7),
            vec3(1.0, 2.0, -1.0),
        ),
    ] {
        let scene = SceneBvh::build(vec![InstanceDesc {
            transform,
            geometries: vec![geometry.clone()],
        }]);
        let rays = camera_tiles(&mut rng, vec3(-12.0, -9.0, 6.0), vec3(1.0, 2.0, -1.0), 32);
        let mut hits = vec![None; rays.len()];
        scene.intersect_packet(&rays, &mut hits);
        let mut hit_count = 0;
        for (ray, packet_hit) in rays.iter().zip(&hits) {
            let single = scene.intersect(ray);
            assert_eq!(single.map(|hit| hit.t), packet_hit.map(|hit| hit.t));
            assert_eq!(scene.occluded(ray), single.is_some());
            // Same primitive: the same record, down to the normal the packet test kept.
            if let (Some(single), Some(packet_hit)) = (single, packet_hit)
                && single.primitive == packet_hit.primitive
            {
                assert_eq!(single, *packet_hit);
            }
            hit_count += usize::from(single.is_some());
        }
        assert!(hit_count > rays.len() / 10, "{hit_count}");
    }
}

#[test]
fn sphere_pretest_never_rejects_a_line_that_touches() {
    use crate::accel::primitives::line_clearly_misses_sphere;
    let mut rng = Rng::new(81);
    for _ in 0..20000 {
        let scale = 10f32.powf(rng.range(-3.0, 4.0));
        let center = rng.point(-1.0, 1.0) * scale * 100.0;
        let radius = scale * rng.range(0.1, 2.0);
        let sphere = PackedSphere::new(center, radius).unwrap();
        // A line passing at just under one radius from the centre.
        let direction = rng.direction() * rng.range(0.2, 3.0);
        let mut side = rng.direction().cross(direction).normalize_or_zero();
        if side == Vec3::ZERO {
            continue;
        }
        side *= radius * (1.0 - 1.0e-4 * rng.unit());
        let origin = center + side - direction * rng.range(1.0, 50.0) * scale;
        let Some(prepared) = TraversalRay::new(origin.into(), direction.into(), 0.0, f32::INFINITY)
        else {
            continue;
        };
        // Exact perpendicular distance of the f32 ray, in f64.
        let offset = origin.as_dvec3() - center.as_dvec3();
        let d = direction.as_dvec3();
        let perp = offset - d * (offset.dot(d) / d.length_squared());
        if perp.length() < radius as f64 {
            assert!(!line_clearly_misses_sphere(&sphere, &prepared));
        }
    }
}

#[test]
fn vectorized_packet_preparation_matches_single_rays() {
    use crate::accel::frustum::FrustumPacket;
    use crate::accel::packet::RayPacket;
    let mut rng = Rng::new(91);
    let mut checked = 0;
    for round in 0..3000 {
        let origin = rng.point(-5.0, 5.0);
        let base = rng.direction();
        let rays: Vec<Ray> = (0..4)
            .map(|lane| {
                let mut ray = Ray::new(
                    origin,
                    (base + rng.point(-0.05, 0.05) * (round % 3) as f32).normalize(),
                    rng.range(0.0, 1.0),
                    rng.range(0.5, 100.0),
                );
                match rng.next_u64() % 12 {
                    0 => ray.direction = Vec3::ZERO,
                    1 => ray.origin.y = f32::NAN,
                    2 => ray.t_max = f32::NAN,
                    3 => ray.direction = vec3(0.0, -0.0, if lane % 2 == 0 { 1.0 } else { -1.0 }),
                    _ => {}
                }
                ray
            })
            .collect();
        // Full groups and the partial ones at the edge of a frame.
        let used = if round % 5 == 0 { 1 + round % 3 } else { 4 };
        let singles: [Option<TraversalRay>; 4] = std::array::from_fn(|lane| {
            (lane < used)
                .then(|| crate::accel::geometry::prepare(&rays[lane]))
                .flatten()
        });
        let vectorized = RayPacket::prepare(&rays[..used]);
        let reference = RayPacket::new(&singles);
        assert_eq!(vectorized.is_some(), reference.is_some(), "{rays:?}");
        let (Some(vectorized), Some(reference)) = (vectorized, reference) else {
            continue;
        };
        assert_eq!(vectorized.lanes, reference.lanes);
        for lane in 0..4 {
            if vectorized.lanes & (1 << lane) != 0 {
                let (a, b) = (vectorized.ray(lane), reference.ray(lane));
                assert_eq!(format!("{a:?}"), format!("{b:?}"));
                checked += 1;
            }
        }
    }
    assert!(checked > 3000);
    // Whole frustum packets: same decision and same rays either way.
    let camera = camera_tiles(&mut rng, vec3(-25.0, -18.0, 12.0), Vec3::ZERO, 48);
    let (mut fast, mut slow) = (FrustumPacket::empty(), FrustumPacket::empty());
    for chunk in camera.chunks(64) {
        let formed = fast.fill_from_rays(chunk);
        assert_eq!(
            formed,
            slow.fill(chunk.len(), |index| crate::accel::geometry::prepare(
                &chunk[index]
            ))
        );
        if formed {
            for index in 0..chunk.len() {
                let (group, lane) = (index / 4, index % 4);
                assert_eq!(fast.groups[group].lanes, slow.groups[group].lanes);
                if fast.groups[group].lanes & (1 << lane) != 0 {
                    let (a, b) = (fast.groups[group].ray(lane), slow.groups[group].ray(lane));
                    assert_eq!(format!("{a:?}"), format!("{b:?}"));
                }
            }
        }
    }
}
/// Frustum packets against single rays and brute force with whole groups and quadrants of
/// dead rays, partial packets and random intervals; and the wide BVH's structure walked from
/// its root.
mod packet_and_structure {
    use super::*;
    use crate::accel::wide_bvh::build_wide_bvh;
    use obvhs::aabb::Aabb;

    /// 8x8 tile of rays in packet order, with a random pattern of invalid lanes/groups/quadrants.
    /// With `spread` > 0 each ray starts at its own point within `spread` of the eye and passes
    /// where the eye's ray would at distance 10 (several viewers, a matrix camera's near plane).
    fn tile(rng: &mut Rng, eye: Vec3, target: Vec3, fov: f32, kill: u32, spread: f32) -> Vec<Ray> {
        let forward = (target - eye).normalize();
        let right = forward.cross(Vec3::Z).normalize();
        let up = right.cross(forward);
        let mut rays = Vec::new();
        for quad in 0..16u32 {
            for lane in 0..4u32 {
                let column = (quad % 4) * 2 + lane % 2;
                let row = (quad / 4) * 2 + lane / 2;
                let u = (column as f32 + 0.5) / 8.0 * 2.0 - 1.0;
                let v = 1.0 - (row as f32 + 0.5) / 8.0 * 2.0;
                let direction = (forward + (right * u + up * v) * fov).normalize();
                let origin = eye + rng.point(-spread, spread);
                let direction = (eye + direction * 10.0 - origin).normalize();
                let mut ray = Ray::new(origin, direction, 0.0, f32::INFINITY);
                let quadrant = [0, 0, 1, 1, 0, 0, 1, 1, 2, 2, 3, 3, 2, 2, 3, 3][quad as usize];
                let dead = match kill {
                    0 => false,
                    1 => rng.next_u64().is_multiple_of(3),
                    2 => quadrant != 3, // only one quadrant alive
                    3 => quadrant % 2 == 0,
                    4 => quad % 3 != 0,
                    _ => !rng.next_u64().is_multiple_of(8),
                };
                if dead {
                    ray.direction = Vec3::ZERO;
                }
                match rng.next_u64() % 8 {
                    0 => ray.t_max = rng.range(0.5, 30.0),
                    1 => ray.t_min = rng.range(0.0, 20.0),
                    _ => {}
                }
                rays.push(ray);
            }
        }
        rays
    }

    fn scenes(rng: &mut Rng) -> Vec<GeometryPrims> {
        let mut out = vec![
            random_triangles(rng, 3000, 10.0, 0.8),
            random_triangles(rng, 3, 1.0, 0.5),
            random_triangles(rng, 7, 1.0, 0.5),
        ];
        // A flat grid at z = 0 of tiny triangles, plus broken ones mixed in.
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        let n = 60u32;
        for j in 0..=n {
            for i in 0..=n {
                positions.push(vec3(i as f32 * 0.3 - 9.0, j as f32 * 0.3 - 9.0, 0.0));
            }
        }
        positions.push(vec3(f32::NAN, 0.0, 0.0));
        let nan_index = positions.len() as u32 - 1;
        for j in 0..n {
            for i in 0..n {
                let a = j * (n + 1) + i;
                indices.push(UVec3::new(a, a + 1, a + n + 2));
                indices.push(UVec3::new(a, a + n + 2, a + n + 1));
                if (i + j) % 17 == 0 {
                    indices.push(UVec3::new(a, a + 1, nan_index));
                    indices.push(UVec3::new(a, a, a + 1));
                    indices.push(UVec3::new(a, 99_999_999, a + 1));
                }
            }
        }
        out.push(GeometryPrims::Triangles { positions, indices });
        out
    }

    #[test]
    fn frustum_packets_with_dead_groups_and_quadrants_match_single_rays() {
        let mut rng = Rng::new(0xBEEF);
        let mut compared = 0usize;
        let mut hit_count = 0usize;
        let (mut frustums, mut tiles) = (0usize, 0usize);
        for prims in scenes(&mut rng) {
            let test: TestGeometry = prims.clone().into();
            let bvh = test.build();
            for round in 0..120 {
                let eye = match round % 3 {
                    0 => rng.point(-25.0, 25.0),
                    1 => rng.point(-5.0, 5.0), // often inside the geometry
                    _ => rng.point(-9.0, 9.0) * vec3(1.0, 1.0, 0.0) + vec3(0.0, 0.0, 0.1),
                };
                let target = rng.point(-8.0, 8.0) * vec3(1.0, 1.0, 0.2);
                let fov = [0.001, 0.02, 0.3, 1.0, 3.0][round % 5];
                let kill = (round / 5 % 6) as u32;
                // Every other round the rays start at points of their own.
                let spread = [0.0, 0.002, 0.0, 0.3, 0.0, 2.0][round / 3 % 6];
                let mut rays = tile(&mut rng, eye, target, fov, kill, spread);
                let keep = 1 + (rng.next_u64() % 64) as usize;
                if round % 4 == 0 {
                    rays.truncate(keep);
                }
                let mut hits = vec![None; rays.len()];
                let mut probe = crate::accel::frustum::FrustumPacket::empty();
                frustums += usize::from(probe.fill_from_rays(&rays));
                tiles += 1;
                bvh.intersect_packet(&rays, &mut hits);
                for (ray, hit) in rays.iter().zip(&hits) {
                    let single = bvh.intersect(ray);
                    assert_eq!(
                        single.map(|h| h.t),
                        hit.map(|h| h.t),
                        "{ray:?} round {round}"
                    );
                    if let Some(r) = TraversalRay::new(
                        ray.origin.into(),
                        ray.direction.into(),
                        ray.t_min,
                        ray.t_max,
                    ) {
                        check_against_brute_force(
                            &test,
                            hit.map(|h| (h.t, h.primitive)),
                            &r,
                            "frustum vs brute",
                        );
                    }
                    compared += 1;
                    hit_count += usize::from(hit.is_some());
                }
            }
        }
        assert!(hit_count > compared / 10, "{hit_count} of {compared}");
        // Most tiles really went through the frustum path.
        assert!(frustums * 3 > tiles, "{frustums} of {tiles}");
    }

    #[test]
    fn scene_frustum_packets_with_dead_groups_and_quadrants_match_single_rays() {
        let mut rng = Rng::new(0xF00D);
        let geometries: Vec<Arc<GeometryBvh>> = [
            random_triangles(&mut rng, 3000, 2.0, 0.2),
            random_triangles(&mut rng, 2, 1.0, 0.5),
        ]
        .into_iter()
        .map(|p| Arc::new(GeometryBvh::build(p)))
        .collect();
        let mut instances = Vec::new();
        for k in 0..30 {
            let transform = Affine3A::from_scale_rotation_translation(
                Vec3::splat(rng.range(0.5, 2.0)) * vec3(1.0, rng.range(0.3, 3.0), 1.0),
                Quat::from_axis_angle(rng.direction(), rng.range(0.0, 6.0)),
                rng.point(-12.0, 12.0),
            );
            let transform = if k % 5 == 0 {
                Affine3A::IDENTITY
            } else {
                transform
            };
            instances.push(InstanceDesc {
                transform,
                geometries: vec![geometries[k % 2].clone()],
            });
        }
        let scene = SceneBvh::build(instances);
        for round in 0..200 {
            let eye = rng.point(-20.0, 20.0);
            let target = rng.point(-10.0, 10.0);
            let fov = [0.01, 0.2, 1.0, 3.0][round % 4];
            let spread = [0.0, 0.05][round % 2];
            let rays = tile(&mut rng, eye, target, fov, (round / 4 % 6) as u32, spread);
            let mut hits = vec![None; rays.len()];
            scene.intersect_packet(&rays, &mut hits);
            for (ray, hit) in rays.iter().zip(&hits) {
                assert_eq!(
                    scene.intersect(ray).map(|h| h.t),
                    hit.map(|h| h.t),
                    "{ray:?}"
                );
            }
        }
    }

    /// Walks the wide BVH from the root and checks its invariants.
    fn check_structure(boxes: &[Aabb]) {
        for sizing in [LeafSizing::Whole, LeafSizing::Split] {
            for alignment in [LeafAlignment::Packed, LeafAlignment::Group] {
                check_structure_with(boxes, sizing, alignment);
            }
        }
    }

    fn check_structure_with(boxes: &[Aabb], sizing: LeafSizing, alignment: LeafAlignment) {
        use crate::accel::wide_bvh::{LEAF_BIT, PADDING, leaf_range, occupied};
        let crate::accel::wide_bvh::WideBvh { nodes, order, .. } =
            build_wide_bvh(boxes.to_vec(), sizing, alignment);
        let n = boxes.len();
        if n == 0 {
            assert!(nodes.is_empty() && order.is_empty());
            return;
        }
        let mut slot_seen = vec![0u32; order.len()];
        let mut node_seen = vec![0u32; nodes.len()];
        let mut stack = vec![0usize];
        while let Some(index) = stack.pop() {
            node_seen[index] += 1;
            let node = &nodes[index];
            let mut children = 0;
            for slot in 0..8 {
                if !occupied(node, slot) {
                    continue;
                }
                children += 1;
                let code = node.children[slot];
                // Child boxes contain what is below them.
                let inside = |aabb: &Aabb| {
                    (0..3).all(|axis| {
                        node.planes[2 * axis][slot] <= aabb.min[axis]
                            && aabb.max[axis] <= node.planes[2 * axis + 1][slot]
                    })
                };
                if code & LEAF_BIT == 0 {
                    let child = &nodes[code as usize];
                    for child_slot in (0..8).filter(|&s| occupied(child, s)) {
                        let low = [0, 2, 4].map(|row| child.planes[row][child_slot]);
                        let high = [1, 3, 5].map(|row| child.planes[row][child_slot]);
                        assert!(inside(&Aabb::new(low.into(), high.into())));
                    }
                    stack.push(code as usize);
                } else {
                    let (first, count) = leaf_range(code);
                    assert!((1..=4).contains(&count));
                    let first = first as usize;
                    if alignment == LeafAlignment::Group {
                        assert!(first % 4 + count as usize <= 4, "a leaf within one group");
                    }
                    for i in first..first + count as usize {
                        slot_seen[i] += 1;
                        assert_ne!(order[i], PADDING);
                        assert!(inside(&boxes[order[i] as usize]));
                    }
                }
            }
            assert!((1..=8).contains(&children));
            if index != 0 {
                assert!(children >= 2, "non-root wide node with {children} children");
            }
        }
        assert!(
            node_seen.iter().all(|&c| c == 1),
            "{n}: nodes {node_seen:?}"
        );
        if alignment == LeafAlignment::Group {
            assert_eq!(order.len() % 4, 0, "whole groups");
            for group in order.chunks(4) {
                assert_ne!(group[0], PADDING, "padding repeats a real first lane");
            }
        }
        // Padding slots belong to no leaf.
        for (seen, &index) in slot_seen.iter_mut().zip(&order) {
            if index == PADDING {
                *seen += 1;
            }
        }
        assert!(slot_seen.iter().all(|&c| c == 1), "{n}: slots");
        let mut ids: Vec<u32> = order.iter().copied().filter(|&i| i != PADDING).collect();
        ids.sort();
        assert_eq!(ids, (0..n as u32).collect::<Vec<_>>());
    }

    #[test]
    fn a_mesh_grid_over_two_scan_chunks_builds_well_formed() {
        // A grid listed cell by cell, two triangles per cell (both cover the cell's square):
        // 5,000 cells span more than one sequentially built range.
        let cells = 5000;
        let grid: Vec<Aabb> = (0..cells * 2)
            .map(|i| {
                let cell = (i / 2) as f32;
                let (x, y) = (cell % 100.0, (cell / 100.0).floor());
                Aabb::new(vec3(x, y, 0.0).into(), vec3(x + 1.0, y + 1.0, 0.1).into())
            })
            .collect();
        check_structure(&grid);
    }

    #[test]
    fn wide_bvh_nodes_and_leaves_are_reachable_once_and_well_formed() {
        let mut rng = Rng::new(7);
        // Not bigger: obvhs' PLOC takes quadratic time on many identical boxes (40,000 take
        // seconds).
        for count in (1..=80).chain([100, 257, 1000, 5000]) {
            let random: Vec<Aabb> = (0..count)
                .map(|_| {
                    let low = rng.point(-50.0, 50.0);
                    Aabb::new(low.into(), (low + rng.point(0.0, 3.0)).into())
                })
                .collect();
            check_structure(&random);
            // All identical boxes.
            let same = vec![Aabb::new(Vec3A::ZERO, Vec3A::ONE); count];
            check_structure(&same);
            // Flat and degenerate (points) boxes.
            let flat: Vec<Aabb> = (0..count)
                .map(|i| {
                    let p = vec3(i as f32, (i % 7) as f32, 0.0);
                    Aabb::new(p.into(), p.into())
                })
                .collect();
            check_structure(&flat);
        }
    }
}

#[test]
fn whole_leaves_stay_whole_in_shared_groups_and_sphere_and_tube_leaves_split() {
    use crate::accel::wide_bvh::{build_wide_bvh, leaf_count};
    let mut rng = Rng::new(61);
    let boxes: Vec<obvhs::aabb::Aabb> = (0..3000)
        .map(|_| {
            let low = rng.point(-20.0, 20.0);
            obvhs::aabb::Aabb::new(low.into(), (low + rng.point(0.0, 1.0)).into())
        })
        .collect();
    let leaves =
        |sizing| leaf_count(&build_wide_bvh(boxes.clone(), sizing, LeafAlignment::Packed).nodes);
    let (whole, split) = (leaves(LeafSizing::Whole), leaves(LeafSizing::Split));
    // Whole: leaves of up to four boxes, mostly full; split: spare slots break them up.
    assert!(whole * 4 >= 3000 && whole * 10 < 3000 * 3, "{whole}");
    assert!(split > 2 * whole, "{split} vs {whole}");
    // Whole leaves in groups of four: the binned-SAH build makes each a leaf of the binary
    // tree, which the collapse keeps whole, and the node's leaves share their groups, so the
    // slots (groups of four, padding included) stay few.
    let whole_grouped = build_wide_bvh(boxes.clone(), LeafSizing::Whole, LeafAlignment::Group);
    let grouped_leaves = leaf_count(&whole_grouped.nodes);
    let slots = whole_grouped.order.len();
    assert_eq!(grouped_leaves, whole);
    assert!(slots * 10 < 3000 * 13, "{slots} slots for 3000 boxes");
    // Geometries choose by the cost of their primitive test.
    let per_leaf = |bvh: &GeometryBvh| bvh.primitive_count() as f64 / bvh.leaf_count() as f64;
    let spheres = GeometryBvh::build(random_spheres(&mut rng, 3000, 20.0, 0.5));
    let tubes = random_tubes(&mut rng, 3000, 20.0, 1.0).build();
    assert!(per_leaf(&spheres) < 1.3, "{}", per_leaf(&spheres));
    assert!(per_leaf(&tubes) < 1.3, "{}", per_leaf(&tubes));
}

// ---------------------------------------------------------------------------------------------
// Meshes whose neighbour runs straddle a scan chunk, with skipped primitives

/// A height field of `columns` x `rows` cells listed cell by cell: two triangles per cell, or
/// one bent quad. Triangle ids in `skipped` get zero area; quads in `skipped` lose their
/// first half (so box indices and source ids stop lining up, and runs shift by one).
fn mesh_height_field(
    rng: &mut Rng,
    columns: u32,
    rows: u32,
    quads: bool,
    skipped: &[usize],
) -> GeometryPrims {
    let mut positions = Vec::new();
    for y in 0..=rows {
        for x in 0..=columns {
            positions.push(vec3(x as f32 * 0.25, y as f32 * 0.25, rng.range(0.0, 0.3)));
        }
    }
    let corner = |x: u32, y: u32| y * (columns + 1) + x;
    let mut triangles = Vec::new();
    let mut quad_indices = Vec::new();
    for y in 0..rows {
        for x in 0..columns {
            let (a, b, c, d) = (
                corner(x, y),
                corner(x + 1, y),
                corner(x + 1, y + 1),
                corner(x, y + 1),
            );
            if quads {
                let quad = if skipped.contains(&quad_indices.len()) {
                    // (a, b, b) has no area; (a, b, d) stays.
                    UVec4::new(a, b, b, d)
                } else {
                    UVec4::new(a, b, c, d)
                };
                quad_indices.push(quad);
            } else {
                for corners in [UVec3::new(a, b, c), UVec3::new(a, c, d)] {
                    let corners = if skipped.contains(&triangles.len()) {
                        UVec3::new(a, a, b)
                    } else {
                        corners
                    };
                    triangles.push(corners);
                }
            }
        }
    }
    if quads {
        GeometryPrims::Quads {
            positions,
            indices: quad_indices,
        }
    } else {
        GeometryPrims::Triangles {
            positions,
            indices: triangles,
        }
    }
}

/// Single rays against brute force (t, id), each hit's record against the record of its
/// primitive alone (uv and normal), and packets (2x2 and frustum) against single rays.
fn check_mesh_against_references(prims: GeometryPrims, rng: &mut Rng, name: &str) {
    let geometry: TestGeometry = prims.into();
    let bvh = geometry.build();
    let (min, max) = bvh.bounds();
    let centre = (min + max) * 0.5;
    let extent = (max - min).max_element();
    let mut rays = Vec::new();
    for i in 0..1500 {
        let origin = centre + rng.direction() * extent * 0.8 + Vec3::Z * extent * 0.3;
        let target = min + (max - min) * rng.point(0.0, 1.0);
        let mut r = ray(origin, target - origin);
        if i % 5 == 0 {
            r.t_max = rng.range(0.0, 2.0 * extent);
        }
        rays.push(r);
    }
    let mut hit_count = 0;
    for (i, r) in rays.iter().enumerate() {
        let single = bvh.intersect(r);
        let context = format!("{name} ray {i} {r:?}");
        check_against_brute_force(
            &geometry,
            single.map(|hit| (hit.t, hit.primitive)),
            &traversal_ray(r),
            &context,
        );
        if let Some(hit) = single {
            hit_count += 1;
            let alone = single_primitive(&geometry, hit.primitive).build();
            let mut window = *r;
            (window.t_min, window.t_max) = (hit.t, hit.t);
            let reference = alone.intersect(&window).expect("primitive hit at its t");
            assert_eq!(
                (reference.t, reference.uv, reference.normal),
                (hit.t, hit.uv, hit.normal),
                "{context}"
            );
        }
    }
    assert!(hit_count > rays.len() / 2, "{name}: {hit_count}");
    // 2x2 packets and frustum packets from above.
    let mut packet_rays_list = packet_rays(rng, 400, extent * 0.5);
    for r in &mut packet_rays_list {
        r.origin += centre;
    }
    let eye = centre + vec3(0.3, -0.2, 1.0) * extent;
    packet_rays_list.extend(camera_tiles(rng, eye, centre, 64));
    let mut hits = vec![None; packet_rays_list.len()];
    bvh.intersect_packet(&packet_rays_list, &mut hits);
    let mut same = 0;
    for (r, packet_hit) in packet_rays_list.iter().zip(&hits) {
        let single = bvh.intersect(r);
        assert_eq!(single.map(|h| h.t), packet_hit.map(|h| h.t), "{name} {r:?}");
        if let (Some(single), Some(packet_hit)) = (single, packet_hit)
            && single.primitive == packet_hit.primitive
        {
            same += 1;
            assert_eq!(single, *packet_hit, "{name} {r:?}");
        }
    }
    assert!(same > 1000, "{name}: {same}");
}

#[test]
fn meshes_with_skipped_primitives_over_several_build_ranges_match_brute_force() {
    let mut rng = Rng::new(77);
    // 2 * 4500 triangles (more than one range built sequentially), id 0 skipped.
    let prims = mesh_height_field(&mut rng, 100, 45, false, &[0, 4500]);
    check_mesh_against_references(prims, &mut rng, "triangles");
    // Quads: 2400 quads, quad 3 keeps only one half.
    let prims = mesh_height_field(&mut rng, 60, 40, true, &[3]);
    check_mesh_against_references(prims, &mut rng, "quads");
}

#[test]
fn tiny_meshes_form_a_single_leaf_and_match_brute_force() {
    let mut rng = Rng::new(78);
    // Up to three pages turning about one shared edge: at most four triangles, so the
    // binary BVH is a single leaf.
    let positions = vec![
        vec3(0.0, 0.0, 0.0),
        vec3(0.0, 1.0, 0.0),
        vec3(1.0, 0.0, 0.0),
        vec3(1.0, 0.0, 0.3),
        vec3(1.0, 0.0, 0.6),
    ];
    let fan = [
        UVec3::new(0, 2, 1),
        UVec3::new(0, 3, 1),
        UVec3::new(0, 4, 1),
    ];
    for count in 1..=3 {
        let prims = GeometryPrims::Triangles {
            positions: positions.clone(),
            indices: fan[..count].to_vec(),
        };
        let geometry: TestGeometry = prims.into();
        let bvh = geometry.build();
        let mut hit_count = 0;
        let mut rays = Vec::new();
        for _ in 0..400 {
            let origin = vec3(0.25, 0.5, 3.0) + rng.point(-1.0, 1.0);
            let target = rng.point(-0.6, 1.1) * vec3(1.0, 1.0, 0.0);
            rays.push(ray(origin, target - origin));
        }
        for r in &rays {
            let single = bvh.intersect(r);
            check_against_brute_force(
                &geometry,
                single.map(|h| (h.t, h.primitive)),
                &traversal_ray(r),
                &format!("{count} triangles"),
            );
            hit_count += usize::from(single.is_some());
        }
        let mut hits = vec![None; rays.len()];
        bvh.intersect_packet(&rays, &mut hits);
        for (r, packet_hit) in rays.iter().zip(&hits) {
            assert_eq!(bvh.intersect(r), *packet_hit);
        }
        assert!(hit_count > 50, "{count}: {hit_count}");
        assert_eq!(bvh.leaf_count(), 1, "{count} triangles");
    }
}

#[test]
fn the_avx2_box_test_finds_the_hits_of_the_baseline() {
    use crate::accel::isa::{self, Isa};
    if !Isa::Avx2.supported() {
        eprintln!("this CPU has no AVX2 and FMA: only the baseline path exists here");
        return;
    }
    // Triangles, quads, spheres and tubes, one of them placed by a rotating, scaling instance;
    // rays from outside and inside, with and without windows, and grazing ones along the
    // grid's plane.
    let mut rng = Rng::new(19);
    let geometries: Vec<Arc<GeometryBvh>> = vec![
        Arc::new(GeometryBvh::build(random_triangles(
            &mut rng, 400, 4.0, 0.8,
        ))),
        Arc::new(GeometryBvh::build(random_quads(&mut rng, 200, 4.0, 0.8))),
        Arc::new(GeometryBvh::build(random_spheres(&mut rng, 200, 4.0, 0.4))),
        Arc::new(random_tubes(&mut rng, 100, 4.0, 0.8).build()),
        Arc::new(GeometryBvh::build(bumpy_grid(40).1)),
    ];
    let scene = SceneBvh::build(vec![
        identity_instance(geometries[..4].to_vec()),
        InstanceDesc {
            transform: Affine3A::from_scale_rotation_translation(
                vec3(1.5, 0.7, 1.1),
                Quat::from_rotation_y(0.6),
                vec3(0.3, -1.0, 0.2),
            ),
            geometries: vec![geometries[4].clone()],
        },
    ]);
    let mut rays = random_rays(&mut rng, 20_000, 4.0);
    rays.extend((0..2_000).map(|_| {
        let origin = vec3(rng.range(-6.0, 6.0), -1.0, rng.range(-6.0, 6.0));
        Ray::new(
            origin,
            vec3(rng.range(-1.0, 1.0), 1e-4, 1.0).normalize(),
            0.0,
            f32::INFINITY,
        )
    }));
    // Single placements too: there `intersect_into` inlines the AVX2 walk into a function
    // compiled for AVX2 as a whole (triangles, quads, and under a transform).
    let transform = Affine3A::from_scale_rotation_translation(
        vec3(1.2, 0.9, 1.0),
        Quat::from_rotation_x(0.4),
        vec3(0.1, 0.2, -0.3),
    );
    let scenes = [
        scene,
        SceneBvh::build(vec![identity_instance(vec![geometries[0].clone()])]),
        SceneBvh::build(vec![identity_instance(vec![geometries[1].clone()])]),
        SceneBvh::build(vec![InstanceDesc {
            transform,
            geometries: vec![geometries[0].clone()],
        }]),
    ];
    // Per ray: `intersect`, `intersect_into` and `occluded`.
    let trace = |scene: &SceneBvh, isa: Isa| -> Vec<(Option<SceneHit>, Option<SceneHit>, bool)> {
        assert_eq!(isa::select(isa), isa);
        rays.iter()
            .map(|ray| {
                let mut written = None;
                scene.intersect_into(ray, &mut written);
                (scene.intersect(ray), written, scene.occluded(ray))
            })
            .collect()
    };
    for (k, scene) in scenes.iter().enumerate() {
        let baseline = trace(scene, Isa::Baseline);
        let avx2 = trace(scene, Isa::Avx2);
        isa::select(Isa::from_environment());
        let hits = baseline.iter().filter(|(hit, ..)| hit.is_some()).count();
        assert!(hits > rays.len() / 10, "scene {k}: only {hits} hits");
        for (i, (a, b)) in baseline.iter().zip(&avx2).enumerate() {
            // Bit for bit: t, ids, barycentrics and normals, by both queries.
            assert_eq!(a.0, a.1, "scene {k}, ray {i}: {:?}", rays[i]);
            assert_eq!(
                format!("{a:?}"),
                format!("{b:?}"),
                "scene {k}, ray {i}: {:?}",
                rays[i]
            );
        }
    }
}

#[test]
fn frustum_packets_find_the_same_hits_on_every_path() {
    use crate::accel::isa::{self, Isa};
    if !Isa::Avx2.supported() {
        eprintln!("this CPU has no AVX2 and FMA: only the baseline path exists here");
        return;
    }
    // A height field (leaves of one or two quads, split into spare slots) and random
    // triangles, seen by pinhole tiles from several sides.
    let mut rng = Rng::new(23);
    let grid_views = [
        (vec3(-10.0, -8.0, 15.0), vec3(24.0, 24.0, 0.0)),
        (vec3(30.0, 20.0, 20.0), vec3(20.0, 25.0, 0.0)),
        (vec3(24.0, 23.0, 40.0), vec3(24.0, 24.0, 0.0)),
    ];
    let random_views = [
        (vec3(-9.0, -7.0, 6.0), Vec3::ZERO),
        (vec3(2.0, 3.0, 12.0), vec3(0.5, -0.5, 0.0)),
        (vec3(8.0, -0.5, 1.0), vec3(-1.0, 0.5, 0.0)),
    ];
    let geometries = [
        (GeometryBvh::build(bumpy_grid(48).1), grid_views),
        (
            GeometryBvh::build(random_triangles(&mut rng, 3000, 6.0, 0.8)),
            random_views,
        ),
    ];
    for (bvh, views) in &geometries {
        for &(eye, target) in views {
            let rays = camera_tiles(&mut rng, eye, target, 64);
            let trace = |isa: Isa| {
                assert_eq!(isa::select(isa), isa);
                let mut hits = vec![None; rays.len()];
                bvh.intersect_packet(&rays, &mut hits);
                hits
            };
            let baseline = trace(Isa::Baseline);
            let avx2 = trace(Isa::Avx2);
            isa::select(Isa::from_environment());
            let hit_count = baseline.iter().flatten().count();
            assert!(hit_count > rays.len() / 4, "{hit_count} hits from {eye}");
            for (i, (a, b)) in baseline.iter().zip(&avx2).enumerate() {
                // Bit for bit: t, ids, barycentrics and normals.
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "ray {i}: {:?}", rays[i]);
                assert_eq!(
                    a.map(|hit| hit.t),
                    bvh.intersect(&rays[i]).map(|hit| hit.t),
                    "ray {i}: {:?}",
                    rays[i]
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Watertightness of closed meshes

/// An icosphere of radius 1 (the icosahedron's faces split four-fold `levels` times), with
/// vertices shared between faces.
fn icosphere(levels: u32) -> (Vec<Vec3>, Vec<UVec3>) {
    let g = (1.0 + 5f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        (-1.0, g, 0.0),
        (1.0, g, 0.0),
        (-1.0, -g, 0.0),
        (1.0, -g, 0.0),
        (0.0, -1.0, g),
        (0.0, 1.0, g),
        (0.0, -1.0, -g),
        (0.0, 1.0, -g),
        (g, 0.0, -1.0),
        (g, 0.0, 1.0),
        (-g, 0.0, -1.0),
        (-g, 0.0, 1.0),
    ]
    .map(|(x, y, z)| vec3(x, y, z).normalize())
    .to_vec();
    let mut faces: Vec<UVec3> = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ]
    .map(UVec3::from_array)
    .to_vec();
    for _ in 0..levels {
        let mut midpoints = std::collections::HashMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let p = (positions[a as usize] + positions[b as usize]).normalize();
                positions.push(p);
                positions.len() as u32 - 1
            })
        };
        let mut next = Vec::new();
        for face in &faces {
            let [a, b, c] = face.to_array();
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            next.extend(
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]].map(UVec3::from_array),
            );
        }
        faces = next;
    }
    (positions, faces)
}

/// A cube over [-1, 1]³ of `n`×`n` quads per face, vertices shared along its edges; every
/// coordinate is a multiple of 2 / n, so the midpoint of any edge is exact.
fn cube_of_quads(n: u32) -> (Vec<Vec3>, Vec<UVec4>) {
    let mut positions = Vec::new();
    let mut index = std::collections::HashMap::new();
    let mut vertex = |p: [i32; 3], positions: &mut Vec<Vec3>| {
        *index.entry(p).or_insert_with(|| {
            let scale = 2.0 / n as f32;
            positions.push(Vec3::from_array(p.map(|c| c as f32 * scale - 1.0)));
            positions.len() as u32 - 1
        })
    };
    let n = n as i32;
    let mut quads = Vec::new();
    for axis in 0..3 {
        for side in [0, n] {
            for i in 0..n {
                for j in 0..n {
                    let corner = |di: i32, dj: i32| {
                        let mut p = [0; 3];
                        p[axis] = side;
                        p[(axis + 1) % 3] = i + di;
                        p[(axis + 2) % 3] = j + dj;
                        p
                    };
                    let corners = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                    let ids = corners.map(|c| vertex(c, &mut positions));
                    quads.push(UVec4::from_array(ids));
                }
            }
        }
    }
    (positions, quads)
}

/// Points on every vertex and (as exactly as floats allow) on every edge of the mesh.
fn vertices_and_edge_points(positions: &[Vec3], faces: &[Vec<u32>]) -> Vec<Vec3> {
    let mut points = positions.to_vec();
    for face in faces {
        for (k, &a) in face.iter().enumerate() {
            let b = face[(k + 1) % face.len()];
            let (pa, pb) = (positions[a as usize], positions[b as usize]);
            points.extend([0.5, 0.25, 0.125].map(|w| pa + (pb - pa) * w));
        }
        // The diagonal along which a quad is split.
        if face.len() == 4 {
            let (pa, pc) = (positions[face[0] as usize], positions[face[2] as usize]);
            points.push(pa + (pc - pa) * 0.5);
        }
    }
    points
}

/// Plain Möller–Trumbore in f32 (not watertight): shows that the rays below do probe the gaps
/// a non-watertight test leaves.
fn moller_trumbore(origin: Vec3, direction: Vec3, [v0, v1, v2]: [Vec3; 3]) -> bool {
    let (e1, e2) = (v1 - v0, v2 - v0);
    let p = direction.cross(e2);
    let determinant = e1.dot(p);
    if determinant == 0.0 {
        return false;
    }
    let inv = 1.0 / determinant;
    let s = origin - v0;
    let u = s.dot(p) * inv;
    let q = s.cross(e1);
    let v = direction.dot(q) * inv;
    u >= 0.0 && v >= 0.0 && u + v <= 1.0 && e2.dot(q) * inv > 0.0
}

#[test]
fn rays_through_shared_edges_and_vertices_of_closed_meshes_never_leak() {
    let (sphere_positions, sphere_faces) = icosphere(3);
    let (cube_positions, cube_quads) = cube_of_quads(6);
    let meshes = [
        (
            GeometryPrims::Triangles {
                positions: sphere_positions.clone(),
                indices: sphere_faces.clone(),
            },
            vertices_and_edge_points(
                &sphere_positions,
                &sphere_faces
                    .iter()
                    .map(|f| f.to_array().to_vec())
                    .collect::<Vec<_>>(),
            ),
            sphere_faces
                .iter()
                .map(|f| f.to_array().map(|i| sphere_positions[i as usize]))
                .collect::<Vec<_>>(),
        ),
        (
            GeometryPrims::Quads {
                positions: cube_positions.clone(),
                indices: cube_quads.clone(),
            },
            vertices_and_edge_points(
                &cube_positions,
                &cube_quads
                    .iter()
                    .map(|q| q.to_array().to_vec())
                    .collect::<Vec<_>>(),
            ),
            cube_quads
                .iter()
                .flat_map(|q| {
                    let [a, b, c, d] = q.to_array().map(|i| cube_positions[i as usize]);
                    [[a, b, c], [a, c, d]]
                })
                .collect::<Vec<_>>(),
        ),
    ];
    let mut rng = Rng::new(23);
    let mut naive_leaks = 0;
    for (prims, targets, triangles) in meshes {
        let geometry = Arc::new(GeometryBvh::build(prims));
        let scene = SceneBvh::build(vec![identity_instance(vec![geometry.clone()])]);
        // From the centre (the direction is the target itself, so the ray passes exactly
        // through it), from points inside, and from outside towards the target.
        let mut rays = Vec::new();
        for &target in &targets {
            rays.push(Ray::new(Vec3::ZERO, target, 0.0, f32::INFINITY));
            let inside = rng.point(-0.3, 0.3);
            rays.push(Ray::new(inside, target - inside, 0.0, f32::INFINITY));
            let outside = target * 3.0 + rng.point(-0.5, 0.5);
            rays.push(Ray::new(outside, target - outside, 0.0, f32::INFINITY));
        }
        // Packets form from rays sharing octant and dominant axis: group them so.
        let key = |ray: &Ray| {
            let d = ray.direction;
            let octant = (d.x < 0.0) as u32 * 4 + (d.y < 0.0) as u32 * 2 + (d.z < 0.0) as u32;
            let a = d.abs();
            let dominant = if a.x >= a.y && a.x >= a.z {
                0
            } else if a.y >= a.z {
                1
            } else {
                2
            };
            octant * 3 + dominant
        };
        rays.sort_by_key(key);
        let mut packet_hits = vec![None; rays.len()];
        scene.intersect_packet(&rays, &mut packet_hits);
        for (ray, packet_hit) in rays.iter().zip(&packet_hits) {
            let hit = geometry.intersect(ray);
            let t = hit.map(|hit| hit.t);
            assert!(t.is_some(), "{ray:?} leaked through the mesh");
            assert!(geometry.occluded(ray), "{ray:?} leaked for any-hit");
            assert_eq!(scene.intersect(ray).map(|hit| hit.t), t, "{ray:?}");
            assert_eq!(packet_hit.map(|hit| hit.t), t, "{ray:?} in a packet");
            let naive_hit = triangles
                .iter()
                .any(|&triangle| moller_trumbore(ray.origin, ray.direction, triangle));
            naive_leaks += usize::from(!naive_hit);
        }
    }
    assert!(
        naive_leaks > 0,
        "the rays should find the gaps of a non-watertight test"
    );
    eprintln!("Möller–Trumbore leaked {naive_leaks} of the rays");
}

/// Height field of `cells` x `cells` quads: vertices and the quads' corner indices.
fn height_field_grid(cells: u32) -> (Vec<Vec3>, Vec<UVec4>) {
    let n = cells + 1;
    let positions = (0..n * n)
        .map(|k| {
            let (x, z) = ((k % n) as f32 / cells as f32, (k / n) as f32 / cells as f32);
            vec3(x, 0.05 * (x * 9.0).sin() * (z * 7.0).cos(), z)
        })
        .collect();
    let quads = (0..cells * cells)
        .map(|k| {
            let a = (k / cells) * n + k % cells;
            UVec4::new(a, a + 1, a + n + 1, a + n)
        })
        .collect();
    (positions, quads)
}

/// The build's layout (nodes, slots, groups, ids) is pinned: faster builders must produce
/// exactly this BVH. Covers the triangle path with and without skipped triangles, quads and
/// spheres (split leaves, packed order), each large enough for the parallel collapse.
/// The collapse chooses which binary subtrees become wide nodes for the least surface-area
/// cost of node visits: on a height field (the kernel bench's scene) few subtrees of at most
/// eight triangles stay wide nodes of their own, unlike with the greedy collapse that opened
/// the largest child first (45,000 triangles: 4,147 nodes, 1,533 of them over at most eight
/// triangles, node cost 6.83; with node visits only 2,748, 402 and 6.54; with leaf tests
/// weighed too 2,485, 146 and 6.60).
#[test]
fn wide_nodes_are_chosen_by_surface_area_cost() {
    let (positions, quads) = height_field_grid(150);
    let bvh = GeometryBvh::build(GeometryPrims::Quads {
        positions,
        indices: quads,
    });
    let shape = bvh.tree_shape();
    assert_eq!(shape.primitives, 45_000, "{shape:?}");
    let small = shape.bottom_nodes[1] + shape.bottom_nodes[2];
    assert!(shape.nodes <= 3_000 && small <= 600, "{shape:?}");
    assert!(shape.node_cost <= 6.65, "{shape:?}");
    // Leaf tests are weighed too: leaves split where slots are left (leaf cost 1.376 when
    // only node visits were weighed, now 1.355), with no more nodes.
    assert!(
        shape.leaf_cost <= 1.365 && shape.nodes <= 2_600,
        "{shape:?}"
    );
}

#[test]
fn build_layout_is_unchanged() {
    let (positions, quads) = height_field_grid(150);
    let triangles: Vec<UVec3> = quads
        .iter()
        .flat_map(|q| [UVec3::new(q.x, q.y, q.z), UVec3::new(q.x, q.z, q.w)])
        .collect();
    let mut with_skipped = triangles.clone();
    for triangle in with_skipped.iter_mut().step_by(97) {
        triangle.y = triangle.x;
    }
    let mut rng = Rng::new(7);
    let fingerprints = [
        GeometryPrims::Triangles {
            positions: positions.clone(),
            indices: triangles,
        },
        GeometryPrims::Triangles {
            positions: positions.clone(),
            indices: with_skipped,
        },
        GeometryPrims::Quads {
            positions,
            indices: quads,
        },
        random_spheres(&mut rng, 20_000, 10.0, 0.05),
    ]
    .map(|prims| GeometryBvh::build(prims).layout_fingerprint());
    assert_eq!(
        fingerprints,
        [
            11121132436863608239,
            3739929396152544745,
            5134351330432008883,
            17152728817455457097
        ]
    );
}

#[test]
fn frustum_packets_filled_from_lane_arrays_match_those_filled_from_rays() {
    use crate::accel::frustum::FrustumPacket;
    let mut rng = Rng::new(95);
    let triangles = TestGeometry::from(random_triangles(&mut rng, 3000, 10.0, 1.5)).build();
    let scene = SceneBvh::build(vec![identity_instance(vec![Arc::new(triangles)])]);
    let (mut scratch, mut reference_scratch) = (PacketScratch::new(), PacketScratch::new());
    let (mut formed, mut hit_count) = (0, 0);
    for round in 0..200 {
        // Eyes in all eight octants around the scene, looking at points near its centre.
        let corner = vec3(
            if round & 1 == 0 { -25.0 } else { 25.0 },
            if round & 2 == 0 { -18.0 } else { 18.0 },
            if round & 4 == 0 { -12.0 } else { 12.0 },
        );
        let target = if round % 16 < 8 {
            rng.point(-3.0, 3.0)
        } else {
            // Views along an axis: tiles straddle octants or dominant axes.
            corner * vec3(1.0, 0.0, 0.0)
        };
        // One 8x8 tile of a 48x48 view.
        let tile = (rng.next_u64() % 36) as usize;
        let mut rays =
            camera_tiles(&mut rng, corner, target, 48)[64 * tile..64 * tile + 64].to_vec();
        for (lane, ray) in rays.iter_mut().enumerate() {
            // Per-lane origins (several viewers, a near plane) in half of the rounds.
            if round % 4 >= 2 {
                ray.origin += rng.point(-0.3, 0.3);
            }
            match rng.next_u64() % 40 {
                0 => ray.origin.x = f32::NAN,
                1 => ray.t_max = f32::NAN,
                2 => ray.t_min = ray.t_max + 1.0,
                3 => ray.direction = Vec3::splat(1.0e-30),
                4 if round % 8 == 7 => ray.direction = -ray.direction,
                _ => {}
            }
            // A whole group without a valid ray.
            if round % 10 == 9 && lane / 4 == 5 {
                ray.direction = Vec3::ZERO;
            }
        }
        let lanes = |of: fn(&Ray) -> f32| -> [f32; 64] { std::array::from_fn(|i| of(&rays[i])) };
        let origin = [
            lanes(|r| r.origin.x),
            lanes(|r| r.origin.y),
            lanes(|r| r.origin.z),
        ];
        let direction = [
            lanes(|r| r.direction.x),
            lanes(|r| r.direction.y),
            lanes(|r| r.direction.z),
        ];
        let (t_min, t_max) = (lanes(|r| r.t_min), lanes(|r| r.t_max));
        let arrays = RayArrays {
            origin: &origin,
            direction: &direction,
            t_min: &t_min,
            t_max: &t_max,
        };
        let (mut from_arrays, mut from_rays) = (FrustumPacket::empty(), FrustumPacket::empty());
        let filled = from_arrays.fill_from_arrays(&arrays);
        assert_eq!(filled, from_rays.fill_from_rays(&rays), "round {round}");
        if filled {
            formed += 1;
            assert_eq!(from_arrays.group_count, from_rays.group_count);
            for (a, b) in from_arrays.groups.iter().zip(&from_rays.groups) {
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "round {round}");
            }
        }
        let mut hits = [None; 64];
        let mut reference = [None; 64];
        scene.intersect_arrays_with(&mut scratch, &arrays, &mut hits);
        scene.intersect_packet_with(&mut reference_scratch, &rays, &mut reference);
        assert_eq!(hits, reference, "round {round}");
        hit_count += hits.iter().flatten().count();
    }
    // Most blocks make frustum packets; some fall back; many rays hit.
    assert!((100..200).contains(&formed), "{formed}");
    assert!(hit_count > 200 * 6, "{hit_count} {formed}");
}

#[test]
fn hits_written_in_place_are_the_returned_hits() {
    // Random triangles, and two placements (one moved) so the two-level walk is used too.
    let mut rng = Rng::new(0x1a7e);
    let prims = random_triangles(&mut rng, 400, 2.0, 0.4);
    let bvh = Arc::new(GeometryBvh::build(prims));
    let single = SceneBvh::build(vec![identity_instance(vec![bvh.clone()])]);
    let mut moved = identity_instance(vec![bvh.clone()]);
    moved.transform = glam::Affine3A::from_translation(vec3(0.3, -0.2, 0.1));
    let two = SceneBvh::build(vec![identity_instance(vec![bvh]), moved]);
    let stale = SceneHit {
        t: -1.0,
        instance: 7,
        geometry: 7,
        primitive: 7,
        uv: Vec2::ZERO,
        normal: Vec3::Z,
        object_normal: Vec3::Z,
    };
    let (mut hit_count, mut miss_count) = (0, 0);
    for scene in [&single, &two] {
        for ray in random_rays(&mut rng, 2000, 3.0) {
            let mut written = Some(stale);
            scene.intersect_into(&ray, &mut written);
            let returned = scene.intersect(&ray);
            assert_eq!(written, returned, "{ray:?}");
            match returned {
                Some(_) => hit_count += 1,
                None => miss_count += 1,
            }
        }
    }
    assert!(
        hit_count > 200 && miss_count > 200,
        "{hit_count} hits, {miss_count} misses"
    );
}

/// Rays lying exactly in a child box's face plane (a direction component of exactly 0, the
/// origin on the plane): the camera at the origin looks at a square whose right edge is at
/// x = 0, so the centre column runs along that edge. Whatever a path decides for such a ray,
/// single rays on every instruction set and frustum packets must decide the same (a budgeted
/// frame's sparse levels trace rays one by one, the full frame in packets).
#[test]
fn rays_in_a_box_face_plane_find_the_same_hits_on_every_path() {
    use crate::accel::isa::{self, Isa};
    if !Isa::Avx2.supported() {
        return;
    }
    let square = |x: f32, y: f32, z: f32, side: f32| {
        let h = side / 2.0;
        Arc::new(GeometryBvh::build(GeometryPrims::Triangles {
            positions: vec![
                vec3(x - h, y - h, z),
                vec3(x + h, y - h, z),
                vec3(x + h, y + h, z),
                vec3(x - h, y - h, z),
                vec3(x + h, y + h, z),
                vec3(x - h, y + h, z),
            ],
            indices: vec![glam::UVec3::new(0, 1, 2), glam::UVec3::new(3, 4, 5)],
        }))
    };
    let scene = SceneBvh::build(vec![identity_instance(vec![
        square(-0.4, 0.1, -3.0, 0.8),
        square(0.3, -0.2, -6.0, 2.5),
    ])]);
    let mut rays = Vec::new();
    for j in 0..47 {
        for i in 0..61 {
            let d = vec3(
                (i as f32 + 0.5) / 61.0 * 1.2 - 0.6,
                (j as f32 + 0.5) / 47.0 * 0.9 - 0.45,
                -1.0,
            );
            rays.push(Ray::new(Vec3::ZERO, d.normalize(), 0.0, f32::INFINITY));
        }
    }
    let on_the_edge = rays.iter().filter(|ray| ray.direction.x == 0.0).count();
    assert_eq!(on_the_edge, 47);
    let trace = |isa: Isa| -> Vec<Option<SceneHit>> {
        assert_eq!(isa::select(isa), isa);
        rays.iter().map(|ray| scene.intersect(ray)).collect()
    };
    let baseline = trace(Isa::Baseline);
    let avx2 = trace(Isa::Avx2);
    isa::select(Isa::from_environment());
    let hits = baseline.iter().filter(|hit| hit.is_some()).count();
    assert!(hits > 500, "only {hits} hits");
    let differing: Vec<usize> = (0..rays.len())
        .filter(|&i| format!("{:?}", baseline[i]) != format!("{:?}", avx2[i]))
        .collect();
    assert!(
        differing.is_empty(),
        "{} rays differ between the ISAs, e.g. {:?}",
        differing.len(),
        differing.first().map(|&i| (rays[i], baseline[i], avx2[i]))
    );
    // Packets of 8x8 rays from the same origin find what single rays find.
    let mut scratch = PacketScratch::new();
    let mut packet_hits = [None; 64];
    for (chunk_index, chunk) in rays.chunks(64).enumerate() {
        scene.intersect_packet_with(&mut scratch, chunk, &mut packet_hits);
        for (lane, hit) in packet_hits[..chunk.len()].iter().enumerate() {
            let i = chunk_index * 64 + lane;
            assert_eq!(
                format!("{hit:?}"),
                format!("{:?}", baseline[i]),
                "ray {i}: {:?}",
                rays[i]
            );
        }
    }
}
