//! Lights: directional, point and spot, evaluated in world space.

use glam::{Affine3A, Vec3};

use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};

const COLOR: ParamSpec = ParamSpec::new("color", &[ANARI_FLOAT32_VEC3], "light colour")
    .default(SpecValue::Floats(&[1.0, 1.0, 1.0]))
    .range(
        SpecValue::Floats(&[0.0, 0.0, 0.0]),
        SpecValue::Floats(&[1.0, 1.0, 1.0]),
    );

pub const DIRECTIONAL: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "directional",
    "light from one direction, at infinity",
    &[
        COLOR,
        ParamSpec::new(
            "direction",
            &[ANARI_FLOAT32_VEC3],
            "direction the light travels",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, -1.0])),
        ParamSpec::new(
            "irradiance",
            &[ANARI_FLOAT32],
            "power per area arriving at a surface facing the light",
        )
        .default(SpecValue::Float(1.0)),
    ],
);

pub const POINT: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "point",
    "point light",
    &[
        COLOR,
        ParamSpec::new("position", &[ANARI_FLOAT32_VEC3], "light position")
            .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new("intensity", &[ANARI_FLOAT32], "radiant intensity (W/sr)")
            .default(SpecValue::Float(1.0)),
    ],
);

pub const SPOT: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "spot",
    "spot light with a smooth falloff at the edge of its cone",
    &[
        COLOR,
        ParamSpec::new("position", &[ANARI_FLOAT32_VEC3], "light position")
            .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new(
            "direction",
            &[ANARI_FLOAT32_VEC3],
            "main emission direction",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, -1.0])),
        ParamSpec::new(
            "openingAngle",
            &[ANARI_FLOAT32],
            "full opening angle of the cone (radians)",
        )
        .default(SpecValue::Float(std::f32::consts::PI)),
        ParamSpec::new(
            "falloffAngle",
            &[ANARI_FLOAT32],
            "angle over which intensity falls to zero inside the cone edge (radians)",
        )
        .default(SpecValue::Float(0.1)),
        ParamSpec::new("intensity", &[ANARI_FLOAT32], "radiant intensity (W/sr)")
            .default(SpecValue::Float(1.0)),
    ],
);

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// `direction` is where the light travels (unit); radiance arriving = color × irradiance.
    Directional {
        direction: Vec3,
        radiance: Vec3,
    },
    Point {
        position: Vec3,
        intensity: Vec3,
    },
    Spot {
        position: Vec3,
        direction: Vec3,
        intensity: Vec3,
        /// cos of half the opening angle, and cos where the falloff starts.
        cos_outer: f32,
        cos_inner: f32,
    },
}

/// What one light contributes at a point: direction towards the light, distance and radiance.
pub struct Incoming {
    pub to_light: Vec3,
    pub distance: f32,
    pub radiance: Vec3,
}

impl Light {
    pub fn build(object: &Object) -> Option<Light> {
        let p = object.committed();
        let color = p.get_vec3("color").unwrap_or(Vec3::ONE);
        let direction = p
            .get_vec3("direction")
            .unwrap_or(Vec3::NEG_Z)
            .try_normalize()
            .unwrap_or(Vec3::NEG_Z);
        let position = p.get_vec3("position").unwrap_or(Vec3::ZERO);
        let intensity = color * p.get_f32("intensity").unwrap_or(1.0);
        Some(match object.subtype.as_str() {
            "directional" => Light::Directional {
                direction,
                radiance: color * p.get_f32("irradiance").unwrap_or(1.0),
            },
            "point" => Light::Point {
                position,
                intensity,
            },
            "spot" => {
                let half = 0.5 * p.get_f32("openingAngle").unwrap_or(std::f32::consts::PI);
                let falloff = p.get_f32("falloffAngle").unwrap_or(0.1).max(0.0);
                Light::Spot {
                    position,
                    direction,
                    intensity,
                    cos_outer: half.cos(),
                    cos_inner: (half - falloff).max(0.0).cos(),
                }
            }
            _ => return None,
        })
    }

    /// The light moved into world space by an instance transform.
    pub fn transformed(&self, transform: &Affine3A) -> Light {
        match *self {
            Light::Directional {
                direction,
                radiance,
            } => Light::Directional {
                direction: transform
                    .transform_vector3(direction)
                    .normalize_or(direction),
                radiance,
            },
            Light::Point {
                position,
                intensity,
            } => Light::Point {
                position: transform.transform_point3(position),
                intensity,
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
        }
    }

    /// Light arriving at `point`, before visibility.
    pub fn incoming(&self, point: Vec3) -> Option<Incoming> {
        match *self {
            Light::Directional {
                direction,
                radiance,
            } => Some(Incoming {
                to_light: -direction,
                distance: f32::INFINITY,
                radiance,
            }),
            Light::Point {
                position,
                intensity,
            } => {
                let d = position - point;
                let distance = d.length();
                (distance > 0.0).then(|| Incoming {
                    to_light: d / distance,
                    distance,
                    radiance: intensity / (distance * distance),
                })
            }
            Light::Spot {
                position,
                direction,
                intensity,
                cos_outer,
                cos_inner,
            } => {
                let d = position - point;
                let distance = d.length();
                if distance <= 0.0 {
                    return None;
                }
                let to_light = d / distance;
                let cos_angle = (-to_light).dot(direction);
                if cos_angle <= cos_outer {
                    return None;
                }
                let edge = if cos_inner > cos_outer {
                    ((cos_angle - cos_outer) / (cos_inner - cos_outer)).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                let smooth = edge * edge * (3.0 - 2.0 * edge);
                Some(Incoming {
                    to_light,
                    distance,
                    radiance: intensity * smooth / (distance * distance),
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_light_falls_off_with_distance_squared() {
        let light = Light::Point {
            position: Vec3::new(0.0, 2.0, 0.0),
            intensity: Vec3::splat(4.0),
        };
        let i = light.incoming(Vec3::ZERO).unwrap();
        assert_eq!(i.to_light, Vec3::Y);
        assert_eq!(i.distance, 2.0);
        assert_eq!(i.radiance, Vec3::splat(1.0));
    }

    #[test]
    fn spot_light_cuts_off_outside_its_cone() {
        let light = Light::Spot {
            position: Vec3::new(0.0, 1.0, 0.0),
            direction: Vec3::NEG_Y,
            intensity: Vec3::ONE,
            cos_outer: (0.5f32).cos(),
            cos_inner: (0.4f32).cos(),
        };
        assert!(light.incoming(Vec3::ZERO).is_some());
        // 45° off axis is outside a half-angle of 0.5 rad.
        assert!(light.incoming(Vec3::new(1.0, 0.0, 0.0)).is_none());
    }
}
