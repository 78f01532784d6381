//! `include/fogtemp.h` is what cbindgen generates from `src/lib.rs` today: regenerate and
//! compare, so a stale committed header fails CI. `FOGTEMP_BLESS=1` rewrites it.
#![allow(clippy::expect_used, clippy::panic)] // test code: a failed expectation is the test failing

use std::path::PathBuf;

#[test]
fn committed_header_matches_cbindgen() {
    let crate_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(&crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header")
        .write(&mut generated);
    let path = crate_dir.join("include/fogtemp.h");
    if std::env::var_os("FOGTEMP_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("write include/fogtemp.h");
        return;
    }
    let committed = std::fs::read(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/fogtemp.h is stale: regenerate with `FOGTEMP_BLESS=1 cargo test -p fogtemp-ffi --test header`\n\
         ---- generated ----\n{}",
        String::from_utf8_lossy(&generated)
    );
}
