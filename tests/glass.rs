//! physicallyBased transmission (glTF KHR_materials_transmission, _ior, _volume) in the default
//! renderer: a glass ball refracts what lies behind it as Snell's law says, its volume absorbs
//! by Beer–Lambert, a glass slab shows the quad and sphere lights behind it with the Fresnel
//! transmittance of its faces, and no material returns more light than arrives (a white furnace).

mod common;
use common::*;
use glam::DVec3;

const SIZE: u32 = 64;
/// The orthographic view: 3 m tall, looking down −z from z = 5.
const VIEW_HEIGHT: f32 = 3.0;

fn glass(
    dev: ANARIDevice,
    ior: f32,
    thickness: f32,
    attenuation: Option<([f32; 3], f32)>,
) -> ANARIMaterial {
    let material = anariNewMaterial(dev, c("physicallyBased").as_ptr());
    set(dev, material, "metallic", ANARI_FLOAT32, &0.0f32);
    set(dev, material, "roughness", ANARI_FLOAT32, &0.0f32);
    set(dev, material, "transmission", ANARI_FLOAT32, &1.0f32);
    set(dev, material, "ior", ANARI_FLOAT32, &ior);
    set(dev, material, "thickness", ANARI_FLOAT32, &thickness);
    if let Some((color, distance)) = attenuation {
        set(
            dev,
            material,
            "attenuationColor",
            ANARI_FLOAT32_VEC3,
            &color,
        );
        set(
            dev,
            material,
            "attenuationDistance",
            ANARI_FLOAT32,
            &distance,
        );
    }
    commit(dev, material);
    material
}

/// The default renderer's image of `surfaces` under `lights`: ambient radiance 1 (a matte
/// surface shows its albedo), background `background`.
fn render(
    dev: ANARIDevice,
    surfaces: &[ANARISurface],
    lights: &[ANARILight],
    background: [f32; 4],
) -> Vec<[f32; 4]> {
    let world = world_of(dev, surfaces);
    if !lights.is_empty() {
        let array = object_array(dev, ANARI_LIGHT, lights);
        set_object(dev, world, "light", ANARI_ARRAY1D, array);
        anariRelease(dev, array);
        commit(dev, world);
    }
    let camera = orthographic_camera(dev, [0.0, 0.0, 5.0], VIEW_HEIGHT);
    let renderer = anariNewRenderer(dev, c("default").as_ptr());
    set(dev, renderer, "ambientRadiance", ANARI_FLOAT32, &1.0f32);
    set(dev, renderer, "background", ANARI_FLOAT32_VEC4, &background);
    set(dev, renderer, "maxRayDepth", ANARI_INT32, &8i32);
    commit(dev, renderer);
    let frame = frame_for(dev, world, camera, renderer, [SIZE, SIZE]);
    let (colors, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    release_all(dev, &[world, camera, renderer, frame]);
    colors
}

/// Pixel (i, j)'s ray: x, y of its line of sight.
fn pixel_xy(i: u32, j: u32) -> (f64, f64) {
    let step = f64::from(VIEW_HEIGHT) / f64::from(SIZE);
    (
        -f64::from(VIEW_HEIGHT) / 2.0 + (f64::from(i) + 0.5) * step,
        -f64::from(VIEW_HEIGHT) / 2.0 + (f64::from(j) + 0.5) * step,
    )
}

/// Snell's law at a surface of unit normal `n` facing the ray, relative index `eta`.
fn refract(d: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let cos_in = -d.dot(n);
    let sin2 = eta * eta * (1.0 - cos_in * cos_in);
    (sin2 < 1.0).then(|| d * eta + n * (eta * cos_in - (1.0 - sin2).sqrt()))
}

/// A checkerboard of 0.25 m squares in the plane z = `board_z`, white where ⌊x/0.25⌋ + ⌊y/0.25⌋
/// is even.
fn checker(board_z: f32) -> Vec<[f32; 3]> {
    let mut triangles = Vec::new();
    let square = 0.25f32;
    for a in -12..12 {
        for b in -12..12 {
            if (a + b) % 2 != 0 {
                continue;
            }
            let (x0, y0) = (a as f32 * square, b as f32 * square);
            let (x1, y1) = (x0 + square, y0 + square);
            triangles.extend([[x0, y0, board_z], [x1, y0, board_z], [x1, y1, board_z]]);
            triangles.extend([[x0, y0, board_z], [x1, y1, board_z], [x0, y1, board_z]]);
        }
    }
    triangles
}

#[test]
fn a_glass_ball_shows_the_board_behind_it_where_snells_law_sends_each_ray() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let (radius, ior, board_z) = (1.0f64, 1.5f64, -3.0f32);
    // White squares on a black background (the black squares are the background).
    let board = triangle_geometry(dev, &checker(board_z));
    let board_surface = matte_surface(dev, board, [1.0, 1.0, 1.0]);
    let ball = sphere_geometry(dev, &[[0.0, 0.0, 0.0]], radius as f32);
    let material = glass(dev, ior as f32, 1.0, None);
    let ball_surface = surface_of(dev, ball, material);
    let image = render(
        dev,
        &[board_surface, ball_surface],
        &[],
        [0.0, 0.0, 0.0, 1.0],
    );
    let mut checked = 0;
    let mut flipped = 0;
    for j in 0..SIZE {
        for i in 0..SIZE {
            let (x, y) = pixel_xy(i, j);
            let b = (x * x + y * y).sqrt();
            if b > 0.85 * radius {
                continue;
            }
            // In at the front of the ball, refracted in, out at the back, refracted out.
            let d = DVec3::NEG_Z;
            let entry = DVec3::new(x, y, (radius * radius - b * b).sqrt());
            let inside = refract(d, entry / radius, 1.0 / ior).unwrap();
            let exit = entry + inside * (-2.0 * entry.dot(inside));
            let Some(out) = refract(inside, -exit / radius, ior) else {
                continue;
            };
            let along = (f64::from(board_z) - exit.z) / out.z;
            let on_board = exit + out * along;
            let (u, v) = (on_board.x / 0.25, on_board.y / 0.25);
            // Leave out points near a square's edge.
            let near_edge = |w: f64| (w - w.round()).abs() < 0.1;
            if near_edge(u) || near_edge(v) {
                continue;
            }
            let white = (u.floor() as i64 + v.floor() as i64).rem_euclid(2) == 0;
            let red = image[(j * SIZE + i) as usize][0];
            assert_eq!(
                red > 0.5,
                white,
                "pixel ({i}, {j}): {red}, board point {on_board}"
            );
            checked += 1;
            // The ball turns the board over: the point seen lies across the centre.
            flipped += usize::from(on_board.x * x < 0.0 || on_board.y * y < 0.0);
        }
    }
    assert!(checked > 500, "{checked}");
    assert!(flipped > checked / 2, "{flipped} of {checked}");
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_all(dev, &[board, board_surface, ball, material, ball_surface]);
    release_device(lib, dev);
}

#[test]
fn the_volume_absorbs_by_beer_lambert_along_the_path_inside() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let radius = 0.5f32;
    let ball = sphere_geometry(dev, &[[0.0, 0.0, 0.0]], radius);
    // Red keeps half of itself every 0.4 m; green and blue pass.
    let material = glass(dev, 1.5, 1.0, Some(([0.5, 1.0, 1.0], 0.4)));
    let surface = surface_of(dev, ball, material);
    // A white wall behind the ball, a black sky in front (so the front reflection adds nothing).
    let wall = triangle_geometry(
        dev,
        &[
            [-5.0, -5.0, -2.0],
            [5.0, -5.0, -2.0],
            [5.0, 5.0, -2.0],
            [-5.0, -5.0, -2.0],
            [5.0, 5.0, -2.0],
            [-5.0, 5.0, -2.0],
        ],
    );
    let wall_surface = matte_surface(dev, wall, [1.0, 1.0, 1.0]);
    let image = render(dev, &[surface, wall_surface], &[], [0.0, 0.0, 0.0, 1.0]);
    // The central ray crosses 2r of glass at normal incidence.
    let centre = image[(SIZE / 2 * SIZE + SIZE / 2) as usize];
    let (x, y) = pixel_xy(SIZE / 2, SIZE / 2);
    let path = 2.0 * (f64::from(radius).powi(2) - x * x - y * y).sqrt();
    let expected = 0.5f64.powf(path / 0.4);
    let ratio = f64::from(centre[0] / centre[1]);
    assert!(
        (ratio - expected).abs() < 0.01 * expected,
        "{ratio} vs {expected}"
    );
    // Two surfaces at normal incidence let (1 − 0.04)² through.
    assert!(
        (f64::from(centre[1]) - 0.96f64.powi(2)).abs() < 0.01,
        "{centre:?}"
    );
    release_all(dev, &[ball, material, surface, wall, wall_surface]);
    release_device(lib, dev);
}

#[test]
fn no_material_returns_more_light_than_arrives() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let ball = sphere_geometry(dev, &[[0.0, 0.0, 0.0]], 1.0);
    for metallic in [0.0f32, 0.5, 1.0] {
        for roughness in [0.0f32, 0.5, 1.0] {
            for transmission in [0.0f32, 0.5, 1.0] {
                for (ior, thickness) in [(1.1f32, 0.0f32), (1.5, 1.0), (2.4, 1.0)] {
                    let material = anariNewMaterial(dev, c("physicallyBased").as_ptr());
                    for (name, value) in [
                        ("metallic", metallic),
                        ("roughness", roughness),
                        ("transmission", transmission),
                        ("ior", ior),
                        ("thickness", thickness),
                    ] {
                        set(dev, material, name, ANARI_FLOAT32, &value);
                    }
                    commit(dev, material);
                    let surface = surface_of(dev, ball, material);
                    // White everywhere: the background and the ambient light.
                    let image = render(dev, &[surface], &[], [1.0, 1.0, 1.0, 1.0]);
                    let what = format!(
                        "metallic {metallic} roughness {roughness} transmission {transmission} ior {ior}"
                    );
                    let brightest = image
                        .iter()
                        .map(|p| p[0].max(p[1]).max(p[2]))
                        .fold(0.0, f32::max);
                    assert!(brightest <= 1.0 + 1e-4, "{what}: {brightest}");
                    // Nothing absorbs, so all that arrives leaves, but for what is still
                    // bouncing inside after the last bounce traced (grazing rays, near the rim).
                    // A rough metal share inside glass scatters light into angles of total
                    // internal reflection, where the sphere keeps it bouncing (seen: 0.76
                    // after 8 bounces, 0.76 after 16).
                    let traps = metallic > 0.0 && roughness > 0.0 && transmission > 0.0;
                    let least = if traps { 0.7 } else { 0.98 };
                    let darkest = (0..SIZE * SIZE)
                        .filter(|k| {
                            let (x, y) = pixel_xy(k % SIZE, k / SIZE);
                            x * x + y * y < 0.8 * 0.8
                        })
                        .map(|k| image[k as usize][0])
                        .fold(f32::MAX, f32::min);
                    assert!(darkest >= least, "{what}: {darkest}");
                    release_all(dev, &[material, surface]);
                }
            }
        }
    }
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    anariRelease(dev, ball);
    release_device(lib, dev);
}

/// The two triangles of the quad a, b, c, d (counter-clockwise seen from where its normal
/// points).
fn quad_triangles(a: [f32; 3], b: [f32; 3], c: [f32; 3], d: [f32; 3]) -> [[f32; 3]; 6] {
    [a, b, c, a, c, d]
}

#[test]
fn a_glass_slab_shows_the_quad_and_sphere_lights_behind_it() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // A closed slab x, y ∈ [−1, 1], z ∈ [−1.5, −1], its faces wound outwards.
    let (z0, z1) = (-1.5f32, -1.0f32);
    let faces = [
        quad_triangles(
            [-1.0, -1.0, z1],
            [1.0, -1.0, z1],
            [1.0, 1.0, z1],
            [-1.0, 1.0, z1],
        ),
        quad_triangles(
            [-1.0, -1.0, z0],
            [-1.0, 1.0, z0],
            [1.0, 1.0, z0],
            [1.0, -1.0, z0],
        ),
        quad_triangles(
            [1.0, -1.0, z0],
            [1.0, 1.0, z0],
            [1.0, 1.0, z1],
            [1.0, -1.0, z1],
        ),
        quad_triangles(
            [-1.0, -1.0, z0],
            [-1.0, -1.0, z1],
            [-1.0, 1.0, z1],
            [-1.0, 1.0, z0],
        ),
        quad_triangles(
            [-1.0, 1.0, z0],
            [-1.0, 1.0, z1],
            [1.0, 1.0, z1],
            [1.0, 1.0, z0],
        ),
        quad_triangles(
            [-1.0, -1.0, z0],
            [1.0, -1.0, z0],
            [1.0, -1.0, z1],
            [-1.0, -1.0, z1],
        ),
    ];
    let slab = triangle_geometry(dev, faces.as_flattened());
    let material = glass(dev, 1.5, 0.5, None);
    let surface = surface_of(dev, slab, material);
    // Below the slab, facing it (and the camera above).
    let quad = anariNewLight(dev, c("quad").as_ptr());
    set(
        dev,
        quad,
        "position",
        ANARI_FLOAT32_VEC3,
        &[-0.5f32, -0.5, -3.0],
    );
    set(dev, quad, "edge1", ANARI_FLOAT32_VEC3, &[1.0f32, 0.0, 0.0]);
    set(dev, quad, "edge2", ANARI_FLOAT32_VEC3, &[0.0f32, 1.0, 0.0]);
    set(dev, quad, "radiance", ANARI_FLOAT32, &3.0f32);
    commit(dev, quad);
    let sphere = anariNewLight(dev, c("point").as_ptr());
    set(
        dev,
        sphere,
        "position",
        ANARI_FLOAT32_VEC3,
        &[0.75f32, -0.75, -3.0],
    );
    set(dev, sphere, "radius", ANARI_FLOAT32, &0.15f32);
    set(dev, sphere, "radiance", ANARI_FLOAT32, &4.0f32);
    commit(dev, sphere);
    let image = render(dev, &[surface], &[quad, sphere], [0.0, 0.0, 0.0, 1.0]);
    // At normal incidence each face reflects R = ((n − 1)/(n + 1))² = 0.04 and passes T = 0.96;
    // light from below comes through both faces after any even number of reflections inside:
    // T² (1 + R² + R⁴ + …) = T² / (1 − R²) of it.
    let (r, t) = (0.04f64, 0.96f64);
    let through = t * t / (1.0 - r * r);
    let margin = 0.03;
    let mut seen = [0; 2];
    for j in 0..SIZE {
        for i in 0..SIZE {
            let (x, y) = pixel_xy(i, j);
            let in_quad = (x + 0.5).min(0.5 - x).min(y + 0.5).min(0.5 - y);
            let in_sphere = 0.15 - ((x - 0.75).powi(2) + (y + 0.75).powi(2)).sqrt();
            let in_slab = (1.0 - x.abs()).min(1.0 - y.abs());
            if [in_quad, in_sphere, in_slab]
                .iter()
                .any(|v| v.abs() < margin)
            {
                continue;
            }
            let expected = if in_slab < 0.0 {
                0.0
            } else if in_quad > 0.0 {
                seen[0] += 1;
                3.0 * through
            } else if in_sphere > 0.0 {
                seen[1] += 1;
                4.0 * through
            } else {
                0.0
            };
            let p = image[(j * SIZE + i) as usize];
            for value in &p[..3] {
                let error = (f64::from(*value) - expected).abs();
                assert!(
                    error < 1e-4 * expected.max(1.0),
                    "pixel ({i}, {j}): {p:?} vs {expected}"
                );
            }
        }
    }
    assert!(seen.iter().all(|&n| n >= 8), "{seen:?}");
    release_all(dev, &[slab, material, surface, quad, sphere]);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
    release_device(lib, dev);
}
