//! The device: object registry, parameters, commits, reference counting and status reporting.
//! Everything here takes plain Rust values; the C boundary (`crate::capi`) converts arguments.

pub mod array;
pub mod catalog;
pub mod datatype;
pub mod frame;
pub mod memory;
pub mod object;
pub mod params;
pub mod pool;
pub mod property;
pub mod registry;
pub mod spec;
pub mod status;

use std::collections::HashMap;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, Weak};

use crate::device::array::{ANARIMemoryDeleter, ArrayError, ArrayStore};
use crate::device::catalog::Kinds;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::params::ParamValue;
use crate::device::pool::WorkerPool;
use crate::device::status::*;

/// A parameter value as it arrived from C, before handles are resolved.
#[derive(Clone, Debug)]
pub enum IncomingValue {
    Data(Vec<u8>),
    String(String),
    Handle(usize),
    Pointer(usize),
}

pub struct Device {
    pub handle: usize,
    app_references: AtomicU32,
    objects: Mutex<HashMap<usize, Arc<Object>>>,
    /// Every object created, also those the application released: objects that refer to each
    /// other (a parameter naming its own object, arrays holding each other) keep one another
    /// alive, and the device's release breaks those cycles.
    created: Mutex<Vec<Weak<Object>>>,
    pub status: Arc<StatusSink>,
    /// The object kinds this device serves.
    kinds: &'static dyn Kinds,
    /// The device's own parameters (statusCallback, numThreads, …).
    pub self_object: Object,
    pool: Mutex<Option<Arc<WorkerPool>>>,
    /// Counts commits and array unmaps anywhere on the device (accumulation restarts on change).
    commit_epoch: AtomicU64,
}

/// Where a message comes from: the API function and the object it concerns.
pub fn source_of(object: Option<&Object>) -> Source {
    object
        .map(|o| Source {
            handle: o.handle,
            kind: o.kind,
        })
        .unwrap_or_default()
}

impl Device {
    pub fn new(
        kinds: &'static dyn Kinds,
        callback: ANARIStatusCallback,
        user_data: usize,
    ) -> Arc<Device> {
        crate::isa::select(crate::isa::Isa::from_environment());
        let handle = registry::next_handle();
        let device = Arc::new(Device {
            handle,
            app_references: AtomicU32::new(1),
            objects: Mutex::new(HashMap::new()),
            created: Mutex::new(Vec::new()),
            status: Arc::new(StatusSink::new(handle, callback, user_data)),
            kinds,
            self_object: Object::new(handle, ANARI_DEVICE, "", Some(&catalog::DEVICE), None, None),
            pool: Mutex::new(None),
            commit_epoch: AtomicU64::new(0),
        });
        registry::add_device(Arc::clone(&device));
        device
    }

    pub fn report(
        &self,
        severity: ANARIStatusSeverity,
        code: ANARIStatusCode,
        source: Source,
        text: String,
    ) {
        self.status.report(&StatusMessage {
            severity,
            code,
            source,
            text,
        });
    }

    pub fn error(&self, code: ANARIStatusCode, object: Option<&Object>, text: String) {
        self.report(ANARI_SEVERITY_ERROR, code, source_of(object), text);
    }

    pub fn warning(&self, object: Option<&Object>, text: String) {
        self.report(
            ANARI_SEVERITY_WARNING,
            ANARI_STATUS_NO_ERROR,
            source_of(object),
            text,
        );
    }

    // ----- registry -------------------------------------------------------------------------

    /// The live object behind `handle`, if the application still holds it on this device.
    pub fn lookup(&self, handle: usize) -> Option<Arc<Object>> {
        self.objects
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(&handle)
            .cloned()
    }

    /// Looks a handle up and reports when it is not a live object of this device.
    pub fn resolve(&self, function: &str, handle: usize) -> Option<Arc<Object>> {
        if handle == 0 {
            self.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                None,
                format!("{function}: the object handle is NULL"),
            );
            return None;
        }
        let object = self.lookup(handle);
        if object.is_none() {
            self.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                None,
                format!(
                    "{function}: {handle:#x} is not a live object of this device \
                     (never created here, or already released)"
                ),
            );
        }
        object
    }

    /// The object kinds this device serves.
    pub fn kinds(&self) -> &'static dyn Kinds {
        self.kinds
    }

    pub fn live_object_count(&self) -> usize {
        self.objects.lock().unwrap_or_else(|e| e.into_inner()).len()
    }

    fn register(&self, object: Object) -> usize {
        let handle = object.handle;
        let object = Arc::new(object);
        {
            let mut created = self.created.lock().unwrap_or_else(|e| e.into_inner());
            // Forgetting the dead now and then keeps the list as long as the live objects.
            if created.len() >= 1024 && created.len().is_power_of_two() {
                created.retain(|o| o.strong_count() > 0);
            }
            created.push(Arc::downgrade(&object));
        }
        self.objects
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(handle, object);
        handle
    }

    // ----- creation -------------------------------------------------------------------------

    /// anariNew*: always returns a valid object; an unknown subtype is reported and ignored at
    /// render time.
    pub fn new_object(&self, function: &str, kind: ANARIDataType, subtype: &str) -> usize {
        let spec = self.kinds.find(kind, subtype);
        let handle = registry::next_handle();
        let frame = (kind == ANARI_FRAME).then(|| self.kinds.new_frame());
        let object = Object::new(handle, kind, subtype, spec, None, frame);
        if spec.is_none() {
            self.warning(
                Some(&object),
                format!(
                    "{function}: unknown {} subtype '{subtype}'; the object is accepted but \
                     ignored when rendering (known subtypes: {})",
                    object::kind_name(kind),
                    self.kinds.subtype_names(kind).join(", ")
                ),
            );
        }
        self.register(object)
    }

    pub fn new_array(
        &self,
        function: &str,
        app_memory: *const std::ffi::c_void,
        deleter: ANARIMemoryDeleter,
        user_data: *const std::ffi::c_void,
        element_type: ANARIDataType,
        dims: [u64; 3],
    ) -> usize {
        let kind = match dims {
            [_, 1, 1] if function.ends_with("1D") => ANARI_ARRAY1D,
            [_, _, 1] if function.ends_with("2D") => ANARI_ARRAY2D,
            _ => ANARI_ARRAY3D,
        };
        let store = match ArrayStore::new(element_type, dims, app_memory, deleter, user_data) {
            Ok(store) => store,
            Err(error) => {
                let (code, what) = match error {
                    ArrayError::InvalidType => (
                        ANARI_STATUS_INVALID_ARGUMENT,
                        format!("{element_type} is not an ANARI data type"),
                    ),
                    ArrayError::TooLarge => (
                        ANARI_STATUS_OUT_OF_MEMORY,
                        format!(
                            "{dims:?} elements of {} overflow the address space",
                            type_name(element_type)
                        ),
                    ),
                    ArrayError::OutOfMemory => (
                        ANARI_STATUS_OUT_OF_MEMORY,
                        format!(
                            "cannot allocate {dims:?} elements of {}",
                            type_name(element_type)
                        ),
                    ),
                    ArrayError::Exceeds(too_big) => (
                        ANARI_STATUS_OUT_OF_MEMORY,
                        format!("{dims:?} elements of {} {too_big}", type_name(element_type)),
                    ),
                };
                self.error(
                    code,
                    None,
                    format!("{function}: {what}; no array was created"),
                );
                return 0;
            }
        };
        let object = Object::new(registry::next_handle(), kind, "", None, Some(store), None);
        if is_object(element_type) && !app_memory.is_null() {
            self.resolve_array_objects(function, &object);
        }
        self.register(object)
    }

    /// Retains the objects named by an array of handles (at creation and at every unmap).
    fn resolve_array_objects(&self, function: &str, array: &Object) {
        let Some(store) = &array.array else { return };
        if !is_object(store.element_type) {
            return;
        }
        let mut resolved = Vec::new();
        for (index, handle) in store.handle_values().into_iter().enumerate() {
            match self.lookup(handle) {
                Some(element) if object_kind_matches(store.element_type, element.kind) => {
                    resolved.push(element)
                }
                Some(element) => self.error(
                    ANARI_STATUS_INVALID_ARGUMENT,
                    Some(array),
                    format!(
                        "{function}: element {index} of an array of {} is a {}; it is ignored",
                        type_name(store.element_type),
                        element.describe()
                    ),
                ),
                None => self.error(
                    ANARI_STATUS_INVALID_ARGUMENT,
                    Some(array),
                    format!(
                        "{function}: element {index} ({handle:#x}) of an array of {} is not a \
                         live object of this device; it is ignored",
                        type_name(store.element_type)
                    ),
                ),
            }
        }
        store.lock().objects = resolved;
    }

    pub fn map_array(&self, function: &str, handle: usize) -> *mut std::ffi::c_void {
        let Some(object) = self.resolve(function, handle) else {
            return std::ptr::null_mut();
        };
        let Some(store) = &object.array else {
            self.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                Some(&object),
                format!("{function}: {} is not an array", object.describe()),
            );
            return std::ptr::null_mut();
        };
        {
            let mut inner = store.lock();
            if inner.mapped {
                drop(inner);
                self.error(
                    ANARI_STATUS_INVALID_OPERATION,
                    Some(&object),
                    format!("{function}: the {} is already mapped", object.describe()),
                );
                return std::ptr::null_mut();
            }
            inner.mapped = true;
        }
        store.data_pointer()
    }

    pub fn unmap_array(&self, function: &str, handle: usize) {
        let Some(object) = self.resolve(function, handle) else {
            return;
        };
        let Some(store) = &object.array else {
            self.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                Some(&object),
                format!("{function}: {} is not an array", object.describe()),
            );
            return;
        };
        let was_mapped = std::mem::replace(&mut store.lock().mapped, false);
        if !was_mapped {
            self.error(
                ANARI_STATUS_INVALID_OPERATION,
                Some(&object),
                format!("{function}: the {} is not mapped", object.describe()),
            );
            return;
        }
        self.commit_epoch.fetch_add(1, Ordering::AcqRel);
        self.resolve_array_objects(function, &object);
    }

    // ----- parameters -----------------------------------------------------------------------

    fn target(&self, function: &str, handle: usize) -> Option<Target> {
        if handle == self.handle {
            return Some(Target::Device);
        }
        self.resolve(function, handle).map(Target::Object)
    }

    pub fn set_parameter(
        &self,
        function: &str,
        handle: usize,
        name: &str,
        data_type: ANARIDataType,
        value: IncomingValue,
    ) {
        let Some(target) = self.target(function, handle) else {
            return;
        };
        let object = target.object(self);
        let Some(value) = self.check_parameter(function, object, name, data_type, value) else {
            return;
        };
        object.stage_set(name, value);
    }

    /// Validates a parameter against the object's table and resolves handles.
    fn check_parameter(
        &self,
        function: &str,
        object: &Object,
        name: &str,
        data_type: ANARIDataType,
        value: IncomingValue,
    ) -> Option<ParamValue> {
        let what = format!("{function}: {} parameter '{name}'", object.describe());
        if !is_valid(data_type) {
            self.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                Some(object),
                format!("{what}: {data_type} is not an ANARI data type; ignored"),
            );
            return None;
        }
        let param = object.spec.and_then(|spec| spec.param(name));
        if let Some(spec) = object.spec {
            match spec.param(name) {
                Some(param) if !accepts_declared(param.types, data_type) => {
                    let accepted: Vec<&str> = param.types.iter().map(|t| type_name(*t)).collect();
                    self.error(
                        ANARI_STATUS_INVALID_ARGUMENT,
                        Some(object),
                        format!(
                            "{what}: given {}, accepted {}; ignored",
                            type_name(data_type),
                            accepted.join(" or ")
                        ),
                    );
                    return None;
                }
                Some(_) => {}
                None if spec.unsupported.contains(&name) => self.warning(
                    Some(object),
                    format!(
                        "{what}: a parameter of {} that cavetrace does not support; it has no \
                         effect",
                        spec.extensions.join(", ")
                    ),
                ),
                None => self.warning(
                    Some(object),
                    format!(
                        "{what}: not a parameter of this object (given as {}); it has no effect",
                        type_name(data_type)
                    ),
                ),
            }
        }
        match value {
            IncomingValue::Handle(handle) => {
                let Some(target) = self.lookup(handle) else {
                    self.error(
                        ANARI_STATUS_INVALID_ARGUMENT,
                        Some(object),
                        format!("{what}: {handle:#x} is not a live object of this device; ignored"),
                    );
                    return None;
                };
                if !object_kind_matches(data_type, target.kind) {
                    self.error(
                        ANARI_STATUS_INVALID_ARGUMENT,
                        Some(object),
                        format!(
                            "{what}: declared {} but the handle is a {}; ignored",
                            type_name(data_type),
                            target.describe()
                        ),
                    );
                    return None;
                }
                // A generic declaration (ANARI_OBJECT, ANARI_ARRAY) is checked by what the
                // handle really is, and stored as that.
                let data_type = match param {
                    Some(param) if data_type != target.kind => {
                        if !param.types.contains(&target.kind) {
                            let accepted: Vec<&str> =
                                param.types.iter().map(|t| type_name(*t)).collect();
                            self.error(
                                ANARI_STATUS_INVALID_ARGUMENT,
                                Some(object),
                                format!(
                                    "{what}: declared {}, the handle is a {} ({}), accepted {}; \
                                     ignored",
                                    type_name(data_type),
                                    target.describe(),
                                    type_name(target.kind),
                                    accepted.join(" or ")
                                ),
                            );
                            return None;
                        }
                        target.kind
                    }
                    _ => data_type,
                };
                if let (Some(param), Some(store)) = (param, &target.array)
                    && !self.elements_accepted(&what, object, param.element_types, store)
                {
                    return None;
                }
                Some(ParamValue::Object {
                    data_type,
                    object: target,
                })
            }
            IncomingValue::String(s) => Some(ParamValue::String(s)),
            IncomingValue::Pointer(address) => Some(ParamValue::Pointer { data_type, address }),
            IncomingValue::Data(bytes) => ParamValue::from_bytes(data_type, &bytes),
        }
    }

    /// Whether an array with `store`'s elements may be the value of a parameter whose elements
    /// must be `accepted` (any, when empty). Generic `ANARI_OBJECT` elements where objects are
    /// expected are checked one by one: those of another kind, or released, are reported by
    /// index and left out by the consumers, and the array is taken.
    fn elements_accepted(
        &self,
        what: &str,
        object: &Object,
        accepted: &[ANARIDataType],
        store: &ArrayStore,
    ) -> bool {
        if accepted.is_empty() || accepted.contains(&store.element_type) {
            return true;
        }
        if store.element_type == ANARI_OBJECT && accepted.iter().all(|t| is_object(*t)) {
            self.report_generic_elements(what, object, store, accepted);
            return true;
        }
        let names: Vec<&str> = accepted.iter().map(|t| type_name(*t)).collect();
        self.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!(
                "{what}: array elements are {}, accepted {}; ignored",
                type_name(store.element_type),
                names.join(" or ")
            ),
        );
        false
    }

    /// Reports the elements of an `ANARI_OBJECT` array that are not of an `accepted` kind or not
    /// live, by index; the consumers leave those out.
    fn report_generic_elements(
        &self,
        what: &str,
        object: &Object,
        store: &ArrayStore,
        accepted: &[ANARIDataType],
    ) {
        let names: Vec<&str> = accepted.iter().map(|t| type_name(*t)).collect();
        for (index, handle) in store.handle_values().into_iter().enumerate() {
            let problem = match self.lookup(handle) {
                Some(element) if accepted.contains(&element.kind) => continue,
                Some(element) => {
                    format!("is a {} ({})", element.describe(), type_name(element.kind))
                }
                None => format!("({handle:#x}) is not a live object of this device"),
            };
            self.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                Some(object),
                format!(
                    "{what}: element {index} of the ANARI_OBJECT array {problem}, accepted {}; \
                     it is left out",
                    names.join(" or ")
                ),
            );
        }
    }

    pub fn unset_parameter(&self, function: &str, handle: usize, name: &str) {
        if let Some(target) = self.target(function, handle) {
            target.object(self).stage_unset(name);
        }
    }

    pub fn unset_all_parameters(&self, function: &str, handle: usize) {
        if let Some(target) = self.target(function, handle) {
            target.object(self).stage_clear();
        }
    }

    /// anariMapParameterArray*: a managed array the application fills, which becomes the
    /// parameter's value at unmap. Returns (pointer, element stride) or None.
    pub fn map_parameter_array(
        &self,
        function: &str,
        handle: usize,
        name: &str,
        element_type: ANARIDataType,
        dims: [u64; 3],
    ) -> Option<(*mut std::ffi::c_void, u64)> {
        let target = self.target(function, handle)?;
        let object = target.object(self);
        let array_handle = self.new_array(
            function,
            std::ptr::null(),
            None,
            std::ptr::null(),
            element_type,
            dims,
        );
        if array_handle == 0 {
            return None;
        }
        // The array is the device's own: it leaves the registry and lives in the staging area.
        let array = self
            .objects
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&array_handle)?;
        let store = array.array.as_ref()?;
        store.lock().mapped = true;
        let pointer = store.data_pointer();
        let stride = element_size(element_type).unwrap_or(0) as u64;
        object
            .staging()
            .mapped_arrays
            .insert(name.to_owned(), array);
        Some((pointer, stride))
    }

    pub fn unmap_parameter_array(&self, function: &str, handle: usize, name: &str) {
        let Some(target) = self.target(function, handle) else {
            return;
        };
        let object = target.object(self);
        let Some(array) = object.staging().mapped_arrays.remove(name) else {
            self.error(
                ANARI_STATUS_INVALID_OPERATION,
                Some(object),
                format!(
                    "{function}: {} parameter '{name}' has no mapped array",
                    object.describe()
                ),
            );
            return;
        };
        if let Some(store) = &array.array {
            store.lock().mapped = false;
        }
        self.resolve_array_objects(function, &array);
        let data_type = array.kind;
        if let Some(param) = object.spec.and_then(|s| s.param(name)) {
            if !param.types.contains(&data_type) {
                self.error(
                    ANARI_STATUS_INVALID_ARGUMENT,
                    Some(object),
                    format!(
                        "{function}: {} parameter '{name}' does not accept {}; ignored",
                        object.describe(),
                        type_name(data_type)
                    ),
                );
                return;
            }
            let what = format!("{function}: {} parameter '{name}'", object.describe());
            if let Some(store) = &array.array
                && !self.elements_accepted(&what, object, param.element_types, store)
            {
                return;
            }
        }
        object.stage_set(
            name,
            ParamValue::Object {
                data_type,
                object: array,
            },
        );
    }

    // ----- commit and lifetime --------------------------------------------------------------

    pub fn commit_epoch(&self) -> u64 {
        self.commit_epoch.load(Ordering::Acquire)
    }

    pub fn commit(&self, function: &str, handle: usize) {
        let Some(target) = self.target(function, handle) else {
            return;
        };
        self.commit_epoch.fetch_add(1, Ordering::AcqRel);
        match target {
            Target::Device => {
                self.self_object.commit_staged();
                self.apply_device_parameters();
            }
            Target::Object(object) => {
                object.commit_staged();
                self.check_required(function, &object);
                self.kinds.commit(self, &object);
            }
        }
    }

    fn check_required(&self, function: &str, object: &Object) {
        let Some(spec) = object.spec else { return };
        let params = object.committed();
        for param in spec.params.iter().filter(|p| p.required) {
            if !params.contains(param.name) {
                self.warning(
                    Some(object),
                    format!(
                        "{function}: {} is missing its required parameter '{}' ({})",
                        object.describe(),
                        param.name,
                        param
                            .types
                            .iter()
                            .map(|t| type_name(*t))
                            .collect::<Vec<_>>()
                            .join(" or ")
                    ),
                );
            }
        }
    }

    fn apply_device_parameters(&self) {
        let params = self.self_object.committed();
        if params.contains("statusCallback") || params.contains("statusCallbackUserData") {
            let function = params
                .get_pointer("statusCallback", ANARI_STATUS_CALLBACK)
                .unwrap_or(0);
            let user = params
                .get_pointer("statusCallbackUserData", ANARI_VOID_POINTER)
                .unwrap_or(0);
            // SAFETY: the address came from the application as an ANARIStatusCallback value;
            // Option<fn> has the same layout as a nullable function pointer.
            let callback: ANARIStatusCallback = unsafe { std::mem::transmute(function) };
            self.status.set_callback(callback, user);
        }
        if let Some(name) = params.get_string("isa") {
            use crate::isa::{self, Isa};
            let Some(requested) = Isa::parse(name) else {
                self.error(
                    ANARI_STATUS_INVALID_ARGUMENT,
                    None,
                    format!(
                        "anariCommitParameters: device parameter 'isa': '{name}' is not one of \
                         {}; the ray kernels keep {}",
                        Isa::VALUES.join(", "),
                        isa::selected().name()
                    ),
                );
                return self.apply_thread_count();
            };
            if isa::select(requested) != requested {
                self.warning(
                    None,
                    format!(
                        "anariCommitParameters: device parameter 'isa': this CPU has no {}; the \
                         ray kernels use {}",
                        requested.name(),
                        isa::selected().name()
                    ),
                );
            }
        }
        self.apply_thread_count();
    }

    /// Drops the render threads when `numThreads` asks for another count.
    fn apply_thread_count(&self) {
        let wanted = self.requested_thread_count();
        let mut pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
        if pool.as_ref().is_some_and(|p| p.thread_count() != wanted) {
            *pool = None;
        }
    }

    /// Render and build threads: `numThreads`, or one per core.
    pub fn requested_thread_count(&self) -> usize {
        let params = self.self_object.committed();
        match params.get_u32("numThreads") {
            Some(n) if n > 0 => n as usize,
            _ => std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(2),
        }
    }

    /// The render threads (created on first use, recreated when numThreads changes).
    pub fn pool(&self) -> Arc<WorkerPool> {
        let mut pool = self.pool.lock().unwrap_or_else(|e| e.into_inner());
        pool.get_or_insert_with(|| Arc::new(WorkerPool::new(self.requested_thread_count())))
            .clone()
    }

    pub fn retain(&self, function: &str, handle: usize) {
        match self.target(function, handle) {
            Some(Target::Device) => {
                self.app_references.fetch_add(1, Ordering::AcqRel);
            }
            Some(Target::Object(object)) => object.retain(),
            None => {}
        }
    }

    /// Drops one application reference; the last one removes the handle. Objects still used by
    /// others stay alive through those references. Returns true when the device itself died.
    pub fn release(&self, function: &str, handle: usize) -> bool {
        match self.target(function, handle) {
            Some(Target::Device) => {
                if self.app_references.fetch_sub(1, Ordering::AcqRel) == 1 {
                    self.shutdown();
                    return true;
                }
                false
            }
            Some(Target::Object(object)) => {
                if object.release() {
                    self.objects
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .remove(&handle);
                    // Nobody can read a released frame: its render in flight stops at the next
                    // tile (the device's release then has nothing left to wait for).
                    if let Some(frame) = &object.frame {
                        frame.discard();
                    }
                    // Still used by another object: stop relying on application memory.
                    if Arc::strong_count(&object) > 1
                        && let Some(store) = &object.array
                    {
                        store.detach_from_application();
                    }
                }
                false
            }
            None => false,
        }
    }

    /// Stops rendering, joins the threads and frees every object.
    fn shutdown(&self) {
        registry::remove_device(self.handle);
        let objects: Vec<Arc<Object>> = self
            .objects
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .drain()
            .map(|(_, o)| o)
            .collect();
        for object in &objects {
            if let Some(frame) = &object.frame {
                frame.discard();
            }
        }
        for object in &objects {
            if let Some(frame) = &object.frame {
                frame.wait();
            }
        }
        // Joining here (not in some later drop) guarantees no thread outlives the release.
        let pool = self.pool.lock().unwrap_or_else(|e| e.into_inner()).take();
        drop(pool);
        drop(objects);
        self.self_object.stage_clear();
        let created = std::mem::take(&mut *self.created.lock().unwrap_or_else(|e| e.into_inner()));
        for object in created.iter().filter_map(Weak::upgrade) {
            object.break_references();
        }
    }
}

enum Target {
    Device,
    Object(Arc<Object>),
}

impl Target {
    fn object<'a>(&'a self, device: &'a Device) -> &'a Object {
        match self {
            Target::Device => &device.self_object,
            Target::Object(object) => object,
        }
    }
}

/// Whether a parameter declared `types` takes a value declared `data_type`: one of them, or the
/// generic `ANARI_ARRAY` / `ANARI_OBJECT` where it takes an array / an object (the handle's real
/// kind is checked when it is resolved).
fn accepts_declared(types: &[ANARIDataType], data_type: ANARIDataType) -> bool {
    types.contains(&data_type)
        || (data_type == ANARI_ARRAY && types.iter().any(|t| is_array(*t)))
        || (data_type == ANARI_OBJECT && types.iter().any(|t| is_object(*t)))
}
