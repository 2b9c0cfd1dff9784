//! `libanari_library_cavetrace.so`: the cavetrace device as the Khronos ANARI SDK loads it.
//! `anariLoadLibrary("cavetrace")` in an application linked with the SDK's `libanari.so` dlopens
//! this file and calls `anari_library_cavetrace_new_library`; everything behind that entry point
//! lives in `cavetrace::sdk`.

pub use cavetrace::sdk::anari_library_cavetrace_new_library;
