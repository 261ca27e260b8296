//! `calib compensate`: read the nominal and identified robots and the targets, compensate
//! ([`host_tools::kinematics::compensate`]), write one CSV row per target.

use anyhow::bail;
use host_tools::io::outputs::Outputs;
use host_tools::io::robot_file::RobotFile;
use host_tools::kinematics::compensate::{Summary, TargetOutcome, to_csv};
use host_tools::kinematics::targets::{CompensationRequest, ConfigurationChoice};
use std::path::PathBuf;

pub use host_tools::kinematics::targets::TargetsFrame;

/// Options of `calib compensate`.
#[derive(Clone, Debug, clap::Args)]
pub struct CompensateOptions {
    /// Nominal robot file: the model the controller plans with.
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// Identified robot file (from calib calibrate --out): the actual robot, with its joint maps
    /// and gravity compliance when it has them (calibrate --model joint-maps,
    /// joint-maps+compliance).
    #[arg(long, value_name = "FILE")]
    pub params: PathBuf,
    /// Target poses of the controller's tool (CSV: x_mm, y_mm, z_mm and an orientation; optional
    /// q1_deg..qN_deg as the start, i.e. the controller's nominal joints for the target, which
    /// also name its arm configuration; without them name the configuration with --near-deg or
    /// --branch, or a `configuration` column of `branch B` per target), in the robot's base frame
    /// unless --targets-frame says otherwise.
    #[arg(long, value_name = "FILE")]
    pub targets: PathBuf,
    /// The frame of the targets: the robot's base (the robot file's DH base), the tracker's (the
    /// cell's, as measured), mapped into the base frame through the registration identified with
    /// the --params file (its `[measurement]` section's `tracker_base`), or a UR pendant's base
    /// (`ur-base`: the DH base turned by 180 deg about z, x and y negated; poses copied from a UR
    /// pendant or URScript's get_actual_tcp_pose are in it).
    #[arg(long, value_enum, default_value_t = TargetsFrame::Base)]
    pub targets_frame: TargetsFrame,
    /// The targets are a robot program's joint targets (CSV: q1_deg..qN_deg, optional id, such as
    /// calib plan --joint-targets writes): each target is the pose the --robot (nominal) model
    /// puts the controller's tool at for those joints, and the joints are its start (and arm
    /// configuration). The output is the program corrected: the joints that put the identified
    /// robot where the program meant.
    #[arg(long, conflicts_with_all = ["near_deg", "branch"])]
    pub joint_targets: bool,
    /// Output CSV: one row per target, in input order.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Also write the compensated joints as a URScript program (Universal Robots, 6 joints): a
    /// movej to each target in order. Only when every target was compensated: a program without
    /// the refused ones is not the program asked for, so nothing is written then.
    #[arg(long, value_name = "FILE")]
    pub urscript: Option<PathBuf>,
    /// URScript: joint speed of the moves, rad/s (above 0, at most 3.2).
    #[arg(long, default_value_t = 0.5, requires = "urscript", allow_hyphen_values = true,
          value_parser = super::joint_speed)]
    pub speed_rad_s: f64,
    /// URScript: joint acceleration of the moves, rad/s^2 (above 0, at most 40).
    #[arg(long, default_value_t = 0.5, requires = "urscript", allow_hyphen_values = true,
          value_parser = super::joint_acceleration)]
    pub acceleration_rad_s2: f64,
    /// Largest allowed change of the commanded pose, mm.
    #[arg(long, default_value_t = 5.0)]
    pub max_correction_mm: f64,
    /// Largest allowed change of the commanded orientation, deg.
    #[arg(long, default_value_t = 0.5)]
    pub max_correction_deg: f64,
    /// Largest allowed change of any joint, deg.
    #[arg(long, default_value_t = 0.5f64.to_degrees())]
    pub max_joint_correction_deg: f64,
    /// Arm configuration of targets without joints (default: the --robot file's
    /// `[compensation]`): that of this posture (joint readings in deg, e.g. the robot's home),
    /// kept by every target (closed form where the robot has one,
    /// each joint within whole turns of the posture; numerical from the posture otherwise).
    #[arg(
        long,
        value_name = "Q1,...,QN",
        value_delimiter = ',',
        allow_hyphen_values = true,
        conflicts_with = "branch"
    )]
    pub near_deg: Option<Vec<f64>>,
    /// Arm configuration of targets without joints, as a closed-form inverse kinematics branch
    /// (spherical wrist or UR-type offset wrist): 0-7, bit 4 = shoulder back, bit 2 = elbow
    /// down, bit 1 = wrist flipped.
    #[arg(long, value_name = "B")]
    pub branch: Option<usize>,
    /// Compensate targets whose joints leave the range of readings a joint map was identified
    /// on (counted in the summary) instead of refusing them.
    #[arg(long)]
    pub allow_extrapolation: bool,
    /// On a 7-joint arm (numerical inverse kinematics), the largest change of the arm angle (the
    /// elbow's turn about the shoulder-wrist line) from the posture or the given joints, deg; a
    /// solution beyond it is another configuration and refused. The configuration joints (on the
    /// iiwa 2, 4 and 6) always keep the posture's side of zero. Default 15; refused for other
    /// robots.
    #[arg(long, value_name = "DEG", value_parser = arm_angle_bound)]
    pub max_arm_angle_deg: Option<f64>,
    /// On a robot without a closed form (numerical inverse kinematics), the largest distance of
    /// any joint from the posture (--near-deg) or the given joints, deg; a solution beyond it is
    /// refused as another configuration. Default 90; refused for robots with a closed form.
    #[arg(long, value_name = "DEG", value_parser = joint_distance_bound)]
    pub near_within_deg: Option<f64>,
    /// The targets' text in the format of a `--targets` file, when they come from memory (the
    /// Python package's arrays): parsed instead of reading `targets`, which then only names
    /// them in messages.
    #[arg(skip)]
    pub targets_text: Option<String>,
}

/// `--near-within-deg`: a finite angle from 0 to 360 deg.
fn joint_distance_bound(text: &str) -> Result<f64, String> {
    let v: f64 = text.parse().map_err(|e| format!("{e}"))?;
    if !(0.0..=360.0).contains(&v) {
        return Err(format!("{v} deg: give 0 to 360 deg"));
    }
    Ok(v)
}

/// `--max-arm-angle-deg`: a finite angle from 0 to 180 deg.
fn arm_angle_bound(text: &str) -> Result<f64, String> {
    let v: f64 = text.parse().map_err(|e| format!("{e}"))?;
    if !(0.0..=180.0).contains(&v) {
        return Err(format!("{v} deg: give 0 to 180 deg"));
    }
    Ok(v)
}

impl CompensateOptions {
    /// The library's request of these options.
    pub fn request(&self) -> CompensationRequest {
        let configuration = match (&self.near_deg, self.branch) {
            (Some(posture), _) => Some(ConfigurationChoice::NearDeg(posture.clone())),
            (None, Some(branch)) => Some(ConfigurationChoice::Branch(branch)),
            (None, None) => None,
        };
        CompensationRequest {
            targets_text: self.targets_text.clone(),
            frame: self.targets_frame,
            joint_targets: self.joint_targets,
            max_correction_mm: self.max_correction_mm,
            max_correction_deg: self.max_correction_deg,
            max_joint_correction_deg: self.max_joint_correction_deg,
            configuration,
            allow_extrapolation: self.allow_extrapolation,
            max_arm_angle_deg: self.max_arm_angle_deg,
            near_within_deg: self.near_within_deg,
            ..CompensationRequest::new(self.targets.clone())
        }
    }
}

/// Runs `calib compensate` for the robot file's joint count (6 to 9 joints, fewer are refused
/// with the reason; joint maps and gravity compliance for every count).
pub fn compensate(options: &CompensateOptions) -> anyhow::Result<Summary> {
    let file = RobotFile::read(&options.robot)?;
    let params = RobotFile::read(&options.params)?;
    let (outcomes, joints) = compensated(options, file, params)?;
    finish(options, &outcomes, joints)
}

/// The outcome of every target of `calib compensate` of the nominal robot `file` and the
/// identified `params`, and the joint count.
fn compensated(
    options: &CompensateOptions,
    file: RobotFile,
    params: RobotFile,
) -> anyhow::Result<(Vec<TargetOutcome>, usize)> {
    let robots = (
        (file, options.robot.as_path()),
        (params, options.params.as_path()),
    );
    Ok(options.request().outcomes(robots.0, robots.1)?)
}

/// Writes the outcomes (all or nothing) and counts them.
fn finish(
    options: &CompensateOptions,
    outcomes: &[host_tools::kinematics::compensate::TargetOutcome],
    joints: usize,
) -> anyhow::Result<Summary> {
    let mut outputs = Outputs::new(&[
        ("--robot", &options.robot),
        ("--params", &options.params),
        ("--targets", &options.targets),
    ]);
    outputs.stage("--out", &options.out, &to_csv(outcomes, joints)?)?;
    if let Some(path) = &options.urscript {
        outputs.stage("--urscript", path, urscript(options, outcomes)?.as_bytes())?;
    }
    outputs.commit()?;
    Ok(Summary::of(outcomes))
}

/// The compensated joints as a URScript program (`--urscript`), targets in input order. Refused
/// when a target was refused (naming the first and why), or for a robot of other than 6 joints.
fn urscript(options: &CompensateOptions, outcomes: &[TargetOutcome]) -> anyhow::Result<String> {
    let refused = outcomes.iter().filter(|o| o.result.is_err()).count();
    if let Some((o, Err(why))) = outcomes
        .iter()
        .map(|o| (o, &o.result))
        .find(|(_, r)| r.is_err())
    {
        bail!(
            "--urscript: {refused} of {} targets were refused (the first, {}: {why}); a program without them is not the program asked for: correct or remove them (calib compensate without --urscript writes each row's reason), nothing was written",
            outcomes.len(),
            o.id
        );
    }
    let targets: Vec<(String, Vec<f64>)> = outcomes
        .iter()
        .filter_map(|o| {
            Some((
                o.id.clone(),
                o.result.as_ref().ok()?.q.iter().copied().collect(),
            ))
        })
        .collect();
    let header = [
        format!(
            "The program of {} compensated by calib compensate for the identified robot {}: {} targets in order.",
            options.targets.display(),
            options.params.display(),
            targets.len()
        ),
        "Joints in rad; the identified robot at them reaches the targets the nominal model meant."
            .to_string(),
    ];
    let motion = host_tools::formats::urscript::Motion {
        speed_rad_s: options.speed_rad_s,
        acceleration_rad_s2: options.acceleration_rad_s2,
        settle_s: 0.0,
    };
    Ok(host_tools::formats::urscript::movej_program(
        "calib_compensated",
        &header,
        &targets,
        &motion,
    )?)
}
