//! The tracker and tool frames of real measurements: which frames are identified
//! (`--frames none|base|base+tool`), their start values by closed-form rigid registration, and
//! the parameters that become redundant once they are identified.
//!
//! A tracker measures `m_j = T_base * F(q_j) * t`: the tracker-to-robot-base transform `T_base`,
//! the nominal flange pose `F(q_j)`, and the tool point `t` (a reflector) or tool frame (a 6-DoF
//! probe) on the flange. Registration alternates two closed forms until they agree: with `t`
//! fixed, `T_base` is the rigid registration (Kabsch/Horn, by SVD) of the points `F(q_j) t` onto
//! the measured points; with `T_base` fixed, `t` is the linear least-squares solution of
//! `R_j t = R_base^T (m_j - p_base) - p_j`. For 6-DoF data the tool rotation is then the
//! rotation nearest to the mean of `(R_base R_j)^T R_measured,j`.

use crate::error::Context;
use crate::io::robot_file::{FrameEntry, RobotFile};
use crate::kinematics::actual::ActualRobot;
use crate::measurement::dataset::Seen;
use calib_core::identify::objective::Measurement;
use calib_core::{FrameParameter, JointParameter, Kinematics, Parameter, ParameterMask, Robot};
use nalgebra::Dyn;
use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::Serialize;

/// With only the base fitted (`frames` base), an identified file's probe or reflector
/// (`[measurement] flange_tool`, identified with the model) stays the tool: the same probe in a
/// new session needs only the tracker's position re-fitted. `robot` in its measurement setup
/// ([`ActualRobot::in_measurement_setup`]), or `None` when there is nothing to keep.
pub(crate) fn with_identified_probe(
    robot: &ActualRobot,
    frames: Frames,
) -> crate::Result<Option<ActualRobot>> {
    if frames != Frames::Base || robot.identified_probe().is_none() {
        return Ok(None);
    }
    robot.in_measurement_setup().map(Some)
}

/// Which frames a calibration identifies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, serde::Deserialize)]
pub enum Frames {
    /// None: the data are in the robot's base frame and the tool is known.
    #[value(name = "none")]
    #[serde(rename = "none")]
    None,
    /// The tracker-to-base frame (6 parameters); the tool is known.
    #[value(name = "base")]
    #[serde(rename = "base")]
    Base,
    /// The base frame and the tool: 3 translations for a reflector (position-only data), 6 for a
    /// 6-DoF probe.
    #[value(name = "base+tool")]
    #[serde(rename = "base+tool")]
    BaseTool,
}

impl Frames {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Base => "base",
            Self::BaseTool => "base+tool",
        }
    }

    /// The frames asked for, or the default for the data: `none` when the data say they are in
    /// the base frame (`# frame: base` or the data profile), `base+tool` otherwise.
    pub fn chosen(asked: Option<Self>, data: &crate::io::tracker_data::TrackerData) -> Self {
        asked.unwrap_or(if data.base_frame {
            Self::None
        } else {
            Self::BaseTool
        })
    }

    /// `true` when the base frame is identified.
    pub fn base(self) -> bool {
        self != Self::None
    }

    /// `true` when the tool is identified.
    pub fn tool(self) -> bool {
        self == Self::BaseTool
    }
}

/// Start values of the frames from the nominal model, and how well they explain the data.
#[derive(Clone, Debug)]
pub(crate) struct Registration {
    /// Tracker-to-base rotation.
    pub base_rotation: Rotation3<f64>,
    /// Tracker-to-base translation, mm.
    pub base_translation: Vector3<f64>,
    /// Tool point on the flange, mm (flange frame).
    pub tool_translation: Vector3<f64>,
    /// Tool rotation relative to the flange (identity for position-only data).
    pub tool_rotation: Rotation3<f64>,
    /// RMS of the position residuals after registration, mm.
    pub rms_mm: f64,
    /// Largest position residual after registration, mm.
    pub max_mm: f64,
    /// Alternations run.
    pub iterations: u32,
}

/// Errors of the registration.
#[derive(Debug, thiserror::Error)]
pub enum RegistrationError {
    /// Fewer than 3 poses.
    #[error("{0} poses: registering the measurement frame needs at least 3")]
    TooFewPoses(usize),
    /// The measured points lie on one line (or on one point).
    #[error(
        "the {0} measured points lie on one line: registration needs poses whose tool points are not on one line"
    )]
    MeasuredOnALine(usize),
    /// The nominal model's tool points of the joint readings lie on one line.
    #[error(
        "the nominal model puts the tool points of the {0} joint readings on one line (the poses move too few joints, or the tool point lies on the axes they move): measure poses that move the tool point across a plane"
    )]
    ModelledOnALine(usize),
    /// The nominal robot cannot be evaluated.
    #[error("the nominal robot: {0}")]
    Model(#[from] calib_core::KinematicsError),
    /// The flange orientations do not determine the tool point.
    #[error(
        "the flange orientations of the poses are too similar to locate the tool on the flange; use poses with varied wrist orientations"
    )]
    ToolUndetermined,
}

/// Rigid registration (Kabsch/Horn): the rotation and translation with `b ~ R a + t` in the
/// least-squares sense, by SVD of the cross-covariance.
pub(crate) fn kabsch(
    a: &[Vector3<f64>],
    b: &[Vector3<f64>],
) -> Option<(Rotation3<f64>, Vector3<f64>)> {
    let n = a.len().min(b.len());
    if n < 3 {
        return None;
    }
    let mean = |v: &[Vector3<f64>]| v.iter().take(n).sum::<Vector3<f64>>() / n as f64;
    let (ca, cb) = (mean(a), mean(b));
    let mut h = Matrix3::zeros();
    for (pa, pb) in a.iter().zip(b).take(n) {
        h += (pa - ca) * (pb - cb).transpose();
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    // The second-largest singular value is 0 when the points are on a line.
    let mut s = svd.singular_values;
    s.as_mut_slice().sort_by(|x, y| y.total_cmp(x));
    if s[1].is_nan() || s[1] <= 1e-9 * s[0].max(1e-300) {
        return None;
    }
    let mut d = Matrix3::identity();
    if (v_t.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = v_t.transpose() * d * u.transpose();
    let rotation = Rotation3::from_matrix_unchecked(r);
    Some((rotation, cb - rotation * ca))
}

/// Why [`kabsch`] found no motion from the model's tool points to the `measured` ones: too few
/// poses, the measured points on one line, or else the model's.
fn degenerate(measured: &[Vector3<f64>]) -> RegistrationError {
    let n = measured.len();
    if n < 3 {
        return RegistrationError::TooFewPoses(n);
    }
    // The second principal extent of a set of points, relative to its first.
    let flat = |points: &[Vector3<f64>]| {
        let centroid = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
        let mut c = Matrix3::zeros();
        for p in points {
            c += (p - centroid) * (p - centroid).transpose();
        }
        let mut s = c.symmetric_eigenvalues();
        s.as_mut_slice().sort_by(|x, y| y.total_cmp(x));
        // As kabsch's test: its second singular value is at most the product of the two sets'
        // second extents, so one of them is below 1e-9 of its first in squared extent.
        s[1].is_nan() || s[1] <= 1e-9 * s[0].max(1e-300)
    };
    if flat(measured) {
        RegistrationError::MeasuredOnALine(n)
    } else {
        RegistrationError::ModelledOnALine(n)
    }
}

/// The rotation nearest (Frobenius) to `m`.
pub(crate) fn nearest_rotation(m: &Matrix3<f64>) -> Option<Rotation3<f64>> {
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    Some(Rotation3::from_matrix_unchecked(u * d * v_t))
}

/// Registers the nominal robot (frames ignored: base and tool are identity) onto measurements
/// in the tracker's frame. With `identify_tool == false` the robot's own tool is kept.
pub(crate) fn register(
    robot: &Robot<f64, Dyn>,
    measurements: &[Measurement<f64, Dyn>],
    identify_tool: bool,
) -> Result<Registration, RegistrationError> {
    let mut bare = *robot;
    bare.base = calib_core::FramePose::identity();
    if identify_tool {
        bare.tool = calib_core::FramePose::identity();
    }
    let kinematics = Kinematics::nominal(&bare)?;
    let flanges: Vec<_> = measurements
        .iter()
        .map(|m| kinematics.forward_angles(&m.angles))
        .collect();
    let measured: Vec<Vector3<f64>> = measurements.iter().map(|m| m.position).collect();
    let n = measured.len();
    let mut tool = Vector3::zeros();
    let mut base = (Rotation3::identity(), Vector3::zeros());
    let mut iterations = 0;
    let mut previous = f64::INFINITY;
    for iteration in 1..=500 {
        iterations = iteration;
        let points: Vec<Vector3<f64>> = flanges
            .iter()
            .map(|f| f.rotation * tool + f.translation.vector)
            .collect();
        base = kabsch(&points, &measured).ok_or_else(|| degenerate(&measured))?;
        if !identify_tool {
            break;
        }
        // t = mean of R_j^T (R_base^T (m_j - p_base) - p_j)  (R_j^T R_j = I).
        let (r, p) = base;
        let mut sum = Vector3::zeros();
        for (f, m) in flanges.iter().zip(&measured) {
            sum += f.rotation.inverse() * (r.inverse() * (m - p) - f.translation.vector);
        }
        let next = sum / n as f64;
        let change = (next - tool).norm();
        tool = next;
        let rms = rms_of(&residuals(&flanges, &measured, &base, &tool));
        if change < 1e-9 || (previous - rms).abs() < 1e-12 * previous.max(1.0) {
            break;
        }
        previous = rms;
    }
    let tool_rotation = if identify_tool {
        if !tool_point_determined(&flanges) {
            return Err(RegistrationError::ToolUndetermined);
        }
        tool_rotation(&flanges, measurements, &base.0)
    } else {
        Rotation3::identity()
    };
    let residuals = residuals(&flanges, &measured, &base, &tool);
    let rms_mm = rms_of(&residuals);
    let max_mm = residuals.iter().copied().fold(0.0, f64::max);
    Ok(Registration {
        base_rotation: base.0,
        base_translation: base.1,
        tool_translation: tool,
        tool_rotation,
        rms_mm,
        max_mm,
        iterations,
    })
}

/// The tool point is determined when the flange rotations differ:
/// `sum (I - R_j)^T (I - R_j)` must be well conditioned.
fn tool_point_determined(flanges: &[calib_core::Pose<f64>]) -> bool {
    let mut spread = Matrix3::zeros();
    for f in flanges {
        let d = Matrix3::identity() - f.rotation.matrix();
        spread += d.transpose() * d;
    }
    spread.symmetric_eigenvalues().min() >= 1e-6 * flanges.len() as f64
}

/// The tool rotation on the flange for 6-DoF data: the rotation nearest to the mean of
/// `(R_base R_j)^T R_measured,j` (identity for position-only data).
fn tool_rotation(
    flanges: &[calib_core::Pose<f64>],
    measurements: &[Measurement<f64, Dyn>],
    base_rotation: &Rotation3<f64>,
) -> Rotation3<f64> {
    let mut sum = Matrix3::zeros();
    let mut count = 0;
    for (f, m) in flanges.iter().zip(measurements) {
        if let Some(rm) = &m.rotation {
            sum += (base_rotation * f.rotation).inverse().matrix() * rm;
            count += 1;
        }
    }
    if count > 0 {
        nearest_rotation(&sum).unwrap_or_else(Rotation3::identity)
    } else {
        Rotation3::identity()
    }
}

/// `|m_j - (R_base (R_j t + p_j) + p_base)|` per pose, mm.
fn residuals(
    flanges: &[calib_core::kinematics::Pose<f64>],
    measured: &[Vector3<f64>],
    base: &(Rotation3<f64>, Vector3<f64>),
    tool: &Vector3<f64>,
) -> Vec<f64> {
    flanges
        .iter()
        .zip(measured)
        .map(|(f, m)| (m - (base.0 * (f.rotation * tool + f.translation.vector) + base.1)).norm())
        .collect()
}

/// Root mean square of `values`.
fn rms_of(values: &[f64]) -> f64 {
    (values.iter().map(|r| r * r).sum::<f64>() / values.len().max(1) as f64).sqrt()
}

/// A frame as a robot-file entry (mm, `rpy_deg` with `R = Rz Ry Rx`).
pub(crate) fn frame_entry(rotation: &Rotation3<f64>, translation: &Vector3<f64>) -> FrameEntry {
    let (roll, pitch, yaw) = rotation.euler_angles();
    FrameEntry {
        xyz_mm: [translation.x, translation.y, translation.z],
        rpy_deg: [roll, pitch, yaw].map(f64::to_degrees),
    }
}

/// The robot file with its base (and, with `tool`, its tool) replaced by the registration.
pub(crate) fn with_registration(
    file: &RobotFile,
    registration: &Registration,
    tool: bool,
) -> RobotFile {
    let mut out = file.clone();
    out.base = Some(frame_entry(
        &registration.base_rotation,
        &registration.base_translation,
    ));
    if tool {
        out.tool = Some(frame_entry(
            &registration.tool_rotation,
            &registration.tool_translation,
        ));
    }
    out
}

/// The identified parameters with frames: the robot's own mask plus the frame parameters, minus
/// the joint parameters the frames make redundant. With the base: `dd1` and `dtheta1` (they move
/// the first joint along and about its own axis, as the base does). With the tool: everything of
/// joint N after its rotation (`da6, dd6, dalpha6, dbeta6, dtheta6` are a constant transform on
/// the flange, like the tool). `full_pose`: the tool's rotations are identified too (6-DoF data).
/// Returns the mask and the joint parameters removed.
pub(crate) fn mask_with_frames(
    mask: &ParameterMask<Dyn>,
    frames: Frames,
    full_pose: bool,
) -> (ParameterMask<Dyn>, Vec<Parameter>) {
    let mut out = *mask;
    let mut removed = Vec::new();
    let mut remove = |out: &mut ParameterMask<Dyn>, p: Parameter| {
        if out.contains(p) {
            out.set(p, false);
            removed.push(p);
        }
    };
    if frames.base() {
        for kind in FrameParameter::ALL {
            out.set(Parameter::Base(kind), true);
        }
        for kind in [JointParameter::D, JointParameter::Theta] {
            remove(&mut out, Parameter::Joint { joint: 1, kind });
        }
    }
    if frames.tool() {
        for kind in FrameParameter::ALL {
            out.set(Parameter::Tool(kind), full_pose || !kind.is_rotation());
        }
        for kind in JointParameter::ALL {
            remove(
                &mut out,
                Parameter::Joint {
                    joint: u8::try_from(mask.joint_count().0).unwrap_or(u8::MAX),
                    kind,
                },
            );
        }
    }
    (out, removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kabsch_recovers_a_known_motion() {
        let r = Rotation3::from_euler_angles(0.3, -1.2, 2.5);
        let t = Vector3::new(3000.0, -200.0, 50.0);
        let a: Vec<Vector3<f64>> = (0..10)
            .map(|i| {
                let x = f64::from(i);
                Vector3::new(x * 100.0, (x * 1.7).sin() * 500.0, (x * 0.3).cos() * 800.0)
            })
            .collect();
        let b: Vec<_> = a.iter().map(|p| r * p + t).collect();
        let (rr, tt) = kabsch(&a, &b).unwrap();
        assert!((rr.matrix() - r.matrix()).norm() < 1e-12);
        assert!((tt - t).norm() < 1e-9);
        let line: Vec<_> = (0..5)
            .map(|i| Vector3::new(f64::from(i), 0.0, 0.0))
            .collect();
        assert!(kabsch(&line, &line).is_none());
    }

    #[test]
    fn implausible_measured_frames_are_blamed_on_the_data_not_the_robot_file() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let dataset = crate::measurement::dataset::Dataset::load(
            &root.join("robots/er10l-c10.toml"),
            &root.join("data/er10l-c10-sim32.csv"),
        )
        .unwrap();
        let seen = dataset.as_given().unwrap();
        let mut wild = dataset.robot.file.clone();
        wild.base = Some(FrameEntry {
            xyz_mm: [-146_114.0, 0.0, 0.0],
            rpy_deg: [0.0; 3],
        });
        let message = measured_model(&wild, &seen, "registered")
            .unwrap_err()
            .to_string();
        assert!(
            message.starts_with(&root.join("data/er10l-c10-sim32.csv").display().to_string())
                && message.contains("frames registered from these data")
                && message.contains("-146114")
                && message.contains("units of the positions"),
            "{message}"
        );
        // The robot file's own frames pass.
        assert!(measured_model(&dataset.robot.file, &seen, "fitted").is_ok());
    }
}

/// Largest registration RMS (mm) accepted: a robot's geometric errors move the tool by a few
/// millimetres, so a nominal model registered onto correct data fits within this; more means the
/// data, the profile (units, Euler convention, joint order) or the robot file are wrong.
pub(crate) const MAX_REGISTRATION_RMS_MM: f64 = 20.0;

/// What the frame identification did, for reports.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct FramesReport {
    /// The frames identified (`none`, `base` or `base+tool` in JSON).
    pub identified: Frames,
    /// RMS position residual of the closed-form registration, mm.
    pub registration_rms_mm: f64,
    /// Largest position residual of the registration, mm.
    pub registration_max_mm: f64,
    /// Alternations of the registration.
    pub registration_iterations: u32,
    /// RMS position residual with the nominal geometry and the frames fitted by least squares, mm.
    pub frames_fit_rms_mm: f64,
    /// Joint parameters not identified because the frames absorb them.
    pub redundant_with_frames: Vec<String>,
    /// The identified base frame (tracker to robot base), when identified.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub base: Option<FrameEntry>,
    /// The identified tool frame (on the flange), when identified.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tool: Option<FrameEntry>,
    /// Probe parameters the data could not determine in a re-registration, held at the robot
    /// file's stored probe (`[measurement] flange_tool`) instead of being fitted.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub held_at_stored_probe: Vec<String>,
    /// The probe the robot file stores (`[measurement] flange_tool`), against which a
    /// re-registration's fitted probe is compared. Not in the JSON report (`None` when read back).
    #[serde(skip)]
    pub stored_probe: Option<crate::io::robot_file::FrameEntry>,
}

/// The probe the robot file of `inputs` stores, if any.
fn stored_probe(inputs: &Seen<'_>) -> Option<crate::io::robot_file::FrameEntry> {
    (inputs.robot.file.measurement.as_ref()).and_then(|m| m.flange_tool.clone())
}

/// The model of `file`, whose frames were `how` (registered or fitted) from the data of
/// `inputs`: frames beyond the plausible ranges of a robot file are blamed on the data, not on the
/// robot file (which holds the nominal frames).
fn measured_model(
    file: &RobotFile,
    inputs: &Seen<'_>,
    how: &str,
) -> crate::Result<crate::io::robot_file::RobotModel> {
    file.to_model(&inputs.robot.model.path).map_err(|e| match e {
        crate::io::robot_file::RobotFileError::Invalid { message, .. } => crate::refused!(input inputs.data.path.display();
            "{}: the tracker and tool frames {how} from these data are not physically plausible ({message}). \
             The positions do not come from this robot in one rigid tracker frame: check the units of the \
             positions (a data profile, --profile), the joint order and signs against the robot file {}, \
             and whether the data are already in the base frame (--frames none)",
            inputs.data.path.display(),
            inputs.robot.model.path.display()
        ),
        other => other.into(),
    })
}

/// The robot file `registered` (the registration's frames) with the frames of `mask` fitted by
/// least squares to `inputs`, the geometry fixed.
fn with_fitted_frames(
    inputs: &Seen<'_>,
    registered: RobotFile,
    mask: &ParameterMask<Dyn>,
    k: f64,
) -> crate::Result<RobotFile> {
    let mut frame_mask = ParameterMask::empty_for(mask.joint_count());
    for p in mask.iter() {
        if matches!(p, Parameter::Base(_) | Parameter::Tool(_)) {
            frame_mask.set(p, true);
        }
    }
    let registered_model = measured_model(&registered, inputs, "registered")?;
    let registered_robot = inputs
        .robot
        .with_frames(registered.clone(), registered_model);
    let fitted_inputs = inputs.for_robot(&registered_robot);
    let frame_parameters = frame_mask.count();
    if !(1..=12).contains(&frame_parameters) {
        return Err(crate::refused!(option "--identify";
            "{frame_parameters} frame parameters; the two frames have 1 to 12"
        ));
    }
    let errors = fit_frames(&fitted_inputs, &frame_mask, k)?;
    let mut fitted = registered.with_errors(&errors, [], &[], "", "");
    fitted.calibration = None;
    Ok(fitted)
}

/// The registration stage a calibration and an evaluation share: the measurement setup of
/// `robot` for `frames` (`with_identified_probe`: with only the base fitted, an identified
/// probe stays the tool), then the frames registered and fitted on `dataset` with the geometry
/// held ([`prepare`]).
pub struct RegisteredSetup {
    /// The robot the frames were registered from: `robot`, or it in its measurement setup.
    pub setup: ActualRobot,
    /// `true` when an identified probe was kept as the tool.
    pub probe_kept: bool,
    /// The robot with the registered and fitted frames.
    pub robot: ActualRobot,
    /// The frames' report.
    pub report: FramesReport,
    /// The parameters identified with these frames.
    pub mask: ParameterMask<Dyn>,
}

/// Registers `frames` of `robot` on `dataset` (orientation weight `k`, mm^2/rad^2): see
/// [`RegisteredSetup`].
pub fn register_setup(
    robot: &ActualRobot,
    frames: Frames,
    dataset: &crate::measurement::dataset::Dataset,
    k: f64,
) -> crate::Result<RegisteredSetup> {
    let setup = with_identified_probe(robot, frames)?;
    let probe_kept = setup.is_some();
    let setup = setup.unwrap_or_else(|| robot.clone());
    let (registered, report, mask) = prepare(frames, &dataset.seen_by(&setup)?, k)?;
    Ok(RegisteredSetup {
        setup,
        probe_kept,
        robot: registered,
        report,
        mask,
    })
}

/// The frames stage: registers the frames of the robot that sees `inputs` and fits them (its
/// geometry held) by least squares. Returns that robot with the fitted frames (the robot itself
/// when `frames` is none: the data are in its base frame), the report and the mask of identified
/// parameters with the frames.
pub fn prepare(
    frames: Frames,
    inputs: &Seen<'_>,
    k: f64,
) -> crate::Result<(ActualRobot, FramesReport, ParameterMask<Dyn>)> {
    let full_pose = inputs.measurements().iter().all(|m| m.rotation.is_some());
    let (mask, removed) = mask_with_frames(&inputs.robot.model.mask, frames, full_pose);
    if frames == Frames::None {
        check_base_frame(inputs)?;
        return Ok((
            inputs.robot.clone(),
            FramesReport {
                identified: frames,
                registration_rms_mm: 0.0,
                registration_max_mm: 0.0,
                registration_iterations: 0,
                frames_fit_rms_mm: 0.0,
                redundant_with_frames: Vec::new(),
                base: None,
                tool: None,
                held_at_stored_probe: Vec::new(),
                stored_probe: stored_probe(inputs),
            },
            mask,
        ));
    }
    let registration = register(
        &inputs.robot.model.robot,
        inputs.measurements(),
        frames.tool(),
    )?;
    if registration.rms_mm > MAX_REGISTRATION_RMS_MM {
        return Err(crate::refused!(input inputs.data.path.display();
            "{}: the nominal robot registered onto the measurements leaves {:.1} mm RMS ({:.1} mm max), \
             far above the few millimetres of a robot's geometric errors (limit {MAX_REGISTRATION_RMS_MM} mm). \
             Check the units and Euler convention of the data (a data profile, --profile), the joint order \
             and signs against the robot file, and whether the data are already in the base frame (--frames none)",
            inputs.data.path.display(),
            registration.rms_mm,
            registration.max_mm
        ));
    }
    let registered = with_registration(&inputs.robot.file, &registration, frames.tool());
    let fitted = with_fitted_frames(inputs, registered, &mask, k)?;
    let model = measured_model(&fitted, inputs, "fitted")?;
    let robot = inputs.robot.with_frames(fitted, model);
    let kinematics = Kinematics::nominal(&robot.model.robot)?;
    let frames_fit_rms_mm =
        crate::measurement::statistics::table3(&kinematics, inputs.measurements())
            .0
            .position_mm
            .rms;
    Ok((
        robot,
        FramesReport {
            identified: frames,
            registration_rms_mm: registration.rms_mm,
            registration_max_mm: registration.max_mm,
            registration_iterations: registration.iterations,
            frames_fit_rms_mm,
            redundant_with_frames: removed.iter().map(ToString::to_string).collect(),
            base: None,
            tool: None,
            held_at_stored_probe: Vec::new(),
            stored_probe: stored_probe(inputs),
        },
        mask,
    ))
}

/// Re-registration with the probe fitted (`base+tool`) against a robot file that stores one
/// (`[measurement] flange_tool`): the probe's parameters the selection `dropped` (the data cannot
/// determine them) are held at the stored probe's values, not at the values the unconstrained
/// frames fit gave them; the frame parameters of `mask` (the selection) are fitted again from
/// there (the geometry of the robot that sees `inputs` held, as in [`prepare`]). A translation is
/// set to the stored one; a rotation is turned about the tool's own axis by the component of the
/// turn from the fitted to the stored probe. Returns the robot with these frames and the
/// parameters held, or `None` when none is held.
pub(crate) fn hold_dropped_probe_parameters(
    inputs: &Seen<'_>,
    (dropped, mask): (&[Parameter], &ParameterMask<Dyn>),
    stored: &FrameEntry,
    k: f64,
) -> crate::Result<Option<(ActualRobot, Vec<Parameter>)>> {
    let held: Vec<Parameter> = dropped
        .iter()
        .copied()
        .filter(|p| matches!(p, Parameter::Tool(_)))
        .collect();
    let Some(fitted) = inputs.robot.file.tool.clone().filter(|_| !held.is_empty()) else {
        return Ok(None);
    };
    let (now, target) = (fitted.isometry(), stored.isometry());
    let mut translation = now.translation.vector;
    // The turn from the fitted probe to the stored one, in the probe's own axes.
    let turn = (now.rotation.inverse() * target.rotation).scaled_axis();
    let mut kept_turn = Vector3::zeros();
    for p in &held {
        match p {
            Parameter::Tool(FrameParameter::Tx) => translation.x = target.translation.vector.x,
            Parameter::Tool(FrameParameter::Ty) => translation.y = target.translation.vector.y,
            Parameter::Tool(FrameParameter::Tz) => translation.z = target.translation.vector.z,
            Parameter::Tool(FrameParameter::Rx) => kept_turn.x = turn.x,
            Parameter::Tool(FrameParameter::Ry) => kept_turn.y = turn.y,
            Parameter::Tool(FrameParameter::Rz) => kept_turn.z = turn.z,
            _ => {}
        }
    }
    let rotation = now.rotation * nalgebra::UnitQuaternion::from_scaled_axis(kept_turn);
    let mut held_file = inputs.robot.file.clone();
    held_file.tool = Some(frame_entry(&rotation.to_rotation_matrix(), &translation));
    let file = with_fitted_frames(inputs, held_file, mask, k)?;
    let model = measured_model(&file, inputs, "fitted")?;
    Ok(Some((inputs.robot.with_frames(file, model), held)))
}

/// How many times better a registration must fit data said to be in the base frame for them to
/// be refused as in another frame.
const REGISTRATION_GAIN: f64 = 3.0;

/// RMS miss of the nominal model, mm, beyond which data said to be in the base frame are refused
/// whatever the cause: five times [`MAX_REGISTRATION_RMS_MM`].
const BEYOND_GEOMETRIC_ERRORS_MM: f64 = 5.0 * MAX_REGISTRATION_RMS_MM;

/// Checks that data said to be in the robot's base frame are. Data the robot file's model misses
/// by more than [`MAX_REGISTRATION_RMS_MM`] are refused when they look like another frame (a
/// registration fits them [`REGISTRATION_GAIN`] times better) or other units (their spread is
/// about 1000 times the model's), or when the model misses them by more than
/// [`BEYOND_GEOMETRIC_ERRORS_MM`]; the error says which.
pub(crate) fn check_base_frame(dataset: &Seen<'_>) -> crate::Result<()> {
    let kinematics = Kinematics::nominal(&dataset.robot.model.robot)?;
    let rms = crate::measurement::statistics::table3(&kinematics, dataset.measurements())
        .0
        .position_mm
        .rms;
    if rms <= MAX_REGISTRATION_RMS_MM {
        return Ok(());
    }
    let measured: Vec<Vector3<f64>> = dataset.measurements().iter().map(|m| m.position).collect();
    let modelled: Vec<Vector3<f64>> = dataset
        .measurements()
        .iter()
        .map(|m| kinematics.forward_angles(&m.angles).translation.vector)
        .collect();
    let ratio = spread(&measured) / spread(&modelled).max(1e-300);
    let registered = register(&dataset.robot.model.robot, dataset.measurements(), true)
        .ok()
        .filter(|r| r.rms_mm <= MAX_REGISTRATION_RMS_MM);
    let units = (300.0..3000.0).contains(&ratio) || (1.0 / 3000.0..1.0 / 300.0).contains(&ratio);
    // Large geometric errors (the paper's Table 2 moves the tool by up to 37 mm) are not a wrong
    // frame: refused only with evidence of one (a registration that explains the data at least
    // REGISTRATION_GAIN times better, spreads of other units) or beyond any geometric error.
    let wrong_frame = registered
        .as_ref()
        .is_some_and(|r| r.rms_mm * REGISTRATION_GAIN < rms);
    if !wrong_frame && !units && rms <= BEYOND_GEOMETRIC_ERRORS_MM {
        return Ok(());
    }
    // Data that do not say they are in the base frame, taken there by an option (a stored
    // registration, `evaluate --stored-registration`, or frames none): no '# frame: base' line
    // to blame; with a stored registration the tracker or the robot moved since.
    let taken_as_base = !dataset.data.base_frame;
    let likely = if let Some(r) = registered.as_ref().filter(|_| wrong_frame && taken_as_base) {
        format!(
            "they are in another frame than the one they were taken in: registered anew, the same model fits them to {:.2} mm RMS. \
             With --stored-registration the tracker (or the robot) moved since that registration: re-register \
             (calibrate --identify frames), or evaluate with --fit-frames base+tool; otherwise fit the frames \
             (--frames base+tool, --fit-frames base+tool)",
            r.rms_mm
        )
    } else if let Some(r) = registered.filter(|_| wrong_frame) {
        format!(
            "they are in another frame: registered like tracker data, the same model fits them to {:.2} mm RMS. \
             Use --frames base+tool (calibrate, check, verify) or --fit-frames base+tool (evaluate), and remove a '# frame: base' line from the data, or frame = \"base\" from the profile",
            r.rms_mm
        )
    } else if (300.0..3000.0).contains(&ratio) {
        format!(
            "their positions spread {ratio:.0} times as far as the robot reaches: millimetres under metre headers (x_m)? \
             Check the units of the position columns"
        )
    } else if (1.0 / 3000.0..1.0 / 300.0).contains(&ratio) {
        format!(
            "their positions spread 1/{:.0} as far as the robot reaches: metres under millimetre headers (x_mm)? \
             Check the units of the position columns",
            1.0 / ratio
        )
    } else {
        "check the units of the columns, the joint order and signs against the robot file, the Euler convention \
         of a data profile, and whether the data are in the base frame at all (--frames base+tool)"
            .to_string()
    };
    Err(crate::refused!(input dataset.data.path.display();
        "{}: the data are said to be in the robot's base frame, but the model of {} misses them by {rms:.1} mm RMS, \
         far beyond the few millimetres of a robot's geometric errors. Likely: {likely}",
        dataset.data.path.display(),
        dataset.robot.model.path.display()
    ))
}

/// RMS distance of points from their centroid, mm.
fn spread(points: &[Vector3<f64>]) -> f64 {
    let centroid = points.iter().sum::<Vector3<f64>>() / points.len().max(1) as f64;
    rms_of(
        &points
            .iter()
            .map(|p| (p - centroid).norm())
            .collect::<Vec<_>>(),
    )
}

/// Least-squares fit of the frame parameters in `mask` alone (nominal geometry).
fn fit_frames(
    inputs: &Seen<'_>,
    mask: &ParameterMask<Dyn>,
    k: f64,
) -> crate::Result<calib_core::ParameterErrors<f64, Dyn>> {
    let set = calib_core::ParameterSet::<Dyn, nalgebra::Dyn>::from_mask(mask)?;
    let problem = inputs.problem(set, k).context("fitting the frames")?;
    let set = problem.set();
    let least_squares = calib_core::identify::lm::LeastSquares::new(&problem);
    let result = least_squares
        .solve(
            &set.zeros(),
            &calib_core::identify::lm::LmSettings::default(),
        )
        .context("fitting the frames")?;
    Ok(set.unpack(&result.x)?)
}
