//! Packets of four rays and frustum packets: the hits of single rays, every path.

use super::*;

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
            transform: random_transform(&mut rng, 12.0),
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
            transform: random_transform(&mut rng, 10.0),
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
fn blocks_of_several_octants_or_dominant_axes_find_the_hits_of_single_rays() {
    use crate::accel::frustum::FrustumPacket;
    use crate::accel::isa;
    let mut rng = Rng::new(77);
    let triangles = TestGeometry::from(random_triangles(&mut rng, 3000, 10.0, 1.5)).build();
    let scene = SceneBvh::build(vec![identity_instance(vec![Arc::new(triangles)])]);
    // Blocks the fill refuses, and how many of them have two classes of eight rays or more
    // (octant × dominant axis): those are split into frustum packets.
    let (mut refused, mut split) = (0, 0);
    for round in 0..120 {
        // An 8x8 block looking at the scene's centre, its rays fanned so wide that they cross
        // the planes where a direction component changes sign (and, turned by 45°, where two
        // components are equally long).
        let eye = rng.point(-1.0, 1.0) + vec3(0.0, 0.0, 25.0);
        let turn = if round % 2 == 0 {
            0.0
        } else {
            std::f32::consts::FRAC_PI_4
        };
        let (sin, cos) = turn.sin_cos();
        let centre = rng.point(-0.05, 0.05);
        let rays: Vec<Ray> = (0..64)
            .map(|lane| {
                let (x, y) = ((lane % 8) as f32 - 3.5, (lane / 8) as f32 - 3.5);
                let spread = rng.range(0.5, 1.5);
                let (u, v) = (x * spread, y * spread);
                let target = centre + vec3(u * cos - v * sin, u * sin + v * cos, 0.0);
                let mut ray = Ray::new(eye, (target - eye).normalize(), 0.0, f32::INFINITY);
                // Some rays in a class of their own, some that cannot be traced.
                match rng.next_u64() % 24 {
                    0 => ray.direction = -ray.direction,
                    1 => ray.t_max = f32::NAN,
                    _ => {}
                }
                ray
            })
            .collect();
        let mut lanes = crate::accel::frustum::LaneArrays::of_rays(&rays);
        if round % 3 == 2 {
            // Per-lane origins.
            for lane in 0..64 {
                lanes.origin[0][lane] += rng.range(-0.2, 0.2);
            }
        }
        let arrays = lanes.arrays();
        let rays: Vec<Ray> = (0..64).map(|lane| arrays.ray(lane)).collect();
        if FrustumPacket::empty().fill_from_arrays(&arrays) {
            continue;
        }
        refused += 1;
        let mut classes = std::collections::HashMap::new();
        for ray in rays.iter().filter_map(crate::accel::geometry::prepare) {
            *classes
                .entry((ray.octant_inv, ray.shear_axes[2]))
                .or_insert(0) += 1;
        }
        if classes.values().filter(|&&count| count >= 8).count() >= 2 {
            split += 1;
        }
        let single: Vec<String> = isa::on_path(isa::Isa::Baseline, || {
            rays.iter()
                .map(|ray| format!("{:?}", scene.intersect(ray)))
                .collect()
        });
        for path in isa::test_paths() {
            let (from_arrays, from_rays) = isa::on_path(path, || {
                let mut scratch = PacketScratch::new();
                let (mut from_arrays, mut from_rays) = ([None; 64], [None; 64]);
                scene.intersect_arrays_with(&mut scratch, &arrays, &mut from_arrays);
                scene.intersect_packet_with(&mut scratch, &rays, &mut from_rays);
                (from_arrays, from_rays)
            });
            for lane in 0..64 {
                assert_eq!(
                    format!("{:?}", from_arrays[lane]),
                    single[lane],
                    "round {round}, lane {lane}, {path:?}"
                );
                assert_eq!(
                    format!("{:?}", from_rays[lane]),
                    single[lane],
                    "round {round}, lane {lane}, {path:?}"
                );
            }
        }
    }
    assert!(
        refused >= 60 && split >= 40,
        "{refused} refused, {split} split"
    );
}
