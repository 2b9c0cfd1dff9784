//! The `lightField` camera (ANARI_CAVETRACE_CAMERA_LIGHT_FIELD): one ray per R, G and B
//! subpixel of a slanted-lenticular light-field display, from the display's calibration.
//!
//! With u = (x+½)/W, v = (y+½)/H (rows from the bottom): tilt = −H/(W·slope),
//! p = pitch·(W/dpi)·cos(atan2(1, slope)), subp = p/(3W); subpixel k (0, 1, 2 from the left) of
//! pixel (x, y) shows view fraction f = frac((u + v·tilt)·p − center + k·subp), 1 − f with
//! `invView`; `views` = N > 0 snaps it to the nearest of the views (i+½)/N. View f looks from
//! E(f) = S + d·n + d·tan((f − ½)·viewCone)·X (S the screen's centre, n its normal towards the
//! viewer, X its unit x axis, d the viewing distance), and the subpixel's ray runs from E(f)
//! through the subpixel's centre LL + ((x + (k+½)/3)/W)(LR−LL) + ((y+½)/H)(UR−LR) (mirrored by
//! `flipImageX`/`flipImageY`). Its shading gives that subpixel's colour channel: R, G, B left to
//! right, B, G, R with `flipSubpixels`. This follows the lenticular interleaving shaders
//! published for such displays, which compute the same view index per subpixel from the same
//! calibration values (pitch, slope, center, dpi, invView, flipSubp) before looking up a quilt.

use std::sync::Arc;

use glam::{DVec2, DVec3, Vec3};

use super::offaxis::ScreenFrame;
use super::rays::{BLOCK_RAYS, BlockRays, ClipRange, EyeRays, ImageRegion, Pinhole, with_clip};
use super::validate;
use super::{Camera, CameraError, Eye, EyeViewport, PixelSet, StereoMode};

/// Most views a quilt may have (quilts of light-field displays have 45 to 100).
const MAX_QUILT_VIEWS: u32 = 4096;

/// Half the vertical field of view the default viewing distance gives the screen: the usual
/// 14° of light-field displays.
const DEFAULT_HALF_FIELD_OF_VIEW_DEGREES: f64 = 7.0;

/// Parameters of a lightField camera as the application set them.
#[derive(Clone, Debug, PartialEq)]
pub struct LightFieldDesc {
    pub lower_left: Option<Vec3>,
    pub lower_right: Option<Vec3>,
    pub upper_right: Option<Vec3>,
    pub pitch: f32,
    pub slope: f32,
    pub center: f32,
    pub dpi: f32,
    pub inv_view: bool,
    /// Degrees.
    pub view_cone: f32,
    pub flip_image_x: bool,
    pub flip_image_y: bool,
    pub flip_subpixels: bool,
    pub viewing_distance: Option<f32>,
    pub views: u32,
    /// Columns × rows of a quilt of whole views; [0, 0] traces one ray per subpixel.
    pub quilt: [u32; 2],
}

impl Default for LightFieldDesc {
    /// The sample calibration of a 2560×1600 panel.
    fn default() -> LightFieldDesc {
        LightFieldDesc {
            lower_left: None,
            lower_right: None,
            upper_right: None,
            pitch: 49.82,
            slope: 5.04,
            center: 0.177,
            dpi: 338.0,
            inv_view: false,
            view_cone: 40.0,
            flip_image_x: false,
            flip_image_y: false,
            flip_subpixels: false,
            viewing_distance: None,
            views: 0,
            quilt: [0, 0],
        }
    }
}

impl LightFieldDesc {
    pub fn build(&self) -> Result<Arc<dyn Camera>, CameraError> {
        Ok(Arc::new(LightFieldCamera::new(self)?))
    }
}

/// A validated lightField camera.
#[derive(Clone, Debug, PartialEq)]
pub struct LightFieldCamera {
    screen: ScreenFrame,
    desc: LightFieldDesc,
    viewing_distance: f64,
}

impl LightFieldCamera {
    pub fn new(desc: &LightFieldDesc) -> Result<LightFieldCamera, CameraError> {
        let screen = validate::screen_corners(desc.lower_left, desc.lower_right, desc.upper_right)?;
        let finite = |name: &str, value: f32| {
            if value.is_finite() {
                Ok(f64::from(value))
            } else {
                Err(CameraError::new(
                    name,
                    format!("must be finite, got {value}"),
                ))
            }
        };
        finite("center", desc.center)?;
        if finite("slope", desc.slope)? == 0.0 {
            return Err(CameraError::new("slope", "must not be 0"));
        }
        validate::positive("pitch", desc.pitch)?;
        validate::positive("dpi", desc.dpi)?;
        let cone = finite("viewCone", desc.view_cone)?;
        if !(cone > 0.0 && cone < 180.0) {
            return Err(CameraError::new(
                "viewCone",
                format!("must be in (0°, 180°), got {cone}"),
            ));
        }
        let [columns, rows] = desc.quilt;
        if (columns == 0) != (rows == 0)
            || u64::from(columns) * u64::from(rows) > u64::from(MAX_QUILT_VIEWS)
        {
            return Err(CameraError::new(
                "quilt",
                format!(
                    "must be 0 × 0 (no quilt) or columns × rows of 1 to {MAX_QUILT_VIEWS} views, \
                     got {columns} × {rows}"
                ),
            ));
        }
        let height = (screen.upper_right - screen.lower_right).length();
        let viewing_distance = match desc.viewing_distance {
            Some(distance) => validate::positive("viewingDistance", distance)?,
            None => 0.5 * height / DEFAULT_HALF_FIELD_OF_VIEW_DEGREES.to_radians().tan(),
        };
        Ok(LightFieldCamera {
            screen,
            desc: desc.clone(),
            viewing_distance,
        })
    }
}

impl LightFieldCamera {
    /// The eye of view fraction f: E(f) = S + d·n + d·tan((f − ½)·viewCone)·X, rounded as an
    /// application's FLOAT32 eye position would be.
    pub(crate) fn view_eye(view_centre: DVec3, view_x: DVec3, view_cone: f64, f: f64) -> DVec3 {
        let eye = view_centre + view_x * ((f - 0.5) * view_cone).tan();
        eye.as_vec3().as_dvec3()
    }

    fn view_centre(&self) -> DVec3 {
        let s = &self.screen;
        let centre = s.lower_left
            + 0.5 * (s.lower_right - s.lower_left)
            + 0.5 * (s.upper_right - s.lower_right);
        centre + s.z * self.viewing_distance
    }

    /// Quilt view k of n: the exact off-axis frustum of the screen from E((k+½)/n).
    fn quilt_view(&self, k: u32, n: u32) -> EyeRays {
        let s = &self.screen;
        let f = (f64::from(k) + 0.5) / f64::from(n);
        let eye = LightFieldCamera::view_eye(
            self.view_centre(),
            s.x * self.viewing_distance,
            f64::from(self.desc.view_cone).to_radians(),
            f,
        );
        EyeRays::pinhole(
            ImageRegion::from_box([0.0, 0.0, 1.0, 1.0]),
            Pinhole::through_screen(eye, s, ClipRange::default()),
        )
    }
}

impl Camera for LightFieldCamera {
    /// One viewport, or a quilt's: view k = row·columns + column, column from the left, row
    /// from the bottom; view rectangles split the frame as evenly as whole pixels allow.
    fn viewports(&self, width: u32, height: u32) -> Vec<EyeViewport> {
        let [columns, rows] = self.desc.quilt;
        if columns == 0 {
            return StereoMode::None.viewports(width, height);
        }
        let split = |size: u32, parts: u32, i: u32| {
            (u64::from(size) * u64::from(i) / u64::from(parts)) as u32
        };
        (0..rows)
            .flat_map(|row| (0..columns).map(move |column| (row, column)))
            .map(|(row, column)| {
                let (x, y) = (split(width, columns, column), split(height, rows, row));
                EyeViewport {
                    eye: Eye::View(row * columns + column),
                    x,
                    y,
                    width: split(width, columns, column + 1) - x,
                    height: split(height, rows, row + 1) - y,
                    pixels: PixelSet::All,
                }
            })
            .collect()
    }

    /// The calibration turned into what every subpixel ray needs, for a `width`×`height` panel;
    /// or, for a quilt, the view's whole-frame rays.
    fn prepare(&self, eye: Eye, width: u32, height: u32) -> EyeRays {
        let [columns, rows] = self.desc.quilt;
        if let Eye::View(k) = eye
            && columns > 0
        {
            return self.quilt_view(k.min(columns * rows - 1), columns * rows);
        }
        let d = &self.desc;
        let (w, h) = (f64::from(width.max(1)), f64::from(height.max(1)));
        let slope = f64::from(d.slope);
        let p = f64::from(d.pitch) * (w / f64::from(d.dpi)) * 1f64.atan2(slope).cos();
        let s = &self.screen;
        EyeRays::light_field(
            ImageRegion::from_box([0.0, 0.0, 1.0, 1.0]),
            LightFieldRays {
                window_origin: s.lower_left,
                window_right: s.lower_right - s.lower_left,
                window_up: s.upper_right - s.lower_right,
                forward: -s.z,
                clip: ClipRange::default(),
                tilt: -h / (w * slope),
                pitch: p,
                subpixel: p / (3.0 * w),
                center: f64::from(d.center),
                inv_view: d.inv_view,
                views: d.views,
                view_cone: f64::from(d.view_cone).to_radians(),
                flip_x: d.flip_image_x,
                flip_y: d.flip_image_y,
                flip_subpixels: d.flip_subpixels,
                view_centre: self.view_centre(),
                view_x: s.x * self.viewing_distance,
                view_eyes: Vec::new(),
            }
            .with_view_eyes(),
        )
    }
}

/// Rays of a light-field display's subpixels (`lightField` camera): each from the eye of its
/// view fraction through its subpixel's centre (see the module's documentation). Called with the
/// subpixel's own viewport coordinates: s = (3x + k + ½) / 3W for subpixel k of pixel x.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct LightFieldRays {
    pub window_origin: DVec3,
    pub window_right: DVec3,
    pub window_up: DVec3,
    pub forward: DVec3,
    pub clip: ClipRange,
    pub tilt: f64,
    pub pitch: f64,
    /// One subpixel's share of the lenticular phase (pitch / 3W).
    pub subpixel: f64,
    pub center: f64,
    pub inv_view: bool,
    pub views: u32,
    /// Radians.
    pub view_cone: f64,
    pub flip_x: bool,
    pub flip_y: bool,
    pub flip_subpixels: bool,
    /// The eye of view fraction ½ (in front of the screen's centre), and the screen's unit x
    /// axis times the viewing distance.
    pub view_centre: DVec3,
    pub view_x: DVec3,
    /// The snapped views' eyes, made from the fields above by [`LightFieldRays::with_view_eyes`]
    /// (so private: they cannot drift from `views`).
    view_eyes: Vec<DVec3>,
}

impl LightFieldRays {
    /// The eyes of the `views` snapped views (view i at fraction (i+½)/N), when there are at
    /// most [`MAX_TABLED_VIEWS`]: each subpixel's eye is then looked up, not computed.
    fn with_view_eyes(mut self) -> LightFieldRays {
        self.view_eyes = if self.views > 0 && self.views <= MAX_TABLED_VIEWS {
            let n = f64::from(self.views);
            (0..self.views)
                .map(|view| self.eye_of_fraction((f64::from(view) + 0.5) / n))
                .collect()
        } else {
            Vec::new()
        };
        self
    }

    /// The view fraction of the subpixel at viewport coordinates (s, t), before snapping.
    #[inline(always)]
    fn view_fraction(&self, s: f64, t: f64) -> f64 {
        // s is the subpixel's centre; the calibration's phase is written for the pixel's
        // centre plus k subpixels, which is s plus one subpixel.
        let f = fraction((s + t * self.tilt) * self.pitch - self.center + self.subpixel);
        if self.inv_view { 1.0 - f } else { f }
    }

    /// The eye of the subpixel at viewport coordinates (s, t): of its view fraction, snapped
    /// to the nearest of `views` views (i+½)/N when there are views.
    #[inline(always)]
    pub(super) fn eye(&self, s: f64, t: f64) -> DVec3 {
        let f = self.view_fraction(s, t);
        if self.views == 0 {
            return self.eye_of_fraction(f);
        }
        let n = f64::from(self.views);
        // `min` makes a NaN fraction view n − 1, in the table as in the formula.
        let view = (f * n).floor().min(n - 1.0);
        match self.view_eyes.get(view as usize) {
            Some(eye) => *eye,
            None => self.eye_of_fraction((view + 0.5) / n),
        }
    }

    /// The eye of view fraction `f`.
    #[inline(always)]
    fn eye_of_fraction(&self, f: f64) -> DVec3 {
        LightFieldCamera::view_eye(self.view_centre, self.view_x, self.view_cone, f)
    }

    /// The subpixel's centre on the screen for viewport coordinates `st`.
    #[inline(always)]
    pub(super) fn target(&self, st: DVec2) -> DVec3 {
        let s = if self.flip_x { 1.0 - st.x } else { st.x };
        let t = if self.flip_y { 1.0 - st.y } else { st.y };
        self.window_origin + s * self.window_right + t * self.window_up
    }
}

/// Most snapped views whose eyes a light-field generator keeps in a table (quilt drivers use
/// 45 to 100).
const MAX_TABLED_VIEWS: u32 = 4096;

/// x − ⌊x⌋: bit for bit `x.rem_euclid(1.0)` but for the sign of a zero result (the remainder
/// and the +1 of a negative x round the same exact value once), without a call to `fmod`. A
/// view fraction's zero sign never reaches a ray: 1 − f, ⌊f·N⌋ + ½ and f − ½ drop it.
#[inline(always)]
fn fraction(x: f64) -> f64 {
    x - x.floor()
}

/// [`EyeRays::ray`]'s light-field rays for a block of subpixels, lane by lane with the same
/// functions (no fused multiply-adds on the AVX2 path, where `floor` is one instruction).
#[inline(always)]
pub(super) fn light_field_block(
    region: &ImageRegion,
    rays: &LightFieldRays,
    s: &[f32; BLOCK_RAYS],
    t: &[f32; BLOCK_RAYS],
    block: &mut BlockRays,
) {
    // The eyes and targets first (branches, a table look-up), then the rays over lane arrays:
    // their square roots and divisions several lanes per instruction.
    let mut eyes = [[0.0; 3]; BLOCK_RAYS];
    let mut targets = [[0.0; 3]; BLOCK_RAYS];
    for i in 0..BLOCK_RAYS {
        let st = region.apply(s[i], t[i]);
        eyes[i] = rays.eye(st.x, st.y).to_array();
        targets[i] = rays.target(st).to_array();
    }
    with_clip!(rays.clip, clip => eye_lanes(&eyes, &targets, rays.forward, clip, block));
    block.clear_cyclopean();
}

/// [`light_field_block`]'s lanes from `eyes` through `targets` with clip range `clip`.
#[inline(always)]
fn eye_lanes(
    eyes: &[[f64; 3]; BLOCK_RAYS],
    targets: &[[f64; 3]; BLOCK_RAYS],
    forward: DVec3,
    clip: &ClipRange,
    block: &mut BlockRays,
) {
    for i in 0..BLOCK_RAYS {
        block.set(i, eyes[i], targets[i], forward, clip);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DVec3, Vec2};

    fn camera(desc: LightFieldDesc) -> LightFieldCamera {
        LightFieldCamera::new(&LightFieldDesc {
            lower_left: Some(Vec3::new(-0.3, -0.2, 0.0)),
            lower_right: Some(Vec3::new(0.3, -0.2, 0.0)),
            upper_right: Some(Vec3::new(0.3, 0.2, 0.0)),
            ..desc
        })
        .unwrap()
    }

    /// The definition, in f64, for subpixel k of pixel (x, y) of a W×H panel.
    fn view_fraction(d: &LightFieldDesc, x: u32, y: u32, k: u32, w: f64, h: f64) -> f64 {
        let (u, v) = ((f64::from(x) + 0.5) / w, (f64::from(y) + 0.5) / h);
        let slope = f64::from(d.slope);
        let tilt = -h / (w * slope);
        let p = f64::from(d.pitch) * (w / f64::from(d.dpi)) * 1f64.atan2(slope).cos();
        let subp = p / (3.0 * w);
        let f = ((u + v * tilt) * p - f64::from(d.center) + f64::from(k) * subp).rem_euclid(1.0);
        if d.inv_view { 1.0 - f } else { f }
    }

    #[test]
    fn subpixel_rays_start_at_the_eye_of_their_view_fraction() {
        let (w, h) = (2560u32, 1600u32);
        for inv_view in [false, true] {
            let desc = LightFieldDesc {
                inv_view,
                ..LightFieldDesc::default()
            };
            let cam = camera(desc.clone());
            let rays = cam.prepare(Eye::Mono, w, h);
            let d = cam.viewing_distance;
            let cone = f64::from(desc.view_cone).to_radians();
            for (x, y) in [(0, 0), (1, 0), (1279, 800), (2559, 1599), (17, 1203)] {
                for k in 0..3 {
                    let f = view_fraction(&desc, x, y, k, f64::from(w), f64::from(h));
                    let eye = DVec3::new(d * ((f - 0.5) * cone).tan(), 0.0, d);
                    let s = ((3 * x + k) as f32 + 0.5) / (3 * w) as f32;
                    let t = (y as f32 + 0.5) / h as f32;
                    let ray = rays.ray(s, t, Vec2::ZERO);
                    // The frame's subpixel coordinate is an f32: across 370 lenticular cycles
                    // its rounding moves the view fraction by up to ~1e-5.
                    assert!(
                        (ray.origin.as_dvec3() - eye).length() < 2e-5 * d.max(1.0),
                        "({x}, {y}) subpixel {k}: {} vs {eye} (f {f})",
                        ray.origin
                    );
                    // The ray passes through the subpixel's centre on the screen.
                    let target =
                        DVec3::new(-0.3 + 0.6 * f64::from(s), -0.2 + 0.4 * f64::from(t), 0.0);
                    let along = (target - ray.origin.as_dvec3()).normalize();
                    assert!((along - ray.direction.as_dvec3()).length() < 1e-6);
                }
            }
        }
    }

    /// Subpixel (s, t)'s ray as the definition reads, computed alone: the view fraction by
    /// `rem_euclid`, the snapped view's eye computed, the unit direction as glam normalizes.
    fn direct_ray(cam: &LightFieldCamera, w: f64, h: f64, s: f32, t: f32) -> (Vec3, Vec3) {
        let d = &cam.desc;
        let slope = f64::from(d.slope);
        let p = f64::from(d.pitch) * (w / f64::from(d.dpi)) * 1f64.atan2(slope).cos();
        let (s, t) = (f64::from(s), f64::from(t));
        let phase = (s + t * (-h / (w * slope))) * p - f64::from(d.center) + p / (3.0 * w);
        let mut f = phase.rem_euclid(1.0);
        if d.inv_view {
            f = 1.0 - f;
        }
        if d.views > 0 {
            let n = f64::from(d.views);
            f = ((f * n).floor().min(n - 1.0) + 0.5) / n;
        }
        let screen = &cam.screen;
        let view_x = screen.x * cam.viewing_distance;
        let cone = f64::from(d.view_cone).to_radians();
        let eye = LightFieldCamera::view_eye(cam.view_centre(), view_x, cone, f);
        let s = if d.flip_image_x { 1.0 - s } else { s };
        let t = if d.flip_image_y { 1.0 - t } else { t };
        let target = screen.lower_left
            + s * (screen.lower_right - screen.lower_left)
            + t * (screen.upper_right - screen.lower_right);
        let towards = target - eye;
        let recip = 1.0 / towards.length_squared().sqrt();
        (eye.as_vec3(), (towards * recip).as_vec3())
    }

    #[test]
    fn subpixel_rays_alone_and_a_block_at_a_time_are_the_definitions_bit_for_bit() {
        // The frame makes a block's rays together (eyes of snapped views from a table): every
        // one must be the ray the definition gives alone, on either instruction-set path.
        let (w, h) = (2560u32, 1600u32);
        let paths = crate::isa::test_paths();
        let mut block = BlockRays::default();
        let mut checked = 0;
        let calibrations = [
            LightFieldDesc::default(),
            LightFieldDesc {
                views: 45,
                ..LightFieldDesc::default()
            },
            LightFieldDesc {
                views: 45,
                inv_view: true,
                flip_image_x: true,
                flip_image_y: true,
                flip_subpixels: true,
                ..LightFieldDesc::default()
            },
            LightFieldDesc {
                views: 7,
                center: -3.7,
                slope: -4.1,
                ..LightFieldDesc::default()
            },
            // More views than the table holds: computed per ray.
            LightFieldDesc {
                views: 5000,
                ..LightFieldDesc::default()
            },
        ];
        for desc in calibrations {
            let cam = camera(desc.clone());
            let rays = cam.prepare(Eye::Mono, w, h);
            assert!(rays.makes_block_rays());
            for (y, offset) in [(0, 0.5), (801, 0.5), (1599, 0.5), (377, 0.123)] {
                let t = (y as f32 + offset) / h as f32;
                let s: Vec<f32> = (0..3 * w)
                    .map(|sub| (sub as f32 + offset) / (3 * w) as f32)
                    .collect();
                for chunk in s.chunks(BLOCK_RAYS) {
                    let lanes: [f32; BLOCK_RAYS] = std::array::from_fn(|i| chunk[i]);
                    for &isa in &paths {
                        assert!(rays.block_rays_on_path(isa, &lanes, &[t; BLOCK_RAYS], &mut block));
                        for (i, &s) in lanes.iter().enumerate() {
                            let (origin, direction) =
                                direct_ray(&cam, f64::from(w), f64::from(h), s, t);
                            let alone = rays.ray(s, t, Vec2::ZERO);
                            for ray in [alone, block.ray(i)] {
                                let what = format!("{desc:?} ({s}, {t}) {isa:?}");
                                assert_eq!(
                                    ray.origin.to_array().map(f32::to_bits),
                                    origin.to_array().map(f32::to_bits),
                                    "{what}"
                                );
                                assert_eq!(
                                    ray.direction.to_array().map(f32::to_bits),
                                    direction.to_array().map(f32::to_bits),
                                    "{what}"
                                );
                                assert_eq!(
                                    (ray.t_min, ray.t_max, ray.cyclopean),
                                    (0.0, f32::INFINITY, None),
                                    "{what}"
                                );
                            }
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert_eq!(checked, 5 * 4 * 3 * w as usize * paths.len());
    }

    #[test]
    fn bad_calibration_is_refused_naming_the_parameter() {
        for (desc, parameter) in [
            (
                LightFieldDesc {
                    slope: 0.0,
                    ..LightFieldDesc::default()
                },
                "slope",
            ),
            (
                LightFieldDesc {
                    dpi: 0.0,
                    ..LightFieldDesc::default()
                },
                "dpi",
            ),
            (
                LightFieldDesc {
                    pitch: f32::NAN,
                    ..LightFieldDesc::default()
                },
                "pitch",
            ),
            (
                LightFieldDesc {
                    view_cone: 180.0,
                    ..LightFieldDesc::default()
                },
                "viewCone",
            ),
            (
                LightFieldDesc {
                    view_cone: 0.0,
                    ..LightFieldDesc::default()
                },
                "viewCone",
            ),
            (
                LightFieldDesc {
                    center: f32::INFINITY,
                    ..LightFieldDesc::default()
                },
                "center",
            ),
            (
                LightFieldDesc {
                    viewing_distance: Some(-1.0),
                    ..LightFieldDesc::default()
                },
                "viewingDistance",
            ),
        ] {
            let error = LightFieldCamera::new(&LightFieldDesc {
                lower_left: Some(Vec3::new(-0.3, -0.2, 0.0)),
                lower_right: Some(Vec3::new(0.3, -0.2, 0.0)),
                upper_right: Some(Vec3::new(0.3, 0.2, 0.0)),
                ..desc
            })
            .unwrap_err();
            assert_eq!(error.parameter, parameter);
        }
    }

    #[test]
    fn fraction_is_rem_euclid_but_for_the_sign_of_zero() {
        let mut values = vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.25,
            -0.25,
            1e-20,
            -1e-20,
            -3.000_000_000_1,
            12345.678,
            -12345.678,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            1e300,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            f64::INFINITY,
            f64::NAN,
        ];
        // Phases of every magnitude a calibration gives (up to a few thousand cycles).
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        for _ in 0..200_000 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            let unit = (state >> 11) as f64 / (1u64 << 53) as f64;
            let scale = [1e-6, 1.0, 40.0, 5000.0][(state >> 3) as usize % 4];
            values.push((2.0 * unit - 1.0) * scale);
        }
        for x in values {
            let (fast, reference) = (fraction(x), x.rem_euclid(1.0));
            let same_bits = fast.to_bits() == reference.to_bits();
            assert!(
                same_bits || fast == reference || (fast.is_nan() && reference.is_nan()),
                "{x}: {fast} vs {reference}"
            );
        }
    }
}
