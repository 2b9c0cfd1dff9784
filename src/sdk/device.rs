//! The device object (`anari::DeviceImpl`): every ANARI call on a device arrives here as a
//! virtual call and goes to the `crate::device::Device` behind it.
//!
//! The SDK device pointer and cavetrace's internal device handle differ, so three things are
//! translated: the device passed as an object (`anariRelease(d, d)`, device parameters), the
//! device (and source) argument of status callbacks, and the device argument of frame completion
//! callbacks. Every other object handle passes through unchanged.

use std::collections::HashMap;
use std::ffi::{CStr, c_char, c_int, c_void};
use std::io::Write;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, RwLock};

use crate::capi::cache::{cached, leak_string_list};
use crate::capi::frame as capi_frame;
use crate::capi::introspect::{self, ANARIProcAddress, object_info};
use crate::capi::object::kind_from_name;
use crate::capi::params::incoming_value;
use crate::capi::types::*;
use crate::capi::{plain_string, string_arg};
use crate::device::array::ANARIMemoryDeleter;
use crate::device::catalog::Kinds;
use crate::device::datatype::*;
use crate::device::status::*;
use crate::device::{Device, IncomingValue};
use crate::kinds::KINDS;
use crate::render::frame::ANARIFrameCompletionCallback;
use crate::sdk::{VirtualTable, allocate, panic_text};

/// Begins with the layout of `anari::DeviceImpl` (vtable, then its two data members); cavetrace's
/// state follows.
#[repr(C)]
pub(super) struct DeviceObject {
    vtable: *const DeviceSlots,
    /// `DeviceImpl::m_defaultStatusCB` / `m_defaultStatusCBUserPtr`: the library's callback, in
    /// force until the application sets the device parameter `statusCallback`.
    default_callback: ANARIStatusCallback,
    default_user_data: *const c_void,
    device: Arc<Device>,
    /// False once the device's last reference is gone (threads joined, objects freed).
    alive: AtomicBool,
    /// The creating library's count of its live devices.
    library_devices: Arc<AtomicUsize>,
    status: RwLock<StatusCallback>,
    /// Completion callbacks by frame handle.
    frame_callbacks: Mutex<HashMap<usize, FrameCallback>>,
}

const _: () = assert!(std::mem::offset_of!(DeviceObject, default_callback) == 8);
const _: () = assert!(std::mem::offset_of!(DeviceObject, default_user_data) == 16);
const _: () = assert!(std::mem::offset_of!(DeviceObject, device) == 24);

/// The application's status callback: as set (`None`: not set) and as committed.
struct StatusCallback {
    staged_function: Option<usize>,
    staged_user_data: Option<usize>,
    function: ANARIStatusCallback,
    user_data: usize,
}

/// A frame's completion callback: as set (`None`: not set) and as committed (0: none).
#[derive(Clone, Copy, Default)]
struct FrameCallback {
    staged_function: Option<usize>,
    staged_user_data: Option<usize>,
    function: usize,
    user_data: usize,
}

/// `anari::DeviceImpl`'s virtual functions in declaration order; each takes the object first,
/// then the arguments of the matching `anari*` function (Itanium: the complete-object destructor
/// and the deleting destructor take the destructor's place, last).
#[repr(C)]
struct DeviceSlots {
    new_array_1d: extern "C" fn(
        *mut DeviceObject,
        *const c_void,
        ANARIMemoryDeleter,
        *const c_void,
        ANARIDataType,
        u64,
    ) -> ANARIArray1D,
    new_array_2d: extern "C" fn(
        *mut DeviceObject,
        *const c_void,
        ANARIMemoryDeleter,
        *const c_void,
        ANARIDataType,
        u64,
        u64,
    ) -> ANARIArray2D,
    new_array_3d: extern "C" fn(
        *mut DeviceObject,
        *const c_void,
        ANARIMemoryDeleter,
        *const c_void,
        ANARIDataType,
        u64,
        u64,
        u64,
    ) -> ANARIArray3D,
    new_geometry: extern "C" fn(*mut DeviceObject, *const c_char) -> ANARIGeometry,
    new_material: extern "C" fn(*mut DeviceObject, *const c_char) -> ANARIMaterial,
    new_sampler: extern "C" fn(*mut DeviceObject, *const c_char) -> ANARISampler,
    new_surface: extern "C" fn(*mut DeviceObject) -> ANARISurface,
    new_spatial_field: extern "C" fn(*mut DeviceObject, *const c_char) -> ANARISpatialField,
    new_volume: extern "C" fn(*mut DeviceObject, *const c_char) -> ANARIVolume,
    new_light: extern "C" fn(*mut DeviceObject, *const c_char) -> ANARILight,
    new_group: extern "C" fn(*mut DeviceObject) -> ANARIGroup,
    new_instance: extern "C" fn(*mut DeviceObject, *const c_char) -> ANARIInstance,
    new_world: extern "C" fn(*mut DeviceObject) -> ANARIWorld,
    new_camera: extern "C" fn(*mut DeviceObject, *const c_char) -> ANARICamera,
    new_renderer: extern "C" fn(*mut DeviceObject, *const c_char) -> ANARIRenderer,
    new_frame: extern "C" fn(*mut DeviceObject) -> ANARIFrame,
    set_parameter:
        extern "C" fn(*mut DeviceObject, ANARIObject, *const c_char, ANARIDataType, *const c_void),
    unset_parameter: extern "C" fn(*mut DeviceObject, ANARIObject, *const c_char),
    unset_all_parameters: extern "C" fn(*mut DeviceObject, ANARIObject),
    map_parameter_array_1d: extern "C" fn(
        *mut DeviceObject,
        ANARIObject,
        *const c_char,
        ANARIDataType,
        u64,
        *mut u64,
    ) -> *mut c_void,
    map_parameter_array_2d: extern "C" fn(
        *mut DeviceObject,
        ANARIObject,
        *const c_char,
        ANARIDataType,
        u64,
        u64,
        *mut u64,
    ) -> *mut c_void,
    map_parameter_array_3d: extern "C" fn(
        *mut DeviceObject,
        ANARIObject,
        *const c_char,
        ANARIDataType,
        u64,
        u64,
        u64,
        *mut u64,
    ) -> *mut c_void,
    unmap_parameter_array: extern "C" fn(*mut DeviceObject, ANARIObject, *const c_char),
    commit_parameters: extern "C" fn(*mut DeviceObject, ANARIObject),
    release: extern "C" fn(*mut DeviceObject, ANARIObject),
    retain: extern "C" fn(*mut DeviceObject, ANARIObject),
    map_array: extern "C" fn(*mut DeviceObject, ANARIArray) -> *mut c_void,
    unmap_array: extern "C" fn(*mut DeviceObject, ANARIArray),
    get_property: extern "C" fn(
        *mut DeviceObject,
        ANARIObject,
        *const c_char,
        ANARIDataType,
        *mut c_void,
        u64,
        ANARIWaitMask,
    ) -> c_int,
    get_object_subtypes: extern "C" fn(*mut DeviceObject, ANARIDataType) -> *const *const c_char,
    get_object_info: extern "C" fn(
        *mut DeviceObject,
        ANARIDataType,
        *const c_char,
        *const c_char,
        ANARIDataType,
    ) -> *const c_void,
    get_parameter_info: extern "C" fn(
        *mut DeviceObject,
        ANARIDataType,
        *const c_char,
        *const c_char,
        ANARIDataType,
        *const c_char,
        ANARIDataType,
    ) -> *const c_void,
    frame_buffer_map: extern "C" fn(
        *mut DeviceObject,
        ANARIFrame,
        *const c_char,
        *mut u32,
        *mut u32,
        *mut ANARIDataType,
    ) -> *const c_void,
    frame_buffer_unmap: extern "C" fn(*mut DeviceObject, ANARIFrame, *const c_char),
    render_frame: extern "C" fn(*mut DeviceObject, ANARIFrame),
    frame_ready: extern "C" fn(*mut DeviceObject, ANARIFrame, ANARIWaitMask) -> c_int,
    discard_frame: extern "C" fn(*mut DeviceObject, ANARIFrame),
    new_object: extern "C" fn(*mut DeviceObject, *const c_char, *const c_char) -> ANARIObject,
    get_proc_address: extern "C" fn(*mut DeviceObject, *const c_char) -> ANARIProcAddress,
    destroy: extern "C" fn(*mut DeviceObject),
    destroy_and_free: extern "C" fn(*mut DeviceObject),
}

const _: () = assert!(std::mem::size_of::<DeviceSlots>() == 41 * 8);

static DEVICE_VTABLE: VirtualTable<DeviceSlots> = VirtualTable::new(DeviceSlots {
    new_array_1d,
    new_array_2d,
    new_array_3d,
    new_geometry,
    new_material,
    new_sampler,
    new_surface,
    new_spatial_field,
    new_volume,
    new_light,
    new_group,
    new_instance,
    new_world,
    new_camera,
    new_renderer,
    new_frame,
    set_parameter,
    unset_parameter,
    unset_all_parameters,
    map_parameter_array_1d,
    map_parameter_array_2d,
    map_parameter_array_3d,
    unmap_parameter_array,
    commit_parameters,
    release,
    retain,
    map_array,
    unmap_array,
    get_property,
    get_object_subtypes,
    get_object_info,
    get_parameter_info,
    frame_buffer_map,
    frame_buffer_unmap,
    render_frame,
    frame_ready,
    discard_frame,
    new_object,
    get_proc_address,
    destroy,
    destroy_and_free,
});

/// A new device reporting to the library's default callback, or NULL when out of memory.
pub(super) fn create(
    default_callback: ANARIStatusCallback,
    default_user_data: *const c_void,
    library_devices: Arc<AtomicUsize>,
) -> *mut DeviceObject {
    let object = allocate::<DeviceObject>();
    if object.is_null() {
        return object;
    }
    // The internal device reports through `forward_status`, which finds this object through its
    // user data and substitutes the SDK device pointer.
    let device = Device::new(&KINDS, Some(forward_status), object as usize);
    library_devices.fetch_add(1, Ordering::AcqRel);
    // SAFETY: `object` is fresh memory of the right size and alignment; the device makes no
    // report before this write (creating it reports nothing).
    unsafe {
        object.write(DeviceObject {
            vtable: &DEVICE_VTABLE.slots,
            default_callback,
            default_user_data,
            device,
            alive: AtomicBool::new(true),
            library_devices,
            status: RwLock::new(StatusCallback {
                staged_function: None,
                staged_user_data: None,
                function: default_callback,
                user_data: default_user_data as usize,
            }),
            frame_callbacks: Mutex::default(),
        })
    };
    object
}

/// Applies a NULL-name-terminated list of device parameters and commits the device.
pub(super) fn initialize(
    this: *mut DeviceObject,
    function: &'static str,
    parameters: *const ANARIParameterValue,
) {
    with_device(this, function, (), |device| {
        let itself = this as ANARIObject;
        let mut entry = parameters;
        while !entry.is_null() {
            // SAFETY: the application passes an array of ANARIParameterValue ended by an entry
            // whose name is NULL.
            let value = unsafe { &*entry };
            if value.name.is_null() {
                break;
            }
            device.set_parameter(function, itself, value.name, value.data_type, value.value);
            // SAFETY: stays within the application's array until its terminating entry.
            entry = unsafe { entry.add(1) };
        }
        device.commit(function, itself);
    })
}

/// Runs a slot body on the device behind `this`; a panic becomes an error report and `fallback`.
fn with_device<R>(
    this: *mut DeviceObject,
    function: &'static str,
    fallback: R,
    body: impl FnOnce(&DeviceObject) -> R,
) -> R {
    if this.is_null() {
        eprintln!("[cavetrace] error: {function}: the device handle is NULL");
        return fallback;
    }
    // SAFETY: the front end calls slots only on device objects this module created and has not
    // yet freed (freeing happens at the last anariRelease or in the deleting destructor).
    let device = unsafe { &*this };
    match catch_unwind(AssertUnwindSafe(|| body(device))) {
        Ok(result) => result,
        Err(payload) => {
            device.device.error(
                ANARI_STATUS_UNKNOWN_ERROR,
                None,
                format!(
                    "{function}: internal error ({}); the call had no effect",
                    panic_text(&*payload)
                ),
            );
            fallback
        }
    }
}

/// Reads the function address a callback-typed parameter value points at.
fn function_value(mem: *const c_void) -> Option<usize> {
    // SAFETY: for function-pointer parameters `mem` points at one pointer value (API contract).
    (!mem.is_null()).then(|| unsafe { (mem as *const usize).read_unaligned() })
}

impl DeviceObject {
    fn address(&self) -> usize {
        self as *const DeviceObject as usize
    }

    /// The internal handle for an object argument: the SDK device pointer means the device.
    fn handle_of(&self, object: ANARIObject) -> usize {
        if object as usize == self.address() {
            self.device.handle
        } else {
            object as usize
        }
    }

    fn status(&self) -> std::sync::RwLockWriteGuard<'_, StatusCallback> {
        self.status.write().unwrap_or_else(|e| e.into_inner())
    }

    fn frame_callbacks(&self) -> MutexGuard<'_, HashMap<usize, FrameCallback>> {
        self.frame_callbacks
            .lock()
            .unwrap_or_else(|e| e.into_inner())
    }

    fn is_frame(&self, handle: usize) -> bool {
        self.device
            .lookup(handle)
            .is_some_and(|o| o.kind == ANARI_FRAME)
    }

    /// Marks the device dead once (its threads are joined and its objects freed).
    fn mark_dead(&self) {
        if self.alive.swap(false, Ordering::AcqRel) {
            self.library_devices.fetch_sub(1, Ordering::AcqRel);
        }
    }

    fn new_object(
        &self,
        function: &'static str,
        kind: ANARIDataType,
        subtype: Option<*const c_char>,
    ) -> ANARIObject {
        let subtype = match subtype {
            Some(pointer) => match string_arg(&self.device, function, "type", pointer) {
                Some(s) => s,
                None => return std::ptr::null_mut(),
            },
            None => String::new(),
        };
        self.device.new_object(function, kind, &subtype) as ANARIObject
    }

    /// Callback parameters of the device and of frames stay here; the internal device gets this
    /// module's forwarders instead, which pass the SDK device pointer on. True when handled.
    ///
    /// A callback's `mem` points at the function pointer, but an ANARI_VOID_POINTER value is
    /// passed by value (`mem` is the user pointer itself, NULL included), as the ANARI
    /// specification and the SDK's C++ `anari::setParameter` have it.
    fn stage_callback_parameter(
        &self,
        function: &str,
        handle: usize,
        name: &str,
        data_type: ANARIDataType,
        mem: *const c_void,
    ) -> bool {
        if handle == self.device.handle {
            match (name, data_type) {
                ("statusCallback", ANARI_STATUS_CALLBACK) => {
                    let Some(address) = function_value(mem) else {
                        return false;
                    };
                    self.status().staged_function = Some(address)
                }
                ("statusCallbackUserData", ANARI_VOID_POINTER) => {
                    self.status().staged_user_data = Some(mem as usize)
                }
                _ => return false,
            }
            return true;
        }
        let is_function = match (name, data_type) {
            ("frameCompletionCallback", ANARI_FRAME_COMPLETION_CALLBACK) => true,
            ("frameCompletionCallbackUserData", ANARI_VOID_POINTER) => false,
            _ => return false,
        };
        if !self.is_frame(handle) {
            return false;
        }
        let value = if is_function {
            let Some(address) = function_value(mem) else {
                return false;
            };
            address
        } else {
            mem as usize
        };
        {
            let mut callbacks = self.frame_callbacks();
            let entry = callbacks.entry(handle).or_default();
            if is_function {
                entry.staged_function = Some(value);
            } else {
                entry.staged_user_data = Some(value);
            }
        }
        self.device.set_parameter(
            function,
            handle,
            "frameCompletionCallback",
            ANARI_FRAME_COMPLETION_CALLBACK,
            IncomingValue::Pointer(forward_frame_completion as *const () as usize),
        );
        self.device.set_parameter(
            function,
            handle,
            "frameCompletionCallbackUserData",
            ANARI_VOID_POINTER,
            IncomingValue::Pointer(self.address()),
        );
        true
    }

    /// Unsets a callback parameter kept here. True when handled.
    fn unstage_callback_parameter(&self, handle: usize, name: &str) -> bool {
        if handle == self.device.handle {
            match name {
                "statusCallback" => self.status().staged_function = None,
                "statusCallbackUserData" => self.status().staged_user_data = None,
                _ => return false,
            }
            return true;
        }
        let mut callbacks = self.frame_callbacks();
        let Some(entry) = callbacks.get_mut(&handle) else {
            return false;
        };
        match name {
            // The forwarder stays set on the frame; with no committed callback it does nothing.
            "frameCompletionCallback" => entry.staged_function = None,
            "frameCompletionCallbackUserData" => entry.staged_user_data = None,
            _ => return false,
        }
        true
    }

    fn set_parameter(
        &self,
        function: &'static str,
        object: ANARIObject,
        name: *const c_char,
        data_type: ANARIDataType,
        mem: *const c_void,
    ) {
        let Some(name) = string_arg(&self.device, function, "name", name) else {
            return;
        };
        let handle = self.handle_of(object);
        if self.stage_callback_parameter(function, handle, &name, data_type, mem) {
            return;
        }
        let described = format!("{function}('{name}')");
        // SAFETY: the application passes `mem` matching `data_type`, per the API contract.
        let Some(value) = (unsafe { incoming_value(&self.device, &described, data_type, mem) })
        else {
            return;
        };
        self.device
            .set_parameter(function, handle, &name, data_type, value);
    }

    fn unset_parameter(&self, object: ANARIObject, name: *const c_char) {
        const F: &str = "anariUnsetParameter";
        let Some(name) = string_arg(&self.device, F, "name", name) else {
            return;
        };
        let handle = self.handle_of(object);
        if !self.unstage_callback_parameter(handle, &name) {
            self.device.unset_parameter(F, handle, &name);
        }
    }

    fn unset_all_parameters(&self, object: ANARIObject) {
        const F: &str = "anariUnsetAllParameters";
        let handle = self.handle_of(object);
        if handle == self.device.handle {
            let mut status = self.status();
            status.staged_function = None;
            status.staged_user_data = None;
        } else if let Some(entry) = self.frame_callbacks().get_mut(&handle) {
            entry.staged_function = None;
            entry.staged_user_data = None;
        }
        self.device.unset_all_parameters(F, handle);
    }

    fn commit(&self, function: &str, object: ANARIObject) {
        let handle = self.handle_of(object);
        self.device.commit(function, handle);
        if handle == self.device.handle {
            let mut status = self.status();
            status.function = match status.staged_function {
                // SAFETY: the application set this address as an ANARIStatusCallback; 0 is None.
                Some(address) => unsafe {
                    std::mem::transmute::<usize, ANARIStatusCallback>(address)
                },
                None => self.default_callback,
            };
            status.user_data = status
                .staged_user_data
                .unwrap_or(self.default_user_data as usize);
        } else if let Some(entry) = self.frame_callbacks().get_mut(&handle) {
            entry.function = entry.staged_function.unwrap_or(0);
            entry.user_data = entry.staged_user_data.unwrap_or(0);
        }
    }

    fn map_parameter_array(
        &self,
        function: &'static str,
        object: ANARIObject,
        name: *const c_char,
        data_type: ANARIDataType,
        dims: [u64; 3],
        element_stride: *mut u64,
    ) -> *mut c_void {
        let Some(name) = string_arg(&self.device, function, "name", name) else {
            return std::ptr::null_mut();
        };
        let handle = self.handle_of(object);
        match self
            .device
            .map_parameter_array(function, handle, &name, data_type, dims)
        {
            Some((pointer, stride)) => {
                if !element_stride.is_null() {
                    // SAFETY: the application passes a writable uint64_t or NULL.
                    unsafe { element_stride.write(stride) };
                }
                pointer
            }
            None => std::ptr::null_mut(),
        }
    }

    /// Drops one reference; true when it was the device's last (the device is then shut down).
    fn release(&self, object: ANARIObject) -> bool {
        let handle = self.handle_of(object);
        let died = self.device.release("anariRelease", handle);
        if died {
            self.mark_dead();
        }
        died
    }

    /// Drops every reference the device still has (a C++ `delete` of the device).
    fn shut_down(&self) {
        while self.alive.load(Ordering::Acquire) {
            if self.device.release("anariRelease", self.device.handle) {
                self.mark_dead();
            }
        }
    }
}

/// The internal device's status callback: passes messages on to the application's callback with
/// the SDK device pointer as the device (and as the source, for messages about the device).
unsafe extern "C" fn forward_status(
    user_data: *const c_void,
    device: *mut c_void,
    source: *mut c_void,
    source_type: ANARIDataType,
    severity: ANARIStatusSeverity,
    code: ANARIStatusCode,
    message: *const c_char,
) {
    // SAFETY: the user data is the DeviceObject the internal device was created for; it is freed
    // only after the device has shut down, and a shut-down device reports nothing.
    let object = unsafe { &*(user_data as *const DeviceObject) };
    let sdk_device = user_data as *mut c_void;
    let source = if source == device { sdk_device } else { source };
    let (function, app_user_data) = {
        let status = object.status.read().unwrap_or_else(|e| e.into_inner());
        (status.function, status.user_data)
    };
    match function {
        // SAFETY: the application registered this callback with this signature; the message
        // stays valid for the duration of the call.
        Some(function) => unsafe {
            function(
                app_user_data as *const c_void,
                sdk_device,
                source,
                source_type,
                severity,
                code,
                message,
            )
        },
        None if severity <= ANARI_SEVERITY_WARNING => {
            // SAFETY: the internal device passes a NUL-terminated message.
            let text = unsafe { CStr::from_ptr(message) }.to_string_lossy();
            // No callback: stderr, like the internal device; a failed write has nowhere to go.
            let _ = writeln!(
                std::io::stderr(),
                "[cavetrace] {}: {text}",
                severity_name(severity)
            );
        }
        None => {}
    }
}

/// The frames' completion callback: calls the application's committed callback for `frame`
/// with the SDK device pointer (the user data) as the device.
unsafe extern "C" fn forward_frame_completion(
    user_data: *const c_void,
    _device: *mut c_void,
    frame: *mut c_void,
) {
    // SAFETY: the user data is the DeviceObject that set this forwarder; render threads are
    // joined before the object is freed.
    let object = unsafe { &*(user_data as *const DeviceObject) };
    let committed = object
        .frame_callbacks()
        .get(&(frame as usize))
        .map(|c| (c.function, c.user_data));
    let Some((function, app_user_data)) = committed else {
        return;
    };
    // SAFETY: the application set this address as an ANARIFrameCompletionCallback; 0 is None.
    let callback = unsafe { std::mem::transmute::<usize, ANARIFrameCompletionCallback>(function) };
    if let Some(callback) = callback {
        // SAFETY: called with the signature the application registered.
        unsafe {
            callback(
                app_user_data as *const c_void,
                user_data as *mut c_void,
                frame,
            )
        };
    }
}

// ----- slots, in vtable order -------------------------------------------------------------------

#[allow(clippy::too_many_arguments)]
fn new_array(
    this: *mut DeviceObject,
    function: &'static str,
    app_memory: *const c_void,
    deleter: ANARIMemoryDeleter,
    user_data: *const c_void,
    data_type: ANARIDataType,
    dims: [u64; 3],
) -> ANARIObject {
    with_device(this, function, std::ptr::null_mut(), |device| {
        device
            .device
            .new_array(function, app_memory, deleter, user_data, data_type, dims)
            as ANARIObject
    })
}

extern "C" fn new_array_1d(
    this: *mut DeviceObject,
    app_memory: *const c_void,
    deleter: ANARIMemoryDeleter,
    user_data: *const c_void,
    data_type: ANARIDataType,
    num_elements1: u64,
) -> ANARIArray1D {
    let dims = [num_elements1, 1, 1];
    new_array(
        this,
        "anariNewArray1D",
        app_memory,
        deleter,
        user_data,
        data_type,
        dims,
    )
}

extern "C" fn new_array_2d(
    this: *mut DeviceObject,
    app_memory: *const c_void,
    deleter: ANARIMemoryDeleter,
    user_data: *const c_void,
    data_type: ANARIDataType,
    num_elements1: u64,
    num_elements2: u64,
) -> ANARIArray2D {
    let dims = [num_elements1, num_elements2, 1];
    new_array(
        this,
        "anariNewArray2D",
        app_memory,
        deleter,
        user_data,
        data_type,
        dims,
    )
}

#[allow(clippy::too_many_arguments)]
extern "C" fn new_array_3d(
    this: *mut DeviceObject,
    app_memory: *const c_void,
    deleter: ANARIMemoryDeleter,
    user_data: *const c_void,
    data_type: ANARIDataType,
    num_elements1: u64,
    num_elements2: u64,
    num_elements3: u64,
) -> ANARIArray3D {
    let dims = [num_elements1, num_elements2, num_elements3];
    new_array(
        this,
        "anariNewArray3D",
        app_memory,
        deleter,
        user_data,
        data_type,
        dims,
    )
}

macro_rules! new_with_subtype {
    ($slot:ident, $function:literal, $kind:expr) => {
        extern "C" fn $slot(this: *mut DeviceObject, subtype: *const c_char) -> ANARIObject {
            with_device(this, $function, std::ptr::null_mut(), |device| {
                device.new_object($function, $kind, Some(subtype))
            })
        }
    };
}

macro_rules! new_without_subtype {
    ($slot:ident, $function:literal, $kind:expr) => {
        extern "C" fn $slot(this: *mut DeviceObject) -> ANARIObject {
            with_device(this, $function, std::ptr::null_mut(), |device| {
                device.new_object($function, $kind, None)
            })
        }
    };
}

new_with_subtype!(new_geometry, "anariNewGeometry", ANARI_GEOMETRY);
new_with_subtype!(new_material, "anariNewMaterial", ANARI_MATERIAL);
new_with_subtype!(new_sampler, "anariNewSampler", ANARI_SAMPLER);
new_without_subtype!(new_surface, "anariNewSurface", ANARI_SURFACE);
new_with_subtype!(
    new_spatial_field,
    "anariNewSpatialField",
    ANARI_SPATIAL_FIELD
);
new_with_subtype!(new_volume, "anariNewVolume", ANARI_VOLUME);
new_with_subtype!(new_light, "anariNewLight", ANARI_LIGHT);
new_without_subtype!(new_group, "anariNewGroup", ANARI_GROUP);
new_with_subtype!(new_instance, "anariNewInstance", ANARI_INSTANCE);
new_without_subtype!(new_world, "anariNewWorld", ANARI_WORLD);
new_with_subtype!(new_camera, "anariNewCamera", ANARI_CAMERA);
new_with_subtype!(new_renderer, "anariNewRenderer", ANARI_RENDERER);
new_without_subtype!(new_frame, "anariNewFrame", ANARI_FRAME);

extern "C" fn set_parameter(
    this: *mut DeviceObject,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    mem: *const c_void,
) {
    const F: &str = "anariSetParameter";
    with_device(this, F, (), |device| {
        device.set_parameter(F, object, name, data_type, mem)
    })
}

extern "C" fn unset_parameter(this: *mut DeviceObject, object: ANARIObject, name: *const c_char) {
    with_device(this, "anariUnsetParameter", (), |device| {
        device.unset_parameter(object, name)
    })
}

extern "C" fn unset_all_parameters(this: *mut DeviceObject, object: ANARIObject) {
    with_device(this, "anariUnsetAllParameters", (), |device| {
        device.unset_all_parameters(object)
    })
}

extern "C" fn map_parameter_array_1d(
    this: *mut DeviceObject,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    num_elements1: u64,
    element_stride: *mut u64,
) -> *mut c_void {
    const F: &str = "anariMapParameterArray1D";
    with_device(this, F, std::ptr::null_mut(), |device| {
        let dims = [num_elements1, 1, 1];
        device.map_parameter_array(F, object, name, data_type, dims, element_stride)
    })
}

extern "C" fn map_parameter_array_2d(
    this: *mut DeviceObject,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    num_elements1: u64,
    num_elements2: u64,
    element_stride: *mut u64,
) -> *mut c_void {
    const F: &str = "anariMapParameterArray2D";
    with_device(this, F, std::ptr::null_mut(), |device| {
        let dims = [num_elements1, num_elements2, 1];
        device.map_parameter_array(F, object, name, data_type, dims, element_stride)
    })
}

#[allow(clippy::too_many_arguments)]
extern "C" fn map_parameter_array_3d(
    this: *mut DeviceObject,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    num_elements1: u64,
    num_elements2: u64,
    num_elements3: u64,
    element_stride: *mut u64,
) -> *mut c_void {
    const F: &str = "anariMapParameterArray3D";
    with_device(this, F, std::ptr::null_mut(), |device| {
        let dims = [num_elements1, num_elements2, num_elements3];
        device.map_parameter_array(F, object, name, data_type, dims, element_stride)
    })
}

extern "C" fn unmap_parameter_array(
    this: *mut DeviceObject,
    object: ANARIObject,
    name: *const c_char,
) {
    const F: &str = "anariUnmapParameterArray";
    with_device(this, F, (), |device| {
        if let Some(name) = string_arg(&device.device, F, "name", name) {
            let handle = device.handle_of(object);
            device.device.unmap_parameter_array(F, handle, &name);
        }
    })
}

extern "C" fn commit_parameters(this: *mut DeviceObject, object: ANARIObject) {
    const F: &str = "anariCommitParameters";
    with_device(this, F, (), |device| device.commit(F, object))
}

/// `anariRelease`; the device's own last release frees the device object as well.
extern "C" fn release(this: *mut DeviceObject, object: ANARIObject) {
    let died = with_device(this, "anariRelease", false, |device| device.release(object));
    if died {
        free_device(this);
    }
}

extern "C" fn retain(this: *mut DeviceObject, object: ANARIObject) {
    const F: &str = "anariRetain";
    with_device(this, F, (), |device| {
        device.device.retain(F, device.handle_of(object))
    })
}

extern "C" fn map_array(this: *mut DeviceObject, array: ANARIArray) -> *mut c_void {
    const F: &str = "anariMapArray";
    with_device(this, F, std::ptr::null_mut(), |device| {
        device.device.map_array(F, array as usize)
    })
}

extern "C" fn unmap_array(this: *mut DeviceObject, array: ANARIArray) {
    const F: &str = "anariUnmapArray";
    with_device(this, F, (), |device| {
        device.device.unmap_array(F, array as usize)
    })
}

extern "C" fn get_property(
    this: *mut DeviceObject,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    mem: *mut c_void,
    size: u64,
    mask: ANARIWaitMask,
) -> c_int {
    with_device(this, "anariGetProperty", 0, |device| {
        let handle = device.handle_of(object);
        introspect::get_property(&device.device, handle, name, data_type, mem, size, mask)
    })
}

extern "C" fn get_object_subtypes(
    this: *mut DeviceObject,
    object_type: ANARIDataType,
) -> *const *const c_char {
    with_device(this, "anariGetObjectSubtypes", std::ptr::null(), |_| {
        let names = KINDS.subtype_names(object_type);
        cached(format!("subtypes {object_type}"), || {
            leak_string_list(&names)
        }) as _
    })
}

extern "C" fn get_object_info(
    this: *mut DeviceObject,
    object_type: ANARIDataType,
    object_subtype: *const c_char,
    info_name: *const c_char,
    info_type: ANARIDataType,
) -> *const c_void {
    const F: &str = "anariGetObjectInfo";
    with_device(this, F, std::ptr::null(), |device| {
        let Some(info) = string_arg(&device.device, F, "infoName", info_name) else {
            return std::ptr::null();
        };
        let subtype = plain_string(object_subtype);
        object_info(object_type, subtype.as_deref(), &info, info_type) as _
    })
}

extern "C" fn get_parameter_info(
    this: *mut DeviceObject,
    object_type: ANARIDataType,
    object_subtype: *const c_char,
    parameter_name: *const c_char,
    parameter_type: ANARIDataType,
    info_name: *const c_char,
    info_type: ANARIDataType,
) -> *const c_void {
    with_device(this, "anariGetParameterInfo", std::ptr::null(), |device| {
        introspect::get_parameter_info(
            &device.device,
            object_type,
            object_subtype,
            parameter_name,
            parameter_type,
            info_name,
            info_type,
        )
    })
}

extern "C" fn frame_buffer_map(
    this: *mut DeviceObject,
    frame: ANARIFrame,
    channel: *const c_char,
    width: *mut u32,
    height: *mut u32,
    pixel_type: *mut ANARIDataType,
) -> *const c_void {
    let mapped = with_device(this, "anariMapFrame", None, |device| {
        capi_frame::map_frame(&device.device, frame, channel)
    });
    let (pointer, w, h, t) = mapped.unwrap_or((std::ptr::null(), 0, 0, ANARI_UNKNOWN));
    capi_frame::write_map_outputs(width, height, pixel_type, (w, h, t));
    pointer
}

extern "C" fn frame_buffer_unmap(
    this: *mut DeviceObject,
    frame: ANARIFrame,
    channel: *const c_char,
) {
    with_device(this, "anariUnmapFrame", (), |device| {
        capi_frame::unmap_frame(&device.device, frame, channel)
    })
}

/// Starts rendering and returns at once; the work runs on the device's own threads.
extern "C" fn render_frame(this: *mut DeviceObject, frame: ANARIFrame) {
    with_device(this, "anariRenderFrame", (), |device| {
        capi_frame::render_frame(&device.device, frame)
    })
}

/// ANARI_NO_WAIT polls (1 when done), ANARI_WAIT blocks until the render is done.
extern "C" fn frame_ready(
    this: *mut DeviceObject,
    frame: ANARIFrame,
    mask: ANARIWaitMask,
) -> c_int {
    with_device(this, "anariFrameReady", 0, |device| {
        capi_frame::frame_ready(&device.device, frame, mask)
    })
}

extern "C" fn discard_frame(this: *mut DeviceObject, frame: ANARIFrame) {
    with_device(this, "anariDiscardFrame", (), |device| {
        capi_frame::discard_frame(&device.device, frame)
    })
}

extern "C" fn new_object(
    this: *mut DeviceObject,
    object_type: *const c_char,
    subtype: *const c_char,
) -> ANARIObject {
    const F: &str = "anariNewObject";
    with_device(this, F, std::ptr::null_mut(), |device| {
        let Some(type_name) = string_arg(&device.device, F, "objectType", object_type) else {
            return std::ptr::null_mut();
        };
        let Some(kind) = kind_from_name(&type_name) else {
            device.device.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                None,
                format!("{F}: unknown object type '{type_name}'; no object was created"),
            );
            return std::ptr::null_mut();
        };
        let subtype = plain_string(subtype).unwrap_or_default();
        device.device.new_object(F, kind, &subtype) as ANARIObject
    })
}

extern "C" fn get_proc_address(this: *mut DeviceObject, name: *const c_char) -> ANARIProcAddress {
    const F: &str = "anariDeviceGetProcAddress";
    with_device(this, F, None, |device| {
        let name = string_arg(&device.device, F, "name", name)?;
        crate::capi::extension::lookup(&name)
    })
}

/// Slot 39, `~DeviceImpl()` (complete object): shuts the device down if the application has not
/// released it, then drops cavetrace's state.
extern "C" fn destroy(this: *mut DeviceObject) {
    with_device(this, "~DeviceImpl", (), |device| device.shut_down());
    if !this.is_null() {
        // SAFETY: `this` is a live device object whose device has shut down; its fields are
        // dropped once, here, and never read again.
        unsafe { std::ptr::drop_in_place(this) };
    }
}

/// Slot 40, deleting `~DeviceImpl()`.
extern "C" fn destroy_and_free(this: *mut DeviceObject) {
    free_device(this);
}

fn free_device(this: *mut DeviceObject) {
    destroy(this);
    // SAFETY: `this` came from `allocate` (malloc) and is freed exactly once.
    unsafe { libc::free(this as *mut c_void) };
}
