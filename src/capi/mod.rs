//! The C boundary: every `extern "C"` function of the ANARI API and nothing else. Functions here
//! check arguments, look handles up, guard against panics and report misuse; the work happens
//! in `crate::device`. No panic ever unwinds into C.

// C entry points receive raw pointers by the API's contract; they cannot be `unsafe fn` (C calls
// them), so each dereference carries its own SAFETY note instead.
#![allow(clippy::not_unsafe_ptr_arg_deref)]

pub mod array;
pub mod cache;
pub mod extension;
pub mod frame;
pub mod image;
pub mod introspect;
pub mod library;
pub mod object;
pub mod offaxis;
pub mod params;
pub mod types;

use std::ffi::{CStr, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;

use crate::device::status::*;
use crate::device::{Device, registry};

/// Runs `body`, turning a panic into an UNKNOWN_ERROR report and `fallback`.
pub(crate) fn guard<R>(
    function: &'static str,
    device: *mut std::ffi::c_void,
    fallback: R,
    body: impl FnOnce() -> R,
) -> R {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(result) => result,
        Err(payload) => {
            let what = panic_text(payload.as_ref());
            let text = format!("{function}: internal error ({what}); the call had no effect");
            match registry::device(device as usize) {
                Some(device) => device.error(ANARI_STATUS_UNKNOWN_ERROR, None, text),
                None => report_without_device(device, ANARI_STATUS_UNKNOWN_ERROR, text),
            }
            fallback
        }
    }
}

/// Reports a problem with a call whose device handle is NULL or dead, so the device's own
/// callback cannot be reached: through the status callback given to anariLoadLibrary when
/// exactly one library is loaded, on stderr otherwise. The message's device and source are the
/// handle the application passed.
pub(crate) fn report_without_device(
    device: *mut std::ffi::c_void,
    code: ANARIStatusCode,
    text: String,
) {
    let (callback, user_data) =
        registry::sole_library().map_or((None, 0), |l| (l.default_callback, l.default_user_data));
    StatusSink::new(device as usize, callback, user_data).report(&StatusMessage {
        severity: ANARI_SEVERITY_ERROR,
        code,
        source: Source {
            handle: device as usize,
            kind: crate::device::datatype::ANARI_DEVICE,
        },
        text,
    });
}

/// The live device behind a handle, or a report through [`report_without_device`].
pub(crate) fn device_of(function: &str, device: *mut std::ffi::c_void) -> Option<Arc<Device>> {
    if device.is_null() {
        report_without_device(
            device,
            ANARI_STATUS_INVALID_ARGUMENT,
            format!(
                "{function}: the device handle is NULL (expected a device from anariNewDevice); \
                 the call has no effect"
            ),
        );
        return None;
    }
    let found = registry::device(device as usize);
    if found.is_none() {
        report_without_device(
            device,
            ANARI_STATUS_INVALID_ARGUMENT,
            format!(
                "{function}: device {device:p} is not a live cavetrace device (never created, \
                 or already released); the call has no effect"
            ),
        );
    }
    found
}

/// Reads a C string argument; NULL and invalid UTF-8 are reported through the device.
pub(crate) fn string_arg(
    device: &Device,
    function: &str,
    argument: &str,
    value: *const c_char,
) -> Option<String> {
    if value.is_null() {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            None,
            format!("{function}: '{argument}' is NULL"),
        );
        return None;
    }
    // SAFETY: the caller passes a NUL-terminated C string, as the ANARI API requires.
    let text = unsafe { CStr::from_ptr(value) };
    match text.to_str() {
        Ok(s) => Some(s.to_owned()),
        Err(_) => {
            device.error(
                ANARI_STATUS_INVALID_ARGUMENT,
                None,
                format!("{function}: '{argument}' is not valid UTF-8"),
            );
            None
        }
    }
}

/// Reads an optional C string without a device to report to.
pub(crate) fn plain_string(value: *const c_char) -> Option<String> {
    if value.is_null() {
        return None;
    }
    // SAFETY: the caller passes a NUL-terminated C string, as the ANARI API requires.
    unsafe { CStr::from_ptr(value) }
        .to_str()
        .ok()
        .map(str::to_owned)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    static SEEN: Mutex<Vec<(i32, String)>> = Mutex::new(Vec::new());

    unsafe extern "C" fn remember(
        _: *const std::ffi::c_void,
        _: *mut std::ffi::c_void,
        _: *mut std::ffi::c_void,
        _: crate::device::datatype::ANARIDataType,
        _: ANARIStatusSeverity,
        code: ANARIStatusCode,
        message: *const c_char,
    ) {
        // SAFETY: the device passes a valid C string.
        let text = unsafe { CStr::from_ptr(message) }
            .to_string_lossy()
            .into_owned();
        SEEN.lock().unwrap().push((code, text));
    }

    #[test]
    fn a_panic_becomes_an_unknown_error_and_the_device_stays_usable() {
        let device = Device::new(&crate::kinds::KINDS, Some(remember), 0);
        let handle = device.handle as *mut std::ffi::c_void;
        let result = guard("anariTest", handle, 7, || -> i32 { panic!("boom") });
        assert_eq!(result, 7);
        let seen = SEEN.lock().unwrap().clone();
        assert_eq!(seen.len(), 1);
        assert_eq!(seen[0].0, ANARI_STATUS_UNKNOWN_ERROR);
        assert!(seen[0].1.contains("anariTest") && seen[0].1.contains("boom"));
        // Still usable afterwards.
        let object = device.new_object("anariNewWorld", crate::device::datatype::ANARI_WORLD, "");
        assert!(device.lookup(object).is_some());
        device.release("anariRelease", device.handle);
    }
}
