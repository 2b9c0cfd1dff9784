//! Scene objects: one file per ANARI object kind. Commits validate parameters and build what is
//! expensive (geometry BVHs, sampler images) once; frames take cheap snapshots of the rest.

pub mod array;
pub mod attributes;
pub mod cell_shapes;
pub mod environment;
pub mod field;
pub mod geometry;
pub mod group;
pub mod instance;
pub mod isosurface;
pub mod light;
pub mod limits;
pub mod macrocells;
pub mod material;
pub mod sampler;
pub mod spatial_field;
pub mod surface;
pub mod unstructured_field;
pub mod volume;
pub mod world;

use std::sync::Arc;

use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::spec::ObjectSpec;

pub const SPECS: &[ObjectSpec] = &[
    geometry::TRIANGLE,
    geometry::QUAD,
    geometry::SPHERE,
    geometry::CYLINDER,
    geometry::CONE,
    geometry::CURVE,
    isosurface::ISOSURFACE,
    material::MATTE,
    material::PHYSICALLY_BASED,
    sampler::IMAGE1D,
    sampler::IMAGE2D,
    sampler::IMAGE3D,
    sampler::PRIMITIVE,
    sampler::TRANSFORM,
    light::DIRECTIONAL,
    light::POINT,
    light::SPOT,
    light::RING,
    light::QUAD,
    light::HDRI,
    surface::SURFACE,
    spatial_field::STRUCTURED_REGULAR,
    unstructured_field::UNSTRUCTURED,
    volume::TRANSFER_FUNCTION1D,
    group::GROUP,
    instance::TRANSFORM,
    world::WORLD,
];

/// Kind-specific work after an object's parameters were committed.
pub fn commit(device: &Device, object: &Object) {
    if object.spec.is_none() {
        return;
    }
    match object.kind {
        ANARI_GEOMETRY => {
            let geometry = geometry::commit(device, object);
            object.set_derived(geometry.map(|g| Arc::new(g) as _));
        }
        ANARI_SAMPLER => {
            let sampler = sampler::commit(device, object);
            object.set_derived(sampler.map(|s| Arc::new(s) as _));
        }
        ANARI_SPATIAL_FIELD if object.subtype == unstructured_field::UNSTRUCTURED.subtype => {
            let field = unstructured_field::commit(device, object);
            object.set_derived(field.map(|f| Arc::new(f) as _));
        }
        ANARI_SPATIAL_FIELD => {
            let field = spatial_field::commit(device, object);
            object.set_derived(field.map(|f| Arc::new(f) as _));
        }
        ANARI_VOLUME => {
            let volume = volume::commit(device, object);
            object.set_derived(volume.map(|v| Arc::new(v) as _));
        }
        ANARI_LIGHT => light::commit(device, object),
        ANARI_MATERIAL => material::commit(device, object),
        ANARI_CAMERA => crate::camera::commit(device, object),
        ANARI_RENDERER | ANARI_FRAME => crate::render::commit(device, object),
        _ => {}
    }
}

/// The "bounds" property of worlds and groups.
pub fn bounds(device: &Device, object: &Object) -> Option<[f32; 6]> {
    match object.kind {
        ANARI_WORLD => Some(world::snapshot(device, object).bounds()),
        ANARI_GROUP => world::group_bounds(device, object),
        _ => None,
    }
}
