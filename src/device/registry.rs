//! Process-wide tables of live libraries and devices, and handle numbering. Handles are opaque
//! numbers shaped like aligned pointers; they are looked up here, never dereferenced.

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use crate::device::Device;
use crate::device::status::ANARIStatusCallback;

static NEXT_HANDLE: AtomicUsize = AtomicUsize::new(1);

/// A fresh handle value: never 0, 16-byte aligned, never reused within the process.
pub fn next_handle() -> usize {
    0x1000_0000 + NEXT_HANDLE.fetch_add(1, Ordering::Relaxed) * 16
}

#[derive(Clone, Copy)]
pub struct LibraryRecord {
    pub default_callback: ANARIStatusCallback,
    pub default_user_data: usize,
}

fn libraries() -> &'static Mutex<HashMap<usize, LibraryRecord>> {
    static LIBRARIES: OnceLock<Mutex<HashMap<usize, LibraryRecord>>> = OnceLock::new();
    LIBRARIES.get_or_init(Default::default)
}

fn devices() -> &'static Mutex<HashMap<usize, Arc<Device>>> {
    static DEVICES: OnceLock<Mutex<HashMap<usize, Arc<Device>>>> = OnceLock::new();
    DEVICES.get_or_init(Default::default)
}

pub fn add_library(record: LibraryRecord) -> usize {
    let handle = next_handle();
    libraries()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(handle, record);
    handle
}

pub fn library(handle: usize) -> Option<LibraryRecord> {
    libraries()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .get(&handle)
        .copied()
}

/// The record of the loaded library when exactly one is loaded: calls on a NULL or dead device
/// report through its status callback (with several, which one the caller meant is unknown).
pub fn sole_library() -> Option<LibraryRecord> {
    let libraries = libraries().lock().unwrap_or_else(|e| e.into_inner());
    if libraries.len() == 1 {
        libraries.values().next().copied()
    } else {
        None
    }
}

pub fn remove_library(handle: usize) -> bool {
    libraries()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .remove(&handle)
        .is_some()
}

pub fn add_device(device: Arc<Device>) {
    devices()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(device.handle, device);
}

pub fn device(handle: usize) -> Option<Arc<Device>> {
    devices()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .get(&handle)
        .cloned()
}

pub fn remove_device(handle: usize) -> Option<Arc<Device>> {
    devices()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .remove(&handle)
}

pub fn live_device_count() -> usize {
    devices().lock().unwrap_or_else(|e| e.into_inner()).len()
}
