//! The one table of object kinds: every subtype's spec, where each kind's commit goes, the
//! properties kinds compute and the frame's render state. It sits above the layers that define
//! the kinds (scene, camera, render) and below the C boundary (capi, sdk), which hand it to
//! every device they create; the device base itself names no kind.
//!
//! A new kind or subtype enters by its spec in its layer's `SPECS` list; a kind with commit
//! work adds its arm to [`AllKinds::commit`] here.

#[cfg(test)]
mod cycle_tests;
#[cfg(test)]
mod tests;

use std::sync::{Arc, LazyLock};

use crate::device::Device;
use crate::device::catalog::{self, Kinds};
use crate::device::datatype::*;
use crate::device::frame::Frame;
use crate::device::object::Object;
use crate::device::property::PropertyValue;
use crate::device::spec::ObjectSpec;
use crate::render::frame::FrameState;
use crate::scene::{
    geometry, isosurface, light, material, sampler, spatial_field, unstructured_field, volume,
    world,
};

/// The kinds cavetrace implements.
pub struct AllKinds;

/// The table every device of this library serves.
pub static KINDS: AllKinds = AllKinds;

static SPECS: LazyLock<Vec<&'static ObjectSpec>> = LazyLock::new(|| {
    std::iter::once(&catalog::DEVICE)
        .chain(crate::scene::SPECS.iter())
        .chain(crate::camera::SPECS.iter())
        .chain(crate::render::SPECS.iter())
        .collect()
});

impl Kinds for AllKinds {
    fn specs(&self) -> &[&'static ObjectSpec] {
        &SPECS
    }

    fn commit(&self, device: &Device, object: &Object) {
        if object.spec.is_none() {
            return;
        }
        match object.kind {
            ANARI_GEOMETRY if object.subtype == isosurface::ISOSURFACE.subtype => {
                object.set_derived(Some(Arc::new(isosurface::commit(device, object))));
            }
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

    fn property(&self, device: &Device, object: &Object, name: &str) -> Option<PropertyValue> {
        let bounds = match (object.kind, name) {
            (ANARI_WORLD, "bounds") => Some(world::snapshot(device, object).bounds()),
            (ANARI_GROUP, "bounds") => world::group_bounds(device, object),
            _ => None,
        };
        // An empty world or group has no bounds: the query fails rather than return an
        // inverted box.
        bounds
            .filter(|b| b[0] <= b[3] && b[1] <= b[4] && b[2] <= b[5])
            .map(PropertyValue::Box3)
    }

    fn new_frame(&self) -> Arc<dyn Frame> {
        Arc::new(FrameState::default())
    }
}
