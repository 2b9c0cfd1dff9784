//! cavetrace: a ray-tracing ANARI device for CAVEs, powerwalls and head-tracked stereo.
//!
//! Layers, with imports running one way (see `docs/architecture.md`): `capi` and `sdk` (the C
//! boundary) → `kinds` (the one table of object kinds) → `render` (renderers, shading, frames)
//! → `scene` (object kinds) and `camera` (camera math) → `device` (the base: objects,
//! parameters, specs, status, arrays); `scene` and `render` also use `accel` (BVHs), which
//! like `device` uses only `isa`.

pub mod accel;
pub mod camera;
pub mod capi;
pub mod device;
pub mod isa;
pub mod kinds;
pub mod render;
pub mod scene;
pub mod sdk;
