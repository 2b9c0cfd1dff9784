//! ANARI "omnidirectional" camera (KHR_CAMERA_OMNIDIRECTIONAL, layout `equirectangular`) with
//! omni-directional stereo (KHR_CAMERA_STEREO) for 360° stereo video.
//!
//! Image point (s', t') in `[0,1]²` (after imageRegion; t' upwards, rows bottom to top) looks
//! at longitude λ = 2π(s' − ½) and latitude φ = π(t' − ½):
//! `direction = cos φ (sin λ · right + cos λ · forward) + sin φ · up`, with
//! `right = direction × up` and `up` made perpendicular to `direction`. So the image centre
//! looks along `direction`, the top row at `up`, the right half to the camera's right, and the
//! left and right edges meet behind the camera (the seam). The ANARI specification leaves the
//! mapping to "latitude/longitude"; this is OSPRay's panoramic camera, which ANARI's
//! `omnidirectional` camera is mapped to there (docs/cameras.md).
//!
//! imageRegion picks the part of that image the frame shows. ANARI allows regions beyond
//! `[0,1]²` and reversed ones (a flip), and leaves the omnidirectional image outside `[0,1]`
//! undefined: here the mapping simply continues (longitude wraps round, latitude goes on over
//! the pole).
//!
//! In stereo each column is seen by eyes on a circle of diameter `interpupillaryDistance`
//! around `position`, perpendicular to the column's longitude (omni-directional stereo, ODS):
//! the eye of fraction f (−½ left, +½ right) sits at
//! `position + f · ipd · (cos λ · right − sin λ · forward)`; the ray direction is the mono one.

use std::sync::Arc;

use glam::{DVec2, DVec3, Vec3};

use super::rays::ImageRegion;
use super::validate;
use super::{
    Camera, CameraError, CameraRay, DEFAULT_INTERPUPILLARY_DISTANCE, Eye, EyeRays, EyeViewport,
    StereoMode,
};

/// The `layout` values of KHR_CAMERA_OMNIDIRECTIONAL.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum OmnidirectionalLayout {
    #[default]
    Equirectangular,
}

impl OmnidirectionalLayout {
    pub const VALUES: [&'static str; 1] = ["equirectangular"];

    pub fn parse(value: &str) -> Option<OmnidirectionalLayout> {
        (value == "equirectangular").then_some(OmnidirectionalLayout::Equirectangular)
    }
}

/// Parameters of an omnidirectional camera as the application set them; `Default` holds the
/// ANARI defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct OmnidirectionalDesc {
    /// Camera position; in stereo the centre of the eyes' circle.
    pub position: Vec3,
    pub direction: Vec3,
    pub up: Vec3,
    /// `[lo.x, lo.y, hi.x, hi.y]` of the full image; may reach beyond `[0,1]²` and run
    /// backwards (a flip).
    pub image_region: [f32; 4],
    pub layout: OmnidirectionalLayout,
    pub stereo_mode: StereoMode,
    pub interpupillary_distance: f32,
}

impl Default for OmnidirectionalDesc {
    fn default() -> Self {
        OmnidirectionalDesc {
            position: Vec3::ZERO,
            direction: Vec3::NEG_Z,
            up: Vec3::Y,
            image_region: [0.0, 0.0, 1.0, 1.0],
            layout: OmnidirectionalLayout::Equirectangular,
            stereo_mode: StereoMode::None,
            interpupillary_distance: DEFAULT_INTERPUPILLARY_DISTANCE,
        }
    }
}

impl OmnidirectionalDesc {
    pub fn build(&self) -> Result<Arc<dyn Camera>, CameraError> {
        Ok(Arc::new(OmnidirectionalCamera::new(self)?))
    }
}

/// A validated omnidirectional camera.
#[derive(Clone, Debug, PartialEq)]
pub struct OmnidirectionalCamera {
    position: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    region: ImageRegion,
    stereo_mode: StereoMode,
    interpupillary_distance: f64,
}

impl OmnidirectionalCamera {
    pub fn new(desc: &OmnidirectionalDesc) -> Result<OmnidirectionalCamera, CameraError> {
        let OmnidirectionalLayout::Equirectangular = desc.layout;
        let (forward, right, up) = validate::view_frame(desc.direction, desc.up)?;
        Ok(OmnidirectionalCamera {
            position: validate::finite_point("position", desc.position)?,
            forward,
            right,
            up,
            region: validate::image_region(desc.image_region)?,
            stereo_mode: desc.stereo_mode,
            interpupillary_distance: validate::non_negative(
                "interpupillaryDistance",
                desc.interpupillary_distance,
            )?,
        })
    }
}

impl Camera for OmnidirectionalCamera {
    fn viewports(&self, width: u32, height: u32) -> Vec<EyeViewport> {
        self.stereo_mode.viewports(width, height)
    }

    fn prepare(&self, eye: Eye, _viewport_width: u32, _viewport_height: u32) -> EyeRays {
        EyeRays::equirectangular(
            self.region,
            EquirectangularRays {
                position: self.position,
                forward: self.forward,
                right: self.right,
                up: self.up,
                eye_offset: self.interpupillary_distance * eye.ipd_fraction(),
            },
        )
    }
}

/// The rays of one eye of an equirectangular camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct EquirectangularRays {
    position: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    /// This eye's signed distance from `position` on the ODS circle's tangent, in meters.
    eye_offset: f64,
}

impl EquirectangularRays {
    /// The ray of image point `st` (after imageRegion).
    #[inline]
    pub(crate) fn ray(&self, st: DVec2) -> CameraRay {
        let longitude = std::f64::consts::TAU * (st.x - 0.5);
        let latitude = std::f64::consts::PI * (st.y - 0.5);
        let (sin_lon, cos_lon) = longitude.sin_cos();
        let (sin_lat, cos_lat) = latitude.sin_cos();
        let direction =
            (self.right * sin_lon + self.forward * cos_lon) * cos_lat + self.up * sin_lat;
        let (origin, cyclopean) = if self.eye_offset == 0.0 {
            (self.position, None)
        } else {
            let tangent = self.right * cos_lon - self.forward * sin_lon;
            (
                self.position + tangent * self.eye_offset,
                Some(self.position.as_vec3()),
            )
        };
        CameraRay {
            origin: origin.as_vec3(),
            direction: direction.normalize().as_vec3(),
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
    use std::f64::consts::{PI, TAU};

    /// The closed form: the unit vector at `longitude` and `latitude` in the camera frame.
    fn expected(forward: DVec3, right: DVec3, up: DVec3, longitude: f64, latitude: f64) -> DVec3 {
        forward * longitude.cos() * latitude.cos()
            + right * longitude.sin() * latitude.cos()
            + up * latitude.sin()
    }

    fn rays(desc: OmnidirectionalDesc, eye: Eye, width: u32, height: u32) -> EyeRays {
        OmnidirectionalCamera::new(&desc)
            .unwrap()
            .prepare(eye, width, height)
    }

    #[test]
    fn every_pixel_centre_looks_at_its_longitude_and_latitude() {
        let (width, height) = (36, 18);
        let desc = OmnidirectionalDesc {
            position: Vec3::new(0.5, 1.6, -0.2),
            direction: Vec3::new(1.0, 0.0, -1.0),
            up: Vec3::new(0.0, 1.0, 0.1),
            ..OmnidirectionalDesc::default()
        };
        let forward = DVec3::new(1.0, 0.0, -1.0).normalize();
        let right = forward.cross(DVec3::new(0.0, 1.0, 0.1)).normalize();
        let up = right.cross(forward);
        let eye = rays(desc, Eye::Mono, width, height);
        for (x, y, s, t) in pixel_centres(width, height) {
            let ray = eye.ray(s, t, Vec2::ZERO);
            let longitude = TAU * ((f64::from(x) + 0.5) / f64::from(width) - 0.5);
            let latitude = PI * ((f64::from(y) + 0.5) / f64::from(height) - 0.5);
            let want = expected(forward, right, up, longitude, latitude);
            assert!(
                (ray.direction.as_dvec3() - want).length() < 1e-6,
                "pixel ({x}, {y}): {} instead of {want}",
                ray.direction
            );
            assert_eq!(ray.origin, Vec3::new(0.5, 1.6, -0.2));
            assert_eq!((ray.t_min, ray.t_max), (0.0, f32::INFINITY));
            assert_eq!(ray.cyclopean, None);
        }
    }

    #[test]
    fn centre_edges_and_poles_follow_the_extension_convention() {
        let eye = rays(OmnidirectionalDesc::default(), Eye::Mono, 8, 4);
        let at = |s: f32, t: f32| eye.ray(s, t, Vec2::ZERO).direction;
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-6;
        // The centre looks along direction (−z), the right quarter to the right (+x), the left
        // quarter to the left.
        assert!(close(at(0.5, 0.5), Vec3::NEG_Z));
        assert!(close(at(0.75, 0.5), Vec3::X));
        assert!(close(at(0.25, 0.5), Vec3::NEG_X));
        // Top and bottom rows are the poles: up and down.
        assert!(close(at(0.3, 1.0), Vec3::Y));
        assert!(close(at(0.9, 0.0), Vec3::NEG_Y));
        // Both edges meet behind the camera (the seam), and the pixels either side of it look
        // half a pixel's longitude to either side of +z.
        assert!(close(at(0.0, 0.5), Vec3::Z));
        assert!(close(at(1.0, 0.5), Vec3::Z));
        let half_pixel = PI / 8.0;
        let first = at(0.5 / 8.0, 0.5).as_dvec3();
        let last = at(7.5 / 8.0, 0.5).as_dvec3();
        assert!((first - DVec3::new(-half_pixel.sin(), 0.0, half_pixel.cos())).length() < 1e-6);
        assert!((last - DVec3::new(half_pixel.sin(), 0.0, half_pixel.cos())).length() < 1e-6);
    }

    #[test]
    fn image_region_crops_the_full_panorama_exactly() {
        let full = rays(OmnidirectionalDesc::default(), Eye::Mono, 64, 32);
        // Columns 16..48 and rows 8..24 of the 64×32 panorama.
        let crop = rays(
            OmnidirectionalDesc {
                image_region: [0.25, 0.25, 0.75, 0.75],
                ..OmnidirectionalDesc::default()
            },
            Eye::Mono,
            32,
            16,
        );
        for (x, y, s, t) in pixel_centres(32, 16) {
            let a = crop.ray(s, t, Vec2::ZERO);
            let b = full.ray(
                (x as f32 + 16.5) / 64.0,
                (y as f32 + 8.5) / 32.0,
                Vec2::ZERO,
            );
            assert!((a.direction - b.direction).length() < 1e-6, "({x}, {y})");
            assert_eq!(a.origin, b.origin);
        }
    }

    #[test]
    fn reversed_and_overhanging_image_regions_flip_and_continue_the_panorama() {
        let full = rays(OmnidirectionalDesc::default(), Eye::Mono, 64, 32);
        let with_region = |image_region| {
            rays(
                OmnidirectionalDesc {
                    image_region,
                    ..OmnidirectionalDesc::default()
                },
                Eye::Mono,
                64,
                32,
            )
        };
        // Upper < lower on x: the panorama mirrored left to right.
        let flipped = with_region([1.0, 0.0, 0.0, 1.0]);
        // [0.5, 1.5] on x: the right half, then past the seam the left half.
        let shifted = with_region([0.5, 0.0, 1.5, 1.0]);
        for (x, y, s, t) in pixel_centres(64, 32) {
            let mirrored = full.ray(1.0 - s, t, Vec2::ZERO).direction;
            let a = flipped.ray(s, t, Vec2::ZERO).direction;
            assert!((a - mirrored).length() < 1e-6, "flipped ({x}, {y})");
            // Looking along −z with up +y, mirroring left to right negates x.
            let b = full.ray(s, t, Vec2::ZERO).direction;
            assert!(
                (a - Vec3::new(-b.x, b.y, b.z)).length() < 1e-6,
                "({x}, {y})"
            );
            let wrapped = full.ray((s + 0.5).fract(), t, Vec2::ZERO).direction;
            let c = shifted.ray(s, t, Vec2::ZERO).direction;
            assert!((c - wrapped).length() < 1e-5, "shifted ({x}, {y})");
        }
    }

    #[test]
    fn stereo_eyes_sit_on_the_ods_circle_perpendicular_to_each_column() {
        let ipd = 0.064;
        let desc = OmnidirectionalDesc {
            position: Vec3::new(0.0, 1.7, 0.0),
            stereo_mode: StereoMode::TopBottom,
            interpupillary_distance: ipd,
            ..OmnidirectionalDesc::default()
        };
        let camera = OmnidirectionalCamera::new(&desc).unwrap();
        let viewports = camera.viewports(16, 16);
        assert_eq!(viewports[0].eye, Eye::Left);
        assert_eq!(viewports[0].y, 8, "left eye in the upper half");
        let centre = DVec3::new(0.0, 1.7, 0.0);
        for (eye, fraction) in [(Eye::Left, -0.5), (Eye::Right, 0.5)] {
            let rays = camera.prepare(eye, 16, 8);
            for (x, y, s, t) in pixel_centres(16, 8) {
                let ray = rays.ray(s, t, Vec2::ZERO);
                let longitude = TAU * ((f64::from(x) + 0.5) / 16.0 - 0.5);
                // Looking along −z with right +x: the tangent is (cos λ, 0, sin λ).
                let want = centre
                    + DVec3::new(longitude.cos(), 0.0, longitude.sin())
                        * (fraction * f64::from(ipd));
                assert!(
                    (ray.origin.as_dvec3() - want).length() < 1e-6,
                    "{eye:?} ({x}, {y}): {} instead of {want}",
                    ray.origin
                );
                // Horizontal, perpendicular to the column's direction, half the IPD away.
                let offset = ray.origin.as_dvec3() - centre;
                assert!(offset.y.abs() < 1e-7);
                let horizontal = DVec3::new(ray.direction.x.into(), 0.0, ray.direction.z.into());
                assert!(offset.dot(horizontal).abs() < 1e-7);
                assert!((offset.length() - 0.5 * f64::from(ipd)).abs() < 1e-7);
                assert_eq!(ray.cyclopean, Some(centre.as_vec3()));
            }
        }
        // The right eye is to the right of the left one looking along each column: (right −
        // left) × direction points up, as right × forward does.
        let left = camera.prepare(Eye::Left, 16, 8).ray(0.7, 0.5, Vec2::ZERO);
        let right = camera.prepare(Eye::Right, 16, 8).ray(0.7, 0.5, Vec2::ZERO);
        assert_eq!(left.direction, right.direction);
        let baseline = right.origin - left.origin;
        assert!(baseline.cross(left.direction).y > 0.0);
    }

    #[test]
    fn depth_is_the_distance_from_the_eye_and_window_depth_its_gl_mapping() {
        let desc = OmnidirectionalDesc {
            position: Vec3::new(0.0, 1.0, 0.0),
            stereo_mode: StereoMode::Left,
            interpupillary_distance: 0.5,
            ..OmnidirectionalDesc::default()
        };
        let rays = OmnidirectionalCamera::new(&desc)
            .unwrap()
            .prepare(Eye::Left, 32, 16);
        let ray = rays.ray(0.3, 0.6, Vec2::ZERO);
        let hit = ray.origin + ray.direction * 2.5;
        assert_eq!(rays.depth(&ray, 2.5), 2.5);
        let near = crate::camera::DEFAULT_WINDOW_DEPTH_NEAR;
        let expected = (1.0 - near / 2.5) as f32;
        assert!((rays.window_depth(&ray, hit) - expected).abs() < 1e-6);
        assert!(rays.parallax(&ray, hit).is_nan());
    }

    #[test]
    fn invalid_parameters_name_themselves() {
        let error = |desc: OmnidirectionalDesc| OmnidirectionalCamera::new(&desc).unwrap_err();
        let up_along_direction = OmnidirectionalDesc {
            up: Vec3::new(0.0, 0.0, -2.0),
            ..OmnidirectionalDesc::default()
        };
        assert_eq!(error(up_along_direction).parameter, "up");
        let bad_region = OmnidirectionalDesc {
            image_region: [0.5, 0.0, 0.5, 1.0],
            ..OmnidirectionalDesc::default()
        };
        assert_eq!(error(bad_region).parameter, "imageRegion");
        let not_finite = OmnidirectionalDesc {
            image_region: [0.0, 0.0, f32::NAN, 1.0],
            ..OmnidirectionalDesc::default()
        };
        assert_eq!(error(not_finite).parameter, "imageRegion");
        let bad_ipd = OmnidirectionalDesc {
            interpupillary_distance: -0.1,
            ..OmnidirectionalDesc::default()
        };
        assert_eq!(error(bad_ipd).parameter, "interpupillaryDistance");
    }
}
