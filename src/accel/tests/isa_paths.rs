//! Every instruction-set path this CPU has (baseline, AVX2, AVX-512) finds the same hits, bit
//! for bit.

use super::*;

/// The paths to compare with the baseline: each wider one this CPU has.
fn wider_paths() -> Vec<crate::accel::isa::Isa> {
    let paths = crate::accel::isa::test_paths();
    if paths.len() == 1 {
        eprintln!("this CPU has no AVX2 and FMA: only the baseline path exists here");
    }
    paths[1..].to_vec()
}

#[test]
fn the_wide_box_tests_find_the_hits_of_the_baseline() {
    use crate::accel::isa::{self, Isa};
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
    // compiled for the path as a whole (triangles, quads, and under a transform).
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
        isa::on_path(isa, || {
            rays.iter()
                .map(|ray| {
                    let mut written = None;
                    scene.intersect_into(ray, &mut written);
                    (scene.intersect(ray), written, scene.occluded(ray))
                })
                .collect()
        })
    };
    for (k, scene) in scenes.iter().enumerate() {
        let baseline = trace(scene, Isa::Baseline);
        let hits = baseline.iter().filter(|(hit, ..)| hit.is_some()).count();
        assert!(hits > rays.len() / 10, "scene {k}: only {hits} hits");
        for isa in wider_paths() {
            let wide = trace(scene, isa);
            for (i, (a, b)) in baseline.iter().zip(&wide).enumerate() {
                // Bit for bit: t, ids, barycentrics and normals, by both queries.
                assert_eq!(a.0, a.1, "scene {k}, ray {i}: {:?}", rays[i]);
                assert_eq!(
                    format!("{a:?}"),
                    format!("{b:?}"),
                    "{isa:?}, scene {k}, ray {i}: {:?}",
                    rays[i]
                );
            }
        }
    }
}

#[test]
fn frustum_packets_find_the_same_hits_on_every_path() {
    use crate::accel::isa::{self, Isa};
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
                isa::on_path(isa, || {
                    let mut hits = vec![None; rays.len()];
                    bvh.intersect_packet(&rays, &mut hits);
                    hits
                })
            };
            let baseline = trace(Isa::Baseline);
            let hit_count = baseline.iter().flatten().count();
            assert!(hit_count > rays.len() / 4, "{hit_count} hits from {eye}");
            for (i, a) in baseline.iter().enumerate() {
                assert_eq!(
                    a.map(|hit| hit.t),
                    bvh.intersect(&rays[i]).map(|hit| hit.t),
                    "ray {i}: {:?}",
                    rays[i]
                );
            }
            for isa in wider_paths() {
                let wide = trace(isa);
                for (i, (a, b)) in baseline.iter().zip(&wide).enumerate() {
                    // Bit for bit: t, ids, barycentrics and normals.
                    let what = format!("{isa:?}, ray {i}: {:?}", rays[i]);
                    assert_eq!(format!("{a:?}"), format!("{b:?}"), "{what}");
                }
            }
        }
    }
}

/// Rays lying exactly in a child box's face plane (a direction component of exactly 0, the
/// origin on the plane): the camera at the origin looks at a square whose right edge is at
/// x = 0, so the centre column runs along that edge. Whatever a path decides for such a ray,
/// single rays on every instruction set and frustum packets must decide the same (a budgeted
/// frame's sparse levels trace rays one by one, the full frame in packets).
#[test]
fn rays_in_a_box_face_plane_find_the_same_hits_on_every_path() {
    use crate::accel::isa::{self, Isa};
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
        isa::on_path(isa, || {
            rays.iter().map(|ray| scene.intersect(ray)).collect()
        })
    };
    let baseline = trace(Isa::Baseline);
    let hits = baseline.iter().filter(|hit| hit.is_some()).count();
    assert!(hits > 500, "only {hits} hits");
    for isa in wider_paths() {
        let wide = trace(isa);
        let differing: Vec<usize> = (0..rays.len())
            .filter(|&i| format!("{:?}", baseline[i]) != format!("{:?}", wide[i]))
            .collect();
        assert!(
            differing.is_empty(),
            "{} rays differ between baseline and {isa:?}, e.g. {:?}",
            differing.len(),
            differing.first().map(|&i| (rays[i], baseline[i], wide[i]))
        );
    }
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
