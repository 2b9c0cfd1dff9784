//! Internals: the box tests of every path against the scalar reference, the traversal ray, the
//! tree layout and its build, hits written in place.

use super::*;

#[test]
fn memory_stays_within_budget_for_a_grid() {
    let cells = 100u32;
    let positions = (0..=cells)
        .flat_map(|y| (0..=cells).map(move |x| vec3(x as f32, y as f32, ((x + y) as f32).sin())))
        .collect();
    let indices = grid_indices(cells);
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
            for path in isa::test_paths() {
                use crate::accel::walk::avx2::{child_hits_avx2, child_hits_avx512};
                // SAFETY: the CPU has the path (`test_paths`).
                paths.extend(unsafe {
                    match path {
                        isa::Isa::Avx512 => Some(child_hits_avx512(node, &box_ray, t_min, t_max)),
                        isa::Isa::Avx2 => Some(child_hits_avx2(node, &box_ray, t_min, t_max)),
                        isa::Isa::Baseline => None,
                    }
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

/// A few thousand random triangles and quads: eight inline stack entries overflow on most rays
/// through them.
fn small_stack_overflowing_trees(rng: &mut Rng) -> [GeometryBvh; 2] {
    [
        GeometryBvh::build(random_triangles(rng, 3000, 6.0, 1.5)),
        GeometryBvh::build(random_quads(rng, 1500, 6.0, 1.5)),
    ]
}

#[test]
fn single_ray_walks_restart_with_a_larger_stack_and_find_the_same_hits() {
    // Eight inline entries overflow on most rays through a few thousand triangles; the walks
    // then restart on the heap and must still give the answers of the inline-stack walk.
    let mut rng = Rng::new(23);
    let mut hits = 0;
    for geometry in &small_stack_overflowing_trees(&mut rng) {
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
fn the_walk_of_large_trees_finds_the_hits_of_the_walk_of_small_ones() {
    // The walk that pushes at every node with hits (trees of `LARGE_TREE_NODES` and more) run
    // on small trees: the same closest hits, ids and `t`, also when its stack restarts.
    let mut rng = Rng::new(29);
    let mut hits = 0;
    for geometry in &small_stack_overflowing_trees(&mut rng) {
        for test_ray in random_rays(&mut rng, 2000, 6.0) {
            let ray = traversal_ray(&test_ray);
            let expected = geometry.closest_slot_and_t(&ray);
            for found in geometry.walks_of_large_trees(&ray) {
                assert_eq!(found, expected, "{test_ray:?}");
            }
            hits += usize::from(expected.is_some());
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
            14967998750147224901,
            4464019723561333011,
            10097288123660644393,
            238843509357211337
        ]
    );
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
