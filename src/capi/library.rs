//! Libraries and devices: anariLoadLibrary … anariNewDevice, device subtypes and extensions.

use std::ffi::{c_char, c_void};

use crate::capi::cache::{cached, leak_string_list};
use crate::capi::types::*;
use crate::capi::{guard, plain_string};
use crate::device::Device;
use crate::device::catalog::Kinds;
use crate::device::datatype::*;
use crate::device::registry::{self, LibraryRecord};
use crate::device::status::*;
use crate::kinds::KINDS;

/// Names under which this library answers anariLoadLibrary, and its device subtypes.
const LIBRARY_NAMES: &[&str] = &["cavetrace", "default"];
pub(crate) const DEVICE_SUBTYPES: &[&str] = &["default", "cavetrace"];

fn report_without_device(
    callback: ANARIStatusCallback,
    user_data: *const c_void,
    source: usize,
    code: ANARIStatusCode,
    text: String,
) {
    let sink = StatusSink::new(0, callback, user_data as usize);
    sink.report(&StatusMessage {
        severity: ANARI_SEVERITY_ERROR,
        code,
        source: Source {
            handle: source,
            kind: ANARI_LIBRARY,
        },
        text,
    });
}

/// Loads the library. "cavetrace" and "default" name this library; "environment" reads
/// `ANARI_LIBRARY`, which must name it too. Anything else returns NULL and says why.
#[unsafe(no_mangle)]
pub extern "C" fn anariLoadLibrary(
    name: *const c_char,
    status_callback: ANARIStatusCallback,
    status_callback_user_data: *const c_void,
) -> ANARILibrary {
    guard(
        "anariLoadLibrary",
        std::ptr::null_mut(),
        std::ptr::null_mut(),
        || {
            let fail = |text: String| {
                report_without_device(
                    status_callback,
                    status_callback_user_data,
                    0,
                    ANARI_STATUS_INVALID_ARGUMENT,
                    format!("anariLoadLibrary: {text}; no library was loaded"),
                );
                std::ptr::null_mut()
            };
            let Some(requested) = plain_string(name) else {
                return fail("the library name is NULL or not UTF-8".into());
            };
            let resolved = if requested == "environment" {
                match std::env::var("ANARI_LIBRARY") {
                    Ok(value) => value,
                    Err(_) => {
                        return fail(
                            "\"environment\" was requested but ANARI_LIBRARY is not set".into(),
                        );
                    }
                }
            } else {
                requested.clone()
            };
            if !LIBRARY_NAMES.contains(&resolved.as_str()) {
                return fail(format!(
                    "this is the cavetrace library; it cannot load '{resolved}' (accepted names: \
                 cavetrace, default, environment with ANARI_LIBRARY=cavetrace)"
                ));
            }
            registry::add_library(LibraryRecord {
                default_callback: status_callback,
                default_user_data: status_callback_user_data as usize,
            }) as ANARILibrary
        },
    )
}

#[unsafe(no_mangle)]
pub extern "C" fn anariUnloadLibrary(library: ANARILibrary) {
    guard("anariUnloadLibrary", std::ptr::null_mut(), (), || {
        if !registry::remove_library(library as usize) {
            eprintln!(
                "[cavetrace] error: anariUnloadLibrary: {library:p} is not a loaded cavetrace library"
            );
        }
    })
}

fn report_modules_unsupported(function: &str, library: ANARILibrary, name: *const c_char) {
    let module = plain_string(name).unwrap_or_else(|| "(NULL)".into());
    let text = format!("{function}: cavetrace has no loadable modules ('{module}' ignored)");
    match registry::library(library as usize) {
        Some(record) => report_without_device(
            record.default_callback,
            record.default_user_data as *const c_void,
            library as usize,
            ANARI_STATUS_INVALID_OPERATION,
            text,
        ),
        None => eprintln!("[cavetrace] error: {text}; {library:p} is not a loaded library"),
    }
}

#[unsafe(no_mangle)]
pub extern "C" fn anariLoadModule(library: ANARILibrary, name: *const c_char) {
    guard("anariLoadModule", std::ptr::null_mut(), (), || {
        report_modules_unsupported("anariLoadModule", library, name)
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariUnloadModule(library: ANARILibrary, name: *const c_char) {
    guard("anariUnloadModule", std::ptr::null_mut(), (), || {
        report_modules_unsupported("anariUnloadModule", library, name)
    })
}

/// Creates a device ("default" or "cavetrace").
#[unsafe(no_mangle)]
pub extern "C" fn anariNewDevice(library: ANARILibrary, subtype: *const c_char) -> ANARIDevice {
    guard(
        "anariNewDevice",
        std::ptr::null_mut(),
        std::ptr::null_mut(),
        || {
            new_device("anariNewDevice", library, subtype)
                .map_or(std::ptr::null_mut(), |d| d.handle as ANARIDevice)
        },
    )
}

fn new_device(
    function: &str,
    library: ANARILibrary,
    subtype: *const c_char,
) -> Option<std::sync::Arc<Device>> {
    let Some(record) = registry::library(library as usize) else {
        eprintln!("[cavetrace] error: {function}: {library:p} is not a loaded cavetrace library");
        return None;
    };
    let requested = plain_string(subtype);
    match requested.as_deref() {
        Some(s) if DEVICE_SUBTYPES.contains(&s) => Some(Device::new(
            &KINDS,
            record.default_callback,
            record.default_user_data,
        )),
        other => {
            report_without_device(
                record.default_callback,
                record.default_user_data as *const c_void,
                library as usize,
                ANARI_STATUS_INVALID_ARGUMENT,
                format!(
                    "{function}: unknown device subtype {:?} (cavetrace offers: default, \
                     cavetrace); no device was created",
                    other.unwrap_or("(NULL)")
                ),
            );
            None
        }
    }
}

/// Creates a device and applies a NULL-terminated list of device parameters, then commits.
#[unsafe(no_mangle)]
pub extern "C" fn anariNewInitializedDevice(
    library: ANARILibrary,
    subtype: *const c_char,
    initializers: *const ANARIParameterValue,
) -> ANARIDevice {
    const F: &str = "anariNewInitializedDevice";
    guard(F, std::ptr::null_mut(), std::ptr::null_mut(), || {
        let Some(device) = new_device(F, library, subtype) else {
            return std::ptr::null_mut();
        };
        let mut entry = initializers;
        while !entry.is_null() {
            // SAFETY: the application passes an array of ANARIParameterValue ended by an entry
            // whose name is NULL.
            let value = unsafe { &*entry };
            if value.name.is_null() {
                break;
            }
            if let Some(name) = plain_string(value.name) {
                // SAFETY: value.value points at data of value.data_type, per the API.
                if let Some(incoming) = unsafe {
                    crate::capi::params::incoming_value(&device, F, value.data_type, value.value)
                } {
                    device.set_parameter(F, device.handle, &name, value.data_type, incoming);
                }
            }
            // SAFETY: stays within the application's array until its terminating entry.
            entry = unsafe { entry.add(1) };
        }
        device.commit(F, device.handle);
        device.handle as ANARIDevice
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariGetDeviceSubtypes(library: ANARILibrary) -> *mut *const c_char {
    guard(
        "anariGetDeviceSubtypes",
        std::ptr::null_mut(),
        std::ptr::null_mut(),
        || {
            if registry::library(library as usize).is_none() {
                eprintln!(
                    "[cavetrace] error: anariGetDeviceSubtypes: {library:p} is not a loaded library"
                );
                return std::ptr::null_mut();
            }
            cached("device subtypes".into(), || {
                leak_string_list(DEVICE_SUBTYPES)
            }) as _
        },
    )
}

#[unsafe(no_mangle)]
pub extern "C" fn anariGetDeviceExtensions(
    library: ANARILibrary,
    device_subtype: *const c_char,
) -> *mut *const c_char {
    guard(
        "anariGetDeviceExtensions",
        std::ptr::null_mut(),
        std::ptr::null_mut(),
        || {
            if registry::library(library as usize).is_none() {
                eprintln!(
                    "[cavetrace] error: anariGetDeviceExtensions: {library:p} is not a loaded library"
                );
                return std::ptr::null_mut();
            }
            match plain_string(device_subtype).as_deref() {
                Some(s) if DEVICE_SUBTYPES.contains(&s) => {
                    cached("device extensions".into(), || {
                        leak_string_list(&KINDS.extensions())
                    }) as _
                }
                _ => std::ptr::null_mut(),
            }
        },
    )
}
