//! The Khronos ANARI SDK's device interface. Applications linked with the SDK's front end
//! (`libanari.so`) pick cavetrace with `anariLoadLibrary("cavetrace")`: the front end dlopens
//! `libanari_library_cavetrace.so`, calls `anari_library_cavetrace_new_library`, and from then
//! on calls C++ virtual functions on the objects it gets back (`anari::LibraryImpl` and
//! `anari::DeviceImpl` of SDK 0.14–0.17). Those objects are built here by hand in the Itanium
//! C++ ABI: the first word points at a table of function pointers in the order the SDK headers
//! declare them, and each function takes the object as its first argument. Every slot forwards
//! to `crate::device`, as `crate::capi` does.
//!
//! Two rules keep this sound inside a C++ process:
//! - nothing unwinds out of a slot: each body runs under `catch_unwind`;
//! - no slot calls an exported `anari*` symbol: the front end's own `anari*` functions sit in the
//!   global symbol scope and would be called instead (ELF interposition).

mod device;
mod library;

pub use library::anari_library_cavetrace_new_library;

use std::any::Any;

/// An Itanium C++ ABI virtual table: two header words, then the slots. Objects point at `slots`.
#[repr(C)]
struct VirtualTable<Slots> {
    /// Offset from this sub-object to the complete object: 0, there is no multiple inheritance.
    offset_to_top: isize,
    /// The dynamic type's `std::type_info`. There is none (no C++ here); the SDK never applies
    /// `typeid` or `dynamic_cast` to library or device handles.
    type_info: usize,
    slots: Slots,
}

impl<Slots> VirtualTable<Slots> {
    const fn new(slots: Slots) -> Self {
        VirtualTable {
            offset_to_top: 0,
            type_info: 0,
            slots,
        }
    }
}

/// Uninitialised memory for one `T` from the C allocator, or NULL. The SDK 0.14 front end frees
/// library objects with C++ `delete` (which ends in `free`), so these objects come from `malloc`.
fn allocate<T>() -> *mut T {
    // SAFETY: malloc has no preconditions; malloc aligns for every fundamental type (align ≤ 16).
    let memory = unsafe { libc::malloc(std::mem::size_of::<T>()) } as *mut T;
    debug_assert!(memory.is_aligned());
    memory
}

/// The text of a caught panic.
fn panic_text(payload: &(dyn Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}
