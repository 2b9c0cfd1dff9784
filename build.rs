//! Gives libcavetrace.so a versioned soname, so that programs linked against an installed
//! libcavetrace.so load libcavetrace.so.0 (see scripts/install.sh).
//!
//! The argument is `rustc-link-arg`, which Cargo passes only when linking this package's own
//! targets, not `rustc-link-arg-cdylib`: Cargo also hands a dependency's cdylib link arguments to
//! every dependent cdylib (rust-lang/cargo#9562), and after the dependent's own arguments, so
//! libanari_library_cavetrace.so would be linked as libcavetrace.so.0 whatever its own build
//! script says. The price: this package's test and bench executables carry the soname too, which
//! matters only if one of them dlopens "libcavetrace.so.0" by that bare name (none does).

fn main() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-link-arg=-Wl,-soname,libcavetrace.so.0");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
