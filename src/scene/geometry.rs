//! Geometry objects: triangle, quad, sphere and cylinder. A commit validates the arrays, skips
//! (and reports) bad primitives, and builds the geometry's BVH once; everything that references
//! the geometry reuses it until the geometry itself is committed again.

use std::sync::Arc;

use glam::{UVec2, UVec3, UVec4, Vec2, Vec3, Vec4};

use crate::accel::{GeometryBvh, GeometryPrims};
use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::params::ParamSet;
use crate::device::pool::with_build_pool;
use crate::device::spec::{ATTRIBUTE_ELEMENT_TYPES, ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::attributes::{ATTRIBUTE_NAMES, Attribute, Interpolation, triangle_weights};

const FLOAT_ELEMENTS: &[ANARIDataType] = &[
    ANARI_FLOAT32,
    ANARI_FLOAT32_VEC2,
    ANARI_FLOAT32_VEC3,
    ANARI_FLOAT32_VEC4,
];
const VEC3_ELEMENTS: &[ANARIDataType] = &[ANARI_FLOAT32_VEC3];
const ARRAY: &[ANARIDataType] = &[ANARI_ARRAY1D];
const VEC4: &[ANARIDataType] = &[ANARI_FLOAT32_VEC4];

macro_rules! attribute_params {
    ($($prefix:literal),*) => {
        [
            ParamSpec::new("color", VEC4, "uniform color"),
            ParamSpec::new("attribute0", VEC4, "uniform attribute0"),
            ParamSpec::new("attribute1", VEC4, "uniform attribute1"),
            ParamSpec::new("attribute2", VEC4, "uniform attribute2"),
            ParamSpec::new("attribute3", VEC4, "uniform attribute3"),
            $(
                ParamSpec::new(concat!($prefix, ".color"), ARRAY, concat!($prefix, " colors")).elements(ATTRIBUTE_ELEMENT_TYPES),
                ParamSpec::new(concat!($prefix, ".attribute0"), ARRAY, concat!($prefix, " attribute0")).elements(FLOAT_ELEMENTS),
                ParamSpec::new(concat!($prefix, ".attribute1"), ARRAY, concat!($prefix, " attribute1")).elements(FLOAT_ELEMENTS),
                ParamSpec::new(concat!($prefix, ".attribute2"), ARRAY, concat!($prefix, " attribute2")).elements(FLOAT_ELEMENTS),
                ParamSpec::new(concat!($prefix, ".attribute3"), ARRAY, concat!($prefix, " attribute3")).elements(FLOAT_ELEMENTS),
            )*
        ]
    };
}

const MESH_ATTRIBUTES: &[ParamSpec] = &attribute_params!("vertex", "faceVarying", "primitive");
const POINT_ATTRIBUTES: &[ParamSpec] = &attribute_params!("vertex", "primitive");

const POSITION: ParamSpec = ParamSpec::new("vertex.position", ARRAY, "vertex positions")
    .required()
    .elements(VEC3_ELEMENTS);
const VERTEX_NORMAL: ParamSpec =
    ParamSpec::new("vertex.normal", ARRAY, "vertex normals for smooth shading")
        .elements(VEC3_ELEMENTS);
const CORNER_NORMAL: ParamSpec =
    ParamSpec::new("faceVarying.normal", ARRAY, "per-corner normals").elements(VEC3_ELEMENTS);
// Tangents are accepted for API completeness; they matter only with normal maps, which no
// material of this device samples.
const TANGENT_ELEMENTS: &[ANARIDataType] = &[ANARI_FLOAT32_VEC3, ANARI_FLOAT32_VEC4];
const VERTEX_TANGENT: ParamSpec = ParamSpec::new(
    "vertex.tangent",
    ARRAY,
    "vertex tangents (unused: no normal maps)",
)
.elements(TANGENT_ELEMENTS);
const CORNER_TANGENT: ParamSpec = ParamSpec::new(
    "faceVarying.tangent",
    ARRAY,
    "per-corner tangents (unused: no normal maps)",
)
.elements(TANGENT_ELEMENTS);

const TRIANGLE_PARAMS: &[ParamSpec] = &[
    POSITION,
    VERTEX_NORMAL,
    CORNER_NORMAL,
    VERTEX_TANGENT,
    CORNER_TANGENT,
    ParamSpec::new(
        "primitive.index",
        ARRAY,
        "vertex indices of each triangle; absent: consecutive triples",
    )
    .elements(&[ANARI_UINT32_VEC3, ANARI_UINT64_VEC3]),
];

const QUAD_PARAMS: &[ParamSpec] = &[
    POSITION,
    VERTEX_NORMAL,
    CORNER_NORMAL,
    VERTEX_TANGENT,
    CORNER_TANGENT,
    ParamSpec::new(
        "primitive.index",
        ARRAY,
        "vertex indices of each quad; absent: consecutive quadruples",
    )
    .elements(&[ANARI_UINT32_VEC4, ANARI_UINT64_VEC4]),
];

const SPHERE_PARAMS: &[ParamSpec] = &[
    ParamSpec::new("vertex.position", ARRAY, "sphere centers")
        .required()
        .elements(VEC3_ELEMENTS),
    ParamSpec::new("vertex.radius", ARRAY, "per-sphere radii").elements(&[ANARI_FLOAT32]),
    ParamSpec::new(
        "primitive.index",
        ARRAY,
        "vertex index of each sphere; absent: one sphere per vertex",
    )
    .elements(&[ANARI_UINT32, ANARI_UINT64]),
    ParamSpec::new(
        "radius",
        &[ANARI_FLOAT32],
        "radius of spheres without vertex.radius",
    )
    .default(SpecValue::Float(1.0)),
];

const CYLINDER_PARAMS: &[ParamSpec] = &[
    ParamSpec::new("vertex.position", ARRAY, "cylinder end points")
        .required()
        .elements(VEC3_ELEMENTS),
    ParamSpec::new(
        "primitive.index",
        ARRAY,
        "end point indices of each cylinder; absent: consecutive pairs",
    )
    .elements(&[ANARI_UINT32_VEC2, ANARI_UINT64_VEC2]),
    ParamSpec::new("primitive.radius", ARRAY, "per-cylinder radii").elements(&[ANARI_FLOAT32]),
    ParamSpec::new(
        "radius",
        &[ANARI_FLOAT32],
        "radius of cylinders without primitive.radius",
    )
    .default(SpecValue::Float(1.0)),
    ParamSpec::new("caps", &[ANARI_STRING], "which ends get flat caps")
        .default(SpecValue::Str("none"))
        .values(&["none", "both"]),
];

pub const TRIANGLE: ObjectSpec = ObjectSpec::new(
    ANARI_GEOMETRY,
    "triangle",
    "triangle mesh, indexed or as consecutive triples",
    TRIANGLE_PARAMS,
)
.shared(MESH_ATTRIBUTES)
.extensions(&["ANARI_KHR_GEOMETRY_TRIANGLE"]);
pub const QUAD: ObjectSpec = ObjectSpec::new(
    ANARI_GEOMETRY,
    "quad",
    "quad mesh (each quad split into two triangles)",
    QUAD_PARAMS,
)
.shared(MESH_ATTRIBUTES)
.extensions(&["ANARI_KHR_GEOMETRY_QUAD"]);
pub const SPHERE: ObjectSpec = ObjectSpec::new(
    ANARI_GEOMETRY,
    "sphere",
    "spheres with a global or per-sphere radius",
    SPHERE_PARAMS,
)
.shared(POINT_ATTRIBUTES)
.extensions(&["ANARI_KHR_GEOMETRY_SPHERE"]);
pub const CYLINDER: ObjectSpec = ObjectSpec::new(
    ANARI_GEOMETRY,
    "cylinder",
    "cylinders between pairs of points",
    CYLINDER_PARAMS,
)
.shared(POINT_ATTRIBUTES);
// KHR_GEOMETRY_CYLINDER is not advertised: per-end caps ("first", "second", vertex.cap) are
// not implemented.

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    Triangle,
    Quad,
    Sphere,
    Cylinder,
}

/// A committed geometry: its BVH plus what shading needs to evaluate attributes and normals.
#[derive(Debug)]
pub struct Geometry {
    pub shape: Shape,
    pub bvh: Arc<GeometryBvh>,
    /// BVH primitive number → ANARI primitive index (None: identical, nothing was skipped).
    pub primitive_ids: Option<Vec<u32>>,
    /// Vertex indices per BVH primitive (triangle 3, quad 4, sphere 1, cylinder 2 used).
    pub vertex_indices: Vec<UVec4>,
    pub vertex_normals: Option<Vec<Vec3>>,
    pub corner_normals: Option<Vec<Vec3>>,
    pub attributes: [Attribute; 5],
}

impl Geometry {
    /// The ANARI primitive index of a BVH primitive.
    pub fn primitive_id(&self, bvh_primitive: u32) -> u32 {
        match &self.primitive_ids {
            Some(ids) => ids[bvh_primitive as usize],
            None => bvh_primitive,
        }
    }

    /// Vertex weights for a hit (uv as reported by the BVH for this shape).
    pub fn interpolation(&self, bvh_primitive: u32, uv: Vec2) -> Interpolation {
        let v = self
            .vertex_indices
            .get(bvh_primitive as usize)
            .copied()
            .unwrap_or(UVec4::ZERO);
        let primitive = self.primitive_id(bvh_primitive);
        match self.shape {
            Shape::Triangle => {
                let w = triangle_weights(uv);
                let c = primitive * 3;
                Interpolation {
                    vertices: [v.x, v.y, v.z, 0],
                    corners: [c, c + 1, c + 2, 0],
                    weights: [w[0], w[1], w[2], 0.0],
                    count: 3,
                }
            }
            Shape::Quad => {
                // uv are the quad's bilinear coordinates: v0 at (0,0), v1 (1,0), v2 (1,1), v3 (0,1).
                let (s, t) = (uv.x, uv.y);
                let c = primitive * 4;
                Interpolation {
                    vertices: [v.x, v.y, v.z, v.w],
                    corners: [c, c + 1, c + 2, c + 3],
                    weights: [(1.0 - s) * (1.0 - t), s * (1.0 - t), s * t, (1.0 - s) * t],
                    count: 4,
                }
            }
            Shape::Sphere => Interpolation::single(v.x),
            Shape::Cylinder => {
                // uv.x runs from the first end point (0) to the second (1).
                let s = uv.x.clamp(0.0, 1.0);
                Interpolation {
                    vertices: [v.x, v.y, 0, 0],
                    corners: [v.x, v.y, 0, 0],
                    weights: [1.0 - s, s, 0.0, 0.0],
                    count: 2,
                }
            }
        }
    }

    /// The shading normal in object space at a hit, falling back to the geometric one.
    pub fn shading_normal(&self, at: &Interpolation, geometric: Vec3) -> Vec3 {
        let blend = |values: &[Vec3], indices: &[u32; 4]| -> Option<Vec3> {
            let mut sum = Vec3::ZERO;
            for (index, weight) in indices.iter().zip(at.weights).take(at.count) {
                sum += *values.get(*index as usize)? * weight;
            }
            Some(sum).filter(|n| n.length_squared() > 1e-20)
        };
        if matches!(self.shape, Shape::Triangle | Shape::Quad) {
            if let Some(n) = self
                .corner_normals
                .as_deref()
                .and_then(|c| blend(c, &at.corners))
            {
                return n.normalize();
            }
            if let Some(n) = self
                .vertex_normals
                .as_deref()
                .and_then(|v| blend(v, &at.vertices))
            {
                return n.normalize();
            }
        }
        geometric
    }

    pub fn memory_bytes(&self) -> usize {
        self.bvh.memory_bytes()
            + self.primitive_ids.as_ref().map_or(0, |p| p.len() * 4)
            + self.vertex_indices.len() * 16
            + self.vertex_normals.as_ref().map_or(0, |n| n.len() * 12)
            + self.corner_normals.as_ref().map_or(0, |n| n.len() * 12)
            + self
                .attributes
                .iter()
                .map(Attribute::memory_bytes)
                .sum::<usize>()
    }
}

/// Collects problems found while reading a geometry, reported once at the end of the commit.
struct Problems<'a> {
    device: &'a Device,
    object: &'a Object,
}

impl Problems<'_> {
    fn report(&self, text: String) {
        self.device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(self.object),
            format!("anariCommitParameters: {} {text}", self.object.describe()),
        );
    }
}

fn array<'p>(params: &'p ParamSet, name: &str) -> Option<&'p crate::scene::array::ArrayStore> {
    params.get_object(name).and_then(|o| o.array.as_ref())
}

/// Groups a flat index list into vectors of `n` (an unreadable array reads as empty).
fn grouped<T>(flat: Option<Vec<u32>>, n: usize, make: impl Fn(&[u32]) -> T) -> Vec<T> {
    flat.map(|f| f.chunks_exact(n).map(make).collect())
        .unwrap_or_default()
}

fn finite(v: Vec3) -> bool {
    v.is_finite()
}

/// Reads the attribute arrays and uniform values of a geometry.
fn read_attributes(params: &ParamSet, has_corners: bool) -> [Attribute; 5] {
    std::array::from_fn(|slot| {
        let name = ATTRIBUTE_NAMES[slot];
        let read = |prefix: &str| -> Option<Vec<Vec4>> {
            array(params, &format!("{prefix}.{name}")).and_then(|a| a.read_attribute())
        };
        Attribute {
            uniform: params.get_vec4(name),
            per_vertex: read("vertex"),
            per_corner: if has_corners {
                read("faceVarying")
            } else {
                None
            },
            per_primitive: read("primitive"),
        }
    })
}

/// Validates a geometry and builds its BVH. Returns None when there is nothing to render.
pub fn commit(device: &Device, object: &Object) -> Option<Geometry> {
    let params = object.committed();
    let problems = Problems { device, object };
    let shape = match object.subtype.as_str() {
        "triangle" => Shape::Triangle,
        "quad" => Shape::Quad,
        "sphere" => Shape::Sphere,
        "cylinder" => Shape::Cylinder,
        _ => return None,
    };
    let Some(positions) = array(&params, "vertex.position").and_then(|a| a.read_vec3()) else {
        problems.report(
            "has no 'vertex.position' array of ANARI_FLOAT32_VEC3; nothing is rendered".into(),
        );
        return None;
    };
    let vertex_count = positions.len();
    let mut skipped = 0usize;
    let mut note_skip = |index: usize, why: &str| {
        if skipped < 5 {
            problems.report(format!("primitive {index}: {why}; it is skipped"));
        }
        skipped += 1;
    };
    let valid_vertex = |i: u32| (i as usize) < vertex_count && finite(positions[i as usize]);

    let mut primitive_ids: Vec<u32> = Vec::new();
    let mut vertex_indices: Vec<UVec4> = Vec::new();
    let prims = match shape {
        Shape::Triangle => {
            let triangles: Vec<UVec3> = match array(&params, "primitive.index") {
                Some(a) => grouped(a.read_indices(3), 3, |c| UVec3::new(c[0], c[1], c[2])),
                None => (0..vertex_count as u32 / 3)
                    .map(|i| UVec3::new(3 * i, 3 * i + 1, 3 * i + 2))
                    .collect(),
            };
            let mut kept = Vec::with_capacity(triangles.len());
            for (i, t) in triangles.iter().enumerate() {
                if !(valid_vertex(t.x) && valid_vertex(t.y) && valid_vertex(t.z)) {
                    note_skip(i, "has an index out of range or a non-finite vertex");
                    continue;
                }
                kept.push(*t);
                primitive_ids.push(i as u32);
                vertex_indices.push(t.extend(0));
            }
            GeometryPrims::Triangles {
                positions: positions.clone(),
                indices: kept,
            }
        }
        Shape::Quad => {
            let quads: Vec<UVec4> = match array(&params, "primitive.index") {
                Some(a) => grouped(a.read_indices(4), 4, |c| UVec4::new(c[0], c[1], c[2], c[3])),
                None => (0..vertex_count as u32 / 4)
                    .map(|i| UVec4::new(4 * i, 4 * i + 1, 4 * i + 2, 4 * i + 3))
                    .collect(),
            };
            let mut kept = Vec::with_capacity(quads.len());
            for (i, q) in quads.iter().enumerate() {
                if !q.to_array().iter().all(|v| valid_vertex(*v)) {
                    note_skip(i, "has an index out of range or a non-finite vertex");
                    continue;
                }
                kept.push(*q);
                primitive_ids.push(i as u32);
                vertex_indices.push(*q);
            }
            GeometryPrims::Quads {
                positions: positions.clone(),
                indices: kept,
            }
        }
        Shape::Sphere => {
            let radii = array(&params, "vertex.radius").and_then(|a| a.read_f32());
            let radius = params.get_f32("radius").unwrap_or(1.0);
            let spheres: Vec<u32> = match array(&params, "primitive.index") {
                Some(a) => a.read_indices(1).unwrap_or_default(),
                None => (0..vertex_count as u32).collect(),
            };
            let mut centers = Vec::with_capacity(spheres.len());
            let mut kept_radii = Vec::with_capacity(spheres.len());
            for (i, v) in spheres.iter().enumerate() {
                let r = radii
                    .as_ref()
                    .map_or(Some(radius), |r| r.get(*v as usize).copied())
                    .unwrap_or(f32::NAN);
                if !valid_vertex(*v) || !r.is_finite() || r <= 0.0 {
                    note_skip(
                        i,
                        "has an index out of range, a non-finite center or a radius that is not positive",
                    );
                    continue;
                }
                centers.push(positions[*v as usize]);
                kept_radii.push(r);
                primitive_ids.push(i as u32);
                vertex_indices.push(UVec4::new(*v, 0, 0, 0));
            }
            GeometryPrims::Spheres {
                centers,
                radii: kept_radii,
            }
        }
        Shape::Cylinder => {
            let pairs: Vec<UVec2> = match array(&params, "primitive.index") {
                Some(a) => grouped(a.read_indices(2), 2, |c| UVec2::new(c[0], c[1])),
                None => (0..vertex_count as u32 / 2)
                    .map(|i| UVec2::new(2 * i, 2 * i + 1))
                    .collect(),
            };
            let radii = array(&params, "primitive.radius").and_then(|a| a.read_f32());
            let radius = params.get_f32("radius").unwrap_or(1.0);
            let caps = params.get_string("caps").unwrap_or("none") != "none";
            let (mut starts, mut ends, mut kept_radii) = (Vec::new(), Vec::new(), Vec::new());
            for (i, p) in pairs.iter().enumerate() {
                let r = radii
                    .as_ref()
                    .map_or(Some(radius), |r| r.get(i).copied())
                    .unwrap_or(f32::NAN);
                if !valid_vertex(p.x) || !valid_vertex(p.y) || !r.is_finite() || r <= 0.0 {
                    note_skip(
                        i,
                        "has an index out of range, a non-finite end point or a radius that is not positive",
                    );
                    continue;
                }
                starts.push(positions[p.x as usize]);
                ends.push(positions[p.y as usize]);
                kept_radii.push(r);
                primitive_ids.push(i as u32);
                vertex_indices.push(UVec4::new(p.x, p.y, 0, 0));
            }
            GeometryPrims::Cylinders {
                starts,
                ends,
                radii: kept_radii,
                caps,
            }
        }
    };
    if skipped > 5 {
        problems.report(format!("{skipped} primitives in all were skipped"));
    }
    let identity = primitive_ids
        .iter()
        .enumerate()
        .all(|(i, id)| i as u32 == *id);
    let mesh = matches!(shape, Shape::Triangle | Shape::Quad);
    let vertex_normals = if mesh {
        array(&params, "vertex.normal").and_then(|a| a.read_vec3())
    } else {
        None
    };
    let corner_normals = if mesh {
        array(&params, "faceVarying.normal").and_then(|a| a.read_vec3())
    } else {
        None
    };
    let attributes = read_attributes(&params, mesh);
    let needs_vertices = vertex_normals.is_some()
        || corner_normals.is_some()
        || attributes
            .iter()
            .any(|a| a.per_vertex.is_some() || a.per_corner.is_some());
    Some(Geometry {
        shape,
        bvh: Arc::new(with_build_pool(device.requested_thread_count(), || {
            GeometryBvh::build(prims)
        })),
        primitive_ids: (!identity).then_some(primitive_ids),
        // Only kept when something is interpolated, to keep big meshes small.
        vertex_indices: if needs_vertices {
            vertex_indices
        } else {
            Vec::new()
        },
        vertex_normals,
        corner_normals,
        attributes,
    })
}
