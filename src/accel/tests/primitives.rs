//! Triangles, quads, spheres and tubes against analytic answers.

use super::*;

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
