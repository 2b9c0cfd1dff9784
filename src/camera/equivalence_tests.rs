//! Cross-model tests: the CAVE invariant for all four ways of getting primary rays, imageRegion
//! crops, and the matrix camera's precision with a tiny near plane.

use glam::{DMat4, DVec3, Mat4, Vec2, Vec3};

use super::offaxis::{off_axis_matrices, off_axis_perspective, perspective_from_matrices};
use super::test_support::{
    HEIGHT, Screen, WIDTH, angle_between, max_screen_error, pixel_centres, screens, unit_sequence,
};
use super::{
    Camera, CameraRay, Eye, EyeRays, MatrixDesc, OffAxisDesc, OrthographicDesc, PerspectiveDesc,
};

const NEAR: f64 = 0.01;
const FAR: f64 = 500.0;

/// Allowed deviation from the expected screen point: f32 outputs resolve about 1e-7 of the
/// coordinates' magnitude, times the lever of the eye-to-screen distance.
fn tolerance(screen: &Screen, eye: DVec3, relative: f64) -> f64 {
    let magnitude = [screen.ll, screen.lr, screen.ur, eye]
        .iter()
        .map(|p| p.abs().max_element())
        .fold(1.0, f64::max);
    relative * magnitude
}

fn offaxis_camera(screen: &Screen, eye: DVec3) -> OffAxisDesc {
    OffAxisDesc {
        lower_left: Some(screen.ll.as_vec3()),
        lower_right: Some(screen.lr.as_vec3()),
        upper_right: Some(screen.ur.as_vec3()),
        position: eye.as_vec3(),
        near: Some(NEAR as f32),
        far: Some(FAR as f32),
        ..OffAxisDesc::default()
    }
}

fn matrix_camera(view: DMat4, proj: DMat4) -> MatrixDesc {
    MatrixDesc {
        view: view.as_mat4(),
        proj: proj.as_mat4(),
        ..MatrixDesc::default()
    }
}

fn mono(camera: &dyn Camera) -> EyeRays {
    camera.prepare(Eye::Mono, WIDTH, HEIGHT)
}

/// Runs `check` for every screen and eye, reporting the worst error of each strategy.
fn for_every_screen_and_eye(
    strategy: &str,
    relative: f64,
    rays_for: impl Fn(&Screen, DVec3) -> EyeRays,
) {
    let mut worst_ratio: f64 = 0.0;
    for screen in screens() {
        for eye in screen.eyes() {
            let rays = rays_for(&screen, eye);
            let error = max_screen_error(&rays, &screen);
            let allowed = tolerance(&screen, eye, relative);
            assert!(
                error <= allowed,
                "{strategy}: screen {} eye {eye}: off by {error:e} m (allowed {allowed:e})",
                screen.name
            );
            worst_ratio = worst_ratio.max(error / allowed);
        }
    }
    println!("{strategy}: worst error {worst_ratio:.3} of the tolerance");
}

#[test]
fn invariant_holds_for_matrix_camera_from_off_axis_matrices() {
    for_every_screen_and_eye("matrix", 2e-6, |screen, eye| {
        let (view, proj) =
            off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
        mono(&*matrix_camera(view, proj).build().unwrap())
    });
}

#[test]
fn invariant_holds_for_perspective_camera_from_off_axis_perspective() {
    for_every_screen_and_eye("perspective fit", 5e-6, |screen, eye| {
        let fit = off_axis_perspective(screen.ll, screen.lr, screen.ur, eye).unwrap();
        mono(&*PerspectiveDesc::from_fit(&fit).build().unwrap())
    });
}

#[test]
fn invariant_holds_for_perspective_camera_from_recovered_matrices() {
    for_every_screen_and_eye("perspective from matrices", 5e-6, |screen, eye| {
        let (view, proj) =
            off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
        // What the C API sees: float matrices.
        let fit = perspective_from_matrices(view.as_mat4().as_dmat4(), proj.as_mat4().as_dmat4())
            .unwrap();
        mono(&*PerspectiveDesc::from_fit(&fit).build().unwrap())
    });
}

#[test]
fn invariant_holds_for_off_axis_camera() {
    for_every_screen_and_eye("offAxis", 2e-6, |screen, eye| {
        mono(&*offaxis_camera(screen, eye).build().unwrap())
    });
}

#[test]
fn all_strategies_give_the_same_rays() {
    for screen in screens() {
        for eye in screen.eyes() {
            let (view, proj) =
                off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
            let fit = off_axis_perspective(screen.ll, screen.lr, screen.ur, eye).unwrap();
            let strategies = [
                mono(&*matrix_camera(view, proj).build().unwrap()),
                mono(&*PerspectiveDesc::from_fit(&fit).build().unwrap()),
                mono(&*offaxis_camera(&screen, eye).build().unwrap()),
            ];
            for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
                let rays = strategies.each_ref().map(|r| r.ray(s, t, Vec2::ZERO));
                for ray in &rays[1..] {
                    let angle = angle_between(ray.direction, rays[0].direction);
                    assert!(angle < 2e-5, "{}: {angle:e} rad", screen.name);
                }
                // Every strategy's ray starts at the eye (the matrix ray's visible part
                // begins on the near plane).
                for ray in &rays {
                    assert!(
                        (ray.origin.as_dvec3() - eye).length() < 1e-5,
                        "{}",
                        screen.name
                    );
                }
                let near_point = rays[0].origin + rays[0].direction * rays[0].t_min;
                let near_distance = (near_point.as_dvec3() - eye).dot(-screen.normal());
                assert!((near_distance - NEAR).abs() < 1e-5, "{near_distance}");
            }
        }
    }
}

/// Same segment of space: origin + t_min·direction agree within `tolerance` (meters), the
/// directions within 1e-5 rad and the segment lengths within `length_tolerance` (relative).
fn assert_same_segment(
    a: &CameraRay,
    b: &CameraRay,
    tolerance: f32,
    length_tolerance: f32,
    what: &str,
) {
    let start = |r: &CameraRay| r.origin + r.direction * r.t_min;
    assert!(
        (start(a) - start(b)).length() <= tolerance,
        "{what}: {a:?} vs {b:?}"
    );
    assert!(
        angle_between(a.direction, b.direction) < 1e-5,
        "{what}: {a:?} vs {b:?}"
    );
    let length = |r: &CameraRay| r.t_max - r.t_min;
    if length(a).is_finite() || length(b).is_finite() {
        assert!(
            (length(a) - length(b)).abs() <= length_tolerance * length(a).abs().max(1.0),
            "{what}: {a:?} vs {b:?}"
        );
    }
}

/// Renders a sub-rectangle `[x0, x1)×[y0, y1)` of a `width`×`height` frame through imageRegion
/// and compares every pixel with the full frame's ray.
fn assert_crop_matches_full_frame(
    what: &str,
    build: impl Fn([f32; 4]) -> std::sync::Arc<dyn Camera>,
) {
    let (width, height) = (40u32, 30u32);
    let (x0, x1, y0, y1) = (7u32, 27u32, 5u32, 20u32);
    let full = build([0.0, 0.0, 1.0, 1.0]).prepare(Eye::Mono, width, height);
    let region = [
        x0 as f32 / width as f32,
        y0 as f32 / height as f32,
        x1 as f32 / width as f32,
        y1 as f32 / height as f32,
    ];
    let crop = build(region).prepare(Eye::Mono, x1 - x0, y1 - y0);
    let mut compared = 0;
    for (x, y, s, t) in pixel_centres(x1 - x0, y1 - y0) {
        let cropped = crop.ray(s, t, Vec2::ZERO);
        let s_full = (x0 + x) as f32 + 0.5;
        let t_full = (y0 + y) as f32 + 0.5;
        let whole = full.ray(s_full / width as f32, t_full / height as f32, Vec2::ZERO);
        assert_same_segment(&cropped, &whole, 1e-5, 1e-6, what);
        compared += 1;
    }
    assert_eq!(compared, 300);
}

#[test]
fn image_region_crop_equals_crop_of_full_frame() {
    let screen = screens()[5];
    let eye = screen.local(0.3, 0.1, 1.2);
    assert_crop_matches_full_frame("perspective", |image_region| {
        PerspectiveDesc {
            position: Vec3::new(0.5, 1.6, 2.0),
            direction: Vec3::new(-0.2, -0.1, -1.0),
            fovy: 0.8,
            // Fixed aspect: the default (viewport aspect) would differ between the frames.
            aspect: Some(4.0 / 3.0),
            near: Some(0.1),
            far: Some(50.0),
            image_region,
            ..PerspectiveDesc::default()
        }
        .build()
        .unwrap()
    });
    assert_crop_matches_full_frame("orthographic", |image_region| {
        OrthographicDesc {
            position: Vec3::new(0.5, 1.6, 2.0),
            direction: Vec3::new(0.3, -0.4, -1.0),
            height: 2.5,
            aspect: Some(4.0 / 3.0),
            near: Some(0.5),
            image_region,
            ..OrthographicDesc::default()
        }
        .build()
        .unwrap()
    });
    assert_crop_matches_full_frame("offAxis", |image_region| {
        OffAxisDesc {
            image_region,
            ..offaxis_camera(&screen, eye)
        }
        .build()
        .unwrap()
    });
    let (view, proj) = off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
    assert_crop_matches_full_frame("matrix", |image_region| {
        MatrixDesc {
            image_region,
            ..matrix_camera(view, proj)
        }
        .build()
        .unwrap()
    });
}

#[test]
fn perspective_and_matrix_cameras_clip_the_same_segment() {
    for screen in screens() {
        let eye = screen.local(-0.3, 0.2, 1.4);
        let (view, proj) =
            off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
        let matrix = mono(&*matrix_camera(view, proj).build().unwrap());
        let offaxis = mono(&*offaxis_camera(&screen, eye).build().unwrap());
        for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
            let a = matrix.ray(s, t, Vec2::ZERO);
            let b = offaxis.ray(s, t, Vec2::ZERO);
            assert!(a.t_min > 0.0);
            // Rounding the projection to f32 moves its far plane by ~0.2% (1 + P[2][2] is
            // ~(2·near/far) and loses most of its bits), so the far end only agrees that well.
            assert_same_segment(&a, &b, 1e-5, 3e-3, screen.name);
        }
    }
}

/// The f32 shortcut that the matrix camera avoids: premultiply the inverses, unproject both
/// NDC points and subtract.
fn naive_f32_direction(inverse_view_proj: Mat4, u: f32, v: f32) -> Vec3 {
    let near = inverse_view_proj.project_point3(Vec3::new(u, v, -1.0));
    let far = inverse_view_proj.project_point3(Vec3::new(u, v, 1.0));
    (far - near).normalize()
}

#[test]
fn matrix_camera_keeps_precision_with_tiny_near_plane() {
    let size = 1600u32;
    let position = Vec3::new(0.7, 1.65, 2.3);
    let direction = Vec3::new(-0.3, -0.15, -1.0).normalize();
    let fovy = 1.1f32;
    let near = 0.001f32;
    let perspective = PerspectiveDesc {
        position,
        direction,
        fovy,
        aspect: Some(1.0),
        near: Some(near),
        far: Some(1000.0),
        ..PerspectiveDesc::default()
    }
    .build()
    .unwrap()
    .prepare(Eye::Mono, size, size);
    let view = glam::camera::rh::view::look_to_mat4(position, direction, Vec3::Y);
    let proj = glam::camera::rh::proj::opengl::perspective(fovy, 1.0, near, 1000.0);
    let matrix = MatrixDesc {
        view,
        proj,
        ..MatrixDesc::default()
    }
    .build()
    .unwrap()
    .prepare(Eye::Mono, size, size);
    let inverse_view_proj = (proj * view).inverse();
    let mut worst: f64 = 0.0;
    let mut worst_naive: f64 = 0.0;
    for (_, _, s, t) in pixel_centres(size, size) {
        let expected = perspective.ray(s, t, Vec2::ZERO);
        let got = matrix.ray(s, t, Vec2::ZERO);
        worst = worst.max(angle_between(got.direction, expected.direction));
        if s < 0.01 && t < 0.01 || (s - 0.5).abs() < 1e-3 {
            let naive = naive_f32_direction(inverse_view_proj, 2.0 * s - 1.0, 2.0 * t - 1.0);
            worst_naive = worst_naive.max(angle_between(naive, expected.direction));
        }
    }
    println!("matrix camera worst angle {worst:e} rad, naive f32 {worst_naive:e} rad");
    assert!(worst < 1e-5, "worst angle {worst:e} rad");
    // The test has teeth: the f32 premultiplied shortcut is far off at this near plane.
    assert!(
        worst_naive > 1e-4,
        "naive f32 worst angle {worst_naive:e} rad"
    );
}

/// A ray's fields as bits, so that equal means bit for bit.
fn ray_bits(ray: &CameraRay) -> [u32; 11] {
    let v = |v: Vec3| v.to_array().map(f32::to_bits);
    let [ox, oy, oz] = v(ray.origin);
    let [dx, dy, dz] = v(ray.direction);
    let [cx, cy, cz] = v(ray.cyclopean.unwrap_or(Vec3::NAN));
    [
        ox,
        oy,
        oz,
        dx,
        dy,
        dz,
        ray.t_min.to_bits(),
        ray.t_max.to_bits(),
        cx,
        cy,
        cz,
    ]
}

#[test]
fn block_rays_are_the_rays_made_one_by_one_on_every_path() {
    use super::{BLOCK_RAYS, BlockRays, StereoMode};
    // Viewport points: pixel centres, jittered samples and the viewport's edges.
    let mut sequence = unit_sequence(3);
    let mut unit = || sequence() as f32;
    let mut points: Vec<(f32, f32)> = pixel_centres(WIDTH, HEIGHT)
        .map(|(_, _, s, t)| (s, t))
        .collect();
    points.extend((0..200).map(|_| (unit(), unit())));
    points.extend([(0.0, 0.0), (1.0, 1.0), (0.0, 1.0), (1.0, 0.0)]);
    let paths = crate::isa::test_paths();
    let mut block = BlockRays::default();
    let mut checked = 0;
    for screen in screens() {
        for eye in screen.eyes() {
            let (view, proj) =
                off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
            let stereo = OffAxisDesc {
                stereo_mode: StereoMode::SideBySide,
                interpupillary_distance: 0.0635,
                near: None,
                far: None,
                image_region: [0.1, 0.2, 0.9, 0.7],
                ..offaxis_camera(&screen, eye)
            };
            let fit = off_axis_perspective(screen.ll, screen.lr, screen.ur, eye).unwrap();
            let cameras = [
                // Clipped at near and far: t_min and t_max per ray.
                offaxis_camera(&screen, eye)
                    .build()
                    .unwrap()
                    .prepare(Eye::Mono, WIDTH, HEIGHT),
                // Unclipped, cropped, one eye of a pair: the cyclopean point.
                stereo.build().unwrap().prepare(Eye::Left, WIDTH, HEIGHT),
                stereo.build().unwrap().prepare(Eye::Right, WIDTH, HEIGHT),
                mono(&*PerspectiveDesc::from_fit(&fit).build().unwrap()),
                // A perspective matrix, traced as the pinhole it is.
                mono(&*matrix_camera(view, proj).build().unwrap()),
            ];
            assert!(cameras[4].traces_as_pinhole());
            for rays in &cameras {
                assert!(rays.makes_block_rays());
                for chunk in points.chunks(BLOCK_RAYS) {
                    let mut s = [0.5; BLOCK_RAYS];
                    let mut t = [0.5; BLOCK_RAYS];
                    for (i, (ps, pt)) in chunk.iter().enumerate() {
                        (s[i], t[i]) = (*ps, *pt);
                    }
                    for &isa in &paths {
                        assert!(rays.block_rays_on_path(isa, &s, &t, &mut block));
                        for i in 0..BLOCK_RAYS {
                            let one = rays.ray(s[i], t[i], Vec2::ZERO);
                            assert_eq!(
                                ray_bits(&block.ray(i)),
                                ray_bits(&one),
                                "{} eye {eye} {isa:?}: ({}, {})",
                                screen.name,
                                s[i],
                                t[i]
                            );
                            checked += 1;
                        }
                    }
                }
            }
        }
    }
    assert!(checked > 10_000, "{checked}");
    // Cameras whose rays do not share one pinhole make theirs one by one.
    let lens = PerspectiveDesc {
        aperture_radius: 0.01,
        focus_distance: 2.0,
        ..PerspectiveDesc::default()
    };
    assert!(!mono(&*lens.build().unwrap()).makes_block_rays());
    assert!(!mono(&*OrthographicDesc::default().build().unwrap()).makes_block_rays());
}
