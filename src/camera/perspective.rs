//! ANARI "perspective" camera (KHR_CAMERA_PERSPECTIVE, KHR_CAMERA_STEREO,
//! KHR_CAMERA_DEPTH_OF_FIELD).

use std::sync::Arc;

use glam::{DVec3, Vec3};

use super::offaxis::PerspectiveFit;
use super::rays::{ClipRange, ImageRegion, Pinhole, StereoGeometry};
use super::validate;
use super::{
    Camera, CameraError, DEFAULT_INTERPUPILLARY_DISTANCE, Eye, EyeRays, EyeViewport, StereoMode,
    viewport_aspect,
};

/// Parameters of a perspective camera as the application set them; `Default` holds the ANARI
/// defaults, `None` means unset.
#[derive(Clone, Debug, PartialEq)]
pub struct PerspectiveDesc {
    /// Camera position; in stereo the point midway between the eyes.
    pub position: Vec3,
    pub direction: Vec3,
    pub up: Vec3,
    /// Vertical field of view in radians, in (0, π).
    pub fovy: f32,
    /// Width / height of the image plane; unset means the viewport's pixel aspect.
    pub aspect: Option<f32>,
    /// `[lo.x, lo.y, hi.x, hi.y]` of the full image; may reach beyond `[0,1]²` and run
    /// backwards (a flip).
    pub image_region: [f32; 4],
    pub near: Option<f32>,
    pub far: Option<f32>,
    pub stereo_mode: StereoMode,
    pub interpupillary_distance: f32,
    pub aperture_radius: f32,
    /// Distance of the focus plane, which is also the zero-parallax plane in stereo.
    pub focus_distance: f32,
}

impl Default for PerspectiveDesc {
    fn default() -> Self {
        PerspectiveDesc {
            position: Vec3::ZERO,
            direction: Vec3::NEG_Z,
            up: Vec3::Y,
            fovy: std::f32::consts::FRAC_PI_3,
            aspect: None,
            image_region: [0.0, 0.0, 1.0, 1.0],
            near: None,
            far: None,
            stereo_mode: StereoMode::None,
            interpupillary_distance: DEFAULT_INTERPUPILLARY_DISTANCE,
            aperture_radius: 0.0,
            focus_distance: 1.0,
        }
    }
}

impl PerspectiveDesc {
    /// A mono camera with the fitted parameters (rounded to f32, as ANARI stores them).
    pub fn from_fit(fit: &PerspectiveFit) -> PerspectiveDesc {
        PerspectiveDesc {
            position: fit.position.as_vec3(),
            direction: fit.direction.as_vec3(),
            up: fit.up.as_vec3(),
            fovy: fit.fovy as f32,
            aspect: Some(fit.aspect as f32),
            image_region: fit.image_region.map(|v| v as f32),
            ..PerspectiveDesc::default()
        }
    }

    pub fn validate(&self) -> Result<(), CameraError> {
        PerspectiveCamera::new(self).map(|_| ())
    }

    pub fn build(&self) -> Result<Arc<dyn Camera>, CameraError> {
        Ok(Arc::new(PerspectiveCamera::new(self)?))
    }
}

/// A validated perspective camera.
#[derive(Clone, Debug, PartialEq)]
pub struct PerspectiveCamera {
    position: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_half_fovy: f64,
    aspect: Option<f64>,
    region: ImageRegion,
    clip: ClipRange,
    stereo_mode: StereoMode,
    interpupillary_distance: f64,
    aperture_radius: f64,
    focus_distance: f64,
}

impl PerspectiveCamera {
    pub fn new(desc: &PerspectiveDesc) -> Result<PerspectiveCamera, CameraError> {
        let position = validate::finite_point("position", desc.position)?;
        let (forward, right, up) = validate::view_frame(desc.direction, desc.up)?;
        let fovy = desc.fovy;
        if !(fovy.is_finite() && fovy > 0.0 && f64::from(fovy) < std::f64::consts::PI) {
            return Err(CameraError::new(
                "fovy",
                format!("must be in (0, π), got {fovy}"),
            ));
        }
        Ok(PerspectiveCamera {
            position,
            forward,
            right,
            up,
            tan_half_fovy: (0.5 * f64::from(fovy)).tan(),
            aspect: validate::optional_positive("aspect", desc.aspect)?,
            region: validate::image_region(desc.image_region)?,
            clip: validate::clip_range(desc.near, desc.far)?,
            stereo_mode: desc.stereo_mode,
            interpupillary_distance: validate::non_negative(
                "interpupillaryDistance",
                desc.interpupillary_distance,
            )?,
            aperture_radius: validate::non_negative("apertureRadius", desc.aperture_radius)?,
            focus_distance: validate::positive("focusDistance", desc.focus_distance)?,
        })
    }
}

impl Camera for PerspectiveCamera {
    fn viewports(&self, width: u32, height: u32) -> Vec<EyeViewport> {
        self.stereo_mode.viewports(width, height)
    }

    /// Both eyes look along `direction` (parallel axes); their windows are the same rectangle
    /// on the plane at `focusDistance`, so each eye gets a shifted off-axis frustum and points
    /// on that plane have zero parallax.
    fn prepare(&self, eye: Eye, viewport_width: u32, viewport_height: u32) -> EyeRays {
        let aspect = self
            .aspect
            .unwrap_or_else(|| viewport_aspect(viewport_width, viewport_height));
        let half_height = self.tan_half_fovy * self.focus_distance;
        let half_width = aspect * half_height;
        let window_centre = self.position + self.forward * self.focus_distance;
        let eye_position =
            self.position + self.right * (self.interpupillary_distance * eye.ipd_fraction());
        EyeRays::pinhole(
            self.region,
            Pinhole {
                eye: eye_position,
                window_origin: window_centre - self.right * half_width - self.up * half_height,
                window_right: self.right * (2.0 * half_width),
                window_up: self.up * (2.0 * half_height),
                forward: self.forward,
                lens_right: self.right * self.aperture_radius,
                lens_up: self.up * self.aperture_radius,
                clip: self.clip,
            },
        )
        .with_stereo(StereoGeometry {
            ipd_fraction: eye.ipd_fraction(),
            baseline: self.right * self.interpupillary_distance,
            plane_point: window_centre,
            plane_normal: self.forward,
            horizontal: self.right,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::test_support::{angle_between, gl_window_depth, hit_plane, pixel_centres};
    use glam::Vec2;
    use glam::dcamera::rh::proj::opengl;
    use glam::dcamera::rh::view::look_to_mat4;

    fn camera(desc: PerspectiveDesc) -> PerspectiveCamera {
        PerspectiveCamera::new(&desc).unwrap()
    }

    #[test]
    fn default_camera_looks_down_minus_z_with_viewport_aspect() {
        let rays = camera(PerspectiveDesc::default()).prepare(Eye::Mono, 200, 100);
        let centre = rays.ray(0.5, 0.5, Vec2::ZERO);
        assert_eq!(centre.origin, Vec3::ZERO);
        assert!((centre.direction - Vec3::NEG_Z).length() < 1e-7);
        assert_eq!((centre.t_min, centre.t_max), (0.0, f32::INFINITY));
        let tan = (std::f64::consts::FRAC_PI_6).tan();
        let corner = rays.ray(1.0, 1.0, Vec2::ZERO).direction.as_dvec3();
        let expected = DVec3::new(2.0 * tan, tan, -1.0).normalize();
        assert!((corner - expected).length() < 1e-7, "{corner}");
        let lower_left = rays.ray(0.0, 0.0, Vec2::ZERO).direction.as_dvec3();
        let expected = DVec3::new(-2.0 * tan, -tan, -1.0).normalize();
        assert!((lower_left - expected).length() < 1e-7, "{lower_left}");
    }

    #[test]
    fn explicit_aspect_and_skewed_up_build_an_orthonormal_frame() {
        let rays = camera(PerspectiveDesc {
            position: Vec3::new(1.0, 2.0, 3.0),
            direction: Vec3::new(0.0, 0.0, 2.0),
            up: Vec3::new(0.0, 1.0, 1.0),
            fovy: 1.2,
            aspect: Some(0.5),
            ..PerspectiveDesc::default()
        })
        .prepare(Eye::Mono, 640, 480);
        // Looking along +z with up ≈ +y: right is −x.
        let tan = 0.6f64.tan();
        let right_edge = rays.ray(1.0, 0.5, Vec2::ZERO).direction.as_dvec3();
        let expected = DVec3::new(-0.5 * tan, 0.0, 1.0).normalize();
        assert!((right_edge - expected).length() < 1e-7, "{right_edge}");
        let top_edge = rays.ray(0.5, 1.0, Vec2::ZERO).direction.as_dvec3();
        let expected = DVec3::new(0.0, tan, 1.0).normalize();
        assert!((top_edge - expected).length() < 1e-7, "{top_edge}");
        assert_eq!(
            rays.ray(0.2, 0.9, Vec2::ZERO).origin,
            Vec3::new(1.0, 2.0, 3.0)
        );
    }

    #[test]
    fn near_and_far_clip_at_planes_perpendicular_to_the_view_axis() {
        let direction = Vec3::new(0.3, -0.2, -1.0);
        let rays = camera(PerspectiveDesc {
            direction,
            near: Some(0.25),
            far: Some(40.0),
            ..PerspectiveDesc::default()
        })
        .prepare(Eye::Mono, 64, 48);
        let forward = direction.normalize();
        for (_, _, s, t) in pixel_centres(16, 12) {
            let ray = rays.ray(s, t, Vec2::ZERO);
            let near_point = ray.origin + ray.direction * ray.t_min;
            let far_point = ray.origin + ray.direction * ray.t_max;
            assert!((near_point.dot(forward) - 0.25).abs() < 1e-6);
            assert!((far_point.dot(forward) - 40.0).abs() < 1e-4);
            assert!(ray.t_min > 0.25 || (s - 0.5).abs() < 0.1);
        }
    }

    #[test]
    fn aperture_zero_ignores_the_lens_sample() {
        let rays = camera(PerspectiveDesc::default()).prepare(Eye::Mono, 10, 10);
        let a = rays.ray(0.3, 0.7, Vec2::new(0.0, 0.0));
        let b = rays.ray(0.3, 0.7, Vec2::new(0.9, 0.1));
        assert_eq!(a, b);
    }

    #[test]
    fn depth_of_field_rays_leave_the_lens_and_meet_on_the_focus_plane() {
        let position = Vec3::new(0.5, 1.0, 4.0);
        let direction = Vec3::new(-0.1, 0.05, -1.0);
        let desc = PerspectiveDesc {
            position,
            direction,
            aperture_radius: 0.05,
            focus_distance: 3.0,
            near: Some(0.1),
            ..PerspectiveDesc::default()
        };
        let rays = camera(desc.clone()).prepare(Eye::Mono, 32, 32);
        let pinhole = camera(PerspectiveDesc {
            aperture_radius: 0.0,
            ..desc
        })
        .prepare(Eye::Mono, 32, 32);
        let forward = direction.as_dvec3().normalize();
        let focus_point = position.as_dvec3() + 3.0 * forward;
        let mut farthest: f64 = 0.0;
        for (s, t) in [(0.5, 0.5), (0.1, 0.8), (0.95, 0.05)] {
            let sharp = pinhole.ray(s, t, Vec2::ZERO);
            let (expected, _) = hit_plane(&sharp, focus_point, forward);
            for lens in [
                Vec2::new(0.0, 0.0),
                Vec2::new(0.99, 0.5),
                Vec2::new(0.3, 0.8),
                Vec2::splat(0.5),
            ] {
                let ray = rays.ray(s, t, lens);
                let offset = ray.origin.as_dvec3() - position.as_dvec3();
                assert!(offset.dot(forward).abs() < 1e-6, "lens not perpendicular");
                assert!(offset.length() <= 0.05 + 1e-6);
                farthest = farthest.max(offset.length());
                let (hit, _) = hit_plane(&ray, focus_point, forward);
                assert!((hit - expected).length() < 1e-5, "{hit} vs {expected}");
                // Near plane still 0.1 in front of the lens plane.
                let near_point = ray.origin + ray.direction * ray.t_min;
                assert!(((near_point - position).as_dvec3().dot(forward) - 0.1).abs() < 1e-6);
            }
            // The lens centre sample is the pinhole ray.
            let centre = rays.ray(s, t, Vec2::splat(0.5));
            assert!((centre.origin - sharp.origin).length() < 1e-7);
            assert!(angle_between(centre.direction, sharp.direction) < 1e-6);
        }
        assert!(
            farthest > 0.049,
            "lens samples should reach the aperture rim"
        );
    }

    /// Where along the row t = ½ the ray of `rays` passes through `point` (s in `[0,1]` units).
    fn row_coordinate(rays: &EyeRays, point: DVec3, normal: DVec3) -> f64 {
        let a = hit_plane(&rays.ray(0.0, 0.5, Vec2::ZERO), point, normal).0;
        let b = hit_plane(&rays.ray(1.0, 0.5, Vec2::ZERO), point, normal).0;
        (point - a).dot(b - a) / (b - a).length_squared()
    }

    #[test]
    fn stereo_disparity_is_ipd_times_one_minus_focus_over_depth() {
        let position = Vec3::new(0.2, 1.5, 0.7);
        let direction = Vec3::new(0.3, -0.2, -1.0);
        for (ipd, focus) in [(0.0635f32, 2.0f32), (0.07, 0.75)] {
            let desc = PerspectiveDesc {
                position,
                direction,
                fovy: 0.9,
                aspect: Some(1.5),
                stereo_mode: StereoMode::SideBySide,
                interpupillary_distance: ipd,
                focus_distance: focus,
                ..PerspectiveDesc::default()
            };
            let cam = camera(desc);
            let (width, height) = (300, 200);
            let left = cam.prepare(Eye::Left, width, height);
            let right = cam.prepare(Eye::Right, width, height);
            let forward = direction.as_dvec3().normalize();
            let window_width = 2.0 * f64::from(focus) * 0.45f64.tan() * 1.5;
            for depth in [0.5, 0.75, 2.0, 5.0, 50.0] {
                let point = position.as_dvec3() + depth * forward;
                let disparity = (row_coordinate(&right, point, forward)
                    - row_coordinate(&left, point, forward))
                    * window_width;
                let expected = f64::from(ipd) * (1.0 - f64::from(focus) / depth);
                assert!(
                    (disparity - expected).abs() < 1e-6,
                    "ipd {ipd} z0 {focus} z {depth}: {disparity} vs {expected}"
                );
            }
        }
    }

    #[test]
    fn stereo_eyes_sit_on_the_right_vector_with_parallel_axes() {
        let position = Vec3::new(-1.0, 1.7, 0.3);
        let cam = camera(PerspectiveDesc {
            position,
            direction: Vec3::X,
            stereo_mode: StereoMode::TopBottom,
            focus_distance: 2.5,
            ..PerspectiveDesc::default()
        });
        // Looking along +x with up +y: right is +z.
        let left = cam.prepare(Eye::Left, 40, 20);
        let right = cam.prepare(Eye::Right, 40, 20);
        let centre = cam.prepare(Eye::Mono, 40, 20);
        let ray = |rays: &EyeRays, s, t| rays.ray(s, t, Vec2::ZERO);
        let half_ipd = 0.5 * DEFAULT_INTERPUPILLARY_DISTANCE;
        assert!((ray(&left, 0.5, 0.5).origin - (position - Vec3::Z * half_ipd)).length() < 1e-7);
        assert!((ray(&right, 0.5, 0.5).origin - (position + Vec3::Z * half_ipd)).length() < 1e-7);
        let plane_point = position.as_dvec3() + DVec3::X * 2.5;
        for (_, _, s, t) in pixel_centres(9, 7) {
            // Every pixel of both eyes lands on the same point of the zero-parallax plane (a
            // toed-in pair would only agree at the centre).
            let (l, _) = hit_plane(&ray(&left, s, t), plane_point, DVec3::X);
            let (r, _) = hit_plane(&ray(&right, s, t), plane_point, DVec3::X);
            let (c, _) = hit_plane(&ray(&centre, s, t), plane_point, DVec3::X);
            assert!((l - r).length() < 1e-6 && (l - c).length() < 1e-6);
        }
        // Parallel axes: both eyes' depth axis is the camera's +x, so window depth ignores
        // the lateral offset (a toed-in eye's axis would be rotated towards the centre).
        for rays in [&left, &right] {
            let depth_near = rays.window_depth_at(position + Vec3::new(1.0, 0.3, 0.4));
            let depth_far = rays.window_depth_at(position + Vec3::new(1.0, -0.3, -0.4));
            assert_eq!(depth_near, depth_far, "window depth must depend on x only");
        }
    }

    #[test]
    fn stereo_viewports_assign_left_eye_left_and_top() {
        for (mode, left_is) in [
            (StereoMode::SideBySide, "left"),
            (StereoMode::TopBottom, "top"),
        ] {
            let cam = camera(PerspectiveDesc {
                stereo_mode: mode,
                ..PerspectiveDesc::default()
            });
            let viewports = cam.viewports(64, 48);
            assert_eq!(viewports.len(), 2);
            let (left, right) = (viewports[0], viewports[1]);
            assert_eq!((left.eye, right.eye), (Eye::Left, Eye::Right));
            match left_is {
                "left" => assert!(left.x + left.width <= right.x && left.y == right.y),
                _ => assert!(left.y >= right.y + right.height && left.x == right.x),
            }
            for viewport in viewports {
                let rays = cam.prepare(viewport.eye, viewport.width, viewport.height);
                let origin_x = rays.ray(0.5, 0.5, Vec2::ZERO).origin.x;
                let expected = match viewport.eye {
                    Eye::Left => -0.5 * DEFAULT_INTERPUPILLARY_DISTANCE,
                    _ => 0.5 * DEFAULT_INTERPUPILLARY_DISTANCE,
                };
                assert!((origin_x - expected).abs() < 1e-7);
            }
        }
        let single = camera(PerspectiveDesc {
            stereo_mode: StereoMode::Right,
            ..PerspectiveDesc::default()
        });
        assert_eq!(single.viewports(8, 8)[0].eye, Eye::Right);
    }

    #[test]
    fn window_depth_matches_opengl_perspective() {
        let position = Vec3::new(0.4, 1.6, 2.0);
        let direction = Vec3::new(-0.2, -0.1, -1.0);
        let (near, far) = (0.05f32, 80.0f32);
        let rays = camera(PerspectiveDesc {
            position,
            direction,
            fovy: 1.0,
            aspect: Some(1.25),
            near: Some(near),
            far: Some(far),
            ..PerspectiveDesc::default()
        })
        .prepare(Eye::Mono, 10, 8);
        let view = look_to_mat4(
            position.as_dvec3(),
            direction.as_dvec3().normalize(),
            DVec3::Y,
        );
        let proj = opengl::perspective(1.0, 1.25, f64::from(near), f64::from(far));
        for (s, t, distance) in [
            (0.5, 0.5, 0.05),
            (0.1, 0.9, 0.3),
            (0.7, 0.2, 3.0),
            (0.9, 0.9, 79.0),
        ] {
            let ray = rays.ray(s, t, Vec2::ZERO);
            let p = ray.origin + ray.direction * distance;
            let expected = gl_window_depth(view, proj, p.as_dvec3());
            let got = f64::from(rays.window_depth_at(p));
            assert!((got - expected).abs() < 2e-6, "{got} vs {expected}");
        }
        let first = rays.ray(0.3, 0.3, Vec2::ZERO);
        assert!(
            rays.window_depth_at(first.origin + first.direction * first.t_min)
                .abs()
                < 1e-5
        );
        let last = first.origin + first.direction * first.t_max;
        assert!((rays.window_depth_at(last) - 1.0).abs() < 1e-5);
        // Outside the clip range the value is clamped.
        assert_eq!(rays.window_depth_at(position - direction), 0.0);
    }

    #[test]
    fn window_depth_defaults_to_one_centimetre_near_and_infinite_far() {
        for near in [None, Some(0.0)] {
            let rays = camera(PerspectiveDesc {
                near,
                ..PerspectiveDesc::default()
            })
            .prepare(Eye::Mono, 10, 10);
            // 1 − n/z with n = 0.01.
            assert!((rays.window_depth_at(Vec3::new(0.3, -0.2, -4.0)) - 0.9975).abs() < 1e-6);
            assert!((rays.window_depth_at(Vec3::new(0.0, 0.0, -0.01))).abs() < 1e-6);
        }
    }

    #[test]
    fn depth_is_distance_from_the_eye() {
        let rays = camera(PerspectiveDesc {
            position: Vec3::new(1.0, 1.0, 1.0),
            near: Some(0.5),
            aperture_radius: 0.1,
            focus_distance: 2.0,
            ..PerspectiveDesc::default()
        })
        .prepare(Eye::Mono, 10, 10);
        let pinhole = rays.ray(0.2, 0.6, Vec2::splat(0.5));
        assert!((rays.depth(&pinhole, 3.25) - 3.25).abs() < 1e-6);
        let through_lens = rays.ray(0.2, 0.6, Vec2::new(0.9, 0.9));
        let hit = through_lens.origin + through_lens.direction * 3.0;
        let expected = (hit - Vec3::ONE).length();
        assert!((rays.depth(&through_lens, 3.0) - expected).abs() < 1e-6);
        assert!(
            (expected - 3.0).abs() > 1e-3,
            "lens offset should matter here"
        );
    }

    #[test]
    fn invalid_parameters_are_named() {
        let nan = f32::NAN;
        let cases: Vec<(PerspectiveDesc, &str)> = vec![
            (
                PerspectiveDesc {
                    position: Vec3::new(nan, 0.0, 0.0),
                    ..Default::default()
                },
                "position",
            ),
            (
                PerspectiveDesc {
                    direction: Vec3::ZERO,
                    ..Default::default()
                },
                "direction",
            ),
            (
                PerspectiveDesc {
                    direction: Vec3::new(0.0, f32::INFINITY, 0.0),
                    ..Default::default()
                },
                "direction",
            ),
            (
                PerspectiveDesc {
                    up: Vec3::ZERO,
                    ..Default::default()
                },
                "up",
            ),
            (
                PerspectiveDesc {
                    up: Vec3::new(0.0, 0.0, 3.0),
                    ..Default::default()
                },
                "up",
            ),
            (
                PerspectiveDesc {
                    fovy: 0.0,
                    ..Default::default()
                },
                "fovy",
            ),
            (
                PerspectiveDesc {
                    fovy: std::f32::consts::PI,
                    ..Default::default()
                },
                "fovy",
            ),
            (
                PerspectiveDesc {
                    fovy: -1.0,
                    ..Default::default()
                },
                "fovy",
            ),
            (
                PerspectiveDesc {
                    fovy: nan,
                    ..Default::default()
                },
                "fovy",
            ),
            (
                PerspectiveDesc {
                    aspect: Some(0.0),
                    ..Default::default()
                },
                "aspect",
            ),
            (
                PerspectiveDesc {
                    aspect: Some(-1.5),
                    ..Default::default()
                },
                "aspect",
            ),
            (
                PerspectiveDesc {
                    aspect: Some(f32::INFINITY),
                    ..Default::default()
                },
                "aspect",
            ),
            (
                PerspectiveDesc {
                    image_region: [0.0, 0.0, f32::INFINITY, 1.0],
                    ..Default::default()
                },
                "imageRegion",
            ),
            (
                PerspectiveDesc {
                    image_region: [0.5, 0.0, 0.5, 1.0],
                    ..Default::default()
                },
                "imageRegion",
            ),
            (
                PerspectiveDesc {
                    image_region: [0.0, nan, 1.0, 1.0],
                    ..Default::default()
                },
                "imageRegion",
            ),
            (
                PerspectiveDesc {
                    near: Some(-0.1),
                    ..Default::default()
                },
                "near",
            ),
            (
                PerspectiveDesc {
                    near: Some(nan),
                    ..Default::default()
                },
                "near",
            ),
            (
                PerspectiveDesc {
                    far: Some(0.0),
                    ..Default::default()
                },
                "far",
            ),
            (
                PerspectiveDesc {
                    far: Some(f32::INFINITY),
                    ..Default::default()
                },
                "far",
            ),
            (
                PerspectiveDesc {
                    near: Some(2.0),
                    far: Some(2.0),
                    ..Default::default()
                },
                "far",
            ),
            (
                PerspectiveDesc {
                    near: Some(3.0),
                    far: Some(2.0),
                    ..Default::default()
                },
                "far",
            ),
            (
                PerspectiveDesc {
                    interpupillary_distance: -0.06,
                    ..Default::default()
                },
                "interpupillaryDistance",
            ),
            (
                PerspectiveDesc {
                    aperture_radius: -0.1,
                    ..Default::default()
                },
                "apertureRadius",
            ),
            (
                PerspectiveDesc {
                    focus_distance: 0.0,
                    ..Default::default()
                },
                "focusDistance",
            ),
            (
                PerspectiveDesc {
                    focus_distance: nan,
                    ..Default::default()
                },
                "focusDistance",
            ),
        ];
        for (desc, parameter) in cases {
            let error = desc.validate().expect_err(parameter);
            assert_eq!(error.parameter, parameter, "{desc:?}: {error}");
            assert!(desc.build().is_err());
        }
        assert_eq!(PerspectiveDesc::default().validate(), Ok(()));
        assert!(
            PerspectiveDesc {
                near: Some(0.0),
                far: Some(1.0),
                ..Default::default()
            }
            .validate()
            .is_ok()
        );
    }
}
