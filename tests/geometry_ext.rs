//! Geometries cylinder, cone and curve (ANARI_KHR_GEOMETRY_CYLINDER, ANARI_KHR_GEOMETRY_CONE,
//! ANARI_KHR_GEOMETRY_CURVE): caps per end, silhouettes, depths, primitive ids and interpolated
//! colours read back from an orthographic view, and bad input reported by the status callback.
//!
//! Every scene is seen by an orthographic camera at z = 5 looking down −z over the square
//! [−1.5, 1.5]², so pixel (x, y) of the SIZE×SIZE frame is the ray from (px, py, 5) along −z
//! (see `pixel_point`) and its depth is 5 − z of the hit.
mod common;
use common::*;

const SIZE: u32 = 64;
const VIEW_HEIGHT: f32 = 3.0;
const EYE_Z: f32 = 5.0;
const MISS: u32 = u32::MAX;

/// World (x, y) of the ray through pixel (x, y).
fn pixel_point(x: u32, y: u32) -> (f32, f32) {
    let at = |i: u32| ((i as f32 + 0.5) / SIZE as f32 - 0.5) * VIEW_HEIGHT;
    (at(x), at(y))
}

/// Every pixel with its world (x, y) and frame index.
fn pixels() -> impl Iterator<Item = (usize, f32, f32)> {
    (0..SIZE).flat_map(|y| {
        (0..SIZE).map(move |x| {
            let (px, py) = pixel_point(x, y);
            ((y * SIZE + x) as usize, px, py)
        })
    })
}

struct Rendered {
    depth: Vec<f32>,
    ids: Vec<u32>,
    albedo: Vec<[f32; 3]>,
}

struct Scene {
    lib: ANARILibrary,
    dev: ANARIDevice,
}

impl Scene {
    fn new(log: &Log) -> Scene {
        let (lib, dev) = device_with_log(log);
        Scene { lib, dev }
    }

    /// A geometry of `subtype` with the given arrays and other parameters, committed.
    fn geometry(
        &self,
        subtype: &str,
        setup: impl FnOnce(ANARIDevice, ANARIGeometry),
    ) -> ANARIGeometry {
        let geometry = anariNewGeometry(self.dev, c(subtype).as_ptr());
        setup(self.dev, geometry);
        commit(self.dev, geometry);
        geometry
    }

    /// Renders `geometry` with a matte material coloured by the geometry's "color" attribute
    /// (white where it has none), then releases it.
    fn render(&self, geometry: ANARIGeometry) -> Rendered {
        let dev = self.dev;
        let material = matte_colored_by(dev, "color");
        let surface = surface_of(dev, geometry, material);
        let world = world_of(dev, &[surface]);
        let camera = orthographic_camera(dev, [0.0, 0.0, EYE_Z], VIEW_HEIGHT);
        let renderer = plain_renderer(dev, "default");
        let frame = frame_for(dev, world, camera, renderer, [SIZE, SIZE]);
        add_channel(dev, frame, "channel.albedo", ANARI_FLOAT32_VEC3);
        render_and_wait(dev, frame);
        let (depth, w, h) = read_channel::<f32>(dev, frame, "channel.depth");
        assert_eq!((w, h), (SIZE, SIZE));
        let (ids, _, _) = read_channel::<u32>(dev, frame, "channel.primitiveId");
        let (albedo, _, _) = read_channel::<[f32; 3]>(dev, frame, "channel.albedo");
        release_all(
            dev,
            &[geometry, material, surface, world, camera, renderer, frame],
        );
        Rendered { depth, ids, albedo }
    }
}

impl Drop for Scene {
    fn drop(&mut self) {
        release_device(self.lib, self.dev);
    }
}

/// End points of two upright segments along y, at x = −0.75 (vertices 0, 1) and x = 0.75
/// (vertices 2, 3), from y = −1 to 1.
const UPRIGHTS: [[f32; 3]; 4] = [
    [-0.75, -1.0, 0.0],
    [-0.75, 1.0, 0.0],
    [0.75, -1.0, 0.0],
    [0.75, 1.0, 0.0],
];

fn positions(dev: ANARIDevice, geometry: ANARIGeometry, points: &[[f32; 3]]) {
    set_array(dev, geometry, "vertex.position", ANARI_FLOAT32_VEC3, points);
}

/// Asserts the depth of a pixel, or that it is empty (`None`).
fn assert_hit(view: &Rendered, index: usize, expected: Option<(f32, u32)>, what: &str) {
    match expected {
        None => assert_eq!(view.ids[index], MISS, "{what}: should be empty"),
        Some((depth, id)) => {
            assert_eq!(view.ids[index], id, "{what}: primitive id");
            assert!(
                (view.depth[index] - depth).abs() < 1e-3,
                "{what}: depth {} instead of {depth}",
                view.depth[index]
            );
        }
    }
}

/// Pixels this close to an outline are not checked (either answer is right).
const EDGE: f32 = 0.02;

// ---- cylinder ----------------------------------------------------------------------------

/// A cylinder of radius 0.5 along z from (0, 0, −1) (first end) to (0, 0, 1) (second end, the
/// one facing the camera), with `caps` and optionally `vertex.cap`.
fn axis_cylinder(scene: &Scene, caps: &str, vertex_caps: Option<[u8; 2]>) -> Rendered {
    let geometry = scene.geometry("cylinder", |dev, g| {
        positions(dev, g, &[[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]]);
        set(dev, g, "radius", ANARI_FLOAT32, &0.5f32);
        set_string(dev, g, "caps", caps);
        if let Some(vertex_caps) = vertex_caps {
            set_array(dev, g, "vertex.cap", ANARI_UINT8, &vertex_caps);
        }
    });
    scene.render(geometry)
}

#[test]
fn cylinder_caps_close_each_end_as_asked_seen_down_the_axis() {
    let log = Log::new();
    let scene = Scene::new(&log);
    // Near end at z = 1 (depth 4), far end at z = −1 (depth 6); rays parallel to the axis
    // never meet the side, so an open bore shows the far cap or nothing.
    let cases = [
        ("none", None, None),
        ("first", None, Some(6.0)),
        ("second", None, Some(4.0)),
        ("both", None, Some(4.0)),
        // vertex.cap overrides caps.
        ("both", Some([0, 0]), None),
        ("none", Some([1, 0]), Some(6.0)),
        ("none", Some([0, 1]), Some(4.0)),
        ("none", Some([1, 1]), Some(4.0)),
    ];
    for (caps, vertex_caps, depth) in cases {
        let view = axis_cylinder(&scene, caps, vertex_caps);
        let mut inside = 0;
        for (i, x, y) in pixels() {
            let r = x.hypot(y);
            let what = format!("caps {caps}, vertex.cap {vertex_caps:?}, pixel at ({x}, {y})");
            if r < 0.5 - EDGE {
                inside += 1;
                assert_hit(&view, i, depth.map(|d| (d, 0)), &what);
            } else if r > 0.5 + EDGE {
                assert_hit(&view, i, None, &what);
            }
        }
        assert!(inside > 300);
    }
    assert!(log.errors().is_empty());
}

#[test]
fn cylinder_sides_have_analytic_depth_and_indexed_primitive_ids() {
    let log = Log::new();
    let scene = Scene::new(&log);
    // Two cylinders of radius 0.25 along y, at x = −0.75 and x = 0.75; the second runs from
    // vertex 3 to vertex 2. Seen from +z their sides are bands of depth 5 − sqrt(r² − dx²).
    let geometry = scene.geometry("cylinder", |dev, g| {
        positions(dev, g, &UPRIGHTS);
        set_array(
            dev,
            g,
            "primitive.index",
            ANARI_UINT32_VEC2,
            &[[0u32, 1], [3, 2]],
        );
        set_array(dev, g, "primitive.radius", ANARI_FLOAT32, &[0.25f32, 0.25]);
    });
    let view = scene.render(geometry);
    for (i, x, y) in pixels() {
        let what = format!("pixel at ({x}, {y})");
        for (id, cx) in [(0, -0.75f32), (1, 0.75)] {
            let dx = x - cx;
            if dx.abs() < 0.25 - EDGE && y.abs() < 1.0 - EDGE {
                let depth = EYE_Z - (0.25f32 * 0.25 - dx * dx).sqrt();
                assert_hit(&view, i, Some((depth, id)), &what);
            }
        }
        if (x.abs() - 0.75).abs() > 0.25 + EDGE || y.abs() > 1.0 + EDGE {
            assert_hit(&view, i, None, &what);
        }
    }
    assert!(log.errors().is_empty());
}

#[test]
fn cylinder_colors_interpolate_along_the_axis_and_per_primitive() {
    let log = Log::new();
    let scene = Scene::new(&log);
    // Along x from red (x = −1) to blue (x = 1).
    let geometry = scene.geometry("cylinder", |dev, g| {
        positions(dev, g, &[[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]);
        set(dev, g, "radius", ANARI_FLOAT32, &0.4f32);
        set_string(dev, g, "caps", "both");
        set_array(
            dev,
            g,
            "vertex.color",
            ANARI_FLOAT32_VEC4,
            &[[1.0f32, 0.0, 0.0, 1.0], [0.0, 0.0, 1.0, 1.0]],
        );
    });
    let view = scene.render(geometry);
    let mut checked = 0;
    for (i, x, y) in pixels() {
        if x.abs() < 1.0 - EDGE && y.abs() < 0.4 - EDGE {
            let s = (x + 1.0) / 2.0;
            let expected = [1.0 - s, 0.0, s];
            let got = view.albedo[i];
            assert!(
                (0..3).all(|k| (got[k] - expected[k]).abs() < 1e-3),
                "at ({x}, {y}): {got:?} instead of {expected:?}"
            );
            checked += 1;
        }
    }
    assert!(checked > 500);

    // primitive.color: one colour per cylinder.
    let geometry = scene.geometry("cylinder", |dev, g| {
        positions(
            dev,
            g,
            &[
                [-1.0, -0.5, 0.0],
                [1.0, -0.5, 0.0],
                [-1.0, 0.5, 0.0],
                [1.0, 0.5, 0.0],
            ],
        );
        set(dev, g, "radius", ANARI_FLOAT32, &0.2f32);
        set_array(
            dev,
            g,
            "primitive.color",
            ANARI_FLOAT32_VEC3,
            &[[0.0f32, 1.0, 0.0], [1.0, 1.0, 0.0]],
        );
    });
    let view = scene.render(geometry);
    let (centre_low, centre_high) = (pixel_index(0.0, -0.5), pixel_index(0.0, 0.5));
    assert_eq!(view.albedo[centre_low], [0.0, 1.0, 0.0]);
    assert_eq!(view.albedo[centre_high], [1.0, 1.0, 0.0]);
    assert_eq!((view.ids[centre_low], view.ids[centre_high]), (0, 1));
    assert!(log.errors().is_empty());
}

/// Index of the pixel whose ray passes nearest to world (x, y).
fn pixel_index(x: f32, y: f32) -> usize {
    let at = |v: f32| ((v / VIEW_HEIGHT + 0.5) * SIZE as f32).floor() as usize;
    at(y) * SIZE as usize + at(x)
}

// ---- cone ----------------------------------------------------------------------------------

#[test]
fn cone_silhouette_is_a_triangle_and_depth_follows_the_flank() {
    let log = Log::new();
    let scene = Scene::new(&log);
    // Base (radius 0.5) at y = −0.5, apex (radius 0) at y = 0.5: radius r(y) = 0.25 − 0.5 y.
    let geometry = scene.geometry("cone", |dev, g| {
        positions(dev, g, &[[0.0, -0.5, 0.0], [0.0, 0.5, 0.0]]);
        set_array(dev, g, "vertex.radius", ANARI_FLOAT32, &[0.5f32, 0.0]);
        set_string(dev, g, "caps", "both");
    });
    let view = scene.render(geometry);
    let mut inside = 0;
    for (i, x, y) in pixels() {
        let what = format!("pixel at ({x}, {y})");
        let r = 0.25 - 0.5 * y;
        // Distance to the outline, roughly: the flanks have slope 1/2.
        let margin = (r - x.abs()).min(y + 0.5).min(0.5 - y);
        if margin > EDGE {
            inside += 1;
            // Rays perpendicular to the axis meet the circle of radius r(y) in their plane.
            let depth = EYE_Z - (r * r - x * x).sqrt();
            assert_hit(&view, i, Some((depth, 0)), &what);
        } else if margin < -EDGE {
            assert_hit(&view, i, None, &what);
        }
    }
    assert!(inside > 150);
    assert!(log.errors().is_empty());
}

/// A cone along z with its base (radius 0.5, vertex 0) at z = `base_z` and its apex (vertex 1)
/// at z = −`base_z`.
fn axis_cone(scene: &Scene, base_z: f32, caps: &str) -> Rendered {
    let geometry = scene.geometry("cone", |dev, g| {
        positions(dev, g, &[[0.0, 0.0, base_z], [0.0, 0.0, -base_z]]);
        set_array(dev, g, "vertex.radius", ANARI_FLOAT32, &[0.5f32, 0.0]);
        set_string(dev, g, "caps", caps);
    });
    scene.render(geometry)
}

#[test]
fn cone_seen_head_on_at_the_apex_and_into_the_open_or_capped_base() {
    let log = Log::new();
    let scene = Scene::new(&log);
    // Apex towards the camera (base at z = −1, apex at z = 1): every ray within the base
    // radius meets the flank at z = 1 − 4ρ, so depth 4 + 4ρ; the centre pixel comes closest to
    // the apex. Caps make no difference from this side.
    for caps in ["none", "first", "both"] {
        let view = axis_cone(&scene, -1.0, caps);
        for (i, x, y) in pixels() {
            let rho = x.hypot(y);
            let what = format!("apex view, caps {caps}, pixel at ({x}, {y})");
            if rho < 0.5 - EDGE {
                assert_hit(&view, i, Some((4.0 + 4.0 * rho, 0)), &what);
            } else if rho > 0.5 + EDGE {
                assert_hit(&view, i, None, &what);
            }
        }
    }
    // Base towards the camera (base at z = 1): open, the inside of the flank at z = 4ρ − 1
    // shows (depth 6 − 4ρ); "first" closes the base at depth 4; the apex end has no disk to
    // cap, so "second" looks like "none".
    for (caps, closed) in [
        ("none", false),
        ("second", false),
        ("first", true),
        ("both", true),
    ] {
        let view = axis_cone(&scene, 1.0, caps);
        for (i, x, y) in pixels() {
            let rho = x.hypot(y);
            let what = format!("base view, caps {caps}, pixel at ({x}, {y})");
            if rho < 0.5 - EDGE {
                let depth = if closed { 4.0 } else { 6.0 - 4.0 * rho };
                assert_hit(&view, i, Some((depth, 0)), &what);
            } else if rho > 0.5 + EDGE {
                assert_hit(&view, i, None, &what);
            }
        }
    }
    assert!(log.errors().is_empty());
}

#[test]
fn cone_vertex_caps_and_colors_follow_the_vertices() {
    let log = Log::new();
    let scene = Scene::new(&log);
    // Two frusta seen down their axes (radius 0.4 at z = 1, 0.2 at z = −1), at x = ∓0.75;
    // the second is indexed backwards. vertex.cap closes vertex 1 (far end of the first) and
    // vertex 3 (near end of the second).
    let geometry = scene.geometry("cone", |dev, g| {
        positions(
            dev,
            g,
            &[
                [-0.75, 0.0, 1.0],
                [-0.75, 0.0, -1.0],
                [0.75, 0.0, -1.0],
                [0.75, 0.0, 1.0],
            ],
        );
        set_array(
            dev,
            g,
            "vertex.radius",
            ANARI_FLOAT32,
            &[0.4f32, 0.2, 0.2, 0.4],
        );
        set_array(
            dev,
            g,
            "primitive.index",
            ANARI_UINT32_VEC2,
            &[[0u32, 1], [3, 2]],
        );
        set_array(dev, g, "vertex.cap", ANARI_UINT8, &[0u8, 1, 0, 1]);
        set_string(dev, g, "caps", "none");
        set_array(
            dev,
            g,
            "vertex.color",
            ANARI_FLOAT32_VEC3,
            &[
                [1.0f32, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [1.0, 1.0, 1.0],
            ],
        );
    });
    let view = scene.render(geometry);
    for (i, x, y) in pixels() {
        let what = format!("pixel at ({x}, {y})");
        let rho_left = (x + 0.75).hypot(y);
        let rho_right = (x - 0.75).hypot(y);
        if rho_left < 0.2 - EDGE {
            // Through the open near end onto the far cap (vertex 1: green).
            assert_hit(&view, i, Some((6.0, 0)), &what);
            assert_eq!(view.albedo[i], [0.0, 1.0, 0.0], "{what}");
        } else if rho_left > 0.2 + EDGE && rho_left < 0.4 - EDGE {
            // The inside of the flank: radius ρ at z = 10ρ − 3, colour between red and green.
            let z = 10.0 * rho_left - 3.0;
            assert_hit(&view, i, Some((EYE_Z - z, 0)), &what);
            let s = (1.0 - z) / 2.0;
            let got = view.albedo[i];
            assert!(
                (got[0] - (1.0 - s)).abs() < 1e-3 && (got[1] - s).abs() < 1e-3,
                "{what}: {got:?} at s {s}"
            );
        }
        if rho_right < 0.4 - EDGE {
            // The near cap at vertex 3: white.
            assert_hit(&view, i, Some((4.0, 1)), &what);
            assert_eq!(view.albedo[i], [1.0, 1.0, 1.0], "{what}");
        }
    }
    assert!(log.errors().is_empty());
}

// ---- curve ---------------------------------------------------------------------------------

/// Distance from (x, y) to the segment a–b in the plane.
fn segment_distance(p: [f32; 2], a: [f32; 2], b: [f32; 2]) -> (f32, f32) {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let s = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
    ((p[0] - a[0] - s * dx).hypot(p[1] - a[1] - s * dy), s)
}

#[test]
fn curve_segments_are_round_tubes_with_round_joints() {
    let log = Log::new();
    let scene = Scene::new(&log);
    // An L through three vertices in the plane z = 0, global radius 0.1, no index: one curve.
    let points = [[-1.0f32, -0.5], [0.5, -0.5], [0.5, 1.0]];
    let geometry = scene.geometry("curve", |dev, g| {
        positions(dev, g, &points.map(|p| [p[0], p[1], 0.0]));
        set(dev, g, "radius", ANARI_FLOAT32, &0.1f32);
    });
    let view = scene.render(geometry);
    let mut covered = 0;
    for (i, x, y) in pixels() {
        let what = format!("pixel at ({x}, {y})");
        let (d0, _) = segment_distance([x, y], points[0], points[1]);
        let (d1, _) = segment_distance([x, y], points[1], points[2]);
        let d = d0.min(d1);
        if d < 0.1 - EDGE {
            covered += 1;
            // Capsules: depth from the nearest point of the polyline, round at the joint too.
            let depth = EYE_Z - (0.01 - d * d).sqrt();
            assert!(
                (view.depth[i] - depth).abs() < 1e-3,
                "{what}: depth {}",
                view.depth[i]
            );
            if (d0 - d1).abs() > 2.0 * EDGE {
                assert_eq!(view.ids[i], if d0 < d1 { 0 } else { 1 }, "{what}");
            }
        } else if d > 0.1 + EDGE {
            assert_hit(&view, i, None, &what);
        }
    }
    assert!(covered > 150);
    assert!(log.errors().is_empty());
}

#[test]
fn curve_radius_varies_per_vertex_and_indexed_segments_leave_gaps() {
    let log = Log::new();
    let scene = Scene::new(&log);
    // Segments 0 → 1 (radius 0.05 → 0.3) and 2 → 3 (0.2 → 0.2); nothing joins 1 and 2.
    let points = [[-1.2f32, -0.8], [0.6, -0.8], [-1.0, 0.6], [1.0, 0.6]];
    let radii = [0.05f32, 0.3, 0.2, 0.2];
    let geometry = scene.geometry("curve", |dev, g| {
        positions(dev, g, &points.map(|p| [p[0], p[1], 0.0]));
        set_array(dev, g, "vertex.radius", ANARI_FLOAT32, &radii);
        set_array(dev, g, "primitive.index", ANARI_UINT32, &[0u32, 2]);
        set_array(
            dev,
            g,
            "vertex.color",
            ANARI_FLOAT32_VEC3,
            &[
                [1.0f32, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [0.0, 0.0, 0.0],
            ],
        );
    });
    let view = scene.render(geometry);
    // Outside distance to the union of the balls swept along a segment (convex in s).
    let swept = |p: [f32; 2], a: usize, b: usize| -> f32 {
        (0..=2000)
            .map(|k| {
                let s = k as f32 / 2000.0;
                let cx = points[a][0] + s * (points[b][0] - points[a][0]);
                let cy = points[a][1] + s * (points[b][1] - points[a][1]);
                (p[0] - cx).hypot(p[1] - cy) - (radii[a] + s * (radii[b] - radii[a]))
            })
            .fold(f32::INFINITY, f32::min)
    };
    let mut per_segment = [0; 2];
    for (i, x, y) in pixels() {
        let what = format!("pixel at ({x}, {y})");
        let d = [swept([x, y], 0, 1), swept([x, y], 2, 3)];
        for (id, distance) in d.iter().enumerate() {
            if *distance < -EDGE {
                per_segment[id] += 1;
                assert_eq!(view.ids[i], id as u32, "{what}");
            }
        }
        if d[0] > EDGE && d[1] > EDGE {
            assert_hit(&view, i, None, &what);
        }
    }
    assert!(
        per_segment[0] > 100 && per_segment[1] > 200,
        "{per_segment:?}"
    );
    // The thick end is 0.3 wide, the thin end 0.05: a pixel 0.2 off the axis near each end.
    assert_ne!(view.ids[pixel_index(0.55, -0.6)], MISS);
    assert_eq!(view.ids[pixel_index(-1.0, -0.6)], MISS);
    // Colour along segment 0 at its middle (on the axis): halfway between red and green.
    let middle = view.albedo[pixel_index(-0.3, -0.8)];
    let (_, s) = segment_distance(pixel_point_of(-0.3, -0.8), points[0], points[1]);
    assert!(
        (middle[0] - (1.0 - s)).abs() < 0.02 && (middle[1] - s).abs() < 0.02,
        "{middle:?}"
    );
    assert!(log.errors().is_empty());
}

/// World (x, y) of the pixel nearest to (x, y).
fn pixel_point_of(x: f32, y: f32) -> [f32; 2] {
    let i = pixel_index(x, y) as u32;
    let (px, py) = pixel_point(i % SIZE, i / SIZE);
    [px, py]
}

// ---- bad input and introspection ------------------------------------------------------------

/// The error texts logged so far.
fn error_texts(log: &Log) -> Vec<String> {
    log.errors().into_iter().map(|(_, text)| text).collect()
}

#[test]
fn bad_primitives_are_reported_and_skipped_while_the_rest_renders() {
    let log = Log::new();
    let scene = Scene::new(&log);
    // Cylinder 1 has a negative radius, cylinder 2 an index out of range.
    let geometry = scene.geometry("cylinder", |dev, g| {
        positions(dev, g, &UPRIGHTS);
        set_array(
            dev,
            g,
            "primitive.index",
            ANARI_UINT32_VEC2,
            &[[0u32, 1], [2, 3], [3, 9]],
        );
        set_array(
            dev,
            g,
            "primitive.radius",
            ANARI_FLOAT32,
            &[0.25f32, -0.25, 0.25],
        );
    });
    let errors = error_texts(&log);
    assert!(
        errors
            .iter()
            .any(|e| e.contains("cylinder") && e.contains("primitive 1") && e.contains("radius")),
        "{errors:?}"
    );
    assert!(
        errors
            .iter()
            .any(|e| e.contains("primitive 2") && e.contains("out of range")),
        "{errors:?}"
    );
    let view = scene.render(geometry);
    assert_eq!(view.ids[pixel_index(-0.75, 0.0)], 0);
    assert_eq!(view.ids[pixel_index(0.75, 0.0)], MISS);

    // Cone: NaN radius at vertex 3; the first cone still shows.
    let geometry = scene.geometry("cone", |dev, g| {
        positions(dev, g, &UPRIGHTS);
        set_array(
            dev,
            g,
            "vertex.radius",
            ANARI_FLOAT32,
            &[0.3f32, 0.1, 0.3, f32::NAN],
        );
    });
    let errors = error_texts(&log);
    assert!(
        errors.iter().any(|e| e.contains("cone")
            && e.contains("primitive 1")
            && e.contains("vertex.radius")),
        "{errors:?}"
    );
    let view = scene.render(geometry);
    assert_eq!(view.ids[pixel_index(-0.75, 0.0)], 0);
    assert_eq!(view.ids[pixel_index(0.75, 0.0)], MISS);

    // Curve: segment 1 starts at the last vertex, so its end is out of range.
    let geometry = scene.geometry("curve", |dev, g| {
        positions(dev, g, &[[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]);
        set(dev, g, "radius", ANARI_FLOAT32, &0.2f32);
        set_array(dev, g, "primitive.index", ANARI_UINT32, &[0u32, 1]);
    });
    let errors = error_texts(&log);
    assert!(
        errors.iter().any(|e| e.contains("curve")
            && e.contains("primitive 1")
            && e.contains("out of range")),
        "{errors:?}"
    );
    let view = scene.render(geometry);
    assert_eq!(view.ids[pixel_index(0.0, 0.0)], 0);

    // An unknown caps value and a vertex.cap array too short for the indices.
    let geometry = scene.geometry("cylinder", |dev, g| {
        positions(dev, g, &[[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]]);
        set_string(dev, g, "caps", "top");
        set(dev, g, "radius", ANARI_FLOAT32, &0.25f32);
    });
    let errors = error_texts(&log);
    assert!(
        errors
            .iter()
            .any(|e| e.contains("'caps' is 'top'") && e.contains("none, first, second, both")),
        "{errors:?}"
    );
    anariRelease(scene.dev, geometry);
    let geometry = scene.geometry("cylinder", |dev, g| {
        positions(dev, g, &[[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]]);
        set_array(dev, g, "vertex.cap", ANARI_UINT8, &[1u8]);
    });
    let errors = error_texts(&log);
    assert!(
        errors
            .iter()
            .any(|e| e.contains("primitive 0") && e.contains("vertex.cap")),
        "{errors:?}"
    );
    anariRelease(scene.dev, geometry);
}

#[test]
fn the_three_extensions_and_subtypes_are_advertised() {
    let log = Log::new();
    let scene = Scene::new(&log);
    let dev = scene.dev;
    let extensions = device_extensions(dev);
    for name in [
        "ANARI_KHR_GEOMETRY_CYLINDER",
        "ANARI_KHR_GEOMETRY_CONE",
        "ANARI_KHR_GEOMETRY_CURVE",
    ] {
        assert!(
            extensions.iter().any(|e| e == name),
            "{name} missing from {extensions:?}"
        );
    }
    let subtypes = c_strings(anariGetObjectSubtypes(dev, ANARI_GEOMETRY));
    for name in ["cylinder", "cone", "curve"] {
        assert!(subtypes.iter().any(|s| s == name), "{subtypes:?}");
    }
    // The caps vocabulary is introspectable.
    let values = anariGetParameterInfo(
        dev,
        ANARI_GEOMETRY,
        c("cone").as_ptr(),
        c("caps").as_ptr(),
        ANARI_STRING,
        c("value").as_ptr(),
        ANARI_STRING_LIST,
    ) as *const *const std::ffi::c_char;
    assert_eq!(c_strings(values), ["none", "first", "second", "both"]);
    assert!(log.errors().is_empty());
}
