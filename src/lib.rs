//! cavetrace: a ray-tracing ANARI device for CAVEs, powerwalls and head-tracked stereo.
//!
//! Layers, with data flowing one way: `capi` (the C boundary) → `device` (registry, parameters,
//! status) → `scene` (object kinds) → `accel` (BVHs) → `render` (shading, tiles, frames).
//! Cameras (`camera`) are pure math used by the renderer.

pub mod accel;
pub mod camera;
pub mod capi;
pub mod device;
pub mod isa;
pub mod render;
pub mod scene;
pub mod sdk;
