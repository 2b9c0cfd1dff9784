//! "matrix" camera (ANARI_VSNRAY_CAMERA_MATRIX): the application's OpenGL view and projection
//! matrices, inverted and used to unproject NDC points (strategy 1 of Zellmann & Amstutz).

use std::sync::Arc;

use glam::{DVec3, DVec4, Mat4};

use super::rays::{ImageRegion, Unproject};
use super::validate;
use super::{Camera, CameraError, Eye, EyeRays, EyeViewport, StereoMode};

/// The near and far points of a pixel must be farther apart than this fraction of the near
/// plane's diagonal, or the frustum counts as flat.
const MIN_DEPTH_TO_NEAR_DIAGONAL: f64 = 1e-6;

/// NDC (u, v) samples checked at validation: the centre and the four corners.
const NDC_SAMPLES: [(f64, f64); 5] = [
    (0.0, 0.0),
    (-1.0, -1.0),
    (1.0, -1.0),
    (1.0, 1.0),
    (-1.0, 1.0),
];

/// Parameters of a matrix camera. `Default` is identity for both: parallel rays through the
/// `[−1,1]³` box, starting at z = −1 and running along +z (identity puts the near plane at eye
/// z = −1, unlike glOrtho which flips z).
#[derive(Clone, Debug, PartialEq)]
pub struct MatrixDesc {
    /// World → eye space, column-major (glm / OpenGL).
    pub view: Mat4,
    /// Eye → clip space, OpenGL NDC z in `[−1, 1]`: any glFrustum / glOrtho style matrix
    /// (asymmetric, off-centre, infinite far plane) is fine.
    pub proj: Mat4,
    /// `[lo.x, lo.y, hi.x, hi.y]` of the full image; may reach beyond `[0,1]²` and run
    /// backwards (a flip).
    pub image_region: [f32; 4],
}

impl Default for MatrixDesc {
    fn default() -> Self {
        MatrixDesc {
            view: Mat4::IDENTITY,
            proj: Mat4::IDENTITY,
            image_region: [0.0, 0.0, 1.0, 1.0],
        }
    }
}

impl MatrixDesc {
    pub fn validate(&self) -> Result<(), CameraError> {
        MatrixCamera::new(self).map(|_| ())
    }

    pub fn build(&self) -> Result<Arc<dyn Camera>, CameraError> {
        Ok(Arc::new(MatrixCamera::new(self)?))
    }
}

/// A validated matrix camera (mono: stereo applications pass one matrix pair per eye).
#[derive(Clone, Debug, PartialEq)]
pub struct MatrixCamera {
    unproject: Unproject,
    region: ImageRegion,
}

impl MatrixCamera {
    pub fn new(desc: &MatrixDesc) -> Result<MatrixCamera, CameraError> {
        let (view, inv_view) = validate::invertible_matrix("view", desc.view)?;
        let (proj, inv_proj) = validate::invertible_matrix("proj", desc.proj)?;
        let region = validate::image_region(desc.image_region)?;
        // The centre of projection is what proj maps to (0,0,1,0); at infinity for a parallel
        // projection.
        let centre = inv_proj * DVec4::Z;
        let perspective = centre.w.abs() > 1e-9 * centre.truncate().length();
        let eye = if perspective {
            let world = inv_view * (centre / centre.w);
            Some(world.truncate() / world.w)
        } else {
            None
        };
        let unproject = Unproject {
            view,
            proj,
            inv_view,
            inv_proj,
            eye,
        };
        check_frustum(&unproject, &NDC_SAMPLES)
            .map_err(|problem| CameraError::new("proj", problem))?;
        // A region beyond [0,1]² reaches past NDC ±1, where an unusual projection may no longer
        // have a near plane in front of its eye; the corners decide, as w is affine in (u, v).
        let [lo_x, lo_y, hi_x, hi_y] = desc.image_region.map(|v| 2.0 * f64::from(v) - 1.0);
        let region_corners = [(lo_x, lo_y), (hi_x, lo_y), (hi_x, hi_y), (lo_x, hi_y)];
        check_frustum(&unproject, &region_corners).map_err(|problem| {
            CameraError::new(
                "imageRegion",
                format!("reaches where proj has no usable frustum: {problem}"),
            )
        })?;
        Ok(MatrixCamera { unproject, region })
    }
}

/// Rejects projections whose near plane is at infinity, whose near and far planes lie on
/// opposite sides of the eye, or whose near and far points coincide, at NDC points `samples`.
fn check_frustum(m: &Unproject, samples: &[(f64, f64)]) -> Result<(), &'static str> {
    let near_point = |u: f64, v: f64| {
        let h = m.unproject(DVec3::new(u, v, -1.0));
        (h.w.abs() > 1e-12 * h.truncate().length()).then(|| h.truncate() / h.w)
    };
    let corners = [(-1.0, -1.0), (1.0, 1.0)].map(|(u, v)| near_point(u, v));
    let [Some(lower_left), Some(upper_right)] = corners else {
        return Err("the near plane is at infinity");
    };
    let near_diagonal = (upper_right - lower_left).length();
    for &(u, v) in samples {
        let Some(near) = near_point(u, v) else {
            return Err("the near plane is at infinity");
        };
        let far = m.unproject(DVec3::new(u, v, 1.0));
        let near_w = m.unproject(DVec3::new(u, v, -1.0)).w;
        let far_is_finite = far.w.abs() > 1e-12 * far.truncate().length();
        if far_is_finite && far.w.signum() != near_w.signum() {
            return Err("the near and far planes lie on opposite sides of the eye");
        }
        let (_, towards_far, depth) = m.segment(u, v);
        if let Some(eye) = m.eye
            && (near - eye).dot(towards_far) <= 0.0
        {
            return Err("the far plane is not beyond the near plane as seen from the eye");
        }
        if depth.is_nan() || depth <= MIN_DEPTH_TO_NEAR_DIAGONAL * near_diagonal {
            return Err("the near and far points coincide (the frustum has no depth)");
        }
    }
    Ok(())
}

impl Camera for MatrixCamera {
    fn viewports(&self, width: u32, height: u32) -> Vec<EyeViewport> {
        StereoMode::None.viewports(width, height)
    }

    /// The matrices fix the aspect, so the viewport size does not matter.
    fn prepare(&self, _eye: Eye, _viewport_width: u32, _viewport_height: u32) -> EyeRays {
        EyeRays::unproject(self.region, self.unproject)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::test_support::{angle_between, pixel_centres};
    use crate::camera::{OrthographicDesc, PerspectiveDesc};
    use glam::camera::rh::proj::opengl;
    use glam::camera::rh::view::{look_at_mat4, look_to_mat4};
    use glam::{Vec2, Vec3, Vec4};

    fn rays(view: Mat4, proj: Mat4) -> EyeRays {
        MatrixCamera::new(&MatrixDesc {
            view,
            proj,
            ..MatrixDesc::default()
        })
        .unwrap()
        .prepare(Eye::Mono, 64, 48)
    }

    #[test]
    fn asymmetric_frustum_rays_pass_through_their_near_plane_points() {
        let (left, right, bottom, top, near, far) = (-0.03f32, 0.11, -0.02, 0.07, 0.1, 30.0);
        let eye = Vec3::new(0.4, 1.7, -0.3);
        let view = look_at_mat4(eye, Vec3::new(-1.0, 1.0, -2.0), Vec3::Y);
        let r = rays(view, opengl::frustum(left, right, bottom, top, near, far));
        let to_world = view.inverse();
        for (_, _, s, t) in pixel_centres(20, 15) {
            let ray = r.ray(s, t, Vec2::ZERO);
            let near_point = to_world.transform_point3(Vec3::new(
                left + s * (right - left),
                bottom + t * (top - bottom),
                -near,
            ));
            // The ray starts at the eye; its visible part begins on the near plane.
            assert!((ray.origin - eye).length() < 1e-6, "{ray:?}");
            let start = ray.origin + ray.direction * ray.t_min;
            assert!((start - near_point).length() < 1e-6, "{ray:?} {near_point}");
            assert!(angle_between(ray.direction, near_point - eye) < 1e-5);
            // The far point lies on the far plane: eye-space z = −far.
            let far_point = ray.origin + ray.direction * ray.t_max;
            let far_z = view.transform_point3(far_point).z;
            assert!((far_z + far).abs() < 1e-3 * far, "{far_z}");
        }
    }

    #[test]
    fn orthographic_matrices_give_parallel_rays_like_the_orthographic_camera() {
        let position = Vec3::new(1.0, 2.0, 5.0);
        let direction = Vec3::new(-0.3, -0.2, -1.0).normalize();
        let view = look_to_mat4(position, direction, Vec3::Y);
        // Off-centre box: centre shifted by (0.5, −0.25) in eye space.
        let proj = opengl::orthographic(-1.0, 2.0, -1.25, 0.75, 0.5, 20.0);
        let r = rays(view, proj);
        let camera_frame = view.inverse();
        let shifted = camera_frame.transform_point3(Vec3::new(0.5, -0.25, 0.0));
        let orthographic = OrthographicDesc {
            position: shifted,
            direction,
            height: 2.0,
            aspect: Some(1.5),
            near: Some(0.5),
            far: Some(20.0),
            ..OrthographicDesc::default()
        }
        .build()
        .unwrap()
        .prepare(Eye::Mono, 64, 48);
        let first = r.ray(0.0, 0.0, Vec2::ZERO).direction;
        for (_, _, s, t) in pixel_centres(16, 12) {
            let ray = r.ray(s, t, Vec2::ZERO);
            assert!(angle_between(ray.direction, first) < 1e-6, "not parallel");
            assert!(angle_between(ray.direction, direction) < 1e-6);
            assert!((ray.t_max - 19.5).abs() < 1e-4, "{ray:?}");
            let expected = orthographic.ray(s, t, Vec2::ZERO);
            let start = expected.origin + expected.direction * expected.t_min;
            assert!(
                (ray.origin - start).length() < 1e-5,
                "{ray:?} vs {expected:?}"
            );
            // Orthographic depth counts from the near plane.
            assert_eq!(r.depth(&ray, 2.5), 2.5);
        }
    }

    #[test]
    fn perspective_depth_counts_from_the_eye() {
        let eye = Vec3::new(0.0, 1.0, 3.0);
        let view = look_to_mat4(eye, Vec3::NEG_Z, Vec3::Y);
        let r = rays(view, opengl::perspective(1.0, 1.3, 0.2, 50.0));
        let ray = r.ray(0.9, 0.1, Vec2::ZERO);
        assert!((ray.origin - eye).length() < 1e-6, "{ray:?}");
        // The near plane is 0.2 ahead; this ray reaches it farther off the axis.
        assert!(ray.t_min > 0.2 && (ray.direction.z * ray.t_min + 0.2).abs() < 1e-6);
        for t in [ray.t_min, 4.0] {
            let hit = ray.origin + ray.direction * t;
            assert!((r.depth(&ray, t) - (hit - eye).length()).abs() < 1e-5);
        }
    }

    #[test]
    fn window_depth_is_what_opengl_writes() {
        let eye = Vec3::new(-0.5, 1.2, 0.8);
        let view = look_at_mat4(eye, Vec3::new(0.5, 0.2, -3.0), Vec3::Y);
        let (near, far) = (0.1f32, 25.0f32);
        let r = rays(view, opengl::frustum(-0.05, 0.08, -0.04, 0.06, near, far));
        for (s, t) in [(0.5, 0.5), (0.05, 0.95), (0.8, 0.3)] {
            let ray = r.ray(s, t, Vec2::ZERO);
            assert!(
                r.window_depth_at(ray.origin + ray.direction * ray.t_min)
                    .abs()
                    < 1e-5
            );
            assert!((r.window_depth_at(ray.origin + ray.direction * ray.t_max) - 1.0).abs() < 1e-5);
            for along in [0.5f32, 2.0, 10.0] {
                let p = ray.origin + ray.direction * along;
                // glFrustum depth of eye-space distance z: f(z − n) / (z(f − n)).
                let z = -f64::from(view.transform_point3(p).z);
                let (n, f) = (f64::from(near), f64::from(far));
                let expected = f * (z - n) / (z * (f - n));
                let got = f64::from(r.window_depth_at(p));
                assert!((got - expected).abs() < 1e-5, "{got} vs {expected}");
            }
        }
    }

    #[test]
    fn perspective_matrices_trace_as_pinholes_with_the_unprojected_rays() {
        let eye = Vec3::new(0.4, 1.7, -0.3);
        let view = look_at_mat4(eye, Vec3::new(-1.0, 1.0, -2.0), Vec3::Y);
        let focal = 1.0 / 0.4f32.tan();
        let infinite = Mat4::from_cols(
            Vec4::new(focal / 1.5, 0.0, 0.0, 0.0),
            Vec4::new(0.0, focal, 0.0, 0.0),
            Vec4::new(0.0, 0.0, -1.0, -1.0),
            Vec4::new(0.0, 0.0, -0.1, 0.0),
        );
        for proj in [
            opengl::frustum(-0.03, 0.11, -0.02, 0.07, 0.1, 30.0),
            opengl::perspective(1.0, 1.3, 0.2, 50.0),
            infinite,
        ] {
            let camera = MatrixCamera::new(&MatrixDesc {
                view,
                proj,
                image_region: [0.1, 0.2, 0.7, 0.9],
            })
            .unwrap();
            let fast = camera.prepare(Eye::Mono, 64, 48);
            assert!(fast.traces_as_pinhole());
            let exact = EyeRays::unproject_exactly(camera.region, camera.unproject);
            for (_, _, s, t) in pixel_centres(20, 15) {
                let (a, b) = (fast.ray(s, t, Vec2::ZERO), exact.ray(s, t, Vec2::ZERO));
                assert!((a.origin - b.origin).length() < 1e-6, "{a:?} vs {b:?}");
                assert!(
                    angle_between(a.direction, b.direction) < 1e-6,
                    "{a:?} vs {b:?}"
                );
                assert!((a.t_min - b.t_min).abs() < 1e-6 * b.t_min, "{a:?} vs {b:?}");
                assert!(
                    a.t_max == b.t_max || (a.t_max - b.t_max).abs() < 1e-5 * b.t_max,
                    "{a:?} vs {b:?}"
                );
            }
        }
        // Orthographic projections keep their rays starting on the near plane.
        let ortho = rays(
            view,
            opengl::orthographic(-1.0, 2.0, -1.25, 0.75, 0.5, 20.0),
        );
        assert!(!ortho.traces_as_pinhole());
    }

    #[test]
    fn infinite_far_plane_gives_unbounded_rays() {
        let (fovy, aspect, near) = (0.8f32, 1.5f32, 0.05f32);
        let focal = 1.0 / (0.5 * fovy).tan();
        // glm::infinitePerspective.
        let infinite = Mat4::from_cols(
            Vec4::new(focal / aspect, 0.0, 0.0, 0.0),
            Vec4::new(0.0, focal, 0.0, 0.0),
            Vec4::new(0.0, 0.0, -1.0, -1.0),
            Vec4::new(0.0, 0.0, -2.0 * near, 0.0),
        );
        let view = look_to_mat4(Vec3::new(1.0, 2.0, 3.0), Vec3::X, Vec3::Y);
        let unbounded = rays(view, infinite);
        let bounded = rays(view, opengl::perspective(fovy, aspect, near, 100.0));
        for (_, _, s, t) in pixel_centres(8, 6) {
            let a = unbounded.ray(s, t, Vec2::ZERO);
            let b = bounded.ray(s, t, Vec2::ZERO);
            assert!(a.t_max > 1e6, "{a:?}");
            assert!(angle_between(a.direction, b.direction) < 1e-6);
            assert!((a.origin - b.origin).length() < 1e-6);
        }
    }

    #[test]
    fn flipped_projection_flips_the_image() {
        let view = look_at_mat4(Vec3::new(0.0, 1.0, 2.0), Vec3::ZERO, Vec3::Y);
        let proj = opengl::perspective(1.0, 1.0, 0.1, 10.0);
        let flipped = Mat4::from_scale(Vec3::new(1.0, -1.0, 1.0)) * proj;
        let upright = rays(view, proj);
        let mirrored = rays(view, flipped);
        for (_, _, s, t) in pixel_centres(6, 6) {
            let a = upright.ray(s, 1.0 - t, Vec2::ZERO);
            let b = mirrored.ray(s, t, Vec2::ZERO);
            assert!(angle_between(a.direction, b.direction) < 1e-6);
        }
    }

    #[test]
    fn identity_default_is_the_unit_box_along_plus_z() {
        let r = MatrixDesc::default()
            .build()
            .unwrap()
            .prepare(Eye::Mono, 2, 2);
        let ray = r.ray(0.25, 0.75, Vec2::ZERO);
        assert_eq!(ray.origin, Vec3::new(-0.5, 0.5, -1.0));
        assert_eq!(ray.direction, Vec3::Z);
        assert_eq!(ray.t_max, 2.0);
    }

    #[test]
    fn matrix_and_perspective_cameras_agree_with_image_region() {
        let position = Vec3::new(0.3, 1.1, 0.2);
        let direction = Vec3::new(0.6, 0.1, -0.8).normalize();
        let region = [0.25, 0.1, 0.75, 0.6];
        let matrix = MatrixDesc {
            view: look_to_mat4(position, direction, Vec3::Y),
            proj: opengl::perspective(0.7, 1.25, 0.01, 100.0),
            image_region: region,
        }
        .build()
        .unwrap()
        .prepare(Eye::Mono, 10, 10);
        let perspective = PerspectiveDesc {
            position,
            direction,
            fovy: 0.7,
            aspect: Some(1.25),
            image_region: region,
            ..PerspectiveDesc::default()
        }
        .build()
        .unwrap()
        .prepare(Eye::Mono, 10, 10);
        for (_, _, s, t) in pixel_centres(10, 10) {
            let a = matrix.ray(s, t, Vec2::ZERO);
            let b = perspective.ray(s, t, Vec2::ZERO);
            assert!(angle_between(a.direction, b.direction) < 1e-6);
        }
    }

    #[test]
    fn a_region_reaching_past_the_projections_usable_frustum_is_named() {
        let view = look_at_mat4(Vec3::new(0.0, 1.0, 2.0), Vec3::ZERO, Vec3::Y);
        // A projective warp: the far plane's w falls with NDC u, 0.1 at u = 0, 0.05 at u = −1,
        // 0 at u = −2; the near plane stays in front of the eye everywhere used here.
        let mut unproject = opengl::perspective(1.0, 1.0, 0.1, 10.0).inverse();
        unproject.x_axis.w += 0.05;
        let proj = unproject.inverse();
        let with_region = |image_region| {
            MatrixDesc {
                view,
                proj,
                image_region,
            }
            .validate()
        };
        assert_eq!(with_region([0.0, 0.0, 1.0, 1.0]), Ok(()));
        assert_eq!(with_region([1.0, 0.0, -0.4, 1.0]), Ok(()));
        let error = with_region([-1.0, 0.0, 1.0, 1.0]).unwrap_err();
        assert_eq!(error.parameter, "imageRegion", "{error}");
        assert!(error.message.contains("opposite sides"), "{error}");
    }

    #[test]
    fn invalid_matrices_are_named() {
        let good_view = look_at_mat4(Vec3::new(0.0, 1.0, 2.0), Vec3::ZERO, Vec3::Y);
        let good_proj = opengl::perspective(1.0, 1.0, 0.1, 10.0);
        let mut nan_view = good_view;
        nan_view.w_axis.y = f32::NAN;
        let mut singular_view = good_view;
        singular_view.z_axis = Vec4::ZERO;
        let mut infinite_proj = good_proj;
        infinite_proj.x_axis.x = f32::INFINITY;
        let mut singular_proj = good_proj;
        singular_proj.w_axis = singular_proj.z_axis * 3.0;
        // A frustum 0.1 µm deep at one meter: its near and far points coincide.
        let flat_proj = opengl::frustum(-1.0, 1.0, -1.0, 1.0, 1.0, 1.000_000_1);
        let cases = [
            (nan_view, good_proj, [0.0, 0.0, 1.0, 1.0], "view"),
            (singular_view, good_proj, [0.0, 0.0, 1.0, 1.0], "view"),
            (Mat4::ZERO, good_proj, [0.0, 0.0, 1.0, 1.0], "view"),
            (good_view, infinite_proj, [0.0, 0.0, 1.0, 1.0], "proj"),
            (good_view, singular_proj, [0.0, 0.0, 1.0, 1.0], "proj"),
            (good_view, flat_proj, [0.0, 0.0, 1.0, 1.0], "proj"),
            (
                good_view,
                good_proj,
                [0.0, 0.0, 2.0, f32::NAN],
                "imageRegion",
            ),
            (good_view, good_proj, [0.0, 0.5, 2.0, 0.5], "imageRegion"),
        ];
        for (view, proj, image_region, parameter) in cases {
            let desc = MatrixDesc {
                view,
                proj,
                image_region,
            };
            let error = desc.validate().expect_err(parameter);
            assert_eq!(error.parameter, parameter, "{desc:?}: {error}");
        }
        let flat_error = MatrixDesc {
            view: good_view,
            proj: flat_proj,
            ..MatrixDesc::default()
        }
        .validate()
        .unwrap_err();
        assert!(flat_error.message.contains("coincide"), "{flat_error}");
        // Slightly deeper is fine.
        let thin = opengl::frustum(-1.0, 1.0, -1.0, 1.0, 1.0, 1.001);
        assert!(
            MatrixDesc {
                view: good_view,
                proj: thin,
                ..MatrixDesc::default()
            }
            .validate()
            .is_ok()
        );
    }
}
