//! The controller's calibration job (`calib-onboard`, f32) on the host: its outcome is the
//! expected value the firmware checks bit for bit (`onboard/expected.bin`, regenerated with
//! `CALIB_UPDATE_EXPECTED=1 cargo test -p calib-tests --test cross_crate -- onboard::`), and it
//! is checked here against the true errors of the simulation and against the f64 core on the
//! same data.

use calib_core::Problem;
use calib_core::identify::lm::{LeastSquares, LmSettings};
use calib_core::identify::objective::{DEFAULT_K, Measurement};
use calib_core::model::paper;
use calib_core::{ParameterErrors, ParameterSet};
use calib_onboard::{D, EXPECTED, NoMarks, run};
use nalgebra::SVector;
use nalgebra::U6;

/// The command that writes the expected outcomes again (named in the messages when one is stale).
const REGENERATE: &str =
    "CALIB_UPDATE_EXPECTED=1 cargo test -p calib-tests --test cross_crate -- onboard::";

#[test]
fn the_job_is_accurate_and_its_encoding_is_the_firmwares_expectation() {
    let outcome = run(&mut NoMarks).unwrap();
    let encoded = outcome.encode();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../onboard/expected.bin");
    if std::env::var_os("CALIB_UPDATE_EXPECTED").is_some() {
        std::fs::write(path, encoded).unwrap();
    } else {
        assert!(
            encoded.as_slice() == EXPECTED,
            "onboard/expected.bin is stale: regenerate it with {REGENERATE}"
        );
    }
    println!("{outcome:?}");
    // Against the truth (Table 2): 0.02 mm and 1e-4 rad tracker noise on 32 poses.
    let robot = paper::er10l_c10::<f64>();
    let set = ParameterSet::<U6, nalgebra::Const<D>>::default_for(&robot).unwrap();
    let truth = set.pack(&paper::table2::<f64>());
    for (i, (got, want)) in outcome.errors.iter().zip(truth.iter()).enumerate() {
        let tolerance = if set.parameters()[i].is_angle() {
            2e-4
        } else {
            0.1
        };
        assert!(
            (f64::from(*got) - want).abs() < tolerance,
            "{}: {got} vs {want}",
            set.parameters()[i]
        );
    }
    assert!(
        outcome.before[0] > 5.0 && outcome.after[0] < 0.05,
        "{:?} {:?}",
        outcome.before,
        outcome.after
    );
    assert_eq!(outcome.generations, 2000);
    for r in outcome.residual_mm {
        assert!(r < 0.01, "{r}");
    }

    // The f64 core on the same measurement bits reaches the same optimum.
    let measurements: Vec<Measurement<f64, U6>> = calib_onboard::measurements()
        .unwrap()
        .iter()
        .map(|m| {
            let q: [f64; 6] =
                std::array::from_fn(|i| f64::from(libm_atan2(m.angles.sin[i], m.angles.cos[i])));
            Measurement::new(
                &q,
                m.position.map(f64::from),
                m.rotation.map(|r| r.map(f64::from)),
                1.0,
            )
            .unwrap()
        })
        .collect();
    let problem = Problem::new(
        &robot,
        &ParameterErrors::zero(),
        set,
        &measurements,
        DEFAULT_K,
    )
    .unwrap();
    let least_squares = LeastSquares::new(&problem);
    let x64 = least_squares
        .solve(&SVector::zeros(), &LmSettings::default())
        .unwrap()
        .x;
    let job =
        nalgebra::SVector::<f64, D>::from_iterator(outcome.errors.iter().map(|e| f64::from(*e)));
    let (length, angle) = set.largest_differences(&job, &x64).unwrap();
    println!("f32 job vs f64 core: {length:.3e} mm, {angle:.3e} rad");
    assert!(length < 5e-3 && angle < 1e-5, "{length} {angle}");
}

/// The joint angle back from its sine and cosine (the f32 measurement stores those).
fn libm_atan2(s: f32, c: f32) -> f32 {
    s.atan2(c)
}

/// The compensation with joint maps (`calib_onboard::maps`, f32): its outcome is the firmware's
/// expectation (`onboard/expected-maps.bin`, regenerated like `expected.bin`); the embedded blocks
/// are still what `calib export` makes of their robot files; every target is reached by the
/// robot with maps as the f64 core evaluates it, and the f64 core's own compensation agrees.
#[test]
fn the_maps_job_matches_the_f64_core_and_its_encoding_is_the_firmwares_expectation() {
    use calib_onboard::maps::{MAPS_BLOCK, MAPS_EXPECTED};
    model_job_matches_the_f64_core(
        MAPS_BLOCK,
        "onboard/data/ur10-series-b-maps.toml",
        "expected-maps.bin",
        &MAPS_EXPECTED,
    );
}

/// The same job with the model with joint maps and gravity compliance (block with the compliance
/// section): the f32 firmware's joints put the f64 model, compliance included, on the targets.
#[test]
fn the_compliance_job_matches_the_f64_core_and_its_encoding_is_the_firmwares_expectation() {
    use calib_onboard::maps::{COMPLIANCE_BLOCK, COMPLIANCE_EXPECTED};
    model_job_matches_the_f64_core(
        COMPLIANCE_BLOCK,
        "onboard/data/ur10-series-b-compliance.toml",
        "expected-compliance.bin",
        &COMPLIANCE_EXPECTED,
    );
}

/// The compensation job of `calib_onboard::maps` with `block` (the export of `file`): its encoding
/// is `expected` (the bytes of `onboard/{expected_file}`, rewritten with CALIB_UPDATE_EXPECTED=1),
/// and its f32 joints put the model, evaluated by the f64 core, on the targets.
fn model_job_matches_the_f64_core(block: &[u8], file: &str, expected_file: &str, expected: &[u8]) {
    use calib_core::Kinematics;
    use calib_core::controller::compensate::{CompensationSettings, compensate_joints};
    use calib_core::controller::storage::{ControllerModel, decode, decode_model};
    use calib_core::kinematics::pose_error::PoseError;
    use calib_onboard::maps::{self, NOMINAL_BLOCK, TARGET_JOINTS};
    use host_tools::formats::export::{BlockScalar, parameter_block};
    use host_tools::io::robot_file::{RobotFile, RobotModel};
    use std::path::Path;

    let outcome = maps::compensate_with_maps(NOMINAL_BLOCK, block, &mut NoMarks).unwrap();
    let path = format!("{}/../onboard/{expected_file}", env!("CARGO_MANIFEST_DIR"));
    if std::env::var_os("CALIB_UPDATE_EXPECTED").is_some() {
        std::fs::write(path, outcome.encode()).unwrap();
    } else {
        assert!(
            outcome.matches(expected),
            "onboard/{expected_file} is stale: regenerate it with {REGENERATE}"
        );
    }
    println!("{outcome:?}");
    assert_eq!(outcome.harmonics, 30);

    // The embedded blocks are the exports of their robot files.
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    for (file, block) in [
        ("host-tools/robots/ur10.toml", NOMINAL_BLOCK),
        (file, block),
    ] {
        let path = Path::new(dir).join(file);
        let robot_file = RobotFile::read(&path).unwrap();
        let model: RobotModel = robot_file.to_model(&path).unwrap();
        let maps = robot_file.joint_maps(&path).unwrap();
        let compliance = robot_file.gravity_compliance(&path, 6).unwrap();
        let exported = parameter_block(
            &model.robot,
            maps.as_ref(),
            compliance.as_ref(),
            BlockScalar::F32,
            1,
        )
        .unwrap();
        assert!(exported == block, "{file}: the embedded block is stale");
    }

    // The f64 core with the block's values (f32 -> f64 is exact).
    let (nominal32, _) = decode::<f32, U6>(NOMINAL_BLOCK).unwrap();
    let (model32, _) = decode_model::<f32, U6, 64>(block).unwrap();
    let widen = |file_robot: &calib_core::Robot<f32, U6>| calib_core::Robot::<f64, U6> {
        joints: file_robot.joints.map(|j| calib_core::MdhJoint {
            a: f64::from(j.a),
            alpha: f64::from(j.alpha),
            theta_offset: f64::from(j.theta_offset),
            d: f64::from(j.d),
            beta: f64::from(j.beta),
        }),
        limits: file_robot.limits.map(|l| calib_core::JointLimits {
            lower: f64::from(l.lower),
            upper: f64::from(l.upper),
        }),
        base: calib_core::FramePose {
            xyz: file_robot.base.xyz.map(f64::from),
            rpy: file_robot.base.rpy.map(f64::from),
        },
        tool: calib_core::FramePose {
            xyz: file_robot.tool.xyz.map(f64::from),
            rpy: file_robot.tool.rpy.map(f64::from),
        },
    };
    let h = model32.maps.harmonics();
    let sin = std::array::from_fn(|j| {
        std::array::from_fn(|k| f64::from(model32.maps.sin_coefficients(j).unwrap()[k]))
    });
    let cos = std::array::from_fn(|j| {
        std::array::from_fn(|k| f64::from(model32.maps.cos_coefficients(j).unwrap()[k]))
    });
    let model64: ControllerModel<f64, U6, 64> = ControllerModel {
        robot: widen(&model32.robot),
        maps: calib_core::model::joint_maps::JointMaps::new(h, sin, cos).unwrap(),
        compliance: widen_compliance(&model32.compliance),
    };
    assert_eq!(
        model64.compliance.is_active(),
        file.contains("compliance"),
        "{file}"
    );
    let nominal64 = Kinematics::nominal(&widen(&nominal32)).unwrap();
    let actual64 = model64.kinematics().unwrap();
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for (i, joints) in TARGET_JOINTS.iter().enumerate() {
        let start = joints.map(f64::from);
        let target = nominal64.forward(&start).unwrap();
        let q32 = outcome.compensated[i].map(f64::from);
        let reached = actual64.forward(&q32).unwrap();
        let miss = PoseError::between(&target, &reached).position.norm();
        let c64 = compensate_joints(
            &nominal64,
            &actual64,
            &widen(&nominal32).limits,
            &target,
            &start,
            &CompensationSettings::default(),
        )
        .unwrap();
        let joint_difference = c64
            .q
            .iter()
            .zip(&q32)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        // The correction itself: how far the uncompensated joints miss.
        let uncompensated = PoseError::between(&target, &actual64.forward(&start).unwrap())
            .position
            .norm();
        worst = (
            worst.0.max(miss),
            worst.1.max(joint_difference),
            worst.2.max(uncompensated),
        );
    }
    println!(
        "f32 compensation with {file}: worst miss {:.2e} mm (f64 core), joints within {:.2e} rad of the f64 core's; uncompensated up to {:.3} mm",
        worst.0, worst.1, worst.2
    );
    // The f32 tolerances are 0.01 mm and 1e-5 rad; the joints of two solutions within them differ
    // by a few times 1e-5 rad.
    assert!(worst.0 < 0.01 && worst.1 < 1e-4, "{worst:?}");
    assert!(worst.2 > 0.5, "{worst:?}");
}

/// `c` in f64 (exact).
fn widen_compliance(
    c: &calib_core::model::compliance::Compliance<f32, U6>,
) -> calib_core::model::compliance::Compliance<f64, U6> {
    use calib_core::model::compliance::{Compliance, PointMass};
    let mass = |m: &PointMass<f32>| PointMass {
        mass_kg: f64::from(m.mass_kg),
        centre_mm: m.centre_mm.map(f64::from),
    };
    Compliance::new(
        c.gravity_mps2().map(f64::from),
        c.links().each_ref().map(mass),
        mass(c.load()),
        c.gains().map(|g| g.map(f64::from)),
    )
    .unwrap()
}
