//! Scene objects: one file per ANARI object kind. Commits validate parameters and build what is
//! expensive (geometry BVHs, sampler images) once; frames take cheap snapshots of the rest.

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
