//! Link arguments of libanari_library_cavetrace.so (ELF targets):
//!
//! - its own soname, `libanari_library_cavetrace.so`, the file name the SDK front end dlopens.
//!   It must not carry cavetrace's `libcavetrace.so.0`: the loader would then take it for
//!   libcavetrace.so.0 (an application's later `dlopen("libcavetrace.so.0")` would return it,
//!   and `ldconfig` would point a libcavetrace.so.0 link at it).
//! - `-Bsymbolic`: the library's references to its own exported functions bind inside the
//!   library. The SDK front end defines the same `anari*` names in the global symbol scope; a
//!   call from cavetrace's Rust code to one of its exported functions could otherwise land in
//!   the front end (ELF interposition). `cavetrace::sdk` makes no such call; this also covers the
//!   rest of the crate (e.g. the addresses anariDeviceGetProcAddress hands out).

fn main() {
    let target_os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    let target_family = std::env::var("CARGO_CFG_TARGET_FAMILY").unwrap_or_default();
    let elf = target_family == "unix" && !matches!(target_os.as_str(), "macos" | "ios");
    if elf {
        println!("cargo:rustc-link-arg-cdylib=-Wl,-soname,libanari_library_cavetrace.so");
        println!("cargo:rustc-link-arg-cdylib=-Wl,-Bsymbolic");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
