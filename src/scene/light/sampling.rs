//! Light sampling: the low-discrepancy point each shading sample uses on a light with extent,
//! and the light arriving at a point from one sample of a light.

use std::f32::consts::{FRAC_1_PI, TAU};

use glam::{Vec2, Vec3};

use super::{Light, QuadSide};

/// What one light contributes at a point: direction towards the light, distance and radiance.
/// For a light with extent, one sample of it: `radiance` is the estimate (radiance over the
/// sample's probability), so `radiance × cos` averages to the irradiance.
pub struct Incoming {
    pub to_light: Vec3,
    pub distance: f32,
    pub radiance: Vec3,
    /// For a light that rays leaving the scene also reach (an environment: an hdri light, a
    /// directional disk), the density per solid angle this sample was drawn with, so that it
    /// can be weighed against a reflection drawn towards the same light.
    pub pdf: Option<f32>,
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

impl LightSampling {
    /// The point in [0,1)² that picks the ambient-occlusion ray at bounce `depth`. At the
    /// camera ray's hit: Roberts' R2 sequence by sample index, shifted by a per-pixel offset
    /// (hashed from the light's, so the two are independent), so that pixelSamples and
    /// accumulated frames cover the hemisphere evenly while neighbouring pixels do not share a
    /// pattern. Deeper bounces hash the index, the pixel and the depth.
    pub fn ambient_point(&self, depth: u32) -> Vec2 {
        let unit = |bits: u32| (bits >> 8) as f32 * (1.0 / (1u32 << 24) as f32);
        if depth == 0 {
            let hash = mix(self.scramble.x.to_bits() ^ mix(self.scramble.y.to_bits() ^ 0xA0761D65));
            let shift = Vec2::new(unit(hash), unit(mix(hash)));
            let r2 = Vec2::new(
                unit(self.index.wrapping_mul(3_242_174_889)),
                unit(self.index.wrapping_mul(2_447_445_414)),
            );
            return (r2 + shift).fract().min(Vec2::splat(1.0 - f32::EPSILON));
        }
        let mut more = self.reflection_numbers(depth.wrapping_add(0x8000_0000));
        Vec2::new(more(), more())
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

pub fn radical_inverse(mut i: u32, base: u32) -> f32 {
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

/// A spot's share of its intensity at cos `cos_angle` off its axis: 1 inside the inner cone,
/// 0 outside the outer, smoothstep in cos between.
pub(super) fn spot_falloff(cos_angle: f32, cos_outer: f32, cos_inner: f32) -> f32 {
    if cos_angle <= cos_outer {
        return 0.0;
    }
    let edge = if cos_inner > cos_outer {
        ((cos_angle - cos_outer) / (cos_inner - cos_outer)).clamp(0.0, 1.0)
    } else {
        1.0
    };
    edge * edge * (3.0 - 2.0 * edge)
}

/// The density per solid angle of directions uniform in a cone of half-angle acos(`cos_max`):
/// 1 / (2π(1 − cos)).
pub(super) fn disk_pdf(cos_max: f32) -> f32 {
    1.0 / (TAU * (1.0 - cos_max))
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

impl Light {
    /// Light arriving at `point`, before visibility. Lights with extent are sampled at
    /// `sampling`'s point; lights without ignore it.
    pub fn incoming_sampled(&self, point: Vec3, sampling: &LightSampling) -> Option<Incoming> {
        match *self {
            Light::Directional {
                direction,
                irradiance,
                cos_half_angle,
                ..
            } if cos_half_angle < 1.0 => {
                // Radiance E/(π sin²θ) over the pdf 1/(2π(1−cos θ)) is 2E/(1+cos θ).
                Some(Incoming {
                    to_light: sample_cone(-direction, cos_half_angle, sampling.point()),
                    distance: f32::INFINITY,
                    radiance: irradiance * (2.0 / (1.0 + cos_half_angle)),
                    pdf: Some(disk_pdf(cos_half_angle)),
                })
            }
            Light::Point {
                position,
                intensity,
                radius,
                ..
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
                    pdf: None,
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
                ..
            } => {
                let sample = map.sample(sampling.point())?;
                let d = sample.direction;
                Some(Incoming {
                    to_light: (forward * d.x + up * d.y + right * d.z).normalize(),
                    distance: f32::INFINITY,
                    radiance: sample.radiance,
                    pdf: Some(map.pdf(d)),
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
            ..
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
            pdf: None,
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
                pdf: None,
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
                    pdf: None,
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
                let smooth = spot_falloff(cos_angle, cos_outer, cos_inner);
                Some(Incoming {
                    to_light,
                    distance,
                    radiance: intensity * smooth / (distance * distance),
                    pdf: None,
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
            visible: true,
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
            visible: true,
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
            visible: true,
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
}
