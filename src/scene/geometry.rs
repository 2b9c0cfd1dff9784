//! Geometry objects: triangle, quad, sphere, cylinder, cone and curve. A commit validates the
//! arrays, skips (and reports) bad primitives, and builds the geometry's BVH once; everything
//! that references the geometry reuses it until the geometry itself is committed again.

use std::sync::Arc;

use glam::{UVec2, UVec3, UVec4, Vec2, Vec3, Vec4};

use crate::accel::{GeometryBvh, GeometryPrims, TubeKind, TubeSegment};
use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::params::ParamSet;
use crate::device::pool::with_build_pool;
use crate::device::spec::{ATTRIBUTE_ELEMENT_TYPES, ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::attributes::{
    ATTRIBUTE_NAMES, Attribute, Interpolation, read_values, triangle_weights,
};

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
pub(crate) const PRIMITIVE_ATTRIBUTES: &[ParamSpec] = &attribute_params!("primitive");

const POSITION: ParamSpec = ParamSpec::new("vertex.position", ARRAY, "vertex positions")
    .required()
    .elements(VEC3_ELEMENTS);
const VERTEX_NORMAL: ParamSpec =
    ParamSpec::new("vertex.normal", ARRAY, "vertex normals for smooth shading")
        .elements(VEC3_ELEMENTS);
const CORNER_NORMAL: ParamSpec =
    ParamSpec::new("faceVarying.normal", ARRAY, "per-corner normals").elements(VEC3_ELEMENTS);
// Tangents orient the normal maps of physicallyBased materials; xyz along the map's first
// axis, w the handedness of the second (glTF).
const TANGENT_ELEMENTS: &[ANARIDataType] = &[ANARI_FLOAT32_VEC3, ANARI_FLOAT32_VEC4];
const VERTEX_TANGENT: ParamSpec = ParamSpec::new(
    "vertex.tangent",
    ARRAY,
    "vertex tangents for normal maps (xyz; w: handedness, default +1)",
)
.elements(TANGENT_ELEMENTS);
const CORNER_TANGENT: ParamSpec = ParamSpec::new(
    "faceVarying.tangent",
    ARRAY,
    "per-corner tangents for normal maps",
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

const CAP_VALUES: &[&str] = &["none", "first", "second", "both"];
const VERTEX_CAP: ParamSpec = ParamSpec::new(
    "vertex.cap",
    ARRAY,
    "per-vertex end caps (0: open, 1: flat cap); overrides 'caps'",
)
.elements(&[ANARI_UINT8]);
const CAPS: ParamSpec = ParamSpec::new(
    "caps",
    &[ANARI_STRING],
    "which end of every primitive gets a flat cap when 'vertex.cap' is not set",
)
.default(SpecValue::Str("none"))
.values(CAP_VALUES);
const PAIR_INDEX_ELEMENTS: &[ANARIDataType] = &[ANARI_UINT32_VEC2, ANARI_UINT64_VEC2];

const CYLINDER_PARAMS: &[ParamSpec] = &[
    ParamSpec::new("vertex.position", ARRAY, "cylinder end points")
        .required()
        .elements(VEC3_ELEMENTS),
    VERTEX_CAP,
    ParamSpec::new(
        "primitive.index",
        ARRAY,
        "end point indices of each cylinder; absent: consecutive pairs",
    )
    .elements(PAIR_INDEX_ELEMENTS),
    ParamSpec::new("primitive.radius", ARRAY, "per-cylinder radii").elements(&[ANARI_FLOAT32]),
    ParamSpec::new(
        "radius",
        &[ANARI_FLOAT32],
        "radius of cylinders without primitive.radius",
    )
    .default(SpecValue::Float(1.0)),
    CAPS,
];

const CONE_PARAMS: &[ParamSpec] = &[
    ParamSpec::new("vertex.position", ARRAY, "cone end points")
        .required()
        .elements(VEC3_ELEMENTS),
    ParamSpec::new(
        "vertex.radius",
        ARRAY,
        "radius at each end point (absent: 1 everywhere)",
    )
    .elements(&[ANARI_FLOAT32]),
    VERTEX_CAP,
    ParamSpec::new(
        "primitive.index",
        ARRAY,
        "end point indices of each cone; absent: consecutive pairs",
    )
    .elements(PAIR_INDEX_ELEMENTS),
    CAPS,
];

const CURVE_PARAMS: &[ParamSpec] = &[
    ParamSpec::new("vertex.position", ARRAY, "curve vertices")
        .required()
        .elements(VEC3_ELEMENTS),
    ParamSpec::new("vertex.radius", ARRAY, "radius at each vertex").elements(&[ANARI_FLOAT32]),
    ParamSpec::new(
        "primitive.index",
        ARRAY,
        "first vertex of each segment (which ends at the next vertex); absent: one curve through all vertices",
    )
    .elements(&[ANARI_UINT32, ANARI_UINT64]),
    ParamSpec::new(
        "radius",
        &[ANARI_FLOAT32],
        "radius of every vertex without vertex.radius",
    )
    .default(SpecValue::Float(1.0)),
];

/// Declares each KHR geometry subtype's spec, one row each: its parameters, the attributes it
/// shares with its family, the one extension it implements, and its description.
macro_rules! khr_geometries {
    ($(
        $name:ident: $subtype:literal, $params:ident, $attributes:ident, $extension:literal,
        $description:literal;
    )*) => {
        $(
            pub const $name: ObjectSpec =
                ObjectSpec::new(ANARI_GEOMETRY, $subtype, $description, $params)
                    .shared($attributes)
                    .extensions(&[$extension]);
        )*
    };
}

khr_geometries! {
    TRIANGLE: "triangle", TRIANGLE_PARAMS, MESH_ATTRIBUTES, "ANARI_KHR_GEOMETRY_TRIANGLE", "triangle mesh, indexed or as consecutive triples";
    QUAD: "quad", QUAD_PARAMS, MESH_ATTRIBUTES, "ANARI_KHR_GEOMETRY_QUAD", "quad mesh (each quad split into two triangles)";
    SPHERE: "sphere", SPHERE_PARAMS, POINT_ATTRIBUTES, "ANARI_KHR_GEOMETRY_SPHERE", "spheres with a global or per-sphere radius";
    CYLINDER: "cylinder", CYLINDER_PARAMS, POINT_ATTRIBUTES, "ANARI_KHR_GEOMETRY_CYLINDER", "cylinders between pairs of points, each end open or flat-capped";
    CONE: "cone", CONE_PARAMS, POINT_ATTRIBUTES, "ANARI_KHR_GEOMETRY_CONE", "truncated cones between pairs of points with a radius per point, each end open or flat-capped";
    CURVE: "curve", CURVE_PARAMS, POINT_ATTRIBUTES, "ANARI_KHR_GEOMETRY_CURVE", "round curves of linear segments with a radius per vertex and rounded joints";
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    Triangle,
    Quad,
    Sphere,
    Cylinder,
    Cone,
    Curve,
    Isosurface,
}

/// A committed geometry: its BVH plus what shading needs to evaluate attributes and normals.
#[derive(Debug)]
pub struct Geometry {
    pub shape: Shape,
    pub bvh: Arc<GeometryBvh>,
    /// BVH primitive number → ANARI primitive index (None: identical, nothing was skipped).
    pub primitive_ids: Option<Vec<u32>>,
    /// Vertex indices per BVH primitive (triangle 3, quad 4, sphere 1, cylinder, cone and curve
    /// segment 2 used).
    pub vertex_indices: Vec<UVec4>,
    pub vertex_normals: Option<Vec<Vec3>>,
    pub corner_normals: Option<Vec<Vec3>>,
    /// Tangents (w: handedness) for normal maps.
    pub vertex_tangents: Option<Vec<Vec4>>,
    pub corner_tangents: Option<Vec<Vec4>>,
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
            Shape::Sphere | Shape::Isosurface => Interpolation::single(v.x),
            Shape::Cylinder | Shape::Cone | Shape::Curve => {
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

    /// Whether [`Self::shading_normal`] can differ from the geometric normal.
    pub fn has_shading_normals(&self) -> bool {
        matches!(self.shape, Shape::Triangle | Shape::Quad)
            && (self.vertex_normals.is_some() || self.corner_normals.is_some())
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

    /// The tangent in object space at a hit (w: handedness), where the geometry gives tangents.
    pub fn tangent(&self, at: &Interpolation) -> Option<Vec4> {
        let blend = |values: &[Vec4], indices: &[u32; 4]| -> Option<Vec4> {
            let mut sum = Vec3::ZERO;
            let mut handedness = 1.0;
            for (index, weight) in indices.iter().zip(at.weights).take(at.count) {
                let value = *values.get(*index as usize)?;
                sum += value.truncate() * weight;
                handedness = value.w;
            }
            Some(sum.extend(handedness)).filter(|t| t.truncate().length_squared() > 1e-20)
        };
        self.corner_tangents
            .as_deref()
            .and_then(|c| blend(c, &at.corners))
            .or_else(|| {
                self.vertex_tangents
                    .as_deref()
                    .and_then(|v| blend(v, &at.vertices))
            })
    }

    pub fn memory_bytes(&self) -> usize {
        self.bvh.memory_bytes()
            + self.primitive_ids.as_ref().map_or(0, |p| p.len() * 4)
            + self.vertex_indices.len() * 16
            + self.vertex_normals.as_ref().map_or(0, |n| n.len() * 12)
            + self.corner_normals.as_ref().map_or(0, |n| n.len() * 12)
            + self.vertex_tangents.as_ref().map_or(0, |t| t.len() * 16)
            + self.corner_tangents.as_ref().map_or(0, |t| t.len() * 16)
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

    fn warn(&self, text: String) {
        self.device.warning(
            Some(self.object),
            format!("anariCommitParameters: {} {text}", self.object.describe()),
        );
    }
}

/// Where cones and cylinders take their per-end flat caps from.
enum Caps {
    /// `vertex.cap`: a non-zero byte caps the primitives' ends at that vertex.
    PerVertex(Vec<u8>),
    /// `caps`: the same ends of every primitive.
    Uniform { first: bool, second: bool },
}

impl Caps {
    fn read(params: &ParamSet, problems: &Problems) -> Caps {
        if let Some(caps) = array(params, "vertex.cap") {
            if caps.element_type == ANARI_UINT8 {
                return Caps::PerVertex(caps.with_bytes(<[u8]>::to_vec));
            }
            problems.report(
                "has a 'vertex.cap' array that is not of ANARI_UINT8; 'caps' is used instead"
                    .into(),
            );
        }
        let (first, second) = match params.get_string("caps").unwrap_or("none") {
            "none" => (false, false),
            "first" => (true, false),
            "second" => (false, true),
            "both" => (true, true),
            other => {
                problems.report(format!(
                    "parameter 'caps' is '{other}'; expected one of {}; 'none' is used",
                    CAP_VALUES.join(", ")
                ));
                (false, false)
            }
        };
        Caps::Uniform { first, second }
    }

    /// Caps at the first and second end point; `None` when `vertex.cap` is too short.
    fn of(&self, ends: UVec2) -> Option<(bool, bool)> {
        match self {
            Caps::PerVertex(caps) => Some((
                *caps.get(ends.x as usize)? != 0,
                *caps.get(ends.y as usize)? != 0,
            )),
            Caps::Uniform { first, second } => Some((*first, *second)),
        }
    }
}

/// What a geometry's BVH is built from.
enum Primitives {
    Standard(GeometryPrims),
    Tubes(Vec<TubeSegment>),
}

/// Radii at the two ends of a tube are usable: finite, not negative, not both zero.
fn usable_radii(r0: f32, r1: f32) -> bool {
    r0.is_finite() && r1.is_finite() && r0 >= 0.0 && r1 >= 0.0 && (r0 > 0.0 || r1 > 0.0)
}

/// Why a tube was skipped for its radii, naming the parameter they came from.
fn bad_radius(from_array: bool, array_name: &str) -> String {
    if from_array {
        format!(
            "has a radius missing from '{array_name}' (index beyond its end), negative or not finite, or no radius above 0"
        )
    } else {
        "has a 'radius' that is negative, zero or not finite".into()
    }
}

fn array<'p>(params: &'p ParamSet, name: &str) -> Option<&'p crate::device::array::ArrayStore> {
    params.get_object(name).and_then(|o| o.array.as_ref())
}

fn finite(v: Vec3) -> bool {
    v.is_finite()
}

/// Reads the attribute arrays and uniform values of a geometry.
pub(crate) fn read_attributes(params: &ParamSet, has_corners: bool) -> [Attribute; 5] {
    std::array::from_fn(|slot| {
        let name = ATTRIBUTE_NAMES[slot];
        let read = |prefix: &str| -> Option<Vec<Vec4>> {
            array(params, &format!("{prefix}.{name}")).and_then(read_values)
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

/// The geometry the next frame renders: the committed build, or for an isosurface whose field
/// was committed since its build, the rebuild (made here, once per field commit).
pub fn current(device: &Device, object: &Object) -> Option<Arc<Geometry>> {
    if object.subtype == crate::scene::isosurface::ISOSURFACE.subtype {
        return crate::scene::isosurface::current(device, object);
    }
    object.derived_as::<Geometry>()
}

/// Validates a geometry and builds its BVH. Returns None when there is nothing to render.
/// (Isosurfaces are built by `scene::isosurface`.)
pub fn commit(device: &Device, object: &Object) -> Option<Geometry> {
    let params = object.committed();
    let problems = Problems { device, object };
    let shape = match object.subtype.as_str() {
        "triangle" => Shape::Triangle,
        "quad" => Shape::Quad,
        "sphere" => Shape::Sphere,
        "cylinder" => Shape::Cylinder,
        "cone" => Shape::Cone,
        "curve" => Shape::Curve,
        _ => return None,
    };
    if let Err(refusal) = crate::scene::limits::check_geometry(&params) {
        device.error(
            refusal.code,
            Some(object),
            format!(
                "anariCommitParameters: {} {}; nothing is rendered",
                object.describe(),
                refusal.reason
            ),
        );
        return None;
    }
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
    let mut triangles_kept_whole = false;
    let prims = match shape {
        Shape::Isosurface => return None,
        Shape::Triangle => {
            let triangles: Vec<UVec3> = match array(&params, "primitive.index") {
                Some(a) => a.read_indices(3, UVec3::from_slice).unwrap_or_default(),
                None => (0..vertex_count as u32 / 3)
                    .map(|i| UVec3::new(3 * i, 3 * i + 1, 3 * i + 2))
                    .collect(),
            };
            let valid = |t: &UVec3| valid_vertex(t.x) && valid_vertex(t.y) && valid_vertex(t.z);
            let kept = if triangles.iter().all(valid) {
                // The usual case, checked first so that big meshes are not copied: ids stay
                // the identity (left empty) and vertex indices are made only if needed.
                triangles_kept_whole = true;
                triangles
            } else {
                let mut kept = Vec::with_capacity(triangles.len());
                for (i, t) in triangles.iter().enumerate() {
                    if !valid(t) {
                        note_skip(i, "has an index out of range or a non-finite vertex");
                        continue;
                    }
                    kept.push(*t);
                    primitive_ids.push(i as u32);
                    vertex_indices.push(t.extend(0));
                }
                kept
            };
            Primitives::Standard(GeometryPrims::Triangles {
                positions,
                indices: kept,
            })
        }
        Shape::Quad => {
            let quads: Vec<UVec4> = match array(&params, "primitive.index") {
                Some(a) => a.read_indices(4, UVec4::from_slice).unwrap_or_default(),
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
            Primitives::Standard(GeometryPrims::Quads {
                positions,
                indices: kept,
            })
        }
        Shape::Sphere => {
            let radii = array(&params, "vertex.radius").and_then(|a| a.read_f32());
            let radius = params.get_f32("radius").unwrap_or(1.0);
            let spheres: Vec<u32> = match array(&params, "primitive.index") {
                Some(a) => a.read_indices(1, |value| value[0]).unwrap_or_default(),
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
            Primitives::Standard(GeometryPrims::Spheres {
                centers,
                radii: kept_radii,
            })
        }
        Shape::Cylinder | Shape::Cone => {
            let pairs: Vec<UVec2> = match array(&params, "primitive.index") {
                Some(a) => a.read_indices(2, UVec2::from_slice).unwrap_or_default(),
                None => (0..vertex_count as u32 / 2)
                    .map(|i| UVec2::new(2 * i, 2 * i + 1))
                    .collect(),
            };
            let caps = Caps::read(&params, &problems);
            // Cylinders: one radius per primitive; cones: one per vertex.
            let radii_name = if shape == Shape::Cone {
                "vertex.radius"
            } else {
                "primitive.radius"
            };
            let radii = array(&params, radii_name).and_then(|a| a.read_f32());
            let radius = if shape == Shape::Cone {
                if radii.is_none() {
                    problems.warn("has no 'vertex.radius'; every cone gets radius 1".into());
                }
                1.0
            } else {
                params.get_f32("radius").unwrap_or(1.0)
            };
            let radius_of = |index: usize| -> f32 {
                radii
                    .as_ref()
                    .map_or(Some(radius), |r| r.get(index).copied())
                    .unwrap_or(f32::NAN)
            };
            let mut segments = Vec::with_capacity(pairs.len());
            for (i, p) in pairs.iter().enumerate() {
                let (r0, r1) = if shape == Shape::Cone {
                    (radius_of(p.x as usize), radius_of(p.y as usize))
                } else {
                    (radius_of(i), radius_of(i))
                };
                if !valid_vertex(p.x) || !valid_vertex(p.y) {
                    note_skip(i, "has an index out of range or a non-finite end point");
                    continue;
                }
                if positions[p.x as usize] == positions[p.y as usize] {
                    note_skip(i, "has two equal end points");
                    continue;
                }
                if !usable_radii(r0, r1) {
                    note_skip(i, &bad_radius(radii.is_some(), radii_name));
                    continue;
                }
                let Some((start_cap, end_cap)) = caps.of(*p) else {
                    note_skip(i, "has an end point beyond the end of 'vertex.cap'");
                    continue;
                };
                segments.push(TubeSegment {
                    start: positions[p.x as usize],
                    end: positions[p.y as usize],
                    start_radius: r0,
                    end_radius: r1,
                    kind: TubeKind::Cone { start_cap, end_cap },
                });
                primitive_ids.push(i as u32);
                vertex_indices.push(UVec4::new(p.x, p.y, 0, 0));
            }
            Primitives::Tubes(segments)
        }
        Shape::Curve => {
            let starts: Vec<u32> = match array(&params, "primitive.index") {
                Some(a) => a.read_indices(1, |value| value[0]).unwrap_or_default(),
                None => (0..vertex_count.saturating_sub(1) as u32).collect(),
            };
            if vertex_count < 2 {
                problems.report(format!(
                    "has {vertex_count} vertex in 'vertex.position'; a curve needs at least 2"
                ));
            }
            let radii = array(&params, "vertex.radius").and_then(|a| a.read_f32());
            let radius = params.get_f32("radius").unwrap_or(1.0);
            let radius_of = |index: u32| -> f32 {
                radii
                    .as_ref()
                    .map_or(Some(radius), |r| r.get(index as usize).copied())
                    .unwrap_or(f32::NAN)
            };
            let mut segments = Vec::with_capacity(starts.len());
            for (i, first) in starts.iter().enumerate() {
                let Some(second) = first.checked_add(1) else {
                    note_skip(i, "starts at an index out of range");
                    continue;
                };
                if !valid_vertex(*first) || !valid_vertex(second) {
                    note_skip(
                        i,
                        "starts at an index out of range (a segment ends at the next vertex) or has a non-finite vertex",
                    );
                    continue;
                }
                let (r0, r1) = (radius_of(*first), radius_of(second));
                if !usable_radii(r0, r1) {
                    note_skip(i, &bad_radius(radii.is_some(), "vertex.radius"));
                    continue;
                }
                segments.push(TubeSegment {
                    start: positions[*first as usize],
                    end: positions[second as usize],
                    start_radius: r0,
                    end_radius: r1,
                    kind: TubeKind::Round,
                });
                primitive_ids.push(i as u32);
                vertex_indices.push(UVec4::new(*first, second, 0, 0));
            }
            Primitives::Tubes(segments)
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
    let tangents = |name: &str| {
        mesh.then(|| array(&params, name).and_then(|a| a.read_attribute()))
            .flatten()
    };
    let vertex_tangents = tangents("vertex.tangent");
    let corner_tangents = tangents("faceVarying.tangent");
    let attributes = read_attributes(&params, mesh);
    let needs_vertices = vertex_normals.is_some()
        || corner_normals.is_some()
        || vertex_tangents.is_some()
        || corner_tangents.is_some()
        || attributes
            .iter()
            .any(|a| a.per_vertex.is_some() || a.per_corner.is_some());
    if needs_vertices
        && triangles_kept_whole
        && let Primitives::Standard(GeometryPrims::Triangles { indices, .. }) = &prims
    {
        vertex_indices = indices.iter().map(|t| t.extend(0)).collect();
    }
    Some(Geometry {
        shape,
        bvh: Arc::new(with_build_pool(
            device.requested_thread_count(),
            || match prims {
                Primitives::Standard(prims) => GeometryBvh::build(prims),
                Primitives::Tubes(segments) => GeometryBvh::build_tubes(&segments),
            },
        )),
        primitive_ids: (!identity).then_some(primitive_ids),
        // Only kept when something is interpolated, to keep big meshes small.
        vertex_indices: if needs_vertices {
            vertex_indices
        } else {
            Vec::new()
        },
        vertex_normals,
        corner_normals,
        vertex_tangents,
        corner_tangents,
        attributes,
    })
}
