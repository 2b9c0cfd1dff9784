//! The world, and the immutable snapshot of it that a frame renders. The snapshot is taken when
//! a frame starts: it reuses every geometry's committed BVH and only builds the top level over
//! instances, so moving an instance or the camera never rebuilds a mesh BVH. Volumes are kept
//! in a flat list beside the BVH (each ray tests every volume's box: meant for a handful).

use std::sync::Arc;

use glam::{Affine3A, Mat3A, Mat4, Vec3, Vec4};

use crate::accel::{InstanceDesc, SceneBvh};
use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::params::ParamSet;
use crate::device::pool::with_build_pool;
use crate::device::spec::{ObjectSpec, ParamSpec};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::attributes::ATTRIBUTE_NAMES;
use crate::scene::field::Field;
use crate::scene::geometry::Geometry;
use crate::scene::light::Light;
use crate::scene::material::Material;
use crate::scene::volume::{PlacedVolume, TransferFunction};

pub const WORLD: ObjectSpec = ObjectSpec::new(
    ANARI_WORLD,
    "",
    "everything a frame renders",
    &[
        ParamSpec::new("instance", &[ANARI_ARRAY1D], "array of instances")
            .elements(&[ANARI_INSTANCE]),
        ParamSpec::new(
            "surface",
            &[ANARI_ARRAY1D],
            "array of surfaces placed as they are",
        )
        .elements(&[ANARI_SURFACE]),
        ParamSpec::new(
            "volume",
            &[ANARI_ARRAY1D],
            "array of volumes placed as they are",
        )
        .elements(&[ANARI_VOLUME]),
        ParamSpec::new(
            "light",
            &[ANARI_ARRAY1D],
            "array of lights placed as they are",
        )
        .elements(&[ANARI_LIGHT]),
    ],
);

/// One surface as rendered.
#[derive(Debug)]
pub struct SurfaceData {
    pub geometry: Arc<Geometry>,
    pub material: Arc<Material>,
    /// channel.objectId value.
    pub id: u32,
}

/// One placed group.
#[derive(Debug)]
pub struct InstanceData {
    pub transform: Affine3A,
    /// Inverse transpose of the linear part, for normals.
    pub normal_transform: Mat3A,
    pub surfaces: Vec<SurfaceData>,
    /// channel.instanceId value.
    pub id: u32,
    /// Uniform attributes for geometries that lack them.
    pub attributes: [Option<Vec4>; 5],
}

/// What a frame renders: immutable, shared by the render threads.
pub struct SceneSnapshot {
    pub bvh: SceneBvh,
    pub instances: Vec<InstanceData>,
    pub lights: Vec<Light>,
    pub volumes: Vec<PlacedVolume>,
    /// Whether any surface's material lets light through (see
    /// [`crate::scene::material::Material::lets_light_through`]).
    pub see_through: bool,
    /// Cluster hook: the ray exchange of a render across MPI ranks (render::cluster), if any.
    pub cluster: Option<std::sync::Arc<dyn std::any::Any + Send + Sync>>,
}

impl SceneSnapshot {
    pub fn empty() -> SceneSnapshot {
        SceneSnapshot {
            bvh: SceneBvh::build(Vec::new()),
            instances: Vec::new(),
            lights: Vec::new(),
            volumes: Vec::new(),
            see_through: false,
            cluster: None,
        }
    }

    /// Bounds of surfaces and volumes as [min.x, min.y, min.z, max.x, max.y, max.z].
    pub fn bounds(&self) -> [f32; 6] {
        let (mut lo, mut hi) = self.bvh.bounds();
        for volume in &self.volumes {
            let (a, b) = volume.world_bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]
    }
}

/// The objects of kind `kind` in the object array `name` (an array of generic `ANARI_OBJECT`
/// elements may hold others, reported when it was set; they are left out).
fn objects_of(params: &ParamSet, name: &str, kind: ANARIDataType) -> Vec<Arc<Object>> {
    let mut objects = params
        .get_object(name)
        .and_then(|o| o.array.as_ref().map(|a| a.objects()))
        .unwrap_or_default();
    objects.retain(|object| object.kind == kind);
    objects
}

fn surface_data(device: &Device, surface: &Object) -> Option<SurfaceData> {
    let params = surface.committed();
    if params.get_bool("visible") == Some(false) {
        return None;
    }
    let geometry_object = params.get_object("geometry")?;
    let geometry = crate::scene::geometry::current(device, geometry_object)?;
    let material = params
        .get_object("material")
        .and_then(|m| crate::scene::material::build(m))
        .unwrap_or_else(|| {
            device.warning(
                Some(surface),
                "anariRenderFrame: surface has no usable material; rendering it grey matte".into(),
            );
            Material::fallback()
        });
    Some(SurfaceData {
        geometry,
        material: Arc::new(material),
        id: params.get_u32("id").unwrap_or(u32::MAX),
    })
}

/// A visible, committed volume whose field can be sampled.
fn volume_data(volume: &Object) -> Option<VolumeParts> {
    if volume.spec.is_none() || volume.commit_count() == 0 {
        return None;
    }
    let params = volume.committed();
    if params.get_bool("visible") == Some(false) {
        return None;
    }
    let transfer = volume.derived_as::<TransferFunction>()?;
    let field = Field::of(params.get_object("value")?)?;
    Some((transfer, field))
}

type VolumeParts = (Arc<TransferFunction>, Field);

/// What a group (or the world itself) holds.
struct GroupContents {
    surfaces: Vec<SurfaceData>,
    lights: Vec<Light>,
    volumes: Vec<VolumeParts>,
}

fn group_contents(device: &Device, params: &ParamSet) -> GroupContents {
    let surfaces = objects_of(params, "surface", ANARI_SURFACE)
        .iter()
        .filter(|s| s.commit_count() > 0)
        .filter_map(|s| surface_data(device, s))
        .collect();
    let lights = objects_of(params, "light", ANARI_LIGHT)
        .iter()
        .filter(|l| l.commit_count() > 0)
        .filter_map(|l| Light::build(l))
        .collect();
    let volumes = objects_of(params, "volume", ANARI_VOLUME)
        .iter()
        .filter_map(|v| volume_data(v))
        .collect();
    GroupContents {
        surfaces,
        lights,
        volumes,
    }
}

fn place_volumes(
    placed: &mut Vec<PlacedVolume>,
    volumes: Vec<VolumeParts>,
    transform: Affine3A,
    instance_id: u32,
) {
    placed.extend(
        volumes
            .into_iter()
            .map(|(transfer, field)| PlacedVolume::new(transfer, field, transform, instance_id)),
    );
}

fn instance_data(transform: Affine3A, surfaces: Vec<SurfaceData>, id: u32) -> InstanceData {
    InstanceData {
        transform,
        normal_transform: transform.matrix3.inverse().transpose(),
        surfaces,
        id,
        attributes: [None; 5],
    }
}

/// Builds what a frame renders from the world's committed state.
pub fn snapshot(device: &Device, world: &Object) -> SceneSnapshot {
    let params = world.committed();
    let mut instances = Vec::new();
    let mut lights = Vec::new();
    let mut volumes = Vec::new();

    let world_contents = group_contents(device, &params);
    lights.extend(world_contents.lights);
    place_volumes(
        &mut volumes,
        world_contents.volumes,
        Affine3A::IDENTITY,
        u32::MAX,
    );
    if !world_contents.surfaces.is_empty() {
        instances.push(instance_data(
            Affine3A::IDENTITY,
            world_contents.surfaces,
            u32::MAX,
        ));
    }

    for instance in objects_of(&params, "instance", ANARI_INSTANCE) {
        if instance.spec.is_none() || instance.commit_count() == 0 {
            continue;
        }
        let ip = instance.committed();
        let Some(group) = ip.get_object("group") else {
            continue;
        };
        let matrix = ip.get_mat4("transform").unwrap_or(Mat4::IDENTITY);
        let transform = Affine3A::from_mat4(matrix);
        if !matrix.is_finite() || transform.matrix3.determinant() == 0.0 {
            device.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                Some(&instance),
                "anariRenderFrame: instance 'transform' is singular or not finite; the instance is skipped"
                    .into(),
            );
            continue;
        }
        let contents = group_contents(device, &group.committed());
        lights.extend(contents.lights.iter().map(|l| l.transformed(&transform)));
        let id = ip.get_u32("id").unwrap_or(u32::MAX);
        place_volumes(&mut volumes, contents.volumes, transform, id);
        let mut data = instance_data(transform, contents.surfaces, id);
        for (slot, name) in ATTRIBUTE_NAMES.iter().enumerate() {
            data.attributes[slot] = ip.get_vec4(name);
        }
        instances.push(data);
    }

    let descs = instances
        .iter()
        .map(|i| InstanceDesc {
            transform: i.transform,
            geometries: i
                .surfaces
                .iter()
                .map(|s| Arc::clone(&s.geometry.bvh))
                .collect(),
        })
        .collect();
    let see_through = instances
        .iter()
        .flat_map(|i| &i.surfaces)
        .any(|s| s.material.lets_light_through());
    SceneSnapshot {
        bvh: with_build_pool(device.requested_thread_count(), || SceneBvh::build(descs)),
        instances,
        lights,
        volumes,
        see_through,
        cluster: None,
    }
}

/// Bounds of a group's surfaces and volumes in its own space.
pub fn group_bounds(device: &Device, group: &Object) -> Option<[f32; 6]> {
    let contents = group_contents(device, &group.committed());
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for s in &contents.surfaces {
        let (a, b) = s.geometry.bvh.bounds();
        lo = lo.min(a);
        hi = hi.max(b);
    }
    for (_, field) in &contents.volumes {
        let (a, b) = field.bounds();
        lo = lo.min(a);
        hi = hi.max(b);
    }
    Some([lo.x, lo.y, lo.z, hi.x, hi.y, hi.z])
}
