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

pub mod program;

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
            return Err(crate::refused!("--poses must be at least 1"));
        }
        if self.core > self.poses {
            return Err(crate::refused!(
                "--core {} is more than --poses {}: the core is part of the fitted poses",
                self.core,
                self.poses
            ));
        }
        if !(self.min_distance_deg.is_finite() && self.min_distance_deg >= 0.0) {
            return Err(crate::refused!(
                "--min-distance-deg must be 0 or more degrees, got {}",
                self.min_distance_deg
            ));
        }
        if !(self.noise_mm.is_finite() && self.noise_mm > 0.0 && self.noise_mm < 100.0) {
            return Err(crate::refused!(
                "the noise level must be above 0 and below 100 mm, got {} (--noise-mm: the tracker's and the robot's repeatability, 1 sigma per coordinate)",
                self.noise_mm
            ));
        }
        if !(self.noise_deg.is_finite() && self.noise_deg > 0.0 && self.noise_deg < 10.0) {
            return Err(crate::refused!(
                "the orientation noise must be above 0 and below 10 deg, got {} (--noise-deg)",
                self.noise_deg
            ));
        }
        if !(self.k.is_finite() && self.k > 0.0) {
            return Err(crate::refused!(
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

/// The identification Jacobian of a set of joint configurations at the nominal model: the
/// parameters `calibrate` identifies on such data and one block of rows per pose.
struct Information {
    /// The identified parameters.
    parameters: Vec<Parameter>,
    /// Parameters of the robot's set that the configurations do not determine.
    undetermined: Vec<Parameter>,
    /// Per pose: its rows (3 position rows in mm, then for `pose` 3 orientation rows in rad
    /// times `sqrt(k)`), per mm or rad of each parameter.
    rows: Vec<DMatrix<f64>>,
}

/// The information of configurations `q` (rad) of the robot in `file` measured as `measure`:
/// the frames identified as `calibrate` does on tracker data (`base+tool`), the robot file's
/// identification set, less what the configurations cannot determine.
fn information(
    file: &RobotFile,
    robot_path: &std::path::Path,
    q: &[Vec<f64>],
    measure: Measure,
    k: f64,
) -> crate::Result<Information> {
    let model = file.to_model(robot_path)?;
    let nominal = Kinematics::nominal(&model.robot)?;
    let mut records = Vec::with_capacity(q.len());
    for (i, q) in q.iter().enumerate() {
        let angles = JointVec::<f64>::from_fn(q.len(), |j| q.get(j).copied().unwrap_or(0.0));
        let pose = nominal
            .forward(&angles)
            .with_context(|| format!("candidate {}", i + 1))?;
        records.push(Record {
            line: i as u64 + 1,
            id: (i + 1).to_string(),
            q: q.clone(),
            position: pose.translation.vector.into(),
            rotation: (measure == Measure::Pose).then(|| *pose.rotation.matrix()),
            weight: 1.0,
            role: None,
            configuration: None,
            time_s: None,
        });
    }
    // In a tracker's frame (here the base frame itself), as the measured file will be.
    let mut dataset = Dataset::from_records(file.clone(), records, false)?;
    let frames = Frames::chosen(None, &dataset.data);
    let (_, mask) = crate::measurement::frames::prepare(frames, &mut dataset, &mut [], k)?;
    let (mut mask, _) = crate::analysis::identifiability::default_mask(&dataset, mask, k)?;
    let report = analyse(&dataset, &mask, k)?;
    let undetermined = report.to_drop();
    for p in &undetermined {
        mask.set(*p, false);
    }
    let parameters: Vec<Parameter> = mask.iter().collect();
    let kinematics = Kinematics::nominal(&dataset.model.robot)?;
    let rows = dataset
        .measurements
        .iter()
        .map(|m| pose_rows(&kinematics, &parameters, &m.angles, measure, k))
        .collect::<crate::Result<_>>()?;
    Ok(Information {
        parameters,
        undetermined,
        rows,
    })
}

/// The rows of one pose: the change of the measured position (mm) and, for `pose`, orientation
/// (rad, times `sqrt(k)`) per mm or rad of each parameter, one parameter at a time.
fn pose_rows(
    kinematics: &Kinematics<f64, Dyn>,
    parameters: &[Parameter],
    angles: &JointAngles<f64, Dyn>,
    measure: Measure,
    k: f64,
) -> crate::Result<DMatrix<f64>> {
    let rows = measure.rows();
    let mut out = DMatrix::zeros(rows, parameters.len());
    for (j, p) in parameters.iter().enumerate() {
        let mut one = ParameterMask::empty_for(kinematics.joint_count());
        one.set(*p, true);
        let set = ParameterSet::<Dyn, nalgebra::U1>::from_mask(&one)?;
        let (_, twist) = kinematics.parameter_jacobian(&set, angles);
        for i in 0..rows {
            let scale = if i < 3 { 1.0 } else { k.sqrt() };
            out[(i, j)] = twist[(i, 0)] * scale;
        }
    }
    Ok(out)
}

/// The candidates' joint values, after checking that each has the robot's joint count and that
/// there are enough of them for the poses asked for.
fn checked_candidates(
    file: &RobotFile,
    candidates: &[(String, Vec<f64>)],
    settings: &PlanSettings,
) -> crate::Result<Vec<Vec<f64>>> {
    settings.check()?;
    let joints = file.joint.len();
    if let Some((id, q)) = candidates.iter().find(|(_, q)| q.len() != joints) {
        return Err(crate::refused!(
            "candidate {id} has {} joint values, the robot has {joints} joints",
            q.len()
        ));
    }
    // Saturating: counts beyond any file (`--poses 18446744073709551615`) are refused here, not
    // an overflow.
    let wanted = settings.poses.saturating_add(settings.verify);
    if candidates.len() < wanted {
        return Err(crate::refused!(
            "{} candidates cannot give {} fitted and {} verification poses; give more candidates (--generate N or a longer --candidates file) or ask for fewer poses",
            candidates.len(),
            settings.poses,
            settings.verify
        ));
    }
    crate::model::counts::joint_count(joints)?;
    Ok(candidates.iter().map(|(_, q)| q.clone()).collect())
}

/// The columns' scales (RMS over the `count` candidates) and every candidate's rows with its
/// columns scaled to unit RMS: units and lever arms drop out of the greedy step's
/// regularisation and of the conditioning. Error: a parameter no candidate moves.
fn unit_scaled(info: &Information, count: usize) -> crate::Result<(Vec<f64>, Vec<DMatrix<f64>>)> {
    let scale: Vec<f64> = (0..info.parameters.len())
        .map(|j| {
            let sum: f64 = info.rows.iter().map(|r| r.column(j).norm_squared()).sum();
            (sum / count as f64).sqrt()
        })
        .collect();
    if let Some(j) = scale
        .iter()
        .position(|s| s.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater))
    {
        return Err(crate::refused!(
            "{} changes no measurement at any candidate; leave it out of the robot file's identify list",
            info.parameters[j]
        ));
    }
    let scaled = info
        .rows
        .iter()
        .map(|r| {
            let mut s = r.clone();
            for (j, mut c) in s.column_iter_mut().enumerate() {
                c /= scale[j];
            }
            s
        })
        .collect();
    Ok((scale, scaled))
}

/// Whether candidate `i` is not chosen yet and at least `--min-distance-deg` from every chosen one.
fn far_enough(q: &[Vec<f64>], chosen: &[(usize, Role)], i: usize, settings: &PlanSettings) -> bool {
    chosen
        .iter()
        .all(|(c, _)| *c != i && distance_deg(&q[*c], &q[i]) >= settings.min_distance_deg)
}

/// The D-optimal core: `settings.core` candidates chosen greedily on the log determinant of the
/// regularised information of the unit-scaled rows `scaled`.
fn d_optimal_core(
    scaled: &[DMatrix<f64>],
    q: &[Vec<f64>],
    settings: &PlanSettings,
) -> crate::Result<Vec<(usize, Role)>> {
    let wanted = settings.poses.saturating_add(settings.verify);
    let parameters = scaled.first().map_or(0, DMatrix::ncols);
    let rows = settings.measure.rows();
    let mut chosen: Vec<(usize, Role)> = Vec::with_capacity(wanted);
    let mut information = DMatrix::<f64>::identity(parameters, parameters) * 1e-6;
    for _ in 0..settings.core {
        let inverse = information
            .clone()
            .cholesky()
            .map(|c| c.inverse())
            .ok_or_else(|| crate::numerical!("the information matrix lost its definiteness"))?;
        let mut best: Option<(usize, f64)> = None;
        for (i, j) in scaled.iter().enumerate() {
            if !far_enough(q, &chosen, i, settings) {
                continue;
            }
            let a = DMatrix::identity(rows, rows) + j * &inverse * j.transpose();
            let gain = a
                .cholesky()
                .map_or(f64::NEG_INFINITY, |c| c.l().diagonal().map(f64::ln).sum());
            if best.is_none_or(|(_, g)| gain > g) {
                best = Some((i, gain));
            }
        }
        let Some((i, _)) = best else {
            return Err(crate::refused!(
                "only {} candidates are at least {} deg apart; lower --min-distance-deg or give more candidates",
                chosen.len(),
                settings.min_distance_deg
            ));
        };
        information += scaled[i].transpose() * &scaled[i];
        chosen.push((i, Role::Core));
    }
    Ok(chosen)
}

/// Adds the fill and verification poses to `chosen`: random candidates, far enough from every
/// chosen pose; for joint maps the fill poses spread each joint's readings instead.
fn fill_and_verify(
    chosen: &mut Vec<(usize, Role)>,
    q: &[Vec<f64>],
    settings: &PlanSettings,
) -> crate::Result<()> {
    let wanted = settings.poses.saturating_add(settings.verify);
    let order = crate::measurement::dataset::shuffled(q.len(), settings.seed);
    let mut random = order.clone().into_iter();
    let ranges = joint_ranges(q);
    for (role, count) in [
        (Role::Fill, settings.poses - settings.core),
        (Role::Verify, settings.verify),
    ] {
        for _ in 0..count {
            let next = if role == Role::Fill && settings.model == PlanModel::JointMaps {
                even_fill(q, &ranges, chosen, &order, |i| {
                    far_enough(q, chosen, i, settings)
                })
            } else {
                random
                    .by_ref()
                    .find(|i| far_enough(q, chosen, *i, settings))
            };
            let Some(i) = next else {
                return Err(crate::refused!(
                    "only {} candidates are at least {} deg apart, {wanted} are needed; lower --min-distance-deg or give more candidates",
                    chosen.len(),
                    settings.min_distance_deg
                ));
            };
            chosen.push((i, role));
        }
    }
    Ok(())
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
        return Err(crate::refused!(
            "{} poses give {} equations for {parameters} identified parameters: a fit needs more equations than parameters (to estimate its own noise); plan at least {} poses",
            settings.poses,
            settings.poses.saturating_mul(rows),
            parameters / rows + 1
        ));
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

/// Each joint's range of readings over the candidates, rad (0 for a joint that does not move).
fn joint_ranges(q: &[Vec<f64>]) -> Vec<f64> {
    let joints = q.first().map_or(0, Vec::len);
    (0..joints)
        .map(|j| {
            let (low, high) = q
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), c| {
                    (l.min(c[j]), h.max(c[j]))
                });
            (high - low).max(0.0)
        })
        .collect()
}

/// The fill pose for joint maps: of the candidates that `eligible` admits (tried in `order`, the
/// first wins a tie), the one whose readings are farthest, joint by joint, from the readings
/// already chosen: the sum over the joints of the distance to the nearest chosen reading, as a
/// fraction of the joint's range. Each map is identified from its own joint's readings, so the
/// fill covers every joint's range evenly instead of the extremes a D-optimal set favours.
fn even_fill(
    q: &[Vec<f64>],
    ranges: &[f64],
    chosen: &[(usize, Role)],
    order: &[usize],
    eligible: impl Fn(usize) -> bool,
) -> Option<usize> {
    let spread = |i: usize| -> f64 {
        (ranges.iter().enumerate())
            .filter(|(_, r)| **r > 0.0)
            .map(|(j, r)| {
                let nearest = (chosen.iter())
                    .map(|(c, _)| (q[*c][j] - q[i][j]).abs())
                    .fold(f64::INFINITY, f64::min);
                nearest.min(*r) / r
            })
            .sum()
    };
    order
        .iter()
        .copied()
        .filter(|i| eligible(*i))
        .map(|i| (i, spread(i)))
        .fold(None, |best: Option<(usize, f64)>, (i, s)| match best {
            Some((_, b)) if b >= s => best,
            _ => Some((i, s)),
        })
        .map(|(i, _)| i)
}

/// Euclidean joint-space distance, degrees.
fn distance_deg(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
        .to_degrees()
}

/// The largest joint move between two configurations, degrees (what a move takes when the
/// joints move together).
fn move_deg(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        .to_degrees()
}

/// The poses in an order that keeps the joint motion short: nearest neighbour from the first
/// (in the candidates' order), then 2-opt moves while any shortens the path.
fn measurement_order(poses: &[(usize, Role)], q: &[Vec<f64>]) -> Vec<(usize, Role)> {
    let d = |a: &(usize, Role), b: &(usize, Role)| move_deg(&q[a.0], &q[b.0]);
    let mut left: Vec<(usize, Role)> = poses.to_vec();
    let mut path = Vec::with_capacity(poses.len());
    if left.is_empty() {
        return path;
    }
    path.push(left.remove(0));
    while !left.is_empty() {
        let Some(last) = path.last() else { break };
        let (next, _) = left
            .iter()
            .enumerate()
            .map(|(i, p)| (i, d(last, p)))
            .fold((0, f64::INFINITY), |b, c| if c.1 < b.1 { c } else { b });
        path.push(left.remove(next));
    }
    // 2-opt on the open path: reverse path[i+1..=j] when that shortens it.
    let n = path.len();
    for _ in 0..100 {
        let mut improved = false;
        for i in 0..n.saturating_sub(2) {
            for j in i + 2..n {
                let before = d(&path[i], &path[i + 1])
                    + if j + 1 < n {
                        d(&path[j], &path[j + 1])
                    } else {
                        0.0
                    };
                let after = d(&path[i], &path[j])
                    + if j + 1 < n {
                        d(&path[i + 1], &path[j + 1])
                    } else {
                        0.0
                    };
                if after < before - 1e-9 {
                    path[i + 1..=j].reverse();
                    improved = true;
                }
            }
        }
        if !improved {
            break;
        }
    }
    path
}

/// Mean of the length of a 3-D isotropic normal vector per unit sigma: `sqrt(8/pi)`.
fn maxwell_mean() -> f64 {
    (8.0 / PI).sqrt()
}

/// Variance of that length per unit sigma squared: `3 - 8/pi`.
fn maxwell_variance() -> f64 {
    3.0 - 8.0 / PI
}

/// The covariance of the identified parameters (in their units) of a fit to the unit-scaled
/// rows `stacked` whose columns were divided by `scale`, under the noise of `settings`: `S^-1
/// A^-1 (J~^T Sigma J~) A^-1 S^-1`. Error: the rows do not determine every parameter.
fn parameter_covariance(
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
        return Err(crate::refused!(
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
fn conditioning(stacked: &DMatrix<f64>, poses: usize) -> (f64, f64) {
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
fn planned_verification(
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
fn predict(
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
fn stack<'m>(blocks: impl Iterator<Item = &'m DMatrix<f64>>, columns: usize) -> DMatrix<f64> {
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
        return Err(crate::refused!(
            "the fitted poses do not determine every parameter"
        ));
    };
    Ok(info
        .rows
        .iter()
        .map(|j| (j * &inverse * j.transpose()).trace())
        .collect())
}

/// The range a joint's candidates are drawn from, rad: its limits `[lower, upper]` when they
/// span at most a turn (wherever they lie, as [190, 350] deg), else the turn within them nearest
/// to [-180, 180] deg (readings a turn apart give the same pose).
fn one_turn(lower: f64, upper: f64) -> (f64, f64) {
    if upper - lower <= 2.0 * PI {
        (lower, upper)
    } else {
        let start = (-PI).clamp(lower, upper - 2.0 * PI);
        (start, start + 2.0 * PI)
    }
}

/// Candidate configurations spread over the joint limits (an unlimited joint: +-180 deg): `count`
/// points of a Halton sequence (the core's), skipping its first point; with `box_mm` only those
/// whose nominal tool point lies in the box `[x_min, x_max, y_min, y_max, z_min, z_max]` of the
/// base frame (at most 100 times `count` points are tried).
pub fn generate(
    file: &RobotFile,
    robot_path: &std::path::Path,
    count: usize,
    box_mm: Option<[f64; 6]>,
) -> crate::Result<Vec<(String, Vec<f64>)>> {
    crate::model::counts::joint_count(file.joint.len())?;
    let robot: Robot<f64, Dyn> = file.to_model(robot_path)?.robot;
    let joints = robot.joints.len();
    if joints > calib_core::identify::halton::MAX_DIMENSION {
        return Err(crate::refused!(
            "--generate handles up to {} joints",
            calib_core::identify::halton::MAX_DIMENSION
        ));
    }
    let kinematics = Kinematics::nominal(&robot)?;
    let bounds: Vec<(f64, f64)> = robot
        .limits
        .iter()
        .map(|l| one_turn(l.lower, l.upper))
        .collect();
    let mut out = Vec::with_capacity(count);
    let mut point = vec![0.0; joints];
    for index in 1..=(count as u64).saturating_mul(100) {
        if out.len() == count {
            break;
        }
        calib_core::identify::halton::halton_point(
            index,
            calib_core::identify::halton::Scrambling::None,
            &mut point,
        );
        let q = JointVec::<f64>::from_fn(bounds.len(), |j| {
            bounds[j].0 + point[j] * (bounds[j].1 - bounds[j].0)
        });
        if let Some(b) = box_mm {
            let p = kinematics.forward(&q)?.translation.vector;
            let inside = (0..3).all(|a| (b[2 * a]..=b[2 * a + 1]).contains(&p[a]));
            if !inside {
                continue;
            }
        }
        out.push((format!("C{:04}", out.len() + 1), q.to_vec()));
    }
    if out.len() < count {
        return Err(crate::refused!(
            "only {} of {count} generated configurations put the tool point in the box {} mm (base frame); widen the box or give candidates (--candidates)",
            out.len(),
            box_mm
                .map(|b| format!(
                    "x {} ... {}, y {} ... {}, z {} ... {}",
                    b[0], b[1], b[2], b[3], b[4], b[5]
                ))
                .unwrap_or_default()
        ));
    }
    Ok(out)
}

/// What `calibrate` says of a plan's verification poses once measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
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

    /// Text for people.
    pub fn text(&self) -> String {
        let p = &self.predicted;
        let mut out = format!(
            "plan check: {} verification poses, measured mean position error {:.4} mm; the plan predicted {:.4} mm (95 % range {:.4} ... {:.4} mm, noise {:.4} mm)\n",
            self.poses, self.measured_mean_mm, p.mean_mm, p.low_mm, p.high_mm, p.noise_mm
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
