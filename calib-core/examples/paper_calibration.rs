//! The paper's experiment with calib-core alone: the ER10L-C10 with the errors of Table 2 as the
//! real robot, 32 exact 6-DoF poses, identified by the paper's improved particle swarm (20
//! particles, 2000 generations) and refined by least squares. Checks its own result: every one of
//! the 24 errors within 1e-6 mm and 1e-9 rad of Table 2.
//!
//! `cargo run --release -p calib-core --example paper_calibration`

use calib_core::identify::ipso::{self, IpsoSettings, SearchSpace, Silent};
use calib_core::identify::lm::LmSettings;
use calib_core::model::paper;
use calib_core::{
    Kinematics, LeastSquares, Measurement, Objective, ParameterErrors, ParameterSet, Problem,
};
use nalgebra::U6;
use nalgebra::U24;
use std::process::ExitCode;

fn main() -> Result<ExitCode, Box<dyn std::error::Error>> {
    let robot = paper::er10l_c10::<f64>();
    let truth = paper::table2::<f64>();
    let real = Kinematics::new(&robot, &truth)?;
    // 32 poses spread over the joint space (rad), measured exactly.
    let mut measurements = Vec::new();
    for i in 0..32u32 {
        let q: [f64; 6] =
            std::array::from_fn(|j| f64::from((i * 7 + j as u32 * 3) % 11) * 0.5 - 2.5);
        measurements.push(Measurement::from_pose(&q, &real.forward(&q)?)?);
    }
    let set = ParameterSet::<U6, U24>::default_for(&robot)?;
    let problem = Problem::new(
        &robot,
        &ParameterErrors::zero(),
        set,
        &measurements,
        calib_core::identify::objective::DEFAULT_K,
    )?;
    // The paper's swarm on the objective of eq. (7).
    let objective = Objective::new(&problem);
    let mut cost = |x: &nalgebra::SVector<f64, 24>| objective.value(x);
    let swarm = ipso::optimize::<f64, 20, U24>(
        &mut cost,
        &SearchSpace::paper(&set),
        &IpsoSettings::paper(),
        &mut Silent,
    )?;
    // Least squares from the swarm's best to the noise floor (here: exact data).
    let fit = LeastSquares::new(&problem).solve(&swarm.best, &LmSettings::default())?;
    let identified = set.unpack(&fit.x)?;
    println!(
        "objective {:.6e} -> {:.6e} (swarm, {} generations) -> least squares cost {:.3e}",
        swarm.initial_cost, swarm.best_cost, swarm.generations, fit.cost
    );
    let mut ok = true;
    for parameter in set.parameters() {
        let (found, want) = (
            identified.get(*parameter).unwrap_or(f64::NAN),
            truth.get(*parameter).unwrap_or(f64::NAN),
        );
        let tolerance = if parameter.is_angle() { 1e-9 } else { 1e-6 };
        let good = (found - want).abs() <= tolerance;
        ok &= good;
        println!(
            "{parameter:<8} identified {found:+.9} true {want:+.9} {}",
            if good { "ok" } else { "WRONG" }
        );
    }
    println!("{}", if ok { "PASS" } else { "FAIL" });
    Ok(if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
