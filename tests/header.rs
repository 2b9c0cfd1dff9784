//! The committed C header must equal a fresh cbindgen generation.
//! Regenerate with: UPDATE_HEADER=1 cargo test --test header

use std::path::PathBuf;

#[test]
fn committed_header_is_up_to_date() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(root.join("cbindgen.toml")).expect("cbindgen.toml");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(&root)
        .with_config(config)
        .generate()
        .expect("cbindgen generation")
        .write(&mut generated);
    let generated = String::from_utf8(generated).unwrap();
    let path = root.join("include/cavetrace.h");
    if std::env::var_os("UPDATE_HEADER").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    // Only the API's own names: internal Rust constants must not leak into the C header.
    for line in generated.lines().filter(|l| l.starts_with("#define ")) {
        let name = line.split_whitespace().nth(1).unwrap_or("");
        assert!(
            name.starts_with("ANARI_") || name == "CAVETRACE_H",
            "internal constant in the header: {line} (exclude it in cbindgen.toml)"
        );
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/cavetrace.h is stale: run `UPDATE_HEADER=1 cargo test --test header` and commit it"
    );
}
