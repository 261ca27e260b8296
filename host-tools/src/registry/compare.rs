//! Two registered calibrations compared (`calib registry compare A B`, issue 55 item 2): two
//! calibrations of one robot (has it changed?) or of two robots of one model (ISO 9283
//! exchangeability: can one's program run on the other?).
//!
//! Both records must keep their identified robot files (`calib registry add --identified`). The
//! parameters compared are the joint and frame errors either file lists in `[calibration.errors]`
//! (relative to the one nominal model both were identified against; a parameter one calibration
//! did not identify stays at its nominal value, exactly). Each change is judged against the
//! uncertainty both calibrations carry: per parameter `z = (b - a) / sqrt(var_a + var_b)`,
//! significant beyond [`Z_95`]; jointly the Mahalanobis distance `d^T (S_a + S_b)^+ d` of all
//! changes against the chi-square distribution of as many degrees of freedom as the summed
//! covariance has rank (the pseudo-inverse keeps directions neither calibration determined out
//! of the test). The joint test needs both full covariances (`calib calibrate` with least
//! squares records them); with standard errors alone only the parameters are judged.
//!
//! What the change does is stated where it matters, at the tool: over [`DEFAULT_POSES`]
//! configurations spread over the joint limits (the core's Halton sequence, as `calib plan
//! --generate` draws them), the tool point of calibration `b`'s controller model against `a`'s
//! (mean, 95th percentile, largest, and where in the workspace: the terciles of
//! [`crate::analysis::workspace`]), beside the movement the two uncertainties alone would
//! explain there (`J (S_a + S_b) J^T`, the propagation of [`crate::analysis::uncertainty`] the
//! certificate uses). Geometry only: joint maps and compliance a file may carry are not compared.

use super::record::Record;
use crate::analysis::consistency::quantile;
use crate::analysis::workspace::WorkspaceMap;
use crate::io::robot_file::RobotFile;
use calib_core::{JointAngles, Kinematics, Parameter, ParameterMask, ParameterSet};
use nalgebra::{DMatrix, DVector, Dyn};
use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF as _};
use std::path::PathBuf;

/// The two-sided 95 % point of the standard normal distribution.
pub const Z_95: f64 = 1.959_963_984_540_054;

/// Configurations the tool's movement is computed at when not told.
pub const DEFAULT_POSES: usize = 1000;

/// An eigenvalue of the summed covariance below this share of the largest is a direction
/// neither calibration determined: left out of the joint test.
const RANK_TOLERANCE: f64 = 1e-10;

/// One side of a comparison.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Side {
    /// The record's number.
    pub id: i64,
    /// The robot's serial number.
    pub serial: String,
    /// The robot's model.
    pub model: String,
    /// When it was calibrated (RFC 3339; empty when the report did not say).
    pub calibrated_at: String,
}

/// One parameter's change.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Change {
    /// The parameter (`da2`, `dtheta3`, `base_x`, ...).
    pub parameter: String,
    /// The unit of the values: `mm` or `deg`.
    pub unit: &'static str,
    /// Its identified error in calibration `a` (0: not identified there, the nominal value).
    pub a: f64,
    /// In calibration `b`.
    pub b: f64,
    /// `b - a`.
    pub change: f64,
    /// The standard deviation of the change from both calibrations' uncertainty; `None` when a
    /// calibration identified it without stating its uncertainty.
    pub sd: Option<f64>,
    /// `change / sd`.
    pub z: Option<f64>,
    /// `|z| > Z_95`.
    pub significant: Option<bool>,
}

/// The changes judged jointly.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JointTest {
    /// The degrees of freedom: the rank of the summed covariance.
    pub degrees_of_freedom: usize,
    /// The squared Mahalanobis distance of the changes.
    pub mahalanobis_squared: f64,
    /// The chi-square distribution's 95 % point for these degrees of freedom.
    pub chi_square_95: f64,
    /// The probability of a distance at least this large when nothing changed.
    pub p_value: f64,
    /// `mahalanobis_squared > chi_square_95`.
    pub significant: bool,
}

/// What the change moves the tool by.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Movement {
    /// Configurations it was computed at.
    pub poses: usize,
    /// Mean distance between the two models' tool points, mm.
    pub mean_mm: f64,
    /// Its 95th percentile, mm.
    pub p95_mm: f64,
    /// Its largest, mm.
    pub max_mm: f64,
    /// The configuration of the largest, deg.
    pub max_pose_deg: Vec<f64>,
    /// The mean over the configurations of the RMS movement the two calibrations'
    /// uncertainties alone predict, mm (`None` without both covariances).
    pub uncertainty_rms_mm: Option<f64>,
    /// The share of configurations where the movement lies beyond its predicted 95 % band.
    pub beyond_band: Option<f64>,
    /// Where in the workspace (calibration `a`'s tool point in the base frame; a region's
    /// "error" is the movement, its "line" the configuration's number).
    pub map: WorkspaceMap,
}

/// Two calibrations compared.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Comparison {
    /// The first.
    pub a: Side,
    /// The second.
    pub b: Side,
    /// One robot (the same serial), or two of one model (exchangeability).
    pub same_robot: bool,
    /// Every parameter either identified.
    pub parameters: Vec<Change>,
    /// The changes judged together; `None` without both covariances.
    pub joint_test: Option<JointTest>,
    /// The tool's movement over the workspace.
    pub movement: Movement,
}

/// One side's identified file with what the comparison needs of it.
struct Identified {
    side: Side,
    file: RobotFile,
    path: PathBuf,
    errors: calib_core::ParameterErrors<f64, Dyn>,
    listed: Vec<Parameter>,
    covariance: Option<(Vec<Parameter>, DMatrix<f64>)>,
}

impl Identified {
    fn of(record: &Record) -> crate::Result<Self> {
        let c = &record.calibration;
        let (file, path) = record.identified_file().ok_or_else(|| {
            crate::refused!(input format!("record {}", record.id);
                "record {} keeps no identified robot file: register the calibration again with --identified FILE (the robot file calib calibrate or calib sockets wrote with --out)", record.id)
        })??;
        let errors = file.calibration_errors(&path)?;
        let joints = file.joint.len();
        let listed = (file.calibration.as_ref().into_iter())
            .flat_map(|s| s.errors.keys())
            .filter_map(|name| Parameter::from_name(name, joints))
            .collect();
        let covariance = match file
            .calibration
            .as_ref()
            .and_then(|s| s.covariance.as_ref())
        {
            Some(_) => {
                let (set, matrix) =
                    crate::analysis::uncertainty::recorded_covariance(&file, &path)?;
                Some((set.parameters().to_vec(), matrix))
            }
            None => None,
        };
        Ok(Self {
            side: Side {
                id: record.id,
                serial: c.serial.clone(),
                model: c.model.clone(),
                calibrated_at: c.calibrated_at.clone(),
            },
            file,
            path,
            errors,
            listed,
            covariance,
        })
    }

    /// The variance of `p`: from the covariance, else the stated standard error; 0 for a
    /// parameter not identified (held at its nominal value); `None` when identified without
    /// an uncertainty.
    fn variance(&self, p: Parameter) -> Option<f64> {
        if let Some((names, matrix)) = &self.covariance
            && let Some(i) = names.iter().position(|n| *n == p)
        {
            return Some(matrix[(i, i)]);
        }
        if !self.listed.contains(&p) {
            return Some(0.0);
        }
        let stated = self
            .file
            .calibration
            .as_ref()?
            .std_errors
            .get(&p.to_string())?;
        stated
            .as_float()
            .or_else(|| stated.as_integer().map(|i| i as f64))
            .map(|s| s * s)
    }

    /// Its covariance over `order` (zero rows and columns for parameters it does not cover).
    fn covariance_over(&self, order: &[Parameter]) -> Option<DMatrix<f64>> {
        let (names, matrix) = self.covariance.as_ref()?;
        let index: Vec<Option<usize>> = (order.iter())
            .map(|p| names.iter().position(|n| n == p))
            .collect();
        Some(DMatrix::from_fn(order.len(), order.len(), |i, j| {
            match (index[i], index[j]) {
                (Some(a), Some(b)) => matrix[(a, b)],
                _ => 0.0,
            }
        }))
    }

    /// The controller's model: the identified geometry with the controller's base and tool.
    fn kinematics(&self) -> crate::Result<Kinematics<f64, Dyn>> {
        let model = self.file.to_model(&self.path)?;
        Ok(Kinematics::nominal(&model.robot)?)
    }
}

/// Compares calibration `b` with calibration `a` at `poses` configurations. Refused: a record
/// without its identified file, robots of different models or joint counts, or identified
/// against different nominal geometry.
pub fn compare(a: &Record, b: &Record, poses: usize) -> crate::Result<Comparison> {
    let (a, b) = (Identified::of(a)?, Identified::of(b)?);
    check_comparable(&a, &b)?;
    let joints = a.file.joint.len();
    let mut mask = ParameterMask::empty_for(crate::model::counts::joint_count(joints)?);
    for p in a.listed.iter().chain(&b.listed) {
        mask.set(*p, true);
    }
    let set = ParameterSet::<Dyn, Dyn>::from_mask(&mask)?;
    let order = set.parameters().to_vec();
    let parameters = order.iter().map(|p| change(&a, &b, *p)).collect();
    let summed = match (a.covariance_over(&order), b.covariance_over(&order)) {
        (Some(sa), Some(sb)) => Some(sa + sb),
        _ => None,
    };
    let d = DVector::from_iterator(
        order.len(),
        (order.iter()).map(|p| b.errors.get(*p).unwrap_or(0.0) - a.errors.get(*p).unwrap_or(0.0)),
    );
    let joint_test = summed.as_ref().map(|s| joint_test(s, &d)).transpose()?;
    let movement = movement(&a, &b, &set, summed.as_ref(), poses)?;
    Ok(Comparison {
        same_robot: a.side.serial == b.side.serial,
        a: a.side,
        b: b.side,
        parameters,
        joint_test,
        movement,
    })
}

/// Refuses calibrations of different robots or nominal models.
fn check_comparable(a: &Identified, b: &Identified) -> crate::Result<()> {
    let (ja, jb) = (a.file.joint.len(), b.file.joint.len());
    let refused = |why: String| {
        crate::refused!(input format!("records {} and {}", a.side.id, b.side.id);
            "records {} and {}: {why}; compare calibrations of one robot, or of two robots of one model", a.side.id, b.side.id)
    };
    if ja != jb {
        return Err(refused(format!("a {ja}-joint and a {jb}-joint robot")));
    }
    if a.side.model != b.side.model {
        return Err(refused(format!(
            "a {} and a {}",
            a.side.model, b.side.model
        )));
    }
    // The nominal geometry is each file's value less its identified error.
    for (j, (ea, eb)) in a.file.joint.iter().zip(&b.file.joint).enumerate() {
        let (na, nb) = (nominal(a, j, ea), nominal(b, j, eb));
        if let Some(k) = (0..5).find(|&k| (na[k] - nb[k]).abs() > 1e-6) {
            return Err(refused(format!(
                "identified against different nominal geometry (joint {}, {} {} against {})",
                j + 1,
                ["a mm", "alpha deg", "theta offset deg", "d mm", "beta deg"][k],
                na[k],
                nb[k]
            )));
        }
    }
    Ok(())
}

/// Joint `j`'s nominal `[a mm, alpha deg, theta offset deg, d mm, beta deg]`.
fn nominal(side: &Identified, j: usize, entry: &crate::io::robot_file::JointEntry) -> [f64; 5] {
    let e = side.errors.joints.get(j).copied().unwrap_or_default();
    [
        entry.a_mm - e.da,
        entry.alpha_deg - e.dalpha.to_degrees(),
        entry.theta_offset_deg - e.dtheta.to_degrees(),
        entry.d_mm - e.dd,
        entry.beta_deg - e.dbeta.to_degrees(),
    ]
}

/// One parameter's change with its significance.
fn change(a: &Identified, b: &Identified, p: Parameter) -> Change {
    let scale = if p.is_angle() {
        180.0 / std::f64::consts::PI
    } else {
        1.0
    };
    let (va, vb) = (
        a.errors.get(p).unwrap_or(0.0) * scale,
        b.errors.get(p).unwrap_or(0.0) * scale,
    );
    let sd = match (a.variance(p), b.variance(p)) {
        (Some(x), Some(y)) => Some((x + y).max(0.0).sqrt() * scale),
        _ => None,
    };
    let z = sd.filter(|s| *s > 0.0).map(|s| (vb - va) / s);
    Change {
        parameter: p.to_string(),
        unit: if p.is_angle() { "deg" } else { "mm" },
        a: va,
        b: vb,
        change: vb - va,
        sd,
        z,
        significant: z.map(|z| z.abs() > Z_95),
    }
}

/// The Mahalanobis test of the changes `d` against the summed covariance `s`.
fn joint_test(s: &DMatrix<f64>, d: &DVector<f64>) -> crate::Result<JointTest> {
    let eigen = s.clone().symmetric_eigen();
    let largest = eigen.eigenvalues.iter().copied().fold(0.0, f64::max);
    let mut distance = 0.0;
    let mut rank = 0;
    for (i, lambda) in eigen.eigenvalues.iter().enumerate() {
        if *lambda > RANK_TOLERANCE * largest && *lambda > 0.0 {
            distance += eigen.eigenvectors.column(i).dot(d).powi(2) / lambda;
            rank += 1;
        }
    }
    if rank == 0 {
        return Err(crate::numerical!(
            "the two calibrations' covariances sum to zero: nothing to judge the changes by"
        ));
    }
    let chi = ChiSquared::new(rank as f64)
        .map_err(|e| crate::numerical!("chi-square of {rank} degrees of freedom: {e}"))?;
    let chi_square_95 = chi.inverse_cdf(0.95);
    Ok(JointTest {
        degrees_of_freedom: rank,
        mahalanobis_squared: distance,
        chi_square_95,
        p_value: chi.sf(distance),
        significant: distance > chi_square_95,
    })
}

/// The tool's movement from `a`'s model to `b`'s over `count` configurations.
fn movement(
    a: &Identified,
    b: &Identified,
    set: &ParameterSet<Dyn, Dyn>,
    summed: Option<&DMatrix<f64>>,
    count: usize,
) -> crate::Result<Movement> {
    if count == 0 {
        return Err(crate::refused!(option "--poses"; "--poses 0: give at least 1 configuration"));
    }
    let configurations = crate::planning::generate(&a.file, &a.path, count, None)?;
    let (ka, kb) = (a.kinematics()?, b.kinematics()?);
    let (mut positions, mut moved, mut predicted, mut beyond) = (vec![], vec![], vec![], 0);
    for (_, q) in &configurations {
        let q = calib_core::model::JointVec::from_slice(q).ok_or_else(
            || crate::refused!(unsupported "more than 9 joints"; "more than 9 joints"),
        )?;
        let (pa, pb) = (ka.forward(&q)?, kb.forward(&q)?);
        let d = pb.translation.vector - pa.translation.vector;
        positions.push([0, 1, 2].map(|i| pa.translation.vector[i]));
        moved.push(d.norm());
        if let Some(s) = summed {
            let (position, _) =
                crate::analysis::uncertainty::pose_covariance(&ka, set, s, &JointAngles::new(&q)?);
            predicted.push(position.trace().max(0.0).sqrt());
            let band = position
                .try_inverse()
                .map(|inverse| (d.transpose() * inverse * d)[0]);
            if band.is_none_or(|m| m > crate::analysis::uncertainty::CHI_SQUARE_3_95) {
                beyond += 1;
            }
        }
    }
    let n = moved.len();
    let (max_at, max_mm) = (moved.iter().copied().enumerate())
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .unwrap_or((0, 0.0));
    let lines: Vec<u64> = (1..=n as u64).collect();
    let have = !predicted.is_empty();
    let map = WorkspaceMap::of(&positions, &moved, &lines, have.then_some(&predicted[..]))
        .ok_or_else(|| crate::numerical!("the workspace map of {n} configurations"))?;
    Ok(Movement {
        poses: n,
        mean_mm: moved.iter().sum::<f64>() / n as f64,
        p95_mm: quantile(&moved, 0.95),
        max_mm,
        max_pose_deg: (configurations[max_at].1.iter())
            .map(|q| q.to_degrees())
            .collect(),
        uncertainty_rms_mm: have.then(|| predicted.iter().sum::<f64>() / n as f64),
        beyond_band: have.then(|| beyond as f64 / n as f64),
        map,
    })
}

impl Comparison {
    /// The comparison for people.
    pub fn text(&self) -> String {
        let side = |s: &Side| {
            format!(
                "record {} (robot {}, {}, calibrated {})",
                s.id,
                s.serial,
                s.model,
                if s.calibrated_at.is_empty() {
                    "at an unknown date"
                } else {
                    &s.calibrated_at
                }
            )
        };
        let mut text = format!(
            "{} against {}: {}\n",
            side(&self.b),
            side(&self.a),
            if self.same_robot {
                "two calibrations of one robot"
            } else {
                "two robots of one model (ISO 9283 exchangeability)"
            }
        );
        text.push_str(&self.parameters_text());
        text.push_str(&self.movement.text());
        text
    }

    /// The parameters' table, the count of changes and the joint test.
    fn parameters_text(&self) -> String {
        let mut text = format!(
            "{:<10} {:>12} {:>12} {:>12} {:>10} {:>7}  unit\n",
            "parameter", "a", "b", "b - a", "sd", "z"
        );
        for c in &self.parameters {
            let optional = |v: Option<f64>, digits: usize| {
                v.map_or("-".to_string(), |v| format!("{v:.digits$}"))
            };
            let digits = if c.unit == "deg" { 5 } else { 4 };
            text.push_str(&format!(
                "{:<10} {:>12.digits$} {:>12.digits$} {:>12.digits$} {:>10} {:>7}  {}{}\n",
                c.parameter,
                c.a,
                c.b,
                c.change,
                optional(c.sd, digits),
                optional(c.z, 2),
                c.unit,
                if c.significant == Some(true) {
                    "  changed (|z| > 1.96)"
                } else {
                    ""
                }
            ));
        }
        let significant = (self.parameters.iter())
            .filter(|c| c.significant == Some(true))
            .count();
        text.push_str(&format!(
            "{significant} of {} parameters changed beyond their uncertainty (95 %, each alone)\n",
            self.parameters.len()
        ));
        text.push_str(&match &self.joint_test {
            Some(t) => format!(
                "jointly: Mahalanobis distance squared {:.2} on {} degrees of freedom (95 % point {:.2}, p = {:.3e}): {}\n",
                t.mahalanobis_squared,
                t.degrees_of_freedom,
                t.chi_square_95,
                t.p_value,
                if t.significant { "CHANGED beyond both calibrations' uncertainty" } else { "no change shown beyond both calibrations' uncertainty" }
            ),
            None => "jointly: not judged (a calibration records standard errors only, no covariance)\n".to_string(),
        });
        text
    }
}

impl Movement {
    /// The movement for people.
    fn text(&self) -> String {
        let m = self;
        let mut text = format!(
            "the tool moves by {:.4} mm on average, {:.4} mm at 95 %, {:.4} mm at most (at {} deg) over {} configurations spread over the joint limits\n",
            m.mean_mm,
            m.p95_mm,
            m.max_mm,
            (m.max_pose_deg.iter())
                .map(|q| format!("{q:.1}"))
                .collect::<Vec<_>>()
                .join(", "),
            m.poses
        );
        if let (Some(rms), Some(beyond)) = (m.uncertainty_rms_mm, m.beyond_band) {
            text.push_str(&format!(
                "the two calibrations' uncertainty alone would move it by {rms:.4} mm RMS on average; the movement lies beyond its 95 % band at {:.1} % of the configurations\n",
                100.0 * beyond
            ));
        }
        if let Some(worst) = m.map.worst.first() {
            text.push_str(&format!(
                "largest mean movement in the region {} ({} configurations): {:.4} mm\n",
                worst.bounds_text(),
                worst.poses,
                worst.mean_mm
            ));
        }
        text
    }
}
