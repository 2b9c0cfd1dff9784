//! cavetrace's off-axis helper functions for CAVE and powerwall applications. Each returns an
//! ANARIStatusCode: ANARI_STATUS_NO_ERROR, or ANARI_STATUS_INVALID_ARGUMENT for NULL pointers,
//! non-finite values and degenerate input (nothing is written then).

use glam::{DMat4, DVec3};

use crate::camera::offaxis::{self, PerspectiveFit};
use crate::capi::guard;
use crate::device::status::*;

/// Reads `N` floats from a C array.
fn read<const N: usize>(pointer: *const f32) -> Option<[f64; N]> {
    if pointer.is_null() {
        return None;
    }
    // SAFETY: the caller passes an array of N floats (documented per function).
    let values = unsafe { std::slice::from_raw_parts(pointer, N) };
    let mut out = [0.0; N];
    for (o, v) in out.iter_mut().zip(values) {
        if !v.is_finite() {
            return None;
        }
        *o = *v as f64;
    }
    Some(out)
}

fn vec3(pointer: *const f32) -> Option<DVec3> {
    read::<3>(pointer).map(DVec3::from_array)
}

fn mat4(pointer: *const f32) -> Option<DMat4> {
    read::<16>(pointer).map(|m| DMat4::from_cols_array(&m))
}

/// Writes `values` to a C array of the same length.
fn write(pointer: *mut f32, values: &[f64]) {
    // SAFETY: checked non-NULL by the caller; the array holds values.len() floats.
    let out = unsafe { std::slice::from_raw_parts_mut(pointer, values.len()) };
    for (o, v) in out.iter_mut().zip(values) {
        *o = *v as f32;
    }
}

fn write_fit(
    fit: &PerspectiveFit,
    position: *mut f32,
    direction: *mut f32,
    up: *mut f32,
    fovy: *mut f32,
    aspect: *mut f32,
    image_region: *mut f32,
) {
    write(position, &fit.position.to_array());
    write(direction, &fit.direction.to_array());
    write(up, &fit.up.to_array());
    write(fovy, &[fit.fovy]);
    write(aspect, &[fit.aspect]);
    write(image_region, &fit.image_region);
}

/// Pape's off-axis view and projection matrices (column-major, OpenGL conventions) for a screen
/// given by its lower-left, lower-right and upper-right corners and an eye in front of it.
/// `view` = R·T(−eye) with R's rows the screen's axes, so walls of any orientation work.
/// Inputs: `ll`, `lr`, `ur`, `eye` float[3]; outputs `view`, `proj` float[16].
#[unsafe(no_mangle)]
pub extern "C" fn cavetraceOffAxisMatrices(
    ll: *const f32,
    lr: *const f32,
    ur: *const f32,
    eye: *const f32,
    near: f32,
    far: f32,
    view: *mut f32,
    proj: *mut f32,
) -> ANARIStatusCode {
    guard(
        "cavetraceOffAxisMatrices",
        std::ptr::null_mut(),
        ANARI_STATUS_UNKNOWN_ERROR,
        || {
            let (Some(ll), Some(lr), Some(ur), Some(eye)) =
                (vec3(ll), vec3(lr), vec3(ur), vec3(eye))
            else {
                return ANARI_STATUS_INVALID_ARGUMENT;
            };
            if view.is_null() || proj.is_null() {
                return ANARI_STATUS_INVALID_ARGUMENT;
            }
            match offaxis::off_axis_matrices(ll, lr, ur, eye, near as f64, far as f64) {
                Ok((v, p)) => {
                    write(view, &v.to_cols_array());
                    write(proj, &p.to_cols_array());
                    ANARI_STATUS_NO_ERROR
                }
                Err(_) => ANARI_STATUS_INVALID_ARGUMENT,
            }
        },
    )
}

/// Strategy 2: the ANARI "perspective" camera parameters (position, direction, up, fovy, aspect,
/// imageRegion) that render exactly the off-axis frustum of an eye and a screen.
/// Inputs float[3]; outputs float[3], float[3], float[3], float*, float*, float[4].
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub extern "C" fn cavetraceOffAxisPerspective(
    ll: *const f32,
    lr: *const f32,
    ur: *const f32,
    eye: *const f32,
    position: *mut f32,
    direction: *mut f32,
    up: *mut f32,
    fovy: *mut f32,
    aspect: *mut f32,
    image_region: *mut f32,
) -> ANARIStatusCode {
    guard(
        "cavetraceOffAxisPerspective",
        std::ptr::null_mut(),
        ANARI_STATUS_UNKNOWN_ERROR,
        || {
            let (Some(ll), Some(lr), Some(ur), Some(eye)) =
                (vec3(ll), vec3(lr), vec3(ur), vec3(eye))
            else {
                return ANARI_STATUS_INVALID_ARGUMENT;
            };
            if [position, direction, up, fovy, aspect, image_region]
                .iter()
                .any(|p| p.is_null())
            {
                return ANARI_STATUS_INVALID_ARGUMENT;
            }
            match offaxis::off_axis_perspective(ll, lr, ur, eye) {
                Ok(fit) => {
                    write_fit(&fit, position, direction, up, fovy, aspect, image_region);
                    ANARI_STATUS_NO_ERROR
                }
                Err(_) => ANARI_STATUS_INVALID_ARGUMENT,
            }
        },
    )
}

/// Strategy 3: recovers eye and screen from an application's view and projection matrices
/// (column-major float[16]) and returns the equivalent "perspective" camera parameters.
/// Matrices that are not a perspective frustum (orthographic, singular, non-finite) are rejected.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub extern "C" fn cavetracePerspectiveFromMatrices(
    view: *const f32,
    proj: *const f32,
    position: *mut f32,
    direction: *mut f32,
    up: *mut f32,
    fovy: *mut f32,
    aspect: *mut f32,
    image_region: *mut f32,
) -> ANARIStatusCode {
    guard(
        "cavetracePerspectiveFromMatrices",
        std::ptr::null_mut(),
        ANARI_STATUS_UNKNOWN_ERROR,
        || {
            let (Some(view), Some(proj)) = (mat4(view), mat4(proj)) else {
                return ANARI_STATUS_INVALID_ARGUMENT;
            };
            if [position, direction, up, fovy, aspect, image_region]
                .iter()
                .any(|p| p.is_null())
            {
                return ANARI_STATUS_INVALID_ARGUMENT;
            }
            match offaxis::perspective_from_matrices(view, proj) {
                Ok(fit) => {
                    write_fit(&fit, position, direction, up, fovy, aspect, image_region);
                    ANARI_STATUS_NO_ERROR
                }
                Err(_) => ANARI_STATUS_INVALID_ARGUMENT,
            }
        },
    )
}
