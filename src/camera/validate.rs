//! Parameter checks shared by the camera descriptions. Each names the offending ANARI parameter.

use glam::{DMat4, DVec3, Mat4, Vec3};

use super::CameraError;
use super::offaxis::{DegenerateScreen, OffAxisError, ScreenFrame};
use super::rays::{ClipRange, ImageRegion};

/// Sine of the smallest angle accepted between `direction` and `up`.
const MIN_DIRECTION_UP_SINE: f64 = 1e-6;

/// Hadamard ratio |det M| / ∏ ‖row‖ below which a matrix counts as singular (scale invariant:
/// 1 for orthogonal rows, 0 for dependent ones).
const SINGULAR_HADAMARD_RATIO: f64 = 1e-12;

pub(crate) fn finite_point(name: &str, v: Vec3) -> Result<DVec3, CameraError> {
    if v.is_finite() {
        Ok(v.as_dvec3())
    } else {
        Err(CameraError::new(name, format!("must be finite, got {v}")))
    }
}

/// The screen rectangle of `screen.lowerLeft`, `screen.lowerRight`, `screen.upperRight` (each
/// required and finite); a degenerate one is reported on the corner that makes it so.
pub(crate) fn screen_corners(
    lower_left: Option<Vec3>,
    lower_right: Option<Vec3>,
    upper_right: Option<Vec3>,
) -> Result<ScreenFrame, CameraError> {
    let corner = |name: &str, value: Option<Vec3>| match value {
        Some(value) => finite_point(name, value),
        None => Err(CameraError::new(name, "is required")),
    };
    let ll = corner("screen.lowerLeft", lower_left)?;
    let lr = corner("screen.lowerRight", lower_right)?;
    let ur = corner("screen.upperRight", upper_right)?;
    ScreenFrame::new(ll, lr, ur).map_err(|error| {
        let parameter = match error {
            OffAxisError::DegenerateScreen(DegenerateScreen::ZeroWidth) => "screen.lowerRight",
            _ => "screen.upperRight",
        };
        CameraError::new(parameter, error.to_string())
    })
}

/// A finite, non-zero vector, normalized.
pub(crate) fn unit_vector(name: &str, v: Vec3) -> Result<DVec3, CameraError> {
    let v = finite_point(name, v)?;
    let length = v.length();
    if length > 0.0 && length.is_finite() {
        Ok(v / length)
    } else {
        Err(CameraError::new(name, "must not be the zero vector"))
    }
}

/// Orthonormal camera frame `(forward, right, up)` from ANARI `direction` and `up`.
pub(crate) fn view_frame(direction: Vec3, up: Vec3) -> Result<(DVec3, DVec3, DVec3), CameraError> {
    named_view_frame(("direction", direction), ("up", up))
}

/// [`view_frame`] of the parameters named `direction.0` and `up.0`.
pub(crate) fn named_view_frame(
    (direction_name, direction): (&str, Vec3),
    (up_name, up): (&str, Vec3),
) -> Result<(DVec3, DVec3, DVec3), CameraError> {
    let forward = unit_vector(direction_name, direction)?;
    let up = unit_vector(up_name, up)?;
    let side = forward.cross(up);
    if side.length() < MIN_DIRECTION_UP_SINE {
        return Err(CameraError::new(
            up_name,
            format!("must not be parallel to {direction_name}"),
        ));
    }
    let right = side.normalize();
    Ok((forward, right, right.cross(forward)))
}

pub(crate) fn positive(name: &str, value: f32) -> Result<f64, CameraError> {
    if value.is_finite() && value > 0.0 {
        Ok(f64::from(value))
    } else {
        Err(CameraError::new(
            name,
            format!("must be finite and positive, got {value}"),
        ))
    }
}

pub(crate) fn non_negative(name: &str, value: f32) -> Result<f64, CameraError> {
    if value.is_finite() && value >= 0.0 {
        Ok(f64::from(value))
    } else {
        Err(CameraError::new(
            name,
            format!("must be finite and non-negative, got {value}"),
        ))
    }
}

pub(crate) fn optional_positive(
    name: &str,
    value: Option<f32>,
) -> Result<Option<f64>, CameraError> {
    value.map(|v| positive(name, v)).transpose()
}

/// The imageRegion box `[lo.x, lo.y, hi.x, hi.y]`, as ANARI allows it: beyond `[0,1]²` (the
/// image plane continues past the default view) and backwards (upper < lower flips that axis).
/// Finite, and not empty on either axis.
pub(crate) fn image_region(region: [f32; 4]) -> Result<ImageRegion, CameraError> {
    let [lo_x, lo_y, hi_x, hi_y] = region;
    if region.iter().any(|v| !v.is_finite()) {
        return Err(CameraError::new(
            "imageRegion",
            format!("must be finite, got {region:?}"),
        ));
    }
    if lo_x == hi_x || lo_y == hi_y {
        return Err(CameraError::new(
            "imageRegion",
            format!("must not be empty (lower ≠ upper on both axes), got {region:?}"),
        ));
    }
    Ok(ImageRegion::from_box(region))
}

/// near ≥ 0, far > 0, near < far when both are set.
pub(crate) fn clip_range(near: Option<f32>, far: Option<f32>) -> Result<ClipRange, CameraError> {
    let near = near.map(|v| non_negative("near", v)).transpose()?;
    let far = optional_positive("far", far)?;
    if let (Some(near), Some(far)) = (near, far)
        && near >= far
    {
        return Err(CameraError::new(
            "far",
            format!("must be greater than near ({near}), got {far}"),
        ));
    }
    Ok(ClipRange { near, far })
}

/// A finite, non-singular matrix converted to f64, with its inverse.
pub(crate) fn invertible_matrix(name: &str, m: Mat4) -> Result<(DMat4, DMat4), CameraError> {
    if !m.is_finite() {
        return Err(CameraError::new(name, "must be finite"));
    }
    let m = m.as_dmat4();
    if is_singular(&m) {
        return Err(CameraError::new(name, "must not be singular"));
    }
    Ok((m, m.inverse()))
}

pub(crate) fn is_singular(m: &DMat4) -> bool {
    let row_norms: f64 = (0..4).map(|i| m.row(i).length()).product();
    let det = m.determinant();
    det.is_nan() || det.abs() <= SINGULAR_HADAMARD_RATIO * row_norms
}
