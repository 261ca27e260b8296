//! Puts the repository's `memory.x` (QEMU mps2-an386) where the linker finds it, and relinks
//! when it changes.

fn main() {
    let out = std::env::var("OUT_DIR").unwrap_or_else(|_| ".".into());
    if let Err(e) = std::fs::copy("../memory.x", format!("{out}/memory.x")) {
        println!("cargo:warning=cannot copy ../memory.x: {e}");
    }
    println!("cargo:rustc-link-search={out}");
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
}
