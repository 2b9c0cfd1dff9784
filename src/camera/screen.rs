//! cavetrace "offAxis" camera (CAVETRACE_CAMERA_OFF_AXIS): a tracked eye looking at a physical
//! screen rectangle in CAVE space; each eye gets its exact off-axis frustum onto the screen.

use std::sync::Arc;

use glam::{DVec3, Vec3};

use super::offaxis::ScreenFrame;
use super::rays::{Blended, ClipRange, ImageRegion, Pinhole, StereoGeometry};
use super::validate;
use super::viewers::{ViewerDesc, ViewerSet};
use super::{
    Camera, CameraError, DEFAULT_INTERPUPILLARY_DISTANCE, Eye, EyeRays, EyeViewport, StereoMode,
};

/// Parameters of an offAxis camera as the application set them; `Default` holds the defaults,
/// `None` means unset (the three screen corners are required).
#[derive(Clone, Debug, PartialEq)]
pub struct OffAxisDesc {
    /// `screen.lowerLeft`, world space (meters).
    pub lower_left: Option<Vec3>,
    /// `screen.lowerRight`.
    pub lower_right: Option<Vec3>,
    /// `screen.upperRight`.
    pub upper_right: Option<Vec3>,
    /// Tracked eye; in stereo the head centre midway between the eyes.
    pub position: Vec3,
    /// The head's right vector (eyes sit at position ± right·ipd/2); unset means the screen's
    /// X axis.
    pub right: Option<Vec3>,
    pub stereo_mode: StereoMode,
    pub interpupillary_distance: f32,
    /// Clip distances from the eye, measured perpendicular to the screen plane (as the near and
    /// far of Pape's glFrustum).
    pub near: Option<f32>,
    pub far: Option<f32>,
    /// `[lo.x, lo.y, hi.x, hi.y]` in screen coordinates; may reach beyond `[0,1]²` and run
    /// backwards (a flip).
    pub image_region: [f32; 4],
    /// Several tracked viewers (`viewer.position` and the other `viewer*` parameters); when
    /// set, `position` and `right` are not used.
    pub viewers: Option<ViewerDesc>,
}

impl Default for OffAxisDesc {
    fn default() -> Self {
        OffAxisDesc {
            lower_left: None,
            lower_right: None,
            upper_right: None,
            position: Vec3::ZERO,
            right: None,
            stereo_mode: StereoMode::None,
            interpupillary_distance: DEFAULT_INTERPUPILLARY_DISTANCE,
            near: None,
            far: None,
            image_region: [0.0, 0.0, 1.0, 1.0],
            viewers: None,
        }
    }
}

impl OffAxisDesc {
    pub fn validate(&self) -> Result<(), CameraError> {
        OffAxisCamera::new(self).map(|_| ())
    }

    pub fn build(&self) -> Result<Arc<dyn Camera>, CameraError> {
        Ok(Arc::new(OffAxisCamera::new(self)?))
    }
}

/// A validated offAxis camera.
#[derive(Clone, Debug, PartialEq)]
pub struct OffAxisCamera {
    screen: ScreenFrame,
    position: DVec3,
    right: DVec3,
    stereo_mode: StereoMode,
    interpupillary_distance: f64,
    region: ImageRegion,
    clip: ClipRange,
    viewers: Option<Arc<ViewerSet>>,
}

impl OffAxisCamera {
    pub fn new(desc: &OffAxisDesc) -> Result<OffAxisCamera, CameraError> {
        let screen = validate::screen_corners(desc.lower_left, desc.lower_right, desc.upper_right)?;
        let interpupillary_distance =
            validate::non_negative("interpupillaryDistance", desc.interpupillary_distance)?;
        let region = validate::image_region(desc.image_region)?;
        let clip = validate::clip_range(desc.near, desc.far)?;
        if let Some(viewers) = &desc.viewers {
            let eye_offset = desc
                .stereo_mode
                .eyes()
                .iter()
                .map(|eye| (interpupillary_distance * eye.ipd_fraction()).abs())
                .fold(0.0, f64::max);
            let viewers = ViewerSet::new(viewers, screen, eye_offset)?;
            return Ok(OffAxisCamera {
                screen,
                position: DVec3::ZERO,
                right: screen.x,
                stereo_mode: desc.stereo_mode,
                interpupillary_distance,
                region,
                clip,
                viewers: Some(Arc::new(viewers)),
            });
        }
        let position = validate::finite_point("position", desc.position)?;
        let right = match desc.right {
            Some(right) => validate::unit_vector("right", right)?,
            None => screen.x,
        };
        let camera = OffAxisCamera {
            screen,
            position,
            right,
            stereo_mode: desc.stereo_mode,
            interpupillary_distance,
            region,
            clip,
            viewers: None,
        };
        for &eye in desc.stereo_mode.eyes() {
            let eye_position = camera.eye_position(eye);
            if let Err(error) = screen.eye_distance(eye_position) {
                let which = match eye {
                    Eye::Mono | Eye::View(_) => "the eye".to_string(),
                    Eye::Left | Eye::Right => format!("the {eye:?} eye at {eye_position}"),
                };
                return Err(CameraError::new("position", format!("{which}: {error}")));
            }
        }
        Ok(camera)
    }

    fn eye_position(&self, eye: Eye) -> DVec3 {
        self.position + self.right * (self.interpupillary_distance * eye.ipd_fraction())
    }
}

impl Camera for OffAxisCamera {
    fn viewports(&self, width: u32, height: u32) -> Vec<EyeViewport> {
        self.stereo_mode.viewports(width, height)
    }

    /// Rays from the eye through the screen point `ll + s'·(lr − ll) + t'·(ur − lr)`; the
    /// screen is the zero-parallax plane. Only the eyes of the stereo mode are checked to be in
    /// front of the screen; another eye requested here still gets rays through the screen.
    fn prepare(&self, eye: Eye, _viewport_width: u32, _viewport_height: u32) -> EyeRays {
        let screen = &self.screen;
        let stereo = StereoGeometry {
            ipd_fraction: eye.ipd_fraction(),
            baseline: self.right * self.interpupillary_distance,
            plane_point: screen.lower_left,
            plane_normal: screen.z,
            horizontal: screen.x,
        };
        if let Some(viewers) = &self.viewers {
            return EyeRays::blended(
                self.region,
                Blended {
                    window_origin: screen.lower_left,
                    window_right: screen.lower_right - screen.lower_left,
                    window_up: screen.upper_right - screen.lower_right,
                    forward: -screen.z,
                    clip: self.clip,
                    viewers: viewers.clone(),
                    eye_offset: self.interpupillary_distance * eye.ipd_fraction(),
                },
            )
            .with_stereo(stereo);
        }
        EyeRays::pinhole(
            self.region,
            Pinhole::through_screen(self.eye_position(eye), screen, self.clip),
        )
        .with_stereo(stereo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::offaxis::off_axis_matrices;
    use crate::camera::test_support::{Screen, gl_window_depth, hit_plane, pixel_centres, screens};
    use glam::Vec2;

    fn desc(screen: &Screen, position: DVec3) -> OffAxisDesc {
        OffAxisDesc {
            lower_left: Some(screen.ll.as_vec3()),
            lower_right: Some(screen.lr.as_vec3()),
            upper_right: Some(screen.ur.as_vec3()),
            position: position.as_vec3(),
            ..OffAxisDesc::default()
        }
    }

    /// Screen coordinates (s, t) of the point where the ray of `rays` through `point` meets
    /// the screen, found from three rays (rays of one eye meet a plane parallel to the screen
    /// in an affine image of the unit square).
    fn screen_coordinates(rays: &EyeRays, point: DVec3, screen: &Screen) -> (f64, f64) {
        let hit = |s, t| hit_plane(&rays.ray(s, t, Vec2::ZERO), point, screen.normal()).0;
        let origin = hit(0.0, 0.0);
        let along_s = hit(1.0, 0.0) - origin;
        let along_t = hit(0.0, 1.0) - origin;
        let offset = point - origin;
        (
            offset.dot(along_s) / along_s.length_squared(),
            offset.dot(along_t) / along_t.length_squared(),
        )
    }

    #[test]
    fn stereo_disparity_on_the_screen_is_ipd_times_one_minus_distance_ratio() {
        for screen in [screens()[0], screens()[1], screens()[3], screens()[5]] {
            let head = screen.local(0.1, -0.05, 1.2);
            let head_distance = 1.2;
            let width = screen.width_axis().length();
            let height = screen.height_axis().length();
            // Level head and a head rolled by 30° within the screen plane.
            let roll = 30f64.to_radians();
            let x = screen.width_axis().normalize();
            let y = screen.height_axis().normalize();
            for right in [None, Some(x * roll.cos() + y * roll.sin())] {
                let cam = OffAxisCamera::new(&OffAxisDesc {
                    right: right.map(|r| r.as_vec3()),
                    stereo_mode: StereoMode::SideBySide,
                    interpupillary_distance: 0.065,
                    ..desc(&screen, head)
                })
                .unwrap();
                let left = cam.prepare(Eye::Left, 50, 50);
                let right_eye = cam.prepare(Eye::Right, 50, 50);
                let eye_axis = right.unwrap_or(x);
                for distance in [0.6, 1.2, 3.0, 20.0] {
                    // A point straight ahead of the head, `distance` from it.
                    let point = head - screen.normal() * distance;
                    let (ls, lt) = screen_coordinates(&left, point, &screen);
                    let (rs, rt) = screen_coordinates(&right_eye, point, &screen);
                    let disparity = x * ((rs - ls) * width) + y * ((rt - lt) * height);
                    let expected = eye_axis * (0.065 * (1.0 - head_distance / distance));
                    assert!(
                        (disparity - expected).length() < 1e-6,
                        "{}: z {distance}: {disparity} vs {expected}",
                        screen.name
                    );
                }
            }
        }
    }

    #[test]
    fn both_eyes_see_each_pixel_at_the_same_screen_point() {
        let screen = screens()[4];
        let cam = OffAxisCamera::new(&OffAxisDesc {
            stereo_mode: StereoMode::TopBottom,
            ..desc(&screen, screen.local(-0.2, 0.3, 1.5))
        })
        .unwrap();
        let viewports = cam.viewports(30, 40);
        assert_eq!(viewports[0].eye, Eye::Left);
        assert!(viewports[0].y >= viewports[1].y + viewports[1].height);
        let [left, right] = [Eye::Left, Eye::Right].map(|eye| cam.prepare(eye, 30, 20));
        let x = screen.width_axis().normalize();
        let left_origin = left.ray(0.5, 0.5, Vec2::ZERO).origin.as_dvec3();
        let right_origin = right.ray(0.5, 0.5, Vec2::ZERO).origin.as_dvec3();
        assert!(
            ((right_origin - left_origin) - x * f64::from(DEFAULT_INTERPUPILLARY_DISTANCE))
                .length()
                < 1e-6
        );
        for (_, _, s, t) in pixel_centres(30, 20) {
            let (l, _) = hit_plane(&left.ray(s, t, Vec2::ZERO), screen.ll, screen.normal());
            let (r, _) = hit_plane(&right.ray(s, t, Vec2::ZERO), screen.ll, screen.normal());
            let expected = screen.point(f64::from(s), f64::from(t));
            assert!((l - expected).length() < 1e-5 && (r - expected).length() < 1e-5);
        }
    }

    #[test]
    fn near_far_and_window_depth_follow_papes_projection() {
        for screen in screens() {
            let head = screen.local(0.3, 0.2, 1.4);
            let cam = OffAxisCamera::new(&OffAxisDesc {
                near: Some(0.1),
                far: Some(60.0),
                stereo_mode: StereoMode::SideBySide,
                ..desc(&screen, head)
            })
            .unwrap();
            for eye in [Eye::Left, Eye::Right] {
                let rays = cam.prepare(eye, 20, 20);
                let eye_position = rays.ray(0.5, 0.5, Vec2::ZERO).origin.as_dvec3();
                let (view, proj) =
                    off_axis_matrices(screen.ll, screen.lr, screen.ur, eye_position, 0.1, 60.0)
                        .unwrap();
                for (s, t) in [(0.1, 0.2), (0.5, 0.5), (0.9, 0.7)] {
                    let ray = rays.ray(s, t, Vec2::ZERO);
                    let near_point = (ray.origin + ray.direction * ray.t_min).as_dvec3();
                    let far_point = (ray.origin + ray.direction * ray.t_max).as_dvec3();
                    let along_axis = |p: DVec3| (eye_position - p).dot(screen.normal());
                    assert!((along_axis(near_point) - 0.1).abs() < 1e-5);
                    assert!((along_axis(far_point) - 60.0).abs() < 1e-3);
                    for along in [1.01 * ray.t_min, 2.0 * ray.t_min, 1.4, 0.9 * ray.t_max] {
                        let p = ray.origin + ray.direction * along;
                        let expected = gl_window_depth(view, proj, p.as_dvec3());
                        let got = f64::from(rays.window_depth_at(p));
                        assert!((got - expected).abs() < 1e-5, "{got} vs {expected}");
                    }
                    assert_eq!(rays.depth(&ray, 2.0), 2.0);
                }
            }
        }
    }

    #[test]
    fn invalid_parameters_are_named() {
        let screen = screens()[0];
        let base = desc(&screen, DVec3::new(0.0, 1.5, 0.0));
        let v = Vec3::new;
        let cases: Vec<(OffAxisDesc, &str)> = vec![
            (
                OffAxisDesc {
                    lower_left: None,
                    ..base.clone()
                },
                "screen.lowerLeft",
            ),
            (
                OffAxisDesc {
                    lower_right: None,
                    ..base.clone()
                },
                "screen.lowerRight",
            ),
            (
                OffAxisDesc {
                    upper_right: None,
                    ..base.clone()
                },
                "screen.upperRight",
            ),
            (
                OffAxisDesc {
                    lower_left: Some(v(f32::NAN, 0.0, -1.5)),
                    ..base.clone()
                },
                "screen.lowerLeft",
            ),
            (
                OffAxisDesc {
                    lower_right: Some(v(1.5, f32::INFINITY, -1.5)),
                    ..base.clone()
                },
                "screen.lowerRight",
            ),
            (
                OffAxisDesc {
                    upper_right: Some(v(1.5, 3.0, f32::NAN)),
                    ..base.clone()
                },
                "screen.upperRight",
            ),
            // lowerRight on lowerLeft: zero width.
            (
                OffAxisDesc {
                    lower_right: base.lower_left,
                    ..base.clone()
                },
                "screen.lowerRight",
            ),
            // upperRight on lowerRight: zero height.
            (
                OffAxisDesc {
                    upper_right: base.lower_right,
                    ..base.clone()
                },
                "screen.upperRight",
            ),
            // Collinear corners.
            (
                OffAxisDesc {
                    upper_right: Some(v(4.5, 0.0, -1.5)),
                    ..base.clone()
                },
                "screen.upperRight",
            ),
            // 2° off a right angle.
            (
                OffAxisDesc {
                    upper_right: Some(v(1.5 + 3.0 * 2f32.to_radians().sin(), 3.0, -1.5)),
                    ..base.clone()
                },
                "screen.upperRight",
            ),
            (
                OffAxisDesc {
                    position: v(0.0, 1.5, -1.5),
                    ..base.clone()
                },
                "position",
            ),
            (
                OffAxisDesc {
                    position: v(0.0, 1.5, -2.0),
                    ..base.clone()
                },
                "position",
            ),
            (
                OffAxisDesc {
                    position: v(0.0, f32::NAN, 0.0),
                    ..base.clone()
                },
                "position",
            ),
            (
                OffAxisDesc {
                    right: Some(Vec3::ZERO),
                    ..base.clone()
                },
                "right",
            ),
            (
                OffAxisDesc {
                    right: Some(v(f32::NAN, 0.0, 0.0)),
                    ..base.clone()
                },
                "right",
            ),
            (
                OffAxisDesc {
                    interpupillary_distance: -0.01,
                    ..base.clone()
                },
                "interpupillaryDistance",
            ),
            (
                OffAxisDesc {
                    near: Some(-0.5),
                    ..base.clone()
                },
                "near",
            ),
            (
                OffAxisDesc {
                    near: Some(1.0),
                    far: Some(0.5),
                    ..base.clone()
                },
                "far",
            ),
            (
                OffAxisDesc {
                    image_region: [0.0, 0.0, 0.0, 0.0],
                    ..base.clone()
                },
                "imageRegion",
            ),
        ];
        for (desc, parameter) in cases {
            let error = desc.validate().expect_err(parameter);
            assert_eq!(error.parameter, parameter, "{desc:?}: {error}");
        }
        assert_eq!(base.validate(), Ok(()));
    }

    #[test]
    fn stereo_rejects_an_eye_behind_the_screen_that_mono_accepts() {
        let screen = screens()[0];
        // Head 2 cm in front of the wall, its right vector tilted 45° into the wall: the left
        // eye (−ipd/2 along right) ends up 2.2 cm behind the head, i.e. behind the wall.
        let tilted_right = Vec3::new(1.0, 0.0, 1.0);
        let close = OffAxisDesc {
            right: Some(tilted_right),
            ..desc(&screen, DVec3::new(0.0, 1.5, -1.48))
        };
        assert_eq!(close.validate(), Ok(()));
        assert_eq!(
            OffAxisDesc {
                stereo_mode: StereoMode::Right,
                ..close.clone()
            }
            .validate(),
            Ok(())
        );
        for mode in [
            StereoMode::SideBySide,
            StereoMode::TopBottom,
            StereoMode::Left,
        ] {
            let error = OffAxisDesc {
                stereo_mode: mode,
                ..close.clone()
            }
            .validate()
            .unwrap_err();
            assert_eq!(error.parameter, "position");
            assert!(error.message.contains("Left eye"), "{error}");
        }
    }
}
