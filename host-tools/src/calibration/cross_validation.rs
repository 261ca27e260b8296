//! The cross-validation estimate of the held-out error, reported with every calibration: the
//! calibration poses are split into folds (leave-one-out up to 20 poses, 5 folds above); each
//! fold is predicted by the model identified by least squares on the other poses, with the same
//! parameters and loss. A small or weak pose set whose estimate is worse than the uncalibrated
//! model's is flagged: its calibration is likely to make the robot less accurate.

use super::CalibrationConfig;
use crate::measurement::dataset::Seen;
use calib_core::identify::lm::{LeastSquares, LmSettings};
use calib_core::{Kinematics, ParameterSet};
use nalgebra::Dyn;
use serde::Serialize;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Poses up to which every pose is its own fold (leave-one-out).
pub(crate) const LEAVE_ONE_OUT_UP_TO: usize = 20;

/// Folds above [`LEAVE_ONE_OUT_UP_TO`] poses.
pub(crate) const FOLDS: usize = 5;

/// The estimate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct CrossValidation {
    /// Number of folds (= poses for leave-one-out).
    pub folds: usize,
    /// Poses predicted (every calibration pose once).
    pub poses: usize,
    /// Mean position error of the predicted poses with the nominal geometry (frames fitted on
    /// all poses), mm.
    pub nominal_mean_mm: f64,
    /// Mean position error of each pose predicted by the model identified without it, mm.
    pub calibrated_mean_mm: f64,
    /// RMS of the same, mm.
    pub calibrated_rms_mm: f64,
    /// Folds whose least squares failed (their poses are not predicted).
    pub failed_folds: usize,
}

impl CrossValidation {
    /// `true` when the model identified from these poses is expected to predict new poses worse
    /// than the nominal model.
    pub(crate) fn worse_than_nominal(&self) -> bool {
        self.calibrated_mean_mm > self.nominal_mean_mm
    }
}

/// Cross-validates the least-squares identification of `set` on `dataset`; `None` with fewer
/// than 3 poses.
pub fn cross_validate(
    dataset: &Seen<'_>,
    set: &ParameterSet<Dyn, Dyn>,
    config: &CalibrationConfig,
) -> Option<CrossValidation> {
    let n = dataset.measurements().len();
    if n < 3 {
        return None;
    }
    let folds = if n <= LEAVE_ONE_OUT_UP_TO { n } else { FOLDS };
    // Poses shuffled with a fixed seed, then dealt into the folds.
    let order = crate::measurement::dataset::shuffled(n, 0);
    let nominal = Kinematics::nominal(&dataset.robot.model.robot).ok()?;
    let settings = LmSettings {
        max_iterations: config.lm_iterations,
        ..LmSettings::default()
    };
    let loss = config.loss.with_scale(config.loss_scale_mm.unwrap_or(1.0));
    // Each fold's least squares alone; `None` when it failed.
    let fold_errors = |fold: usize| -> Option<(Vec<f64>, Vec<f64>)> {
        let held: Vec<usize> = order.iter().skip(fold).step_by(folds).copied().collect();
        // The fold's poses left out of the least squares by a mask, not a copy of the others:
        // a fold costs 9 bytes per pose, not the measurements again.
        let held = crate::measurement::dataset::mask(n, &held);
        let robot = &dataset.robot.model.robot;
        let problem = dataset.problem(set.clone(), config.k).ok()?;
        let least_squares = LeastSquares::new(&problem).leaving_out(&held);
        let mut weights = vec![1.0; n];
        let x = least_squares
            .solve_robust(&set.zeros(), &settings, loss, &mut weights)
            .ok()?
            .result
            .x;
        drop(weights);
        let model = Kinematics::new(robot, &set.unpack(&x).ok()?).ok()?;
        let predicted = || {
            dataset
                .measurements()
                .iter()
                .zip(&held)
                .filter(|(_, h)| **h)
                .map(|(m, _)| m)
        };
        Some((
            crate::measurement::statistics::table3(&model, predicted()).1,
            crate::measurement::statistics::table3(&nominal, predicted()).1,
        ))
    };
    let (mut nominal_errors, mut errors, mut failed) = (Vec::new(), Vec::new(), 0);
    // In fold order whichever thread fitted it, so the sums below are the same bits.
    for fold in on_all_cores(folds, fold_errors) {
        match fold {
            Some((calibrated, nominal)) => {
                errors.extend(calibrated);
                nominal_errors.extend(nominal);
            }
            None => failed += 1,
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt();
    Some(CrossValidation {
        folds,
        poses: errors.len(),
        nominal_mean_mm: mean(&nominal_errors),
        calibrated_mean_mm: mean(&errors),
        calibrated_rms_mm: rms,
        failed_folds: failed,
    })
}

/// `work(i)` for `i` in `0..count`, spread over the cores (scoped threads taking the next index
/// from a shared counter; the calling thread is one of them, and a thread the system refuses is
/// one fewer), returned in index order.
fn on_all_cores<R: Send>(count: usize, work: impl Fn(usize) -> R + Sync) -> Vec<R> {
    let threads = super::cores().min(count);
    let next = AtomicUsize::new(0);
    let take = || {
        let mut done = Vec::new();
        loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            if i >= count {
                return done;
            }
            done.push((i, work(i)));
        }
    };
    let done: Vec<(usize, R)> = std::thread::scope(|scope| {
        let helpers: Vec<_> = (1..threads)
            .filter_map(|_| {
                std::thread::Builder::new()
                    .name("calib-folds".into())
                    .spawn_scoped(scope, take)
                    .ok()
            })
            .collect();
        let mut all = take();
        for helper in helpers {
            // A helper that panicked lost its indices: they are worked again below.
            if let Ok(done) = helper.join() {
                all.extend(done);
            }
        }
        all
    });
    let mut ordered: Vec<Option<R>> = (0..count).map(|_| None).collect();
    for (i, r) in done {
        if let Some(slot) = ordered.get_mut(i) {
            *slot = Some(r);
        }
    }
    ordered
        .into_iter()
        .enumerate()
        .map(|(i, r)| r.unwrap_or_else(|| work(i)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every index is worked once, whichever thread took it, and the results come back in index
    /// order (what makes the folds' sums the same bits on any number of cores).
    #[test]
    fn work_on_all_cores_comes_back_in_index_order() {
        let calls = AtomicUsize::new(0);
        let squares = on_all_cores(37, |i| {
            calls.fetch_add(1, Ordering::Relaxed);
            i * i
        });
        assert_eq!(squares, (0..37).map(|i| i * i).collect::<Vec<_>>());
        assert_eq!(calls.load(Ordering::Relaxed), 37);
        assert!(on_all_cores(0, |i| i).is_empty());
    }
}
