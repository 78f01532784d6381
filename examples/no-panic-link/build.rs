//! Keeps the reset vector and the exported `exercise` through the linker's garbage
//! collection: without them nothing is linked, and no panic path could be found.
fn main() {
    println!("cargo:rustc-link-arg-bins=--entry=Reset");
    println!("cargo:rustc-link-arg-bins=--undefined=exercise");
}
