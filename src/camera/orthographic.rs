//! ANARI "orthographic" camera (KHR_CAMERA_ORTHOGRAPHIC).

use std::sync::Arc;

use glam::{DVec3, Vec3};

use super::rays::{ClipRange, ImageRegion, Parallel};
use super::validate;
use super::{Camera, CameraError, Eye, EyeRays, EyeViewport, StereoMode, viewport_aspect};

/// Parameters of an orthographic camera as the application set them; `Default` holds the ANARI
/// defaults, `None` means unset.
#[derive(Clone, Debug, PartialEq)]
pub struct OrthographicDesc {
    /// Centre of the image plane, where the rays start.
    pub position: Vec3,
    pub direction: Vec3,
    pub up: Vec3,
    /// Height of the image plane in world units.
    pub height: f32,
    /// Width / height of the image plane; unset means the viewport's pixel aspect.
    pub aspect: Option<f32>,
    /// `[lo.x, lo.y, hi.x, hi.y]` of the full image; may reach beyond `[0,1]²` and run
    /// backwards (a flip).
    pub image_region: [f32; 4],
    /// Clip distances from the image plane along `direction`.
    pub near: Option<f32>,
    pub far: Option<f32>,
}

impl Default for OrthographicDesc {
    fn default() -> Self {
        OrthographicDesc {
            position: Vec3::ZERO,
            direction: Vec3::NEG_Z,
            up: Vec3::Y,
            height: 1.0,
            aspect: None,
            image_region: [0.0, 0.0, 1.0, 1.0],
            near: None,
            far: None,
        }
    }
}

impl OrthographicDesc {
    pub fn validate(&self) -> Result<(), CameraError> {
        OrthographicCamera::new(self).map(|_| ())
    }

    pub fn build(&self) -> Result<Arc<dyn Camera>, CameraError> {
        Ok(Arc::new(OrthographicCamera::new(self)?))
    }
}

/// A validated orthographic camera (mono only).
#[derive(Clone, Debug, PartialEq)]
pub struct OrthographicCamera {
    position: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    height: f64,
    aspect: Option<f64>,
    region: ImageRegion,
    clip: ClipRange,
}

impl OrthographicCamera {
    pub fn new(desc: &OrthographicDesc) -> Result<OrthographicCamera, CameraError> {
        let position = validate::finite_point("position", desc.position)?;
        let (forward, right, up) = validate::view_frame(desc.direction, desc.up)?;
        Ok(OrthographicCamera {
            position,
            forward,
            right,
            up,
            height: validate::positive("height", desc.height)?,
            aspect: validate::optional_positive("aspect", desc.aspect)?,
            region: validate::image_region(desc.image_region)?,
            clip: validate::clip_range(desc.near, desc.far)?,
        })
    }
}

impl Camera for OrthographicCamera {
    fn viewports(&self, width: u32, height: u32) -> Vec<EyeViewport> {
        StereoMode::None.viewports(width, height)
    }

    fn prepare(&self, _eye: Eye, viewport_width: u32, viewport_height: u32) -> EyeRays {
        let aspect = self
            .aspect
            .unwrap_or_else(|| viewport_aspect(viewport_width, viewport_height));
        let half_height = 0.5 * self.height;
        let half_width = aspect * half_height;
        EyeRays::parallel(
            self.region,
            Parallel {
                plane_origin: self.position - self.right * half_width - self.up * half_height,
                plane_right: self.right * (2.0 * half_width),
                plane_up: self.up * (2.0 * half_height),
                forward: self.forward,
                clip: self.clip,
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::test_support::{gl_window_depth, pixel_centres};
    use glam::Vec2;
    use glam::dcamera::rh::proj::opengl;
    use glam::dcamera::rh::view::look_to_mat4;

    fn rays(desc: OrthographicDesc, width: u32, height: u32) -> EyeRays {
        OrthographicCamera::new(&desc)
            .unwrap()
            .prepare(Eye::Mono, width, height)
    }

    #[test]
    fn rays_are_parallel_and_start_on_the_image_rectangle() {
        let position = Vec3::new(2.0, 1.0, -3.0);
        let r = rays(
            OrthographicDesc {
                position,
                direction: Vec3::new(0.0, -2.0, 0.0),
                up: Vec3::new(0.0, 0.0, -1.0),
                height: 4.0,
                ..OrthographicDesc::default()
            },
            300,
            200,
        );
        // right = direction × up = (0,−1,0) × (0,0,−1) = (1,0,0).
        for (_, _, s, t) in pixel_centres(30, 20) {
            let ray = r.ray(s, t, Vec2::new(0.3, 0.3));
            assert_eq!(ray.direction, Vec3::NEG_Y);
            let expected = position + Vec3::X * ((s - 0.5) * 6.0) + Vec3::NEG_Z * ((t - 0.5) * 4.0);
            assert!(
                (ray.origin - expected).length() < 1e-6,
                "{ray:?} vs {expected}"
            );
            assert_eq!((ray.t_min, ray.t_max), (0.0, f32::INFINITY));
        }
    }

    #[test]
    fn near_far_depth_and_window_depth_follow_gl_ortho() {
        let position = Vec3::new(0.5, 1.5, 2.0);
        let direction = Vec3::new(0.0, 0.0, -1.0);
        let r = rays(
            OrthographicDesc {
                position,
                direction,
                height: 2.0,
                aspect: Some(1.5),
                near: Some(0.5),
                far: Some(10.5),
                ..OrthographicDesc::default()
            },
            8,
            8,
        );
        let ray = r.ray(0.25, 0.75, Vec2::ZERO);
        assert_eq!((ray.t_min, ray.t_max), (0.5, 10.5));
        assert_eq!(r.depth(&ray, 4.0), 4.0);
        let view = look_to_mat4(position.as_dvec3(), direction.as_dvec3(), DVec3::Y);
        let proj = opengl::orthographic(-1.5, 1.5, -1.0, 1.0, 0.5, 10.5);
        for t in [0.5, 1.0, 5.0, 10.5] {
            let p = ray.origin + ray.direction * t;
            let expected = gl_window_depth(view, proj, p.as_dvec3());
            assert!((f64::from(r.window_depth_at(p)) - expected).abs() < 1e-6);
        }
        assert_eq!(r.window_depth_at(ray.origin + ray.direction * 5.5), 0.5);
        // Unset near/far: window depth spans 0 .. 1000 in front of the image plane.
        let unset = rays(OrthographicDesc::default(), 4, 4);
        assert_eq!(unset.window_depth_at(Vec3::new(0.1, 0.2, -250.0)), 0.25);
    }

    #[test]
    fn invalid_parameters_are_named() {
        let cases: Vec<(OrthographicDesc, &str)> = vec![
            (
                OrthographicDesc {
                    position: Vec3::new(0.0, f32::NAN, 0.0),
                    ..Default::default()
                },
                "position",
            ),
            (
                OrthographicDesc {
                    direction: Vec3::ZERO,
                    ..Default::default()
                },
                "direction",
            ),
            (
                OrthographicDesc {
                    up: Vec3::new(0.0, 0.0, -0.5),
                    ..Default::default()
                },
                "up",
            ),
            (
                OrthographicDesc {
                    up: Vec3::new(f32::NAN, 1.0, 0.0),
                    ..Default::default()
                },
                "up",
            ),
            (
                OrthographicDesc {
                    height: 0.0,
                    ..Default::default()
                },
                "height",
            ),
            (
                OrthographicDesc {
                    height: -2.0,
                    ..Default::default()
                },
                "height",
            ),
            (
                OrthographicDesc {
                    height: f32::INFINITY,
                    ..Default::default()
                },
                "height",
            ),
            (
                OrthographicDesc {
                    aspect: Some(0.0),
                    ..Default::default()
                },
                "aspect",
            ),
            (
                OrthographicDesc {
                    image_region: [0.2, 0.9, 0.1, 0.9],
                    ..Default::default()
                },
                "imageRegion",
            ),
            (
                OrthographicDesc {
                    near: Some(-1.0),
                    ..Default::default()
                },
                "near",
            ),
            (
                OrthographicDesc {
                    near: Some(5.0),
                    far: Some(1.0),
                    ..Default::default()
                },
                "far",
            ),
        ];
        for (desc, parameter) in cases {
            let error = desc.validate().expect_err(parameter);
            assert_eq!(error.parameter, parameter, "{desc:?}: {error}");
        }
        assert_eq!(OrthographicDesc::default().validate(), Ok(()));
    }
}
