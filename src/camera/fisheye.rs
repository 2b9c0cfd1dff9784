//! cavetrace "fisheye" camera: an azimuthal equidistant image of a dome (planetarium domes,
//! fulldome masters), seen from a tracked viewer.
//!
//! The dome is a sphere around `dome.center`. Its frame: `axis` (`dome.direction`, where the
//! image centre looks), `up` (`dome.up` made perpendicular to the axis, the image's top) and
//! `right = axis × up`; then both axis and up are turned by `dome.tilt` about `right`, the
//! axis towards the image's bottom edge (a planetarium's front with the default up).
//!
//! The image circle is the largest circle centred in the image (after imageRegion: the whole
//! image of which the region is a part). A point at distance r from its centre, with radius R,
//! at angle ψ from the image's right axis, maps to the dome point in direction
//! `cos α · axis + sin α (cos ψ · right + sin ψ · up)` from the centre, with α = (r/R)·fov/2.
//! That mapping is fixed by the dome; the viewer only moves the rays' origin: each ray starts
//! at the eye (`position`, or an eye beside it in stereo) and passes through the pixel's dome
//! point `dome.center + dome.radius · direction` (without `dome.radius`, the dome is infinitely
//! far and every eye looks along the direction itself). Pixels outside the image circle get an
//! empty ray (`t_max` 0): they show the renderer's background, with no depth and no ids.

use std::sync::Arc;

use glam::{DVec2, DVec3, Vec3};

use super::rays::ImageRegion;
use super::validate;
use super::{
    Camera, CameraError, CameraRay, DEFAULT_INTERPUPILLARY_DISTANCE, Eye, EyeRays, EyeViewport,
    StereoMode,
};

/// Parameters of a fisheye camera as the application set them; `Default` holds the defaults, a
/// 180° dome overhead with the front (−z) at the image's bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct FisheyeDesc {
    /// The tracked viewer (the head centre between the eyes in stereo).
    pub position: Vec3,
    pub dome_center: Vec3,
    /// `None`: the dome is infinitely far away.
    pub dome_radius: Option<f32>,
    pub dome_direction: Vec3,
    pub dome_up: Vec3,
    /// Radians; turns the axis towards the image's bottom edge.
    pub dome_tilt: f32,
    /// Full angle of the image circle in radians, in (0, 2π].
    pub fov: f32,
    /// The head's right vector for stereo; `None`: the dome's right vector.
    pub right: Option<Vec3>,
    pub image_region: [f32; 4],
    pub stereo_mode: StereoMode,
    pub interpupillary_distance: f32,
}

impl Default for FisheyeDesc {
    fn default() -> Self {
        FisheyeDesc {
            position: Vec3::ZERO,
            dome_center: Vec3::ZERO,
            dome_radius: None,
            dome_direction: Vec3::Y,
            dome_up: Vec3::Z,
            dome_tilt: 0.0,
            fov: std::f32::consts::PI,
            right: None,
            image_region: [0.0, 0.0, 1.0, 1.0],
            stereo_mode: StereoMode::None,
            interpupillary_distance: DEFAULT_INTERPUPILLARY_DISTANCE,
        }
    }
}

impl FisheyeDesc {
    pub fn build(&self) -> Result<Arc<dyn Camera>, CameraError> {
        Ok(Arc::new(FisheyeCamera::new(self)?))
    }
}

/// A validated fisheye camera.
#[derive(Clone, Debug, PartialEq)]
pub struct FisheyeCamera {
    position: DVec3,
    dome: Dome,
    head_right: DVec3,
    region: ImageRegion,
    stereo_mode: StereoMode,
    interpupillary_distance: f64,
}

/// The dome: its centre, radius (`None`: at infinity), tilted frame and half field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Dome {
    center: DVec3,
    radius: Option<f64>,
    axis: DVec3,
    right: DVec3,
    up: DVec3,
    half_fov: f64,
}

impl FisheyeCamera {
    pub fn new(desc: &FisheyeDesc) -> Result<FisheyeCamera, CameraError> {
        let position = validate::finite_point("position", desc.position)?;
        let center = validate::finite_point("dome.center", desc.dome_center)?;
        let radius = validate::optional_positive("dome.radius", desc.dome_radius)?;
        let (axis, right, up) = validate::named_view_frame(
            ("dome.direction", desc.dome_direction),
            ("dome.up", desc.dome_up),
        )?;
        let tilt = desc.dome_tilt;
        if !tilt.is_finite() {
            return Err(CameraError::new(
                "dome.tilt",
                format!("must be finite, got {tilt}"),
            ));
        }
        let (sin_tilt, cos_tilt) = f64::from(tilt).sin_cos();
        let fov = desc.fov;
        if !(fov.is_finite() && fov > 0.0 && f64::from(fov) <= std::f64::consts::TAU + 1e-6) {
            return Err(CameraError::new(
                "fov",
                format!("must be in (0, 2π], got {fov}"),
            ));
        }
        if let Some(radius) = radius {
            let distance = (position - center).length();
            if distance >= radius {
                return Err(CameraError::new(
                    "position",
                    format!(
                        "must be inside the dome: {distance} m from dome.center, dome.radius is \
                         {radius} m"
                    ),
                ));
            }
        }
        let head_right = match desc.right {
            Some(right) => validate::unit_vector("right", right)?,
            None => right,
        };
        Ok(FisheyeCamera {
            position,
            dome: Dome {
                center,
                radius,
                axis: axis * cos_tilt - up * sin_tilt,
                right,
                up: up * cos_tilt + axis * sin_tilt,
                half_fov: 0.5 * f64::from(fov).min(std::f64::consts::TAU),
            },
            head_right,
            region: validate::image_region(desc.image_region)?,
            stereo_mode: desc.stereo_mode,
            interpupillary_distance: validate::non_negative(
                "interpupillaryDistance",
                desc.interpupillary_distance,
            )?,
        })
    }
}

impl Camera for FisheyeCamera {
    fn viewports(&self, width: u32, height: u32) -> Vec<EyeViewport> {
        self.stereo_mode.viewports(width, height)
    }

    /// The image circle is inscribed in the whole image whose imageRegion part is this
    /// viewport, measured in the viewport's pixels (a circle on non-square frames too; a
    /// reversed region mirrors the image, so only the extent's size counts).
    fn prepare(&self, eye: Eye, viewport_width: u32, viewport_height: u32) -> EyeRays {
        let offset = self.interpupillary_distance * eye.ipd_fraction();
        let extent = self.region.extent().abs();
        let image = DVec2::new(
            f64::from(viewport_width.max(1)) / extent.x,
            f64::from(viewport_height.max(1)) / extent.y,
        );
        EyeRays::dome(
            self.region,
            DomeRays {
                eye: self.position + self.head_right * offset,
                head: (offset != 0.0).then_some(self.position),
                dome: self.dome,
                image,
                circle_radius: 0.5 * image.x.min(image.y),
            },
        )
    }
}

/// The rays of one eye of a fisheye camera for one viewport size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct DomeRays {
    eye: DVec3,
    /// The head between the eyes, for a stereo eye.
    head: Option<DVec3>,
    dome: Dome,
    /// Size of the whole image (before imageRegion) in viewport pixels, and its circle's radius.
    image: DVec2,
    circle_radius: f64,
}

impl DomeRays {
    /// The unit direction from the dome's centre of image point `st` (after imageRegion), or
    /// `None` outside the image circle.
    #[inline]
    pub(crate) fn dome_direction(&self, st: DVec2) -> Option<DVec3> {
        let offset = (st - DVec2::splat(0.5)) * self.image;
        let distance = offset.length();
        let r = distance / self.circle_radius;
        if r > 1.0 {
            return None;
        }
        let dome = &self.dome;
        let (sin_angle, cos_angle) = (r * dome.half_fov).sin_cos();
        let across = if distance > 0.0 {
            (dome.right * offset.x + dome.up * offset.y) / distance
        } else {
            DVec3::ZERO
        };
        Some(dome.axis * cos_angle + across * sin_angle)
    }

    /// The ray of image point `st` (after imageRegion).
    #[inline]
    pub(crate) fn ray(&self, st: DVec2) -> CameraRay {
        let cyclopean = self.head.map(|head| head.as_vec3());
        let Some(direction) = self.dome_direction(st) else {
            return CameraRay {
                origin: self.eye.as_vec3(),
                direction: self.dome.axis.as_vec3(),
                t_min: 0.0,
                t_max: 0.0,
                cyclopean,
            };
        };
        let direction = match self.dome.radius {
            Some(radius) => (self.dome.center + direction * radius - self.eye).normalize(),
            None => direction,
        };
        CameraRay {
            origin: self.eye.as_vec3(),
            direction: direction.as_vec3(),
            t_min: 0.0,
            t_max: f32::INFINITY,
            cyclopean,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::test_support::pixel_centres;
    use glam::Vec2;
    use std::f64::consts::{FRAC_PI_2, PI, TAU};

    fn camera(desc: FisheyeDesc) -> FisheyeCamera {
        FisheyeCamera::new(&desc).unwrap()
    }

    fn angle(a: DVec3, b: DVec3) -> f64 {
        a.normalize().dot(b.normalize()).clamp(-1.0, 1.0).acos()
    }

    #[test]
    fn centre_pixel_looks_along_the_dome_axis() {
        let rays = camera(FisheyeDesc::default()).prepare(Eye::Mono, 33, 33);
        let ray = rays.ray(0.5, 0.5, Vec2::ZERO);
        assert!(
            (ray.direction - Vec3::Y).length() < 1e-7,
            "{}",
            ray.direction
        );
        assert_eq!(ray.origin, Vec3::ZERO);
        assert_eq!((ray.t_min, ray.t_max), (0.0, f32::INFINITY));
    }

    #[test]
    fn angle_from_the_axis_grows_linearly_with_the_radius_and_keeps_its_azimuth() {
        for (fov, width, height) in [(PI, 41, 41), (TAU, 40, 30), (1.3, 30, 52)] {
            let rays = camera(FisheyeDesc {
                fov: fov as f32,
                ..FisheyeDesc::default()
            })
            .prepare(Eye::Mono, width, height);
            let circle = 0.5 * f64::from(width.min(height));
            let mut inside = 0;
            for (x, y, s, t) in pixel_centres(width, height) {
                let ray = rays.ray(s, t, Vec2::ZERO);
                let px = f64::from(x) + 0.5 - 0.5 * f64::from(width);
                let py = f64::from(y) + 0.5 - 0.5 * f64::from(height);
                let r = px.hypot(py);
                if r > circle {
                    assert_eq!(ray.t_max, 0.0, "({x}, {y}) is outside the circle");
                    continue;
                }
                inside += 1;
                let direction = ray.direction.as_dvec3();
                let want = r / circle * 0.5 * fov;
                let got = angle(direction, DVec3::Y);
                assert!((got - want).abs() < 1e-6, "({x}, {y}): {got} vs {want}");
                // Image right is +x, image up is +z (the back of the dome).
                if r > 0.5 && want < PI - 1e-3 {
                    let azimuth = direction.z.atan2(direction.x);
                    let expected = py.atan2(px);
                    let difference = (azimuth - expected + PI).rem_euclid(TAU) - PI;
                    assert!(difference.abs() < 1e-5, "({x}, {y}) azimuth {azimuth}");
                }
                assert_eq!(ray.t_max, f32::INFINITY);
            }
            assert!(inside > 0);
        }
    }

    #[test]
    fn pixels_outside_the_image_circle_get_empty_rays() {
        let rays = camera(FisheyeDesc::default()).prepare(Eye::Mono, 20, 20);
        // The corners are outside the circle, the middle of each edge just inside.
        for (s, t) in [(0.025, 0.025), (0.975, 0.975), (0.025, 0.975)] {
            let ray = rays.ray(s, t, Vec2::ZERO);
            assert_eq!((ray.t_min, ray.t_max), (0.0, 0.0));
            assert!(ray.direction.is_normalized());
        }
        for (s, t) in [(0.025, 0.5), (0.5, 0.975)] {
            let ray = rays.ray(s, t, Vec2::ZERO);
            assert_eq!(ray.t_max, f32::INFINITY);
        }
    }

    #[test]
    fn tilt_rotates_every_ray_about_the_dome_right_vector() {
        let tilt = 0.5f64;
        let flat = camera(FisheyeDesc::default()).prepare(Eye::Mono, 24, 24);
        let tilted = camera(FisheyeDesc {
            dome_tilt: tilt as f32,
            ..FisheyeDesc::default()
        })
        .prepare(Eye::Mono, 24, 24);
        // Right is +x; the axis (+y) turns towards the image bottom (−z, the front): a turn
        // of −tilt about +x.
        let rotation = glam::DQuat::from_axis_angle(DVec3::X, -tilt);
        for (x, y, s, t) in pixel_centres(24, 24) {
            let a = flat.ray(s, t, Vec2::ZERO);
            let b = tilted.ray(s, t, Vec2::ZERO);
            assert_eq!(a.t_max, b.t_max);
            let want = rotation * a.direction.as_dvec3();
            assert!(
                (b.direction.as_dvec3() - want).length() < 1e-6,
                "({x}, {y})"
            );
        }
        let centre = tilted.ray(0.5, 0.5, Vec2::ZERO).direction.as_dvec3();
        assert!((centre - DVec3::new(0.0, tilt.cos(), -tilt.sin())).length() < 1e-7);
        // A quarter turn puts the axis at the front (−z) and the zenith at the image's top.
        let front = camera(FisheyeDesc {
            dome_tilt: FRAC_PI_2 as f32,
            ..FisheyeDesc::default()
        })
        .prepare(Eye::Mono, 24, 24);
        let top = front.ray(0.5, 23.5 / 24.0, Vec2::ZERO).direction.as_dvec3();
        let angle = FRAC_PI_2 * 11.5 / 12.0;
        assert!((top - DVec3::new(0.0, angle.sin(), -angle.cos())).length() < 1e-6);
        assert!((front.ray(0.5, 0.5, Vec2::ZERO).direction - Vec3::NEG_Z).length() < 1e-6);
    }

    #[test]
    fn viewer_off_centre_sees_the_same_dome_point_through_each_pixel() {
        let center = DVec3::new(0.0, 0.0, 0.0);
        let radius = 7.5;
        let centred = camera(FisheyeDesc {
            dome_radius: Some(radius as f32),
            ..FisheyeDesc::default()
        })
        .prepare(Eye::Mono, 32, 32);
        let viewer = Vec3::new(1.2, 1.6, 2.5);
        let tracked = camera(FisheyeDesc {
            position: viewer,
            dome_radius: Some(radius as f32),
            dome_tilt: 0.0,
            ..FisheyeDesc::default()
        })
        .prepare(Eye::Mono, 32, 32);
        for (x, y, s, t) in pixel_centres(32, 32) {
            let a = centred.ray(s, t, Vec2::ZERO);
            let b = tracked.ray(s, t, Vec2::ZERO);
            assert_eq!(a.t_max == 0.0, b.t_max == 0.0);
            if a.t_max == 0.0 {
                continue;
            }
            let dome_point = center + a.direction.as_dvec3() * radius;
            assert_eq!(b.origin, viewer);
            // The tracked ray passes through the centred ray's dome point.
            let to_point = dome_point - b.origin.as_dvec3();
            let miss = to_point.cross(b.direction.as_dvec3()).length();
            assert!(miss < 1e-5, "({x}, {y}) misses by {miss} m");
            assert!(to_point.dot(b.direction.as_dvec3()) > 0.0);
        }
    }

    #[test]
    fn stereo_eyes_straddle_the_viewer_along_the_right_vector() {
        let desc = FisheyeDesc {
            position: Vec3::new(0.0, 1.2, 0.0),
            dome_radius: Some(6.0),
            stereo_mode: StereoMode::SideBySide,
            interpupillary_distance: 0.06,
            right: Some(Vec3::new(0.0, 0.0, 2.0)),
            ..FisheyeDesc::default()
        };
        let camera = camera(desc);
        let left = camera.prepare(Eye::Left, 16, 16).ray(0.3, 0.6, Vec2::ZERO);
        let right = camera.prepare(Eye::Right, 16, 16).ray(0.3, 0.6, Vec2::ZERO);
        assert!((left.origin - Vec3::new(0.0, 1.2, -0.03)).length() < 1e-7);
        assert!((right.origin - Vec3::new(0.0, 1.2, 0.03)).length() < 1e-7);
        assert_eq!(left.cyclopean, Some(Vec3::new(0.0, 1.2, 0.0)));
        // Both eyes' rays meet on the dome (zero parallax there).
        let (l, r) = (left.origin.as_dvec3(), right.origin.as_dvec3());
        let (dl, dr) = (left.direction.as_dvec3(), right.direction.as_dvec3());
        let on_sphere = |o: DVec3, d: DVec3| {
            let b = o.dot(d);
            o + d * (-b + (b * b - o.length_squared() + 36.0).sqrt())
        };
        assert!((on_sphere(l, dl) - on_sphere(r, dr)).length() < 1e-5);
    }

    #[test]
    fn infinite_dome_keeps_directions_for_every_eye() {
        let camera = camera(FisheyeDesc {
            position: Vec3::new(0.4, 1.0, 0.0),
            stereo_mode: StereoMode::SideBySide,
            ..FisheyeDesc::default()
        });
        let mono = FisheyeCamera::new(&FisheyeDesc::default())
            .unwrap()
            .prepare(Eye::Mono, 16, 16);
        let left = camera.prepare(Eye::Left, 16, 16);
        for (_, _, s, t) in pixel_centres(16, 16) {
            assert_eq!(
                left.ray(s, t, Vec2::ZERO).direction,
                mono.ray(s, t, Vec2::ZERO).direction
            );
        }
    }

    #[test]
    fn image_region_crops_the_full_dome_image_exactly() {
        // A region of another aspect than the image: the circle stays the whole image's.
        let full = camera(FisheyeDesc::default()).prepare(Eye::Mono, 40, 40);
        let crop = camera(FisheyeDesc {
            image_region: [0.5, 0.25, 1.0, 1.0],
            ..FisheyeDesc::default()
        })
        .prepare(Eye::Mono, 20, 30);
        for (x, y, s, t) in pixel_centres(20, 30) {
            let a = crop.ray(s, t, Vec2::ZERO);
            let b = full.ray(
                (x as f32 + 20.5) / 40.0,
                (y as f32 + 10.5) / 40.0,
                Vec2::ZERO,
            );
            assert_eq!(a.t_max, b.t_max, "({x}, {y})");
            assert!((a.direction - b.direction).length() < 1e-6, "({x}, {y})");
        }
    }

    #[test]
    fn invalid_parameters_name_themselves() {
        let defaults = FisheyeDesc::default;
        let cases = [
            (
                FisheyeDesc {
                    fov: 7.0,
                    ..defaults()
                },
                "fov",
            ),
            (
                FisheyeDesc {
                    dome_up: Vec3::new(0.0, -3.0, 0.0),
                    ..defaults()
                },
                "dome.up",
            ),
            (
                FisheyeDesc {
                    dome_direction: Vec3::ZERO,
                    ..defaults()
                },
                "dome.direction",
            ),
            (
                FisheyeDesc {
                    dome_radius: Some(0.0),
                    ..defaults()
                },
                "dome.radius",
            ),
            (
                FisheyeDesc {
                    dome_tilt: f32::NAN,
                    ..defaults()
                },
                "dome.tilt",
            ),
            (
                FisheyeDesc {
                    right: Some(Vec3::ZERO),
                    ..defaults()
                },
                "right",
            ),
            (
                FisheyeDesc {
                    position: Vec3::new(0.0, 0.0, 9.0),
                    dome_radius: Some(5.0),
                    ..defaults()
                },
                "position",
            ),
        ];
        for (desc, parameter) in cases {
            assert_eq!(FisheyeCamera::new(&desc).unwrap_err().parameter, parameter);
        }
    }
}
