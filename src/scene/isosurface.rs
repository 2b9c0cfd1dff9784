//! Geometry `isosurface`: the surfaces where a spatial field equals one of its `isovalue`s,
//! intersected exactly. Every cell whose value range straddles an isovalue enters the BVH as one
//! procedural primitive per such isovalue. A ray meets a structured grid cell's trilinear
//! interpolant along a cubic in the ray parameter (Marmitt et al. 2004): the cubic's extrema
//! split the cell's stretch of the ray into monotone pieces and the first piece whose ends differ
//! in sign is bisected to f64 precision. Unstructured cells: tetrahedra are linear (the root is
//! closed-form), hexahedra that are parallelepipeds are trilinear like grid cells, and wedges,
//! pyramids and other hexahedra have their interpolant sampled at 16 points along the ray, the
//! first sign change bisected. Normals are the interpolant's gradient (pointing to higher
//! values). The ANARI primitive id of a hit is the index of its isovalue, so `primitive.*`
//! arrays give each isovalue its colour and attributes.

use std::sync::Arc;

use glam::{DMat3, DVec3, Vec2, Vec3};

use crate::accel::{GeometryBvh, ProceduralHit, ProceduralPrimitives, Ray};
use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::params::ParamValue;
use crate::device::pool::with_build_pool;
use crate::device::spec::{ObjectSpec, ParamSpec};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::cell_shapes::{CellGeometry, CellShape, hex_values_in_bit_order};
use crate::scene::field::Field;
use crate::scene::geometry::{Geometry, PRIMITIVE_ATTRIBUTES, Shape, read_attributes};

pub const ISOSURFACE: ObjectSpec = ObjectSpec::new(
    ANARI_GEOMETRY,
    "isosurface",
    "surfaces where a spatial field equals its isovalues, intersected exactly; the primitive id \
     of a hit is the index of its isovalue",
    &[
        ParamSpec::new(
            "isovalue",
            &[ANARI_FLOAT32, ANARI_ARRAY1D],
            "isovalue(s) defining the isosurface(s)",
        )
        .required()
        .elements(&[ANARI_FLOAT32]),
        ParamSpec::new(
            "field",
            &[ANARI_SPATIAL_FIELD],
            "spatial field to be isosurfaced (structuredRegular or unstructured; a new \
             commit of the field rebuilds the isosurface at the next render)",
        )
        .required(),
    ],
)
.shared(PRIMITIVE_ATTRIBUTES)
.extensions(&["ANARI_KHR_GEOMETRY_ISOSURFACE"]);

/// Pieces of a cell's stretch of ray sampled for the first sign change when the interpolant is
/// not a polynomial along the ray (wedges, pyramids, warped hexahedra).
const SAMPLED_PIECES: usize = 16;
/// Each cell's stretch of ray is widened by this fraction of its length on both sides, so that
/// a root on a face shared by two cells is not lost to rounding in both. The interpolant is
/// continuous across faces, so the widened search finds the same root.
const CLIP_SLACK: f64 = 1e-7;

/// The cells of a field that straddle an isovalue, as procedural primitives.
#[derive(Debug)]
struct IsoCells {
    field: Field,
    isovalues: Vec<f32>,
    /// Per primitive: (cell, isovalue index).
    entries: Vec<(u32, u32)>,
}

/// Polynomial in one variable, coefficients from the constant term up.
type Cubic = [f64; 4];

fn product(a: &Cubic, b: &Cubic) -> Cubic {
    let mut out = [0.0; 4];
    for i in 0..4 {
        for j in 0..4 - i {
            out[i + j] += a[i] * b[j];
        }
    }
    out
}

fn evaluate(p: &Cubic, s: f64) -> f64 {
    ((p[3] * s + p[2]) * s + p[1]) * s + p[0]
}

/// Coefficients of the trilinear interpolant of `v` (bit order x + 2y + 4z) in the basis
/// 1, x, y, z, xy, xz, yz, xyz.
fn trilinear_basis(v: &[f64; 8]) -> [f64; 8] {
    [
        v[0],
        v[1] - v[0],
        v[2] - v[0],
        v[4] - v[0],
        v[3] - v[1] - v[2] + v[0],
        v[5] - v[1] - v[4] + v[0],
        v[6] - v[2] - v[4] + v[0],
        v[7] - v[3] - v[5] - v[6] + v[1] + v[2] + v[4] - v[0],
    ]
}

/// Gradient, in cell coordinates, of the trilinear interpolant with basis coefficients `c`.
fn trilinear_gradient(c: &[f64; 8], p: DVec3) -> DVec3 {
    DVec3::new(
        c[1] + c[4] * p.y + c[5] * p.z + c[7] * p.y * p.z,
        c[2] + c[4] * p.x + c[6] * p.z + c[7] * p.x * p.z,
        c[3] + c[5] * p.x + c[6] * p.y + c[7] * p.x * p.y,
    )
}

/// Bisects `f` on `[lo, hi]` (whose ends differ in sign) down to adjacent doubles.
fn bisect(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    let lo_sign = f(lo) < 0.0;
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        let value = f(mid);
        if value == 0.0 {
            return mid;
        }
        if (value < 0.0) == lo_sign {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// First ray parameter in `[t0, t1]` where the trilinear interpolant of `v` (isovalue already
/// subtracted, bit order) is zero along the cell-coordinate line `a + b t`.
fn trilinear_root(v: &[f64; 8], a: DVec3, b: DVec3, t0: f64, t1: f64) -> Option<f64> {
    let c = trilinear_basis(v);
    let start = a + b * t0;
    let [x, y, z] = [0, 1, 2].map(|k| [start[k], b[k], 0.0, 0.0]);
    let (xy, xz, yz) = (product(&x, &y), product(&x, &z), product(&y, &z));
    let xyz = product(&xy, &z);
    let mut f = [c[0], 0.0, 0.0, 0.0];
    for (coefficient, term) in [
        (c[1], x),
        (c[2], y),
        (c[3], z),
        (c[4], xy),
        (c[5], xz),
        (c[6], yz),
        (c[7], xyz),
    ] {
        for k in 0..4 {
            f[k] += coefficient * term[k];
        }
    }
    let length = t1 - t0;
    // Extrema of the cubic (roots of its derivative 3f₃s² + 2f₂s + f₁) inside the stretch.
    let mut cuts = [0.0, length, length, length];
    let (qa, qb, qc) = (3.0 * f[3], 2.0 * f[2], f[1]);
    let mut count = 1;
    let mut add = |s: f64| {
        if s > 0.0 && s < length {
            cuts[count] = s;
            count += 1;
        }
    };
    if qa == 0.0 {
        if qb != 0.0 {
            add(-qc / qb);
        }
    } else {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            let q = -0.5 * (qb + disc.sqrt().copysign(qb));
            let roots = if q == 0.0 {
                [0.0, 0.0]
            } else {
                [q / qa, qc / q]
            };
            add(roots[0].min(roots[1]));
            add(roots[0].max(roots[1]));
        }
    }
    cuts[count] = length;
    let cuts = &mut cuts[..=count];
    cuts.sort_by(f64::total_cmp);
    for piece in cuts.windows(2) {
        let (l, r) = (piece[0], piece[1]);
        let (fl, fr) = (evaluate(&f, l), evaluate(&f, r));
        if fl == 0.0 {
            return Some(t0 + l);
        }
        if (fl < 0.0) != (fr < 0.0) {
            return Some(t0 + bisect(|s| evaluate(&f, s), l, r));
        }
    }
    (evaluate(&f, length) == 0.0).then_some(t1)
}

/// The ray's stretch inside the box [0, 1]³ of cell coordinates `a + b t`.
fn unit_box_clip(a: DVec3, b: DVec3) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        if b[k] == 0.0 {
            if !(0.0..=1.0).contains(&a[k]) {
                return None;
            }
            continue;
        }
        let (u, w) = (-a[k] / b[k], (1.0 - a[k]) / b[k]);
        t0 = t0.max(u.min(w));
        t1 = t1.min(u.max(w));
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Widens a cell's stretch a little and cuts it to the ray's interval. The upper end reaches
/// up to the next f32 above `t_max`: a root found there may still round to `t_max` (as it does
/// when a hit is looked up again with `t_max` set to it).
fn search_interval((t0, t1): (f64, f64), ray: &Ray) -> Option<(f64, f64)> {
    let slack = (t1 - t0) * CLIP_SLACK + (t0.abs() + t1.abs()) * 1e-12;
    let upper = ray.t_max.next_up() as f64;
    let (t0, t1) = ((t0 - slack).max(ray.t_min as f64), (t1 + slack).min(upper));
    (t0 <= t1).then_some((t0, t1))
}

/// Unit normal from a gradient, or against the ray where the gradient vanishes.
fn normal_from(gradient: DVec3, direction: DVec3) -> Vec3 {
    let unit = gradient.normalize_or_zero();
    let unit = if unit == DVec3::ZERO {
        -direction.normalize_or(DVec3::Z)
    } else {
        unit
    };
    unit.as_vec3().normalize_or(Vec3::Z)
}

impl IsoCells {
    /// A trilinear cell (grid cell or parallelepiped) in the frame `x = origin + frame · ξ`.
    fn trilinear_hit(
        &self,
        values: [f64; 8],
        (origin, frame): (DVec3, DMat3),
        ray: &Ray,
    ) -> Option<(f64, DVec3)> {
        let inverse = frame.inverse();
        let o = ray.origin.as_dvec3();
        let d = ray.direction.as_dvec3();
        let a = inverse * (o - origin);
        let b = inverse * d;
        let (t0, t1) = search_interval(unit_box_clip(a, b)?, ray)?;
        let t = trilinear_root(&values, a, b, t0, t1)?;
        let gradient =
            inverse.transpose() * trilinear_gradient(&trilinear_basis(&values), a + b * t);
        Some((t, gradient))
    }

    /// A tetrahedron: the interpolant is linear, so the root is closed-form.
    fn linear_hit(&self, cell: &CellGeometry, values: &[f64], ray: &Ray) -> Option<(f64, DVec3)> {
        let o = ray.origin.as_dvec3();
        let d = ray.direction.as_dvec3();
        let (t0, t1) = search_interval(cell.clip(o, d)?, ray)?;
        let gradient = cell.gradient(DVec3::splat(0.25), values);
        let speed = gradient.dot(d);
        if speed == 0.0 {
            return None;
        }
        let t = (-values[0] - gradient.dot(o - cell.points[0])) / speed;
        (t >= t0 && t <= t1).then_some((t, gradient))
    }

    /// Any other cell: the interpolant sampled along the ray, the first sign change bisected.
    fn sampled_hit(&self, cell: &CellGeometry, values: &[f64], ray: &Ray) -> Option<(f64, DVec3)> {
        let o = ray.origin.as_dvec3();
        let d = ray.direction.as_dvec3();
        let (t0, t1) = search_interval(cell.clip(o, d)?, ray)?;
        let count = cell.shape.vertex_count();
        let at = |t: f64| -> Option<(f64, DVec3)> {
            let xi = cell.parametric(o + d * t)?;
            let (weights, _) = cell.shape.weights(xi);
            Some((
                weights
                    .iter()
                    .zip(values)
                    .take(count)
                    .map(|(w, v)| w * v)
                    .sum(),
                xi,
            ))
        };
        let mut previous: Option<(f64, f64)> = None;
        for k in 0..=SAMPLED_PIECES {
            let t = t0 + (t1 - t0) * k as f64 / SAMPLED_PIECES as f64;
            let Some((value, _)) = at(t) else {
                previous = None;
                continue;
            };
            let root = match previous {
                _ if value == 0.0 => Some(t),
                Some((tp, vp)) if (vp < 0.0) != (value < 0.0) => {
                    Some(bisect(|s| at(s).map_or(f64::NAN, |(v, _)| v), tp, t))
                }
                _ => None,
            };
            if let Some(root) = root {
                let (_, xi) = at(root)?;
                return Some((root, cell.gradient(xi, values)));
            }
            previous = Some((t, value));
        }
        None
    }
}

impl ProceduralPrimitives for IsoCells {
    fn count(&self) -> usize {
        self.entries.len()
    }

    fn bounds(&self, index: u32) -> Option<(Vec3, Vec3)> {
        let (cell, _) = self.entries[index as usize];
        Some(match &self.field {
            Field::Structured(f) => {
                let (origin, spacing) = f.grid();
                let lo = origin + grid_cell(f.dims(), cell).as_vec3() * spacing;
                let hi = lo + spacing;
                let pad = (hi - lo)
                    .max_element()
                    .max(lo.abs().max(hi.abs()).max_element())
                    * 1e-6;
                (lo - pad, hi + pad)
            }
            Field::Unstructured(f) => f.cell_bounds(cell),
        })
    }

    fn intersect(&self, index: u32, ray: &Ray) -> Option<ProceduralHit> {
        let (cell, iso) = self.entries[index as usize];
        let isovalue = self.isovalues[iso as usize] as f64;
        let (t, gradient) = match &self.field {
            Field::Structured(f) => {
                let corner = grid_cell(f.dims(), cell);
                let values = std::array::from_fn(|b| {
                    let at =
                        corner + glam::UVec3::new(b as u32 & 1, (b as u32 >> 1) & 1, b as u32 >> 2);
                    f.vertex_value([at.x as usize, at.y as usize, at.z as usize]) as f64 - isovalue
                });
                let (origin, spacing) = f.grid();
                let lo = origin.as_dvec3() + corner.as_dvec3() * spacing.as_dvec3();
                self.trilinear_hit(values, (lo, DMat3::from_diagonal(spacing.as_dvec3())), ray)?
            }
            Field::Unstructured(f) => {
                let geometry = f.cell_geometry(cell);
                let mut values = f.cell_values(cell);
                values.iter_mut().for_each(|v| *v -= isovalue);
                let values = &values[..geometry.shape.vertex_count()];
                if geometry.shape == CellShape::Tetrahedron {
                    self.linear_hit(&geometry, values, ray)?
                } else if let Some(frame) = geometry.affine_frame() {
                    self.trilinear_hit(hex_values_in_bit_order(values), frame, ray)?
                } else {
                    self.sampled_hit(&geometry, values, ray)?
                }
            }
        };
        let t32 = t as f32;
        (t32 >= ray.t_min && t32 <= ray.t_max).then(|| ProceduralHit {
            t: t32,
            normal: normal_from(gradient, ray.direction.as_dvec3()),
            uv: Vec2::ZERO,
        })
    }

    fn memory_bytes(&self) -> usize {
        self.entries.capacity() * 8 + self.isovalues.capacity() * 4
    }
}

/// Grid coordinates of the lower corner of structured cell number `cell` (x fastest).
fn grid_cell(dims: [usize; 3], cell: u32) -> glam::UVec3 {
    let (cx, cy) = (dims[0] as u32 - 1, dims[1] as u32 - 1);
    glam::UVec3::new(cell % cx, (cell / cx) % cy, cell / (cx * cy))
}

/// (cell, isovalue index) for every cell whose values straddle an isovalue; cells of one
/// constant value are left out (their level set is the whole cell, not a surface).
fn straddling_cells(field: &Field, isovalues: &[f32]) -> Vec<(u32, u32)> {
    let mut entries = Vec::new();
    let mut add = |cell: u32, values: &[f64]| {
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if lo < hi {
            for (k, iso) in isovalues.iter().enumerate() {
                if (lo..=hi).contains(&(*iso as f64)) {
                    entries.push((cell, k as u32));
                }
            }
        }
    };
    match field {
        Field::Structured(f) => {
            let [nx, ny, nz] = f.dims();
            if nx < 2 || ny < 2 || nz < 2 {
                return entries;
            }
            let cells = (nx - 1) * (ny - 1) * (nz - 1);
            for cell in 0..cells.min(u32::MAX as usize) as u32 {
                let corner = grid_cell(f.dims(), cell);
                let values: [f64; 8] = std::array::from_fn(|b| {
                    let at =
                        corner + glam::UVec3::new(b as u32 & 1, (b as u32 >> 1) & 1, b as u32 >> 2);
                    f.vertex_value([at.x as usize, at.y as usize, at.z as usize]) as f64
                });
                add(cell, &values);
            }
        }
        Field::Unstructured(f) => {
            for cell in 0..f.cell_count() as u32 {
                let count = f.cell_geometry(cell).shape.vertex_count();
                add(cell, &f.cell_values(cell)[..count]);
            }
        }
    }
    entries
}

/// The BVH over the straddling cells and, per BVH primitive, its isovalue index (the ANARI
/// primitive id).
fn build(field: Field, isovalues: Vec<f32>) -> (GeometryBvh, Vec<u32>) {
    let entries = straddling_cells(&field, &isovalues);
    let primitive_ids = entries.iter().map(|(_, iso)| *iso).collect();
    let cells = IsoCells {
        field,
        isovalues,
        entries,
    };
    (
        GeometryBvh::build_procedural(Arc::new(cells)),
        primitive_ids,
    )
}

/// An isosurface's derived state: its geometry (`None` when it cannot be rendered) and the
/// commit count its field had when it was built, so that a later commit of the field rebuilds
/// it at the next render.
#[derive(Debug)]
pub struct IsosurfaceBuild {
    field_commit: Option<u64>,
    geometry: Option<Arc<Geometry>>,
}

/// Builds the isosurface at its commit.
pub fn commit(device: &Device, object: &Object) -> IsosurfaceBuild {
    build_from_field(
        device,
        object,
        "anariCommitParameters: geometry 'isosurface'",
    )
}

/// The isosurface as the next frame renders it: rebuilt when its field was committed since
/// the last build (each time step of a simulation), reused otherwise.
pub fn current(device: &Device, object: &Object) -> Option<Arc<Geometry>> {
    let derived = object.derived()?;
    let built = Arc::clone(&derived).downcast::<IsosurfaceBuild>().ok()?;
    let field_commit = field_commit(object);
    if field_commit == built.field_commit {
        return built.geometry.clone();
    }
    let rebuilt = Arc::new(build_from_field(
        device,
        object,
        "anariRenderFrame: geometry 'isosurface' (rebuilt for its field's new commit)",
    ));
    let geometry = rebuilt.geometry.clone();
    object.replace_derived_if_unchanged(&derived, rebuilt);
    geometry
}

fn field_commit(object: &Object) -> Option<u64> {
    object
        .committed()
        .get_object("field")
        .map(|field| field.commit_count())
}

/// The isosurface of the field's current build, stamped with the field's commit count (read
/// first, so that a commit of the field during the build is seen at the next render).
fn build_from_field(device: &Device, object: &Object, what: &str) -> IsosurfaceBuild {
    IsosurfaceBuild {
        field_commit: field_commit(object),
        geometry: build_geometry(device, object, what).map(Arc::new),
    }
}

/// Builds the isosurface geometry; reports and returns `None` when it cannot be rendered.
fn build_geometry(device: &Device, object: &Object, what: &str) -> Option<Geometry> {
    let params = object.committed();
    let fail = |text: String| {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!("{what} {text}; nothing is rendered"),
        );
        None
    };
    // Missing required parameters are already reported.
    let field_object = params.get_object("field")?;
    let Some(field) = Field::of(field_object) else {
        return fail(format!(
            "parameter 'field': the {} is not a usable committed spatial field",
            field_object.describe()
        ));
    };
    let isovalues = match params.get("isovalue")? {
        ParamValue::Object { object: array, .. } => {
            match array.array.as_ref().and_then(|a| a.read_f32()) {
                Some(values) => values,
                None => {
                    return fail(format!(
                        "parameter 'isovalue': the {} does not hold ANARI_FLOAT32 values",
                        array.describe()
                    ));
                }
            }
        }
        _ => match params.get_f32("isovalue") {
            Some(value) => vec![value],
            None => return fail("parameter 'isovalue' is not an ANARI_FLOAT32".into()),
        },
    };
    if isovalues.is_empty() {
        return fail("parameter 'isovalue' is an empty array".into());
    }
    if let Some(k) = isovalues.iter().position(|v| !v.is_finite()) {
        device.warning(
            Some(object),
            format!("{what} isovalue {k} is not finite; that surface is empty"),
        );
    }
    match &field {
        Field::Structured(f) if f.is_nearest() => device.warning(
            Some(object),
            format!(
                "{what}: the field's filter is 'nearest'; the isosurface is taken of its \
                 trilinear interpolant"
            ),
        ),
        Field::Unstructured(f) if f.is_cell_centred() => device.warning(
            Some(object),
            format!(
                "{what}: the field has cell-centred values, constant inside each cell, so no \
                 cell holds an isosurface; nothing is rendered (give 'vertex.data' instead)"
            ),
        ),
        _ => {}
    }
    let (bvh, primitive_ids) = with_build_pool(device.requested_thread_count(), || {
        build(field, isovalues.clone())
    });
    if primitive_ids.is_empty() {
        device.warning(
            Some(object),
            format!(
                "{what}: no cell of the field has values on both sides of any isovalue \
                 {isovalues:?}; the isosurface is empty"
            ),
        );
    }
    Some(Geometry {
        shape: Shape::Isosurface,
        bvh: Arc::new(bvh),
        primitive_ids: Some(primitive_ids),
        vertex_indices: Vec::new(),
        vertex_normals: None,
        corner_normals: None,
        vertex_tangents: None,
        corner_tangents: None,
        attributes: read_attributes(&params, false),
    })
}

#[cfg(test)]
mod tests;
