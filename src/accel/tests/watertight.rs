//! Watertightness of closed meshes: rays through shared edges and vertices never leak.

use super::*;

/// An icosphere of radius 1 (the icosahedron's faces split four-fold `levels` times), with
/// vertices shared between faces.
fn icosphere(levels: u32) -> (Vec<Vec3>, Vec<UVec3>) {
    let g = (1.0 + 5f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        (-1.0, g, 0.0),
        (1.0, g, 0.0),
        (-1.0, -g, 0.0),
        (1.0, -g, 0.0),
        (0.0, -1.0, g),
        (0.0, 1.0, g),
        (0.0, -1.0, -g),
        (0.0, 1.0, -g),
        (g, 0.0, -1.0),
        (g, 0.0, 1.0),
        (-g, 0.0, -1.0),
        (-g, 0.0, 1.0),
    ]
    .map(|(x, y, z)| vec3(x, y, z).normalize())
    .to_vec();
    let mut faces: Vec<UVec3> = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ]
    .map(UVec3::from_array)
    .to_vec();
    for _ in 0..levels {
        let mut midpoints = std::collections::HashMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let p = (positions[a as usize] + positions[b as usize]).normalize();
                positions.push(p);
                positions.len() as u32 - 1
            })
        };
        let mut next = Vec::new();
        for face in &faces {
            let [a, b, c] = face.to_array();
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            next.extend(
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]].map(UVec3::from_array),
            );
        }
        faces = next;
    }
    (positions, faces)
}

/// A cube over [-1, 1]³ of `n`×`n` quads per face, vertices shared along its edges; every
/// coordinate is a multiple of 2 / n, so the midpoint of any edge is exact.
fn cube_of_quads(n: u32) -> (Vec<Vec3>, Vec<UVec4>) {
    let mut positions = Vec::new();
    let mut index = std::collections::HashMap::new();
    let mut vertex = |p: [i32; 3], positions: &mut Vec<Vec3>| {
        *index.entry(p).or_insert_with(|| {
            let scale = 2.0 / n as f32;
            positions.push(Vec3::from_array(p.map(|c| c as f32 * scale - 1.0)));
            positions.len() as u32 - 1
        })
    };
    let n = n as i32;
    let mut quads = Vec::new();
    for axis in 0..3 {
        for side in [0, n] {
            for i in 0..n {
                for j in 0..n {
                    let corner = |di: i32, dj: i32| {
                        let mut p = [0; 3];
                        p[axis] = side;
                        p[(axis + 1) % 3] = i + di;
                        p[(axis + 2) % 3] = j + dj;
                        p
                    };
                    let corners = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                    let ids = corners.map(|c| vertex(c, &mut positions));
                    quads.push(UVec4::from_array(ids));
                }
            }
        }
    }
    (positions, quads)
}

/// Points on every vertex and (as exactly as floats allow) on every edge of the mesh.
fn vertices_and_edge_points(positions: &[Vec3], faces: &[Vec<u32>]) -> Vec<Vec3> {
    let mut points = positions.to_vec();
    for face in faces {
        for (k, &a) in face.iter().enumerate() {
            let b = face[(k + 1) % face.len()];
            let (pa, pb) = (positions[a as usize], positions[b as usize]);
            points.extend([0.5, 0.25, 0.125].map(|w| pa + (pb - pa) * w));
        }
        // The diagonal along which a quad is split.
        if face.len() == 4 {
            let (pa, pc) = (positions[face[0] as usize], positions[face[2] as usize]);
            points.push(pa + (pc - pa) * 0.5);
        }
    }
    points
}

/// Plain Möller–Trumbore in f32 (not watertight): shows that the rays below do probe the gaps
/// a non-watertight test leaves.
fn moller_trumbore(origin: Vec3, direction: Vec3, [v0, v1, v2]: [Vec3; 3]) -> bool {
    let (e1, e2) = (v1 - v0, v2 - v0);
    let p = direction.cross(e2);
    let determinant = e1.dot(p);
    if determinant == 0.0 {
        return false;
    }
    let inv = 1.0 / determinant;
    let s = origin - v0;
    let u = s.dot(p) * inv;
    let q = s.cross(e1);
    let v = direction.dot(q) * inv;
    u >= 0.0 && v >= 0.0 && u + v <= 1.0 && e2.dot(q) * inv > 0.0
}

#[test]
fn rays_through_shared_edges_and_vertices_of_closed_meshes_never_leak() {
    let (sphere_positions, sphere_faces) = icosphere(3);
    let (cube_positions, cube_quads) = cube_of_quads(6);
    let meshes = [
        (
            GeometryPrims::Triangles {
                positions: sphere_positions.clone(),
                indices: sphere_faces.clone(),
            },
            vertices_and_edge_points(
                &sphere_positions,
                &sphere_faces
                    .iter()
                    .map(|f| f.to_array().to_vec())
                    .collect::<Vec<_>>(),
            ),
            sphere_faces
                .iter()
                .map(|f| f.to_array().map(|i| sphere_positions[i as usize]))
                .collect::<Vec<_>>(),
        ),
        (
            GeometryPrims::Quads {
                positions: cube_positions.clone(),
                indices: cube_quads.clone(),
            },
            vertices_and_edge_points(
                &cube_positions,
                &cube_quads
                    .iter()
                    .map(|q| q.to_array().to_vec())
                    .collect::<Vec<_>>(),
            ),
            cube_quads
                .iter()
                .flat_map(|q| {
                    let [a, b, c, d] = q.to_array().map(|i| cube_positions[i as usize]);
                    [[a, b, c], [a, c, d]]
                })
                .collect::<Vec<_>>(),
        ),
    ];
    let mut rng = Rng::new(23);
    let mut naive_leaks = 0;
    for (prims, targets, triangles) in meshes {
        let geometry = Arc::new(GeometryBvh::build(prims));
        let scene = SceneBvh::build(vec![identity_instance(vec![geometry.clone()])]);
        // From the centre (the direction is the target itself, so the ray passes exactly
        // through it), from points inside, and from outside towards the target.
        let mut rays = Vec::new();
        for &target in &targets {
            rays.push(Ray::new(Vec3::ZERO, target, 0.0, f32::INFINITY));
            let inside = rng.point(-0.3, 0.3);
            rays.push(Ray::new(inside, target - inside, 0.0, f32::INFINITY));
            let outside = target * 3.0 + rng.point(-0.5, 0.5);
            rays.push(Ray::new(outside, target - outside, 0.0, f32::INFINITY));
        }
        // Packets form from rays sharing octant and dominant axis: group them so.
        let key = |ray: &Ray| {
            let d = ray.direction;
            let octant = (d.x < 0.0) as u32 * 4 + (d.y < 0.0) as u32 * 2 + (d.z < 0.0) as u32;
            let a = d.abs();
            let dominant = if a.x >= a.y && a.x >= a.z {
                0
            } else if a.y >= a.z {
                1
            } else {
                2
            };
            octant * 3 + dominant
        };
        rays.sort_by_key(key);
        let mut packet_hits = vec![None; rays.len()];
        scene.intersect_packet(&rays, &mut packet_hits);
        for (ray, packet_hit) in rays.iter().zip(&packet_hits) {
            let hit = geometry.intersect(ray);
            let t = hit.map(|hit| hit.t);
            assert!(t.is_some(), "{ray:?} leaked through the mesh");
            assert!(geometry.occluded(ray), "{ray:?} leaked for any-hit");
            assert_eq!(scene.intersect(ray).map(|hit| hit.t), t, "{ray:?}");
            assert_eq!(packet_hit.map(|hit| hit.t), t, "{ray:?} in a packet");
            let naive_hit = triangles
                .iter()
                .any(|&triangle| moller_trumbore(ray.origin, ray.direction, triangle));
            naive_leaks += usize::from(!naive_hit);
        }
    }
    assert!(
        naive_leaks > 0,
        "the rays should find the gaps of a non-watertight test"
    );
    eprintln!("Möller–Trumbore leaked {naive_leaks} of the rays");
}
