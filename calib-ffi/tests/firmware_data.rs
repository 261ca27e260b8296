//! The data of the C firmware and of the host C test (`firmware-c/src/calib_data.h`): the
//! parameter blocks (`calib export --format block` of the robot files, through the same library
//! function), the targets' joints, and the joints the host computes for them with this library
//! (the Rust core through the C API), which the C programs must reproduce bit for bit. Fails when
//! the committed file differs (with `CALIB_UPDATE_EXPECTED=1` it rewrites it), and checks the
//! expected joints against the f64 core.

// A test's helpers may panic: a failure is the test's result.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use calib_ffi::*;
use host_tools::formats::export::{BlockScalar, parameter_block};
use host_tools::io::robot_file::{RobotFile, RobotModel};
use std::fmt::Write as _;
use std::path::Path;

/// Joint readings of the targets, rad: within Series B's ranges, where the maps were identified
/// (the Rust firmware's targets).
const TARGET_JOINTS: [[f32; 6]; 4] = [
    [-1.7, -1.0, 0.4, -1.8, -1.0, 0.2],
    [-1.4, -1.6, 1.2, -1.2, -0.8, 0.4],
    [-2.2, -0.5, -0.6, -2.5, -1.6, -0.3],
    [-1.2, -2.0, 1.8, -0.6, -0.4, 0.5],
];

fn export(file: &str, scalar: BlockScalar, sequence: u32) -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(file);
    let robot_file = RobotFile::read(&path).unwrap();
    let model: RobotModel = robot_file.to_model(&path).unwrap();
    let maps = robot_file.joint_maps(&path).unwrap();
    let compliance = robot_file.gravity_compliance(&path, 6).unwrap();
    parameter_block(
        &model.robot,
        maps.as_ref(),
        compliance.as_ref(),
        scalar,
        sequence,
    )
    .unwrap()
}

/// The joints that put `block`'s model on each target (the nominal pose at the target's joints),
/// in f32, through the C API.
fn compensated(nominal_block: &[u8], targets: &[CalibPoseF32], block: &[u8]) -> Vec<[f32; 6]> {
    let robot = nominal_robot(nominal_block);
    let mut model: CalibModelF32 = unsafe { std::mem::zeroed() };
    unsafe {
        assert_eq!(
            calib_model_decode_f32(
                &mut model,
                block.as_ptr(),
                block.len(),
                std::ptr::null_mut()
            ),
            CalibStatus::Ok
        );
    }
    TARGET_JOINTS
        .iter()
        .zip(targets)
        .map(|(q, target)| unsafe {
            let mut result: CalibCompensatedF32 = std::mem::zeroed();
            let status = calib_compensate_joints_f32(
                &robot,
                &model,
                target,
                q.as_ptr(),
                std::ptr::null(),
                &mut result,
            );
            assert_eq!(status, CalibStatus::Ok);
            // The whole model at the result is on the target (f32 tolerance 1e-2 mm) and was
            // not there before (mm-level errors: the compensation did something).
            let mut reached: CalibPoseF32 = std::mem::zeroed();
            calib_model_forward_f32(&model, result.q.as_ptr(), &mut reached);
            let miss = distance(&reached, target);
            calib_model_forward_f32(&model, q.as_ptr(), &mut reached);
            let uncorrected = distance(&reached, target);
            println!("target {q:?}: uncorrected {uncorrected:.3} mm, compensated {miss:.2e} mm");
            assert!(miss <= 1e-2 && uncorrected > 0.3, "{miss} {uncorrected}");
            result.q
        })
        .collect()
}

fn nominal_robot(nominal_block: &[u8]) -> CalibRobotF32 {
    let mut robot: CalibRobotF32 = unsafe { std::mem::zeroed() };
    unsafe {
        assert_eq!(
            calib_robot_decode_f32(&mut robot, nominal_block.as_ptr(), nominal_block.len()),
            CalibStatus::Ok
        );
    }
    robot
}

/// The nominal robot's pose at each target's joints (the targets), through the C API.
fn target_poses(nominal_block: &[u8]) -> Vec<CalibPoseF32> {
    let robot = nominal_robot(nominal_block);
    TARGET_JOINTS
        .iter()
        .map(|q| unsafe {
            let mut target: CalibPoseF32 = std::mem::zeroed();
            assert_eq!(
                calib_robot_forward_f32(&robot, q.as_ptr(), &mut target),
                CalibStatus::Ok
            );
            target
        })
        .collect()
}

fn distance(a: &CalibPoseF32, b: &CalibPoseF32) -> f64 {
    a.position_mm
        .iter()
        .zip(&b.position_mm)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
        .sum::<f64>()
        .sqrt()
}

fn bytes(out: &mut String, name: &str, source: &str, data: &[u8]) {
    writeln!(out, "/* {source} ({} bytes) */", data.len()).unwrap();
    writeln!(out, "static const uint8_t {name}[{}] = {{", data.len()).unwrap();
    for line in data.chunks(16) {
        let items: Vec<String> = line.iter().map(|b| format!("0x{b:02x}")).collect();
        writeln!(out, "    {},", items.join(", ")).unwrap();
    }
    writeln!(out, "}};\n").unwrap();
}

fn bits<const W: usize>(out: &mut String, name: &str, comment: &str, rows: &[[f32; W]]) {
    writeln!(out, "/* {comment} */").unwrap();
    let width = if W == 6 {
        "CALIB_JOINTS"
    } else {
        "POSE_VALUES"
    };
    writeln!(out, "static const uint32_t {name}[TARGETS][{width}] = {{").unwrap();
    for row in rows {
        let items: Vec<String> = row
            .iter()
            .map(|v| format!("0x{:08x}u", v.to_bits()))
            .collect();
        writeln!(out, "    {{{}}},", items.join(", ")).unwrap();
    }
    writeln!(out, "}};\n").unwrap();
}

#[test]
fn firmware_data_are_the_exports_and_the_host_results() {
    let nominal = export("host-tools/robots/ur10.toml", BlockScalar::F32, 1);
    let maps = export("onboard/data/ur10-series-b-maps.toml", BlockScalar::F32, 1);
    let compliance = export(
        "onboard/data/ur10-series-b-compliance.toml",
        BlockScalar::F32,
        2,
    );
    let geometric = export(
        "firmware-c/data/ur10-series-b-geometric.toml",
        BlockScalar::F32,
        1,
    );
    let nominal64 = export("host-tools/robots/ur10.toml", BlockScalar::F64, 1);
    let compliance64 = export(
        "onboard/data/ur10-series-b-compliance.toml",
        BlockScalar::F64,
        1,
    );
    let targets = target_poses(&nominal);
    let with_geometry = compensated(&nominal, &targets, &geometric);
    let with_compliance = compensated(&nominal, &targets, &compliance);
    let with_maps = compensated(&nominal, &targets, &maps);

    let mut out = String::new();
    out.push_str(
        "/* calib_data.h: data of the C firmware and the host C test. Generated by\n \
         * calib-ffi/tests/firmware_data.rs (CALIB_UPDATE_EXPECTED=1 cargo test -p calib-ffi\n \
         * --test firmware_data); do not edit. The blocks are `calib export --format block` of\n \
         * the files named; the expected joints are the host's f32 results (the Rust core through\n \
         * the same C API), as IEEE-754 bit patterns. */\n\
         #ifndef CALIB_DATA_H\n#define CALIB_DATA_H\n\n#include <stdint.h>\n#include \"calib.h\"\n\n\
         #define TARGETS 4\n/* A pose as 12 floats: position (mm), then the row-major rotation. */\n\
         #define POSE_VALUES 12\n\n",
    );
    let files = [
        (
            "NOMINAL_F32",
            "host-tools/robots/ur10.toml, --scalar f32, --sequence 1",
            &nominal,
        ),
        (
            "GEOMETRIC_F32",
            "firmware-c/data/ur10-series-b-geometric.toml, --scalar f32, --sequence 1",
            &geometric,
        ),
        (
            "MAPS_F32",
            "onboard/data/ur10-series-b-maps.toml, --scalar f32, --sequence 1",
            &maps,
        ),
        (
            "COMPLIANCE_F32",
            "onboard/data/ur10-series-b-compliance.toml, --scalar f32, --sequence 2",
            &compliance,
        ),
        (
            "NOMINAL_F64",
            "host-tools/robots/ur10.toml, --scalar f64, --sequence 1",
            &nominal64,
        ),
        (
            "COMPLIANCE_F64",
            "onboard/data/ur10-series-b-compliance.toml, --scalar f64, --sequence 1",
            &compliance64,
        ),
    ];
    for (name, source, data) in files {
        bytes(&mut out, name, source, data);
    }
    bits(
        &mut out,
        "TARGET_JOINTS",
        "joint readings of the targets, rad",
        &TARGET_JOINTS,
    );
    let poses: Vec<[f32; 12]> = targets
        .iter()
        .map(|p| {
            let mut v = [0.0; 12];
            v[..3].copy_from_slice(&p.position_mm);
            v[3..].copy_from_slice(&p.rotation);
            v
        })
        .collect();
    bits(
        &mut out,
        "TARGET_POSES",
        "the targets: NOMINAL_F32's pose at TARGET_JOINTS (position mm, row-major rotation)",
        &poses,
    );
    bits(
        &mut out,
        "EXPECTED_GEOMETRIC",
        "compensated joints with GEOMETRIC_F32 (geometry only), rad",
        &with_geometry,
    );
    bits(
        &mut out,
        "EXPECTED_COMPLIANCE",
        "compensated joints with COMPLIANCE_F32 (maps and gravity compliance), rad",
        &with_compliance,
    );
    bits(
        &mut out,
        "EXPECTED_MAPS",
        "compensated joints with MAPS_F32 (maps), rad",
        &with_maps,
    );
    out.push_str("#endif /* CALIB_DATA_H */\n");

    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware-c/src/calib_data.h");
    if std::env::var("CALIB_UPDATE_EXPECTED").as_deref() == Ok("1") {
        std::fs::write(&path, &out).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == out,
        "firmware-c/src/calib_data.h is stale: regenerate it with CALIB_UPDATE_EXPECTED=1 cargo \
         test -p calib-ffi --test firmware_data and commit it"
    );
    // The onboard firmware's blocks are the same exports.
    let onboard = |f: &str| {
        std::fs::read(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../onboard/data")
                .join(f),
        )
        .unwrap()
    };
    assert!(onboard("ur10-nominal.calb") == nominal);
    assert!(onboard("ur10-series-b-maps.calb") == maps);
}
