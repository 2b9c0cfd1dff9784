//! The object every ANARI handle refers to: kind, subtype, staged and committed parameters,
//! the application's reference count, and the derived state its kind builds at commit.

use std::any::Any;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, RwLock};

use crate::device::datatype::*;
use crate::device::params::ParamSet;
use crate::device::spec::ObjectSpec;
use crate::render::frame::FrameState;
use crate::scene::array::ArrayStore;

/// What the application has set but not yet committed.
#[derive(Default)]
pub struct Staging {
    pub params: ParamSet,
    /// Arrays handed out by anariMapParameterArray*, waiting for their unmap.
    pub mapped_arrays: HashMap<String, Arc<Object>>,
}

/// Derived state built at commit (a geometry's BVH, a camera's model, …).
pub type Derived = Arc<dyn Any + Send + Sync>;

pub struct Object {
    /// The value the application holds (never dereferenced; looked up in the registry).
    pub handle: usize,
    pub kind: ANARIDataType,
    pub subtype: String,
    /// `None` for subtypes the device does not know: the object exists but is ignored.
    pub spec: Option<&'static ObjectSpec>,
    app_references: AtomicU32,
    staging: Mutex<Staging>,
    committed: RwLock<Arc<ParamSet>>,
    commit_count: AtomicU64,
    derived: RwLock<Option<Derived>>,
    /// Present for array objects only.
    pub array: Option<ArrayStore>,
    /// Present for frame objects only.
    pub frame: Option<Arc<FrameState>>,
}

impl std::fmt::Debug for Object {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.describe())
    }
}

impl Object {
    pub fn new(
        handle: usize,
        kind: ANARIDataType,
        subtype: &str,
        spec: Option<&'static ObjectSpec>,
        array: Option<ArrayStore>,
    ) -> Object {
        let frame = (kind == ANARI_FRAME).then(|| Arc::new(FrameState::default()));
        Object {
            handle,
            kind,
            subtype: subtype.to_owned(),
            spec,
            app_references: AtomicU32::new(1),
            staging: Mutex::new(Staging::default()),
            committed: RwLock::new(Arc::new(ParamSet::default())),
            commit_count: AtomicU64::new(0),
            derived: RwLock::new(None),
            array,
            frame,
        }
    }

    /// "geometry 'triangle'" / "world" — used in every status message.
    pub fn describe(&self) -> String {
        let kind = kind_name(self.kind);
        if self.subtype.is_empty() {
            kind.to_owned()
        } else {
            format!("{kind} '{}'", self.subtype)
        }
    }

    pub fn staging(&self) -> MutexGuard<'_, Staging> {
        self.staging.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The parameters as of the last commit.
    pub fn committed(&self) -> Arc<ParamSet> {
        self.committed
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Snapshots the staged parameters as the committed ones and returns the new count.
    pub fn commit_staged(&self) -> u64 {
        let snapshot = Arc::new(self.staging().params.clone());
        *self.committed.write().unwrap_or_else(|e| e.into_inner()) = snapshot;
        self.commit_count.fetch_add(1, Ordering::AcqRel) + 1
    }

    pub fn commit_count(&self) -> u64 {
        self.commit_count.load(Ordering::Acquire)
    }

    pub fn derived(&self) -> Option<Derived> {
        self.derived
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The derived state as a concrete type.
    pub fn derived_as<T: Any + Send + Sync>(&self) -> Option<Arc<T>> {
        self.derived().and_then(|d| d.downcast::<T>().ok())
    }

    pub fn set_derived(&self, derived: Option<Derived>) {
        *self.derived.write().unwrap_or_else(|e| e.into_inner()) = derived;
    }

    pub fn retain(&self) {
        self.app_references.fetch_add(1, Ordering::AcqRel);
    }

    /// Drops one application reference; true when it was the last.
    pub fn release(&self) -> bool {
        self.app_references.fetch_sub(1, Ordering::AcqRel) == 1
    }

    pub fn app_references(&self) -> u32 {
        self.app_references.load(Ordering::Acquire)
    }
}

/// Lower-case kind name for messages ("geometry", "spatial field").
pub fn kind_name(kind: ANARIDataType) -> &'static str {
    match kind {
        ANARI_DEVICE => "device",
        ANARI_ARRAY | ANARI_ARRAY1D => "array1D",
        ANARI_ARRAY2D => "array2D",
        ANARI_ARRAY3D => "array3D",
        ANARI_CAMERA => "camera",
        ANARI_FRAME => "frame",
        ANARI_GEOMETRY => "geometry",
        ANARI_GROUP => "group",
        ANARI_INSTANCE => "instance",
        ANARI_LIGHT => "light",
        ANARI_MATERIAL => "material",
        ANARI_RENDERER => "renderer",
        ANARI_SURFACE => "surface",
        ANARI_SAMPLER => "sampler",
        ANARI_SPATIAL_FIELD => "spatial field",
        ANARI_VOLUME => "volume",
        ANARI_WORLD => "world",
        _ => "object",
    }
}
