//! Isosurfaces against closed forms.

use super::*;
use crate::scene::spatial_field::StructuredRegularField;
use crate::scene::unstructured_field::{UnstructuredField, from_cells};

const H: f32 = 0.1;
const HALF_WIDTH: f32 = 1.5;

/// f = |x|² on a grid of spacing H over [−1.5, 1.5]³.
fn radial_field() -> Field {
    let n = (2.0 * HALF_WIDTH / H).round() as usize + 1;
    let mut values = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = Vec3::new(i as f32, j as f32, k as f32) * H - HALF_WIDTH;
                values.push(p.length_squared());
            }
        }
    }
    let field = StructuredRegularField::from_floats(
        [n; 3],
        values,
        Vec3::splat(-HALF_WIDTH),
        Vec3::splat(H),
        false,
    )
    .unwrap();
    Field::Structured(Arc::new(field))
}

fn down(x: f32, y: f32, t_min: f32) -> Ray {
    Ray::new(Vec3::new(x, y, 5.0), Vec3::NEG_Z, t_min, f32::INFINITY)
}

/// The trilinear interpolant of |x|² on the grid equals, per axis, u² + (u − a)(a + H − u) in
/// the cell [a, a + H]: at a cell centre that is u² + H²/4, and along z it is linear in each
/// cell. The first crossing of the interpolant with `iso` going down z from the top, and the
/// interpolant's gradient there.
fn interpolant_crossing(x: f64, y: f64, iso: f64) -> (f64, DVec3) {
    let h = H as f64;
    let lateral = x * x + y * y + h * h / 2.0;
    let cells = (2.0 * HALF_WIDTH as f64 / h).round() as i32;
    for cell in (0..cells).rev() {
        let a = -HALF_WIDTH as f64 + cell as f64 * h;
        // lateral + z (2a + H) − a (a + H) = iso
        let z = (iso - lateral + a * (a + h)) / (2.0 * a + h);
        if (a..=a + h).contains(&z) {
            return (z, DVec3::new(2.0 * x, 2.0 * y, 2.0 * a + h));
        }
    }
    panic!("no crossing at ({x}, {y})");
}

/// Cell centres (x, y) inside the sphere of radius 0.97, |x|, |y| up to 0.55.
fn centre_rays() -> Vec<(f32, f32)> {
    let mut rays = Vec::new();
    for i in -6..=5 {
        for j in [-6, -3, 0, 2, 5] {
            rays.push(((i as f32 + 0.5) * H, (j as f32 + 0.5) * H));
        }
    }
    rays
}

#[test]
fn a_radial_field_gives_the_sphere_of_its_interpolant() {
    let radius = 0.97f32;
    let (bvh, ids) = build(radial_field(), vec![radius * radius]);
    assert!(ids.iter().all(|&id| id == 0));
    for (x, y) in centre_rays() {
        let hit = bvh
            .intersect(&down(x, y, 0.0))
            .expect("the ray crosses the sphere");
        let (z, gradient) = interpolant_crossing(x as f64, y as f64, (radius * radius) as f64);
        // The interpolant's own crossing: only f32 rounding of the stored values and of t.
        assert!(
            (hit.t as f64 - (5.0 - z)).abs() < 2e-5,
            "({x}, {y}): {} vs {}",
            hit.t,
            5.0 - z
        );
        let expected = gradient.normalize().as_vec3();
        assert!(
            (hit.normal - expected).length() < 1e-5,
            "{} vs {expected}",
            hit.normal
        );
        // The true sphere: the interpolant exceeds |x|² by e ∈ [H²/2, 3H²/4] here, so its
        // crossing lies below the sphere's by e / (z_sphere + z) ≤ 3H²/4 / (2z); its gradient
        // differs only along z, by at most H, against a true gradient of length 2R.
        let sphere_z = (radius * radius - x * x - y * y).sqrt() as f64;
        let depth_bound = 0.75 * (H * H) as f64 / (2.0 * z);
        assert!(
            sphere_z - z > 0.0 && sphere_z - z <= depth_bound,
            "{sphere_z} {z}"
        );
        let radial = Vec3::new(x, y, z as f32).normalize();
        let angle = hit.normal.dot(radial).clamp(-1.0, 1.0).acos();
        assert!(angle <= (H / (2.0 * radius - H)).atan(), "angle {angle}");
    }
    // Beside the sphere: no hit.
    assert!(bvh.intersect(&down(1.05, 0.05, 0.0)).is_none());
}

#[test]
fn several_isovalues_give_nested_shells_with_their_index_as_primitive_id() {
    let (outer, inner) = (0.9f32, 0.45f32);
    let (bvh, ids) = build(radial_field(), vec![inner * inner, outer * outer]);
    let (x, y) = (0.05, 0.15);
    let mut t_min = 0.0;
    let mut seen = Vec::new();
    while let Some(hit) = bvh.intersect(&down(x, y, t_min)) {
        seen.push((ids[hit.primitive as usize], hit.t, hit.normal.z));
        t_min = hit.t + 1e-4;
    }
    let order: Vec<u32> = seen.iter().map(|s| s.0).collect();
    assert_eq!(order, [1, 0, 0, 1], "{seen:?}");
    // Depths: the interpolant's crossings of each shell, top and (by symmetry) bottom.
    for (k, (iso, top)) in [(outer, true), (inner, true), (inner, false), (outer, false)]
        .iter()
        .enumerate()
    {
        let (z, _) = interpolant_crossing(x as f64, y as f64, (iso * iso) as f64);
        let expected = if *top { 5.0 - z } else { 5.0 + z };
        assert!(
            (seen[k].1 as f64 - expected).abs() < 2e-5,
            "{k}: {seen:?} {expected}"
        );
        // Normals point to higher values: outwards.
        assert_eq!(seen[k].2 > 0.0, *top, "{seen:?}");
    }
}

/// The unit cube as 8 VTK-ordered points moved by `warp` applied to the point.
fn cube_points(origin: Vec3, size: f32) -> Vec<Vec3> {
    [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
    ]
    .iter()
    .map(|c| origin + Vec3::from_array(*c) * size)
    .collect()
}

fn unstructured(field: UnstructuredField) -> Field {
    Field::Unstructured(Arc::new(field))
}

#[test]
fn linear_fields_give_planes_in_every_cell_shape() {
    // f = 0.1x − 0.2y + z: every shape function set reproduces it, so the isosurface f = 0.6
    // is a plane in tetrahedra (closed-form root), parallelepiped and warped hexahedra (cubic
    // and sampled roots), wedges and pyramids (sampled roots).
    let gradient = Vec3::new(0.1, -0.2, 1.0);
    let iso = 0.6f32;
    let mut points = cube_points(Vec3::ZERO, 1.0);
    let warped = {
        let mut p = cube_points(Vec3::new(2.0, 0.0, 0.0), 1.0);
        // Only the top face, above the plane, stops being planar.
        p[6] += Vec3::new(0.0, 0.0, 0.2);
        p
    };
    points.extend(&warped);
    points.push(Vec3::new(4.5, 0.5, 0.5)); // 16: pyramid apex
    let cube = |offset: u32| (offset..offset + 8).collect::<Vec<u32>>();
    let mut indices = Vec::new();
    let mut types = Vec::new();
    // Tetrahedron and wedge halves of the first cube are tested on separate fields below.
    indices.extend(cube(8));
    types.push(12u8);
    // Pyramid on the warped cube's face x = 3 (vertices 9, 10, 14, 13 in VTK order 1, 2, 6, 5).
    indices.extend([9, 13, 14, 10, 16]);
    types.push(14);
    let values: Vec<f32> = points.iter().map(|p| p.dot(gradient)).collect();
    let shapes = [
        from_cells(points.clone(), cube(0), &[12], values.clone(), false).unwrap(),
        from_cells(
            points.clone(),
            vec![0, 1, 3, 4],
            &[10],
            values.clone(),
            false,
        )
        .unwrap(),
        from_cells(
            points.clone(),
            vec![0, 1, 3, 4, 5, 7],
            &[13],
            values.clone(),
            false,
        )
        .unwrap(),
        from_cells(points.clone(), indices, &types, values.clone(), false).unwrap(),
    ];
    for (case, field) in shapes.into_iter().enumerate() {
        let field = unstructured(field);
        let (bvh, _) = build(field.clone(), vec![iso]);
        let mut hits = 0;
        for x in [0.1f32, 0.3, 0.45, 2.2, 2.6, 2.9, 3.1, 3.3] {
            for y in [0.1f32, 0.2, 0.4, 0.7] {
                let ray = Ray::new(Vec3::new(x, y, 5.0), Vec3::NEG_Z, 0.0, f32::INFINITY);
                let z = iso - 0.1 * x + 0.2 * y;
                let inside = !field.sample(Vec3::new(x, y, z)).is_nan();
                match bvh.intersect(&ray) {
                    Some(hit) => {
                        assert!(inside, "case {case}: hit at ({x}, {y}) outside the cells");
                        assert!(
                            (hit.t - (5.0 - z)).abs() < 2e-5,
                            "case {case}: {} vs {}",
                            hit.t,
                            5.0 - z
                        );
                        assert!(
                            (hit.normal - gradient.normalize()).length() < 1e-5,
                            "case {case}"
                        );
                        hits += 1;
                    }
                    None => assert!(!inside, "case {case}: missed ({x}, {y}, {z})"),
                }
            }
        }
        assert!(hits >= 2, "case {case}: only {hits} hits");
    }
}

#[test]
fn a_hexahedron_mesh_matches_the_grid_it_was_made_from() {
    // The grid's cells as hexahedra: the same trilinear interpolants, the same hits.
    let Field::Structured(grid) = radial_field() else {
        unreachable!()
    };
    let [n, _, _] = grid.dims();
    let (origin, spacing) = grid.grid();
    let vertex = |i: usize, j: usize, k: usize| (i + n * (j + n * k)) as u32;
    let mut positions = Vec::new();
    let mut values = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                positions.push(origin + Vec3::new(i as f32, j as f32, k as f32) * spacing);
                values.push(grid.vertex_value([i, j, k]));
            }
        }
    }
    let mut indices = Vec::new();
    for k in 0..n - 1 {
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                indices.extend([
                    vertex(i, j, k),
                    vertex(i + 1, j, k),
                    vertex(i + 1, j + 1, k),
                    vertex(i, j + 1, k),
                    vertex(i, j, k + 1),
                    vertex(i + 1, j, k + 1),
                    vertex(i + 1, j + 1, k + 1),
                    vertex(i, j + 1, k + 1),
                ]);
            }
        }
    }
    let types = vec![12u8; (n - 1).pow(3)];
    let mesh = unstructured(from_cells(positions, indices, &types, values, false).unwrap());
    let iso = vec![0.81f32];
    let (grid_bvh, _) = build(Field::Structured(grid), iso.clone());
    let (mesh_bvh, _) = build(mesh, iso);
    for (x, y) in centre_rays() {
        let a = grid_bvh.intersect(&down(x, y, 0.0)).unwrap();
        let b = mesh_bvh.intersect(&down(x, y, 0.0)).unwrap();
        assert!(
            (a.t - b.t).abs() < 1e-5 && (a.normal - b.normal).length() < 1e-5,
            "{a:?} {b:?}"
        );
    }
}

#[test]
fn constant_cells_and_values_out_of_range_add_no_primitive() {
    let field = unstructured(
        from_cells(
            cube_points(Vec3::ZERO, 1.0),
            (0..8).collect(),
            &[12],
            vec![1.0; 8],
            false,
        )
        .unwrap(),
    );
    assert!(straddling_cells(&field, &[1.0]).is_empty());
    let (bvh, _) = build(radial_field(), vec![100.0]);
    assert_eq!(bvh.primitive_count(), 0);
}

/// First root of `f − iso` along `origin + t direction` for t in [0, 10], by dense sampling and
/// bisection of the closed form (independent of the cubic).
fn reference_root(f: impl Fn(DVec3) -> f64, origin: DVec3, direction: DVec3) -> Option<f64> {
    let g = |t: f64| f(origin + direction * t);
    let samples = 200_000;
    let mut previous = g(0.0);
    for k in 1..=samples {
        let t = 10.0 * k as f64 / samples as f64;
        let value = g(t);
        if (previous < 0.0) != (value < 0.0) {
            return Some(bisect(g, t - 10.0 / samples as f64, t));
        }
        previous = value;
    }
    None
}

#[test]
fn cross_terms_follow_the_cubic_along_the_ray() {
    // One cell [−1, 1]³ holding the corner values of xyz: its trilinear interpolant is xyz.
    let values = (0..8)
        .map(|b| {
            [b & 1, (b >> 1) & 1, b >> 2]
                .iter()
                .map(|&s| if s == 1 { 1.0 } else { -1.0 })
                .product()
        })
        .collect();
    let field = StructuredRegularField::from_floats(
        [2; 3],
        values,
        Vec3::splat(-1.0),
        Vec3::splat(2.0),
        false,
    )
    .unwrap();
    let iso = 0.02f32;
    let (bvh, _) = build(Field::Structured(Arc::new(field)), vec![iso]);
    let f = |p: DVec3| p.x * p.y * p.z - iso as f64;
    let mut hits = 0;
    for (origin, direction) in [
        (Vec3::new(-2.0, -2.0, -2.0), Vec3::new(1.0, 1.0, 1.0)),
        (Vec3::new(-2.0, -1.9, -2.1), Vec3::new(1.0, 1.0, 1.0)),
        (Vec3::new(0.5, 0.6, 3.0), Vec3::new(0.0, 0.0, -1.0)),
        (Vec3::new(-1.5, 0.9, 0.3), Vec3::new(1.0, -0.4, 0.2)),
        (Vec3::new(1.8, -0.2, -1.7), Vec3::new(-1.0, 0.3, 0.9)),
        (Vec3::new(0.2, 2.0, 0.7), Vec3::new(0.1, -1.0, -0.35)),
    ] {
        let direction = direction.normalize();
        let ray = Ray::new(origin, direction, 0.0, f32::INFINITY);
        let expected = reference_root(f, origin.as_dvec3(), direction.as_dvec3()).filter(|&t| {
            (origin.as_dvec3() + direction.as_dvec3() * t)
                .abs()
                .max_element()
                <= 1.0
        });
        match (bvh.intersect(&ray), expected) {
            (Some(hit), Some(t)) => {
                assert!(
                    (hit.t as f64 - t).abs() < 1e-5,
                    "{origin}: {} vs {t}",
                    hit.t
                );
                let p = origin.as_dvec3() + direction.as_dvec3() * t;
                let normal = DVec3::new(p.y * p.z, p.x * p.z, p.x * p.y)
                    .normalize()
                    .as_vec3();
                assert!(
                    (hit.normal - normal).length() < 1e-4,
                    "{} vs {normal}",
                    hit.normal
                );
                hits += 1;
            }
            (None, None) => {}
            (hit, expected) => panic!("{origin}: {hit:?} vs {expected:?}"),
        }
    }
    assert!(hits >= 4, "{hits}");
}
