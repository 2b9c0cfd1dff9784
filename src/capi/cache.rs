//! Storage for pointers handed out by introspection calls. ANARI lets applications keep these
//! pointers for the life of the library, so each distinct answer is built once and kept; the
//! set of answers is bounded by the device's tables.

use std::collections::HashMap;
use std::ffi::{CString, c_char};
use std::sync::{Mutex, OnceLock};

fn cache() -> &'static Mutex<HashMap<String, usize>> {
    static CACHE: OnceLock<Mutex<HashMap<String, usize>>> = OnceLock::new();
    CACHE.get_or_init(Default::default)
}

/// The address stored under `key`, built by `make` (which leaks what it builds) on first use.
pub fn cached(key: String, make: impl FnOnce() -> usize) -> usize {
    let mut map = cache().lock().unwrap_or_else(|e| e.into_inner());
    *map.entry(key).or_insert_with(make)
}

/// A NUL-terminated copy of `s` that lives forever.
pub fn leak_c_string(s: &str) -> *const c_char {
    let owned = CString::new(s.replace('\0', " ")).unwrap_or_default();
    Box::leak(owned.into_boxed_c_str()).as_ptr()
}

/// A NULL-terminated array of C strings that lives forever, as a `const char**` address.
pub fn leak_string_list(items: &[&str]) -> usize {
    let mut pointers: Vec<usize> = items.iter().map(|s| leak_c_string(s) as usize).collect();
    pointers.push(0);
    Box::leak(pointers.into_boxed_slice()).as_ptr() as usize
}

/// Leaks a copy of `values` and returns its address.
pub fn leak_slice<T: Copy>(values: &[T]) -> usize {
    Box::leak(values.to_vec().into_boxed_slice()).as_ptr() as usize
}
