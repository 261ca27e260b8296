//! The committed C header `include/calib.h` is what cbindgen generates from the sources now:
//! fails on any difference (with `CALIB_UPDATE_HEADER=1` it rewrites the header instead).

// A test's helpers may panic: a failure is the test's result.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use std::path::Path;

#[test]
fn committed_header_equals_the_generated_one() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).unwrap();
    let bindings = cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .unwrap();
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let generated = String::from_utf8(generated).unwrap();
    let path = crate_dir.join("include/calib.h");
    if std::env::var("CALIB_UPDATE_HEADER").as_deref() == Ok("1") {
        std::fs::write(&path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/calib.h differs from what cbindgen generates from calib-ffi/src; regenerate it \
         with CALIB_UPDATE_HEADER=1 cargo test -p calib-ffi --test header and commit it"
    );
    // The constants a C caller sizes its memory with are in the header.
    for name in [
        "CALIB_JOINTS",
        "CALIB_HARMONICS",
        "CALIB_MODEL_F32_WORDS",
        "CALIB_ROBOT_F32_WORDS",
        "CALIB_BLOCK_MAX_BYTES_F32",
        "CALIB_API_VERSION_MAJOR",
    ] {
        assert!(generated.contains(&format!("#define {name} ")), "{name}");
    }
}
