//! Gives the shared library a versioned soname, so that programs linked against an installed
//! libcavetrace.so load libcavetrace.so.0 (see scripts/install.sh). `rustc-link-arg-cdylib`
//! applies to this package's own cdylib only (the older `rustc-cdylib-link-arg` leaked into
//! dependent cdylibs such as libanari_library_cavetrace.so).

fn main() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-link-arg-cdylib=-Wl,-soname,libcavetrace.so.0");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
