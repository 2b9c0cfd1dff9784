//! Lights: directional, point, spot, ring, quad and hdri, evaluated in world space. A
//! directional light with an `angularDiameter`, a point light with a `radius`, a ring with a
//! radius, a quad light and an environment (hdri) have extent and cast soft shadows: they are
//! sampled per pixel sample (see `LightSampling`).

use std::f32::consts::{FRAC_1_PI, PI, TAU};

use std::sync::Arc;

use glam::{Affine3A, Vec2, Vec3};

use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::params::ParamSet;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::attributes::read_values;
use crate::scene::environment::EnvironmentMap;

const COLOR: ParamSpec = ParamSpec::new("color", &[ANARI_FLOAT32_VEC3], "light colour")
    .default(SpecValue::Floats(&[1.0, 1.0, 1.0]))
    .range(
        SpecValue::Floats(&[0.0, 0.0, 0.0]),
        SpecValue::Floats(&[1.0, 1.0, 1.0]),
    );

const INTENSITY: ParamSpec =
    ParamSpec::new("intensity", &[ANARI_FLOAT32], "radiant intensity (W/sr)")
        .default(SpecValue::Float(1.0))
        .range(SpecValue::Float(0.0), SpecValue::None);
const POWER: ParamSpec = ParamSpec::new(
    "power",
    &[ANARI_FLOAT32],
    "total emitted power (W); overrides intensity",
)
.range(SpecValue::Float(0.0), SpecValue::None);

const RADIANCE: ParamSpec = ParamSpec::new(
    "radiance",
    &[ANARI_FLOAT32],
    "radiance of the light's surface (W/sr/m²); overrides the other strengths when the light \
     has extent",
)
.range(SpecValue::Float(0.0), SpecValue::None);

// The emission cone of spot and ring lights.
const OPENING_ANGLE: ParamSpec = ParamSpec::new(
    "openingAngle",
    &[ANARI_FLOAT32],
    "full opening angle of the cone (radians)",
)
.default(SpecValue::Float(PI));
const FALLOFF_ANGLE: ParamSpec = ParamSpec::new(
    "falloffAngle",
    &[ANARI_FLOAT32],
    "angle over which intensity falls to zero inside the cone edge (radians)",
)
.default(SpecValue::Float(0.1));

pub const DIRECTIONAL: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "directional",
    "light from one direction, at infinity; a disk of angularDiameter casts soft shadows",
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
        .default(SpecValue::Float(1.0))
        .range(SpecValue::Float(0.0), SpecValue::None),
        ParamSpec::new(
            "angularDiameter",
            &[ANARI_FLOAT32],
            "apparent diameter of the light's disk (radians)",
        )
        .default(SpecValue::Float(0.0))
        .range(SpecValue::Float(0.0), SpecValue::Float(PI)),
        RADIANCE,
    ],
)
.extensions(&["ANARI_KHR_LIGHT_DIRECTIONAL"]);

pub const POINT: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "point",
    "point light; a radius makes it a sphere light with soft shadows",
    &[
        COLOR,
        ParamSpec::new("position", &[ANARI_FLOAT32_VEC3], "light position")
            .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        INTENSITY,
        POWER,
        ParamSpec::new("radius", &[ANARI_FLOAT32], "radius of the sphere light")
            .default(SpecValue::Float(0.0))
            .range(SpecValue::Float(0.0), SpecValue::None),
        RADIANCE,
    ],
)
.extensions(&["ANARI_KHR_LIGHT_POINT"]);

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
        OPENING_ANGLE,
        FALLOFF_ANGLE,
        INTENSITY,
        POWER,
    ],
)
.extensions(&["ANARI_KHR_LIGHT_SPOT"]);

pub const QUAD: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "quad",
    "a parallelogram emitting like a diffuse surface (the same radiance in every direction) \
     from one side or both; soft shadows",
    &[
        COLOR,
        ParamSpec::new("position", &[ANARI_FLOAT32_VEC3], "a corner of the quad")
            .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new("edge1", &[ANARI_FLOAT32_VEC3], "vector of the first edge")
            .default(SpecValue::Floats(&[1.0, 0.0, 0.0])),
        ParamSpec::new("edge2", &[ANARI_FLOAT32_VEC3], "vector of the second edge")
            .default(SpecValue::Floats(&[0.0, 1.0, 0.0])),
        ParamSpec::new(
            "intensity",
            &[ANARI_FLOAT32],
            "radiant intensity (W/sr) along the quad's normal: radiance × area",
        )
        .default(SpecValue::Float(1.0))
        .range(SpecValue::Float(0.0), SpecValue::None),
        POWER,
        RADIANCE,
        ParamSpec::new(
            "side",
            &[ANARI_STRING],
            "emitting sides: front (the side edge1 × edge2 points to), back or both",
        )
        .default(SpecValue::Str("front"))
        .values(&["front", "back", "both"]),
    ],
)
.extensions(&["ANARI_KHR_LIGHT_QUAD"])
.unsupported(&["intensityDistribution"]);

pub const RING: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "ring",
    "a spot light spread over a ring (an annulus facing direction): each of its points \
     emits as the spot would; soft shadows",
    &[
        COLOR,
        ParamSpec::new("position", &[ANARI_FLOAT32_VEC3], "centre of the ring")
            .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new(
            "direction",
            &[ANARI_FLOAT32_VEC3],
            "the ring's axis, the main emission direction",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, -1.0])),
        OPENING_ANGLE,
        FALLOFF_ANGLE,
        ParamSpec::new(
            "intensity",
            &[ANARI_FLOAT32],
            "radiant intensity (W/sr) of the whole ring along its axis",
        )
        .default(SpecValue::Float(1.0))
        .range(SpecValue::Float(0.0), SpecValue::None),
        POWER,
        ParamSpec::new("radius", &[ANARI_FLOAT32], "outer radius of the ring")
            .default(SpecValue::Float(0.0))
            .range(SpecValue::Float(0.0), SpecValue::None),
        ParamSpec::new("innerRadius", &[ANARI_FLOAT32], "inner radius of the ring")
            .default(SpecValue::Float(0.0))
            .range(SpecValue::Float(0.0), SpecValue::None),
        ParamSpec::new(
            "radiance",
            &[ANARI_FLOAT32],
            "radiance of the ring along its axis (W/sr/m²): intensity = radiance × area; \
             overrides the other strengths when the ring has area",
        )
        .range(SpecValue::Float(0.0), SpecValue::None),
    ],
)
.extensions(&["ANARI_KHR_LIGHT_RING"])
.unsupported(&["intensityDistribution", "c0"]);

pub const HDRI: ObjectSpec = ObjectSpec::new(
    ANARI_LIGHT,
    "hdri",
    "light from an environment image around the scene (equirectangular), sampled by \
     luminance; not seen by camera rays",
    &[
        COLOR,
        ParamSpec::new(
            "up",
            &[ANARI_FLOAT32_VEC3],
            "direction of the image's first row (its top edge)",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, 1.0])),
        ParamSpec::new(
            "direction",
            &[ANARI_FLOAT32_VEC3],
            "direction the image's centre is seen in",
        )
        .default(SpecValue::Floats(&[1.0, 0.0, 0.0])),
        ParamSpec::new(
            "radiance",
            &[ANARI_ARRAY2D],
            "radiance image (W/sr/m²); columns run around up from direction towards \
             direction × up, rows from up down",
        )
        .elements(&[ANARI_FLOAT32_VEC3])
        .required(),
        ParamSpec::new("layout", &[ANARI_STRING], "image layout")
            .default(SpecValue::Str("equirectangular"))
            .values(&["equirectangular"]),
        ParamSpec::new("scale", &[ANARI_FLOAT32], "factor on the radiance")
            .default(SpecValue::Float(1.0))
            .range(SpecValue::Float(0.0), SpecValue::None),
    ],
)
.extensions(&["ANARI_KHR_LIGHT_HDRI"]);

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
    },
    /// `radius` > 0 makes it a sphere light of the same intensity seen from afar.
    Point {
        position: Vec3,
        intensity: Vec3,
        radius: f32,
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
    },
    /// An environment map (colour and scale included) with its frame's axes in world space:
    /// `forward` (the image centre), `up` (its first row), `right` = forward × up.
    Hdri {
        map: Arc<EnvironmentMap>,
        forward: Vec3,
        up: Vec3,
        right: Vec3,
    },
}

/// What one light contributes at a point: direction towards the light, distance and radiance.
/// For a light with extent, one sample of it: `radiance` is the estimate (radiance over the
/// sample's probability), so `radiance × cos` averages to the irradiance.
pub struct Incoming {
    pub to_light: Vec3,
    pub distance: f32,
    pub radiance: Vec3,
}

/// Which point of a light with extent one shading sample uses: a 2D Halton point (bases 11
/// and 13, independent of the pixel and lens sequences) for the pixel sample index, rotated by
/// a per-pixel offset so neighbouring pixels do not share shadow patterns. Successive samples
/// and accumulated frames cover the light evenly, so soft shadows converge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSampling {
    pub index: u32,
    pub scramble: Vec2,
}

impl LightSampling {
    /// The sampling for sample `index` of pixel (`x`, `y`).
    pub fn for_pixel(index: u32, x: u32, y: u32) -> LightSampling {
        let hash = mix(x.wrapping_mul(0x9E37_79B9) ^ mix(y.wrapping_add(0x7F4A_7C15)));
        let unit = |bits: u32| (bits >> 8) as f32 * (1.0 / (1u32 << 24) as f32);
        LightSampling {
            index,
            scramble: Vec2::new(unit(hash), unit(mix(hash ^ 0x68E3_1DA4))),
        }
    }

    /// The point in [0,1)² for this sample.
    pub fn point(&self) -> Vec2 {
        let halton = Vec2::new(
            radical_inverse(self.index, 11),
            radical_inverse(self.index, 13),
        );
        let p = (halton + self.scramble).fract();
        // fract can round up to 1.0 for tiny negative offsets; keep the half-open range.
        p.min(Vec2::splat(1.0 - f32::EPSILON))
    }
}

impl LightSampling {
    /// The point in [0,1)² that picks a glossy reflection at bounce `depth` (0: the camera
    /// ray's hit). The first bounce follows Roberts' R2 sequence (an additive recurrence by
    /// the plastic number, low-discrepancy and independent of the Halton bases above) by
    /// sample index alone, the same in every pixel: pixelSamples and accumulated frames cover
    /// the lobe evenly, and the two eyes of a stereo pair reflect a surface point alike
    /// (cyclopean lighting). Deeper bounces hash the index, the pixel and the depth, so each
    /// bounce's choice is independent of those above it (a product of bounces needs that).
    pub fn reflection_point(&self, depth: u32) -> Vec2 {
        if depth == 0 {
            let unit = |bits: u32| (bits >> 8) as f32 * (1.0 / (1u32 << 24) as f32);
            // 2³² / ρ and 2³² / ρ², ρ the plastic number: the recurrence in fixed point, exact
            // modulo 1 for any index.
            return Vec2::new(
                unit(self.index.wrapping_mul(3_242_174_889)),
                unit(self.index.wrapping_mul(2_447_445_414)),
            );
        }
        let mut more = self.reflection_numbers(depth);
        Vec2::new(more(), more())
    }

    /// Further numbers in [0,1) for the glossy reflection at bounce `depth` (its acceptance and
    /// redraws): hashed from the sample index and the depth, and below the first bounce the
    /// pixel (see [`LightSampling::reflection_point`]).
    pub fn reflection_numbers(&self, depth: u32) -> impl FnMut() -> f32 {
        let pixel = if depth == 0 {
            0
        } else {
            mix(self.scramble.x.to_bits() ^ mix(self.scramble.y.to_bits()))
        };
        let mut state = mix(self.index ^ mix(pixel ^ mix(depth.wrapping_add(0x3C6E_F372))));
        move || {
            state = mix(state.wrapping_add(0x9E37_79B9));
            (state >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
        }
    }
}

impl Default for LightSampling {
    /// Sample 0 with no scramble: the centre-weighted first Halton point.
    fn default() -> LightSampling {
        LightSampling {
            index: 0,
            scramble: Vec2::splat(0.5),
        }
    }
}

/// A 32-bit integer hash (lowbias32), good enough to decorrelate pixels.
fn mix(mut v: u32) -> u32 {
    v ^= v >> 16;
    v = v.wrapping_mul(0x7FEB_352D);
    v ^= v >> 15;
    v = v.wrapping_mul(0x846C_A68B);
    v ^ (v >> 16)
}

fn radical_inverse(mut i: u32, base: u32) -> f32 {
    let inverse = 1.0 / base as f64;
    let mut scale = inverse;
    let mut value = 0.0f64;
    while i > 0 {
        value += (i % base) as f64 * scale;
        i /= base;
        scale *= inverse;
    }
    value as f32
}

/// A direction in the cone of half-angle acos(`cos_max`) around unit `axis`, uniform in solid
/// angle, for `u` in [0,1)².
fn sample_cone(axis: Vec3, cos_max: f32, u: Vec2) -> Vec3 {
    let cos_theta = 1.0 - u.x * (1.0 - cos_max);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = TAU * u.y;
    let (tangent, bitangent) = axis.any_orthonormal_pair();
    (tangent * (sin_theta * phi.cos()) + bitangent * (sin_theta * phi.sin()) + axis * cos_theta)
        .normalize()
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

/// A parameter that must be finite and within [0, `maximum`]: `Err` names what was wrong.
fn checked(
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
fn checked_params(subtype: &str) -> &'static [(&'static str, Option<(f32, &'static str)>)] {
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
fn valid(params: &ParamSet, name: &str, subtype: &str) -> Option<f32> {
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
            } => Light::Directional {
                direction: transform
                    .transform_vector3(direction)
                    .normalize_or(direction),
                irradiance,
                cos_half_angle,
            },
            Light::Point {
                position,
                intensity,
                radius,
            } => Light::Point {
                position: transform.transform_point3(position),
                intensity,
                radius,
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
            } => Light::Quad {
                position: transform.transform_point3(position),
                edge1: transform.transform_vector3(edge1),
                edge2: transform.transform_vector3(edge2),
                radiance,
                side,
            },
            Light::Ring {
                position,
                direction,
                intensity,
                cos_outer,
                cos_inner,
                inner,
                outer,
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
            },
            // The environment turns with the instance (a degenerate transform leaves it).
            Light::Hdri {
                ref map,
                forward,
                up,
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

    /// Light arriving at `point`, before visibility. Lights with extent are sampled at
    /// `sampling`'s point; lights without ignore it.
    pub fn incoming_sampled(&self, point: Vec3, sampling: &LightSampling) -> Option<Incoming> {
        match *self {
            Light::Directional {
                direction,
                irradiance,
                cos_half_angle,
            } if cos_half_angle < 1.0 => {
                // Radiance E/(π sin²θ) over the pdf 1/(2π(1−cos θ)) is 2E/(1+cos θ).
                Some(Incoming {
                    to_light: sample_cone(-direction, cos_half_angle, sampling.point()),
                    distance: f32::INFINITY,
                    radiance: irradiance * (2.0 / (1.0 + cos_half_angle)),
                })
            }
            Light::Point {
                position,
                intensity,
                radius,
            } if radius > 0.0 => {
                let axis = position - point;
                let centre_distance = axis.length();
                // Inside the sphere there is no surface facing in; nothing is lit.
                if centre_distance <= radius {
                    return None;
                }
                let axis = axis / centre_distance;
                let sin2_max = (radius / centre_distance).powi(2);
                let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
                let to_light = sample_cone(axis, cos_max, sampling.point());
                // Distance to the near side of the sphere along the sampled direction.
                let along = centre_distance * to_light.dot(axis);
                let across2 = (centre_distance * centre_distance - along * along).max(0.0);
                let distance = along - (radius * radius - across2).max(0.0).sqrt();
                let sphere_radiance = intensity * (FRAC_1_PI / (radius * radius));
                // 1 − cos θ written so that tiny spheres do not cancel to zero.
                let solid_angle = TAU * sin2_max / (1.0 + cos_max);
                Some(Incoming {
                    to_light,
                    distance: distance.max(0.0),
                    radiance: sphere_radiance * solid_angle,
                })
            }
            Light::Quad { .. } => self.quad_incoming(point, sampling.point()),
            Light::Ring {
                position,
                direction,
                outer,
                inner,
                ..
            } if outer > 0.0 => {
                // A point of the annulus, uniform by area.
                let u = sampling.point();
                let radius = (inner * inner + u.x * (outer * outer - inner * inner)).sqrt();
                let (tangent, bitangent) = direction.any_orthonormal_pair();
                let angle = TAU * u.y;
                let on_ring = position + (tangent * angle.cos() + bitangent * angle.sin()) * radius;
                self.spot_from(on_ring, point)
            }
            Light::Hdri {
                ref map,
                forward,
                up,
                right,
            } => {
                let sample = map.sample(sampling.point())?;
                let d = sample.direction;
                Some(Incoming {
                    to_light: (forward * d.x + up * d.y + right * d.z).normalize(),
                    distance: f32::INFINITY,
                    radiance: sample.radiance,
                })
            }
            _ => self.incoming(point),
        }
    }

    /// A ring light's emission from its point `from` to `point`: the spot light's, at `from`.
    fn spot_from(&self, from: Vec3, point: Vec3) -> Option<Incoming> {
        let Light::Ring {
            direction,
            intensity,
            cos_outer,
            cos_inner,
            ..
        } = *self
        else {
            return None;
        };
        Light::Spot {
            position: from,
            direction,
            intensity,
            cos_outer,
            cos_inner,
        }
        .incoming(point)
    }

    /// One sample of a quad light seen from `point`: the quad's point at `(u, v)`, chosen
    /// uniformly by area; the radiance estimate is L·cos θ_light·A / d² (the area density
    /// turned into one per solid angle).
    fn quad_incoming(&self, point: Vec3, uv: Vec2) -> Option<Incoming> {
        let Light::Quad {
            position,
            edge1,
            edge2,
            radiance,
            side,
        } = *self
        else {
            return None;
        };
        let on_light = position + edge1 * uv.x + edge2 * uv.y;
        let d = on_light - point;
        let distance = d.length();
        // NaN distances (a non-finite point) fail this too.
        if distance.is_nan() || distance <= 0.0 {
            return None;
        }
        let to_light = d / distance;
        let normal_area = edge1.cross(edge2);
        // cos θ_light × area: the front side faces along edge1 × edge2.
        let facing = -to_light.dot(normal_area);
        let projected = match side {
            QuadSide::Front => facing,
            QuadSide::Back => -facing,
            QuadSide::Both => facing.abs(),
        };
        (projected > 0.0).then(|| Incoming {
            to_light,
            distance,
            radiance: radiance * (projected / (distance * distance)),
        })
    }

    /// Light arriving at `point` from the light's centre, before visibility.
    pub fn incoming(&self, point: Vec3) -> Option<Incoming> {
        match *self {
            Light::Directional {
                direction,
                irradiance,
                ..
            } => Some(Incoming {
                to_light: -direction,
                distance: f32::INFINITY,
                radiance: irradiance,
            }),
            Light::Point {
                position,
                intensity,
                ..
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
            // From its centre.
            Light::Quad { .. } => self.quad_incoming(point, Vec2::splat(0.5)),
            Light::Ring { position, .. } => self.spot_from(position, point),
            // An environment has no one direction: a fixed sample of it.
            Light::Hdri { .. } => self.incoming_sampled(point, &LightSampling::default()),
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
            radius: 0.0,
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

    /// Mean of radiance × cos over many samples at a point facing the light.
    fn mean_irradiance(light: &Light, point: Vec3, normal: Vec3, samples: u32) -> f32 {
        let sum: f32 = (0..samples)
            .map(|index| {
                let sampling = LightSampling {
                    index,
                    scramble: Vec2::new(0.3, 0.7),
                };
                let i = light.incoming_sampled(point, &sampling).unwrap();
                i.radiance.x * normal.dot(i.to_light).max(0.0)
            })
            .sum();
        sum / samples as f32
    }

    #[test]
    fn a_disk_light_gives_its_irradiance_on_average() {
        let light = Light::Directional {
            direction: Vec3::NEG_Z,
            irradiance: Vec3::splat(2.0),
            cos_half_angle: 0.3f32.cos(),
        };
        let e = mean_irradiance(&light, Vec3::ZERO, Vec3::Z, 4096);
        assert!((e - 2.0).abs() < 2e-3, "{e}");
        // Tilted by 45°, with the whole disk above the horizon: E·cos 45°.
        let tilted = Vec3::new(1.0, 0.0, 1.0).normalize();
        let e = mean_irradiance(&light, Vec3::ZERO, tilted, 4096);
        assert!((e - 2.0 * 0.5f32.sqrt()).abs() < 2e-3, "{e}");
    }

    #[test]
    fn a_sphere_light_matches_a_point_light_of_the_same_intensity() {
        let light = Light::Point {
            position: Vec3::new(0.0, 0.0, 2.0),
            intensity: Vec3::splat(4.0),
            radius: 0.5,
        };
        let e = mean_irradiance(&light, Vec3::ZERO, Vec3::Z, 4096);
        assert!((e - 1.0).abs() < 1e-3, "{e}");
        let i = light
            .incoming_sampled(Vec3::ZERO, &LightSampling::default())
            .unwrap();
        // Samples end on the sphere's near surface.
        let end = i.to_light * i.distance;
        assert!(((end - Vec3::new(0.0, 0.0, 2.0)).length() - 0.5).abs() < 1e-5);
        assert!(i.distance < 2.0);
        assert!(
            light
                .incoming_sampled(Vec3::new(0.0, 0.0, 1.8), &LightSampling::default())
                .is_none()
        );
    }

    #[test]
    fn light_samples_stay_in_the_unit_square_and_differ_between_pixels() {
        for index in 0..256 {
            let p = LightSampling::for_pixel(index, 5, 9).point();
            assert!(p.cmpge(Vec2::ZERO).all() && p.cmplt(Vec2::ONE).all(), "{p}");
        }
        assert_ne!(
            LightSampling::for_pixel(0, 0, 0).scramble,
            LightSampling::for_pixel(0, 1, 0).scramble
        );
    }

    static REPORTED: std::sync::Mutex<Vec<(i32, String)>> = std::sync::Mutex::new(Vec::new());

    unsafe extern "C" fn remember(
        _: *const std::ffi::c_void,
        _: *mut std::ffi::c_void,
        _: *mut std::ffi::c_void,
        _: ANARIDataType,
        _: crate::device::status::ANARIStatusSeverity,
        code: crate::device::status::ANARIStatusCode,
        message: *const std::ffi::c_char,
    ) {
        // SAFETY: the device passes a valid C string.
        let text = unsafe { std::ffi::CStr::from_ptr(message) }.to_string_lossy();
        REPORTED.lock().unwrap().push((code, text.into_owned()));
    }

    #[test]
    fn commit_reports_bad_values_and_build_ignores_them() {
        use crate::device::IncomingValue;
        let device = Device::new(Some(remember), 0);
        let handle = device.new_object("anariNewLight", ANARI_LIGHT, "point");
        let set = |name: &str, value: f32| {
            let bytes = value.to_ne_bytes().to_vec();
            device.set_parameter(
                "anariSetParameter",
                handle,
                name,
                ANARI_FLOAT32,
                IncomingValue::Data(bytes),
            );
        };
        set("power", -2.0);
        set("radius", f32::NAN);
        set("radiance", 3.0);
        device.commit("anariCommitParameters", handle);
        let object = device.lookup(handle).unwrap();
        REPORTED.lock().unwrap().clear();
        commit(&device, &object);
        let reported = std::mem::take(&mut *REPORTED.lock().unwrap());
        let has = |code: i32, words: &[&str]| {
            reported
                .iter()
                .any(|(c, t)| *c == code && words.iter().all(|w| t.contains(w)))
        };
        assert!(
            has(
                ANARI_STATUS_INVALID_ARGUMENT,
                &["light 'point'", "'power'", "-2"]
            ),
            "{reported:?}"
        );
        assert!(
            has(ANARI_STATUS_INVALID_ARGUMENT, &["'radius'", "NaN"]),
            "{reported:?}"
        );
        // The radius is invalid, so the light has no extent and its radiance is unused.
        assert!(
            has(
                crate::device::status::ANARI_STATUS_NO_ERROR,
                &["'radiance'", "'radius' > 0"]
            ),
            "{reported:?}"
        );
        assert_eq!(reported.len(), 3, "{reported:?}");
        assert_eq!(
            Light::build(&object),
            Some(Light::Point {
                position: Vec3::ZERO,
                intensity: Vec3::ONE,
                radius: 0.0,
            })
        );
        device.release("anariRelease", handle);
    }
}
