//! Status codes, severities and the status callback that reports them to the application.

use std::ffi::{CString, c_void};
use std::os::raw::{c_char, c_int, c_uint};
use std::sync::RwLock;

use crate::device::datatype::ANARIDataType;

pub type ANARIStatusCode = c_int;
pub type ANARIStatusSeverity = c_int;
pub type ANARILogLevel = c_int;
pub type ANARIWaitMask = c_uint;

pub const ANARI_STATUS_NO_ERROR: ANARIStatusCode = 0;
pub const ANARI_STATUS_UNKNOWN_ERROR: ANARIStatusCode = 1;
pub const ANARI_STATUS_INVALID_ARGUMENT: ANARIStatusCode = 2;
pub const ANARI_STATUS_INVALID_OPERATION: ANARIStatusCode = 3;
pub const ANARI_STATUS_OUT_OF_MEMORY: ANARIStatusCode = 4;
pub const ANARI_STATUS_UNSUPPORTED_DEVICE: ANARIStatusCode = 5;
pub const ANARI_STATUS_VERSION_MISMATCH: ANARIStatusCode = 6;

pub const ANARI_SEVERITY_FATAL_ERROR: ANARIStatusSeverity = 1;
pub const ANARI_SEVERITY_ERROR: ANARIStatusSeverity = 2;
pub const ANARI_SEVERITY_WARNING: ANARIStatusSeverity = 3;
pub const ANARI_SEVERITY_PERFORMANCE_WARNING: ANARIStatusSeverity = 4;
pub const ANARI_SEVERITY_INFO: ANARIStatusSeverity = 5;
pub const ANARI_SEVERITY_DEBUG: ANARIStatusSeverity = 6;

pub const ANARI_LOG_DEBUG: ANARILogLevel = 1;
pub const ANARI_LOG_INFO: ANARILogLevel = 2;
pub const ANARI_LOG_WARNING: ANARILogLevel = 3;
pub const ANARI_LOG_ERROR: ANARILogLevel = 4;
pub const ANARI_LOG_NONE: ANARILogLevel = 5;

pub const ANARI_NO_WAIT: ANARIWaitMask = 0;
pub const ANARI_WAIT: ANARIWaitMask = 1;

/// `ANARIStatusCallback`: (userPtr, device, source, sourceType, severity, code, message).
pub type ANARIStatusCallback = Option<
    unsafe extern "C" fn(
        user_ptr: *const c_void,
        device: *mut c_void,
        source: *mut c_void,
        source_type: ANARIDataType,
        severity: ANARIStatusSeverity,
        code: ANARIStatusCode,
        message: *const c_char,
    ),
>;

/// Where a status message came from: the handle value and its data type.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Source {
    pub handle: usize,
    pub kind: ANARIDataType,
}

/// One message delivered to the application.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StatusMessage {
    pub severity: ANARIStatusSeverity,
    pub code: ANARIStatusCode,
    pub source: Source,
    pub text: String,
}

#[derive(Clone, Copy)]
struct Callback {
    function: ANARIStatusCallback,
    user_data: usize,
}

/// The application's status callback (or stderr when it gave none).
pub struct StatusSink {
    callback: RwLock<Callback>,
    device_handle: usize,
}

impl StatusSink {
    pub fn new(device_handle: usize, function: ANARIStatusCallback, user_data: usize) -> Self {
        StatusSink {
            callback: RwLock::new(Callback {
                function,
                user_data,
            }),
            device_handle,
        }
    }

    pub fn set_callback(&self, function: ANARIStatusCallback, user_data: usize) {
        *self.callback.write().unwrap_or_else(|e| e.into_inner()) = Callback {
            function,
            user_data,
        };
    }

    /// Delivers one message. Messages reach the callback on the thread that noticed the problem.
    pub fn report(&self, message: &StatusMessage) {
        let callback = *self.callback.read().unwrap_or_else(|e| e.into_inner());
        match callback.function {
            Some(function) => {
                let text = CString::new(message.text.replace('\0', " ")).unwrap_or_default();
                // SAFETY: the application registered this callback with this signature; all
                // pointers passed stay valid for the duration of the call.
                unsafe {
                    function(
                        callback.user_data as *const c_void,
                        self.device_handle as *mut c_void,
                        message.source.handle as *mut c_void,
                        message.source.kind,
                        message.severity,
                        message.code,
                        text.as_ptr(),
                    )
                }
            }
            None => {
                if message.severity <= ANARI_SEVERITY_WARNING {
                    eprintln!(
                        "[cavetrace] {}: {}",
                        severity_name(message.severity),
                        message.text
                    );
                }
            }
        }
    }
}

/// The message a panic carried (`panic!` with a literal or a formatted string), for reports.
pub fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

pub fn severity_name(severity: ANARIStatusSeverity) -> &'static str {
    match severity {
        ANARI_SEVERITY_FATAL_ERROR => "fatal error",
        ANARI_SEVERITY_ERROR => "error",
        ANARI_SEVERITY_WARNING => "warning",
        ANARI_SEVERITY_PERFORMANCE_WARNING => "performance warning",
        ANARI_SEVERITY_INFO => "info",
        _ => "debug",
    }
}
