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
use crate::accel::walk::TraversalRay;
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

/// One triangle stored per axis: `rows[axis] = (v0[axis], v1[axis], v2[axis], 0)`, so that the
/// three vertices are sheared with a few four-wide operations.
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
        PackedTriangle {
            rows: [
                Vec4::new(v0.x, v1.x, v2.x, 0.0),
                Vec4::new(v0.y, v1.y, v2.y, 0.0),
                Vec4::new(v0.z, v1.z, v2.z, 0.0),
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
        unit_normal(self.vertices())
    }
}

/// Unit normal `(v1 - v0) x (v2 - v0)` of a triangle's vertices (zero for a degenerate one).
#[inline(always)]
fn unit_normal([v0, v1, v2]: [Vec3; 3]) -> Vec3 {
    (v1 - v0).cross(v2 - v0).normalize_or_zero()
}

/// Triangles in a group: a leaf's triangles tested together against one ray.
pub(crate) const GROUP_LANES: usize = 4;

/// Up to four triangles in SIMD lanes: `vertices[i][axis]` holds coordinate `axis` of vertex
/// `i` of every lane's triangle (what the watertight test reads, nothing to gather), and
/// `ids[lane]` the lane's source id, on the cache line of the last vertex row, so a hit's id
/// costs no miss of its own. Lanes beyond a leaf's count repeat lane 0 and are masked off.
/// 160 bytes, aligned to 32 so that a group always spans exactly three cache lines.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct TriangleGroup {
    pub vertices: [[Vec4; 3]; 3],
    pub ids: [u32; GROUP_LANES],
}

const _: () = assert!(size_of::<TriangleGroup>() == 160);

impl TriangleGroup {
    /// Packs up to four triangles (at least one) with their source ids (as many);
    /// missing lanes repeat the first.
    pub fn new(triangles: &[PackedTriangle], ids: &[u32]) -> TriangleGroup {
        debug_assert_eq!(triangles.len(), ids.len());
        let mut vertices = [[Vec4::ZERO; 3]; 3];
        for lane in 0..GROUP_LANES {
            let triangle = triangles.get(lane).unwrap_or(&triangles[0]);
            for (axis, row) in triangle.rows.iter().enumerate() {
                for (vertex, coordinates) in vertices.iter_mut().enumerate() {
                    coordinates[axis][lane] = row[vertex];
                }
            }
        }
        let ids = std::array::from_fn(|lane| *ids.get(lane).unwrap_or(&ids[0]));
        TriangleGroup { vertices, ids }
    }

    /// [`PackedTriangle::normal`] of the triangle in `lane`, read straight from the lanes.
    #[inline]
    pub fn normal(&self, lane: usize) -> Vec3 {
        unit_normal(
            self.vertices
                .map(|[x, y, z]| Vec3::new(x[lane], y[lane], z[lane])),
        )
    }

    /// The triangle in `lane`.
    #[inline(always)]
    pub fn triangle(&self, lane: usize) -> PackedTriangle {
        let row = |axis: usize| {
            Vec4::new(
                self.vertices[0][axis][lane],
                self.vertices[1][axis][lane],
                self.vertices[2][axis][lane],
                0.0,
            )
        };
        PackedTriangle {
            rows: [row(0), row(1), row(2)],
        }
    }
}

/// What a group's watertight test reads of one ray: the permuted axes, and the permuted
/// origin, the shear and `t_min` across the lanes. [`GroupRay`] splats them once per ray;
/// [`SplatOnUse`] reads them from the [`TraversalRay`] where the test needs them (with AVX a
/// broadcast load costs what a vector load does, so nothing is set up per ray).
pub(crate) trait GroupRayValues {
    /// Each below 3 (checked where the values are made).
    fn axes(&self) -> [usize; 3];
    fn origin(&self) -> [Vec4; 3];
    fn shear(&self) -> [Vec4; 3];
    fn t_min(&self) -> Vec4;

    /// A group's watertight test, lane by lane the arithmetic of [`triangle_t_uv`] (the same
    /// `t` and barycentrics), with `t` accepted in `[t_min, t_max]`: the hit lanes among
    /// `lanes` (bit per lane), their `t`, and the edge functions `V`, `W` with the determinant
    /// `U + V + W`.
    #[inline(always)]
    fn hits(&self, group: &TriangleGroup, lanes: u32, t_max: f32) -> (u32, Vec4, [Vec4; 3]) {
        hits_with::<false, _>(self, group, lanes, t_max)
    }
}

/// [`GroupRayValues`] splat once per ray and kept.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GroupRay {
    axes: [usize; 3],
    origin: [Vec4; 3],
    shear: [Vec4; 3],
    t_min: Vec4,
}

impl GroupRay {
    #[inline(always)]
    pub fn new(ray: &TraversalRay) -> GroupRay {
        let axes = ray.shear_axes;
        // `hits` indexes vertex rows by these without bounds checks.
        assert!(axes.iter().all(|&axis| axis < 3));
        let origin = ray.permuted_origin;
        GroupRay {
            axes,
            origin: [origin.x, origin.y, origin.z].map(Vec4::splat),
            shear: [ray.shear.x, ray.shear.y, ray.shear.z].map(Vec4::splat),
            t_min: Vec4::splat(ray.t_min),
        }
    }
}

impl GroupRayValues for GroupRay {
    #[inline(always)]
    fn axes(&self) -> [usize; 3] {
        self.axes
    }
    #[inline(always)]
    fn origin(&self) -> [Vec4; 3] {
        self.origin
    }
    #[inline(always)]
    fn shear(&self) -> [Vec4; 3] {
        self.shear
    }
    #[inline(always)]
    fn t_min(&self) -> Vec4 {
        self.t_min
    }
}

/// [`GroupRayValues`] splat from the ray's fields at each use.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SplatOnUse<'a>(&'a TraversalRay);

impl<'a> SplatOnUse<'a> {
    #[inline(always)]
    pub fn new(ray: &'a TraversalRay) -> SplatOnUse<'a> {
        // `hits` indexes vertex rows by these without bounds checks.
        assert!(ray.shear_axes.iter().all(|&axis| axis < 3));
        SplatOnUse(ray)
    }
}

impl GroupRayValues for SplatOnUse<'_> {
    #[inline(always)]
    fn axes(&self) -> [usize; 3] {
        self.0.shear_axes
    }
    #[inline(always)]
    fn origin(&self) -> [Vec4; 3] {
        let origin = &self.0.permuted_origin;
        [origin.x, origin.y, origin.z].map(Vec4::splat)
    }
    #[inline(always)]
    fn shear(&self) -> [Vec4; 3] {
        let shear = &self.0.shear;
        [shear.x, shear.y, shear.z].map(Vec4::splat)
    }
    #[inline(always)]
    fn t_min(&self) -> Vec4 {
        Vec4::splat(self.0.t_min)
    }
}

/// [`GroupRayValues::hits`] for a group where some lane's edge function came out exactly zero:
/// the whole test again, those lanes' edge functions redone in f64. Out of line, so that the
/// common path keeps no sheared coordinates around for it.
#[cold]
#[inline(never)]
fn hits_on_edges<R: GroupRayValues + ?Sized>(
    ray: &R,
    group: &TriangleGroup,
    lanes: u32,
    t_max: f32,
) -> (u32, Vec4, [Vec4; 3]) {
    hits_with::<true, R>(ray, group, lanes, t_max)
}

#[inline(always)]
fn hits_with<const ON_EDGES: bool, R: GroupRayValues + ?Sized>(
    ray: &R,
    group: &TriangleGroup,
    lanes: u32,
    t_max: f32,
) -> (u32, Vec4, [Vec4; 3]) {
    let [kx, ky, kz] = ray.axes();
    let [origin_x, origin_y, origin_z] = ray.origin();
    let [shear_x, shear_y, shear_z] = ray.shear();
    let sheared = |vertex: &[Vec4; 3]| {
        // SAFETY: every `GroupRayValues` maker checked that every axis is below 3.
        let row = |axis: usize| unsafe { *vertex.get_unchecked(axis) };
        let z = row(kz) - origin_z;
        let x = (row(kx) - origin_x) - shear_x * z;
        let y = (row(ky) - origin_y) - shear_y * z;
        (x, y, z)
    };
    let (x0, y0, z0) = sheared(&group.vertices[0]);
    let (x1, y1, z1) = sheared(&group.vertices[1]);
    let (x2, y2, z2) = sheared(&group.vertices[2]);
    let mut u = x2 * y1 - y2 * x1;
    let mut v = x0 * y2 - y0 * x2;
    let mut w = x1 * y0 - y1 * x0;
    let zero = Vec4::ZERO;
    let mut on_edge = (u.cmpeq(zero) | v.cmpeq(zero) | w.cmpeq(zero)).bitmask() & lanes;
    if !ON_EDGES && on_edge != 0 {
        return hits_on_edges(ray, group, lanes, t_max);
    }
    while on_edge != 0 {
        let lane = on_edge.trailing_zeros() as usize;
        on_edge &= on_edge - 1;
        let exact = edge_functions_f64(
            Vec4::new(x0[lane], x1[lane], x2[lane], 0.0),
            Vec4::new(y0[lane], y1[lane], y2[lane], 0.0),
        );
        (u[lane], v[lane], w[lane]) = (exact.x, exact.y, exact.z);
    }
    let negative = u.cmplt(zero) | v.cmplt(zero) | w.cmplt(zero);
    let positive = u.cmpgt(zero) | v.cmpgt(zero) | w.cmpgt(zero);
    let determinant = u + v + w;
    let candidates = (!(negative & positive) & determinant.cmpne(zero)).bitmask() & lanes;
    if candidates == 0 {
        return (0, zero, [v, w, determinant]);
    }
    let scaled_t = u * (z0 * shear_z) + v * (z1 * shear_z) + w * (z2 * shear_z);
    let t = scaled_t / determinant;
    let inside = t.cmpge(ray.t_min()) & t.cmple(Vec4::splat(t_max));
    (inside.bitmask() & candidates, t, [v, w, determinant])
}

/// [`GroupRay::hits`] for a ray used once.
#[inline(always)]
fn group_hits(group: &TriangleGroup, lanes: u32, ray: &TraversalRay) -> (u32, Vec4, [Vec4; 3]) {
    GroupRay::new(ray).hits(group, lanes, ray.t_max)
}

/// `MISSED[hits]`: per lane `-inf` where bit `lane` of `hits` is set, else `+inf` (the max of a
/// lane's `t` with it keeps the hits and puts the rest beyond them).
static MISSED: [Vec4; 16] = {
    let mut table = [Vec4::ZERO; 16];
    let mut hits = 0;
    while hits < 16 {
        let mut lanes = [f32::INFINITY; 4];
        let mut lane = 0;
        while lane < 4 {
            if hits & (1 << lane) != 0 {
                lanes[lane] = f32::NEG_INFINITY;
            }
            lane += 1;
        }
        table[hits] = Vec4::from_array(lanes);
        hits += 1;
    }
    table
};

/// Among the hit lanes (`hits`, bit per lane, not empty) the one with the smallest `t`; among
/// lanes hit at the same `t` the last one, as when the triangles are tested one after another.
/// Returns the lane and its `t`.
#[inline(always)]
pub(crate) fn closest_lane(hits: u32, t: Vec4) -> (usize, f32) {
    let candidates = t.max(MISSED[(hits & 15) as usize]);
    let nearest_t = candidates.min_element();
    let nearest = candidates.cmpeq(Vec4::splat(nearest_t)).bitmask() & hits;
    ((31 - nearest.leading_zeros()) as usize, nearest_t)
}

/// Closest hit among a group's triangles in `lanes` (bit per lane): `(lane, t, b1, b2)`. Among
/// lanes hit at the same `t` the last one wins, as when the triangles are tested one after
/// another.
#[inline(always)]
pub(crate) fn group_closest(
    group: &TriangleGroup,
    lanes: u32,
    ray: &TraversalRay,
) -> Option<(usize, f32, Vec2)> {
    let (hits, t, [v, w, determinant]) = group_hits(group, lanes, ray);
    if hits == 0 {
        return None;
    }
    let (lane, t) = closest_lane(hits, t);
    let inv = 1.0 / determinant[lane];
    Some((lane, t, Vec2::new(v[lane] * inv, w[lane] * inv)))
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
#[cfg(test)]
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
