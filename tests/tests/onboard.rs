//! The controller's calibration job (`calib-onboard`, f32) on the host: its outcome is the
//! expected value the firmware checks bit for bit (`onboard/expected.bin`, regenerated with
//! `CALIB_UPDATE_EXPECTED=1 cargo test -p calib-tests --test onboard`), and it is checked here
//! against the true errors of the simulation and against the f64 core on the same data.

use calib_core::Problem;
use calib_core::identify::lm::{LeastSquares, LmSettings};
use calib_core::identify::objective::{DEFAULT_K, Measurement};
use calib_core::model::paper;
use calib_core::{ParameterErrors, ParameterSet};
use calib_onboard::{D, EXPECTED, NoMarks, run};
use nalgebra::SVector;

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
            "onboard/expected.bin is stale: regenerate it with CALIB_UPDATE_EXPECTED=1 cargo test -p calib-tests --test onboard"
        );
    }
    println!("{outcome:?}");
    // Against the truth (Table 2): 0.02 mm and 1e-4 rad tracker noise on 32 poses.
    let robot = paper::er10l_c10::<f64>();
    let set = ParameterSet::<6, D>::default_for(&robot).unwrap();
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
    let measurements: Vec<Measurement<f64, 6>> = calib_onboard::measurements()
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
    let (length, angle) = set.largest_differences(&job, &x64);
    println!("f32 job vs f64 core: {length:.3e} mm, {angle:.3e} rad");
    assert!(length < 5e-3 && angle < 1e-5, "{length} {angle}");
}

/// The joint angle back from its sine and cosine (the f32 measurement stores those).
fn libm_atan2(s: f32, c: f32) -> f32 {
    s.atan2(c)
}
