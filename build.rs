//! Gives the shared library a versioned soname, so that programs linked against an installed
//! libcavetrace.so load libcavetrace.so.0 (see scripts/install.sh).

fn main() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,libcavetrace.so.0");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
