//! Tubes: truncated cones (cylinders when both radii are equal) with an optional flat cap at
//! each end, for the ANARI `cone` and `cylinder` geometries, and round cones, the convex hull of
//! the balls around both end points, for the segments of the ANARI `curve` geometry.
//!
//! * The lateral surface is solved in the tube's axis frame: with the axial coordinate
//!   `s(t)` and the part `perp(t)` perpendicular to the axis, `|perp(t)|^2 = r(s(t))^2` is a
//!   quadratic in `t`, solved in f64 with a discriminant written as a difference of two squares
//!   (for equal radii: the distance between the ray line and the axis). Roots outside the axial range are dropped, which also drops the mirrored
//!   nappe.
//! * A round cone is the union of its two balls and of the frustum between the circles where
//!   the cone tangent to both balls touches them, so a hit on a ball counts only beyond that
//!   circle (on the outer side of the ball). A ball inside the other one leaves just the bigger
//!   ball. Consecutive segments of a curve share the ball at their common vertex, so joints are
//!   closed and rounded.
//!
//! Every test accepts `t` only in `[ray.t_min, ray.t_max]` after rounding to f32, and ties keep
//! the lateral surface.

use crate::accel::primitives::{
    ball_roots, in_interval, is_usable_box, is_usable_point, quadratic_roots, unit_or_axis,
};
use crate::accel::walk::TraversalRay;
use glam::{DVec3, Vec2, Vec3};
use obvhs::aabb::Aabb;

/// One tube as the scene layer describes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TubeSegment {
    pub start: Vec3,
    pub end: Vec3,
    /// Radius at `start`; at least 0.
    pub start_radius: f32,
    /// Radius at `end`; at least 0.
    pub end_radius: f32,
    pub kind: TubeKind,
}

/// The shape between and at the two end points of a [`TubeSegment`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TubeKind {
    /// Truncated cone, open, or closed by a flat disk at either end.
    Cone { start_cap: bool, end_cap: bool },
    /// Convex hull of the balls of the two radii around the two end points.
    Round,
}

const START_CAP: u8 = 1;
const END_CAP: u8 = 2;
const ROUND: u8 = 4;

/// A usable tube in BVH slot order.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PackedTube {
    start: Vec3,
    end: Vec3,
    start_radius: f32,
    end_radius: f32,
    flags: u8,
}

/// Which surface of a tube was hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum TubePart {
    Side,
    StartCap,
    EndCap,
    StartBall,
    EndBall,
}

impl PackedTube {
    /// `None` for non-finite or out-of-range points, negative or non-finite radii, two zero
    /// radii, and cones of zero length.
    pub fn new(segment: &TubeSegment) -> Option<PackedTube> {
        let radii = [segment.start_radius, segment.end_radius];
        let radii_usable =
            radii.iter().all(|r| r.is_finite() && *r >= 0.0) && radii.iter().any(|r| *r > 0.0);
        if !(radii_usable && is_usable_point(segment.start) && is_usable_point(segment.end)) {
            return None;
        }
        let flags = match segment.kind {
            TubeKind::Cone { start_cap, end_cap } => {
                if segment.start == segment.end {
                    return None;
                }
                (if start_cap { START_CAP } else { 0 }) | (if end_cap { END_CAP } else { 0 })
            }
            TubeKind::Round => ROUND,
        };
        let tube = PackedTube {
            start: segment.start,
            end: segment.end,
            start_radius: segment.start_radius,
            end_radius: segment.end_radius,
            flags,
        };
        is_usable_box(&tube.bounds()).then_some(tube)
    }

    fn is_round(&self) -> bool {
        self.flags & ROUND != 0
    }

    /// Box of the two end points grown by the larger radius and padded by a few ulps. It holds
    /// every kind of tube; it is not tight (along the axis of a cone or cylinder, or at the thin
    /// end of a tapered tube), but it is the box Embree-based devices (the ANARI reference device
    /// among them) report, so that world bounds, and cameras framed from them, agree.
    pub fn bounds(&self) -> Aabb {
        let radius = self.start_radius.max(self.end_radius) as f64;
        let magnitude = self.start.abs().max(self.end.abs()).max_element() as f64;
        let extent = DVec3::splat(radius + (radius + magnitude) * 1.0e-6);
        let min = self.start.min(self.end).as_dvec3() - extent;
        let max = self.start.max(self.end).as_dvec3() + extent;
        Aabb::new(min.as_vec3().into(), max.as_vec3().into())
    }
}

/// Ray in a tube's frame: axial coordinates from `start` and the components perpendicular to
/// the axis.
struct AxisFrame {
    axis: DVec3,
    length: f64,
    origin_axial: f64,
    direction_axial: f64,
    origin_perp: DVec3,
    direction_perp: DVec3,
}

/// The frame, or `None` when the end points coincide.
#[inline(always)]
fn axis_frame(tube: &PackedTube, ray: &TraversalRay) -> Option<AxisFrame> {
    let start = tube.start.as_dvec3();
    let axis_vector = tube.end.as_dvec3() - start;
    let length = axis_vector.length();
    if length == 0.0 {
        return None;
    }
    let axis = axis_vector / length;
    let origin = ray.origin.as_dvec3() - start;
    let direction = ray.direction.as_dvec3();
    let origin_axial = origin.dot(axis);
    let direction_axial = direction.dot(axis);
    Some(AxisFrame {
        axis,
        length,
        origin_axial,
        direction_axial,
        origin_perp: origin - axis * origin_axial,
        direction_perp: direction - axis * direction_axial,
    })
}

/// A frustum of the lateral surface: axial range `[from, to]`, radius `radius` at `from`,
/// growing by `slope` per unit of axial length.
#[derive(Clone, Copy)]
struct Side {
    from: f64,
    to: f64,
    radius: f64,
    slope: f64,
}

impl Side {
    fn radius_at(&self, axial: f64) -> f64 {
        self.radius + self.slope * (axial - self.from)
    }
}

/// The lateral frustum of a tube, or `None` for a round cone reduced to its bigger ball.
#[inline(always)]
fn side_of(tube: &PackedTube, length: f64) -> Option<Side> {
    let (r0, r1) = (tube.start_radius as f64, tube.end_radius as f64);
    if !tube.is_round() {
        return Some(Side {
            from: 0.0,
            to: length,
            radius: r0,
            slope: (r1 - r0) / length,
        });
    }
    if length <= (r0 - r1).abs() {
        return None;
    }
    // The tangent cone touches each ball on the circle at axial offset radius * sin from the
    // centre, where sin is that of the cone's half angle.
    let sin = (r0 - r1) / length;
    let cos = (1.0 - sin * sin).sqrt();
    Some(Side {
        from: r0 * sin,
        to: length + r1 * sin,
        radius: r0 * cos,
        slope: -sin / cos,
    })
}

/// Calls `consider` with every root of the lateral surface inside its axial range.
#[inline(always)]
fn side_roots(frame: &AxisFrame, side: &Side, mut consider: impl FnMut(f64)) {
    let radius_at_origin = side.radius_at(frame.origin_axial);
    let radius_rate = side.slope * frame.direction_axial;
    let a = frame.direction_perp.length_squared() - radius_rate * radius_rate;
    let b = radius_at_origin * radius_rate - frame.origin_perp.dot(frame.direction_perp);
    let c = frame.origin_perp.length_squared() - radius_at_origin * radius_at_origin;
    let mut offer = |t: f64| {
        let axial = frame.origin_axial + t * frame.direction_axial;
        if axial >= side.from && axial <= side.to {
            consider(t);
        }
    };
    if a == 0.0 {
        // Parallel to the axis (cylinder) or to a generating line (cone): at most one root.
        if b != 0.0 {
            offer(c / (2.0 * b));
        }
        return;
    }
    // b^2 - a c rewritten as a difference of two squares that are computed directly: exact
    // for rays through the axis (the apex seen head-on), and for equal radii the distance
    // between the axis and the ray line.
    let disc = (frame.direction_perp * radius_at_origin - frame.origin_perp * radius_rate)
        .length_squared()
        - frame
            .origin_perp
            .cross(frame.direction_perp)
            .length_squared();
    if disc.is_nan() || disc < 0.0 {
        return;
    }
    for t in quadratic_roots(a, b, c, disc) {
        offer(t);
    }
}

/// Closest hit of a tube in the ray interval and the part it lies on.
#[inline(always)]
pub(crate) fn tube_hit(tube: &PackedTube, ray: &TraversalRay) -> Option<(f32, TubePart)> {
    let mut best: Option<(f32, TubePart)> = None;
    let mut consider = |t: f64, part: TubePart| {
        if let Some(t) = in_interval(t, ray)
            && best.is_none_or(|(best_t, _)| t < best_t)
        {
            best = Some((t, part));
        }
    };
    let frame = axis_frame(tube, ray);
    let side = frame.as_ref().and_then(|f| side_of(tube, f.length));
    if let (Some(frame), Some(side)) = (&frame, &side) {
        side_roots(frame, side, |t| consider(t, TubePart::Side));
    }
    if tube.is_round() {
        let Some((frame, side)) = frame.zip(side) else {
            // One ball holds the other (or both centres coincide): only the bigger one shows.
            let (center, radius, part) = if tube.start_radius >= tube.end_radius {
                (tube.start, tube.start_radius, TubePart::StartBall)
            } else {
                (tube.end, tube.end_radius, TubePart::EndBall)
            };
            for t in ball_roots(center, radius, ray).into_iter().flatten() {
                consider(t, part);
            }
            return best;
        };
        let axial_at = |t: f64| frame.origin_axial + t * frame.direction_axial;
        for t in ball_roots(tube.start, tube.start_radius, ray)
            .into_iter()
            .flatten()
        {
            if axial_at(t) <= side.from {
                consider(t, TubePart::StartBall);
            }
        }
        for t in ball_roots(tube.end, tube.end_radius, ray)
            .into_iter()
            .flatten()
        {
            if axial_at(t) >= side.to {
                consider(t, TubePart::EndBall);
            }
        }
        return best;
    }
    let frame = frame?;
    if frame.direction_axial != 0.0 {
        let caps = [
            (START_CAP, 0.0, tube.start_radius, TubePart::StartCap),
            (END_CAP, frame.length, tube.end_radius, TubePart::EndCap),
        ];
        for (flag, plane, radius, part) in caps {
            if tube.flags & flag == 0 || radius <= 0.0 {
                continue;
            }
            let t = (plane - frame.origin_axial) / frame.direction_axial;
            let radial = frame.origin_perp + frame.direction_perp * t;
            let radius = radius as f64;
            if radial.length_squared() <= radius * radius {
                consider(t, part);
            }
        }
    }
    best
}

/// Unit normal and parameters of a tube hit found by [`tube_hit`] (see `PrimHit::uv`): the
/// lateral surface and balls give `(axial position / length in [0, 1], 0)`, caps give
/// `(0 or 1, distance from the axis / radius)`.
pub(crate) fn tube_surface(
    tube: &PackedTube,
    ray: &TraversalRay,
    t: f32,
    part: TubePart,
) -> (Vec3, Vec2) {
    let t = t as f64;
    let point = ray.origin.as_dvec3() + ray.direction.as_dvec3() * t;
    let Some(frame) = axis_frame(tube, ray) else {
        // Coinciding centres: a ball.
        let center = if part == TubePart::EndBall {
            tube.end
        } else {
            tube.start
        };
        let u = if part == TubePart::EndBall { 1.0 } else { 0.0 };
        return (unit_or_axis(point - center.as_dvec3()), Vec2::new(u, 0.0));
    };
    let axial = frame.origin_axial + t * frame.direction_axial;
    let along = Vec2::new((axial / frame.length).clamp(0.0, 1.0) as f32, 0.0);
    let radial = frame.origin_perp + frame.direction_perp * t;
    match part {
        TubePart::Side => {
            let Some(side) = side_of(tube, frame.length) else {
                return (unit_or_axis(radial), along);
            };
            // Gradient of |perp|^2 - r(s)^2, halved.
            let normal = radial - frame.axis * (side.radius_at(axial) * side.slope);
            let normal = if normal.length_squared() > 0.0 {
                normal
            } else {
                // The apex: the axis direction away from the cone.
                -frame.axis * side.slope.signum()
            };
            (unit_or_axis(normal), along)
        }
        TubePart::StartBall | TubePart::EndBall => {
            let center = if part == TubePart::StartBall {
                tube.start
            } else {
                tube.end
            };
            (unit_or_axis(point - center.as_dvec3()), along)
        }
        TubePart::StartCap | TubePart::EndCap => {
            let (sign, u, radius) = if part == TubePart::StartCap {
                (-1.0, 0.0, tube.start_radius)
            } else {
                (1.0, 1.0, tube.end_radius)
            };
            let v = (radial.length() / radius as f64).min(1.0) as f32;
            (unit_or_axis(frame.axis * sign), Vec2::new(u, v))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DVec2, Vec3A, vec3};

    fn traversal(origin: Vec3, direction: Vec3) -> TraversalRay {
        TraversalRay::new(
            Vec3A::from(origin),
            Vec3A::from(direction.normalize()),
            0.0,
            f32::INFINITY,
        )
        .unwrap()
    }

    fn cone(start: Vec3, end: Vec3, r0: f32, r1: f32, caps: (bool, bool)) -> PackedTube {
        PackedTube::new(&TubeSegment {
            start,
            end,
            start_radius: r0,
            end_radius: r1,
            kind: TubeKind::Cone {
                start_cap: caps.0,
                end_cap: caps.1,
            },
        })
        .unwrap()
    }

    fn round(start: Vec3, end: Vec3, r0: f32, r1: f32) -> PackedTube {
        PackedTube::new(&TubeSegment {
            start,
            end,
            start_radius: r0,
            end_radius: r1,
            kind: TubeKind::Round,
        })
        .unwrap()
    }

    /// Deterministic xorshift generator.
    struct Rng(u64);
    impl Rng {
        fn unit(&mut self) -> f32 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32 / (1u64 << 24) as f32
        }
        fn range(&mut self, low: f32, high: f32) -> f32 {
            low + (high - low) * self.unit()
        }
        fn point(&mut self, extent: f32) -> Vec3 {
            vec3(
                self.range(-extent, extent),
                self.range(-extent, extent),
                self.range(-extent, extent),
            )
        }
    }

    /// Distance from `p` (axial, radial >= 0) to the closed convex polygon `corners` (in order).
    fn polygon_distance(p: DVec2, corners: &[DVec2]) -> f64 {
        let mut distance = f64::INFINITY;
        let mut inside = true;
        for (i, a) in corners.iter().enumerate() {
            let b = corners[(i + 1) % corners.len()];
            let edge = b - *a;
            let h = ((p - *a).dot(edge) / edge.length_squared()).clamp(0.0, 1.0);
            distance = distance.min((p - *a - edge * h).length());
            inside &= edge.perp_dot(p - *a) >= 0.0;
        }
        if inside { -distance } else { distance }
    }

    /// Exact distance to a solid capped cone (outside), in the plane of the axis.
    fn capped_cone_distance(tube: &PackedTube, p: Vec3) -> f64 {
        let start = tube.start.as_dvec3();
        let axis_vector = tube.end.as_dvec3() - start;
        let length = axis_vector.length();
        let axis = axis_vector / length;
        let offset = p.as_dvec3() - start;
        let axial = offset.dot(axis);
        let radial = (offset - axis * axial).length();
        let (r0, r1) = (tube.start_radius as f64, tube.end_radius as f64);
        // Counter-clockwise: the section mirrored across the axis.
        let corners = [
            DVec2::new(0.0, -r0),
            DVec2::new(length, -r1),
            DVec2::new(length, r1),
            DVec2::new(0.0, r0),
        ];
        polygon_distance(DVec2::new(axial, radial), &corners)
    }

    /// Exact distance (outside) to the union of the balls swept from start to end.
    fn round_cone_distance(tube: &PackedTube, p: Vec3) -> f64 {
        let (a, b) = (tube.start.as_dvec3(), tube.end.as_dvec3());
        let (r0, r1) = (tube.start_radius as f64, tube.end_radius as f64);
        let at = |s: f64| (p.as_dvec3() - (a + (b - a) * s)).length() - (r0 + (r1 - r0) * s);
        // Convex in s: ternary search.
        let (mut low, mut high) = (0.0, 1.0);
        for _ in 0..100 {
            let m1 = low + (high - low) / 3.0;
            let m2 = high - (high - low) / 3.0;
            if at(m1) <= at(m2) {
                high = m2;
            } else {
                low = m1;
            }
        }
        at(0.5 * (low + high)).min(at(0.0)).min(at(1.0))
    }

    /// Sphere-traces a ray from outside: `Some(t)` on a hit, `None` on a clear miss, and
    /// `Err(())` when the ray passes too close to the surface to tell.
    fn trace(
        distance: impl Fn(Vec3) -> f64,
        origin: Vec3,
        direction: Vec3,
    ) -> Result<Option<f64>, ()> {
        let direction = direction.normalize().as_dvec3();
        let mut t = 0.0;
        let mut closest = f64::INFINITY;
        for _ in 0..20_000 {
            let d = distance((origin.as_dvec3() + direction * t).as_vec3());
            if d < 1.0e-6 {
                return Ok(Some(t));
            }
            closest = closest.min(d);
            t += d;
            if t > 100.0 {
                break;
            }
        }
        if closest > 1.0e-3 { Ok(None) } else { Err(()) }
    }

    fn check_against_tracing(tube: &PackedTube, distance: impl Fn(Vec3) -> f64, seed: u64) {
        let mut rng = Rng(seed);
        let mut hits = 0;
        for _ in 0..3000 {
            let origin = rng.point(3.0);
            if distance(origin) < 0.05 {
                continue;
            }
            // Aim near the tube so that most rays hit or graze it.
            let target = tube.start.lerp(tube.end, rng.unit()) + rng.point(0.8);
            let direction = (target - origin).normalize();
            let Ok(expected) = trace(&distance, origin, direction) else {
                continue;
            };
            let found = tube_hit(tube, &traversal(origin, direction)).map(|(t, _)| t as f64);
            match (found, expected) {
                (None, None) => {}
                (Some(t), Some(expected)) => {
                    hits += 1;
                    assert!(
                        (t - expected).abs() < 1.0e-3,
                        "t {t} vs traced {expected} from {origin} along {direction}"
                    );
                }
                _ => panic!("found {found:?}, traced {expected:?} from {origin} along {direction}"),
            }
        }
        assert!(hits > 300, "too few hits ({hits}) to be a test");
    }

    #[test]
    fn capped_cones_agree_with_sphere_tracing() {
        let shapes = [
            (vec3(0.1, -0.3, 0.2), vec3(-0.4, 0.7, 0.1), 0.5, 0.0),
            (vec3(0.0, 0.0, -0.5), vec3(0.0, 0.0, 0.5), 0.3, 0.3),
            (vec3(0.3, 0.2, 0.0), vec3(-0.2, -0.4, 0.6), 0.1, 0.6),
        ];
        for (i, (start, end, r0, r1)) in shapes.into_iter().enumerate() {
            let tube = cone(start, end, r0, r1, (true, true));
            check_against_tracing(&tube, |p| capped_cone_distance(&tube, p), 7 + i as u64);
        }
    }

    #[test]
    fn round_cones_agree_with_sphere_tracing() {
        let shapes = [
            (vec3(0.1, -0.3, 0.2), vec3(-0.4, 0.7, 0.1), 0.5, 0.1),
            (vec3(0.0, 0.0, -0.5), vec3(0.0, 0.0, 0.5), 0.2, 0.2),
            (vec3(0.3, 0.2, 0.0), vec3(-0.2, -0.4, 0.6), 0.0, 0.4),
            // The first ball holds the second.
            (vec3(0.0, 0.0, 0.0), vec3(0.1, 0.0, 0.0), 0.6, 0.2),
        ];
        for (i, (start, end, r0, r1)) in shapes.into_iter().enumerate() {
            let tube = round(start, end, r0, r1);
            check_against_tracing(&tube, |p| round_cone_distance(&tube, p), 21 + i as u64);
        }
    }

    #[test]
    fn open_ends_show_the_inside() {
        // Looking down the +z axis into a tube from z = 2: the near end is `end`.
        let origin = vec3(0.05, 0.0, 2.0);
        let ray = traversal(origin, vec3(0.0, 0.0, -1.0));
        let start = vec3(0.0, 0.0, -0.5);
        let end = vec3(0.0, 0.0, 0.5);
        let both = tube_hit(&cone(start, end, 0.3, 0.3, (true, true)), &ray).unwrap();
        assert_eq!(both.1, TubePart::EndCap);
        assert!((both.0 - 1.5).abs() < 1.0e-6);
        let first = tube_hit(&cone(start, end, 0.3, 0.3, (true, false)), &ray).unwrap();
        assert_eq!(first.1, TubePart::StartCap);
        assert!((first.0 - 2.5).abs() < 1.0e-6);
        // A ray exactly parallel to the axis never meets the side of a cylinder.
        assert_eq!(
            tube_hit(&cone(start, end, 0.3, 0.3, (false, false)), &ray),
            None
        );
        // An open cone narrowing away from the eye is seen from inside.
        let (t, part) = tube_hit(&cone(end, start, 0.3, 0.0, (false, false)), &ray).unwrap();
        assert_eq!(part, TubePart::Side);
        // The side passes radius 0.05 at 5/6 of the way from the base at z = 0.5.
        assert!((t - (1.5 + 1.0 * 5.0 / 6.0)).abs() < 1.0e-5, "{t}");
        let (normal, uv) = tube_surface(&cone(end, start, 0.3, 0.0, (false, false)), &ray, t, part);
        assert!((uv.x - 5.0 / 6.0).abs() < 1.0e-5);
        // Outward normal of a cone with half-angle atan(0.3): radial out, tilted towards the
        // apex (at -z here).
        let expected = vec3(1.0, 0.0, -0.3).normalize();
        assert!(normal.distance(expected) < 1.0e-5, "{normal}");
    }

    #[test]
    fn cone_apex_is_hit_head_on() {
        // Base at z = -0.5 (radius 0.4), apex at z = 0.5; eye on the axis beyond the apex.
        let tube = cone(
            vec3(0.0, 0.0, -0.5),
            vec3(0.0, 0.0, 0.5),
            0.4,
            0.0,
            (false, false),
        );
        let ray = traversal(vec3(0.0, 0.0, 2.0), vec3(0.0, 0.0, -1.0));
        let (t, part) = tube_hit(&tube, &ray).unwrap();
        assert_eq!(part, TubePart::Side);
        assert!((t - 1.5).abs() < 1.0e-6, "{t}");
        let (normal, _) = tube_surface(&tube, &ray, t, part);
        assert_eq!(normal, Vec3::Z);
        // Slightly off axis: the flank, with t growing by 1 / 0.4 per unit of radius.
        let ray = traversal(vec3(0.1, 0.0, 2.0), vec3(0.0, 0.0, -1.0));
        let (t, _) = tube_hit(&tube, &ray).unwrap();
        assert!((t - 1.75).abs() < 1.0e-5, "{t}");
    }

    #[test]
    fn round_cone_normals_are_continuous_across_the_tangent_circle() {
        let tube = round(vec3(0.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), 0.4, 0.1);
        let mut previous: Option<Vec3> = None;
        let mut parts = std::collections::BTreeSet::new();
        for i in 0..=200 {
            // From the lower ball across the side to the upper ball, short of the poles.
            let z = -0.3 + 1.35 * i as f32 / 200.0;
            let ray = traversal(vec3(2.0, 0.0, z), vec3(-1.0, 0.0, 0.0));
            let (t, part) = tube_hit(&tube, &ray).unwrap();
            let (normal, _) = tube_surface(&tube, &ray, t, part);
            assert!((normal.length() - 1.0).abs() < 1.0e-5);
            parts.insert(format!("{part:?}"));
            if let Some(previous) = previous {
                assert!(normal.dot(previous) > 0.99, "jump at z {z}");
            }
            previous = Some(normal);
        }
        assert_eq!(parts.len(), 3, "{parts:?}");
    }

    #[test]
    fn bvh_over_tubes_agrees_with_brute_force_for_single_rays_and_packets() {
        use crate::accel::{GeometryBvh, Ray};
        let mut rng = Rng(99);
        let segments: Vec<TubeSegment> = (0..400)
            .map(|i| {
                let start = rng.point(4.0);
                let end = start + rng.point(0.8);
                let kind = match i % 3 {
                    0 => TubeKind::Round,
                    1 => TubeKind::Cone {
                        start_cap: true,
                        end_cap: false,
                    },
                    _ => TubeKind::Cone {
                        start_cap: false,
                        end_cap: true,
                    },
                };
                TubeSegment {
                    start,
                    end,
                    start_radius: rng.range(0.0, 0.3),
                    end_radius: rng.range(0.02, 0.3),
                    kind,
                }
            })
            .collect();
        let packed: Vec<Option<PackedTube>> = segments.iter().map(PackedTube::new).collect();
        let bvh = GeometryBvh::build_tubes(&segments);
        assert_eq!(bvh.primitive_count(), segments.len());
        let brute_force = |ray: &Ray| -> Option<f32> {
            let traversal = TraversalRay::new(
                ray.origin.into(),
                ray.direction.into(),
                ray.t_min,
                ray.t_max,
            )?;
            packed
                .iter()
                .flatten()
                .filter_map(|tube| tube_hit(tube, &traversal).map(|hit| hit.0))
                .min_by(f32::total_cmp)
        };
        let mut hits = 0;
        for _ in 0..40 {
            let origin = rng.point(6.0);
            let aim = rng.point(3.0);
            let rays: Vec<Ray> = (0..64)
                .map(|_| {
                    let direction = (aim + rng.point(0.7) - origin).normalize();
                    Ray::new(origin, direction, 0.0, f32::INFINITY)
                })
                .collect();
            let mut packet_hits = vec![None; rays.len()];
            bvh.intersect_packet(&rays, &mut packet_hits);
            for (ray, packet_hit) in rays.iter().zip(&packet_hits) {
                let expected = brute_force(ray);
                let single = bvh.intersect(ray);
                assert_eq!(single.map(|hit| hit.t), expected, "{ray:?}");
                assert_eq!(packet_hit.map(|hit| hit.t), expected, "{ray:?}");
                if let Some(hit) = single {
                    hits += 1;
                    assert!((hit.normal.length() - 1.0).abs() < 1.0e-5);
                    assert!((0.0..=1.0).contains(&hit.uv.x));
                }
            }
        }
        assert!(hits > 300, "{hits}");
    }

    #[test]
    fn unusable_segments_are_rejected() {
        let segment = |r0: f32, r1: f32, end: Vec3, kind: TubeKind| TubeSegment {
            start: Vec3::ZERO,
            end,
            start_radius: r0,
            end_radius: r1,
            kind,
        };
        let open = TubeKind::Cone {
            start_cap: false,
            end_cap: false,
        };
        assert!(PackedTube::new(&segment(-0.1, 0.2, Vec3::X, open)).is_none());
        assert!(PackedTube::new(&segment(0.0, 0.0, Vec3::X, open)).is_none());
        assert!(PackedTube::new(&segment(f32::NAN, 0.2, Vec3::X, open)).is_none());
        assert!(PackedTube::new(&segment(0.1, 0.2, Vec3::ZERO, open)).is_none());
        assert!(PackedTube::new(&segment(0.1, 0.2, Vec3::NAN, TubeKind::Round)).is_none());
        // A round segment of zero length is a ball.
        let ball = PackedTube::new(&segment(0.1, 0.2, Vec3::ZERO, TubeKind::Round)).unwrap();
        let (t, part) = tube_hit(&ball, &traversal(vec3(0.0, 0.0, 1.0), -Vec3::Z)).unwrap();
        assert_eq!(part, TubePart::EndBall);
        assert!((t - 0.8).abs() < 1.0e-6);
    }
}
