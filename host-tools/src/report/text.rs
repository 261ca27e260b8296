//! A calibration result as text for people: the run in a few lines, then the paper's Table 3
//! before and after on the calibration and the validation poses.

use crate::analysis::evaluation::Evaluation;
use crate::analysis::truth::TruthRow;
use crate::calibration::LossChoice;
use crate::calibration::{CalibrationResult, swarm_stop};
use crate::measurement::frames::Frames;
use crate::report::tables::{table3_text, truth_text};

/// A probe fitted this far (mm) from the stored one has moved (a probe's re-fit scatters by
/// tenths of a millimetre).
const PROBE_MOVED_MM: f64 = 0.5;

fn condition(c: Option<f64>) -> String {
    c.map_or_else(|| "infinite".to_string(), |c| format!("{c:.3e}"))
}

impl CalibrationResult {
    /// The cross-validation lines: the calibrated model against the nominal one, with a warning
    /// when it predicts worse; for a re-registration (`--identify frames`) the frames' prediction
    /// against their fit, and the probe against the stored one.
    fn cross_validation_text(&self) -> String {
        let Some(cv) = &self.cross_validation else {
            return String::new();
        };
        let mut text = String::new();
        if self.config.identify == crate::calibration::Identify::Frames {
            // Re-registration: the same geometry either way, so the comparison is the frames'
            // fit on the poses against their prediction of new ones, not a model against another.
            text.push_str(&format!(
                "\ncross-validation (frames only, {} folds): poses predicted by the frames fitted without them: mean |dp| {:.4} mm \
                 (RMS {:.4} mm); the frames fitted on every pose: {:.4} mm (the same geometry, the robot file's)\n",
                cv.folds, cv.calibrated_mean_mm, cv.calibrated_rms_mm, cv.nominal_mean_mm
            ));
            text.push_str(&self.probe_text());
            return text;
        }
        text.push_str(&format!(
            "\ncross-validation (geometric model, {} folds{}, least squares): poses predicted by the model identified without them: \
             mean |dp| {:.4} mm (RMS {:.4} mm), nominal geometry {:.4} mm{}\n",
            cv.folds,
            if cv.folds == cv.poses + cv.failed_folds { ", leave-one-out" } else { "" },
            cv.calibrated_mean_mm,
            cv.calibrated_rms_mm,
            cv.nominal_mean_mm,
            if cv.failed_folds > 0 {
                format!(" ({} folds failed to fit)", cv.failed_folds)
            } else {
                String::new()
            }
        ));
        if cv.worse_than_nominal() {
            text.push_str(
                "WARNING: calibrated on these poses, the model is expected to miss new poses by more than the \
                 nominal model: the pose set is too small or too weak for the parameters identified. Measure more \
                 poses, spread over the workspace, or identify fewer parameters\n",
            );
        }
        text
    }

    /// For a re-registration: how far the probe fitted now lies from the one the file stores, and
    /// the frames choice that fits (a moved probe is fitted with `--frames base+tool`; one that
    /// stayed is kept with `--frames base`).
    fn probe_text(&self) -> String {
        let stored = self.frames.stored_probe.as_ref();
        let (Some(stored), Some(fitted)) = (stored, self.frames.tool.as_ref()) else {
            return String::new();
        };
        let (a, b) = (stored.isometry(), fitted.isometry());
        let moved_mm = (b.translation.vector - a.translation.vector).norm();
        let turned_deg = a.rotation.angle_to(&b.rotation).to_degrees();
        let advice = if moved_mm > PROBE_MOVED_MM {
            "the probe was moved or exchanged: keep fitting it (--frames base+tool)"
        } else {
            "the probe stayed: --frames base keeps the stored one and fits the tracker alone"
        };
        format!(
            "probe: fitted at ({:.2}, {:.2}, {:.2}) mm, the file's at ({:.2}, {:.2}, {:.2}) mm: moved {moved_mm:.2} mm, \
             turned {turned_deg:.3} deg; {advice}\n",
            fitted.xyz_mm[0],
            fitted.xyz_mm[1],
            fitted.xyz_mm[2],
            stored.xyz_mm[0],
            stored.xyz_mm[1],
            stored.xyz_mm[2],
        )
    }

    /// The text `calib calibrate` prints; `truth` adds the comparison with known errors.
    pub fn text(&self, truth: Option<&[TruthRow]>) -> String {
        let mut text = self.run_text();
        let before_note = if self.frames.identified == Frames::None {
            ""
        } else if self.config.identify == crate::calibration::Identify::Frames {
            "; frames only: before and after = the robot file's geometry with the frames fitted"
        } else {
            "; before = nominal geometry with the frames fitted"
        };
        text.push_str(&table3_text(
            &format!("Table 3 statistics on the calibration poses{before_note}"),
            &self.calibration.before,
            &self.calibration.after,
        ));
        if let Some(stage) = &self.validation {
            text.push('\n');
            text.push_str(&table3_text(
                &format!("Table 3 statistics on the validation poses (held out, not used to calibrate{before_note})"),
                &stage.before,
                &stage.after,
            ));
        }
        if let Some(held_out) = &self.held_out {
            text.push_str(&held_out.text());
        }
        if let Some(conditions) = &self.conditions {
            text.push_str(&conditions.text());
        }
        if self.validation.is_some() {
            text.push_str(&caveats_text(&self.caveats));
        }
        if let Some(uncertainty) = &self.uncertainty {
            text.push_str("  ");
            text.push_str(&uncertainty.text());
        }
        if let Some(budget) = &self.budget {
            text.push_str(&budget.text());
        }
        if let Some(acceptance) = &self.acceptance {
            text.push_str(&acceptance.text());
        }
        if let Some(check) = &self.plan_check {
            text.push('\n');
            text.push_str(&check.text());
        }
        if let Some(maps) = &self.joint_maps {
            text.push_str(&maps.text());
        }
        text.push_str(&self.cross_validation_text());
        if !self.implausible.is_empty() {
            text.push_str("\nWARNING: the result is not plausible (written because of --accept-implausible):\n");
            for problem in &self.implausible {
                text.push_str(&format!("  - {problem}\n"));
            }
        }
        if let Some(rows) = truth {
            text.push_str("\nidentified errors against the truth\n");
            text.push_str(&truth_text(rows));
        }
        text
    }

    /// The lines about the run: stages, identifiability, frames, outliers, objective.
    fn run_text(&self) -> String {
        let config = &self.config;
        let mut text = format!(
            "calibrated {} with {} poses of {} by {} in {:.3} s\n",
            self.robot,
            self.calibration.poses,
            self.data_path.display(),
            config.method.name(),
            self.seconds,
        );
        if let Some(s) = &self.swarm {
            text.push_str(&format!(
                "  IPSO: {} particles, {} generations ({}), {} evaluations, objective {:.6e} -> {:.6e}\n",
                config.swarm.particles,
                s.generations,
                swarm_stop(s.stop),
                s.evaluations,
                self.objective.initial,
                self.objective.after_swarm
            ));
        }
        if let Some(l) = &self.least_squares {
            text.push_str(&format!(
                "  least squares: {} iterations ({}), 0.5 |r|^2 {:.6e} -> {:.6e}, residual sigma {:.4e} mm\n",
                l.iterations, l.stop, l.cost_initial, l.cost_final, l.sigma_mm
            ));
        }
        text.push_str(&self.identifiability_text());
        if self.frames.identified != Frames::None {
            let f = &self.frames;
            text.push_str(&format!(
                "  frames: {} identified; registration of the nominal robot {:.3} mm RMS ({:.3} mm max), \
                 nominal geometry with fitted frames {:.3} mm RMS; not identified (the frames absorb them): {}\n",
                f.identified.name(),
                f.registration_rms_mm,
                f.registration_max_mm,
                f.frames_fit_rms_mm,
                if f.redundant_with_frames.is_empty() {
                    "none".to_string()
                } else {
                    f.redundant_with_frames.join(", ")
                }
            ));
        }
        if config.loss != LossChoice::L2 {
            let ids: Vec<String> = self
                .outliers
                .iter()
                .map(|o| format!("{} (line {}, {:.3} mm)", o.id, o.line, o.residual_mm))
                .collect();
            let (scale, estimated) = self.least_squares.as_ref().map_or(
                (None, String::new()),
                |l| {
                    let estimated = match (l.outlier_position_mm, l.outlier_rotation_deg) {
                        (Some(p), Some(r)) => format!(
                            " (estimated from the data; outliers beyond {p:.4} mm or {r:.4} deg)"
                        ),
                        (Some(p), None) => {
                            format!(" (estimated from the data; outliers beyond {p:.4} mm)")
                        }
                        _ => String::new(),
                    };
                    (l.loss_scale_mm, estimated)
                },
            );
            text.push_str(&format!(
                "  {:?} loss, scale {:.4} mm{}: {} outlier pose(s){}{}\n",
                config.loss,
                scale.unwrap_or(f64::NAN),
                estimated,
                self.outliers.len(),
                if ids.is_empty() { "" } else { ": " },
                ids.join(", ")
            ));
        }
        text.push_str(&format!(
            "objective (eq. 7, k = {:e} mm^2/rad^2): {:.6e} at the nominal model -> {:.6e}\n\n",
            config.k, self.objective.initial, self.objective.r#final
        ));
        text
    }

    /// The identifiability line, the ill-conditioning warning or what `auto_mask` dropped.
    fn identifiability_text(&self) -> String {
        let id = &self.identifiability;
        let mut text = format!(
            "  identifiability: {} parameters, rank {}, scaled condition number {}\n",
            id.parameters,
            id.rank,
            condition(id.condition_number)
        );
        if let Some(reflector) = &id.reflector_on_last_axis {
            text.push_str("  ");
            text.push_str(&reflector.text());
        }
        if id.ill_conditioned && self.dropped.is_empty() {
            text.push_str("  ");
            text.push_str(&id.ill_conditioned_text());
        }
        if !self.dropped.is_empty() {
            let dropped: Vec<String> = self.dropped.iter().map(ToString::to_string).collect();
            text.push_str(&format!(
                "  dropped {} ({}scaled condition number {} -> {}; --keep-ill-conditioned keeps an ill-conditioned set)\n",
                dropped.join(", "),
                if id.undetermined.is_empty() {
                    String::new()
                } else {
                    format!("the data cannot determine {}; ", id.problem())
                },
                condition(id.condition_number),
                condition(id.condition_number_after_drop),
            ));
        }
        if let Some(significance) = &self.significance {
            text.push_str(&significance.text());
        }
        if !self.frames.held_at_stored_probe.is_empty() {
            text.push_str(&format!(
                "  held at the robot file's probe ([measurement] flange_tool), not fitted: {}\n",
                self.frames.held_at_stored_probe.join(", ")
            ));
        }
        text
    }
}

/// The certificate's caveats, one per line; a line saying none was found when there is none.
fn caveats_text(caveats: &[crate::analysis::caveats::Caveat]) -> String {
    if caveats.is_empty() {
        return "caveats: none (plan check, cross-validation, joint ranges of the held-out poses, predicted band)\n".to_owned();
    }
    let mut text = String::from("caveats:\n");
    for c in caveats {
        text.push_str(&format!("  - {}\n", c.line()));
    }
    text
}

/// A model evaluated on poses ([`crate::analysis::evaluation::evaluate_model`]) as text for
/// people, titled `title`: how the frames were fitted, then Table 3 (`calib evaluate`).
pub fn evaluation(evaluation: &Evaluation, title: &str) -> String {
    let mut text = String::new();
    if evaluation.frames.identified.base() {
        text.push_str(&format!(
            "frames fitted ({}, geometry kept) on {} poses: {:.4} mm RMS\n",
            evaluation.frames.identified.name(),
            evaluation.fitted_poses,
            evaluation.frames.frames_fit_rms_mm
        ));
        if evaluation.fitted_poses_evaluated {
            text.push_str(
                "the statistics include the poses that fitted the frames (--fit-poses N keeps them out)\n",
            );
        }
    }
    text.push_str(&crate::report::tables::table3_single_text(
        title,
        &evaluation.table,
    ));
    text
}
