//! The walk of eight rays together (`SceneBvh::intersect8`) against rays one by one.

use super::*;
use crate::accel::isa;

/// `SceneBvh::intersect8` against `intersect_into`, record by record, on random rays in eights
/// (mixed octants and intervals, a few with `t_min < 0` or no direction), on coherent eights
/// (eight origins centimetres apart looking at one spot, as light-field subpixels) and on eights
/// aimed at a grid's vertices and edges (ties between triangles, where only the same visiting
/// order gives the same record); on one untransformed placement, one transformed placement, and
/// several placements (the top level walked together): two in one instance, the same grid
/// twice in one place untransformed and twice turned (every hit a tie between placements),
/// triangles beside spheres, 56 instances of small grids turned about every axis (object rays of one eight
/// in several octants) some twice in one place, spheres only (ray by ray); and with a stack
/// too small for the walks of eights, so that their rays fall back to the single-ray walk.
#[test]
fn rays_in_eights_get_the_records_of_single_rays() {
    // The walk of eights is AVX2 only, taken on the AVX2 and AVX-512 paths (else the rays go
    // one by one); both are checked, with the fallbacks' single rays on each.
    let wide_paths = &isa::test_paths()[1..];
    if wide_paths.is_empty() {
        return;
    }
    let mut rng = Rng::new(808);
    let cloud = Arc::new(GeometryBvh::build(random_triangles(
        &mut rng, 3000, 4.0, 0.6,
    )));
    let (_, grid_prims) = bumpy_grid(24);
    let grid = Arc::new(GeometryBvh::build(grid_prims));
    let turned = InstanceDesc {
        transform: Affine3A::from_scale_rotation_translation(
            Vec3::splat(0.75),
            glam::Quat::from_rotation_z(0.3),
            vec3(-6.0, -5.0, 0.5),
        ),
        geometries: vec![grid.clone()],
    };
    let spheres = Arc::new(GeometryBvh::build(random_spheres(&mut rng, 300, 8.0, 0.6)));
    let placed = |transform: Affine3A, geometries: Vec<Arc<GeometryBvh>>| InstanceDesc {
        transform,
        geometries,
    };
    // The grid twice in one place, untransformed and turned: every hit on one is a hit at the
    // same `t` on the other (ties between placements).
    let twins = vec![
        identity_instance(vec![grid.clone()]),
        identity_instance(vec![grid.clone()]),
        placed(turned.transform, vec![grid.clone()]),
        placed(turned.transform, vec![grid.clone()]),
    ];
    // Small grids scattered and turned about every axis (object rays of one eight in
    // different octants), some twice in one place: a top level of several levels.
    let mut scattered = Vec::new();
    for i in 0..48 {
        let axis = [Vec3::X, Vec3::Y, Vec3::Z, vec3(1.0, 1.0, 0.0).normalize()][i % 4];
        let transform = Affine3A::from_scale_rotation_translation(
            Vec3::splat(rng.range(0.1, 0.3)),
            glam::Quat::from_axis_angle(axis, 0.4 * i as f32),
            rng.point(-10.0, 10.0),
        );
        // Every third with spheres beside the grid, every sixth placed twice.
        let mut geometries = vec![grid.clone()];
        if i % 3 == 0 {
            geometries.push(spheres.clone());
        }
        for _ in 0..1 + usize::from(i % 6 == 0) {
            scattered.push(placed(transform, geometries.clone()));
        }
    }
    let scenes = [
        (vec![identity_instance(vec![cloud.clone()])], 4.0f32, true),
        (vec![identity_instance(vec![grid.clone()])], 12.0, true),
        (vec![turned.clone()], 12.0, true),
        (
            vec![identity_instance(vec![cloud.clone(), grid.clone()])],
            12.0,
            true,
        ),
        (twins, 12.0, true),
        // Mixed kinds: triangles walked together, spheres lane by lane.
        (
            vec![
                identity_instance(vec![cloud.clone(), spheres.clone()]),
                placed(turned.transform, vec![spheres.clone(), grid.clone()]),
            ],
            12.0,
            true,
        ),
        (scattered, 12.0, true),
        // No triangles among several placements: ray by ray.
        (
            vec![
                identity_instance(vec![spheres.clone()]),
                placed(turned.transform, vec![spheres]),
            ],
            12.0,
            false,
        ),
    ];
    let mut compared = 0;
    for (index, (instances, extent, walked_together)) in scenes.into_iter().enumerate() {
        let scene = SceneBvh::build(instances);
        isa::select(isa::Isa::Avx2);
        assert_eq!(
            scene.walks_eights_together(),
            walked_together && !crate::accel::counters::ENABLED,
            "{scene:?}"
        );
        let mut eights: Vec<[Ray; 8]> = Vec::new();
        let mut random = random_rays(&mut rng, 8 * 200, extent);
        for (i, ray) in random.iter_mut().enumerate() {
            match i % 53 {
                0 => ray.t_min = -1.0,
                1 => ray.direction = Vec3::ZERO,
                _ => {}
            }
        }
        eights.extend(
            random
                .chunks_exact(8)
                .map(|c| std::array::from_fn(|i| c[i])),
        );
        for _ in 0..400 {
            let eye = rng.point(-1.5 * extent, 1.5 * extent) + vec3(0.0, 0.0, 2.0 * extent);
            let target = rng.point(-extent, extent);
            let snap = rng.unit() < 0.5;
            eights.push(std::array::from_fn(|i| {
                let origin = eye + vec3(0.05 * (i % 4) as f32, 0.05 * (i / 4) as f32, 0.0);
                let mut aim = target + rng.point(-0.02 * extent, 0.02 * extent);
                if snap {
                    // Grid vertices and edge midpoints.
                    aim = (aim * 2.0).round() * 0.5;
                }
                Ray::new(origin, (aim - origin).normalize(), 0.0, f32::INFINITY)
            }));
        }
        for rays in &eights {
            let mut expected = [None; 8];
            for (ray, hit) in rays.iter().zip(&mut expected) {
                scene.intersect_into(ray, hit);
                compared += usize::from(hit.is_some());
            }
            for (k, hybrid) in [0, 1, 3, 8].into_iter().enumerate() {
                let path = wide_paths[k % wide_paths.len()];
                let mut hits = [None; 8];
                // Selected at every call: other tests switch the path for a while.
                isa::select(path);
                scene.intersect8_with(rays, &mut hits, hybrid);
                assert_eq!(
                    hits, expected,
                    "scene {index}, rays {rays:?}, hybrid {hybrid}"
                );
                // (A counting build walks every ray alone.)
                if walked_together && !crate::accel::counters::ENABLED {
                    // Twelve entries overflow at the root's first inner child (unless every
                    // lane walks alone from the root, `hybrid` 8).
                    let mut hits = [None; 8];
                    isa::select(path);
                    scene.intersect8_with_stack::<12>(rays, &mut hits, hybrid);
                    assert_eq!(
                        hits, expected,
                        "scene {index}, rays {rays:?}, hybrid {hybrid}, small stack"
                    );
                    // Five entries: a top level's walk overflows at the first node with more
                    // than four children hit (and every placement's walk at its root).
                    let mut hits = [None; 8];
                    isa::select(isa::Isa::Avx2);
                    scene.intersect8_with_stack::<5>(rays, &mut hits, hybrid);
                    assert_eq!(
                        hits, expected,
                        "scene {index}, rays {rays:?}, hybrid {hybrid}, tiny stack"
                    );
                }
            }
        }
    }
    isa::select(isa::Isa::from_environment());
    assert!(compared > 5_000, "only {compared} hits compared");
}
