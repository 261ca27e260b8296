//! The plan check of a calibration of a measured plan: the verification poses' measured mean
//! error against the plan's prediction, with the fitted poses of largest leverage and residual.

use super::*;

/// What `calibrate` says of a plan's verification poses once measured.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct PlanCheck {
    /// What the plan predicted.
    pub predicted: PlannedVerification,
    /// Measured mean position error of the verification poses after calibration, mm.
    pub measured_mean_mm: f64,
    /// Verification poses.
    pub poses: usize,
    /// `true` when the measured mean is above the prediction's 95 % range: the model misses an
    /// error the plan assumed absent (see [`PlanCheck::text`]).
    pub gap: bool,
    /// The fitted poses of largest leverage: id, leverage, residual position error (mm).
    pub largest_leverage: Vec<(String, Option<f64>, f64)>,
    /// The fitted poses of largest residual: id, leverage (`null` when not computed), residual
    /// position error (mm).
    pub largest_residual: Vec<(String, Option<f64>, f64)>,
    /// Why the leverages are missing, when they are.
    pub leverage_note: Option<String>,
}

impl PlanCheck {
    /// Poses listed in each of the two lists.
    pub(crate) const LISTED: usize = 3;

    /// The certificate's caveat when the verification poses missed the prediction (`gap`).
    pub fn caveat(&self) -> Option<crate::analysis::caveats::Caveat> {
        self.gap.then(|| crate::analysis::caveats::Caveat {
            kind: crate::analysis::caveats::CaveatKind::PlanCheck,
            text: format!(
                "the plan's {} verification poses measured {:.4} mm mean error, above the {:.4} mm the plan allowed: \
                 the model misses an error the plan assumed absent",
                self.poses, self.measured_mean_mm, self.predicted.high_mm
            ),
            lines: Vec::new(),
        })
    }

    /// Where the measured mean lies against the prediction's 95 % range, in words: `below the
    /// range (better than predicted: ...)`, `within the range` or `above the range`.
    pub fn verdict(&self) -> &'static str {
        verdict(
            self.measured_mean_mm,
            self.predicted.low_mm,
            self.predicted.high_mm,
        )
    }

    /// Text for people.
    pub fn text(&self) -> String {
        let p = &self.predicted;
        let mut out = format!(
            "plan check: {} verification poses, measured mean position error {:.4} mm; the plan predicted {:.4} mm (95 % range {:.4} ... {:.4} mm, noise {:.4} mm): {}\n",
            self.poses,
            self.measured_mean_mm,
            p.mean_mm,
            p.low_mm,
            p.high_mm,
            p.noise_mm,
            self.verdict()
        );
        if self.gap {
            out.push_str(&format!(
                "WARNING: the verification error is {:.4} mm above the predicted range: the calibrated model misses an error the plan assumed absent (joint-angle errors, compliance, temperature, or a bad measurement), or the noise level was set too low. Look first at poses of high leverage with a large residual:\n",
                self.measured_mean_mm - p.high_mm
            ));
            let list = |name: &str, rows: &[(String, Option<f64>, f64)]| {
                let items: Vec<String> = rows
                    .iter()
                    .map(|(id, h, r)| match h {
                        Some(h) => format!("{id} (leverage {h:.2}, residual {r:.4} mm)"),
                        None => format!("{id} (residual {r:.4} mm)"),
                    })
                    .collect();
                format!("  largest {name}: {}\n", items.join(", "))
            };
            if let Some(note) = &self.leverage_note {
                out.push_str(&format!("  {note}\n"));
            } else {
                out.push_str(&list("leverage", &self.largest_leverage));
            }
            out.push_str(&list("residual", &self.largest_residual));
        }
        out
    }
}

/// The check of a plan's verification poses: `measured_mean_mm` against `predicted`, with the
/// fitted poses (id, joint values in rad, residual position error in mm) ranked by leverage and
/// by residual. Leverages the fitted poses cannot give (they do not determine every parameter at
/// the nominal model) are left out with the reason; the comparison stands without them.
#[allow(clippy::too_many_arguments)]
pub(crate) fn check_plan(
    predicted: PlannedVerification,
    measured_mean_mm: f64,
    poses: usize,
    file: &RobotFile,
    robot_path: &std::path::Path,
    fitted: &[(String, Vec<f64>, f64)],
    measure: Measure,
    k: f64,
) -> PlanCheck {
    let q: Vec<Vec<f64>> = fitted.iter().map(|(_, q, _)| q.clone()).collect();
    let (h, leverage_note) = match leverages(file, robot_path, &q, measure, k) {
        Ok(h) => (h.into_iter().map(Some).collect(), None),
        Err(e) => (
            vec![None; fitted.len()],
            Some(format!("leverages not computed: {e}")),
        ),
    };
    let mut rows: Vec<(String, Option<f64>, f64)> = fitted
        .iter()
        .zip(h)
        .map(|((id, _, r), h)| (id.clone(), h, *r))
        .collect();
    rows.sort_by(|a, b| b.1.unwrap_or(-1.0).total_cmp(&a.1.unwrap_or(-1.0)));
    let largest_leverage = (rows.iter())
        .filter(|r| r.1.is_some())
        .take(PlanCheck::LISTED)
        .cloned()
        .collect();
    rows.sort_by(|a, b| b.2.total_cmp(&a.2));
    let largest_residual = rows.iter().take(PlanCheck::LISTED).cloned().collect();
    PlanCheck {
        predicted,
        measured_mean_mm,
        poses,
        gap: measured_mean_mm > predicted.high_mm,
        largest_leverage,
        largest_residual,
        leverage_note,
    }
}

/// Where a measured mean error (mm) lies against a predicted 95 % range `[low, high]` (mm), in
/// words. Below it the model did better than the plan predicted: the noise level the plan assumed
/// (or the errors it expected) was larger than this measurement's, and the prediction says little
/// about this measurement's accuracy beyond that it is no worse.
pub(crate) fn verdict(measured: f64, low: f64, high: f64) -> &'static str {
    if measured > high {
        "above the range"
    } else if measured < low {
        "below the range (better than predicted: the plan assumed more noise or larger errors than this measurement had)"
    } else {
        "within the range"
    }
}
