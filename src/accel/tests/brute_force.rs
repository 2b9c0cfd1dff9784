//! Random primitives and rays: every BVH answer against the brute-force one.

use super::*;

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
