//! Packed primitive layouts and their ray intersection tests.
//!
//! * Triangles use the watertight test of Woop, Benthin and Wald (JCGT 2013): vertices are moved
//!   into a sheared ray space where the ray runs along +z and the three edge functions decide
//!   the hit. Rays through a shared edge or vertex hit at least one of the triangles; edge
//!   functions that come out exactly zero are redone in f64.
//! * Spheres solve their quadratic in f64 with the cancellation-free root pair
//!   `q = b + sign(b) sqrt(disc)`, `t0 = c / q`, `t1 = q / a` (also used by the tubes of
//!   `tube`), and compute the discriminant from the distance between the line and the centre,
//!   so that far-away, large and tiny spheres and rays starting on the surface stay accurate.
//!
//! Every test accepts `t` only in `[ray.t_min, ray.t_max]` after rounding to f32.

use crate::accel::MAX_COORDINATE;
use crate::accel::wide_bvh::TraversalRay;
use glam::{DVec3, Vec2, Vec3, Vec3A, Vec4, Vec4Swizzles};
use obvhs::aabb::Aabb;

#[inline]
pub(crate) fn is_usable_point(point: Vec3) -> bool {
    point.is_finite() && point.abs().max_element() <= MAX_COORDINATE
}

#[inline]
pub(crate) fn is_usable_box(aabb: &Aabb) -> bool {
    aabb.min.is_finite()
        && aabb.max.is_finite()
        && aabb.min.abs().max_element() <= MAX_COORDINATE
        && aabb.max.abs().max_element() <= MAX_COORDINATE
}

/// A triangle stored per axis: `rows[axis] = (v0[axis], v1[axis], v2[axis], normal[axis])`, so
/// that the three vertices are sheared with a few four-wide operations. The unit normal fills
/// the lane that would be padding: packet tests record it with each hit, so that hit records
/// need not load the triangle again.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PackedTriangle {
    pub rows: [Vec4; 3],
}

impl PackedTriangle {
    /// `None` for non-finite, out-of-range or zero-area triangles.
    pub fn new(v0: Vec3, v1: Vec3, v2: Vec3) -> Option<PackedTriangle> {
        if !(is_usable_point(v0) && is_usable_point(v1) && is_usable_point(v2)) {
            return None;
        }
        // A positive finite squared length is exactly what `normal()` needs to normalize.
        let area_squared = (v1 - v0).cross(v2 - v0).length_squared();
        if !(area_squared.is_finite() && area_squared > 0.0) {
            return None;
        }
        Some(PackedTriangle::from_usable(v0, v1, v2))
    }

    /// Packs vertices that [`Self::new`] has already accepted, without checking them again.
    pub fn from_usable(v0: Vec3, v1: Vec3, v2: Vec3) -> PackedTriangle {
        let normal = (v1 - v0).cross(v2 - v0).normalize_or_zero();
        PackedTriangle {
            rows: [
                Vec4::new(v0.x, v1.x, v2.x, normal.x),
                Vec4::new(v0.y, v1.y, v2.y, normal.y),
                Vec4::new(v0.z, v1.z, v2.z, normal.z),
            ],
        }
    }

    pub fn vertices(&self) -> [Vec3; 3] {
        let [x, y, z] = self.rows;
        [
            Vec3::new(x.x, y.x, z.x),
            Vec3::new(x.y, y.y, z.y),
            Vec3::new(x.z, y.z, z.z),
        ]
    }

    pub fn bounds(&self) -> Aabb {
        let [v0, v1, v2] = self.vertices();
        Aabb::new(v0.min(v1).min(v2).into(), v0.max(v1).max(v2).into())
    }

    /// Unit normal `(v1 - v0) x (v2 - v0)`; non-zero for every constructed triangle.
    #[inline]
    pub fn normal(&self) -> Vec3 {
        let [x, y, z] = self.rows;
        Vec3::new(x.w, y.w, z.w)
    }
}

/// Edge functions recomputed in f64 for the rare rays that pass exactly through an edge.
#[cold]
fn edge_functions_f64(x: Vec4, y: Vec4) -> Vec4 {
    let x = x.as_dvec4();
    let y = y.as_dvec4();
    Vec4::new(
        (x.z * y.y - y.z * x.y) as f32,
        (x.x * y.z - y.x * x.z) as f32,
        (x.y * y.x - y.y * x.x) as f32,
        0.0,
    )
}

/// Watertight ray/triangle test. On a hit returns `(t, b1, b2)` where `b1`, `b2` are the
/// barycentric weights of `v1` and `v2`; the weights are only computed when `WITH_UV`.
#[inline(always)]
fn triangle_hit<const WITH_UV: bool>(
    triangle: &PackedTriangle,
    ray: &TraversalRay,
) -> Option<(f32, f32, f32)> {
    let [kx, ky, kz] = ray.shear_axes;
    let origin = ray.permuted_origin;
    let z = triangle.rows[kz] - Vec4::splat(origin.z);
    let x = (triangle.rows[kx] - Vec4::splat(origin.x)) - Vec4::splat(ray.shear.x) * z;
    let y = (triangle.rows[ky] - Vec4::splat(origin.y)) - Vec4::splat(ray.shear.y) * z;
    // Lanes: U (weight of v0), V (v1), W (v2); lane 3 (from the normal) is unused.
    let mut weights = x.zxyw() * y.yzxw() - y.zxyw() * x.yzxw();
    if weights.cmpeq(Vec4::ZERO).bitmask() & 0b111 != 0 {
        weights = edge_functions_f64(x, y);
    }
    let negative = weights.cmplt(Vec4::ZERO).bitmask() & 0b111;
    let positive = weights.cmpgt(Vec4::ZERO).bitmask() & 0b111;
    if negative != 0 && positive != 0 {
        return None;
    }
    let determinant = weights.x + weights.y + weights.z;
    if determinant == 0.0 {
        return None;
    }
    let z = z * ray.shear.z;
    let scaled_t = weights.x * z.x + weights.y * z.y + weights.z * z.z;
    let t = scaled_t / determinant;
    if !(t >= ray.t_min && t <= ray.t_max) {
        return None;
    }
    if WITH_UV {
        let inv = 1.0 / determinant;
        Some((t, weights.y * inv, weights.z * inv))
    } else {
        Some((t, 0.0, 0.0))
    }
}

/// Hit distance of a triangle, `None` on a miss.
#[inline(always)]
pub(crate) fn triangle_t(triangle: &PackedTriangle, ray: &TraversalRay) -> Option<f32> {
    triangle_hit::<false>(triangle, ray).map(|hit| hit.0)
}

/// `(t, b1, b2)` of a triangle hit.
pub(crate) fn triangle_t_uv(triangle: &PackedTriangle, ray: &TraversalRay) -> Option<(f32, Vec2)> {
    triangle_hit::<true>(triangle, ray).map(|(t, b1, b2)| (t, Vec2::new(b1, b2)))
}

/// Accepts a root if, rounded to f32, it lies inside the ray interval.
#[inline(always)]
pub(crate) fn in_interval(t: f64, ray: &TraversalRay) -> Option<f32> {
    let t = t as f32;
    (t >= ray.t_min && t <= ray.t_max).then_some(t)
}

/// Roots of `a t^2 - 2 b t + c = 0` given `disc = b^2 - a c >= 0`, in ascending order, without
/// cancellation between `b` and the square root.
#[inline(always)]
pub(crate) fn quadratic_roots(a: f64, b: f64, c: f64, disc: f64) -> [f64; 2] {
    let q = b + disc.sqrt().copysign(b);
    if q == 0.0 {
        // b == 0 and disc == 0: a double root at b / a.
        return [b / a; 2];
    }
    let (t0, t1) = (c / q, q / a);
    if t0 <= t1 { [t0, t1] } else { [t1, t0] }
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct PackedSphere {
    pub center: Vec3,
    pub radius: f32,
}

impl PackedSphere {
    pub fn new(center: Vec3, radius: f32) -> Option<PackedSphere> {
        let sphere = PackedSphere { center, radius };
        (radius.is_finite() && radius > 0.0 && is_usable_box(&sphere.bounds())).then_some(sphere)
    }

    /// Box padded by a few ulps so that rounding never shaves off a rim hit.
    pub fn bounds(&self) -> Aabb {
        let pad = self.radius + (self.radius + self.center.abs().max_element()) * 1.0e-6;
        Aabb::new(
            (self.center - Vec3::splat(pad)).into(),
            (self.center + Vec3::splat(pad)).into(),
        )
    }
}

#[inline(always)]
pub(crate) fn sphere_t(sphere: &PackedSphere, ray: &TraversalRay) -> Option<f32> {
    if line_clearly_misses_sphere(sphere, ray) {
        return None;
    }
    let [near, far] = ball_roots(sphere.center, sphere.radius, ray)?;
    in_interval(near, ray).or_else(|| in_interval(far, ray))
}

/// Both roots (in f64) of a ray and a ball, or `None` on a miss or a radius that is not
/// positive. Spheres and the end balls of tubes share it.
#[inline(always)]
pub(crate) fn ball_roots(center: Vec3, radius: f32, ray: &TraversalRay) -> Option<[f64; 2]> {
    if radius <= 0.0 {
        return None;
    }
    let origin = ray.origin.as_dvec3() - center.as_dvec3();
    let direction = ray.direction.as_dvec3();
    let radius = radius as f64;
    let a = direction.length_squared();
    let b = -origin.dot(direction);
    // Distance from the centre to the line, measured directly instead of through b^2 - a c.
    let closest = origin + direction * (b / a);
    let disc = a * (radius * radius - closest.length_squared());
    // Also rejects NaN.
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let c = origin.length_squared() - radius * radius;
    Some(quadratic_roots(a, b, c, disc))
}

/// Cheap f32 rejection for the common miss: the ray's line passes the centre farther than the
/// radius by more than a margin covering f32 rounding (the perpendicular distance is off by
/// at most a few ulps of `|origin - centre|`; the margin is ten times that).
#[inline(always)]
pub(crate) fn line_clearly_misses_sphere(sphere: &PackedSphere, ray: &TraversalRay) -> bool {
    let offset = ray.origin - Vec3A::from(sphere.center);
    let direction = ray.direction;
    let along = offset.dot(direction) / direction.length_squared();
    let distance_squared = (offset - direction * along).length_squared();
    let margin = 1.0e-5 * offset.length_squared();
    distance_squared > sphere.radius * sphere.radius + margin
}

/// Outward unit normal and `(longitude, colatitude)` parameters at the hit `t`.
pub(crate) fn sphere_surface(sphere: &PackedSphere, ray: &TraversalRay, t: f32) -> (Vec3, Vec2) {
    let offset =
        ray.origin.as_dvec3() - sphere.center.as_dvec3() + ray.direction.as_dvec3() * t as f64;
    let normal = unit_or_axis(offset);
    let longitude = normal.y.atan2(normal.x) / std::f32::consts::TAU;
    let longitude = if longitude < 0.0 {
        longitude + 1.0
    } else {
        longitude
    };
    let colatitude = normal.z.clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
    (normal, Vec2::new(longitude.min(0.999_999_94), colatitude))
}

/// Normalizes in f64, then once more in f32 so the result is unit length in f32.
pub(crate) fn unit_or_axis(v: DVec3) -> Vec3 {
    let unit = v.normalize_or_zero().as_vec3().normalize_or_zero();
    if unit == Vec3::ZERO { Vec3::Z } else { unit }
}
