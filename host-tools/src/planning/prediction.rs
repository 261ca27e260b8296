//! What a plan predicts: the identified parameters' covariance of the linear model at the
//! nominal parameters (the sandwich `A^-1 (J^T S J) A^-1`), the conditioning, the verification
//! poses' expected mean error with its 95 % range, and the poses' leverages.

use super::*;

/// The predicted accuracy of a plan (the module's assumptions).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Prediction {
    /// The position noise assumed, 1 sigma per coordinate, mm.
    pub noise_mm: f64,
    /// The orientation noise assumed, 1 sigma per axis, deg (`None` for positions only).
    pub noise_deg: Option<f64>,
    /// Identified parameters.
    pub parameters: usize,
    /// Equations of the fitted poses.
    pub equations: usize,
    /// Condition number of the fitted poses' Jacobian, columns scaled to unit norm (as
    /// `calib check`).
    pub condition_number: f64,
    /// Observability index O1 (Borm and Menq) of the fitted poses, scaled Jacobian.
    pub observability_index: f64,
    /// Standard error of each identified parameter: name, value (mm or deg), unit.
    pub standard_errors: Vec<(String, f64, &'static str)>,
    /// Mean position error of a pose measured with no model error at all (the noise floor),
    /// mm: `sigma sqrt(8/pi)`.
    pub noise_floor_mean_mm: f64,
    /// Predicted mean position error of the verification poses after calibration and its 95 %
    /// range; `None` without verification poses.
    pub verification: Option<PlannedVerification>,
    /// Predicted mean position error over all candidates (the working region) after
    /// calibration, as a held-out test would measure it (noise included), mm.
    pub region_mean_mm: f64,
    /// RMS of the estimation term alone over the candidates (the model's own predicted error),
    /// mm.
    pub region_estimation_rms_mm: f64,
}

impl Prediction {
    /// Text for people, with its assumptions.
    pub fn text(&self) -> String {
        let mut out = format!(
            "prediction for {} identified parameters from {} equations (linear model at the nominal parameters, white noise {:.4} mm per coordinate{}, no unmodelled error):\n",
            self.parameters,
            self.equations,
            self.noise_mm,
            self.noise_deg
                .map(|d| format!(" and {d:.4} deg per orientation axis"))
                .unwrap_or_default()
        );
        out.push_str(&format!(
            "  scaled condition number {:.3}, observability index O1 {:.4e}\n",
            self.condition_number, self.observability_index
        ));
        if let Some(v) = &self.verification {
            out.push_str(&format!(
                "  verification poses: mean position error {:.4} mm (95 % range {:.4} ... {:.4} mm; noise floor {:.4} mm)\n",
                v.mean_mm, v.low_mm, v.high_mm, self.noise_floor_mean_mm
            ));
        }
        out.push_str(&format!(
            "  over the candidates: mean position error {:.4} mm held out, model error alone {:.4} mm RMS\n",
            self.region_mean_mm, self.region_estimation_rms_mm
        ));
        out.push_str("  standard errors:");
        for (i, (name, value, unit)) in self.standard_errors.iter().enumerate() {
            if i % 6 == 0 {
                out.push_str("\n   ");
            }
            out.push_str(&format!(" {name} {value:.2e} {unit};"));
        }
        out.push('\n');
        out
    }
}

/// Mean of the length of a 3-D isotropic normal vector per unit sigma: `sqrt(8/pi)`.
pub(super) fn maxwell_mean() -> f64 {
    (8.0 / PI).sqrt()
}

/// Variance of that length per unit sigma squared: `3 - 8/pi`.
pub(super) fn maxwell_variance() -> f64 {
    3.0 - 8.0 / PI
}

/// The covariance of the identified parameters (in their units) of a fit to the unit-scaled
/// rows `stacked` whose columns were divided by `scale`, under the noise of `settings`: `S^-1
/// A^-1 (J~^T Sigma J~) A^-1 S^-1`. Error: the rows do not determine every parameter.
pub(super) fn parameter_covariance(
    stacked: &DMatrix<f64>,
    scale: &[f64],
    settings: &PlanSettings,
) -> crate::Result<DMatrix<f64>> {
    let sigma = settings.noise_mm;
    // Noise of each weighted row: position rows sigma, orientation rows sigma_r sqrt(k).
    let row_sigma = |row: usize| {
        if settings.measure == Measure::Position || row % 6 < 3 {
            sigma
        } else {
            settings.noise_deg.to_radians() * settings.k.sqrt()
        }
    };
    let Some(inverse) = (stacked.transpose() * stacked)
        .cholesky()
        .map(|c| c.inverse())
    else {
        return Err(crate::refused!(undetermined Vec::<String>::new();
            "the fitted poses do not determine every parameter (singular information matrix); plan more poses or a smaller identify list"
        ));
    };
    let mut noisy = stacked.clone();
    for (r, mut row) in noisy.row_iter_mut().enumerate() {
        row *= row_sigma(r);
    }
    let mut covariance = &inverse * (noisy.transpose() * &noisy) * &inverse;
    for (r, sr) in scale.iter().enumerate() {
        for (c, sc) in scale.iter().enumerate() {
            covariance[(r, c)] /= sr * sc;
        }
    }
    Ok(covariance)
}

/// The condition number and the observability index O1 of `stacked` with its columns at unit
/// norm (as `calib check`), for `poses` fitted poses.
pub(super) fn conditioning(stacked: &DMatrix<f64>, poses: usize) -> (f64, f64) {
    let mut unit = stacked.clone();
    for mut c in unit.column_iter_mut() {
        let n = c.norm();
        if n > 0.0 {
            c /= n;
        }
    }
    let singular = unit.singular_values();
    let (largest, smallest) = (singular.max(), singular.min());
    let observability_index =
        (singular.iter().map(|s| s.ln()).sum::<f64>() / stacked.ncols() as f64).exp()
            / (poses as f64).sqrt();
    let condition_number = if smallest > 0.0 {
        largest / smallest
    } else {
        f64::INFINITY
    };
    (condition_number, observability_index)
}

/// The predicted mean error of the verification poses `verify` (none without them) and its 95 %
/// interval; `held_out(i)` is candidate `i`'s mean square error and its estimation part.
pub(super) fn planned_verification(
    verify: &[usize],
    held_out: impl Fn(usize) -> (f64, f64),
    sigma: f64,
) -> Option<PlannedVerification> {
    if verify.is_empty() {
        return None;
    }
    let (mut mean, mut variance) = (0.0, 0.0);
    for i in verify {
        let (s2, _) = held_out(*i);
        mean += maxwell_mean() * s2.sqrt();
        variance += maxwell_variance() * s2;
    }
    let n = verify.len() as f64;
    let (mean, half) = (mean / n, 1.96 * variance.sqrt() / n);
    Some(PlannedVerification {
        mean_mm: mean,
        low_mm: (mean - half).max(0.0),
        high_mm: mean + half,
        noise_mm: sigma,
    })
}

/// The prediction for the fitted poses of `chosen` (see [`Prediction`]).
pub(super) fn predict(
    info: &Information,
    scaled: &[DMatrix<f64>],
    scale: &[f64],
    chosen: &[(usize, Role)],
    settings: &PlanSettings,
) -> crate::Result<Prediction> {
    let p = info.parameters.len();
    let fitted: Vec<usize> = chosen
        .iter()
        .filter(|(_, r)| *r != Role::Verify)
        .map(|(i, _)| *i)
        .collect();
    let stacked = stack(fitted.iter().map(|i| &scaled[*i]), p);
    let sigma = settings.noise_mm;
    let covariance = parameter_covariance(&stacked, scale, settings)?;
    let (condition_number, observability_index) = conditioning(&stacked, fitted.len());
    let standard_errors = info
        .parameters
        .iter()
        .enumerate()
        .map(|(i, parameter)| {
            let se = covariance[(i, i)].max(0.0).sqrt();
            if !parameter.is_angle() {
                (parameter.to_string(), se, "mm")
            } else {
                (parameter.to_string(), se.to_degrees(), "deg")
            }
        })
        .collect();
    // Per pose: |e|^2 = |noise|^2 + |J_p dx|^2, dx ~ N(0, C); its length taken as that of an
    // isotropic normal vector of the same mean square.
    let held_out = |i: usize| {
        let position = info.rows[i].rows(0, 3);
        let estimation = (position * &covariance * position.transpose()).trace();
        (sigma * sigma + estimation / 3.0, estimation)
    };
    let verify: Vec<usize> = chosen
        .iter()
        .filter(|(_, r)| *r == Role::Verify)
        .map(|(i, _)| *i)
        .collect();
    let verification = planned_verification(&verify, held_out, sigma);
    let (mut region_mean, mut region_estimation) = (0.0, 0.0);
    for i in 0..info.rows.len() {
        let (s2, estimation) = held_out(i);
        region_mean += maxwell_mean() * s2.sqrt();
        region_estimation += estimation;
    }
    let candidates = info.rows.len() as f64;
    Ok(Prediction {
        noise_mm: sigma,
        noise_deg: (settings.measure == Measure::Pose).then_some(settings.noise_deg),
        parameters: p,
        equations: stacked.nrows(),
        condition_number,
        observability_index,
        standard_errors,
        noise_floor_mean_mm: maxwell_mean() * sigma,
        verification,
        region_mean_mm: region_mean / candidates,
        region_estimation_rms_mm: (region_estimation / candidates).sqrt(),
    })
}

/// The row blocks stacked into one matrix of `columns` columns.
pub(super) fn stack<'m>(
    blocks: impl Iterator<Item = &'m DMatrix<f64>>,
    columns: usize,
) -> DMatrix<f64> {
    let blocks: Vec<&DMatrix<f64>> = blocks.collect();
    let rows = blocks.iter().map(|b| b.nrows()).sum();
    let mut out = DMatrix::zeros(rows, columns);
    let mut at = 0;
    for b in blocks {
        out.view_mut((at, 0), (b.nrows(), columns)).copy_from(b);
        at += b.nrows();
    }
    out
}

/// Leverage of each pose in a fit of `q` (rad) measured as `measure`: the share of the pose's
/// own measurement in its fitted value, `trace(J_i (J^T J)^-1 J_i^T)` over its rows (0 ... its
/// row count; they sum to the parameter count), at the nominal model. A pose of high leverage
/// and a large residual is the first suspect when the verification error exceeds the
/// prediction.
pub fn leverages(
    file: &RobotFile,
    robot_path: &std::path::Path,
    q: &[Vec<f64>],
    measure: Measure,
    k: f64,
) -> crate::Result<Vec<f64>> {
    crate::model::counts::joint_count(file.joint.len())?;
    let info = information(file, robot_path, q, measure, k)?;
    let stacked = stack(info.rows.iter(), info.parameters.len());
    let Some(inverse) = (stacked.transpose() * &stacked)
        .cholesky()
        .map(|c| c.inverse())
    else {
        return Err(crate::refused!(undetermined Vec::<String>::new();
            "the fitted poses do not determine every parameter"
        ));
    };
    Ok(info
        .rows
        .iter()
        .map(|j| (j * &inverse * j.transpose()).trace())
        .collect())
}
