//! Commit checks of lights: strengths and sizes that are negative or not finite, and
//! parameters a light cannot use, are reported and ignored.

use std::f32::consts::PI;

use glam::Vec3;

use crate::device::Device;
use crate::device::object::Object;
use crate::device::params::ParamSet;
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;

use super::Light;

/// A parameter that must be finite and within [0, `maximum`]: `Err` names what was wrong.
pub(super) fn checked(
    params: &ParamSet,
    name: &str,
    maximum: Option<(f32, &str)>,
) -> Result<Option<f32>, String> {
    let Some(value) = params.get_f32(name) else {
        return Ok(None);
    };
    if !value.is_finite() || value < 0.0 {
        return Err(format!(
            "parameter '{name}' is {value}, expected a finite value ≥ 0"
        ));
    }
    if let Some((max, max_name)) = maximum
        && value > max
    {
        return Err(format!(
            "parameter '{name}' is {value}, expected at most {max_name}"
        ));
    }
    Ok(Some(value))
}

/// The non-negative scalar parameters each light subtype checks, with their upper bounds.
pub(super) fn checked_params(
    subtype: &str,
) -> &'static [(&'static str, Option<(f32, &'static str)>)] {
    match subtype {
        "directional" => &[
            ("irradiance", None),
            ("angularDiameter", Some((PI, "π"))),
            ("radiance", None),
        ],
        "point" => &[
            ("intensity", None),
            ("power", None),
            ("radius", None),
            ("radiance", None),
        ],
        "spot" => &[("intensity", None), ("power", None)],
        "quad" => &[("intensity", None), ("power", None), ("radiance", None)],
        "hdri" => &[("scale", None)],
        "ring" => &[
            ("intensity", None),
            ("power", None),
            ("radius", None),
            ("innerRadius", None),
            ("radiance", None),
        ],
        _ => &[],
    }
}

/// A checked parameter's value, or `None` when unset or invalid (invalid values are ignored;
/// `commit` reports them).
pub(super) fn valid(params: &ParamSet, name: &str, subtype: &str) -> Option<f32> {
    let maximum = checked_params(subtype)
        .iter()
        .find(|(n, _)| *n == name)
        .and_then(|(_, m)| *m);
    checked(params, name, maximum).ok().flatten()
}

/// Reports light parameters that will be ignored: negative, NaN or infinite strengths and
/// sizes, and a radiance on a light without extent.
pub fn commit(device: &Device, object: &Object) {
    let params = object.committed();
    let subtype = object.subtype.as_str();
    for (name, maximum) in checked_params(subtype) {
        if let Err(what) = checked(&params, name, *maximum) {
            device.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                Some(object),
                format!(
                    "anariCommitParameters: {} {what}; it is ignored",
                    object.describe()
                ),
            );
        }
    }
    if subtype == "hdri" {
        if Light::build(object).is_none() {
            device.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                Some(object),
                format!(
                    "anariCommitParameters: {} needs 'radiance' (an ARRAY2D of FLOAT32_VEC3 with \
                     some light in it) and 'up' and 'direction' that are not parallel; it emits \
                     nothing",
                    object.describe()
                ),
            );
        }
        return;
    }
    if subtype == "quad" {
        let edge = |name: &str, default: Vec3| params.get_vec3(name).unwrap_or(default);
        let area = edge("edge1", Vec3::X)
            .cross(edge("edge2", Vec3::Y))
            .length();
        if !(area.is_finite() && area > 0.0) {
            device.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                Some(object),
                format!(
                    "anariCommitParameters: {} parameters 'edge1' and 'edge2' span no area \
                     (parallel, zero or not finite); the light emits nothing",
                    object.describe()
                ),
            );
        }
        if let Some(side) = params.get_string("side")
            && !["front", "back", "both"].contains(&side)
        {
            device.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                Some(object),
                format!(
                    "anariCommitParameters: {} parameter 'side' is '{side}', expected front, \
                     back or both; using front",
                    object.describe()
                ),
            );
        }
        return;
    }
    let extent = match subtype {
        "directional" => "angularDiameter",
        "point" => "radius",
        _ => return,
    };
    if valid(&params, "radiance", subtype).is_some()
        && valid(&params, extent, subtype).unwrap_or(0.0) == 0.0
    {
        device.warning(
            Some(object),
            format!(
                "anariCommitParameters: {} parameter 'radiance' needs '{extent}' > 0 (a light \
                 without extent emits no radiance); it is ignored",
                object.describe()
            ),
        );
    }
}
