//! Measurement planning (`calib plan`): which poses to measure, chosen from candidate joint
//! configurations with the nominal model only, and the accuracy they are predicted to give.
//!
//! A plan has three roles ([`Role`]):
//! - **core**: a greedy D-optimal selection (each step adds the candidate that most increases
//!   `log det(J^T J)` of the identification Jacobian with unit-RMS columns over the candidates),
//!   about 12 poses: on real UR10 data such a core halves the bad draws of a random set of the
//!   same size (docs/RESULTS.md, "Planned poses");
//! - **fill**: random candidates from the working region. A pure D-optimal set picks extreme
//!   poses, where the non-geometric error is largest, and loses to random poses above about 20
//!   poses; a core filled with random poses did not;
//! - **verify**: random candidates kept out of the fit, measured to check the prediction.
//!
//! No two plan poses are closer than a joint-space distance (Euclidean over the joints, degrees),
//! so near-repeated poses are not both chosen, and the poses are put in an order that keeps the
//! joint motion short (nearest neighbour, then 2-opt, on the largest joint move between poses).
//!
//! The prediction ([`Prediction`]) assumes the linear model at the nominal parameters, white
//! noise of `noise_mm` (1 sigma) on every measured position coordinate and `noise_deg` on every
//! orientation axis (the fit weights them by `k`, which need not match: the covariance is the
//! sandwich `A^-1 (J^T S J) A^-1`, `A = J^T J`), and a complete model: unmodelled errors (joint-angle maps,
//! compliance, temperature) make the measured error larger, which `calibrate` flags when it
//! compares the verification poses with the prediction ([`PlanCheck`]).

mod candidates;
mod check;
mod design;
mod information;
mod prediction;
pub mod program;
mod request;
mod tour;

use self::{candidates::*, design::*, information::*, prediction::*, tour::*};
pub use candidates::generate;
pub use check::PlanCheck;
pub(crate) use check::{check_plan, verdict};
pub use prediction::{Prediction, leverages};
pub use request::{Candidates, MAX_CANDIDATES, Noise, PlanRequest, Residuals};

use crate::analysis::identifiability::analyse;
use crate::error::Context;
use crate::io::robot_file::RobotFile;
use crate::io::tracker_data::{PlannedVerification, Record, Role};
use crate::measurement::dataset::Dataset;
use crate::measurement::frames::Frames;
use calib_core::model::JointVec;
use calib_core::{JointAngles, Kinematics, Parameter, ParameterMask, ParameterSet, Robot};
use nalgebra::DMatrix;
use nalgebra::Dyn;
use serde::Serialize;
use std::f64::consts::PI;

/// Default number of D-optimal core poses (the rest of `--poses` are fill poses).
pub const DEFAULT_CORE: usize = 12;

/// Default number of verification poses.
pub const DEFAULT_VERIFY: usize = 15;

/// Default smallest joint-space distance between two plan poses, degrees (Euclidean over the
/// joints). On the UR10's Series B, 0, 5 and 10 deg chose the same poses; 20 deg made a pure
/// D-optimal set of 30 poses reach the held-out error of 50 random ones (docs/RESULTS.md).
pub const DEFAULT_MIN_DISTANCE_DEG: f64 = 20.0;

/// What the tracker measures at each pose.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Measure {
    /// The position of a reflector (3 coordinates per pose).
    Position,
    /// Position and orientation of a 6-DoF probe (6 per pose).
    Pose,
}

impl Measure {
    /// Equations per pose.
    pub fn rows(self) -> usize {
        match self {
            Self::Position => 3,
            Self::Pose => 6,
        }
    }
}

/// The model a plan is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum PlanModel {
    /// The geometric parameters and the frames (`calibrate --model geometric`): random fill.
    Geometric,
    /// The geometry and each joint's angle-error map (`calibrate --model joint-maps`, 6-joint
    /// robots): the core as for the geometry, fill poses that cover each joint's range evenly.
    JointMaps,
}

/// How to plan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlanSettings {
    /// Poses to fit: the core and the fill poses.
    pub poses: usize,
    /// D-optimal core poses (at most `poses`).
    pub core: usize,
    /// Verification poses, besides `poses`.
    pub verify: usize,
    /// Smallest joint-space distance between two plan poses, degrees.
    pub min_distance_deg: f64,
    /// What the tracker measures.
    pub measure: Measure,
    /// The model the plan is for.
    pub model: PlanModel,
    /// Noise of each measured position coordinate (tracker and robot repeatability), 1 sigma,
    /// mm.
    pub noise_mm: f64,
    /// Noise of each measured orientation axis, 1 sigma, deg (used with [`Measure::Pose`]).
    pub noise_deg: f64,
    /// Weight of the orientation rows, mm^2/rad^2 (as `calibrate --k`).
    pub k: f64,
    /// Seed of the random fill and verification poses.
    pub seed: u64,
}

impl PlanSettings {
    /// The settings' own checks, with the flag to change.
    pub fn check(&self) -> crate::Result<()> {
        if self.poses == 0 {
            return Err(crate::refused!(option "--poses"; "--poses must be at least 1"));
        }
        if self.core > self.poses {
            return Err(crate::refused!(option "--core";
                "--core {} is more than --poses {}: the core is part of the fitted poses",
                self.core,
                self.poses
            ));
        }
        if !(self.min_distance_deg.is_finite() && self.min_distance_deg >= 0.0) {
            return Err(crate::refused!(option "--min-distance-deg";
                "--min-distance-deg must be 0 or more degrees, got {}",
                self.min_distance_deg
            ));
        }
        if !(self.noise_mm.is_finite() && self.noise_mm > 0.0 && self.noise_mm < 100.0) {
            return Err(crate::refused!(option "--noise-mm";
                "the noise level must be above 0 and below 100 mm, got {} (--noise-mm: the tracker's and the robot's repeatability, 1 sigma per coordinate)",
                self.noise_mm
            ));
        }
        if !(self.noise_deg.is_finite() && self.noise_deg > 0.0 && self.noise_deg < 10.0) {
            return Err(crate::refused!(option "--noise-deg";
                "the orientation noise must be above 0 and below 10 deg, got {} (--noise-deg)",
                self.noise_deg
            ));
        }
        if !(self.k.is_finite() && self.k > 0.0) {
            return Err(crate::refused!(option "--k";
                "--k must be a positive weight (mm^2/rad^2), got {}",
                self.k
            ));
        }
        Ok(())
    }
}

/// One pose of a plan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlannedPose {
    /// The pose's identifier: the candidate's id.
    pub id: String,
    /// Index of the candidate it is (0-based, in the candidates' order).
    pub candidate: usize,
    /// Joint values, rad.
    pub q: Vec<f64>,
    /// Its role.
    pub role: Role,
}

/// A measurement plan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Plan {
    /// The poses in measurement order.
    pub poses: Vec<PlannedPose>,
    /// The identified parameters the plan is optimised for (the robot file's identification
    /// set with the frames `calibrate` fits), by name.
    pub parameters: Vec<String>,
    /// Parameters of that set no candidate set could determine, left out of the plan.
    pub undetermined: Vec<String>,
    /// Number of candidates.
    pub candidates: usize,
    /// The settings.
    pub settings: PlanSettings,
    /// Sum over the measurement order of the largest joint move between consecutive poses, deg.
    pub joint_travel_deg: f64,
    /// The same in the candidates' order of the chosen poses, deg (what the ordering saved).
    pub joint_travel_unordered_deg: f64,
    /// The prediction.
    pub prediction: Prediction,
}

impl Plan {
    /// The poses of one role, in measurement order.
    pub fn of_role(&self, role: Role) -> impl Iterator<Item = &PlannedPose> {
        self.poses.iter().filter(move |p| p.role == role)
    }

    /// Text for people.
    pub fn text(&self) -> String {
        let count = |role| self.of_role(role).count();
        let mut out = format!(
            "plan: {} poses to measure from {} candidates: {} core (D-optimal), {} fill (random), {} verify (kept out of the fit); no two closer than {} deg in joint space\n",
            self.poses.len(),
            self.candidates,
            count(Role::Core),
            count(Role::Fill),
            count(Role::Verify),
            self.settings.min_distance_deg
        );
        if self.settings.model == PlanModel::JointMaps {
            out.push_str("for joint maps: the fill poses cover each joint's range evenly (the maps are identified from each joint's own readings); the core and the prediction are for the geometric parameters\n");
        }
        out.push_str(&format!(
            "optimised for the {} parameters the calibration identifies ({}), measuring {}\n",
            self.parameters.len(),
            self.parameters.join(" "),
            match self.settings.measure {
                Measure::Position => "positions",
                Measure::Pose => "positions and orientations",
            }
        ));
        if !self.undetermined.is_empty() {
            out.push_str(&format!(
                "not determined by any of the candidates (left out): {}\n",
                self.undetermined.join(" ")
            ));
        }
        out.push_str(&format!(
            "measurement order: joint travel {:.0} deg (largest joint move summed; {:.0} deg in the candidates' order)\n",
            self.joint_travel_deg, self.joint_travel_unordered_deg
        ));
        out.push_str(&self.prediction.text());
        out
    }

    /// The plan as a tracker CSV without measurements (docs/USAGE.md): `id`, `role`, the joints
    /// in degrees and empty measurement columns (quaternion columns for `pose`), for the tracker
    /// software to fill; `comments` and the prediction line at the top.
    pub fn csv(&self, comments: &[String]) -> crate::Result<String> {
        let mut text = String::new();
        for c in comments {
            text.push_str(&format!("# {}\n", crate::io::text::one_line(c)));
        }
        if let Some(v) = &self.prediction.verification {
            text.push_str(&format!("# {}\n", v.comment()));
        }
        let mut measured = vec!["x_mm", "y_mm", "z_mm"];
        if self.settings.measure == Measure::Pose {
            measured.extend(["qw", "qx", "qy", "qz"]);
        }
        text.push_str(&self.poses_csv(&measured)?);
        Ok(text)
    }

    /// The poses as CSV rows: `id`, `role`, `q1_deg..qN_deg`, then the `measured` columns empty.
    pub(crate) fn poses_csv(&self, measured: &[&str]) -> crate::Result<String> {
        let joints = self.poses.first().map_or(0, |p| p.q.len());
        let mut header: Vec<String> = vec!["id".into(), "role".into()];
        header.extend((1..=joints).map(|i| format!("q{i}_deg")));
        header.extend(measured.iter().map(|s| s.to_string()));
        let mut writer = csv::Writer::from_writer(Vec::new());
        writer.write_record(&header)?;
        for p in &self.poses {
            let mut fields = vec![p.id.clone(), p.role.name().to_string()];
            fields.extend(p.q.iter().map(|q| q.to_degrees().to_string()));
            fields.extend(measured.iter().map(|_| String::new()));
            writer.write_record(&fields)?;
        }
        let bytes = writer.into_inner().map_err(|e| e.into_error())?;
        Ok(std::str::from_utf8(&bytes)?.to_string())
    }
}

/// Plans the measurement of the robot in `file` (at `robot_path`, for messages) from
/// `candidates` (joint values in rad, with ids).
pub fn plan(
    file: &RobotFile,
    robot_path: &std::path::Path,
    candidates: &[(String, Vec<f64>)],
    settings: &PlanSettings,
) -> crate::Result<Plan> {
    let q = checked_candidates(file, candidates, settings)?;
    let info = information(file, robot_path, &q, settings.measure, settings.k)?;
    let parameters = info.parameters.len();
    let rows = settings.measure.rows();
    if settings.poses.saturating_mul(rows) <= parameters {
        return Err(
            crate::refused!(too_few settings.poses.saturating_mul(rows), parameters + 1;
                "{} poses give {} equations for {parameters} identified parameters: a fit needs more equations than parameters (to estimate its own noise); plan at least {} poses",
                settings.poses,
                settings.poses.saturating_mul(rows),
                parameters / rows + 1
            ),
        );
    }
    let (scale, scaled) = unit_scaled(&info, candidates.len())?;
    let mut chosen = d_optimal_core(&scaled, &q, settings)?;
    fill_and_verify(&mut chosen, &q, settings)?;
    let prediction = predict(&info, &scaled, &scale, &chosen, settings)?;
    let mut by_candidate = chosen.clone();
    by_candidate.sort_unstable_by_key(|(i, _)| *i);
    let travel = |order: &[(usize, Role)]| {
        order
            .windows(2)
            .map(|w| move_deg(&q[w[0].0], &q[w[1].0]))
            .sum::<f64>()
    };
    let unordered = travel(&by_candidate);
    let ordered = measurement_order(&by_candidate, &q);
    Ok(Plan {
        joint_travel_deg: travel(&ordered),
        joint_travel_unordered_deg: unordered,
        poses: ordered
            .into_iter()
            .map(|(i, role)| PlannedPose {
                id: candidates[i].0.clone(),
                candidate: i,
                q: q[i].clone(),
                role,
            })
            .collect(),
        parameters: info.parameters.iter().map(|p| p.to_string()).collect(),
        undetermined: info.undetermined.iter().map(|p| p.to_string()).collect(),
        candidates: candidates.len(),
        settings: settings.clone(),
        prediction,
    })
}

#[cfg(test)]
mod tests {
    use super::one_turn;

    #[test]
    fn candidates_span_the_limits_or_one_turn_within_them() {
        let deg = |(a, b): (f64, f64)| (a.to_degrees().round(), b.to_degrees().round());
        let r = f64::to_radians;
        assert_eq!(deg(one_turn(r(190.0), r(350.0))), (190.0, 350.0));
        assert_eq!(deg(one_turn(r(-360.0), r(360.0))), (-180.0, 180.0));
        assert_eq!(deg(one_turn(r(-370.0), r(0.0))), (-360.0, 0.0));
        assert_eq!(deg(one_turn(r(100.0), r(900.0))), (100.0, 460.0));
        assert_eq!(
            deg(one_turn(f64::NEG_INFINITY, f64::INFINITY)),
            (-180.0, 180.0)
        );
    }
}
