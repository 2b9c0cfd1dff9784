//! C types of the ANARI API. Handles are `void*` as in Khronos anari.h (C mode).

use std::ffi::{c_char, c_void};

use crate::device::datatype::ANARIDataType;

pub type ANARILibrary = *mut c_void;
pub type ANARIObject = *mut c_void;
pub type ANARIDevice = *mut c_void;
pub type ANARICamera = *mut c_void;
pub type ANARIArray = *mut c_void;
pub type ANARIArray1D = *mut c_void;
pub type ANARIArray2D = *mut c_void;
pub type ANARIArray3D = *mut c_void;
pub type ANARIFrame = *mut c_void;
pub type ANARIFuture = *mut c_void;
pub type ANARIGeometry = *mut c_void;
pub type ANARIGroup = *mut c_void;
pub type ANARIInstance = *mut c_void;
pub type ANARILight = *mut c_void;
pub type ANARIMaterial = *mut c_void;
pub type ANARISampler = *mut c_void;
pub type ANARISurface = *mut c_void;
pub type ANARIRenderer = *mut c_void;
pub type ANARISpatialField = *mut c_void;
pub type ANARIVolume = *mut c_void;
pub type ANARIWorld = *mut c_void;

/// One entry of a parameter list (anariGetObjectInfo "parameter"); a NULL name ends the list.
/// cbindgen:field-names=[name, type]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct ANARIParameter {
    pub name: *const c_char,
    pub data_type: ANARIDataType,
}

/// A named value for anariNewInitializedDevice; a NULL name ends the list.
/// cbindgen:field-names=[name, type, value]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct ANARIParameterValue {
    pub name: *const c_char,
    pub data_type: ANARIDataType,
    pub value: *const c_void,
}
