//! Off-axis projection math for screens in CAVE space (pure f64 functions, no camera state).
//!
//! A screen is the rectangle with lower-left `ll`, lower-right `lr` and upper-right `ur`
//! corners. Its frame (Pape's recipe) is X = norm(lr − ll), Y = norm(ur − lr), Z = X × Y;
//! Z points from the screen towards a viewer in front of it.
//! The three functions here back the C helpers `cavetraceOffAxisMatrices`,
//! `cavetraceOffAxisPerspective` and `cavetracePerspectiveFromMatrices`.

use std::fmt;

use glam::{DMat4, DVec3, DVec4};

use super::validate::is_singular;

/// Largest |cos| of the angle between the screen's bottom and right edges that still counts as
/// a right angle (≈ 0.057°): tracked or hand-measured corners are never exact.
pub const RIGHT_ANGLE_TOLERANCE: f64 = 1e-3;

/// Smallest |sin| between the screen edges before the corners count as collinear.
const COLLINEAR_SINE: f64 = 1e-9;

/// The eye must be farther than this fraction of the screen's longer edge from the screen
/// plane.
const MIN_EYE_DISTANCE_FRACTION: f64 = 1e-6;

/// Why a screen, an eye or a pair of matrices has no off-axis frustum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OffAxisError {
    /// The named input has a NaN or infinite component.
    NonFinite(&'static str),
    /// The corners do not span a rectangle of non-zero area.
    DegenerateScreen(DegenerateScreen),
    /// The angle at the lower-right corner differs from 90° by more than the tolerance.
    NotRectangular { cos_angle: f64 },
    /// The eye is on the screen plane or behind it (`distance` is its signed distance, positive
    /// in front).
    EyeOnOrBehindScreen { distance: f64 },
    /// near must be positive and finite, far finite and greater than near.
    InvalidClipRange { near: f64, far: f64 },
    /// The named matrix ("view" or "proj") is singular.
    Singular(&'static str),
    /// The projection is parallel (orthographic): there is no eye point.
    NotPerspective,
    /// The projection mirrors the image (e.g. a flipped y axis); no ANARI perspective camera
    /// produces it.
    Mirrored,
}

/// Which part of the screen is degenerate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DegenerateScreen {
    /// lowerRight coincides with lowerLeft.
    ZeroWidth,
    /// upperRight coincides with lowerRight.
    ZeroHeight,
    /// The three corners lie on one line.
    Collinear,
}

impl fmt::Display for OffAxisError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OffAxisError::NonFinite(what) => write!(f, "{what} has a non-finite component"),
            OffAxisError::DegenerateScreen(DegenerateScreen::ZeroWidth) => {
                write!(f, "screen has zero width (lowerRight equals lowerLeft)")
            }
            OffAxisError::DegenerateScreen(DegenerateScreen::ZeroHeight) => {
                write!(f, "screen has zero height (upperRight equals lowerRight)")
            }
            OffAxisError::DegenerateScreen(DegenerateScreen::Collinear) => {
                write!(f, "screen corners are collinear")
            }
            OffAxisError::NotRectangular { cos_angle } => write!(
                f,
                "screen corners do not form a right angle at lowerRight (cos = {cos_angle:.3e}, \
                 tolerance {RIGHT_ANGLE_TOLERANCE:.0e})"
            ),
            OffAxisError::EyeOnOrBehindScreen { distance } => write!(
                f,
                "eye is on or behind the screen plane (signed distance {distance} m)"
            ),
            OffAxisError::InvalidClipRange { near, far } => write!(
                f,
                "need 0 < near < far, both finite (near = {near}, far = {far})"
            ),
            OffAxisError::Singular(which) => write!(f, "{which} matrix is singular"),
            OffAxisError::NotPerspective => {
                write!(f, "projection is orthographic, it has no eye point")
            }
            OffAxisError::Mirrored => write!(f, "projection mirrors the image"),
        }
    }
}

impl std::error::Error for OffAxisError {}

/// A symmetric perspective camera (ANARI "perspective" parameters) whose imageRegion crops a
/// screen exactly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerspectiveFit {
    pub position: DVec3,
    /// Unit length, perpendicular onto the screen plane.
    pub direction: DVec3,
    /// Unit length, the screen's Y axis.
    pub up: DVec3,
    /// Vertical field of view in radians, in (0, π).
    pub fovy: f64,
    pub aspect: f64,
    /// `[lo.x, lo.y, hi.x, hi.y]`, inside `[0,1]²`.
    pub image_region: [f64; 4],
}

/// An orthonormal screen frame validated from three corners.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ScreenFrame {
    pub lower_left: DVec3,
    pub lower_right: DVec3,
    pub upper_right: DVec3,
    pub x: DVec3,
    pub y: DVec3,
    pub z: DVec3,
}

impl ScreenFrame {
    pub(crate) fn new(ll: DVec3, lr: DVec3, ur: DVec3) -> Result<ScreenFrame, OffAxisError> {
        for (value, name) in [(ll, "lowerLeft"), (lr, "lowerRight"), (ur, "upperRight")] {
            if !value.is_finite() {
                return Err(OffAxisError::NonFinite(name));
            }
        }
        let bottom = lr - ll;
        let side = ur - lr;
        // Relative to the corners' magnitude so that a screen far from the origin is judged by
        // what f64 can resolve there.
        let scale = ll.abs().max_element().max(lr.abs().max_element());
        let scale = scale.max(ur.abs().max_element());
        let resolvable = 1e-12 * scale;
        if bottom.length() <= resolvable {
            return Err(OffAxisError::DegenerateScreen(DegenerateScreen::ZeroWidth));
        }
        if side.length() <= resolvable {
            return Err(OffAxisError::DegenerateScreen(DegenerateScreen::ZeroHeight));
        }
        let x = bottom.normalize();
        let y_raw = side.normalize();
        let normal = x.cross(y_raw);
        if normal.length() < COLLINEAR_SINE {
            return Err(OffAxisError::DegenerateScreen(DegenerateScreen::Collinear));
        }
        let cos_angle = x.dot(y_raw);
        if cos_angle.abs() > RIGHT_ANGLE_TOLERANCE {
            return Err(OffAxisError::NotRectangular { cos_angle });
        }
        let z = normal.normalize();
        // Re-orthogonalize so the view rotation is exactly orthonormal; for an exact rectangle
        // this is norm(ur − lr) again.
        let y = z.cross(x);
        Ok(ScreenFrame {
            lower_left: ll,
            lower_right: lr,
            upper_right: ur,
            x,
            y,
            z,
        })
    }

    /// Signed distance of `p` from the screen plane, positive in front.
    pub(crate) fn signed_distance(&self, p: DVec3) -> f64 {
        (p - self.lower_left).dot(self.z)
    }

    /// The eye's distance from the screen plane, if it is clearly in front of it.
    pub(crate) fn eye_distance(&self, eye: DVec3) -> Result<f64, OffAxisError> {
        if !eye.is_finite() {
            return Err(OffAxisError::NonFinite("eye"));
        }
        let distance = self.signed_distance(eye);
        let longer_edge = (self.lower_right - self.lower_left)
            .length()
            .max((self.upper_right - self.lower_right).length());
        if distance > MIN_EYE_DISTANCE_FRACTION * longer_edge {
            Ok(distance)
        } else {
            Err(OffAxisError::EyeOnOrBehindScreen { distance })
        }
    }

    /// Screen extents seen from `eye` as `[left, right, bottom, top]` tangents, i.e. at unit
    /// distance in front of the eye along −Z.
    fn tangent_extents(&self, eye: DVec3, distance: f64) -> [f64; 4] {
        [
            self.x.dot(self.lower_left - eye) / distance,
            self.x.dot(self.lower_right - eye) / distance,
            self.y.dot(self.lower_left - eye) / distance,
            self.y.dot(self.upper_right - eye) / distance,
        ]
    }
}

/// Pape's off-axis view and projection matrices (OpenGL conventions, column-major) for an eye
/// in front of the screen: `view = R·T(−eye)` with R's rows X, Y, Z, and
/// `proj = glFrustum(l, r, b, t, near, far)` with the screen edges scaled onto the near plane.
/// Correct for screens of any orientation.
pub fn off_axis_matrices(
    ll: DVec3,
    lr: DVec3,
    ur: DVec3,
    eye: DVec3,
    near: f64,
    far: f64,
) -> Result<(DMat4, DMat4), OffAxisError> {
    if !(near.is_finite() && far.is_finite() && near > 0.0 && far > near) {
        return Err(OffAxisError::InvalidClipRange { near, far });
    }
    let frame = ScreenFrame::new(ll, lr, ur)?;
    let distance = frame.eye_distance(eye)?;
    let [left, right, bottom, top] = frame.tangent_extents(eye, distance).map(|e| e * near);
    let rotation = DMat4::from_cols(
        frame.x.extend(0.0),
        frame.y.extend(0.0),
        frame.z.extend(0.0),
        DVec4::W,
    )
    .transpose();
    let view = rotation * DMat4::from_translation(-eye);
    Ok((view, gl_frustum(left, right, bottom, top, near, far)))
}

/// Strategy 2 of Zellmann & Amstutz: a symmetric perspective camera at the eye, looking
/// perpendicularly onto the screen plane (along −Z) with up = Y, whose fovy/aspect is the
/// smallest symmetric frustum containing the screen, and the imageRegion (inside `[0,1]²`) that
/// crops exactly the screen.
pub fn off_axis_perspective(
    ll: DVec3,
    lr: DVec3,
    ur: DVec3,
    eye: DVec3,
) -> Result<PerspectiveFit, OffAxisError> {
    let frame = ScreenFrame::new(ll, lr, ur)?;
    let distance = frame.eye_distance(eye)?;
    let [left, right, bottom, top] = frame.tangent_extents(eye, distance);
    let half_width = left.abs().max(right.abs());
    let half_height = bottom.abs().max(top.abs());
    // (e + h) / 2h is exactly 0 for e = −h and exactly 1 for e = h, so the clamp only guards
    // against rounding for screens touching the frustum edges.
    let to_unit = |e: f64, half: f64| ((e + half) / (2.0 * half)).clamp(0.0, 1.0);
    Ok(PerspectiveFit {
        position: eye,
        direction: -frame.z,
        up: frame.y,
        fovy: 2.0 * half_height.atan(),
        aspect: half_width / half_height,
        image_region: [
            to_unit(left, half_width),
            to_unit(bottom, half_height),
            to_unit(right, half_width),
            to_unit(top, half_height),
        ],
    })
}

/// Strategy 3: recovers the eye (the centre of projection, view⁻¹·proj⁻¹·(0,0,1,0)) and a
/// screen rectangle (any plane section of the frustum, spanned by the NDC corners) from an
/// application's view and projection matrices, then fits a perspective camera as
/// [`off_axis_perspective`] does. Works for any glFrustum-style projection (asymmetric,
/// off-centre) combined with any view matrix.
pub fn perspective_from_matrices(view: DMat4, proj: DMat4) -> Result<PerspectiveFit, OffAxisError> {
    if !view.is_finite() {
        return Err(OffAxisError::NonFinite("view"));
    }
    if !proj.is_finite() {
        return Err(OffAxisError::NonFinite("proj"));
    }
    if is_singular(&view) {
        return Err(OffAxisError::Singular("view"));
    }
    if is_singular(&proj) {
        return Err(OffAxisError::Singular("proj"));
    }
    let inv_view = view.inverse();
    let inv_proj = proj.inverse();
    // The centre of projection is the point proj sends to (0,0,1,0) (w_clip = 0); for a
    // parallel projection it lies at infinity.
    let centre_eye_space = inv_proj * DVec4::Z;
    if centre_eye_space.w.abs() <= 1e-9 * centre_eye_space.truncate().length() {
        return Err(OffAxisError::NotPerspective);
    }
    let centre = inv_view * (centre_eye_space / centre_eye_space.w);
    let eye = centre.truncate() / centre.w;
    // Homogeneous world points of the NDC near-plane corners; the direction from the eye to a
    // homogeneous point h is h.xyz·c.w − c.xyz·h.w (times 1/(h.w·c.w)), which is affine in
    // (u, v): the corners of a parallelogram whose pixels map exactly like the matrix camera's.
    let corner_direction = |u: f64, v: f64| {
        let h = inv_view * (inv_proj * DVec4::new(u, v, -1.0, 1.0));
        (
            h.truncate() * centre.w - centre.truncate() * h.w,
            h.w * centre.w,
        )
    };
    let corners =
        [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].map(|(u, v)| corner_direction(u, v));
    // All corners must lie on the same side of the eye (in front of it).
    let sign = corners[0].1.signum();
    if corners.iter().any(|(_, w)| w.signum() != sign || *w == 0.0) {
        return Err(OffAxisError::Singular("proj"));
    }
    // One common scale for all corners keeps the parallelogram; unit-ish size avoids the
    // tiny near plane.
    let scale = sign / corners[0].0.length();
    let [ll, lr, ur, _] = corners.map(|(d, _)| eye + d * scale);
    let frame = ScreenFrame::new(ll, lr, ur)?;
    if frame.signed_distance(eye) < 0.0 {
        return Err(OffAxisError::Mirrored);
    }
    off_axis_perspective(ll, lr, ur, eye)
}

/// OpenGL glFrustum (column-major, NDC z in `[−1, 1]`).
fn gl_frustum(left: f64, right: f64, bottom: f64, top: f64, near: f64, far: f64) -> DMat4 {
    let width = right - left;
    let height = top - bottom;
    let depth = far - near;
    DMat4::from_cols(
        DVec4::new(2.0 * near / width, 0.0, 0.0, 0.0),
        DVec4::new(0.0, 2.0 * near / height, 0.0, 0.0),
        DVec4::new(
            (right + left) / width,
            (top + bottom) / height,
            -(far + near) / depth,
            -1.0,
        ),
        DVec4::new(0.0, 0.0, -2.0 * far * near / depth, 0.0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::test_support::{gl_window_depth, screens};
    use glam::dcamera::rh::proj::opengl;
    use glam::dcamera::rh::view::look_at_mat4;

    const NEAR: f64 = 0.05;
    const FAR: f64 = 200.0;

    fn ndc(view: DMat4, proj: DMat4, p: DVec3) -> DVec3 {
        (proj * view * p.extend(1.0)).truncate() / (proj * view * p.extend(1.0)).w
    }

    #[test]
    fn screen_corners_map_to_ndc_corners_for_every_wall_and_eye() {
        for screen in screens() {
            let upper_left = screen.ll + screen.height_axis();
            for eye in screen.eyes() {
                let (view, proj) =
                    off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
                for (corner, expected) in [
                    (screen.ll, (-1.0, -1.0)),
                    (screen.lr, (1.0, -1.0)),
                    (screen.ur, (1.0, 1.0)),
                    (upper_left, (-1.0, 1.0)),
                    (screen.centre(), (0.0, 0.0)),
                ] {
                    let p = ndc(view, proj, corner);
                    assert!(
                        (p.x - expected.0).abs() < 1e-9 && (p.y - expected.1).abs() < 1e-9,
                        "{}: eye {eye} corner {corner} -> {p}",
                        screen.name
                    );
                }
            }
        }
    }

    #[test]
    fn view_is_rigid_puts_eye_at_origin_and_screen_at_minus_distance() {
        for screen in screens() {
            for eye in screen.eyes() {
                let (view, _) =
                    off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
                assert!(view.transform_point3(eye).length() < 1e-9);
                let rotation = glam::DMat3::from_mat4(view);
                assert!(
                    (rotation * rotation.transpose() - glam::DMat3::IDENTITY)
                        .to_cols_array()
                        .iter()
                        .all(|e| e.abs() < 1e-12)
                );
                assert!((rotation.determinant() - 1.0).abs() < 1e-12);
                let distance = (eye - screen.ll).dot(screen.normal());
                for corner in [screen.ll, screen.lr, screen.ur] {
                    let z = view.transform_point3(corner).z;
                    assert!(
                        (z + distance).abs() < 1e-9,
                        "{}: {z} vs {distance}",
                        screen.name
                    );
                }
                // Screen X maps to eye-space +x, screen Y to +y.
                let x = view.transform_vector3(screen.width_axis().normalize());
                let y = view.transform_vector3(screen.height_axis().normalize());
                assert!((x - DVec3::X).length() < 1e-12 && (y - DVec3::Y).length() < 1e-12);
            }
        }
    }

    #[test]
    fn front_wall_matches_glam_look_at_and_frustum() {
        let screen = screens()[0];
        let eye = DVec3::new(0.3, 1.6, 0.4);
        let (view, proj) =
            off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
        let distance = 1.9;
        let scale = NEAR / distance;
        let expected_proj = opengl::frustum(
            (-1.5 - 0.3) * scale,
            (1.5 - 0.3) * scale,
            (0.0 - 1.6) * scale,
            (3.0 - 1.6) * scale,
            NEAR,
            FAR,
        );
        let expected_view = look_at_mat4(eye, eye - DVec3::Z, DVec3::Y);
        assert!(
            proj.abs_diff_eq(expected_proj, 1e-12),
            "{proj} vs {expected_proj}"
        );
        assert!(
            view.abs_diff_eq(expected_view, 1e-12),
            "{view} vs {expected_view}"
        );
    }

    #[test]
    fn side_wall_view_rotates_the_eye_translation() {
        // For the left wall the screen's X axis is −z: a row-wise rotation must be applied to
        // the eye translation too, so the eye (not the world origin) ends up at the origin.
        let screen = screens()[1];
        let eye = DVec3::new(0.2, 1.7, 0.5);
        let (view, proj) =
            off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
        let expected_view = look_at_mat4(eye, eye - DVec3::X, DVec3::Y);
        assert!(view.abs_diff_eq(expected_view, 1e-12), "{view}");
        // Screen from the eye: x from −(1.5 − 0.5)... along X = −z: ll.z = 1.5 → x = −1.0.
        let scale = NEAR / 1.7;
        let expected_proj = opengl::frustum(
            -(1.5 - 0.5) * scale,
            (1.5 + 0.5) * scale,
            -1.7 * scale,
            1.3 * scale,
            NEAR,
            FAR,
        );
        assert!(proj.abs_diff_eq(expected_proj, 1e-12), "{proj}");
    }

    #[test]
    fn window_depth_of_screen_plane_points_follows_gl_frustum_mapping() {
        let screen = screens()[3];
        let eye = screen.local(0.1, -0.2, 1.7);
        let (view, proj) =
            off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
        let z = 1.7;
        let expected = FAR * (z - NEAR) / (z * (FAR - NEAR));
        let depth = gl_window_depth(view, proj, screen.point(0.3, 0.8));
        assert!((depth - expected).abs() < 1e-12, "{depth} vs {expected}");
    }

    #[test]
    fn centred_eye_fit_is_the_plain_symmetric_frustum() {
        let screen = screens()[6];
        let eye = screen.local(0.0, 0.0, 2.5);
        let fit = off_axis_perspective(screen.ll, screen.lr, screen.ur, eye).unwrap();
        assert_eq!(fit.image_region, [0.0, 0.0, 1.0, 1.0]);
        assert!((fit.fovy - 2.0 * (1.125f64 / 2.5).atan()).abs() < 1e-12);
        assert!((fit.aspect - 4.0 / 2.25).abs() < 1e-12);
        assert!((fit.direction - DVec3::NEG_Z).length() < 1e-12);
        assert!((fit.up - DVec3::Y).length() < 1e-12);
        assert_eq!(fit.position, eye);
    }

    #[test]
    fn off_centre_fit_crops_the_screen_inside_the_unit_square() {
        let screen = screens()[0];
        // 1 m right of the wall's right edge: the whole screen is left of the view axis.
        let eye = DVec3::new(2.5, 1.0, 0.5);
        let fit = off_axis_perspective(screen.ll, screen.lr, screen.ur, eye).unwrap();
        // Tangents at distance 2: x from −4/2 to −1/2, y from −1/2 to 2/2.
        let [lo_x, lo_y, hi_x, hi_y] = fit.image_region;
        assert_eq!(lo_x, 0.0);
        assert!((hi_x - (-0.5 + 2.0) / 4.0).abs() < 1e-12);
        assert!((lo_y - (-0.5 + 1.0) / 2.0).abs() < 1e-12);
        assert_eq!(hi_y, 1.0);
        assert!((fit.fovy - 2.0 * 1f64.atan()).abs() < 1e-12);
        assert!((fit.aspect - 2.0).abs() < 1e-12);
        for screen in screens() {
            for eye in screen.eyes() {
                let fit = off_axis_perspective(screen.ll, screen.lr, screen.ur, eye).unwrap();
                let [lo_x, lo_y, hi_x, hi_y] = fit.image_region;
                assert!(0.0 <= lo_x && lo_x < hi_x && hi_x <= 1.0, "{fit:?}");
                assert!(0.0 <= lo_y && lo_y < hi_y && hi_y <= 1.0, "{fit:?}");
                // The frustum is as tight as possible: the screen touches it on each axis.
                assert!(lo_x == 0.0 || hi_x == 1.0);
                assert!(lo_y == 0.0 || hi_y == 1.0);
                assert!(fit.fovy > 0.0 && fit.fovy < std::f64::consts::PI);
                assert!(fit.direction.dot(screen.normal()) + 1.0 < 1e-12);
            }
        }
    }

    #[test]
    fn fit_from_matrices_equals_fit_from_screen() {
        for screen in screens() {
            for eye in screen.eyes() {
                let direct = off_axis_perspective(screen.ll, screen.lr, screen.ur, eye).unwrap();
                let (view, proj) =
                    off_axis_matrices(screen.ll, screen.lr, screen.ur, eye, NEAR, FAR).unwrap();
                let recovered = perspective_from_matrices(view, proj).unwrap();
                let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
                assert!((recovered.position - direct.position).length() < 1e-9);
                assert!((recovered.direction - direct.direction).length() < 1e-9);
                assert!((recovered.up - direct.up).length() < 1e-9);
                assert!(
                    close(recovered.fovy, direct.fovy),
                    "{recovered:?} {direct:?}"
                );
                assert!(close(recovered.aspect, direct.aspect));
                for i in 0..4 {
                    assert!(close(recovered.image_region[i], direct.image_region[i]));
                }
            }
        }
    }

    #[test]
    fn fit_from_symmetric_gl_matrices_recovers_look_at_parameters() {
        let eye = DVec3::new(1.0, 2.0, 3.0);
        let target = DVec3::new(-2.0, 0.5, -4.0);
        let view = look_at_mat4(eye, target, DVec3::Y);
        let proj = opengl::perspective(0.9, 1.6, 0.001, 1000.0);
        let fit = perspective_from_matrices(view, proj).unwrap();
        assert!((fit.position - eye).length() < 1e-9);
        assert!((fit.direction - (target - eye).normalize()).length() < 1e-9);
        assert!((fit.fovy - 0.9).abs() < 1e-9);
        assert!((fit.aspect - 1.6).abs() < 1e-9);
        for (got, expected) in fit.image_region.iter().zip([0.0, 0.0, 1.0, 1.0]) {
            assert!((got - expected).abs() < 1e-9, "{:?}", fit.image_region);
        }
    }

    #[test]
    fn fit_from_matrices_rejects_what_no_perspective_camera_can_do() {
        let view = look_at_mat4(DVec3::ONE, DVec3::ZERO, DVec3::Y);
        let ortho = opengl::orthographic(-1.0, 1.0, -1.0, 1.0, 0.1, 10.0);
        assert_eq!(
            perspective_from_matrices(view, ortho),
            Err(OffAxisError::NotPerspective)
        );
        let proj = opengl::frustum(-0.1, 0.2, -0.1, 0.1, 0.1, 10.0);
        let mut singular = proj;
        singular.y_axis = singular.x_axis * 2.0;
        assert_eq!(
            perspective_from_matrices(view, singular),
            Err(OffAxisError::Singular("proj"))
        );
        assert_eq!(
            perspective_from_matrices(DMat4::ZERO, proj),
            Err(OffAxisError::Singular("view"))
        );
        let mut nan = proj;
        nan.z_axis.w = f64::NAN;
        assert_eq!(
            perspective_from_matrices(view, nan),
            Err(OffAxisError::NonFinite("proj"))
        );
        let mut infinite = view;
        infinite.w_axis.x = f64::INFINITY;
        assert_eq!(
            perspective_from_matrices(infinite, proj),
            Err(OffAxisError::NonFinite("view"))
        );
        // Vulkan-style y flip: the image is mirrored.
        let flipped = DMat4::from_scale(DVec3::new(1.0, -1.0, 1.0)) * proj;
        assert_eq!(
            perspective_from_matrices(view, flipped),
            Err(OffAxisError::Mirrored)
        );
        // A sheared projection has a parallelogram, not a rectangle, as its screen.
        let mut sheared = proj;
        sheared.y_axis.x = 0.5;
        assert!(matches!(
            perspective_from_matrices(view, sheared),
            Err(OffAxisError::NotRectangular { .. })
        ));
    }

    #[test]
    fn bad_screens_eyes_and_clip_ranges_are_rejected() {
        let v = DVec3::new;
        let (ll, lr, ur) = (v(-1.0, 0.0, -1.0), v(1.0, 0.0, -1.0), v(1.0, 2.0, -1.0));
        let eye = v(0.0, 1.0, 1.0);
        assert_eq!(
            off_axis_perspective(ll, ll, ur, eye),
            Err(OffAxisError::DegenerateScreen(DegenerateScreen::ZeroWidth))
        );
        assert_eq!(
            off_axis_perspective(ll, lr, lr, eye),
            Err(OffAxisError::DegenerateScreen(DegenerateScreen::ZeroHeight))
        );
        assert_eq!(
            off_axis_perspective(ll, lr, v(3.0, 0.0, -1.0), eye),
            Err(OffAxisError::DegenerateScreen(DegenerateScreen::Collinear))
        );
        // 1° off a right angle.
        let skewed = lr + 2.0 * v(1f64.to_radians().sin(), 1f64.to_radians().cos(), 0.0);
        assert!(matches!(
            off_axis_perspective(ll, lr, skewed, eye),
            Err(OffAxisError::NotRectangular { cos_angle }) if (cos_angle - 1f64.to_radians().sin()).abs() < 1e-12
        ));
        // 0.01° off is within tolerance.
        let nearly = lr + 2.0 * v(0.01f64.to_radians().sin(), 0.01f64.to_radians().cos(), 0.0);
        assert!(off_axis_perspective(ll, lr, nearly, eye).is_ok());
        assert_eq!(
            off_axis_perspective(ll, lr, ur, v(0.0, 1.0, -1.0)),
            Err(OffAxisError::EyeOnOrBehindScreen { distance: 0.0 })
        );
        assert_eq!(
            off_axis_perspective(ll, lr, ur, v(0.0, 1.0, -3.0)),
            Err(OffAxisError::EyeOnOrBehindScreen { distance: -2.0 })
        );
        assert_eq!(
            off_axis_perspective(v(f64::NAN, 0.0, 0.0), lr, ur, eye),
            Err(OffAxisError::NonFinite("lowerLeft"))
        );
        assert_eq!(
            off_axis_perspective(ll, lr, ur, v(0.0, f64::INFINITY, 0.0)),
            Err(OffAxisError::NonFinite("eye"))
        );
        for (near, far) in [
            (0.0, 10.0),
            (-1.0, 10.0),
            (5.0, 5.0),
            (5.0, 1.0),
            (0.1, f64::INFINITY),
            (f64::NAN, 1.0),
        ] {
            assert!(matches!(
                off_axis_matrices(ll, lr, ur, eye, near, far),
                Err(OffAxisError::InvalidClipRange { .. })
            ));
        }
        assert!(off_axis_matrices(ll, lr, ur, eye, 0.1, 10.0).is_ok());
    }

    #[test]
    fn errors_have_readable_messages() {
        assert_eq!(
            OffAxisError::EyeOnOrBehindScreen { distance: -0.5 }.to_string(),
            "eye is on or behind the screen plane (signed distance -0.5 m)"
        );
        assert_eq!(
            OffAxisError::Singular("proj").to_string(),
            "proj matrix is singular"
        );
        assert_eq!(
            OffAxisError::DegenerateScreen(DegenerateScreen::Collinear).to_string(),
            "screen corners are collinear"
        );
    }
}
