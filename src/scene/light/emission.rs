//! What rays see of the lights: the radiance an environment (an hdri light, a directional
//! disk) sends along a direction that leaves the scene, with the density light sampling draws
//! that direction with (so a reflection that finds the light can be weighed against the light's
//! own samples), and whether camera rays see it (KHR_LIGHT_PRIMARY_VISIBILITY).

use std::f32::consts::PI;

use glam::Vec3;

use super::Light;
use super::sampling::{disk_pdf, spot_falloff};

/// An environment's radiance from one direction and the density per solid angle of its light
/// samples there.
pub struct Seen {
    pub radiance: Vec3,
    pub pdf: f32,
}

impl Light {
    /// The radiance arriving from the unit direction `to_light` out of the scene, for lights
    /// at infinity with extent (an hdri light, a directional light with an angularDiameter);
    /// `None` for every other light and outside a disk.
    pub fn environment(&self, to_light: Vec3) -> Option<Seen> {
        match *self {
            Light::Directional {
                direction,
                irradiance,
                cos_half_angle,
                ..
            } if cos_half_angle < 1.0 => {
                if to_light.dot(-direction) < cos_half_angle {
                    return None;
                }
                // The disk's irradiance E is its radiance times its projected solid angle
                // π sin²θ.
                let sin2 = 1.0 - cos_half_angle * cos_half_angle;
                Some(Seen {
                    radiance: irradiance / (PI * sin2),
                    pdf: disk_pdf(cos_half_angle),
                })
            }
            Light::Hdri {
                ref map,
                forward,
                up,
                right,
                ..
            } => {
                let local = Vec3::new(to_light.dot(forward), to_light.dot(up), to_light.dot(right));
                Some(Seen {
                    radiance: map.radiance(local),
                    pdf: map.pdf(local),
                })
            }
            _ => None,
        }
    }

    /// Where a ray from `origin` along unit `direction` meets a light with extent in the scene
    /// (a sphere light, a quad, a ring) before `t_max`, and the radiance it sees there; `None`
    /// for lights at infinity and lights without extent.
    pub fn hit_by(&self, origin: Vec3, direction: Vec3, t_max: f32) -> Option<(f32, Vec3)> {
        match *self {
            Light::Point {
                position,
                intensity,
                radius,
                ..
            } if radius > 0.0 => {
                // |o + t d − p|² = r²: the near root.
                let to_centre = position - origin;
                let along = to_centre.dot(direction);
                let across2 = to_centre.length_squared() - along * along;
                let inside = radius * radius - across2;
                let t = along - inside.max(0.0).sqrt();
                (inside >= 0.0 && t > 0.0 && t < t_max)
                    .then(|| (t, intensity / (PI * radius * radius)))
            }
            Light::Quad {
                position,
                edge1,
                edge2,
                radiance,
                side,
                ..
            } => {
                let normal = edge1.cross(edge2);
                let facing = direction.dot(normal);
                let t = (position - origin).dot(normal) / facing;
                if !(t > 0.0 && t < t_max) {
                    return None;
                }
                let offset = origin + direction * t - position;
                let norm2 = normal.length_squared();
                let u = offset.cross(edge2).dot(normal) / norm2;
                let v = edge1.cross(offset).dot(normal) / norm2;
                // The front side faces along edge1 × edge2, so a ray against it sees it.
                let seen = match side {
                    super::QuadSide::Front => facing < 0.0,
                    super::QuadSide::Back => facing > 0.0,
                    super::QuadSide::Both => true,
                };
                ((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v) && seen)
                    .then_some((t, radiance))
            }
            Light::Ring {
                position,
                direction: axis,
                intensity,
                cos_outer,
                cos_inner,
                inner,
                outer,
                ..
            } if outer > 0.0 => {
                // The annulus emits along its axis: a ray travelling against it sees it.
                let cos_angle = -direction.dot(axis);
                if cos_angle <= 0.0 {
                    return None;
                }
                let t = (position - origin).dot(axis) / direction.dot(axis);
                if !(t > 0.0 && t < t_max) {
                    return None;
                }
                let radius = (origin + direction * t - position).length();
                if radius < inner || radius > outer {
                    return None;
                }
                // Each point is a spot of the ring's intensity over its area: radiance is
                // that intensity per area over the projected area, cos of the angle.
                let area = PI * (outer * outer - inner * inner);
                let falloff = spot_falloff(cos_angle, cos_outer, cos_inner);
                Some((t, intensity * falloff / (area * cos_angle)))
            }
            _ => None,
        }
    }

    /// The `visible` parameter (KHR_LIGHT_PRIMARY_VISIBILITY): whether camera rays see the
    /// light. Lights without extent (a point, a spot, a directional light of no diameter) are
    /// never seen by any ray.
    pub fn visible(&self) -> bool {
        match *self {
            Light::Directional { visible, .. }
            | Light::Point { visible, .. }
            | Light::Quad { visible, .. }
            | Light::Ring { visible, .. }
            | Light::Hdri { visible, .. } => visible,
            Light::Spot { .. } => false,
        }
    }

    /// Whether the light is an environment image, which takes the background's place where it
    /// is seen.
    pub fn is_hdri(&self) -> bool {
        matches!(self, Light::Hdri { .. })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::light::LightSampling;
    use glam::Vec2;

    #[test]
    fn a_disk_is_seen_with_the_radiance_and_density_of_its_samples() {
        let light = Light::Directional {
            direction: Vec3::NEG_Z,
            irradiance: Vec3::splat(2.0),
            cos_half_angle: 0.2f32.cos(),
            visible: true,
        };
        for index in 0..16 {
            let sampling = LightSampling {
                index,
                scramble: Vec2::new(0.3, 0.7),
            };
            let sample = light.incoming_sampled(Vec3::ZERO, &sampling).unwrap();
            let seen = light.environment(sample.to_light).unwrap();
            assert_eq!(sample.pdf, Some(seen.pdf));
            let estimate = seen.radiance / seen.pdf;
            assert!((estimate - sample.radiance).abs().max_element() < 1e-4 * estimate.x);
        }
        // Outside the disk, nothing.
        assert!(
            light
                .environment(Vec3::new(0.3, 0.0, 1.0).normalize())
                .is_none()
        );
        assert!(light.environment(Vec3::NEG_Z).is_none());
    }
}
