//! The object every ANARI handle refers to: kind, subtype, staged and committed parameters,
//! the application's reference count, and the derived state its kind builds at commit.

use std::any::Any;
use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, RwLock};

use crate::device::array::ArrayStore;
use crate::device::datatype::*;
use crate::device::frame::Frame;
use crate::device::params::ParamSet;
use crate::device::spec::ObjectSpec;

/// What the application has set but not yet committed.
#[derive(Default)]
pub struct Staging {
    params: ParamSet,
    /// Arrays handed out by anariMapParameterArray*, waiting for their unmap.
    pub mapped_arrays: HashMap<String, Arc<Object>>,
    /// Names set or unset since the last commit (for the render-time diagnostics).
    touched: BTreeSet<String>,
}

/// How a parameter's staged value differs from its committed one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pending {
    Set,
    Unset,
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
    /// Counts staged changes (sets and unsets); `reported_changes` is the count the render-time
    /// diagnostics last looked at, so that each change is reported once.
    changes: AtomicU64,
    reported_changes: AtomicU64,
    reported_uncommitted: AtomicBool,
    derived: RwLock<Option<Derived>>,
    /// Present for array objects only.
    pub array: Option<ArrayStore>,
    /// Present for frame objects only.
    pub frame: Option<Arc<dyn Frame>>,
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
        frame: Option<Arc<dyn Frame>>,
    ) -> Object {
        Object {
            handle,
            kind,
            subtype: subtype.to_owned(),
            spec,
            app_references: AtomicU32::new(1),
            staging: Mutex::new(Staging::default()),
            committed: RwLock::new(Arc::new(ParamSet::default())),
            commit_count: AtomicU64::new(0),
            changes: AtomicU64::new(0),
            reported_changes: AtomicU64::new(0),
            reported_uncommitted: AtomicBool::new(false),
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

    /// Stages a parameter value (anariSetParameter, anariUnmapParameterArray).
    pub fn stage_set(&self, name: &str, value: crate::device::params::ParamValue) {
        let mut staging = self.staging();
        staging.params.set(name, value);
        staging.touched.insert(name.to_owned());
        self.changes.fetch_add(1, Ordering::AcqRel);
    }

    /// Stages the removal of a parameter (anariUnsetParameter).
    pub fn stage_unset(&self, name: &str) {
        let mut staging = self.staging();
        staging.params.unset(name);
        staging.touched.insert(name.to_owned());
        self.changes.fetch_add(1, Ordering::AcqRel);
    }

    /// Stages the removal of every parameter (anariUnsetAllParameters).
    pub fn stage_clear(&self) {
        let committed = self.committed();
        let mut staging = self.staging();
        let names: Vec<String> = staging
            .params
            .names()
            .chain(committed.names())
            .map(str::to_owned)
            .collect();
        staging.touched.extend(names);
        staging.params.clear();
        self.changes.fetch_add(1, Ordering::AcqRel);
    }

    /// Snapshots the staged parameters as the committed ones and returns the new count.
    pub fn commit_staged(&self) -> u64 {
        let mut staging = self.staging();
        let snapshot = Arc::new(staging.params.clone());
        staging.touched.clear();
        *self.committed.write().unwrap_or_else(|e| e.into_inner()) = snapshot;
        drop(staging);
        self.commit_count.fetch_add(1, Ordering::AcqRel) + 1
    }

    /// The parameters whose staged value differs from the committed one, when there are
    /// changes not looked at before (each change is reported once); empty otherwise.
    pub fn unreported_changes(&self) -> Vec<(String, Pending)> {
        let changes = self.changes.load(Ordering::Acquire);
        if self.reported_changes.swap(changes, Ordering::AcqRel) == changes {
            return Vec::new();
        }
        let staging = self.staging();
        let committed = self.committed();
        staging
            .touched
            .iter()
            .filter_map(
                |name| match (staging.params.get(name), committed.get(name)) {
                    (Some(staged), Some(old)) if staged.same_as(old) => None,
                    (Some(_), _) => Some((name.clone(), Pending::Set)),
                    (None, Some(_)) => Some((name.clone(), Pending::Unset)),
                    (None, None) => None,
                },
            )
            .collect()
    }

    /// True the first time it is asked (the diagnostics' "never committed" report is made once).
    pub fn first_report_of_no_commit(&self) -> bool {
        !self.reported_uncommitted.swap(true, Ordering::AcqRel)
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

    /// Replaces the derived state only if it is still `expected`: a rebuild made while
    /// rendering must not overwrite what a commit made meanwhile.
    pub fn replace_derived_if_unchanged(&self, expected: &Derived, derived: Derived) {
        let mut slot = self.derived.write().unwrap_or_else(|e| e.into_inner());
        if slot.as_ref().is_some_and(|d| Arc::ptr_eq(d, expected)) {
            *slot = Some(derived);
        }
    }

    /// Drops every reference this object holds to others (parameters, derived state, array
    /// elements): the device's release uses it to free objects that refer to each other.
    pub fn break_references(&self) {
        {
            let mut staging = self.staging();
            staging.params.clear();
            staging.mapped_arrays.clear();
        }
        *self.committed.write().unwrap_or_else(|e| e.into_inner()) = Arc::default();
        self.set_derived(None);
        if let Some(store) = &self.array {
            store.lock().objects.clear();
        }
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
