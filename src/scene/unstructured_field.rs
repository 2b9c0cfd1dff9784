//! Spatial fields: `unstructured`, scalars on a mesh of tetrahedra, hexahedra, wedges and
//! pyramids (VTK cell types 10, 12, 13, 14 and VTK's vertex order), given per vertex and
//! interpolated by each cell's shape functions, or given per cell and constant inside it. A
//! point is located through a BVH over the cells' boxes; outside every cell the field has no
//! value (NaN, which volumes treat as empty space).

use glam::{DVec3, Vec3};

use crate::device::Device;
use crate::device::array::ArrayStore;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::spec::{ObjectSpec, ParamSpec};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::cell_shapes::{CellGeometry, CellShape, MAX_CELL_VERTICES};
use crate::scene::macrocells::MacrocellGrid;
use crate::scene::spatial_field::{DATA_ELEMENT_TYPES, decode_scalars};

const ARRAY: &[ANARIDataType] = &[ANARI_ARRAY1D];

pub const UNSTRUCTURED: ObjectSpec = ObjectSpec::new(
    ANARI_SPATIAL_FIELD,
    "unstructured",
    "scalars on tetrahedra, hexahedra, wedges and pyramids (VTK cell types and vertex order)",
    &[
        ParamSpec::new("vertex.position", ARRAY, "vertex positions")
            .required()
            .elements(&[ANARI_FLOAT32_VEC3]),
        ParamSpec::new(
            "vertex.data",
            ARRAY,
            "vertex-centred scalars, interpolated by each cell's shape functions (used when \
             both vertex.data and cell.data are set)",
        )
        .elements(DATA_ELEMENT_TYPES),
        ParamSpec::new(
            "index",
            ARRAY,
            "vertex indices of all cells, one after the other; absent: 0, 1, 2, …",
        )
        .elements(&[ANARI_UINT32]),
        ParamSpec::new(
            "cell.data",
            ARRAY,
            "cell-centred scalars, constant inside each cell",
        )
        .elements(DATA_ELEMENT_TYPES),
        ParamSpec::new(
            "cell.type",
            ARRAY,
            "VTK type of each cell: 10 tetrahedron, 12 hexahedron, 13 wedge, 14 pyramid; \
             absent: read from the spacing of cell.index (4, 8, 6, 5 vertices)",
        )
        .elements(&[ANARI_UINT8]),
        ParamSpec::new(
            "cell.index",
            ARRAY,
            "position in 'index' of each cell's first vertex; absent: cells follow one another",
        )
        .elements(&[ANARI_UINT32]),
    ],
)
.extensions(&["ANARI_KHR_SPATIAL_FIELD_UNSTRUCTURED"]);

/// Same bound on marching samples along the field's diagonal as for structured fields.
const MAX_SAMPLES_PER_DIAGONAL: f32 = 4096.0;
/// Cells per leaf of the point-location BVH.
const LEAF_CELLS: usize = 4;

/// Where a field's values live.
#[derive(Debug)]
enum Values {
    PerVertex(Vec<f32>),
    PerCell(Vec<f32>),
}

#[derive(Clone, Copy, Debug)]
struct Cell {
    shape: CellShape,
    /// Position of the first vertex in `indices`.
    first: u32,
}

/// A node of the point-location BVH: a leaf holds `count > 0` cells from `start` in the cell
/// order; an inner node's children are the next node and node `start`.
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    start: u32,
    count: u32,
}

/// A committed `unstructured` field.
#[derive(Debug)]
pub struct UnstructuredField {
    positions: Vec<Vec3>,
    indices: Vec<u32>,
    cells: Vec<Cell>,
    /// Per cell, its box padded by a hair so that points on faces are found.
    boxes: Vec<(Vec3, Vec3)>,
    values: Values,
    nodes: Vec<Node>,
    /// Cells in BVH leaf order.
    order: Vec<u32>,
    bounds: (Vec3, Vec3),
    step: f32,
    /// Value ranges of blocks of space, for volumes' empty-space skipping.
    macrocells: MacrocellGrid,
}

fn cell_box(points: &[DVec3]) -> (Vec3, Vec3) {
    let lo = points.iter().fold(DVec3::INFINITY, |a, p| a.min(*p));
    let hi = points.iter().fold(DVec3::NEG_INFINITY, |a, p| a.max(*p));
    let pad = (hi - lo)
        .max_element()
        .max(lo.abs().max(hi.abs()).max_element())
        * 1e-6;
    ((lo - pad).as_vec3(), (hi + pad).as_vec3())
}

impl UnstructuredField {
    /// The cell ids the builder kept, in the input order of `cell_data`/cells. Every cell must
    /// already be valid (indices in range, finite positions).
    fn new(positions: Vec<Vec3>, indices: Vec<u32>, cells: Vec<Cell>, values: Values) -> Self {
        let mut field = UnstructuredField {
            positions,
            indices,
            cells,
            boxes: Vec::new(),
            values,
            nodes: Vec::new(),
            order: Vec::new(),
            bounds: (Vec3::INFINITY, Vec3::NEG_INFINITY),
            step: 0.0,
            macrocells: MacrocellGrid::over_cells((Vec3::ZERO, Vec3::ONE), std::iter::empty(), 0),
        };
        let mut smallest_side = f32::INFINITY;
        field.boxes = (0..field.cells.len())
            .map(|c| {
                let geometry = field.cell_geometry(c as u32);
                let points = &geometry.points[..geometry.shape.vertex_count()];
                let (lo, hi) = cell_box(points);
                let exact_lo = points.iter().fold(DVec3::INFINITY, |a, p| a.min(*p));
                let exact_hi = points.iter().fold(DVec3::NEG_INFINITY, |a, p| a.max(*p));
                smallest_side = smallest_side.min((exact_hi - exact_lo).min_element() as f32);
                field.bounds = (
                    field.bounds.0.min(exact_lo.as_vec3()),
                    field.bounds.1.max(exact_hi.as_vec3()),
                );
                (lo, hi)
            })
            .collect();
        let (lo, hi) = field.bounds;
        let floor = (hi - lo).length() / MAX_SAMPLES_PER_DIAGONAL;
        field.step = (smallest_side * 0.5).max(floor);
        field.order = (0..field.cells.len() as u32).collect();
        let mut order = std::mem::take(&mut field.order);
        field.build_node(&mut order, 0);
        field.order = order;
        let ranges = (0..field.cells.len() as u32).map(|c| {
            let count = field.cells[c as usize].shape.vertex_count();
            let values = &field.cell_values(c)[..count];
            let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (field.boxes[c as usize], (lo as f32, hi as f32))
        });
        field.macrocells = MacrocellGrid::over_cells(field.bounds, ranges, field.cells.len());
        field
    }

    /// Value ranges of blocks of space (empty where no cell is).
    pub fn macrocells(&self) -> &MacrocellGrid {
        &self.macrocells
    }

    /// Builds the subtree over `cells` (a slice of the order starting at `offset`).
    fn build_node(&mut self, cells: &mut [u32], offset: usize) {
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        let (mut centre_lo, mut centre_hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for &c in cells.iter() {
            let (a, b) = self.boxes[c as usize];
            lo = lo.min(a);
            hi = hi.max(b);
            centre_lo = centre_lo.min((a + b) * 0.5);
            centre_hi = centre_hi.max((a + b) * 0.5);
        }
        let index = self.nodes.len();
        self.nodes.push(Node {
            lo,
            hi,
            start: offset as u32,
            count: cells.len() as u32,
        });
        if cells.len() <= LEAF_CELLS {
            return;
        }
        let axis = (centre_hi - centre_lo).max_position();
        let middle = cells.len() / 2;
        let centre = |c: &u32| {
            let (a, b) = self.boxes[*c as usize];
            a[axis] + b[axis]
        };
        cells.select_nth_unstable_by(middle, |a, b| centre(a).total_cmp(&centre(b)));
        let (left, right) = cells.split_at_mut(middle);
        self.build_node(left, offset);
        let right_index = self.nodes.len() as u32;
        self.build_node(right, offset + middle);
        self.nodes[index].start = right_index;
        self.nodes[index].count = 0;
    }

    /// Object-space box around all cells (not padded: volumes start marching on its faces).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.bounds
    }

    /// Distance between ray-marching samples: half the shortest box side of the smallest cell.
    pub fn step(&self) -> f32 {
        self.step
    }

    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }

    /// Whether the values are given per cell (constant inside each cell).
    pub fn is_cell_centred(&self) -> bool {
        matches!(self.values, Values::PerCell(_))
    }

    /// Shape and vertex positions of a cell.
    pub fn cell_geometry(&self, cell: u32) -> CellGeometry {
        let Cell { shape, first } = self.cells[cell as usize];
        let mut points = [DVec3::ZERO; MAX_CELL_VERTICES];
        for (k, point) in points.iter_mut().take(shape.vertex_count()).enumerate() {
            let vertex = self.indices[first as usize + k] as usize;
            *point = self.positions[vertex].as_dvec3();
        }
        CellGeometry { shape, points }
    }

    /// The values at a cell's vertices (a cell-centred value repeated).
    pub fn cell_values(&self, cell: u32) -> [f64; MAX_CELL_VERTICES] {
        let Cell { shape, first } = self.cells[cell as usize];
        let mut values = [0.0; MAX_CELL_VERTICES];
        for (k, value) in values.iter_mut().take(shape.vertex_count()).enumerate() {
            *value = match &self.values {
                Values::PerVertex(v) => v[self.indices[first as usize + k] as usize] as f64,
                Values::PerCell(v) => v[cell as usize] as f64,
            };
        }
        values
    }

    /// Padded object-space box of a cell.
    pub fn cell_bounds(&self, cell: u32) -> (Vec3, Vec3) {
        self.boxes[cell as usize]
    }

    /// The cell holding `point` and the point's parametric coordinates in it.
    pub fn locate(&self, point: Vec3) -> Option<(u32, DVec3)> {
        let inside = |(lo, hi): (Vec3, Vec3)| point.cmpge(lo).all() && point.cmple(hi).all();
        let mut stack = [0u32; 64];
        let mut depth = usize::from(!self.nodes.is_empty());
        while depth > 0 {
            depth -= 1;
            let node = self.nodes[stack[depth] as usize];
            if !inside((node.lo, node.hi)) {
                continue;
            }
            if node.count == 0 {
                let here = stack[depth];
                stack[depth] = here + 1;
                stack[depth + 1] = node.start;
                depth += 2;
                continue;
            }
            for &cell in &self.order[node.start as usize..(node.start + node.count) as usize] {
                if inside(self.boxes[cell as usize])
                    && let Some(xi) = self.cell_geometry(cell).locate(point.as_dvec3())
                {
                    return Some((cell, xi));
                }
            }
        }
        None
    }

    /// The field at `point`; NaN outside every cell.
    pub fn sample(&self, point: Vec3) -> f32 {
        let Some((cell, xi)) = self.locate(point) else {
            return f32::NAN;
        };
        match &self.values {
            Values::PerCell(v) => v[cell as usize],
            Values::PerVertex(_) => {
                let shape = self.cells[cell as usize].shape;
                let (weights, _) = shape.weights(xi);
                let values = self.cell_values(cell);
                weights
                    .iter()
                    .zip(values)
                    .take(shape.vertex_count())
                    .map(|(w, v)| w * v)
                    .sum::<f64>() as f32
            }
        }
    }
}

/// A FLOAT32 field for tests and tools: `shapes[c]` lists cell `c`'s vertices in `indices`.
pub fn from_cells(
    positions: Vec<Vec3>,
    indices: Vec<u32>,
    types: &[u8],
    values: Vec<f32>,
    cell_centred: bool,
) -> Option<UnstructuredField> {
    let mut cells = Vec::with_capacity(types.len());
    let mut first = 0u32;
    for &code in types {
        let shape = CellShape::from_vtk(code)?;
        cells.push(Cell { shape, first });
        first += shape.vertex_count() as u32;
    }
    let values = if cell_centred {
        Values::PerCell(values)
    } else {
        Values::PerVertex(values)
    };
    Some(UnstructuredField::new(positions, indices, cells, values))
}

fn array<'p>(params: &'p crate::device::params::ParamSet, name: &str) -> Option<&'p ArrayStore> {
    params.get_object(name).and_then(|o| o.array.as_ref())
}

fn scalars(store: &ArrayStore) -> Option<Vec<f32>> {
    store.with_bytes(|bytes| decode_scalars(store.element_type, bytes))
}

/// Builds the field from its committed parameters; reports and returns `None` when it cannot
/// be sampled. Unusable cells are left out and reported.
pub fn commit(device: &Device, object: &Object) -> Option<UnstructuredField> {
    let params = object.committed();
    let what = "anariCommitParameters: spatial field 'unstructured'";
    let fail = |text: String| {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!("{what} {text}; the field renders nothing"),
        );
        None
    };
    // A missing 'vertex.position' is already reported as a missing required parameter.
    let positions_store = array(&params, "vertex.position")?;
    let Some(positions) = positions_store.read_vec3() else {
        return fail("parameter 'vertex.position' does not hold ANARI_FLOAT32_VEC3".into());
    };
    let indices = match array(&params, "index") {
        Some(store) => match store.read_u32() {
            Some(indices) => indices,
            None => return fail("parameter 'index' does not hold ANARI_UINT32".into()),
        },
        None => (0..positions.len() as u32).collect(),
    };
    let firsts = match array(&params, "cell.index") {
        Some(store) => match store.read_u32() {
            Some(firsts) => Some(firsts),
            None => return fail("parameter 'cell.index' does not hold ANARI_UINT32".into()),
        },
        None => None,
    };
    let types = match array(&params, "cell.type") {
        Some(store) if store.element_type == ANARI_UINT8 => Some(store.with_bytes(<[u8]>::to_vec)),
        Some(_) => return fail("parameter 'cell.type' does not hold ANARI_UINT8".into()),
        None => None,
    };
    // Cell list: (first vertex position in `indices`, VTK code).
    let listed: Vec<(u32, Option<CellShape>)> = match (&firsts, &types) {
        (Some(firsts), Some(types)) => {
            if firsts.len() != types.len() {
                return fail(format!(
                    "has {} entries in 'cell.index' but {} in 'cell.type'; one each per cell",
                    firsts.len(),
                    types.len()
                ));
            }
            firsts
                .iter()
                .zip(types)
                .map(|(f, t)| (*f, CellShape::from_vtk(*t)))
                .collect()
        }
        (None, Some(types)) => {
            let mut first = 0u32;
            types
                .iter()
                .map(|t| {
                    let shape = CellShape::from_vtk(*t);
                    let here = first;
                    first = first.saturating_add(shape.map_or(0, |s| s.vertex_count() as u32));
                    (here, shape)
                })
                .collect()
        }
        (Some(firsts), None) => {
            // The shape follows from the number of vertices up to the next cell.
            let mut ends: Vec<u32> = firsts.iter().skip(1).copied().collect();
            ends.push(indices.len() as u32);
            firsts
                .iter()
                .zip(ends)
                .map(|(&f, end)| {
                    let shape = match end.checked_sub(f) {
                        Some(4) => Some(CellShape::Tetrahedron),
                        Some(8) => Some(CellShape::Hexahedron),
                        Some(6) => Some(CellShape::Wedge),
                        Some(5) => Some(CellShape::Pyramid),
                        _ => None,
                    };
                    (f, shape)
                })
                .collect()
        }
        (None, None) => {
            return fail("has neither 'cell.type' nor 'cell.index': its cells are unknown".into());
        }
    };
    let vertex_data = match array(&params, "vertex.data") {
        Some(store) => match scalars(store) {
            Some(values) if values.len() == positions.len() => Some(values),
            _ => {
                return fail(format!(
                    "parameter 'vertex.data' must hold one scalar of {} per vertex ({} \
                     vertices)",
                    DATA_ELEMENT_TYPES
                        .iter()
                        .map(|t| type_name(*t))
                        .collect::<Vec<_>>()
                        .join(", "),
                    positions.len()
                ));
            }
        },
        None => None,
    };
    let cell_data = match array(&params, "cell.data") {
        Some(store) => match scalars(store) {
            Some(values) if values.len() == listed.len() => Some(values),
            _ => {
                return fail(format!(
                    "parameter 'cell.data' must hold one scalar of {} per cell ({} cells)",
                    DATA_ELEMENT_TYPES
                        .iter()
                        .map(|t| type_name(*t))
                        .collect::<Vec<_>>()
                        .join(", "),
                    listed.len()
                ));
            }
        },
        None => None,
    };
    if vertex_data.is_some() && cell_data.is_some() {
        device.warning(
            Some(object),
            format!("{what} has both 'vertex.data' and 'cell.data'; 'vertex.data' is used"),
        );
    }
    let values = match (vertex_data, cell_data) {
        (Some(v), _) => Values::PerVertex(v),
        (None, Some(c)) => Values::PerCell(c),
        (None, None) => {
            return fail("has neither 'vertex.data' nor 'cell.data': it has no values".into());
        }
    };

    let mut cells = Vec::with_capacity(listed.len());
    let mut kept_values = Vec::new();
    let mut skipped = 0usize;
    for (number, (first, shape)) in listed.iter().enumerate() {
        let why = match shape {
            None => Some(format!(
                "has a cell type other than 10, 12, 13, 14{}",
                if types.is_none() {
                    " (read from cell.index: not 4, 5, 6 or 8 vertices)"
                } else {
                    ""
                }
            )),
            Some(shape) => {
                let range = *first as usize..*first as usize + shape.vertex_count();
                match indices.get(range) {
                    None => Some("runs past the end of 'index'".into()),
                    Some(vertices) => vertices
                        .iter()
                        .any(|&v| positions.get(v as usize).is_none_or(|p| !p.is_finite()))
                        .then(|| "has a vertex index out of range or a non-finite vertex".into()),
                }
            }
        };
        match (why, shape) {
            (None, Some(shape)) => {
                cells.push(Cell {
                    shape: *shape,
                    first: *first,
                });
                if let Values::PerCell(v) = &values {
                    kept_values.push(v[number]);
                }
            }
            (why, _) => {
                if skipped < 5 {
                    device.error(
                        ANARI_STATUS_INVALID_ARGUMENT,
                        Some(object),
                        format!(
                            "{what}: cell {number} {}; it is skipped",
                            why.unwrap_or_default()
                        ),
                    );
                }
                skipped += 1;
            }
        }
    }
    if skipped > 5 {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!("{what}: {skipped} cells in all were skipped"),
        );
    }
    if cells.is_empty() {
        return fail("has no usable cell".into());
    }
    let values = match values {
        Values::PerCell(_) => Values::PerCell(kept_values),
        per_vertex => per_vertex,
    };
    Some(UnstructuredField::new(positions, indices, cells, values))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::field::Field;
    use crate::scene::spatial_field::StructuredRegularField;
    use crate::scene::volume::{PlacedVolume, TransferFunction, integrate};
    use glam::{Affine3A, Vec4};
    use std::sync::Arc;

    /// Unit cube corners in VTK hexahedron order.
    pub(crate) fn unit_cube() -> Vec<Vec3> {
        vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ]
    }

    #[test]
    fn a_tetrahedron_interpolates_by_barycentric_weights() {
        let p = [
            Vec3::new(0.5, -1.0, 0.25),
            Vec3::new(3.0, 0.0, 0.5),
            Vec3::new(0.0, 2.5, -0.5),
            Vec3::new(1.0, 0.5, 3.0),
        ];
        let v = [2.0f32, -1.0, 5.0, 0.5];
        let field = from_cells(p.to_vec(), vec![0, 1, 2, 3], &[10], v.to_vec(), false).unwrap();
        for b in [
            [0.25f32, 0.25, 0.25, 0.25],
            [0.1, 0.2, 0.3, 0.4],
            [0.7, 0.1, 0.1, 0.1],
            [0.0, 0.5, 0.5, 0.0],
        ] {
            let point = p[0] * b[0] + p[1] * b[1] + p[2] * b[2] + p[3] * b[3];
            let expected = v[0] * b[0] + v[1] * b[1] + v[2] * b[2] + v[3] * b[3];
            let sample = field.sample(point);
            assert!(
                (sample - expected).abs() < 1e-5,
                "{b:?}: {sample} vs {expected}"
            );
        }
        // Outside (beyond the face opposite vertex 0): no value.
        let outside = p[1] * 0.4 + p[2] * 0.4 + p[3] * 0.4 - p[0] * 0.2;
        assert!(field.sample(outside).is_nan());
    }

    #[test]
    fn a_hexahedron_interpolates_trilinearly() {
        // A box [1, 3] × [0, 1] × [0, 0.5] with values v(x, y, z) at its corners.
        let positions: Vec<Vec3> = unit_cube()
            .iter()
            .map(|c| Vec3::new(1.0 + 2.0 * c.x, c.y, 0.5 * c.z))
            .collect();
        let values: Vec<f32> = (0..8)
            .map(|i| [1.0, 4.0, -2.0, 0.5, 3.0, 7.0, 2.0, -1.0][i])
            .collect();
        let field = from_cells(positions, (0..8).collect(), &[12], values.clone(), false).unwrap();
        let (r, s, t) = (0.3f32, 0.8, 0.6);
        let corner = |i: usize| values[i];
        let lerp = |a: f32, b: f32, f: f32| a + (b - a) * f;
        let expected = lerp(
            lerp(
                lerp(corner(0), corner(1), r),
                lerp(corner(3), corner(2), r),
                s,
            ),
            lerp(
                lerp(corner(4), corner(5), r),
                lerp(corner(7), corner(6), r),
                s,
            ),
            t,
        );
        let sample = field.sample(Vec3::new(1.0 + 2.0 * r, s, 0.5 * t));
        assert!((sample - expected).abs() < 1e-5, "{sample} vs {expected}");
    }

    #[test]
    fn wedges_pyramids_and_cell_data_are_located() {
        // A unit cube split into two wedges (prisms over the triangles of the bottom square)
        // and, beside it, a pyramid on the square x ∈ [1, 2].
        let mut positions = unit_cube();
        positions.push(Vec3::new(1.5, 0.5, 0.5));
        let indices = vec![0, 1, 3, 4, 5, 7, 1, 2, 3, 5, 6, 7, 1, 5, 6, 2, 8];
        let field = from_cells(
            positions.clone(),
            indices.clone(),
            &[13, 13, 14],
            vec![1.0, 2.0, 3.0],
            true,
        )
        .unwrap();
        assert_eq!(field.sample(Vec3::new(0.2, 0.2, 0.5)), 1.0);
        assert_eq!(field.sample(Vec3::new(0.8, 0.8, 0.5)), 2.0);
        // The pyramid: base on the face x = 1, apex at (1.5, 0.5, 0.5).
        assert_eq!(field.sample(Vec3::new(1.1, 0.5, 0.5)), 3.0);
        assert!(field.sample(Vec3::new(1.9, 0.1, 0.1)).is_nan());
        // Vertex data: linear x + y + z is reproduced exactly by wedges.
        let values: Vec<f32> = positions.iter().map(|p| p.x + p.y + p.z).collect();
        let linear = from_cells(positions, indices, &[13, 13, 14], values, false).unwrap();
        let point = Vec3::new(0.3, 0.6, 0.45);
        assert!((linear.sample(point) - 1.35).abs() < 1e-5);
    }

    /// An n³-vertex grid over [0, 1]³ of `f`, as a structured field and as hexahedra (or as
    /// six tetrahedra per hexahedron, split along the diagonal 0–6 the same way in every cell).
    fn grid_and_mesh(
        n: usize,
        f: impl Fn(Vec3) -> f32,
        tetrahedra: bool,
    ) -> (StructuredRegularField, UnstructuredField) {
        let h = 1.0 / (n - 1) as f32;
        let at = |i: usize, j: usize, k: usize| Vec3::new(i as f32, j as f32, k as f32) * h;
        let mut positions = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    positions.push(at(i, j, k));
                }
            }
        }
        let values: Vec<f32> = positions.iter().map(|p| f(*p)).collect();
        let vertex = |i: usize, j: usize, k: usize| (i + n * (j + n * k)) as u32;
        let mut indices = Vec::new();
        let mut types = Vec::new();
        for k in 0..n - 1 {
            for j in 0..n - 1 {
                for i in 0..n - 1 {
                    let hex = [
                        vertex(i, j, k),
                        vertex(i + 1, j, k),
                        vertex(i + 1, j + 1, k),
                        vertex(i, j + 1, k),
                        vertex(i, j, k + 1),
                        vertex(i + 1, j, k + 1),
                        vertex(i + 1, j + 1, k + 1),
                        vertex(i, j + 1, k + 1),
                    ];
                    if tetrahedra {
                        for [a, b] in [[1, 2], [2, 3], [3, 7], [7, 4], [4, 5], [5, 1]] {
                            indices.extend([hex[0], hex[a], hex[b], hex[6]]);
                            types.push(10);
                        }
                    } else {
                        indices.extend(hex);
                        types.push(12);
                    }
                }
            }
        }
        let grid = StructuredRegularField::from_floats(
            [n; 3],
            values.clone(),
            Vec3::ZERO,
            Vec3::splat(h),
            false,
        )
        .unwrap();
        let mesh = from_cells(positions, indices, &types, values, false).unwrap();
        (grid, mesh)
    }

    fn transfer() -> Arc<TransferFunction> {
        let colors = vec![Vec4::new(1.0, 0.0, 0.0, 1.0), Vec4::new(0.0, 0.5, 1.0, 1.0)];
        Arc::new(TransferFunction::new(0, (0.0, 1.0), colors, vec![0.0, 0.9, 0.3], 0.2).unwrap())
    }

    /// Transmittance and colour of a volume over `field` along a few oblique rays.
    fn march(field: impl Into<Field>) -> Vec<(f32, Vec3)> {
        let volume = PlacedVolume::new(transfer(), field, Affine3A::IDENTITY, 0);
        [
            (Vec3::new(0.3, 0.4, 3.0), Vec3::new(0.05, 0.1, -1.0)),
            (Vec3::new(-2.0, 0.55, 0.45), Vec3::new(1.0, -0.02, 0.03)),
            (Vec3::new(0.9, -1.0, 0.2), Vec3::new(-0.2, 1.0, 0.3)),
        ]
        .iter()
        .map(|(o, d)| {
            let result =
                integrate(std::slice::from_ref(&volume), *o, d.normalize(), 0.0, 100.0).unwrap();
            (result.transmittance, result.color)
        })
        .collect()
    }

    fn assert_same(a: &[(f32, Vec3)], b: &[(f32, Vec3)]) {
        for (x, y) in a.iter().zip(b) {
            assert!(
                (x.0 - y.0).abs() < 1e-5 && (x.1 - y.1).abs().max_element() < 1e-5,
                "{a:?} vs {b:?}"
            );
        }
        // The rays do cross something that absorbs.
        assert!(a.iter().all(|x| x.0 < 0.9), "{a:?}");
    }

    #[test]
    fn a_volume_over_hexahedra_transmits_what_the_same_grid_does() {
        let wavy = |p: Vec3| 0.5 + 0.4 * (3.0 * p.x).sin() * (2.0 * p.y + p.z).cos();
        let (grid, mesh) = grid_and_mesh(5, wavy, false);
        assert_eq!(grid.step(), mesh.step());
        assert_same(&march(Arc::new(grid)), &march(Arc::new(mesh)));
    }

    #[test]
    fn a_volume_over_tetrahedra_transmits_what_the_same_linear_grid_does() {
        let linear = |p: Vec3| 0.3 * p.x + 0.5 * p.y + 0.2 * p.z;
        let (grid, mesh) = grid_and_mesh(4, linear, true);
        assert_same(&march(Arc::new(grid)), &march(Arc::new(mesh)));
    }

    #[test]
    fn a_constant_unstructured_slab_transmits_the_closed_form() {
        // A 1 × 1 × 0.5 slab of value 0.5 (opacity 0.9 per 0.2 units): crossed straight it
        // passes 0.1^(0.5 / 0.2) of the light.
        let (_, mesh) = grid_and_mesh(3, |_| 0.5, true);
        let thin = UnstructuredField::new(
            mesh.positions
                .iter()
                .map(|p| Vec3::new(p.x, p.y, 0.5 * p.z))
                .collect(),
            mesh.indices.clone(),
            mesh.cells.clone(),
            Values::PerVertex(vec![0.5; mesh.positions.len()]),
        );
        let volume = PlacedVolume::new(transfer(), Arc::new(thin), Affine3A::IDENTITY, 0);
        let result = integrate(
            &[volume],
            Vec3::new(0.37, 0.61, 2.0),
            Vec3::NEG_Z,
            0.0,
            10.0,
        )
        .unwrap();
        let expected = 0.1f32.powf(0.5 / 0.2);
        assert!(
            (result.transmittance - expected).abs() < 1e-5,
            "{} vs {expected}",
            result.transmittance
        );
    }
}
