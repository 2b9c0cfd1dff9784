//! One handle over every spatial field kind, for what samples fields: volumes and isosurfaces.

use std::sync::Arc;

use glam::Vec3;

use crate::device::object::Object;
use crate::scene::macrocells::MacrocellGrid;
use crate::scene::spatial_field::StructuredRegularField;
use crate::scene::unstructured_field::UnstructuredField;

/// A committed spatial field of any kind.
#[derive(Clone, Debug)]
pub enum Field {
    Structured(Arc<StructuredRegularField>),
    Unstructured(Arc<UnstructuredField>),
}

impl From<Arc<StructuredRegularField>> for Field {
    fn from(field: Arc<StructuredRegularField>) -> Field {
        Field::Structured(field)
    }
}

impl From<Arc<UnstructuredField>> for Field {
    fn from(field: Arc<UnstructuredField>) -> Field {
        Field::Unstructured(field)
    }
}

impl Field {
    /// The field a committed spatial field object built, if its commit succeeded.
    pub fn of(object: &Object) -> Option<Field> {
        object
            .derived_as::<StructuredRegularField>()
            .map(Field::Structured)
            .or_else(|| {
                object
                    .derived_as::<UnstructuredField>()
                    .map(Field::Unstructured)
            })
    }

    /// Object-space box the field has values in.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        match self {
            Field::Structured(f) => f.bounds(),
            Field::Unstructured(f) => f.bounds(),
        }
    }

    /// Object-space distance between ray-marching samples.
    pub fn step(&self) -> f32 {
        match self {
            Field::Structured(f) => f.step(),
            Field::Unstructured(f) => f.step(),
        }
    }

    /// The field at an object-space point; NaN where it has no value.
    #[inline]
    pub fn sample(&self, point: Vec3) -> f32 {
        match self {
            Field::Structured(f) => f.sample(point),
            Field::Unstructured(f) => f.sample(point),
        }
    }

    /// Value ranges of blocks of the field, for empty-space skipping.
    pub fn macrocells(&self) -> &MacrocellGrid {
        match self {
            Field::Structured(f) => f.macrocells(),
            Field::Unstructured(f) => f.macrocells(),
        }
    }
}
