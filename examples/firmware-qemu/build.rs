//! Build script for the QEMU firmware harness.
//!
//! 1. Puts `memory.x` on the linker search path (cortex-m-rt's `link.x` INCLUDEs it).
//! 2. Stages the two data files the firmware embeds with `include_bytes!`:
//!    * `$OUT_DIR/model.bin`      <- `$FOGTEMP_FW_MODEL`      (default: data/model.fogm)
//!    * `$OUT_DIR/trajectory.bin` <- `$FOGTEMP_FW_TRAJECTORY` (default: data/trajectory.bin)
//!
//!    Relative paths are taken relative to this crate's directory. The defaults are the
//!    committed fixture written by the root test `tests/firmware_fixture.rs`.

use std::env;
use std::fs;
use std::path::{Path, PathBuf};

fn stage(out: &Path, manifest: &Path, var: &str, default: Option<&str>, dest: &str) {
    println!("cargo:rerun-if-env-changed={var}");
    let src = env::var_os(var).map(PathBuf::from).or_else(|| default.map(PathBuf::from)).map(|p| {
        if p.is_absolute() {
            p
        } else {
            manifest.join(p)
        }
    });
    let bytes = match src {
        Some(p) => {
            println!("cargo:rerun-if-changed={}", p.display());
            fs::read(&p).unwrap_or_else(|e| panic!("{var}: cannot read {}: {e}", p.display()))
        }
        None => Vec::new(),
    };
    fs::write(out.join(dest), bytes).expect("write staged data file");
}

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));

    fs::copy(manifest.join("memory.x"), out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");

    stage(&out, &manifest, "FOGTEMP_FW_MODEL", Some("data/model.fogm"), "model.bin");
    stage(&out, &manifest, "FOGTEMP_FW_TRAJECTORY", Some("data/trajectory.bin"), "trajectory.bin");
}
