//! Parameters: anariSetParameter, anariUnset*, anariMapParameterArray*, anariCommitParameters.

use std::ffi::{CStr, c_char, c_void};

use crate::capi::types::*;
use crate::capi::{device_of, guard, string_arg};
use crate::device::datatype::*;
use crate::device::status::*;
use crate::device::{Device, IncomingValue};

/// Converts `mem` of `data_type` as passed to anariSetParameter into an owned value.
///
/// # Safety
/// `mem` must point at a value of `data_type` (for ANARI_STRING: be the C string itself).
pub(crate) unsafe fn incoming_value(
    device: &Device,
    function: &str,
    data_type: ANARIDataType,
    mem: *const c_void,
) -> Option<IncomingValue> {
    let fail = |text: String| {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            None,
            format!("{function}: {text}"),
        );
        None
    };
    // ANARI passes a VOID_POINTER value as `mem` itself (NULL is a valid value), not by address.
    if data_type == ANARI_VOID_POINTER {
        return Some(IncomingValue::Pointer(mem as usize));
    }
    if mem.is_null() {
        return fail(format!(
            "the value pointer for a {} parameter is NULL; ignored",
            type_name(data_type)
        ));
    }
    let Some(size) = element_size(data_type) else {
        return fail(format!("{data_type} is not an ANARI data type; ignored"));
    };
    Some(match data_type {
        ANARI_STRING => {
            // SAFETY: for ANARI_STRING the value is a NUL-terminated C string (caller contract).
            let text = unsafe { CStr::from_ptr(mem as *const c_char) };
            IncomingValue::String(text.to_string_lossy().into_owned())
        }
        ANARI_STRING_LIST | ANARI_DATA_TYPE_LIST | ANARI_PARAMETER_LIST | ANARI_LIBRARY => {
            return fail(format!(
                "{} cannot be a parameter value; ignored",
                type_name(data_type)
            ));
        }
        t if is_object(t) => {
            // SAFETY: for object types `mem` points at one handle (caller contract).
            IncomingValue::Handle(unsafe { (mem as *const usize).read_unaligned() })
        }
        ANARI_FUNCTION_POINTER
        | ANARI_MEMORY_DELETER
        | ANARI_STATUS_CALLBACK
        | ANARI_FRAME_COMPLETION_CALLBACK => {
            // SAFETY: for pointer types `mem` points at one pointer value (caller contract).
            IncomingValue::Pointer(unsafe { (mem as *const usize).read_unaligned() })
        }
        _ => {
            // SAFETY: plain data of `size` bytes (caller contract); size ≤ 64 for every type.
            let bytes = unsafe { std::slice::from_raw_parts(mem as *const u8, size) };
            IncomingValue::Data(bytes.to_vec())
        }
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariSetParameter(
    device: ANARIDevice,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    mem: *const c_void,
) {
    const F: &str = "anariSetParameter";
    guard(F, device, (), || {
        let Some(device) = device_of(F, device) else {
            return;
        };
        let Some(name) = string_arg(&device, F, "name", name) else {
            return;
        };
        let function = format!("{F}('{name}')");
        // SAFETY: the application passes `mem` matching `data_type`, per the API contract.
        let Some(value) = (unsafe { incoming_value(&device, &function, data_type, mem) }) else {
            return;
        };
        device.set_parameter(F, object as usize, &name, data_type, value);
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariUnsetParameter(
    device: ANARIDevice,
    object: ANARIObject,
    name: *const c_char,
) {
    const F: &str = "anariUnsetParameter";
    guard(F, device, (), || {
        let Some(device) = device_of(F, device) else {
            return;
        };
        let Some(name) = string_arg(&device, F, "name", name) else {
            return;
        };
        device.unset_parameter(F, object as usize, &name);
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariUnsetAllParameters(device: ANARIDevice, object: ANARIObject) {
    const F: &str = "anariUnsetAllParameters";
    guard(F, device, (), || {
        let Some(device) = device_of(F, device) else {
            return;
        };
        device.unset_all_parameters(F, object as usize);
    })
}

fn map_parameter_array(
    function: &'static str,
    device: ANARIDevice,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    dims: [u64; 3],
    element_stride: *mut u64,
) -> *mut c_void {
    guard(function, device, std::ptr::null_mut(), || {
        let Some(device) = device_of(function, device) else {
            return std::ptr::null_mut();
        };
        let Some(name) = string_arg(&device, function, "name", name) else {
            return std::ptr::null_mut();
        };
        match device.map_parameter_array(function, object as usize, &name, data_type, dims) {
            Some((pointer, stride)) => {
                if !element_stride.is_null() {
                    // SAFETY: the application passes a writable uint64_t or NULL.
                    unsafe { element_stride.write(stride) };
                }
                pointer
            }
            None => std::ptr::null_mut(),
        }
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariMapParameterArray1D(
    device: ANARIDevice,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    num_elements1: u64,
    element_stride: *mut u64,
) -> *mut c_void {
    map_parameter_array(
        "anariMapParameterArray1D",
        device,
        object,
        name,
        data_type,
        [num_elements1, 1, 1],
        element_stride,
    )
}

#[unsafe(no_mangle)]
pub extern "C" fn anariMapParameterArray2D(
    device: ANARIDevice,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    num_elements1: u64,
    num_elements2: u64,
    element_stride: *mut u64,
) -> *mut c_void {
    map_parameter_array(
        "anariMapParameterArray2D",
        device,
        object,
        name,
        data_type,
        [num_elements1, num_elements2, 1],
        element_stride,
    )
}

#[unsafe(no_mangle)]
pub extern "C" fn anariMapParameterArray3D(
    device: ANARIDevice,
    object: ANARIObject,
    name: *const c_char,
    data_type: ANARIDataType,
    num_elements1: u64,
    num_elements2: u64,
    num_elements3: u64,
    element_stride: *mut u64,
) -> *mut c_void {
    map_parameter_array(
        "anariMapParameterArray3D",
        device,
        object,
        name,
        data_type,
        [num_elements1, num_elements2, num_elements3],
        element_stride,
    )
}

#[unsafe(no_mangle)]
pub extern "C" fn anariUnmapParameterArray(
    device: ANARIDevice,
    object: ANARIObject,
    name: *const c_char,
) {
    const F: &str = "anariUnmapParameterArray";
    guard(F, device, (), || {
        let Some(device) = device_of(F, device) else {
            return;
        };
        let Some(name) = string_arg(&device, F, "name", name) else {
            return;
        };
        device.unmap_parameter_array(F, object as usize, &name);
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariCommitParameters(device: ANARIDevice, object: ANARIObject) {
    const F: &str = "anariCommitParameters";
    guard(F, device, (), || {
        let Some(device) = device_of(F, device) else {
            return;
        };
        device.commit(F, object as usize);
    })
}
