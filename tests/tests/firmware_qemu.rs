//! The firmware on an emulated Cortex-M4F: builds `firmware/` for thumbv7em-none-eabihf, runs it
//! under `qemu-system-arm` (mps2-an386) through `firmware/run.sh`, and checks its exit status
//! (0 only when its f32 outcome equals the host's `onboard/expected.bin` bit for bit) and its
//! decoded defmt log. Skips, saying so, when QEMU, the target or defmt-print is missing, unless
//! `CALIB_REQUIRE_QEMU=1` (as `.ci/run` sets), where a missing tool is a failure.

use std::process::Command;

fn have(program: &str, args: &[&str]) -> bool {
    Command::new(program)
        .args(args)
        .output()
        .is_ok_and(|o| o.status.success())
}

#[test]
fn firmware_calibrates_in_qemu_bit_identically() {
    let target_installed = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("thumbv7em-none-eabihf"));
    let missing: Vec<&str> = [
        ("qemu-system-arm", have("qemu-system-arm", &["--version"])),
        ("defmt-print", have("defmt-print", &["--version"])),
        (
            "arm-none-eabi-size",
            have("arm-none-eabi-size", &["--version"]),
        ),
        ("the thumbv7em-none-eabihf target", target_installed),
    ]
    .into_iter()
    .filter(|(_, ok)| !ok)
    .map(|(name, _)| name)
    .collect();
    if !missing.is_empty() {
        let message = format!(
            "SKIPPED firmware_calibrates_in_qemu_bit_identically: missing {} \
             (apt-get install qemu-system-arm binutils-arm-none-eabi; cargo install defmt-print --locked; \
             rustup target add thumbv7em-none-eabihf)",
            missing.join(", ")
        );
        assert!(
            std::env::var("CALIB_REQUIRE_QEMU").as_deref() != Ok("1"),
            "{message}"
        );
        eprintln!("{message}");
        return;
    }
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../firmware/run.sh");
    let mut command = Command::new("bash");
    command.arg(script).arg("--size");
    // The outer cargo's settings must not leak into the firmware's own build.
    for (key, _) in std::env::vars() {
        if key.starts_with("CARGO") || key == "RUSTFLAGS" || key == "RUSTC_WRAPPER" {
            command.env_remove(key);
        }
    }
    let output = command.output().unwrap();
    let log = String::from_utf8_lossy(&output.stdout);
    println!("{log}\n{}", String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "firmware failed");
    assert!(
        log.contains("outcome equals the host's bit for bit: PASS"),
        "{log}"
    );
    assert!(log.contains("IPSO: 2000 generations"), "{log}");
    // The models with joint maps, and with maps and compliance: loaded from their blocks, 4
    // targets compensated with each (the bits are the host's: part of the PASS above).
    assert!(log.contains("30 harmonics per joint"), "{log}");
    for what in ["maps", "compliance"] {
        let line = format!("compensated with {what}: joints");
        assert_eq!(log.matches(&line).count(), 4, "{line}: {log}");
    }
    // The decoded statistics are the host's (same job, same bits).
    let host = calib_onboard::run(&mut calib_onboard::NoMarks).unwrap();
    for (name, table) in [("before", host.before), ("after", host.after)] {
        let line = format!(
            "{name} calibration: position mean {} std {} max {} mm",
            table[0], table[1], table[2]
        );
        assert!(log.contains(&line), "{line}\n{log}");
    }
    // The instruction counter is calibrated against a loop of known length.
    let counted = number_after(&log, "100000 x (nop, subs, bne) counted as ");
    assert!(counted.abs_diff(300_000) <= 40, "{counted}");
    // The controller budgets (issue 7). Instruction counts under `-icount` are deterministic, so
    // these are exact measurements, not timings.
    let budgets = [
        (
            "flash (vector table + text + rodata): ",
            64 * 1024,
            "flash, bytes",
        ),
        (
            "forward kinematics (6 joints, f32, with sin/cos of q): ",
            3_000,
            "forward kinematics, instructions",
        ),
        ("whole swarm ", 1_500_000_000, "whole swarm, instructions"),
        ("slowest ", 30_000, "one compensation, instructions"),
        (
            "slowest with maps ",
            40_000,
            "one compensation with joint maps, instructions",
        ),
        (
            "slowest with compliance ",
            40_000,
            "one compensation with joint maps and compliance, instructions",
        ),
        (
            "model block with maps: ",
            8 * 1024,
            "the model's block, bytes",
        ),
        (
            "model block with compliance: ",
            8 * 1024,
            "the block with compliance, bytes",
        ),
    ];
    for (prefix, budget, what) in budgets {
        let measured = number_after(&log, prefix);
        assert!(measured <= budget, "{what}: {measured} > {budget}");
    }
    let ram = number_after(&log, "static RAM (data + bss): ") + number_after(&log, "peak stack ");
    assert!(ram <= 24 * 1024, "RAM {ram} bytes > 24 KiB");
}

/// The integer that follows `prefix` in the firmware's log.
fn number_after(log: &str, prefix: &str) -> u64 {
    log.split(prefix)
        .nth(1)
        .and_then(|rest| rest.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no number after {prefix:?} in the log:\n{log}"))
}
