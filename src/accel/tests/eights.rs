//! The walk of eight rays together (`SceneBvh::intersect8`) against rays one by one.

use super::*;
use crate::accel::isa;

/// `SceneBvh::intersect8` against `intersect_into`, record by record, on random rays in eights
/// (mixed octants and intervals, a few with `t_min < 0` or no direction), on coherent eights
/// (eight origins centimetres apart looking at one spot, as light-field subpixels) and on eights
/// aimed at a grid's vertices and edges (ties between triangles, where only the same visiting
/// order gives the same record); on one untransformed placement, one transformed placement and
/// two placements (ray by ray); and with a stack too small for the walk of eights, so that its
/// rays fall back to the single-ray walk.
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
    let scenes = [
        (vec![identity_instance(vec![cloud.clone()])], 4.0f32, true),
        (vec![identity_instance(vec![grid.clone()])], 12.0, true),
        (vec![turned], 12.0, true),
        (vec![identity_instance(vec![cloud, grid])], 12.0, false),
    ];
    let mut compared = 0;
    for (instances, extent, walked_together) in scenes {
        let scene = SceneBvh::build(instances);
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
                assert_eq!(hits, expected, "rays {rays:?}, hybrid {hybrid}");
                // (A counting build walks every ray alone.)
                if walked_together && !crate::accel::counters::ENABLED {
                    // Twelve entries overflow at the root's first inner child (unless every
                    // lane walks alone from the root, `hybrid` 8).
                    let mut hits = [None; 8];
                    isa::select(path);
                    scene.intersect8_with_stack::<12>(rays, &mut hits, hybrid);
                    assert_eq!(
                        hits, expected,
                        "rays {rays:?}, hybrid {hybrid}, small stack"
                    );
                }
            }
        }
    }
    isa::select(isa::Isa::from_environment());
    assert!(compared > 5_000, "only {compared} hits compared");
}
