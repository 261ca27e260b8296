//! The joint and parameter counts as types: the controller compiles them (`U6`, `U24`), a host
//! takes them at run time (`Dyn`, `Dyn`), and both must give the same bits. The swarm's side is checked in host-tools
//! (`swarm_team::team_evaluates_bit_for_bit`) and against the golden objective
//! (`swarm_golden`); here least squares (plain and robust), its covariance and standard errors,
//! and the identifiability analysis on the bundled paper scenario (32 simulated 6-DoF poses of
//! the ER10L-C10) and on its position-only half.

use calib_core::identify::identifiability::{DEFAULT_RANK_TOLERANCE, Identifiability};
use calib_core::identify::lm::{LeastSquares, LmSettings, Loss};
use calib_core::identify::objective::{DEFAULT_K, Measurement};
use calib_core::model::JointCount;
use calib_core::{ParameterErrors, ParameterSet, Problem};
use nalgebra::{Dim, Dyn, U6, U24};

fn bits(values: impl IntoIterator<Item = f64>) -> Vec<u64> {
    values.into_iter().map(f64::to_bits).collect()
}

/// The bundled measurements of the paper scenario; position-only when asked.
fn paper_measurements(position_only: bool) -> Vec<Measurement<f64, Dyn>> {
    let mut measurements = host_tools::measurement::dataset::Dataset::load(
        &calib_tests::repo("host-tools/robots/er10l-c10.toml"),
        &calib_tests::repo("host-tools/data/er10l-c10-sim32.csv"),
    )
    .expect("bundled files")
    .readings;
    if position_only {
        for m in &mut measurements {
            m.rotation = None;
        }
    }
    measurements
}

/// Everything a calibration reads from least squares and the analysis, as bits, with the joint
/// count `N` and the parameter count `D`.
fn results<N: JointCount, D: Dim>(
    measurements: &[Measurement<f64, Dyn>],
    loss: Loss<f64>,
) -> Vec<Vec<u64>>
where
    nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<D>
        + nalgebra::allocator::Allocator<D, D>
        + nalgebra::allocator::Allocator<nalgebra::U6, D>,
{
    let robot = calib_core::model::paper::er10l_c10::<f64>()
        .recount::<N>()
        .unwrap();
    let measurements: Vec<Measurement<f64, N>> =
        measurements.iter().map(|m| m.recount().unwrap()).collect();
    let measurements = &measurements[..];
    let set = ParameterSet::<N, D>::default_for(&robot).expect("the paper's 24 parameters");
    let problem = Problem::new(
        &robot,
        &ParameterErrors::zeros_for(robot.joint_count()),
        set,
        measurements,
        DEFAULT_K,
    )
    .expect("valid problem");
    let least_squares = LeastSquares::new(&problem);
    let analysis = Identifiability::from_factor(
        &least_squares
            .jacobian_factor(&problem.set().zeros())
            .unwrap(),
        measurements.len(),
        DEFAULT_RANK_TOLERANCE,
    );
    let combination = analysis.combination(analysis.pivots[23], 0.0);
    let mut out = vec![
        bits(analysis.singular_values.iter().copied()),
        bits(analysis.weakest_direction.iter().copied()),
        bits([analysis.condition_number, analysis.observability]),
        analysis.pivots.iter().map(|p| *p as u64).collect(),
        bits(
            combination
                .into_iter()
                .flat_map(|c| c.iter().copied().collect::<Vec<_>>()),
        ),
    ];
    // Position-only data of a reflector on the flange leave dalpha6 undetermined: least squares
    // refuses them, the same way for both counts.
    let mut weights = vec![0.0; measurements.len()];
    match least_squares.solve_robust(
        &problem.set().zeros(),
        &LmSettings::default(),
        loss,
        &mut weights,
    ) {
        Ok(robust) => {
            let fit = &robust.result;
            let covariance = fit.covariance().expect("regular R");
            let errors = fit.standard_errors().expect("regular R");
            out.extend([
                bits(fit.x.iter().copied()),
                bits(fit.r.iter().copied()),
                bits([fit.cost, fit.initial_cost, fit.sigma()]),
                vec![u64::from(fit.iterations), u64::from(robust.reweightings)],
                bits(covariance.iter().copied()),
                bits(errors.iter().copied()),
                bits(weights),
            ]);
        }
        Err(e) => out.push(format!("{e:?}").bytes().map(u64::from).collect()),
    }
    out
}

#[test]
fn least_squares_and_identifiability_give_the_same_bits_for_compiled_and_run_time_counts() {
    for position_only in [false, true] {
        let measurements = paper_measurements(position_only);
        for loss in [Loss::L2, Loss::Cauchy(0.05)] {
            let fixed = results::<U6, U24>(&measurements, loss);
            let dynamic = results::<Dyn, Dyn>(&measurements, loss);
            // Not a trivial comparison: 24 singular values; with 6-DoF data a fit that moved
            // and a full R; position-only, the refusal.
            assert_eq!(fixed[0].len(), 24);
            if position_only {
                assert_eq!(fixed.len(), 6, "{loss:?}");
            } else {
                assert!(fixed[5].iter().any(|b| *b != 0), "{loss:?}");
                assert_eq!(fixed[6].len(), 24 * 24);
            }
            assert_eq!(fixed.len(), dynamic.len());
            for (i, (a, b)) in fixed.iter().zip(&dynamic).enumerate() {
                assert_eq!(a, b, "item {i}, position only {position_only}, {loss:?}");
            }
        }
    }
}
