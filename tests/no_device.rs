//! Calls on a NULL or released device handle: the device's own status callback cannot be
//! reached, so the report goes to the callback given to anariLoadLibrary when exactly one
//! library is loaded, and to stderr otherwise.
//!
//! Which libraries are loaded is process-wide state, so everything here runs in one test (this
//! file is its own test process).

mod common;

use std::ffi::{c_char, c_void};
use std::sync::Mutex;

use common::*;

/// One message as the callback received it.
#[derive(Debug, Clone)]
struct Seen {
    device: usize,
    source: usize,
    source_type: ANARIDataType,
    severity: ANARIStatusSeverity,
    code: ANARIStatusCode,
    text: String,
}

struct Inbox(Mutex<Vec<Seen>>);

impl Inbox {
    fn take(&self) -> Vec<Seen> {
        std::mem::take(&mut self.0.lock().unwrap())
    }
}

unsafe extern "C" fn remember(
    user: *const c_void,
    device: *mut c_void,
    source: *mut c_void,
    source_type: ANARIDataType,
    severity: ANARIStatusSeverity,
    code: ANARIStatusCode,
    message: *const c_char,
) {
    // SAFETY: the test passes a live Inbox as user data; the device passes a C string.
    let inbox = unsafe { &*(user as *const Inbox) };
    let text = unsafe { std::ffi::CStr::from_ptr(message) }
        .to_string_lossy()
        .into_owned();
    inbox.0.lock().unwrap().push(Seen {
        device: device as usize,
        source: source as usize,
        source_type,
        severity,
        code,
        text,
    });
}

fn load(inbox: &Inbox) -> ANARILibrary {
    let library = anariLoadLibrary(
        c("cavetrace").as_ptr(),
        Some(remember),
        inbox as *const Inbox as *const c_void,
    );
    assert!(!library.is_null());
    library
}

/// Exactly one error naming `function` and every one of `words`, reported for `handle`.
fn assert_one_error(seen: &[Seen], handle: usize, function: &str, words: &[&str]) {
    assert_eq!(seen.len(), 1, "{seen:?}");
    let m = &seen[0];
    assert_eq!(m.severity, ANARI_SEVERITY_ERROR, "{m:?}");
    assert_eq!(m.code, ANARI_STATUS_INVALID_ARGUMENT, "{m:?}");
    assert_eq!((m.device, m.source), (handle, handle), "{m:?}");
    assert_eq!(m.source_type, ANARI_DEVICE, "{m:?}");
    assert!(m.text.starts_with(function), "{m:?}");
    for word in words {
        assert!(m.text.contains(word), "{word:?} missing in {m:?}");
    }
}

#[test]
fn calls_without_a_live_device_report_through_the_only_library() {
    let first = Inbox(Mutex::new(Vec::new()));
    let second = Inbox(Mutex::new(Vec::new()));

    // One library loaded: a NULL device is reported through its callback.
    let library = load(&first);
    anariCommitParameters(std::ptr::null_mut(), std::ptr::null_mut());
    assert_one_error(
        &first.take(),
        0,
        "anariCommitParameters",
        &["device handle is NULL", "anariNewDevice"],
    );
    let null = std::ptr::null_mut();
    assert!(anariNewWorld(null).is_null());
    assert_one_error(&first.take(), 0, "anariNewWorld", &["NULL"]);
    assert!(
        anariMapFrame(
            null,
            null,
            c("channel.color").as_ptr(),
            null.cast(),
            null.cast(),
            null.cast()
        )
        .is_null()
    );
    assert_one_error(&first.take(), 0, "anariMapFrame", &["NULL"]);

    // A released device: reported with the dead handle as device and source.
    let device = anariNewDevice(library, c("default").as_ptr());
    assert!(!device.is_null());
    let world = anariNewWorld(device);
    anariRelease(device, world);
    anariRelease(device, device);
    assert!(first.take().is_empty());
    anariRenderFrame(device, world);
    assert_one_error(
        &first.take(),
        device as usize,
        "anariRenderFrame",
        &["not a live cavetrace device", "already released"],
    );
    anariRelease(device, device);
    assert_one_error(
        &first.take(),
        device as usize,
        "anariRelease",
        &["not a live"],
    );

    // Two libraries: which one the application meant is unknown, so neither callback hears it
    // (the report goes to stderr).
    let other = load(&second);
    anariCommitParameters(device, device);
    assert!(first.take().is_empty());
    assert!(second.take().is_empty());

    // Back to one: the remaining library's callback.
    anariUnloadLibrary(library);
    anariRetain(std::ptr::null_mut(), std::ptr::null_mut());
    assert!(first.take().is_empty());
    assert_one_error(&second.take(), 0, "anariRetain", &["NULL"]);
    anariUnloadLibrary(other);

    // No library at all: stderr only, and nothing breaks.
    anariCommitParameters(std::ptr::null_mut(), std::ptr::null_mut());
    assert!(first.take().is_empty() && second.take().is_empty());
}
