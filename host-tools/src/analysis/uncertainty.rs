//! The uncertainty of an identified model's prediction at any pose, propagated from the
//! identified parameters' covariance: the position's covariance at joint readings `q` is
//! `J(q) S J(q)^T` (mm^2), `J` the 3 position rows of the parameter Jacobian at the identified
//! errors and `S` the covariance least squares leaves (`sigma^2 (J^T J)^-1`, mm and rad), and the
//! orientation's likewise from the 3 rotation rows. A measured pose adds the instrument's noise,
//! `sigma^2 I` per coordinate: the prediction's error `e = measured - predicted` then has the
//! covariance `C = J S J^T + sigma^2 I`, and lies inside the predicted 95 % band when
//! `e^T C^-1 e <= 7.815` (the 95 % point of the chi-square distribution with 3 degrees of freedom).
//!
//! On held-out poses the share inside that band says whether the model's stated uncertainty can be
//! trusted: about 95 % for a model that describes the robot (checked by simulation with known
//! noise), less where errors the model does not have (joint-dependent, thermal) remain.

use calib_core::{JointAngles, Kinematics, ParameterSet};
use nalgebra::{DMatrix, Dyn, Matrix3, Vector3};
use serde::Serialize;

/// The 95 % point of the chi-square distribution with 3 degrees of freedom.
pub(crate) const CHI_SQUARE_3_95: f64 = 7.814_727_903_251_178;

/// The covariance of the position (mm^2) and of the orientation (rad^2) at one pose from the
/// parameters' covariance `covariance` (in the order of `set`), for the model `kinematics`.
pub(crate) fn pose_covariance(
    kinematics: &Kinematics<f64, Dyn>,
    set: &ParameterSet<Dyn, Dyn>,
    covariance: &DMatrix<f64>,
    angles: &JointAngles<f64, Dyn>,
) -> (Matrix3<f64>, Matrix3<f64>) {
    let (_, jacobian) = kinematics.parameter_jacobian(set, angles);
    let full = &jacobian * covariance * jacobian.transpose();
    (
        full.fixed_view::<3, 3>(0, 0).into_owned(),
        full.fixed_view::<3, 3>(3, 3).into_owned(),
    )
}

/// A pose's predicted standard deviations, from the parameters alone (without the instrument).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct PoseSd {
    /// Of the position along x, y and z of the measurement frame, mm.
    pub position_mm: [f64; 3],
    /// Of the position's length, `sqrt(trace)`: the RMS of the position error, mm.
    pub position_rms_mm: f64,
    /// Of the orientation about x, y and z, deg.
    pub orientation_deg: [f64; 3],
}

impl PoseSd {
    /// The standard deviations of the covariances `(position, orientation)`.
    pub fn of((position, orientation): &(Matrix3<f64>, Matrix3<f64>)) -> Self {
        Self {
            position_mm: [0, 1, 2].map(|i| position[(i, i)].max(0.0).sqrt()),
            position_rms_mm: position.trace().max(0.0).sqrt(),
            orientation_deg: [0, 1, 2].map(|i| orientation[(i, i)].max(0.0).sqrt().to_degrees()),
        }
    }
}

/// The held-out poses against their predicted 95 % band.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Coverage {
    /// Held-out poses.
    pub poses: usize,
    /// The instrument's noise assumed per coordinate (1 sigma), mm: the mean over the poses.
    pub noise_mm: f64,
    /// Where it came from: the instrument the data profile states, or the fit's residual sigma.
    pub noise_source: String,
    /// Poses whose error lies inside the predicted 95 % band.
    pub inside_95: usize,
    /// Their share, %.
    pub percent_inside_95: f64,
    /// Mean over the poses of the predicted RMS position error from the parameters alone, mm.
    pub mean_model_rms_mm: f64,
    /// Largest of it, mm.
    pub max_model_rms_mm: f64,
    /// The pose of that largest predicted error: its data file's line.
    pub max_model_rms_line: u64,
    /// What the band is made of: the noise's share of its variance (`3 sigma^2` against the
    /// parameters' `trace(J S J^T)`), mean over the poses, %. Near 100 the band holds through
    /// the noise term, and says little about the model's own uncertainty.
    pub noise_share_percent: f64,
    /// How well the parameters' per-pose prediction ranks the poses: Spearman's rank correlation
    /// of the predicted RMS error with the measured error (1: the largest predicted are the
    /// largest measured; near 0: no ranking). `None` for fewer than 3 poses.
    pub rank_correlation: Option<f64>,
    /// The predicted RMS position error from the parameters alone of every pose, in order, mm
    /// (in the JSON report as `per_pose.validation_predicted_rms_mm`).
    #[serde(skip)]
    pub model_rms_mm: Vec<f64>,
    /// The signed position error of every pose, in order, mm (for the uncertainty budget).
    #[serde(skip)]
    pub errors_mm: Vec<[f64; 3]>,
    /// Every pose's distance from the robot's base, in order, mm (for the budget's temperature).
    #[serde(skip)]
    pub reach_mm: Vec<f64>,
    /// The instrument's noise per coordinate over the poses (RMS), mm, and the instrument in
    /// words; `None` when the data profile states no instrument.
    #[serde(skip)]
    pub instrument: Option<(f64, String)>,
}

/// One held-out pose for [`coverage`]: its joint angles, its position error `measured -
/// predicted` (mm, measurement frame), its data file's line, and the instrument's noise there
/// (1 sigma per coordinate, mm).
pub(crate) type HeldOutPose = (JointAngles<f64, Dyn>, Vector3<f64>, u64, f64);

/// The held-out `poses` against the band of `kinematics` (the identified model) with the
/// parameters' covariance `covariance` (in the order of `set`) and each pose's noise; `noise_source`
/// says where the noise came from.
pub(crate) fn coverage(
    (kinematics, set, covariance): (
        &Kinematics<f64, Dyn>,
        &ParameterSet<Dyn, Dyn>,
        &DMatrix<f64>,
    ),
    poses: &[HeldOutPose],
    noise_source: String,
) -> Option<Coverage> {
    if poses.is_empty() {
        return None;
    }
    let mut inside = 0;
    let (mut sum, mut max, mut max_line, mut noise_sum) = (0.0, 0.0, 0, 0.0);
    let mut model_rms_mm = Vec::with_capacity(poses.len());
    let (mut measured, mut noise_share) = (Vec::with_capacity(poses.len()), 0.0);
    for (angles, error, line, noise_mm) in poses {
        noise_sum += *noise_mm;
        measured.push(error.norm());
        let (position, _) = pose_covariance(kinematics, set, covariance, angles);
        let rms = position.trace().max(0.0).sqrt();
        model_rms_mm.push(rms);
        sum += rms;
        if rms > max {
            (max, max_line) = (rms, *line);
        }
        let noise_variance = 3.0 * noise_mm * noise_mm;
        noise_share += noise_variance / (position.trace().max(0.0) + noise_variance).max(1e-300);
        let band = position + Matrix3::identity() * (noise_mm * noise_mm);
        let inside_band = band
            .cholesky()
            .map(|c| error.dot(&c.solve(error)) <= CHI_SQUARE_3_95);
        if inside_band == Some(true) {
            inside += 1;
        }
    }
    Some(Coverage {
        poses: poses.len(),
        noise_mm: noise_sum / poses.len() as f64,
        noise_source,
        inside_95: inside,
        percent_inside_95: 100.0 * inside as f64 / poses.len() as f64,
        mean_model_rms_mm: sum / poses.len() as f64,
        max_model_rms_mm: max,
        max_model_rms_line: max_line,
        noise_share_percent: 100.0 * noise_share / poses.len() as f64,
        rank_correlation: spearman(&model_rms_mm, &measured),
        model_rms_mm,
        errors_mm: poses.iter().map(|p| [p.1.x, p.1.y, p.1.z]).collect(),
        reach_mm: Vec::new(),
        instrument: None,
    })
}

/// Spearman's rank correlation of `a` and `b` (the Pearson correlation of their ranks, ties
/// given their mean rank); `None` for fewer than 3 pairs, unequal lengths or a constant side.
pub(crate) fn spearman(a: &[f64], b: &[f64]) -> Option<f64> {
    if a.len() != b.len() || a.len() < 3 {
        return None;
    }
    let ranks = |v: &[f64]| {
        let mut order: Vec<usize> = (0..v.len()).collect();
        order.sort_by(|i, j| v[*i].total_cmp(&v[*j]));
        let mut rank = vec![0.0; v.len()];
        let mut start = 0;
        while start < order.len() {
            let mut end = start + 1;
            while end < order.len() && v[order[end]] == v[order[start]] {
                end += 1;
            }
            // Ranks start + 1 ..= end share their mean.
            let mean = (start + 1 + end) as f64 / 2.0;
            for k in &order[start..end] {
                rank[*k] = mean;
            }
            start = end;
        }
        rank
    };
    let (ra, rb) = (ranks(a), ranks(b));
    let n = a.len() as f64;
    let (ma, mb) = (ra.iter().sum::<f64>() / n, rb.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    (saa > 0.0 && sbb > 0.0).then(|| sab / (saa * sbb).sqrt())
}

impl Coverage {
    /// The line for people.
    pub fn text(&self) -> String {
        format!(
            "predicted uncertainty (parameters' covariance, and {:.4} mm of noise per coordinate, {}): the held-out \
             errors lie inside their predicted 95 % band for {:.1} % of {} poses; the parameters alone predict {:.4} mm \
             RMS on average, at most {:.4} mm (line {}); {}\n",
            self.noise_mm,
            self.noise_source,
            self.percent_inside_95,
            self.poses,
            self.mean_model_rms_mm,
            self.max_model_rms_mm,
            self.max_model_rms_line,
            self.makeup()
        )
    }

    /// What the band is made of and how well the per-pose prediction ranks the poses, in words.
    pub fn makeup(&self) -> String {
        format!(
            "the band is {:.1} % noise and {:.1} % parameters (variance, mean over the poses){}; the per-pose prediction ranks \
             the measured errors with Spearman correlation {} (1: largest predicted = largest measured; 0: no ranking)",
            self.noise_share_percent,
            100.0 - self.noise_share_percent,
            if self.noise_share_percent > 80.0 {
                ": it holds through the noise term, not through the model's own uncertainty"
            } else {
                ""
            },
            self.rank_correlation.map_or_else(
                || "not computed (fewer than 3 poses)".to_string(),
                |r| format!("{r:.2}")
            )
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Spearman's correlation against closed forms: 1 for any increasing relation, -1 for a
    /// decreasing one, and for ranks (1, 2, 3, 4, 5) against (2, 1, 4, 3, 5), with
    /// `sum d^2 = 4`, `1 - 6 * 4 / (5 * 24) = 0.8`; ties take their mean rank.
    #[test]
    fn spearman_matches_closed_forms() {
        let a = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert!((spearman(&a, &a.map(|x: f64| x.exp())).unwrap() - 1.0).abs() < 1e-12);
        assert!((spearman(&a, &a.map(|x| -x * x)).unwrap() + 1.0).abs() < 1e-12);
        let swapped = [2.0, 1.0, 4.0, 3.0, 5.0];
        assert!((spearman(&a, &swapped).unwrap() - 0.8).abs() < 1e-12);
        // Ties: ranks (1.5, 1.5, 3) against (1, 2, 3): Pearson of those, sqrt(3)/2.
        let r = spearman(&[1.0, 1.0, 2.0], &[1.0, 2.0, 3.0]).unwrap();
        assert!((r - 3f64.sqrt() / 2.0).abs() < 1e-12, "{r}");
        assert_eq!(spearman(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]), None);
        assert_eq!(spearman(&[1.0, 2.0], &[1.0, 2.0]), None);
    }

    /// A closed form: one identified parameter, a translation of the base along x with variance
    /// 4 mm^2, moves every pose's position along x by itself, so the position's covariance is
    /// diag(4, 0, 0) at any pose and the orientation's is zero.
    #[test]
    fn a_base_translation_propagates_to_every_pose_unchanged() {
        use calib_core::{FrameParameter, Parameter, ParameterMask};
        let text =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml"))
                .unwrap();
        let file =
            crate::io::robot_file::RobotFile::parse(&text, std::path::Path::new("ur10.toml"))
                .unwrap();
        let model = file.to_model(std::path::Path::new("ur10.toml")).unwrap();
        let mut mask = ParameterMask::empty_for(model.robot.joint_count());
        mask.set(Parameter::Base(FrameParameter::Tx), true);
        let set = ParameterSet::<Dyn, Dyn>::from_mask(&mask).unwrap();
        let kinematics = Kinematics::nominal(&model.robot).unwrap();
        let covariance = DMatrix::from_element(1, 1, 4.0);
        for q in [
            [0.1, -1.0, 1.2, -0.3, 0.5, 0.2],
            [1.0, -2.0, 0.4, 1.3, -0.5, 2.0],
        ] {
            let q = calib_core::model::JointVec::from_slice(&q).unwrap();
            let angles = JointAngles::new(&q).unwrap();
            let sd = PoseSd::of(&pose_covariance(&kinematics, &set, &covariance, &angles));
            assert!((sd.position_mm[0] - 2.0).abs() < 1e-12, "{sd:?}");
            assert!(sd.position_mm[1].abs() < 1e-12 && sd.position_mm[2].abs() < 1e-12);
            assert!(sd.orientation_deg.iter().all(|v| v.abs() < 1e-12));
        }
    }

    /// Significance and correlation of a hand-made covariance: sd 1 and 2, correlation 0.95.
    #[test]
    fn parameters_within_two_standard_errors_and_correlated_pairs_are_named() {
        let names = ["da1".to_string(), "dd2".to_string(), "da3".to_string()];
        let covariance =
            DMatrix::from_row_slice(3, 3, &[1.0, 1.9, 0.0, 1.9, 4.0, 0.0, 0.0, 0.0, 1.0]);
        let s = Significance::of(&names, &[1.5, 5.0, -3.0], &covariance);
        assert_eq!(s.not_significant, ["da1"]);
        assert_eq!(s.correlated.len(), 1);
        let (a, b, rho) = &s.correlated[0];
        assert_eq!((a.as_str(), b.as_str()), ("da1", "dd2"));
        assert!((rho - 0.95).abs() < 1e-12);
    }
}

/// Correlation beyond which a pair of identified parameters is named: the data hardly tell them
/// apart, and their values trade off against each other.
pub(crate) const STRONG_CORRELATION: f64 = 0.9;

/// The identified parameters read against their covariance: which joint parameters are smaller
/// than twice their standard error (not significant at about 95 %: the data do not show the
/// robot to differ from its drawing there; the frames' parameters are errors of frames fitted to
/// these very data, near zero by construction, and are not judged) and which pairs are strongly
/// correlated.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct Significance {
    /// Joint parameters with `|value| < 2 standard errors`, in canonical order.
    pub not_significant: Vec<String>,
    /// Pairs with `|correlation| > 0.9`: `(first, second, correlation)`, strongest first.
    pub correlated: Vec<(String, String, f64)>,
}

impl Significance {
    /// Of the parameters `names` with values `values` (in the order of the covariance's rows).
    pub fn of(names: &[String], values: &[f64], covariance: &DMatrix<f64>) -> Self {
        let sd: Vec<f64> = (0..names.len())
            .map(|i| covariance[(i, i)].max(0.0).sqrt())
            .collect();
        let not_significant = (names.iter().zip(values).zip(&sd))
            .filter(|((n, v), s)| {
                !(n.starts_with("base_") || n.starts_with("tool_")) && v.abs() < 2.0 * **s
            })
            .map(|((n, _), _)| n.clone())
            .collect();
        let mut correlated = Vec::new();
        for i in 0..names.len() {
            for j in i + 1..names.len() {
                let rho = covariance[(i, j)] / (sd[i] * sd[j]);
                if rho.abs() > STRONG_CORRELATION {
                    correlated.push((names[i].clone(), names[j].clone(), rho));
                }
            }
        }
        correlated.sort_by(|a, b| b.2.abs().total_cmp(&a.2.abs()));
        Self {
            not_significant,
            correlated,
        }
    }

    /// The lines for people (nothing when nothing is named).
    pub fn text(&self) -> String {
        let mut text = String::new();
        if !self.not_significant.is_empty() {
            text.push_str(&format!(
                "  smaller than twice their standard error (not shown to differ from zero): {}\n",
                self.not_significant.join(", ")
            ));
        }
        if !self.correlated.is_empty() {
            let pairs: Vec<String> = (self.correlated.iter())
                .map(|(a, b, rho)| format!("{a}/{b} {rho:+.3}"))
                .collect();
            text.push_str(&format!(
                "  strongly correlated pairs (|correlation| > {STRONG_CORRELATION}): {}\n",
                pairs.join(", ")
            ));
        }
        text
    }
}
/// The largest standard deviation of a length parameter a recorded covariance may state, mm: a
/// calibration that cannot tell a link length within a metre has identified nothing.
const MAX_SD_MM: f64 = 1000.0;

/// The largest standard deviation of an angle parameter a recorded covariance may state, rad.
const MAX_SD_RAD: f64 = std::f64::consts::PI;

/// The parameters' covariance a robot file records (`[calibration.covariance]`), checked: every
/// name a parameter of the robot, in canonical order, the matrix square, finite and symmetric,
/// its diagonal not negative and no standard deviation beyond [`MAX_SD_MM`] or [`MAX_SD_RAD`]. Returns the parameter set (in the file's order) and the matrix.
pub(crate) fn recorded_covariance(
    file: &crate::io::robot_file::RobotFile,
    path: &std::path::Path,
) -> crate::Result<(ParameterSet<Dyn, Dyn>, DMatrix<f64>)> {
    let entry = (file.calibration.as_ref())
        .and_then(|c| c.covariance.as_ref())
        .ok_or_else(|| {
            crate::refused!(input path.display();
                "{}: has no [calibration.covariance]: give a robot file identified by calib calibrate with least squares \
                 (--method lm or ipso+lm) on the geometry",
                path.display()
            )
        })?;
    let joints = file.joint.len();
    let n = entry.parameters.len();
    let bad = |why: String| crate::refused!(input path.display(); "{}: [calibration.covariance]: {why}", path.display());
    let mut mask = calib_core::ParameterMask::empty_for(
        calib_core::model::joint_count(joints).ok_or_else(|| bad(format!("{joints} joints")))?,
    );
    let mut order = Vec::with_capacity(n);
    for name in &entry.parameters {
        let p = calib_core::Parameter::from_name(name, joints).ok_or_else(|| {
            bad(format!(
                "\"{name}\" is not a parameter of this {joints}-joint robot"
            ))
        })?;
        mask.set(p, true);
        order.push(p);
    }
    let set = ParameterSet::<Dyn, Dyn>::from_mask(&mask)?;
    if set.parameters() != order.as_slice() {
        return Err(bad(
            "the parameters are not in canonical order (as calib calibrate writes them), or repeat"
                .into(),
        ));
    }
    if entry.matrix.len() != n || entry.matrix.iter().any(|r| r.len() != n) {
        return Err(bad(format!("the matrix is not {n} x {n}")));
    }
    let matrix = DMatrix::from_fn(n, n, |i, j| entry.matrix[i][j]);
    for i in 0..n {
        if !(matrix[(i, i)].is_finite() && matrix[(i, i)] >= 0.0) {
            return Err(bad(format!(
                "the variance of {} is {}",
                entry.parameters[i],
                matrix[(i, i)]
            )));
        }
        let (limit, unit) = if order[i].is_angle() {
            (MAX_SD_RAD, "rad")
        } else {
            (MAX_SD_MM, "mm")
        };
        if matrix[(i, i)].sqrt() > limit {
            return Err(bad(format!(
                "the standard deviation of {} is {:e} {unit}, beyond any calibration's (at most {limit} {unit}): the file is damaged, or not a calibration's",
                entry.parameters[i],
                matrix[(i, i)].sqrt()
            )));
        }
        for j in 0..i {
            let (a, b) = (matrix[(i, j)], matrix[(j, i)]);
            if !(a.is_finite()
                && (a - b).abs() <= 1e-9 * (matrix[(i, i)] * matrix[(j, j)]).sqrt() + 1e-300)
            {
                return Err(bad(format!(
                    "not symmetric: {} / {} is {a} one way and {b} the other",
                    entry.parameters[i], entry.parameters[j]
                )));
            }
        }
    }
    Ok((set, matrix))
}

/// The predicted standard deviations of the identified model's pose at each of `poses` (joint
/// readings, rad), from the parameters' covariance the identified file at `path` records, along
/// and about the robot's base axes. The model is the one the calibration identified: in its
/// measurement setup (the registered tracker and the probe, `[measurement]`), where the covariance
/// holds; the joint parameters are determined relative to that registration, so a rigid
/// placement of the whole robot, which no tracker data fix, is not part of it.
pub fn at_poses(
    file: &crate::io::robot_file::RobotFile,
    path: &std::path::Path,
    poses: &[Vec<f64>],
) -> crate::Result<Vec<PoseSd>> {
    let (set, covariance) = recorded_covariance(file, path)?;
    let model = file.in_measurement_setup().to_model(path)?;
    let kinematics = Kinematics::nominal(&model.robot)?;
    let [roll, pitch, yaw] = model.robot.base.rpy;
    let base = *nalgebra::Rotation3::from_euler_angles(roll, pitch, yaw).matrix();
    let along_base = |c: Matrix3<f64>| base.transpose() * c * base;
    poses
        .iter()
        .map(|q| {
            let q = calib_core::model::JointVec::from_slice(q).ok_or_else(
                || crate::refused!(unsupported "more than 9 joints"; "more than 9 joints"),
            )?;
            let angles = JointAngles::new(&q)?;
            let (position, orientation) = pose_covariance(&kinematics, &set, &covariance, &angles);
            Ok(PoseSd::of(&(along_base(position), along_base(orientation))))
        })
        .collect()
}
