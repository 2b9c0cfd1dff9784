//! The library object (`anari::LibraryImpl`): the SDK front end's handle for a loaded library.

use std::ffi::{c_char, c_void};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::capi::cache::{cached, leak_string_list};
use crate::capi::plain_string;
use crate::capi::types::{ANARIDevice, ANARILibrary, ANARIParameterValue};
use crate::device::catalog::Kinds;
use crate::device::datatype::ANARI_LIBRARY;
use crate::device::status::*;
use crate::kinds::KINDS;
use crate::sdk::device::{self, DeviceObject};
use crate::sdk::{VirtualTable, allocate, panic_text};

/// Device subtypes this library creates (the same as `anariNewDevice` of libcavetrace accepts).
use crate::capi::library::DEVICE_SUBTYPES;

/// Begins with the layout of `anari::LibraryImpl` (32 bytes); the front end reads `dl_handle`
/// (byte offset 8) to dlclose the library after deleting the object (SDK ≥ 0.16).
#[repr(C)]
pub(super) struct LibraryObject {
    vtable: *const LibrarySlots,
    dl_handle: *mut c_void,
    default_callback: ANARIStatusCallback,
    default_user_data: *const c_void,
    /// Devices created by this library and not yet destroyed.
    live_devices: Arc<AtomicUsize>,
}

const _: () = assert!(std::mem::offset_of!(LibraryObject, dl_handle) == 8);
const _: () = assert!(std::mem::offset_of!(LibraryObject, default_callback) == 16);
const _: () = assert!(std::mem::offset_of!(LibraryObject, default_user_data) == 24);
const _: () = assert!(std::mem::offset_of!(LibraryObject, live_devices) == 32);

/// `anari::LibraryImpl`'s virtual functions in declaration order (Itanium: the complete-object
/// destructor, then the deleting destructor, take the destructor's place).
#[repr(C)]
struct LibrarySlots {
    destroy: extern "C" fn(*mut LibraryObject),
    destroy_and_free: extern "C" fn(*mut LibraryObject),
    new_device: extern "C" fn(*mut LibraryObject, *const c_char) -> ANARIDevice,
    new_initialized_device:
        extern "C" fn(*mut LibraryObject, *const c_char, *const ANARIParameterValue) -> ANARIDevice,
    get_device_extensions: extern "C" fn(*mut LibraryObject, *const c_char) -> *const *const c_char,
    get_device_subtypes: extern "C" fn(*mut LibraryObject) -> *const *const c_char,
    load_module: extern "C" fn(*mut LibraryObject, *const c_char),
    unload_module: extern "C" fn(*mut LibraryObject, *const c_char),
}

static LIBRARY_VTABLE: VirtualTable<LibrarySlots> = VirtualTable::new(LibrarySlots {
    destroy,
    destroy_and_free,
    new_device,
    new_initialized_device,
    get_device_extensions,
    get_device_subtypes,
    load_module,
    unload_module,
});

/// The entry point `anariLoadLibrary("cavetrace")` of the SDK front end looks up after it has
/// dlopened `libanari_library_cavetrace.so`. `dl_handle` is that dlopen handle; the callback
/// is the application's default status callback. Returns NULL only when out of memory.
///
/// cbindgen:ignore
#[unsafe(no_mangle)]
pub extern "C" fn anari_library_cavetrace_new_library(
    dl_handle: *mut c_void,
    default_callback: ANARIStatusCallback,
    default_user_data: *const c_void,
) -> ANARILibrary {
    let created = catch_unwind(|| {
        let library = allocate::<LibraryObject>();
        if !library.is_null() {
            // SAFETY: `library` is fresh memory of the right size and alignment.
            unsafe {
                library.write(LibraryObject {
                    vtable: &LIBRARY_VTABLE.slots,
                    dl_handle,
                    default_callback,
                    default_user_data,
                    live_devices: Arc::default(),
                })
            };
        }
        library
    });
    match created {
        Ok(library) if !library.is_null() => library as ANARILibrary,
        Ok(_) => {
            report(
                default_callback,
                default_user_data,
                std::ptr::null(),
                ANARI_STATUS_OUT_OF_MEMORY,
                "anariLoadLibrary: out of memory; cavetrace was not loaded".into(),
            );
            std::ptr::null_mut()
        }
        Err(payload) => {
            report(
                default_callback,
                default_user_data,
                std::ptr::null(),
                ANARI_STATUS_UNKNOWN_ERROR,
                format!(
                    "anariLoadLibrary: internal error ({}); cavetrace was not loaded",
                    panic_text(&*payload)
                ),
            );
            std::ptr::null_mut()
        }
    }
}

/// An error for the library's default callback; there is no device yet.
fn report(
    callback: ANARIStatusCallback,
    user_data: *const c_void,
    library: *const LibraryObject,
    code: ANARIStatusCode,
    text: String,
) {
    report_with_severity(
        callback,
        user_data,
        library,
        ANARI_SEVERITY_ERROR,
        code,
        text,
    );
}

fn report_with_severity(
    callback: ANARIStatusCallback,
    user_data: *const c_void,
    library: *const LibraryObject,
    severity: ANARIStatusSeverity,
    code: ANARIStatusCode,
    text: String,
) {
    StatusSink::new(0, callback, user_data as usize).report(&StatusMessage {
        severity,
        code,
        source: Source {
            handle: library as usize,
            kind: ANARI_LIBRARY,
        },
        text,
    });
}

impl LibraryObject {
    fn report(&self, code: ANARIStatusCode, text: String) {
        report(
            self.default_callback,
            self.default_user_data,
            self,
            code,
            text,
        );
    }

    /// Creates a device if `subtype` names one of this library's, else reports and returns NULL.
    fn new_device(&self, function: &str, subtype: *const c_char) -> *mut DeviceObject {
        let requested = plain_string(subtype);
        match requested.as_deref() {
            Some(s) if DEVICE_SUBTYPES.contains(&s) => {
                let device = device::create(
                    self.default_callback,
                    self.default_user_data,
                    Arc::clone(&self.live_devices),
                );
                if device.is_null() {
                    self.report(
                        ANARI_STATUS_OUT_OF_MEMORY,
                        format!("{function}: out of memory; no device was created"),
                    );
                }
                device
            }
            other => {
                self.report(
                    ANARI_STATUS_INVALID_ARGUMENT,
                    format!(
                        "{function}: unknown device subtype {:?} (cavetrace offers: {}); no \
                         device was created",
                        other.unwrap_or("(NULL)"),
                        DEVICE_SUBTYPES.join(", ")
                    ),
                );
                std::ptr::null_mut()
            }
        }
    }
}

/// Runs a slot body on the library behind `this`; a panic becomes an error report and `fallback`.
fn with_library<R>(
    this: *mut LibraryObject,
    function: &'static str,
    fallback: R,
    body: impl FnOnce(&LibraryObject) -> R,
) -> R {
    if this.is_null() {
        eprintln!("[cavetrace] error: {function}: the library handle is NULL");
        return fallback;
    }
    // SAFETY: the front end calls slots only on library objects this module created and has not
    // yet destroyed.
    let library = unsafe { &*this };
    match catch_unwind(AssertUnwindSafe(|| body(library))) {
        Ok(result) => result,
        Err(payload) => {
            library.report(
                ANARI_STATUS_UNKNOWN_ERROR,
                format!(
                    "{function}: internal error ({}); the call had no effect",
                    panic_text(&*payload)
                ),
            );
            fallback
        }
    }
}

/// Slot 0, `~LibraryImpl()` (complete object). Devices still alive stop working once the front
/// end dlcloses the library, so that is reported.
extern "C" fn destroy(this: *mut LibraryObject) {
    with_library(this, "anariUnloadLibrary", (), |library| {
        let live = library.live_devices.load(Ordering::Acquire);
        if live > 0 {
            report_with_severity(
                library.default_callback,
                library.default_user_data,
                library,
                ANARI_SEVERITY_WARNING,
                ANARI_STATUS_INVALID_OPERATION,
                format!(
                    "anariUnloadLibrary: {live} device(s) of this library are still alive; \
                     release them (anariRelease(device, device)) before unloading the library"
                ),
            );
        }
    });
    if !this.is_null() {
        // SAFETY: `this` is a live library object (checked above); its fields are dropped once,
        // here, and never read again.
        unsafe { std::ptr::drop_in_place(&raw mut (*this).live_devices) };
    }
}

/// Slot 1, deleting `~LibraryImpl()`. Never dlcloses: the front end does that afterwards, and
/// unloading from here would unmap the code still running.
extern "C" fn destroy_and_free(this: *mut LibraryObject) {
    destroy(this);
    // SAFETY: `this` came from `allocate` (malloc) and the front end deletes it exactly once.
    unsafe { libc::free(this as *mut c_void) };
}

/// Slot 2, `newDevice(subtype)`.
extern "C" fn new_device(this: *mut LibraryObject, subtype: *const c_char) -> ANARIDevice {
    const F: &str = "anariNewDevice";
    with_library(this, F, std::ptr::null_mut(), |library| {
        library.new_device(F, subtype) as ANARIDevice
    })
}

/// Slot 3, `newInitializedDevice(subtype, parameters)`: a device with a NULL-name-terminated list
/// of device parameters applied and committed.
extern "C" fn new_initialized_device(
    this: *mut LibraryObject,
    subtype: *const c_char,
    parameters: *const ANARIParameterValue,
) -> ANARIDevice {
    const F: &str = "anariNewInitializedDevice";
    with_library(this, F, std::ptr::null_mut(), |library| {
        let device = library.new_device(F, subtype);
        if !device.is_null() {
            device::initialize(device, F, parameters);
        }
        device as ANARIDevice
    })
}

/// Slot 4, `getDeviceExtensions(deviceSubtype)`: NULL for an unknown subtype.
extern "C" fn get_device_extensions(
    this: *mut LibraryObject,
    device_subtype: *const c_char,
) -> *const *const c_char {
    with_library(
        this,
        "anariGetDeviceExtensions",
        std::ptr::null(),
        |_| match plain_string(device_subtype).as_deref() {
            Some(s) if DEVICE_SUBTYPES.contains(&s) => cached("device extensions".into(), || {
                leak_string_list(&KINDS.extensions())
            }) as _,
            _ => std::ptr::null(),
        },
    )
}

/// Slot 5, `getDeviceSubtypes()`.
extern "C" fn get_device_subtypes(this: *mut LibraryObject) -> *const *const c_char {
    with_library(this, "anariGetDeviceSubtypes", std::ptr::null(), |_| {
        cached("device subtypes".into(), || {
            leak_string_list(DEVICE_SUBTYPES)
        }) as _
    })
}

fn report_modules_unsupported(library: &LibraryObject, function: &str, name: *const c_char) {
    let module = plain_string(name).unwrap_or_else(|| "(NULL)".into());
    library.report(
        ANARI_STATUS_INVALID_OPERATION,
        format!("{function}: cavetrace has no loadable modules ('{module}' ignored)"),
    );
}

/// Slot 6, `loadModule(name)`.
extern "C" fn load_module(this: *mut LibraryObject, name: *const c_char) {
    const F: &str = "anariLoadModule";
    with_library(this, F, (), |library| {
        report_modules_unsupported(library, F, name)
    })
}

/// Slot 7, `unloadModule(name)`.
extern "C" fn unload_module(this: *mut LibraryObject, name: *const c_char) {
    const F: &str = "anariUnloadModule";
    with_library(this, F, (), |library| {
        report_modules_unsupported(library, F, name)
    })
}
