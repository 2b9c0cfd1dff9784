//! Instances: transformed placements, the top level, several geometries per instance.

use super::*;

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
        let transform = random_transform(&mut rng, 12.0);
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
