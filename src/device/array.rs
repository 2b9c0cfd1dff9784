//! Array objects: managed (device memory filled through map/unmap), shared (application memory,
//! zero copy) and captured (application memory handed over with a deleter called exactly once).

use std::ffi::c_void;
use std::sync::{Arc, Mutex, MutexGuard};

use glam::{UVec2, UVec3, UVec4, Vec2, Vec3, Vec4};

use crate::device::datatype::*;
use crate::device::object::Object;

/// `ANARIMemoryDeleter`: (userPtr, appMemory).
pub type ANARIMemoryDeleter =
    Option<unsafe extern "C" fn(user_ptr: *const c_void, app_memory: *const c_void)>;

enum Storage {
    /// Device-owned, 8-byte aligned (enough for every element type).
    Managed(Vec<u64>),
    /// Application memory; captured memory carries the deleter to call when the array dies.
    Application {
        address: usize,
        deleter: ANARIMemoryDeleter,
        user_data: usize,
    },
}

pub struct ArrayInner {
    storage: Storage,
    pub mapped: bool,
    /// Retained elements of arrays of object handles, resolved at creation and at each unmap.
    pub objects: Vec<Arc<Object>>,
}

/// The payload of an ANARI array object.
pub struct ArrayStore {
    pub element_type: ANARIDataType,
    pub dims: [u64; 3],
    pub byte_size: usize,
    inner: Mutex<ArrayInner>,
}

#[derive(Debug, PartialEq, Eq)]
pub enum ArrayError {
    InvalidType,
    TooLarge,
    OutOfMemory,
    /// More than the system has available (checked before allocating).
    Exceeds(crate::device::memory::TooBig),
}

impl ArrayStore {
    /// Creates the store; `app_memory` NULL means managed. Fails on overflow or allocation failure
    /// (in which case a captured deleter is NOT called: the device never took the memory).
    pub fn new(
        element_type: ANARIDataType,
        dims: [u64; 3],
        app_memory: *const c_void,
        deleter: ANARIMemoryDeleter,
        user_data: *const c_void,
    ) -> Result<ArrayStore, ArrayError> {
        let element = element_size(element_type).ok_or(ArrayError::InvalidType)?;
        let count = dims[0]
            .checked_mul(dims[1])
            .and_then(|c| c.checked_mul(dims[2]))
            .ok_or(ArrayError::TooLarge)?;
        let bytes = count
            .checked_mul(element as u64)
            .filter(|b| *b <= isize::MAX as u64)
            .ok_or(ArrayError::TooLarge)? as usize;
        let storage = if app_memory.is_null() {
            crate::device::memory::check(bytes as u64).map_err(ArrayError::Exceeds)?;
            let words = bytes.div_ceil(8);
            let mut memory: Vec<u64> = Vec::new();
            memory
                .try_reserve_exact(words)
                .map_err(|_| ArrayError::OutOfMemory)?;
            memory.resize(words, 0);
            Storage::Managed(memory)
        } else {
            Storage::Application {
                address: app_memory as usize,
                deleter,
                user_data: user_data as usize,
            }
        };
        Ok(ArrayStore {
            element_type,
            dims,
            byte_size: bytes,
            inner: Mutex::new(ArrayInner {
                storage,
                mapped: false,
                objects: Vec::new(),
            }),
        })
    }

    pub fn lock(&self) -> MutexGuard<'_, ArrayInner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub fn element_count(&self) -> usize {
        (self.dims[0] * self.dims[1] * self.dims[2]) as usize
    }

    pub fn is_managed(&self) -> bool {
        matches!(self.lock().storage, Storage::Managed(_))
    }

    /// Called when the application releases a shared array that others still use: ANARI lets
    /// the application free shared memory then, so the device keeps its own copy from here on.
    /// Captured memory stays: it is the device's until the deleter runs.
    pub fn detach_from_application(&self) {
        let mut inner = self.lock();
        let Storage::Application {
            address,
            deleter: None,
            ..
        } = inner.storage
        else {
            return;
        };
        let mut copy: Vec<u64> = Vec::new();
        if copy.try_reserve_exact(self.byte_size.div_ceil(8)).is_err() {
            // Nothing sensible remains: forget the application's memory instead of reading it.
            inner.storage = Storage::Managed(Vec::new());
            return;
        }
        copy.resize(self.byte_size.div_ceil(8), 0);
        // SAFETY: the application's memory is still valid during anariRelease (it may free it
        // only afterwards) and holds byte_size bytes; the copy has room for them.
        unsafe {
            std::ptr::copy_nonoverlapping(
                address as *const u8,
                copy.as_mut_ptr() as *mut u8,
                self.byte_size,
            )
        };
        inner.storage = Storage::Managed(copy);
    }

    /// Pointer handed to the application by anariMapArray.
    pub fn data_pointer(&self) -> *mut c_void {
        let mut inner = self.lock();
        match &mut inner.storage {
            Storage::Managed(memory) => memory.as_mut_ptr() as *mut c_void,
            Storage::Application { address, .. } => *address as *mut c_void,
        }
    }

    /// Runs `f` over the array's bytes.
    pub fn with_bytes<R>(&self, f: impl FnOnce(&[u8]) -> R) -> R {
        let inner = self.lock();
        match &inner.storage {
            Storage::Managed(memory) => {
                // SAFETY: the Vec<u64> holds at least byte_size bytes; u8 has no alignment needs.
                let bytes = unsafe {
                    std::slice::from_raw_parts(memory.as_ptr() as *const u8, self.byte_size)
                };
                f(bytes)
            }
            Storage::Application { address, .. } => {
                // SAFETY: ANARI requires shared/captured application memory to hold
                // numElements × element size bytes and to stay valid until the array is released.
                let bytes =
                    unsafe { std::slice::from_raw_parts(*address as *const u8, self.byte_size) };
                f(bytes)
            }
        }
    }

    /// The handle values stored in an array of objects.
    pub fn handle_values(&self) -> Vec<usize> {
        self.with_bytes(|bytes| {
            bytes
                .chunks_exact(std::mem::size_of::<usize>())
                .map(|c| usize::from_ne_bytes(c.try_into().unwrap()))
                .collect()
        })
    }

    pub fn objects(&self) -> Vec<Arc<Object>> {
        self.lock().objects.clone()
    }

    fn floats(&self, components: usize) -> Option<Vec<f32>> {
        if float32_components(self.element_type) != Some(components) {
            return None;
        }
        Some(self.with_bytes(|bytes| {
            bytes
                .chunks_exact(4)
                .map(|c| f32::from_ne_bytes(c.try_into().unwrap()))
                .collect()
        }))
    }

    fn u32s(&self, expected: ANARIDataType) -> Option<Vec<u32>> {
        if self.element_type != expected {
            return None;
        }
        Some(self.with_bytes(|bytes| {
            bytes
                .chunks_exact(4)
                .map(|c| u32::from_ne_bytes(c.try_into().unwrap()))
                .collect()
        }))
    }

    pub fn read_f32(&self) -> Option<Vec<f32>> {
        self.floats(1)
    }
    pub fn read_vec2(&self) -> Option<Vec<Vec2>> {
        Some(
            self.floats(2)?
                .chunks_exact(2)
                .map(Vec2::from_slice)
                .collect(),
        )
    }
    pub fn read_vec3(&self) -> Option<Vec<Vec3>> {
        Some(
            self.floats(3)?
                .chunks_exact(3)
                .map(Vec3::from_slice)
                .collect(),
        )
    }
    pub fn read_vec4(&self) -> Option<Vec<Vec4>> {
        Some(
            self.floats(4)?
                .chunks_exact(4)
                .map(Vec4::from_slice)
                .collect(),
        )
    }
    pub fn read_u32(&self) -> Option<Vec<u32>> {
        self.u32s(ANARI_UINT32)
    }
    pub fn read_uvec2(&self) -> Option<Vec<UVec2>> {
        Some(
            self.u32s(ANARI_UINT32_VEC2)?
                .chunks_exact(2)
                .map(UVec2::from_slice)
                .collect(),
        )
    }
    pub fn read_uvec3(&self) -> Option<Vec<UVec3>> {
        Some(
            self.u32s(ANARI_UINT32_VEC3)?
                .chunks_exact(3)
                .map(UVec3::from_slice)
                .collect(),
        )
    }
    pub fn read_uvec4(&self) -> Option<Vec<UVec4>> {
        Some(
            self.u32s(ANARI_UINT32_VEC4)?
                .chunks_exact(4)
                .map(UVec4::from_slice)
                .collect(),
        )
    }

    /// Reads an index array of UINT32 or UINT64 elements with `components` (1 to 4) per
    /// element, each element passed to `make` as a slice of `components` values, in one pass
    /// (big meshes' index arrays are not copied twice). 64-bit values beyond u32 range read as
    /// u32::MAX (out of range for any geometry).
    pub fn read_indices<T>(&self, components: usize, make: impl Fn(&[u32]) -> T) -> Option<Vec<T>> {
        let (narrow, wide) = match components {
            1 => (ANARI_UINT32, ANARI_UINT64),
            2 => (ANARI_UINT32_VEC2, ANARI_UINT64_VEC2),
            3 => (ANARI_UINT32_VEC3, ANARI_UINT64_VEC3),
            4 => (ANARI_UINT32_VEC4, ANARI_UINT64_VEC4),
            _ => return None,
        };
        let value_bytes = if self.element_type == narrow {
            4
        } else if self.element_type == wide {
            8
        } else {
            return None;
        };
        Some(self.with_bytes(|bytes| {
            bytes
                .chunks_exact(value_bytes * components)
                .map(|element| {
                    let mut values = [0u32; 4];
                    for (value, raw) in values.iter_mut().zip(element.chunks_exact(value_bytes)) {
                        *value = if value_bytes == 4 {
                            raw.try_into().map_or(u32::MAX, u32::from_ne_bytes)
                        } else {
                            raw.try_into()
                                .map(u64::from_ne_bytes)
                                .ok()
                                .and_then(|wide| u32::try_from(wide).ok())
                                .unwrap_or(u32::MAX)
                        };
                    }
                    make(&values[..components])
                })
                .collect()
        }))
    }

    /// Reads any numeric attribute array as Vec4 (missing components: y=z=0, w=1), normalising
    /// fixed-point types to [0,1] and decoding sRGB bytes to linear.
    pub fn read_attribute(&self) -> Option<Vec<Vec4>> {
        let t = self.element_type;
        let expand = |values: &[f32], n: usize| -> Vec<Vec4> {
            values
                .chunks_exact(n)
                .map(|c| {
                    let mut v = Vec4::new(0.0, 0.0, 0.0, 1.0);
                    for (i, x) in c.iter().enumerate() {
                        v[i] = *x;
                    }
                    v
                })
                .collect()
        };
        if let Some(n) = float32_components(t) {
            return Some(expand(&self.floats(n)?, n));
        }
        let (n, scalar_bytes, srgb) = match t {
            ANARI_UFIXED8 => (1, 1, false),
            ANARI_UFIXED8_VEC2 => (2, 1, false),
            ANARI_UFIXED8_VEC3 => (3, 1, false),
            ANARI_UFIXED8_VEC4 => (4, 1, false),
            ANARI_UFIXED8_RGBA_SRGB => (4, 1, true),
            ANARI_UFIXED8_RGB_SRGB => (3, 1, true),
            ANARI_UFIXED16 => (1, 2, false),
            ANARI_UFIXED16_VEC2 => (2, 2, false),
            ANARI_UFIXED16_VEC3 => (3, 2, false),
            ANARI_UFIXED16_VEC4 => (4, 2, false),
            _ => return None,
        };
        let values: Vec<f32> = self.with_bytes(|bytes| {
            bytes
                .chunks_exact(scalar_bytes)
                .enumerate()
                .map(|(i, c)| {
                    let v = if scalar_bytes == 1 {
                        c[0] as f32 / 255.0
                    } else {
                        u16::from_ne_bytes([c[0], c[1]]) as f32 / 65535.0
                    };
                    // sRGB applies to colour components, not alpha.
                    if srgb && (i % n) < 3 {
                        srgb_to_linear(v)
                    } else {
                        v
                    }
                })
                .collect()
        });
        Some(expand(&values, n))
    }
}

impl Drop for ArrayInner {
    fn drop(&mut self) {
        if let Storage::Application {
            address,
            deleter: Some(deleter),
            user_data,
        } = self.storage
        {
            // SAFETY: the application gave us this deleter for this memory; the array is being
            // destroyed, so this is the one and only call.
            unsafe { deleter(user_data as *const c_void, address as *const c_void) }
        }
    }
}

/// Inverse sRGB transfer function: encoded [0,1] → linear (how `*_SRGB` elements are read).
pub fn srgb_to_linear(encoded: f32) -> f32 {
    if encoded <= 0.040_45 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    static DELETED: AtomicUsize = AtomicUsize::new(0);
    unsafe extern "C" fn count_deletes(_: *const c_void, _: *const c_void) {
        DELETED.fetch_add(1, Ordering::SeqCst);
    }

    #[test]
    fn managed_array_is_zeroed_and_sized() {
        let a = ArrayStore::new(
            ANARI_FLOAT32_VEC3,
            [4, 1, 1],
            std::ptr::null(),
            None,
            std::ptr::null(),
        )
        .unwrap();
        assert_eq!(a.byte_size, 48);
        assert_eq!(a.read_vec3().unwrap(), vec![Vec3::ZERO; 4]);
        assert!(a.read_vec4().is_none());
    }

    #[test]
    fn captured_deleter_runs_once_on_drop() {
        let data = [1.0f32, 2.0, 3.0];
        let before = DELETED.load(Ordering::SeqCst);
        let a = ArrayStore::new(
            ANARI_FLOAT32,
            [3, 1, 1],
            data.as_ptr() as *const c_void,
            Some(count_deletes),
            std::ptr::null(),
        )
        .unwrap();
        assert_eq!(a.read_f32().unwrap(), vec![1.0, 2.0, 3.0]);
        drop(a);
        assert_eq!(DELETED.load(Ordering::SeqCst), before + 1);
    }

    #[test]
    fn index_arrays_read_as_tuples_of_32_or_64_bit_values() {
        let narrow = [1u32, 2, 3, 4, 5, 6];
        let a = ArrayStore::new(
            ANARI_UINT32_VEC3,
            [2, 1, 1],
            narrow.as_ptr() as *const c_void,
            None,
            std::ptr::null(),
        )
        .unwrap();
        let triples = a.read_indices(3, glam::UVec3::from_slice).unwrap();
        assert_eq!(
            triples,
            [glam::UVec3::new(1, 2, 3), glam::UVec3::new(4, 5, 6)]
        );
        // Other component counts do not match the element type.
        assert!(a.read_indices(2, glam::UVec2::from_slice).is_none());
        // 64-bit values beyond u32 range become u32::MAX, out of range for any geometry.
        let wide = [7u64, u64::from(u32::MAX) + 1, 9, 10];
        let a = ArrayStore::new(
            ANARI_UINT64_VEC2,
            [2, 1, 1],
            wide.as_ptr() as *const c_void,
            None,
            std::ptr::null(),
        )
        .unwrap();
        let pairs = a.read_indices(2, glam::UVec2::from_slice).unwrap();
        assert_eq!(
            pairs,
            [glam::UVec2::new(7, u32::MAX), glam::UVec2::new(9, 10)]
        );
        let singles = a.read_indices(1, |value| value[0]);
        assert!(singles.is_none());
    }

    #[test]
    fn overflowing_sizes_are_rejected() {
        let r = ArrayStore::new(
            ANARI_FLOAT32_VEC4,
            [u64::MAX / 2, 4, 1],
            std::ptr::null(),
            None,
            std::ptr::null(),
        );
        assert_eq!(r.err(), Some(ArrayError::TooLarge));
        let r = ArrayStore::new(12345, [1, 1, 1], std::ptr::null(), None, std::ptr::null());
        assert_eq!(r.err(), Some(ArrayError::InvalidType));
    }

    #[test]
    fn srgb_bytes_decode_to_linear_attributes() {
        let data: [u8; 4] = [255, 0, 188, 128];
        let a = ArrayStore::new(
            ANARI_UFIXED8_RGBA_SRGB,
            [1, 1, 1],
            data.as_ptr() as *const c_void,
            None,
            std::ptr::null(),
        )
        .unwrap();
        let v = a.read_attribute().unwrap()[0];
        assert!((v.x - 1.0).abs() < 1e-6 && v.y == 0.0);
        assert!((v.z - 0.5029).abs() < 2e-3, "{}", v.z);
        assert!((v.w - 128.0 / 255.0).abs() < 1e-6);
    }
}
