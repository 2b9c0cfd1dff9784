//! Spatial fields: `structuredRegular`, a vertex-centred grid of scalars placed by `origin` and
//! `spacing`, reconstructed with nearest-vertex or trilinear filtering. The voxels are copied at
//! commit in their own width (8 or 16 bits stay 8 or 16 bits; FLOAT64 narrows to FLOAT32).

use glam::Vec3;

use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::macrocells::MacrocellGrid;

/// Element types `data` may hold (KHR_SPATIAL_FIELD_STRUCTURED_REGULAR).
pub const DATA_ELEMENT_TYPES: &[ANARIDataType] = &[
    ANARI_UFIXED8,
    ANARI_FIXED16,
    ANARI_UFIXED16,
    ANARI_FLOAT32,
    ANARI_FLOAT64,
];

pub const STRUCTURED_REGULAR: ObjectSpec = ObjectSpec::new(
    ANARI_SPATIAL_FIELD,
    "structuredRegular",
    "vertex-centred scalars on a regular 3D grid",
    &[
        ParamSpec::new(
            "data",
            &[ANARI_ARRAY3D],
            "vertex-centred scalar values, x fastest",
        )
        .required()
        .elements(DATA_ELEMENT_TYPES),
        ParamSpec::new(
            "origin",
            &[ANARI_FLOAT32_VEC3],
            "position of the first vertex in object space",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new(
            "spacing",
            &[ANARI_FLOAT32_VEC3],
            "size of a grid cell in object space",
        )
        .default(SpecValue::Floats(&[1.0, 1.0, 1.0])),
        ParamSpec::new("filter", &[ANARI_STRING], "reconstruction between vertices")
            .default(SpecValue::Str("linear"))
            .values(&["nearest", "linear"]),
    ],
)
.extensions(&["ANARI_KHR_SPATIAL_FIELD_STRUCTURED_REGULAR"]);

/// Most samples a ray takes along the diagonal of one field's box: bounds the cost of grids
/// with very uneven spacing (the step never drops below diagonal / this).
const MAX_SAMPLES_PER_DIAGONAL: f32 = 4096.0;

/// Voxel values in the width they were given; fixed-point types are normalised when read.
#[derive(Debug)]
enum Voxels {
    Unorm8(Vec<u8>),
    Snorm16(Vec<i16>),
    Unorm16(Vec<u16>),
    Float(Vec<f32>),
}

trait Voxel: Copy {
    fn value(self) -> f32;
}

impl Voxel for u8 {
    fn value(self) -> f32 {
        self as f32 / 255.0
    }
}

impl Voxel for i16 {
    fn value(self) -> f32 {
        // Both -32768 and -32767 map to -1, as for signed normalised formats elsewhere.
        (self as f32 / 32767.0).max(-1.0)
    }
}

impl Voxel for u16 {
    fn value(self) -> f32 {
        self as f32 / 65535.0
    }
}

impl Voxel for f32 {
    fn value(self) -> f32 {
        self
    }
}

/// A committed `structuredRegular` field.
#[derive(Debug)]
pub struct StructuredRegularField {
    dims: [usize; 3],
    voxels: Voxels,
    origin: Vec3,
    spacing: Vec3,
    inverse_spacing: Vec3,
    /// Largest grid coordinate on each axis (dims − 1).
    last: Vec3,
    nearest: bool,
    /// Value ranges of blocks of cells, for volumes' empty-space skipping.
    macrocells: MacrocellGrid,
}

impl StructuredRegularField {
    fn new(
        dims: [usize; 3],
        voxels: Voxels,
        origin: Vec3,
        spacing: Vec3,
        nearest: bool,
    ) -> StructuredRegularField {
        let mut field = StructuredRegularField {
            dims,
            voxels,
            origin,
            spacing,
            inverse_spacing: spacing.recip(),
            last: Vec3::new(
                (dims[0] - 1) as f32,
                (dims[1] - 1) as f32,
                (dims[2] - 1) as f32,
            ),
            nearest,
            macrocells: MacrocellGrid::over_grid([1, 1, 1], origin, spacing, |_| f32::NAN),
        };
        field.macrocells =
            MacrocellGrid::over_grid(dims, origin, spacing, |v| field.vertex_value(v));
        field
    }

    /// Value ranges of blocks of cells.
    pub fn macrocells(&self) -> &MacrocellGrid {
        &self.macrocells
    }

    /// A field of FLOAT32 values (x fastest); `None` when `values` does not fill `dims`.
    pub fn from_floats(
        dims: [usize; 3],
        values: Vec<f32>,
        origin: Vec3,
        spacing: Vec3,
        nearest: bool,
    ) -> Option<StructuredRegularField> {
        let count = dims[0].checked_mul(dims[1])?.checked_mul(dims[2])?;
        (count == values.len() && count > 0).then(|| {
            StructuredRegularField::new(dims, Voxels::Float(values), origin, spacing, nearest)
        })
    }

    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Position of vertex (0, 0, 0) and the size of a cell.
    pub fn grid(&self) -> (Vec3, Vec3) {
        (self.origin, self.spacing)
    }

    /// Whether values are reconstructed by nearest-vertex filtering.
    pub fn is_nearest(&self) -> bool {
        self.nearest
    }

    /// The value at grid vertex `[i, j, k]` (each below its `dims`).
    pub fn vertex_value(&self, [i, j, k]: [usize; 3]) -> f32 {
        let index = i + self.dims[0] * (j + self.dims[1] * k);
        match &self.voxels {
            Voxels::Unorm8(v) => v[index].value(),
            Voxels::Snorm16(v) => v[index].value(),
            Voxels::Unorm16(v) => v[index].value(),
            Voxels::Float(v) => v[index],
        }
    }

    /// Object-space box [origin, origin + (dims − 1) × spacing].
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.origin, self.origin + self.last * self.spacing)
    }

    /// Object-space distance between ray-marching samples: half the smallest cell side, so
    /// that every cell is sampled at least twice along any axis.
    pub fn step(&self) -> f32 {
        let (lo, hi) = self.bounds();
        let floor = (hi - lo).length() / MAX_SAMPLES_PER_DIAGONAL;
        (self.spacing.min_element() * 0.5).max(floor)
    }

    /// The field at object-space `point`, which is clamped into the box first (ray marching
    /// samples on the box faces, where rounding may put a point a hair outside).
    #[inline]
    pub fn sample(&self, point: Vec3) -> f32 {
        let local = ((point - self.origin) * self.inverse_spacing).clamp(Vec3::ZERO, self.last);
        match &self.voxels {
            Voxels::Unorm8(v) => self.sample_in(v, local),
            Voxels::Snorm16(v) => self.sample_in(v, local),
            Voxels::Unorm16(v) => self.sample_in(v, local),
            Voxels::Float(v) => self.sample_in(v, local),
        }
    }

    /// `local` is a grid coordinate already clamped into [0, dims − 1].
    #[inline]
    fn sample_in<T: Voxel>(&self, voxels: &[T], local: Vec3) -> f32 {
        let [nx, ny, nz] = self.dims;
        if self.nearest {
            let i = local.round();
            return voxels[i.x as usize + nx * (i.y as usize + ny * i.z as usize)].value();
        }
        // The cell's lower corner and the strides to its upper neighbours (0 on a flat axis,
        // and the last cell on each axis also serves its far face).
        let axis = |l: f32, n: usize, stride: usize| {
            if n < 2 {
                return (0, 0, 0.0);
            }
            let lower = (l as usize).min(n - 2);
            (lower, stride, l - lower as f32)
        };
        let (x0, sx, fx) = axis(local.x, nx, 1);
        let (y0, sy, fy) = axis(local.y, ny, nx);
        let (z0, sz, fz) = axis(local.z, nz, nx * ny);
        let base = x0 + nx * (y0 + ny * z0);
        let cell = &voxels[base..=base + sx + sy + sz];
        let lerp = |a: f32, b: f32, f: f32| a + (b - a) * f;
        let row = |offset: usize| lerp(cell[offset].value(), cell[offset + sx].value(), fx);
        let plane = |offset: usize| lerp(row(offset), row(offset + sy), fy);
        lerp(plane(0), plane(sz), fz)
    }
}

/// Scalars of any `DATA_ELEMENT_TYPES` element type, fixed-point normalised (the unstructured
/// field's `vertex.data` and `cell.data`).
pub fn decode_scalars(element_type: ANARIDataType, bytes: &[u8]) -> Option<Vec<f32>> {
    Some(match decode(element_type, bytes)? {
        Voxels::Unorm8(v) => v.into_iter().map(Voxel::value).collect(),
        Voxels::Snorm16(v) => v.into_iter().map(Voxel::value).collect(),
        Voxels::Unorm16(v) => v.into_iter().map(Voxel::value).collect(),
        Voxels::Float(v) => v,
    })
}

fn decode(element_type: ANARIDataType, bytes: &[u8]) -> Option<Voxels> {
    Some(match element_type {
        ANARI_UFIXED8 => Voxels::Unorm8(bytes.to_vec()),
        ANARI_FIXED16 => Voxels::Snorm16(
            bytes
                .chunks_exact(2)
                .map(|c| i16::from_ne_bytes([c[0], c[1]]))
                .collect(),
        ),
        ANARI_UFIXED16 => Voxels::Unorm16(
            bytes
                .chunks_exact(2)
                .map(|c| u16::from_ne_bytes([c[0], c[1]]))
                .collect(),
        ),
        ANARI_FLOAT32 => Voxels::Float(
            bytes
                .chunks_exact(4)
                .map(|c| f32::from_ne_bytes(c.try_into().unwrap()))
                .collect(),
        ),
        ANARI_FLOAT64 => Voxels::Float(
            bytes
                .chunks_exact(8)
                .map(|c| f64::from_ne_bytes(c.try_into().unwrap()) as f32)
                .collect(),
        ),
        _ => return None,
    })
}

/// Builds the field from its committed parameters; reports and returns `None` when it cannot
/// be sampled.
pub fn commit(device: &Device, object: &Object) -> Option<StructuredRegularField> {
    if object.subtype != STRUCTURED_REGULAR.subtype {
        return None;
    }
    let params = object.committed();
    let fail = |what: String| {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!(
                "anariCommitParameters: spatial field 'structuredRegular' {what}; the field \
                 renders nothing"
            ),
        );
        None
    };
    // A missing 'data' is already reported as a missing required parameter.
    let data = params.get_object("data")?;
    let Some(store) = data.array.as_ref().filter(|_| data.kind == ANARI_ARRAY3D) else {
        return fail(format!(
            "parameter 'data' is a {}, expected an ANARI_ARRAY3D",
            data.describe()
        ));
    };
    if !DATA_ELEMENT_TYPES.contains(&store.element_type) {
        return fail(format!(
            "parameter 'data' holds {}, expected one of {}",
            type_name(store.element_type),
            DATA_ELEMENT_TYPES
                .iter()
                .map(|t| type_name(*t))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    let dims = store.dims.map(|d| d as usize);
    if dims.contains(&0) {
        return fail(format!("parameter 'data' is empty ({dims:?} vertices)"));
    }
    let origin = params.get_vec3("origin").unwrap_or(Vec3::ZERO);
    if !origin.is_finite() {
        return fail(format!("parameter 'origin' {origin} is not finite"));
    }
    let spacing = params.get_vec3("spacing").unwrap_or(Vec3::ONE);
    if !spacing.is_finite() || spacing.min_element() <= 0.0 {
        return fail(format!(
            "parameter 'spacing' {spacing} must be finite and positive on every axis"
        ));
    }
    let nearest = match params.get_string("filter") {
        None | Some("linear") => false,
        Some("nearest") => true,
        Some(other) => {
            device.warning(
                Some(object),
                format!(
                    "anariCommitParameters: spatial field 'structuredRegular' parameter \
                     'filter': unknown value '{other}' (accepted: nearest, linear); using linear"
                ),
            );
            false
        }
    };
    if dims.iter().any(|&d| d < 2) {
        device.warning(
            Some(object),
            format!(
                "anariCommitParameters: spatial field 'structuredRegular' has {dims:?} vertices; \
                 with fewer than 2 along an axis its box is flat and renders nothing"
            ),
        );
    }
    let voxels = store.with_bytes(|bytes| decode(store.element_type, bytes))?;
    Some(StructuredRegularField::new(
        dims, voxels, origin, spacing, nearest,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 2×2×2 grid: value = x index (0 or 1), spacing 2 from origin (1, 0, 0).
    fn ramp(nearest: bool) -> StructuredRegularField {
        let values = (0..8).map(|i| (i % 2) as f32).collect();
        StructuredRegularField::from_floats(
            [2, 2, 2],
            values,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::splat(2.0),
            nearest,
        )
        .unwrap()
    }

    #[test]
    fn bounds_follow_origin_spacing_and_vertex_count() {
        let field = ramp(false);
        assert_eq!(
            field.bounds(),
            (Vec3::new(1.0, 0.0, 0.0), Vec3::new(3.0, 2.0, 2.0))
        );
        assert_eq!(field.step(), 1.0);
    }

    #[test]
    fn linear_interpolates_and_nearest_picks_the_closest_vertex() {
        let linear = ramp(false);
        let nearest = ramp(true);
        assert!((linear.sample(Vec3::new(1.5, 1.0, 1.0)) - 0.25).abs() < 1e-6);
        assert_eq!(nearest.sample(Vec3::new(1.5, 1.0, 1.0)), 0.0);
        assert_eq!(nearest.sample(Vec3::new(2.5, 1.0, 1.0)), 1.0);
        // Outside the box: clamped to the face.
        assert_eq!(linear.sample(Vec3::new(9.0, 1.0, 1.0)), 1.0);
    }

    #[test]
    fn fixed_point_voxels_are_normalised() {
        let Some(Voxels::Snorm16(v)) = decode(ANARI_FIXED16, &(-32768i16).to_ne_bytes()) else {
            panic!("FIXED16 decodes")
        };
        assert_eq!(v[0].value(), -1.0);
        assert_eq!(255u8.value(), 1.0);
        assert_eq!(32767i16.value(), 1.0);
        assert_eq!(65535u16.value(), 1.0);
        assert!(decode(ANARI_FLOAT32_VEC3, &[0; 12]).is_none());
    }
}
