//! Frames: anariRenderFrame, anariFrameReady, anariDiscardFrame, anariMapFrame, anariUnmapFrame.

use std::ffi::{c_char, c_int, c_void};
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
        if let Some(device) = device_of(F, device) {
            render_frame(&device, frame);
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
        device_of(F, device).map_or(0, |device| frame_ready(&device, frame, mask))
    })
}

/// Asks the render in flight to stop soon (within one tile per thread).
#[unsafe(no_mangle)]
pub extern "C" fn anariDiscardFrame(device: ANARIDevice, frame: ANARIFrame) {
    const F: &str = "anariDiscardFrame";
    guard(F, device, (), || {
        if let Some(device) = device_of(F, device) {
            discard_frame(&device, frame);
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
    guard(F, device, std::ptr::null(), || {
        write_map_outputs(width, height, pixel_type, (0, 0, ANARI_UNKNOWN));
        let Some(device) = device_of(F, device) else {
            return std::ptr::null();
        };
        let Some((pointer, w, h, t)) = map_frame(&device, frame, channel) else {
            return std::ptr::null();
        };
        write_map_outputs(width, height, pixel_type, (w, h, t));
        pointer
    })
}

#[unsafe(no_mangle)]
pub extern "C" fn anariUnmapFrame(device: ANARIDevice, frame: ANARIFrame, channel: *const c_char) {
    const F: &str = "anariUnmapFrame";
    guard(F, device, (), || {
        if let Some(device) = device_of(F, device) {
            unmap_frame(&device, frame, channel);
        }
    })
}

// The work of the frame functions once the device is known, shared with the SDK device's slots.

pub(crate) fn render_frame(device: &Device, frame: ANARIFrame) {
    if let Some(frame) = frame_of(device, "anariRenderFrame", frame) {
        crate::render::render_frame(device, &frame);
    }
}

pub(crate) fn frame_ready(device: &Device, frame: ANARIFrame, mask: ANARIWaitMask) -> c_int {
    let Some(frame) = frame_of(device, "anariFrameReady", frame) else {
        return 0;
    };
    let state = frame.frame.as_ref().expect("checked by frame_of");
    if mask & ANARI_WAIT != 0 {
        state.wait();
    }
    state.is_ready() as c_int
}

pub(crate) fn discard_frame(device: &Device, frame: ANARIFrame) {
    if let Some(frame) = frame_of(device, "anariDiscardFrame", frame) {
        frame.frame.as_ref().expect("checked by frame_of").discard();
    }
}

/// The mapped channel's (pixels, width, height, type), or `None` after a report.
pub(crate) fn map_frame(
    device: &Device,
    frame: ANARIFrame,
    channel: *const c_char,
) -> Option<(*const c_void, u32, u32, ANARIDataType)> {
    const F: &str = "anariMapFrame";
    let frame = frame_of(device, F, frame)?;
    let channel = string_arg(device, F, "channel", channel)?;
    let mapped = frame
        .frame
        .as_ref()
        .expect("checked by frame_of")
        .map(&channel);
    if mapped.is_none() {
        device.error(
            ANARI_STATUS_INVALID_OPERATION,
            Some(&frame),
            format!(
                "{F}: '{channel}' is not available: enable it with the frame parameter \
                 '{channel}' (an ANARI_DATA_TYPE), commit, and render first"
            ),
        );
    }
    mapped
}

/// Writes a mapping's size and pixel type to the application's out pointers.
pub(crate) fn write_map_outputs(
    width: *mut u32,
    height: *mut u32,
    pixel_type: *mut ANARIDataType,
    (w, h, t): (u32, u32, ANARIDataType),
) {
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
}

pub(crate) fn unmap_frame(device: &Device, frame: ANARIFrame, channel: *const c_char) {
    const F: &str = "anariUnmapFrame";
    let Some(frame) = frame_of(device, F, frame) else {
        return;
    };
    let Some(channel) = string_arg(device, F, "channel", channel) else {
        return;
    };
    if !frame
        .frame
        .as_ref()
        .expect("checked by frame_of")
        .unmap(&channel)
    {
        device.error(
            ANARI_STATUS_INVALID_OPERATION,
            Some(&frame),
            format!("{F}: '{channel}' is not mapped"),
        );
    }
}
