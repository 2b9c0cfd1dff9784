//! Invalid primitives, rays and empty geometries.

use super::*;

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
