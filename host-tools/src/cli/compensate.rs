//! `calib compensate`: read the nominal and identified robots and the targets, compensate
//! ([`crate::kinematics::compensate`]), write one CSV row per target.

use crate::formats::export::controller_model;
use crate::io::outputs::Outputs;
use crate::io::robot_file::RobotFile;
use crate::io::robot_file::RobotModel;
use crate::io::tracker_data::TrackerData;
use crate::kinematics::actual::ActualRobot;
use crate::kinematics::compensate::TargetOutcome;
use crate::kinematics::compensate::{
    Configuration, Request, Summary, compensate_targets, compensate_targets_of, to_csv,
};
use anyhow::bail;
use calib_core::controller::compensate::CompensationSettings;
use std::path::PathBuf;

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
    /// The request of these options for a robot whose joint maps (if any) were identified on
    /// `map_ranges` (rad, per joint; `None` where a joint has no map); without a configuration
    /// option, the nominal robot file's `[compensation]` default, if any.
    fn request(
        &self,
        map_ranges: Vec<Option<[f64; 2]>>,
        default: Option<&crate::io::robot_file::CompensationSection>,
    ) -> anyhow::Result<Request> {
        let robot = self.robot.display();
        let configuration = match (&self.near_deg, self.branch, default) {
            (Some(posture), _, _) => Some(near(posture, "--near-deg")?),
            (None, Some(branch), _) => Some(Configuration::Branch(branch)),
            (None, None, Some(section)) => match (&section.near_deg, section.branch) {
                (Some(posture), None) => {
                    Some(near(posture, &format!("{robot}: [compensation] near_deg"))?)
                }
                (None, Some(branch)) => Some(Configuration::Branch(branch)),
                _ => bail!(
                    "{robot}: [compensation] states the configuration of targets without joints: give near_deg = [...] (a posture, deg) or branch = 0-7, one of them"
                ),
            },
            (None, None, None) => None,
        };
        Ok(Request {
            configuration,
            configuration_is_default: self.near_deg.is_none() && self.branch.is_none(),
            map_ranges,
            allow_extrapolation: self.allow_extrapolation,
            bounds: crate::kinematics::configuration::ConfigurationBounds {
                max_arm_angle_rad: (self.max_arm_angle_deg)
                    .unwrap_or(crate::kinematics::configuration::DEFAULT_MAX_ARM_ANGLE_DEG)
                    .to_radians(),
                max_joint_distance_rad: (self.near_within_deg)
                    .unwrap_or(crate::kinematics::configuration::DEFAULT_MAX_JOINT_DISTANCE_DEG)
                    .to_radians(),
            },
            stated_bounds: crate::cli::given_flags([
                ("--near-within-deg", self.near_within_deg.is_some()),
                ("--max-arm-angle-deg", self.max_arm_angle_deg.is_some()),
            ]),
        })
    }
}

/// The frame target poses are given in (`calib compensate --targets-frame`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TargetsFrame {
    /// The robot's base frame, as the controller plans.
    Base,
    /// The laser tracker's frame: the cell as measured.
    Tracker,
    /// A Universal Robots controller's base frame, as the pendant shows poses: the DH base of the
    /// robot file (ur_description's `base_link`) turned by 180 deg about z (x and y negated).
    UrBase,
}

/// Maps targets given in the tracker's frame into the robot's base frame through the registration
/// identified with the `params` file: `T_base = B^-1 T_tracker`, `B` its `[measurement]`
/// section's `tracker_base`. Refused without a registration, and for a target file that says
/// `# frame: base`.
fn targets_into_base(
    targets: &mut TrackerData,
    (params, params_path): (&RobotFile, &std::path::Path),
    targets_path: &std::path::Path,
) -> anyhow::Result<()> {
    if targets.base_frame {
        bail!(
            "{}: says '# frame: base', but --targets-frame tracker says the targets are in the tracker's frame; remove one",
            targets_path.display()
        );
    }
    let Some(measurement) = &params.measurement else {
        bail!(
            "{}: has no [measurement] section, the registration of the tracker that --targets-frame tracker maps the targets \
             through: give a file calibrated on data in the tracker's frame, or targets in the base frame",
            params_path.display()
        );
    };
    let base = measurement.tracker_base.isometry();
    for record in &mut targets.records {
        let position = nalgebra::Point3::from(nalgebra::Vector3::from(record.position));
        record.position = base.inverse_transform_point(&position).coords.into();
        record.rotation = record
            .rotation
            .map(|r| base.rotation.to_rotation_matrix().matrix().transpose() * r);
    }
    targets.base_frame = true;
    Ok(())
}

/// The joint targets of the file at `path` (`--joint-targets`) as target poses: each record's
/// position and orientation the nominal model's pose at its joints, in the base frame; its
/// joints stay as the start. Joints outside the nominal model's limits are refused with the line.
fn nominal_poses_of(
    nominal: &RobotModel,
    path: &std::path::Path,
    text: Option<&str>,
) -> anyhow::Result<TrackerData> {
    let profile = crate::io::profile::DataProfile::default();
    let mut targets = match text {
        Some(text) => TrackerData::parse_joints(text, path, &profile)?,
        None => TrackerData::read_joints(path, &profile)?,
    };
    let joints = nominal.robot.joints.len();
    if targets.joints != joints {
        bail!(
            "{}: has {} joint columns, the robot {} has {joints} joints",
            path.display(),
            targets.joints,
            nominal.path.display()
        );
    }
    let kinematics = calib_core::Kinematics::nominal(&nominal.robot)?;
    for record in &mut targets.records {
        let q = calib_core::model::JointVec::from_slice(&record.q)
            .ok_or_else(|| anyhow::anyhow!("{}: more than 9 joints", path.display()))?;
        if let Some(outside) = nominal.outside_limits(&record.q) {
            bail!("{}:{}: {outside}", path.display(), record.line);
        }
        let pose = kinematics.forward(&q)?;
        record.position = pose.translation.vector.into();
        record.rotation = Some(*pose.rotation.matrix());
    }
    targets.orientation = crate::io::tracker_data::OrientationColumns::Quaternion;
    targets.base_frame = true;
    Ok(targets)
}

/// The configuration of the posture `deg` (deg), named `what` in errors.
fn near(deg: &[f64], what: &str) -> anyhow::Result<Configuration> {
    if let Some(v) = deg.iter().find(|v| !v.is_finite()) {
        bail!("{what}: {v} is not a finite angle");
    }
    let Some(q) = calib_core::model::JointVec::from_slice(
        &deg.iter().map(|v| v.to_radians()).collect::<Vec<_>>(),
    ) else {
        bail!("{what} has {} values; at most 9 joints", deg.len());
    };
    Ok(Configuration::Near(q))
}

/// The fewest joints that put a tool on a 6-DoF pose.
const MIN_JOINTS: usize = 6;

/// Runs `calib compensate` for the robot file's joint count (6 to 9 joints, fewer are refused
/// with the reason; joint maps for every count, gravity compliance for 6-joint robots).
pub fn compensate(options: &CompensateOptions) -> anyhow::Result<Summary> {
    let file = RobotFile::read(&options.robot)?;
    let params = RobotFile::read(&options.params)?;
    let (outcomes, joints) = compensated(options, file, params)?;
    finish(options, &outcomes, joints)
}

/// The table `calib compensate` writes to `--out` (CSV, one row per target), computed and
/// written nowhere, with its summary, from the robots already read (the Python package's
/// `compensate`, whose robots may be built in memory): `file` the nominal robot, `params` the
/// identified one; `options`' robot paths name them in messages only.
pub fn compensated_table_of(
    options: &CompensateOptions,
    file: RobotFile,
    params: RobotFile,
) -> anyhow::Result<(Vec<u8>, Summary)> {
    let (outcomes, joints) = compensated(options, file, params)?;
    Ok((to_csv(&outcomes, joints)?, Summary::of(&outcomes)))
}

/// The outcome of every target of `calib compensate` of the nominal robot `file` and the
/// identified `params`, and the joint count.
fn compensated(
    options: &CompensateOptions,
    file: RobotFile,
    params: RobotFile,
) -> anyhow::Result<(Vec<TargetOutcome>, usize)> {
    file.refuse_joint_maps(
        &options.robot,
        "calib compensate's --robot (the nominal model the controller plans with)",
    )?;
    if file.joint.len() < MIN_JOINTS {
        bail!(
            "{}: compensation puts the tool on 6-DoF target poses (position and orientation), which \
             takes at least {MIN_JOINTS} joints; this robot has {}, so the identified robot generally \
             cannot reach a pose its nominal model reaches (calibrate, check, evaluate, verify, fk \
             and export take it)",
            options.robot.display(),
            file.joint.len()
        );
    }
    params.expect_joints(
        &options.params,
        file.joint.len(),
        "the nominal robot of --robot",
    )?;
    let actual = ActualRobot::from_file(params.clone(), &options.params)?;
    crate::model::counts::joint_count(file.joint.len())?;
    // The readings each non-zero map was identified on.
    let ranges = params
        .joint_maps
        .as_ref()
        .map(crate::model::joint_maps::JointMapsSection::ranges)
        .unwrap_or_default();
    let map_ranges = (0..file.joint.len())
        .map(|j| {
            let mapped = actual.maps.as_ref().is_some_and(|m| !m.is_zero(j));
            ranges.get(j).copied().filter(|_| mapped)
        })
        .collect();
    let request = options.request(map_ranges, file.compensation.as_ref())?;
    let nominal = file.to_model(&options.robot)?;
    let outcomes = if actual.maps.is_none() && actual.compliance.is_none() {
        compensate_geometric(options, (nominal, &actual), &params, &request)?
    } else {
        compensate_model(options, (nominal, &actual), &params, &request)?
    };
    Ok((outcomes, file.joint.len()))
}

/// `calib compensate` of a model with joint maps or gravity compliance (the compliance a 6R
/// arm's, refused for other counts): the controller's model, geometry, maps (zero without) and
/// compliance (none without), of the identified robot `actual` (the file `params`); `nominal` the
/// model the controller plans with.
fn compensate_model(
    options: &CompensateOptions,
    (nominal, actual): (RobotModel, &ActualRobot),
    params: &RobotFile,
    request: &Request,
) -> anyhow::Result<Vec<TargetOutcome>> {
    let (targets, settings) = inputs(options, &nominal, params)?;
    let model = controller_model(
        actual.model.robot,
        actual.maps.as_ref(),
        actual.compliance.as_ref(),
    )?;
    let real = model.kinematics()?;
    Ok(compensate_targets_of(
        &nominal.robot,
        &real,
        &targets,
        &settings,
        request,
    )?)
}

/// `calib compensate` of a geometric model (`actual`, of the file `params`).
fn compensate_geometric(
    options: &CompensateOptions,
    (nominal, actual): (RobotModel, &ActualRobot),
    params: &RobotFile,
    request: &Request,
) -> anyhow::Result<Vec<TargetOutcome>> {
    let (targets, settings) = inputs(options, &nominal, params)?;
    Ok(compensate_targets(
        &nominal.robot,
        &actual.model.robot,
        &targets,
        &settings,
        request,
    )?)
}

/// The targets (through the registration of the identified file `params` for targets in the
/// tracker's frame; the nominal poses of `nominal` for joint targets) and the settings, checked.
fn inputs(
    options: &CompensateOptions,
    nominal: &RobotModel,
    params: &RobotFile,
) -> anyhow::Result<(TrackerData, CompensationSettings<f64>)> {
    let mut targets = if options.joint_targets {
        if options.targets_frame != TargetsFrame::Base {
            bail!(
                "--joint-targets: the targets are the nominal poses of the joints, in the base frame; drop --targets-frame"
            );
        }
        nominal_poses_of(nominal, &options.targets, options.targets_text.as_deref())?
    } else if let Some(text) = &options.targets_text {
        TrackerData::parse_targets(text, &options.targets)?
    } else {
        TrackerData::read_targets(&options.targets)?
    };
    match options.targets_frame {
        TargetsFrame::Tracker => {
            targets_into_base(&mut targets, (params, &options.params), &options.targets)?;
        }
        TargetsFrame::UrBase => {
            // The pendant's base is the DH base turned by a half turn about z.
            let half_turn =
                nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(-1.0, -1.0, 1.0));
            for record in &mut targets.records {
                let [x, y, z] = record.position;
                record.position = [-x, -y, z];
                record.rotation = record.rotation.map(|r| half_turn * r);
            }
        }
        TargetsFrame::Base => {}
    }
    if targets.rows_without_orientation() {
        bail!(
            "{}: targets need an orientation (qw..qz or rx_deg..rz_deg)",
            options.targets.display()
        );
    }
    let joints = nominal.robot.joints.len();
    if targets.joints != 0 && targets.joints != joints {
        bail!(
            "{}: has {} joint columns; give all of q1_deg..q{joints}_deg as start values, or none",
            options.targets.display(),
            targets.joints
        );
    }
    for (name, v) in [
        ("--max-correction-mm", options.max_correction_mm),
        ("--max-correction-deg", options.max_correction_deg),
        (
            "--max-joint-correction-deg",
            options.max_joint_correction_deg,
        ),
    ] {
        if !(v.is_finite() && v > 0.0) {
            bail!("{name} must be a finite number > 0, got {v}");
        }
    }
    let settings = CompensationSettings {
        max_correction_mm: options.max_correction_mm,
        max_correction_rad: options.max_correction_deg.to_radians(),
        max_joint_correction_rad: options.max_joint_correction_deg.to_radians(),
        ..CompensationSettings::default()
    };
    Ok((targets, settings))
}

/// Writes the outcomes (all or nothing) and counts them.
fn finish(
    options: &CompensateOptions,
    outcomes: &[crate::kinematics::compensate::TargetOutcome],
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
    let motion = crate::formats::urscript::Motion {
        speed_rad_s: options.speed_rad_s,
        acceleration_rad_s2: options.acceleration_rad_s2,
        settle_s: 0.0,
    };
    Ok(crate::formats::urscript::movej_program(
        "calib_compensated",
        &header,
        &targets,
        &motion,
    )?)
}
