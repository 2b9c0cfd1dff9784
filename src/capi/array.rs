//! Arrays: anariNewArray1D/2D/3D, anariMapArray, anariUnmapArray.

use std::ffi::c_void;

use crate::capi::types::*;
use crate::capi::{device_of, guard};
use crate::device::array::ANARIMemoryDeleter;
use crate::device::datatype::ANARIDataType;

#[allow(clippy::too_many_arguments)]
fn new_array(
    function: &'static str,
    device: ANARIDevice,
    app_memory: *const c_void,
    deleter: ANARIMemoryDeleter,
    user_data: *const c_void,
    data_type: ANARIDataType,
    dims: [u64; 3],
) -> ANARIArray {
    guard(function, device, std::ptr::null_mut(), || {
        let Some(device) = device_of(function, device) else {
            return std::ptr::null_mut();
        };
        device.new_array(function, app_memory, deleter, user_data, data_type, dims) as ANARIArray
    })
}

/// A 1D array: NULL `appMemory` makes a managed array (fill it with anariMapArray); otherwise
/// the application's memory is shared, or captured when a deleter is given.
#[unsafe(no_mangle)]
pub extern "C" fn anariNewArray1D(
    device: ANARIDevice,
    app_memory: *const c_void,
    deleter: ANARIMemoryDeleter,
    user_data: *const c_void,
    data_type: ANARIDataType,
    num_elements1: u64,
) -> ANARIArray1D {
    new_array(
        "anariNewArray1D",
        device,
        app_memory,
        deleter,
        user_data,
        data_type,
        [num_elements1, 1, 1],
    )
}

#[unsafe(no_mangle)]
pub extern "C" fn anariNewArray2D(
    device: ANARIDevice,
    app_memory: *const c_void,
    deleter: ANARIMemoryDeleter,
    user_data: *const c_void,
    data_type: ANARIDataType,
    num_elements1: u64,
    num_elements2: u64,
) -> ANARIArray2D {
    new_array(
        "anariNewArray2D",
        device,
        app_memory,
        deleter,
        user_data,
        data_type,
        [num_elements1, num_elements2, 1],
    )
}

#[allow(clippy::too_many_arguments)]
#[unsafe(no_mangle)]
pub extern "C" fn anariNewArray3D(
    device: ANARIDevice,
    app_memory: *const c_void,
    deleter: ANARIMemoryDeleter,
    user_data: *const c_void,
    data_type: ANARIDataType,
    num_elements1: u64,
    num_elements2: u64,
    num_elements3: u64,
) -> ANARIArray3D {
    new_array(
        "anariNewArray3D",
        device,
        app_memory,
        deleter,
        user_data,
        data_type,
        [num_elements1, num_elements2, num_elements3],
    )
}

#[unsafe(no_mangle)]
pub extern "C" fn anariMapArray(device: ANARIDevice, array: ANARIArray) -> *mut c_void {
    const F: &str = "anariMapArray";
    guard(F, device, std::ptr::null_mut(), || {
        let Some(device) = device_of(F, device) else {
            return std::ptr::null_mut();
        };
        device.map_array(F, array as usize)
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariUnmapArray(device: ANARIDevice, array: ANARIArray) {
    const F: &str = "anariUnmapArray";
    guard(F, device, (), || {
        if let Some(device) = device_of(F, device) {
            device.unmap_array(F, array as usize);
        }
    })
}
