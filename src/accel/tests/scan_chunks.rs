//! Meshes whose neighbour runs straddle a scan chunk of the build, with skipped primitives.

use super::*;

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
