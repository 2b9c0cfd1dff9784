//! cavetrace's own C functions, reachable by name through anariDeviceGetProcAddress.

use crate::capi::introspect::ANARIProcAddress;

/// The address of a cavetrace function by its C name.
pub fn lookup(name: &str) -> ANARIProcAddress {
    // SAFETY: each entry is an `extern "C"` function; callers cast the pointer back to its real
    // signature, as anariDeviceGetProcAddress requires.
    let address: unsafe extern "C" fn() = unsafe {
        match name {
            "cavetraceLiveDeviceCount" => {
                std::mem::transmute::<extern "C" fn() -> u64, unsafe extern "C" fn()>(
                    crate::capi::object::cavetraceLiveDeviceCount,
                )
            }
            _ => return None,
        }
    };
    Some(address)
}
