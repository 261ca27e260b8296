//! The least-squares stage on measurements of any kind ([`MeasurementKind`]): the parameters a
//! selection kept, fitted from zero errors by the core's Levenberg-Marquardt on the kind's
//! residuals, with their covariance and standard errors. The tracker's solve adds to it what
//! only poses have (the swarm, the robust loss and its outliers, the compliance rounds:
//! `calibration/solve.rs`); a new kind needs nothing here.

use super::result::LeastSquaresReport;
use super::{CalibrationConfig, IdentifiedParameter, Selection};
use crate::analysis::kind::MeasurementKind;
use calib_core::identify::lm::{LeastSquares, LmSettings};
use calib_core::identify::residuals::Residuals;
use calib_core::{ParameterErrors, ParameterSet};
use nalgebra::Dyn;
use std::time::Instant;

/// A least-squares fit of a selection on measurements of some kind.
#[derive(Clone, Debug)]
pub struct KindFit {
    /// The identified parameters' set.
    pub set: ParameterSet<Dyn, Dyn>,
    /// The identified values with their standard errors, in the set's order (mm, rad).
    pub parameters: Vec<IdentifiedParameter>,
    /// All errors (identified ones set, others zero), mm and rad.
    pub errors: ParameterErrors<f64, Dyn>,
    /// The identified parameters' covariance, in the set's order (`None`: singular).
    pub covariance: Option<nalgebra::DMatrix<f64>>,
    /// How least squares ran (no robust loss: `loss_scale_mm` is `None`).
    pub least_squares: LeastSquaresReport,
    /// The residual standard deviation, `sqrt(2 cost / degrees of freedom)`, mm.
    pub sigma_mm: f64,
    /// Wall-clock time of the fit, s.
    pub seconds: f64,
}

/// Fits the parameters of `selection` to the measurements of `kind` by least squares from zero
/// errors (at most `config.lm_iterations` iterations).
pub fn least_squares_of<K: MeasurementKind>(
    kind: &K,
    selection: &Selection,
    config: &CalibrationConfig,
) -> crate::Result<KindFit> {
    let set = crate::model::counts::solvable_set(&selection.mask)?;
    let residuals = kind.residuals(set.clone())?;
    let started = Instant::now();
    let settings = LmSettings {
        max_iterations: config.lm_iterations,
        ..LmSettings::default()
    };
    let start = nalgebra::DVector::zeros(residuals.parameters());
    let fit = LeastSquares::new(&residuals)
        .solve(&start, &settings)
        .map_err(|e| super::solve::lm_error(e, &set))?;
    let seconds = started.elapsed().as_secs_f64();
    let standard_errors = fit.standard_errors();
    let parameters = super::solve::identified_parameters(&set, &fit.x, standard_errors.as_ref());
    let errors = set.unpack(&fit.x)?;
    let least_squares = LeastSquaresReport::of(&fit);
    Ok(KindFit {
        sigma_mm: fit.sigma(),
        covariance: fit.covariance(),
        set,
        parameters,
        errors,
        least_squares,
        seconds,
    })
}
