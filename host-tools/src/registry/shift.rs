//! The shift check (`calib check-shift`, issue 55 item 3): a short set of poses measured with
//! the tracker at the start of a shift, against the registered calibration's prediction and the
//! uncertainty it carries. Is the robot still within its calibration, and if not, what moved?
//!
//! Each pose's position error `e = measured - predicted` (the identified model in the
//! calibration's own measurement setup: its registered tracker placement and probe) is judged
//! against its covariance `C = J S J^T + sigma^2 I` (the identified parameters' covariance `S`
//! propagated as the certificate does, and the instrument's noise `sigma`, by default estimated
//! from the calibration's own position residuals). A pose lies beyond its prediction when `e^T C^-1 e`
//! exceeds the chi-square (3 degrees of freedom) point of `k` standard deviations (`k = 3`:
//! 99.73 %, 14.16). The robot has drifted when more poses lie beyond than chance gives at that
//! level (the binomial distribution's count, so that one pose in ten past 3 standard deviations
//! is not an alarm by itself), or when the errors together do (the sum of `e^T C^-1 e` over the
//! poses against the chi-square point of `3 n` degrees of freedom: a small shift of every pose),
//! or when any pose's `|e|` exceeds a stated limit in mm.
//!
//! The likely cause is the simplest change that explains the errors down to the noise: one
//! joint's zero (1 parameter), the tool or probe moved on the flange (3), the robot's base moved
//! against the tracker (6; a moved tracker looks the same). Each is fitted to the errors by least
//! squares; the first, by fewest parameters, whose remaining errors are consistent with the
//! noise (their sum of squares within the chi-square distribution's 95 % point) is named, with
//! its fitted values. None consistent: the robot changed in a way no single cause explains, and
//! the one explaining most is stated as partial.

use super::record::Record;
use crate::measurement::dataset::Dataset;
use calib_core::{FrameParameter, JointAngles, JointParameter, Kinematics, Parameter};
use calib_core::{ParameterMask, ParameterSet};
use nalgebra::{DMatrix, DVector, Dyn, Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use statrs::distribution::{ChiSquared, ContinuousCDF as _};
use std::path::Path;

/// Standard deviations a pose may lie from its prediction, by default.
pub const DEFAULT_K: f64 = 3.0;

/// How the check judges.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShiftSettings {
    /// Drift beyond `k` standard deviations (in the pose's own covariance).
    pub k: f64,
    /// Drift beyond this position error, mm, when given.
    pub limit_mm: Option<f64>,
    /// The instrument's noise per coordinate, mm (`None`: the calibration's own estimate).
    pub noise_mm: Option<f64>,
    /// The tracker was placed anew since the calibration: its placement is fitted on the
    /// check's poses first (6 parameters), so a base that moved cannot be told from it.
    pub register_tracker: bool,
}

impl Default for ShiftSettings {
    fn default() -> Self {
        Self {
            k: DEFAULT_K,
            limit_mm: None,
            noise_mm: None,
            register_tracker: false,
        }
    }
}

/// One pose of the check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseCheck {
    /// Its line in the data file.
    pub line: u64,
    /// Its id, when the data name their poses.
    pub id: String,
    /// Measured minus predicted position along the measurement frame's x, y, z, mm.
    pub error_mm: [f64; 3],
    /// `|error|`, mm.
    pub distance_mm: f64,
    /// The RMS of the error its covariance predicts (parameters and noise), mm.
    pub predicted_rms_mm: f64,
    /// `e^T C^-1 e`.
    pub mahalanobis_squared: f64,
    /// Beyond `k` standard deviations.
    pub beyond: bool,
    /// Beyond the limit in mm, when one is given.
    pub over_limit: bool,
}

/// A cause fitted to the errors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Cause {
    /// `joint 2's zero`, `the tool or probe on the flange`, `the base against the tracker`.
    pub name: String,
    /// The fitted change of each of its parameters: name, value, unit (`mm` or `deg`).
    pub change: Vec<(String, f64, String)>,
    /// The share of the errors' sum of squares it explains.
    pub explained: f64,
    /// The RMS position error left, mm.
    pub remaining_rms_mm: f64,
    /// The errors left are consistent with the noise and the model's uncertainty.
    pub consistent: bool,
}

/// A shift check's result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShiftCheck {
    /// The robot.
    pub serial: String,
    /// The calibration it was checked against.
    pub calibration: i64,
    /// The data file.
    pub data: String,
    /// Its SHA-256.
    pub data_sha256: String,
    /// How it judged.
    pub settings: ShiftSettings,
    /// The noise used, mm per coordinate.
    pub noise_mm: f64,
    /// The chi-square point of `k` standard deviations (3 degrees of freedom).
    pub threshold: f64,
    /// Mean position error, mm.
    pub mean_mm: f64,
    /// Largest, mm.
    pub max_mm: f64,
    /// Every pose.
    pub poses: Vec<PoseCheck>,
    /// Poses beyond `k` standard deviations.
    pub beyond: usize,
    /// The most poses chance puts beyond `k` standard deviations at that level.
    pub beyond_allowed: usize,
    /// The sum of `e^T C^-1 e` over the poses.
    pub mahalanobis_squared_sum: f64,
    /// Its chi-square point of `k` standard deviations (`3 n` degrees of freedom).
    pub sum_threshold: f64,
    /// Drifted: more poses beyond than chance gives, the sum beyond its point, or a pose over
    /// the limit.
    pub drifted: bool,
    /// The likely cause (when drifted): the simplest consistent one, else the one explaining
    /// most.
    pub cause: Option<Cause>,
}

/// Checks the poses in `data` (read through `profile`) against `record`'s calibration.
/// Refused: a record without its identified file or covariance-free and noise-free (give
/// `--noise-mm`), data of another robot.
pub fn check(
    record: &Record,
    data: &Path,
    profile: &crate::io::profile::DataProfile,
    settings: ShiftSettings,
) -> crate::Result<ShiftCheck> {
    let id = record.id;
    let (file, path) = record.identified_file().ok_or_else(|| {
        crate::refused!(input format!("record {id}");
            "record {id} keeps no identified robot file to predict the poses with: register the calibration with --identified FILE")
    })??;
    let bytes = crate::io::input::read(data, crate::io::input::Input::Data)
        .map_err(|e| crate::refused!(input data.display(); "--data {}: {e}", data.display()))?;
    // Parsed from the bytes hashed: the check's SHA-256 is of the data it judged.
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        crate::refused!(input data.display();
            "--data {}: byte {} is not UTF-8 text; save the file as UTF-8", data.display(), e.valid_up_to())
    })?;
    let tracker = crate::io::tracker_data::TrackerData::parse_profiled(text, data, profile)?;
    let dataset = Dataset::from_data(file, &path, tracker)?;
    let noise = noise_of(record, settings)?;
    let (robot, covariance) = model_of(&dataset, settings.register_tracker, &path)?;
    let kinematics = Kinematics::nominal(&robot.model.robot)?;
    let (level, threshold) = threshold_of(settings.k)?;
    let seen = dataset.seen_by(&robot)?;
    let (poses, errors) = judge(
        &kinematics,
        covariance.as_ref(),
        (&seen.measurements, &dataset.data.records),
        (noise, threshold, settings.limit_mm),
    );
    let n = poses.len().max(1) as f64;
    let beyond = poses.iter().filter(|p| p.beyond).count();
    let beyond_allowed = allowed_by_chance(poses.len(), level)?;
    let mahalanobis_squared_sum: f64 = poses.iter().map(|p| p.mahalanobis_squared).sum();
    let fitted = if settings.register_tracker { 6.0 } else { 0.0 };
    let sum_threshold = ChiSquared::new((3.0 * n - fitted).max(1.0))
        .map_err(|e| crate::numerical!("chi-square: {e}"))?
        .inverse_cdf(level);
    let drifted = beyond > beyond_allowed
        || mahalanobis_squared_sum > sum_threshold
        || poses.iter().any(|p| p.over_limit);
    Ok(ShiftCheck {
        serial: record.calibration.serial.clone(),
        calibration: id,
        data: data.display().to_string(),
        data_sha256: super::record::sha256(&bytes),
        settings,
        noise_mm: noise,
        threshold,
        mean_mm: poses.iter().map(|p| p.distance_mm).sum::<f64>() / n,
        max_mm: poses.iter().map(|p| p.distance_mm).fold(0.0, f64::max),
        cause: if drifted {
            likely_cause(&kinematics, &errors, !settings.register_tracker)?
        } else {
            None
        },
        drifted,
        beyond,
        beyond_allowed,
        mahalanobis_squared_sum,
        sum_threshold,
        poses,
    })
}

/// The most of `n` poses that lie beyond the `level` point by chance: the largest count `c`
/// with a probability of at least `c` such poses above `1 - level`.
fn allowed_by_chance(n: usize, level: f64) -> crate::Result<usize> {
    use statrs::distribution::DiscreteCDF as _;
    let binomial = statrs::distribution::Binomial::new(1.0 - level, n as u64)
        .map_err(|e| crate::numerical!("binomial: {e}"))?;
    // P(X >= c + 1) = sf(c).
    Ok((0..n as u64)
        .find(|c| binomial.sf(*c) <= 1.0 - level)
        .map_or(n, |c| c as usize))
}

/// The model the poses are predicted with (the calibration's measurement setup, or its tracker
/// placement fitted anew with `register_tracker`) and its parameters' covariance, if recorded.
fn model_of(
    dataset: &Dataset,
    register_tracker: bool,
    path: &Path,
) -> crate::Result<(crate::kinematics::actual::ActualRobot, Option<Covariance>)> {
    let robot = match (register_tracker, &dataset.robot.file.measurement) {
        (true, _) => {
            let k = calib_core::identify::objective::DEFAULT_K;
            let frames = crate::measurement::frames::Frames::Base;
            crate::measurement::frames::register_setup(&dataset.robot, frames, dataset, k)?.robot
        }
        (false, Some(_)) => dataset.robot.in_measurement_setup()?,
        (false, None) => dataset.robot.clone(),
    };
    let recorded = (robot.file.calibration.as_ref()).and_then(|c| c.covariance.as_ref());
    let covariance = match recorded {
        Some(_) => Some(crate::analysis::uncertainty::recorded_covariance(
            &robot.file,
            path,
        )?),
        None => None,
    };
    Ok((robot, covariance))
}

/// The identified parameters and their covariance (mm, rad).
type Covariance = (ParameterSet<Dyn, Dyn>, DMatrix<f64>);

/// A pose's angles, position error (mm) and variance per coordinate (mm^2).
type PoseError = (JointAngles<f64, Dyn>, Vector3<f64>, f64);

/// The probability `k` standard deviations cover, and its chi-square point (3 degrees of
/// freedom).
fn threshold_of(k: f64) -> crate::Result<(f64, f64)> {
    if !(k.is_finite() && k > 0.0) {
        return Err(
            crate::refused!(option "--k"; "--k {k}: give a positive number of standard deviations (3 by default)"),
        );
    }
    let p = statrs::function::erf::erf(k / std::f64::consts::SQRT_2);
    let point = ChiSquared::new(3.0)
        .map_err(|e| crate::numerical!("chi-square: {e}"))?
        .inverse_cdf(p);
    Ok((p, point))
}

/// Each pose judged against its covariance (the parameters' `covariance` propagated, and the
/// `noise`): beyond `threshold`, over `limit_mm`. Also each pose's angles, error and
/// variance per coordinate, for the causes.
fn judge(
    kinematics: &Kinematics<f64, Dyn>,
    covariance: Option<&Covariance>,
    (measurements, rows): (
        &[calib_core::identify::objective::Measurement<f64, Dyn>],
        &[crate::io::tracker_data::Record],
    ),
    (noise, threshold, limit_mm): (f64, f64, Option<f64>),
) -> (Vec<PoseCheck>, Vec<PoseError>) {
    let mut poses = Vec::with_capacity(measurements.len());
    let mut errors = Vec::with_capacity(measurements.len());
    for (m, row) in measurements.iter().zip(rows) {
        let predicted = kinematics.forward_angles(&m.angles).translation.vector;
        let e: Vector3<f64> = m.position - predicted;
        let parameters = covariance.map_or(Matrix3::zeros(), |(set, s)| {
            crate::analysis::uncertainty::pose_covariance(kinematics, set, s, &m.angles).0
        });
        let c = parameters + Matrix3::identity() * noise * noise;
        let mahalanobis = c
            .try_inverse()
            .map_or(f64::INFINITY, |inverse| (e.transpose() * inverse * e)[0]);
        let distance = e.norm();
        poses.push(PoseCheck {
            line: row.line,
            id: row.id.clone(),
            error_mm: [e.x, e.y, e.z],
            distance_mm: distance,
            predicted_rms_mm: c.trace().max(0.0).sqrt(),
            mahalanobis_squared: mahalanobis,
            beyond: mahalanobis > threshold,
            over_limit: limit_mm.is_some_and(|limit| distance > limit),
        });
        errors.push((m.angles, e, c.trace() / 3.0));
    }
    (poses, errors)
}

/// The noise per coordinate, mm: given, else estimated from the calibration's own position
/// residuals: their RMS length over the calibration poses, per coordinate (`/ sqrt 3`), and
/// corrected for the parameters the fit took (`sqrt(rows / (rows - parameters))`). (Least
/// squares' residual sigma would not do for 6-DoF data: it mixes the position rows with the
/// orientation rows, in their weighting.)
fn noise_of(record: &Record, settings: ShiftSettings) -> crate::Result<f64> {
    if let Some(noise) = settings.noise_mm {
        if !(noise.is_finite() && noise > 0.0) {
            return Err(crate::refused!(option "--noise-mm";
                "--noise-mm {noise}: give the instrument's noise per coordinate, a positive number of mm"));
        }
        return Ok(noise);
    }
    let report: serde_json::Value =
        serde_json::from_str(&record.calibration.report).unwrap_or_default();
    let rms = report["calibration"]["after"]["position_mm"]["rms"].as_f64();
    let rows = report["least_squares"]["rows"].as_f64();
    let parameters = report["parameters"].as_object().map(|p| p.len() as f64);
    let estimate = match (rms, rows, parameters) {
        (Some(rms), Some(rows), Some(p)) => {
            crate::analysis::budget::residual_noise_mm(rms, rows, p)
        }
        _ => None,
    };
    match estimate {
        Some(noise) => Ok(noise),
        None => Err(crate::refused!(option "--noise-mm";
            "record {}'s report states no least-squares fit to estimate the noise from: give --noise-mm, the instrument's noise per coordinate", record.id)),
    }
}

/// The hypotheses, simplest first: each joint's zero, the tool, the base (with `base`).
fn hypotheses(joints: usize, base: bool) -> Vec<(String, Vec<Parameter>)> {
    let mut out: Vec<(String, Vec<Parameter>)> = (1..=joints)
        .map(|j| {
            let name = if j == 1 {
                "joint 1's zero (or the base turned about joint 1's axis: the two look alike)"
                    .to_string()
            } else {
                format!("joint {j}'s zero")
            };
            let joint = u8::try_from(j).unwrap_or(u8::MAX);
            (
                name,
                vec![Parameter::Joint {
                    joint,
                    kind: JointParameter::Theta,
                }],
            )
        })
        .collect();
    let translation = [FrameParameter::Tx, FrameParameter::Ty, FrameParameter::Tz];
    out.push((
        "the tool or probe moved on the flange".to_string(),
        translation.iter().map(|k| Parameter::Tool(*k)).collect(),
    ));
    if !base {
        return out;
    }
    out.push((
        "the base moved against the tracker (or the tracker against the base: the two look alike)"
            .to_string(),
        FrameParameter::ALL
            .iter()
            .map(|k| Parameter::Base(*k))
            .collect(),
    ));
    out
}

/// The simplest cause consistent with the errors, else the one explaining most.
fn likely_cause(
    kinematics: &Kinematics<f64, Dyn>,
    errors: &[PoseError],
    base: bool,
) -> crate::Result<Option<Cause>> {
    let rows = 3 * errors.len();
    let r = DVector::from_iterator(rows, errors.iter().flat_map(|(_, e, _)| e.iter().copied()));
    let total: f64 = r.norm_squared();
    // The variance each coordinate's error has without any change.
    let variance = errors.iter().map(|(_, _, v)| v).sum::<f64>() / errors.len().max(1) as f64;
    let joints = nalgebra::Dim::value(&kinematics.joint_count());
    let mut causes = Vec::new();
    for (name, parameters) in hypotheses(joints, base) {
        let p = parameters.len();
        if rows <= p {
            continue;
        }
        let mut mask = ParameterMask::empty_for(crate::model::counts::joint_count(joints)?);
        for parameter in &parameters {
            mask.set(*parameter, true);
        }
        let set = ParameterSet::<Dyn, Dyn>::from_mask(&mask)?;
        let mut j = DMatrix::zeros(rows, p);
        for (i, (angles, _, _)) in errors.iter().enumerate() {
            let (_, jacobian) = kinematics.parameter_jacobian(&set, angles);
            j.view_mut((3 * i, 0), (3, p))
                .copy_from(&jacobian.view((0, 0), (3, p)));
        }
        let x = j
            .clone()
            .svd(true, true)
            .solve(&r, 1e-12)
            .map_err(|e| crate::numerical!("fitting {name}: {e}"))?;
        let remaining = (&r - &j * &x).norm_squared();
        let limit = ChiSquared::new((rows - p) as f64)
            .map_err(|e| crate::numerical!("chi-square: {e}"))?
            .inverse_cdf(0.95);
        let change = (set.parameters().iter().zip(x.iter()))
            .map(|(parameter, v)| {
                let (value, unit) = match parameter.is_angle() {
                    true => (v.to_degrees(), "deg"),
                    false => (*v, "mm"),
                };
                (parameter.to_string(), value, unit.to_string())
            })
            .collect();
        causes.push(Cause {
            name,
            change,
            explained: if total > 0.0 {
                1.0 - remaining / total
            } else {
                0.0
            },
            remaining_rms_mm: (remaining / errors.len().max(1) as f64).sqrt(),
            consistent: remaining / variance <= limit,
        });
    }
    let simplest = causes.iter().find(|c| c.consistent).cloned();
    Ok(simplest.or_else(|| {
        causes
            .into_iter()
            .max_by(|a, b| a.explained.total_cmp(&b.explained))
    }))
}

impl ShiftCheck {
    /// The check for people.
    pub fn text(&self) -> String {
        let mut text = format!(
            "shift check of robot {} against calibration record {}: {} poses of {}\n",
            self.serial,
            self.calibration,
            self.poses.len(),
            self.data
        );
        text.push_str(&format!(
            "position error: mean {:.4} mm, largest {:.4} mm; judged at {} standard deviations (chi-square {:.2}, noise {:.4} mm per coordinate){}\n",
            self.mean_mm,
            self.max_mm,
            self.settings.k,
            self.threshold,
            self.noise_mm,
            self.settings.limit_mm.map_or(String::new(), |l| format!(" and the limit {l} mm"))
        ));
        for p in self.poses.iter().filter(|p| p.beyond || p.over_limit) {
            text.push_str(&format!(
                "  {}: line {}{}: {:.4} mm (predicted {:.4} mm RMS; {:.1} standard deviations)\n",
                if p.over_limit {
                    "over the limit"
                } else {
                    "beyond"
                },
                p.line,
                if p.id.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", p.id)
                },
                p.distance_mm,
                p.predicted_rms_mm,
                p.mahalanobis_squared.sqrt()
            ));
        }
        text.push_str(&format!(
            "{} of {} poses beyond {} standard deviations (chance allows {}); all together: {:.1} against {:.1}\n",
            self.beyond,
            self.poses.len(),
            self.settings.k,
            self.beyond_allowed,
            self.mahalanobis_squared_sum,
            self.sum_threshold
        ));
        if !self.drifted {
            text.push_str("OK: within its calibration's prediction\n");
            return text;
        }
        text.push_str("DRIFT: beyond its calibration's prediction\n");
        if let Some(c) = &self.cause {
            let values: Vec<String> = (c.change.iter())
                .map(|(name, v, unit)| format!("{name} {v:+.4} {unit}"))
                .collect();
            text.push_str(&format!(
                "likely cause: {} ({}): explains {:.1} % of the errors, {:.4} mm RMS left{}\n",
                c.name,
                values.join(", "),
                100.0 * c.explained,
                c.remaining_rms_mm,
                if c.consistent {
                    ""
                } else {
                    "; no single cause explains them down to the noise: recalibrate"
                }
            ));
        }
        text
    }
}

/// A recorded shift check, as listed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CheckSummary {
    /// Its number.
    pub id: i64,
    /// The calibration record it checked against.
    pub calibration: i64,
    /// The robot.
    pub serial: String,
    /// When it was measured (RFC 3339).
    pub checked_at: String,
    /// Poses measured.
    pub poses: i64,
    /// Mean position error, mm.
    pub mean_mm: f64,
    /// Largest, mm.
    pub max_mm: f64,
    /// Some pose drifted.
    pub drifted: bool,
    /// The likely cause named, when drifted.
    pub cause: Option<String>,
}

/// The drift of the checks against one calibration over time: the least-squares line through
/// their mean errors.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DriftRate {
    /// The calibration record the checks are against.
    pub calibration: i64,
    /// Checks on the line.
    pub checks: usize,
    /// Days from the first to the last.
    pub days: f64,
    /// The slope, mm of mean error per 30 days.
    pub mm_per_30_days: f64,
    /// Its standard error, mm per 30 days (`None` with 2 checks: a line through two points).
    pub sd_mm_per_30_days: Option<f64>,
}

/// The drift rate of the checks against the latest calibration checked; `None` with fewer than
/// two such checks, or all within a day.
pub fn drift_rate(checks: &[CheckSummary]) -> Option<DriftRate> {
    let calibration = checks.last()?.calibration;
    let points: Vec<(f64, f64)> = (checks.iter())
        .filter(|c| c.calibration == calibration)
        .filter_map(|c| {
            let t = humantime::parse_rfc3339(&c.checked_at).ok()?;
            let s = t.duration_since(std::time::UNIX_EPOCH).ok()?.as_secs_f64();
            Some((s / 86_400.0, c.mean_mm))
        })
        .collect();
    let n = points.len() as f64;
    if points.len() < 2 {
        return None;
    }
    let (mt, my) = (
        points.iter().map(|p| p.0).sum::<f64>() / n,
        points.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = points.iter().map(|p| (p.0 - mt).powi(2)).sum();
    if points.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max)
        - points.iter().map(|p| p.0).fold(f64::INFINITY, f64::min)
        < 1.0
    {
        return None;
    }
    let slope = points.iter().map(|p| (p.0 - mt) * (p.1 - my)).sum::<f64>() / sxx;
    let sd = (points.len() > 2).then(|| {
        let rss: f64 = (points.iter())
            .map(|p| (p.1 - my - slope * (p.0 - mt)).powi(2))
            .sum();
        (rss / (n - 2.0) / sxx).sqrt() * 30.0
    });
    let first = points.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let last = points.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    Some(DriftRate {
        calibration,
        checks: points.len(),
        days: last - first,
        mm_per_30_days: slope * 30.0,
        sd_mm_per_30_days: sd,
    })
}

impl DriftRate {
    /// The rate for people.
    pub fn text(&self) -> String {
        format!(
            "drift over {} checks against record {} in {:.1} days: {:+.4} mm of mean error per 30 days{}\n",
            self.checks,
            self.calibration,
            self.days,
            self.mm_per_30_days,
            self.sd_mm_per_30_days
                .map_or(String::new(), |sd| format!(" (+- {sd:.4})"))
        )
    }
}

/// A shift check run and recorded, as `calib check-shift` prints it with `--json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Recorded {
    /// The check's number in the registry.
    pub check: i64,
    /// When the poses were measured (RFC 3339).
    pub checked_at: String,
    /// The check.
    pub result: ShiftCheck,
    /// The drift rate of the robot's checks, this one included.
    pub drift_rate: Option<DriftRate>,
}

/// Checks robot `serial` with the poses in `data` (through `profile`) against its calibration
/// `record` (default: the latest) in the registry `db`, records the check as measured at
/// `checked_at` (RFC 3339; default now) and states the drift rate. Refused: no such robot or
/// record, a time that is not RFC 3339, and as [`check`] and [`super::Registry::add_check`].
pub fn check_and_record(
    db: &Path,
    serial: &str,
    data: &Path,
    profile: &crate::io::profile::DataProfile,
    (record, checked_at): (Option<i64>, Option<&str>),
    settings: ShiftSettings,
) -> crate::Result<Recorded> {
    let checked_at = super::time_or_now(checked_at, "--checked-at")?;
    let mut registry = super::Registry::open(db, super::Access::Write)?;
    let records = registry.robot(serial)?;
    let chosen = match record {
        Some(id) => records.iter().find(|r| r.id == id).ok_or_else(|| {
            crate::refused!(option "--record"; "--record {id}: no calibration record {id} of robot {serial}")
        })?,
        None => records.last().ok_or_else(|| {
            crate::refused!(option "--serial";
                "no calibration of robot {serial} is registered: register one (calib registry add) before checking it")
        })?,
    };
    let result = check(chosen, data, profile, settings)?;
    let id = registry.add_check(&result, &checked_at)?;
    let drift_rate = drift_rate(&registry.checks(serial)?);
    Ok(Recorded {
        check: id,
        checked_at,
        result,
        drift_rate,
    })
}
