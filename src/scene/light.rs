//! Lights: directional, point, spot, ring, quad and hdri, evaluated in world space. A
//! directional light with an `angularDiameter`, a point light with a `radius`, a ring with a
//! radius, a quad light and an environment (hdri) have extent and cast soft shadows: they are
//! sampled per pixel sample (see `LightSampling`). This file builds a committed light; its
//! parameter specs, commit checks and sampling live in the submodules.

mod emission;
mod sampling;
mod specs;
mod validate;

use std::f32::consts::{PI, TAU};
use std::sync::Arc;

use glam::{Affine3A, Vec3};

use crate::device::object::Object;
use crate::device::params::ParamSet;
use crate::scene::attributes::read_values;
use crate::scene::environment::EnvironmentMap;

pub use emission::Seen;
pub use sampling::{Incoming, LightSampling, radical_inverse};
pub use specs::{DIRECTIONAL, HDRI, POINT, QUAD, RING, SPOT};
pub use validate::commit;
use validate::valid;

/// Which sides of a quad light emit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QuadSide {
    Front,
    Back,
    Both,
}

#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    /// `direction` is where the light travels (unit). `irradiance` (colour included) arrives at
    /// a surface facing the light. `cos_half_angle` < 1 makes it a disk of that angular radius.
    Directional {
        direction: Vec3,
        irradiance: Vec3,
        cos_half_angle: f32,
        /// KHR_LIGHT_PRIMARY_VISIBILITY: whether camera rays see the disk.
        visible: bool,
    },
    /// `radius` > 0 makes it a sphere light of the same intensity seen from afar.
    Point {
        position: Vec3,
        intensity: Vec3,
        radius: f32,
        visible: bool,
    },
    Spot {
        position: Vec3,
        direction: Vec3,
        intensity: Vec3,
        /// cos of half the opening angle, and cos where the falloff starts.
        cos_outer: f32,
        cos_inner: f32,
    },
    /// The parallelogram `position + u·edge1 + v·edge2`, u, v in [0, 1], of `radiance`.
    Quad {
        position: Vec3,
        edge1: Vec3,
        edge2: Vec3,
        radiance: Vec3,
        side: QuadSide,
        visible: bool,
    },
    /// A spot light spread evenly over the annulus of radii `inner`..`outer` around
    /// `position` in the plane perpendicular to `direction` (radius 0: the spot light).
    Ring {
        position: Vec3,
        direction: Vec3,
        intensity: Vec3,
        cos_outer: f32,
        cos_inner: f32,
        inner: f32,
        outer: f32,
        visible: bool,
    },
    /// An environment map (colour and scale included) with its frame's axes in world space:
    /// `forward` (the image centre), `up` (its first row), `right` = forward × up.
    Hdri {
        map: Arc<EnvironmentMap>,
        forward: Vec3,
        up: Vec3,
        right: Vec3,
        visible: bool,
    },
}

/// A spot or ring light's cone: cos of half the opening angle, cos where the falloff starts,
/// and the cone's solid angle weighted by the smoothstep falloff (smooth in cos θ, so its
/// integral over the falloff band is half the band).
fn emission_cone(p: &ParamSet) -> (f32, f32, f32) {
    let half = 0.5 * p.get_f32("openingAngle").unwrap_or(PI);
    let falloff = p.get_f32("falloffAngle").unwrap_or(0.1).max(0.0);
    let (cos_outer, cos_inner) = (half.cos(), (half - falloff).max(0.0).cos());
    (
        cos_outer,
        cos_inner,
        TAU * (1.0 - 0.5 * (cos_inner + cos_outer)),
    )
}

/// The environment frame from `up` and `direction`: unit (forward, up, right = forward × up),
/// forward made perpendicular to up; `None` when they are parallel, zero or not finite.
fn environment_axes(up: Vec3, direction: Vec3) -> Option<(Vec3, Vec3, Vec3)> {
    let up = up.try_normalize()?;
    let forward = (direction - up * direction.dot(up)).try_normalize()?;
    Some((forward, up, forward.cross(up)))
}

impl Light {
    pub fn build(object: &Object) -> Option<Light> {
        let p = object.committed();
        let subtype = object.subtype.as_str();
        let valid = |name: &str| valid(&p, name, subtype);
        let color = p.get_vec3("color").unwrap_or(Vec3::ONE);
        let direction = p
            .get_vec3("direction")
            .unwrap_or(Vec3::NEG_Z)
            .try_normalize()
            .unwrap_or(Vec3::NEG_Z);
        let position = p.get_vec3("position").unwrap_or(Vec3::ZERO);
        let intensity = valid("intensity").unwrap_or(1.0);
        let visible = p.get_bool("visible").unwrap_or(true);
        Some(match subtype {
            "directional" => {
                let half_angle = 0.5 * valid("angularDiameter").unwrap_or(0.0);
                let sin_half = half_angle.sin();
                // A disk of radiance L seen under half-angle θ gives a facing surface the
                // irradiance L·π·sin²θ (its projected solid angle).
                let irradiance = match valid("radiance") {
                    Some(radiance) if half_angle > 0.0 => radiance * PI * sin_half * sin_half,
                    _ => valid("irradiance").unwrap_or(1.0),
                };
                Light::Directional {
                    direction,
                    irradiance: color * irradiance,
                    cos_half_angle: if half_angle > 0.0 {
                        half_angle.cos()
                    } else {
                        1.0
                    },
                    visible,
                }
            }
            "point" => {
                let radius = valid("radius").unwrap_or(0.0);
                // A sphere of radiance L has the intensity L·π·r² in every direction.
                let intensity = match (valid("radiance"), valid("power")) {
                    (Some(radiance), _) if radius > 0.0 => radiance * PI * radius * radius,
                    (_, Some(power)) => power / (2.0 * TAU),
                    _ => intensity,
                };
                Light::Point {
                    position,
                    intensity: color * intensity,
                    radius,
                    visible,
                }
            }
            "spot" => {
                let (cos_outer, cos_inner, solid_angle) = emission_cone(&p);
                let intensity = match valid("power") {
                    Some(power) if solid_angle > 0.0 => power / solid_angle,
                    Some(_) => 0.0,
                    None => intensity,
                };
                Light::Spot {
                    position,
                    direction,
                    intensity: color * intensity,
                    cos_outer,
                    cos_inner,
                }
            }
            "ring" => {
                let (cos_outer, cos_inner, solid_angle) = emission_cone(&p);
                let outer = valid("radius").unwrap_or(0.0);
                let inner = valid("innerRadius").unwrap_or(0.0).min(outer);
                let area = PI * (outer * outer - inner * inner);
                let intensity = match (valid("radiance"), valid("power")) {
                    (Some(radiance), _) if area > 0.0 => radiance * area,
                    (_, Some(power)) if solid_angle > 0.0 => power / solid_angle,
                    (_, Some(_)) => 0.0,
                    _ => intensity,
                };
                Light::Ring {
                    position,
                    direction,
                    intensity: color * intensity,
                    cos_outer,
                    cos_inner,
                    inner,
                    outer,
                    visible,
                }
            }
            "quad" => {
                let edge1 = p.get_vec3("edge1").unwrap_or(Vec3::X);
                let edge2 = p.get_vec3("edge2").unwrap_or(Vec3::Y);
                let area = edge1.cross(edge2).length();
                if !(area.is_finite() && area > 0.0 && position.is_finite()) {
                    return None;
                }
                let side = match p.get_string("side") {
                    Some("back") => QuadSide::Back,
                    Some("both") => QuadSide::Both,
                    _ => QuadSide::Front,
                };
                let sides = if side == QuadSide::Both { 2.0 } else { 1.0 };
                // A diffuse emitter of radiance L and area A: intensity L·A along its normal,
                // power L·A·π per emitting side.
                let radiance = match (valid("radiance"), valid("power")) {
                    (Some(radiance), _) => radiance,
                    (_, Some(power)) => power / (PI * area * sides),
                    _ => intensity / area,
                };
                Light::Quad {
                    position,
                    edge1,
                    edge2,
                    radiance: color * radiance,
                    side,
                    visible,
                }
            }
            "hdri" => {
                let array = p.get_object("radiance")?;
                let store = array.array.as_ref()?;
                let (width, height) = (store.dims[0] as usize, store.dims[1] as usize);
                let scale = color * valid("scale").unwrap_or(1.0);
                let texels = read_values(store)?
                    .into_iter()
                    .map(|texel| texel.truncate() * scale)
                    .collect();
                let map = EnvironmentMap::new(texels, width, height)?;
                let up = p.get_vec3("up").unwrap_or(Vec3::Z);
                let direction = p.get_vec3("direction").unwrap_or(Vec3::X);
                let (forward, up, right) = environment_axes(up, direction)?;
                Light::Hdri {
                    map: Arc::new(map),
                    forward,
                    up,
                    right,
                    visible,
                }
            }
            _ => return None,
        })
    }

    /// The light moved into world space by an instance transform. A sphere light keeps its
    /// radius (as its intensity is kept): transforms place lights, they do not resize them.
    pub fn transformed(&self, transform: &Affine3A) -> Light {
        match *self {
            Light::Directional {
                direction,
                irradiance,
                cos_half_angle,
                visible,
            } => Light::Directional {
                direction: transform
                    .transform_vector3(direction)
                    .normalize_or(direction),
                irradiance,
                cos_half_angle,
                visible,
            },
            Light::Point {
                position,
                intensity,
                radius,
                visible,
            } => Light::Point {
                position: transform.transform_point3(position),
                intensity,
                radius,
                visible,
            },
            Light::Spot {
                position,
                direction,
                intensity,
                cos_outer,
                cos_inner,
            } => Light::Spot {
                position: transform.transform_point3(position),
                direction: transform
                    .transform_vector3(direction)
                    .normalize_or(direction),
                intensity,
                cos_outer,
                cos_inner,
            },
            // A quad is placed and shaped by the transform; its radiance stays.
            Light::Quad {
                position,
                edge1,
                edge2,
                radiance,
                side,
                visible,
            } => Light::Quad {
                position: transform.transform_point3(position),
                edge1: transform.transform_vector3(edge1),
                edge2: transform.transform_vector3(edge2),
                radiance,
                side,
                visible,
            },
            Light::Ring {
                position,
                direction,
                intensity,
                cos_outer,
                cos_inner,
                inner,
                outer,
                visible,
            } => Light::Ring {
                position: transform.transform_point3(position),
                direction: transform
                    .transform_vector3(direction)
                    .normalize_or(direction),
                intensity,
                cos_outer,
                cos_inner,
                inner,
                outer,
                visible,
            },
            // The environment turns with the instance (a degenerate transform leaves it).
            Light::Hdri {
                ref map,
                forward,
                up,
                visible,
                ..
            } => {
                let turned = environment_axes(
                    transform.transform_vector3(up),
                    transform.transform_vector3(forward),
                );
                let (forward, up, right) = turned.unwrap_or((forward, up, forward.cross(up)));
                Light::Hdri {
                    map: map.clone(),
                    forward,
                    up,
                    right,
                    visible,
                }
            }
        }
    }

    /// Whether the light has extent (and so needs samples for its soft shadows).
    pub fn has_extent(&self) -> bool {
        match *self {
            Light::Directional { cos_half_angle, .. } => cos_half_angle < 1.0,
            Light::Point { radius, .. } => radius > 0.0,
            Light::Spot { .. } => false,
            Light::Ring { outer, .. } => outer > 0.0,
            Light::Quad { .. } | Light::Hdri { .. } => true,
        }
    }
}
