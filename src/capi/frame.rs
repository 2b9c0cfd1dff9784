//! Frames: anariRenderFrame, anariFrameReady, anariDiscardFrame, anariMapFrame, anariUnmapFrame.

use std::ffi::{c_char, c_void};
use std::sync::Arc;

use crate::capi::types::*;
use crate::capi::{device_of, guard, string_arg};
use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::status::*;

/// The frame behind `frame`, or a report naming the function.
fn frame_of(device: &Device, function: &str, frame: ANARIFrame) -> Option<Arc<Object>> {
    let object = device.resolve(function, frame as usize)?;
    if object.frame.is_none() {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(&object),
            format!("{function}: {} is not a frame", object.describe()),
        );
        return None;
    }
    Some(object)
}

/// Starts rendering and returns at once; the work runs on the device's own threads.
#[unsafe(no_mangle)]
pub extern "C" fn anariRenderFrame(device: ANARIDevice, frame: ANARIFrame) {
    const F: &str = "anariRenderFrame";
    guard(F, device, (), || {
        let Some(device) = device_of(F, device) else {
            return;
        };
        if let Some(frame) = frame_of(&device, F, frame) {
            crate::render::render_frame(&device, &frame);
        }
    })
}

/// ANARI_NO_WAIT polls (1 when done), ANARI_WAIT blocks until the render is done.
#[unsafe(no_mangle)]
pub extern "C" fn anariFrameReady(
    device: ANARIDevice,
    frame: ANARIFrame,
    mask: ANARIWaitMask,
) -> std::ffi::c_int {
    const F: &str = "anariFrameReady";
    guard(F, device, 0, || {
        let Some(device) = device_of(F, device) else {
            return 0;
        };
        let Some(frame) = frame_of(&device, F, frame) else {
            return 0;
        };
        let state = frame.frame.as_ref().expect("checked by frame_of");
        if mask & ANARI_WAIT != 0 {
            state.wait();
        }
        state.is_ready() as std::ffi::c_int
    })
}

/// Asks the render in flight to stop soon (within one tile per thread).
#[unsafe(no_mangle)]
pub extern "C" fn anariDiscardFrame(device: ANARIDevice, frame: ANARIFrame) {
    const F: &str = "anariDiscardFrame";
    guard(F, device, (), || {
        let Some(device) = device_of(F, device) else {
            return;
        };
        if let Some(frame) = frame_of(&device, F, frame) {
            frame.frame.as_ref().expect("checked by frame_of").discard();
        }
    })
}

/// Waits for the render and returns the channel's pixels, rows bottom to top.
#[unsafe(no_mangle)]
pub extern "C" fn anariMapFrame(
    device: ANARIDevice,
    frame: ANARIFrame,
    channel: *const c_char,
    width: *mut u32,
    height: *mut u32,
    pixel_type: *mut ANARIDataType,
) -> *const c_void {
    const F: &str = "anariMapFrame";
    let write_out = |w: u32, h: u32, t: ANARIDataType| {
        // SAFETY: each out pointer is either NULL or writable, per the API.
        unsafe {
            if !width.is_null() {
                width.write(w);
            }
            if !height.is_null() {
                height.write(h);
            }
            if !pixel_type.is_null() {
                pixel_type.write(t);
            }
        }
    };
    guard(F, device, std::ptr::null(), || {
        write_out(0, 0, ANARI_UNKNOWN);
        let Some(device) = device_of(F, device) else {
            return std::ptr::null();
        };
        let Some(frame) = frame_of(&device, F, frame) else {
            return std::ptr::null();
        };
        let Some(channel) = string_arg(&device, F, "channel", channel) else {
            return std::ptr::null();
        };
        let state = frame.frame.as_ref().expect("checked by frame_of");
        match state.map(&channel) {
            Some((pointer, w, h, t)) => {
                write_out(w, h, t);
                pointer
            }
            None => {
                device.error(
                    ANARI_STATUS_INVALID_OPERATION,
                    Some(&frame),
                    format!(
                        "{F}: '{channel}' is not available: enable it with the frame parameter \
                         '{channel}' (an ANARI_DATA_TYPE), commit, and render first"
                    ),
                );
                std::ptr::null()
            }
        }
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariUnmapFrame(device: ANARIDevice, frame: ANARIFrame, channel: *const c_char) {
    const F: &str = "anariUnmapFrame";
    guard(F, device, (), || {
        let Some(device) = device_of(F, device) else {
            return;
        };
        let Some(frame) = frame_of(&device, F, frame) else {
            return;
        };
        let Some(channel) = string_arg(&device, F, "channel", channel) else {
            return;
        };
        if !frame.frame.as_ref().expect("checked").unmap(&channel) {
            device.error(
                ANARI_STATUS_INVALID_OPERATION,
                Some(&frame),
                format!("{F}: '{channel}' is not mapped"),
            );
        }
    })
}
