//! The C firmware on an emulated Cortex-M4F: `firmware-c/run.sh --size` builds calib-ffi as a
//! static library for thumbv7em-none-eabihf (linked with panic-never's handler: the build fails
//! if any panic is reachable), compiles the C program with arm-none-eabi-gcc and runs both
//! variants under `qemu-system-arm` (mps2-an386). Each exits 0 only when its compensated joints
//! equal the host's bit for bit and every API check passed. Then the footprint goals of issue 17
//! are checked from the log and the linker map. Skips, saying so, when a tool is missing, unless
//! `CALIB_REQUIRE_QEMU=1` (as `.ci/run` sets), where a missing tool is a failure.

// A test's helpers may panic: a failure is the test's result.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

/// Bytes per output section (`.text`, `.rodata`, `.ARM.exidx`, `.data`, `.bss`) of the input
/// sections that come from the Rust static library (`libcalib_ffi.a`: the calib-ffi crate, the
/// core, nalgebra, libm and Rust's compiler builtins), read from a GNU ld map file.
fn library_sections(map: &str) -> Vec<(String, u64)> {
    let wanted = [".text", ".rodata", ".ARM.exidx", ".data", ".bss"];
    let mut sums: Vec<(String, u64)> = wanted.iter().map(|s| (s.to_string(), 0)).collect();
    let Some(start) = map.find("Linker script and memory map") else {
        panic!("not a GNU ld map file");
    };
    let mut output = String::new();
    let mut named_input = false;
    for line in map[start..].lines() {
        if line.starts_with('.') {
            // An output section: `.text  0x00000040  0x5e2c`.
            output = line.split_whitespace().next().unwrap_or("").to_string();
            named_input = false;
            continue;
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        // An input section: ` .text.name  0xADDR  0xSIZE  file`, or its name alone on one line
        // and ` 0xADDR 0xSIZE file` on the next.
        if line.starts_with(' ') && fields.len() == 1 && fields[0].starts_with('.') {
            named_input = true;
            continue;
        }
        let numbers = if line.starts_with(' ') && fields.first().is_some_and(|f| f.starts_with('.'))
        {
            fields.get(1..)
        } else if named_input {
            Some(&fields[..])
        } else {
            None
        };
        named_input = false;
        let Some([address, size, file, ..]) = numbers else {
            continue;
        };
        if !address.starts_with("0x") || !file.contains("libcalib_ffi.a") {
            continue;
        }
        let size = u64::from_str_radix(size.trim_start_matches("0x"), 16).unwrap_or(0);
        if let Some((_, sum)) = sums.iter_mut().find(|(name, _)| *name == output) {
            *sum += size;
        }
    }
    sums
}

#[test]
fn c_firmware_compensates_in_qemu_bit_identically_within_its_budgets() {
    if !calib_tests::embedded_tools_present(
        "c_firmware_compensates_in_qemu_bit_identically_within_its_budgets",
        &["qemu-system-arm", "arm-none-eabi-gcc", "arm-none-eabi-size"],
        "apt-get install qemu-system-arm gcc-arm-none-eabi binutils-arm-none-eabi; rustup target add thumbv7em-none-eabihf",
    ) {
        return;
    }
    let (log, success) = calib_tests::run_firmware_script("firmware-c/run.sh");
    assert!(success, "the C firmware failed (see its log above)");
    // Both variants ran every check and passed (the joints equal the host's bit for bit).
    assert_eq!(log.matches("failed checks: 0").count(), 2, "{log}");
    assert_eq!(log.matches("\nPASS").count(), 2, "{log}");
    assert!(!log.contains("FAIL"), "{log}");

    // The compensation-only variant's log comes first.
    let compensation = log
        .split("== calib-firmware-c\n")
        .next()
        .unwrap_or_default();
    let counted = calib_tests::number_after(compensation, "counter check (300000 instructions):");
    assert!(counted.abs_diff(300_000) <= 40, "counter: {counted}");
    let slowest =
        calib_tests::number_after(compensation, "geometric compensation slowest instructions:");
    assert!(
        slowest <= 30_000,
        "one compensation: {slowest} > 30,000 instructions"
    );
    let stack = [
        "peak stack of decoding the robot and loading a model (bytes):",
        "peak stack of a geometric compensation (bytes):",
        "peak stack of loading two slots (bytes):",
        "peak stack of a compensation with maps and compliance (bytes):",
    ]
    .iter()
    .map(|label| calib_tests::number_after(compensation, label))
    .max()
    .unwrap_or(0);

    let map = std::fs::read_to_string(calib_tests::repo(
        "target/firmware-c/calib-firmware-c-compensation.map",
    ))
    .unwrap();
    let sections = library_sections(&map);
    let bytes = |name: &str| {
        sections
            .iter()
            .find(|(s, _)| s == name)
            .map_or(0, |(_, n)| *n)
    };
    let flash = bytes(".text") + bytes(".rodata") + bytes(".ARM.exidx");
    let static_ram = bytes(".data") + bytes(".bss");
    println!(
        "library in the compensation-only firmware: flash {flash} bytes (text {}, rodata {}), \
         static RAM {static_ram} bytes, peak stack {stack} bytes",
        bytes(".text"),
        bytes(".rodata")
    );
    assert!(
        bytes(".text") > 10_000,
        "the map was not read: {sections:?}"
    );
    // Issue 56: at least 2 KiB free under the library's 24 KiB budget (22,443 bytes).
    assert!(flash <= 22 * 1024, "library flash {flash} > 22 KiB");
    assert_eq!(static_ram, 0, "the library has no global state");
    assert!(
        static_ram + stack <= 4 * 1024,
        "library RAM: static {static_ram} + peak stack {stack} > 4 KiB"
    );
}
