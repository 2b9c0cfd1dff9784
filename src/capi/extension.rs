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
            "cavetraceOffAxisMatrices" => {
                std::mem::transmute::<
                    extern "C" fn(
                        *const f32,
                        *const f32,
                        *const f32,
                        *const f32,
                        f32,
                        f32,
                        *mut f32,
                        *mut f32,
                    ) -> i32,
                    unsafe extern "C" fn(),
                >(crate::capi::offaxis::cavetraceOffAxisMatrices)
            }
            "cavetraceOffAxisPerspective" => {
                std::mem::transmute::<
                    extern "C" fn(
                        *const f32,
                        *const f32,
                        *const f32,
                        *const f32,
                        *mut f32,
                        *mut f32,
                        *mut f32,
                        *mut f32,
                        *mut f32,
                        *mut f32,
                    ) -> i32,
                    unsafe extern "C" fn(),
                >(crate::capi::offaxis::cavetraceOffAxisPerspective)
            }
            "cavetracePerspectiveFromMatrices" => {
                std::mem::transmute::<
                    extern "C" fn(
                        *const f32,
                        *const f32,
                        *mut f32,
                        *mut f32,
                        *mut f32,
                        *mut f32,
                        *mut f32,
                        *mut f32,
                    ) -> i32,
                    unsafe extern "C" fn(),
                >(crate::capi::offaxis::cavetracePerspectiveFromMatrices)
            }
            _ => return None,
        }
    };
    Some(address)
}
