//! The targets of a compensation and what is asked of it ([`CompensationRequest`]): where the
//! target poses come from (a file, or its text from memory), in which frame, whether they are a
//! program's joint targets, the arm configuration of targets without joints, the largest
//! corrections; and the policy of `calib compensate` that turns a nominal and an identified robot
//! file into one outcome per target ([`CompensationRequest::outcomes`]). `calib compensate` and
//! Python's `compensate` build the same request.

use super::actual::ActualRobot;
use super::compensate::{
    Configuration, Request, TargetOutcome, compensate_targets, compensate_targets_of,
};
use super::configuration::{
    ConfigurationBounds, DEFAULT_MAX_ARM_ANGLE_DEG, DEFAULT_MAX_JOINT_DISTANCE_DEG,
};
use crate::io::robot_file::{CompensationSection, RobotFile, RobotModel};
use crate::io::tracker_data::TrackerData;
use crate::model::controller_model;
use calib_core::controller::compensate::CompensationSettings;
use std::path::{Path, PathBuf};

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

/// The arm configuration of targets without joints, as asked.
#[derive(Clone, Debug, PartialEq)]
pub enum ConfigurationChoice {
    /// That of this posture (joint readings, deg), kept by every target (`--near-deg`).
    NearDeg(Vec<f64>),
    /// A closed-form inverse kinematics branch, 0-7 (`--branch`).
    Branch(usize),
}

/// A compensation asked for: `calib compensate`'s options without the outputs.
#[derive(Clone, Debug, PartialEq)]
pub struct CompensationRequest {
    /// The targets file (`--targets`); with `targets_text`, the name of the targets in messages.
    pub targets: PathBuf,
    /// The targets' text in the format of a targets file, when they come from memory (the Python
    /// package's arrays): parsed instead of reading `targets`.
    pub targets_text: Option<String>,
    /// The frame of the target poses.
    pub frame: TargetsFrame,
    /// The targets are a robot program's joint targets (`q1_deg..qN_deg`, optional id): each the
    /// pose the nominal model puts the tool at, the joints its start and configuration.
    pub joint_targets: bool,
    /// Largest allowed change of the commanded position, mm (above 0).
    pub max_correction_mm: f64,
    /// Largest allowed change of the commanded orientation, deg (above 0).
    pub max_correction_deg: f64,
    /// Largest allowed change of any joint, deg (above 0).
    pub max_joint_correction_deg: f64,
    /// The configuration of targets without joints; `None`: the nominal robot file's
    /// `[compensation]`, if any.
    pub configuration: Option<ConfigurationChoice>,
    /// Compensate targets whose joints leave the range a joint map was identified on (counted)
    /// instead of refusing them.
    pub allow_extrapolation: bool,
    /// On a 7-joint arm, the largest change of the arm angle, deg (0 to 180; default 15).
    pub max_arm_angle_deg: Option<f64>,
    /// On a robot without a closed form, the largest distance of any joint from the posture or
    /// the given joints, deg (0 to 360; default 90).
    pub near_within_deg: Option<f64>,
}

/// The fewest joints that put a tool on a 6-DoF pose.
const MIN_JOINTS: usize = 6;

impl CompensationRequest {
    /// A request for the targets file `targets` with `calib compensate`'s defaults: targets in
    /// the base frame, 5 mm, 0.5 deg and 0.5 rad (in deg) of largest corrections, the robot
    /// file's configuration, no extrapolation.
    pub fn new(targets: PathBuf) -> Self {
        Self {
            targets,
            targets_text: None,
            frame: TargetsFrame::Base,
            joint_targets: false,
            max_correction_mm: 5.0,
            max_correction_deg: 0.5,
            max_joint_correction_deg: 0.5f64.to_degrees(),
            configuration: None,
            allow_extrapolation: false,
            max_arm_angle_deg: None,
            near_within_deg: None,
        }
    }

    /// The outcome of every target for a controller planning with the nominal robot `file` (read
    /// from `robot`) and the identified robot `params` (read from `params_path`; both paths name
    /// them in messages), and the joint count. Errors: what the request or the files cannot do
    /// (fewer than 6 joints, maps in the nominal file, targets of another joint count, bounds
    /// out of range or for a robot they do not bound, ...); a target that cannot be compensated
    /// is an outcome with its reason, not an error.
    pub fn outcomes(
        &self,
        (file, robot): (RobotFile, &Path),
        (params, params_path): (RobotFile, &Path),
    ) -> crate::Result<(Vec<TargetOutcome>, usize)> {
        file.refuse_joint_maps(
            robot,
            "calib compensate's --robot (the nominal model the controller plans with)",
        )?;
        if file.joint.len() < MIN_JOINTS {
            return Err(crate::refused!(unsupported "compensation";
                "{}: compensation puts the tool on 6-DoF target poses (position and orientation), which \
                 takes at least {MIN_JOINTS} joints; this robot has {}, so the identified robot generally \
                 cannot reach a pose its nominal model reaches (calibrate, check, evaluate, verify, fk \
                 and export take it)",
                robot.display(),
                file.joint.len()
            ));
        }
        params.expect_joints(
            params_path,
            file.joint.len(),
            "the nominal robot of --robot",
        )?;
        let actual = ActualRobot::from_file(params.clone(), params_path)?;
        crate::model::counts::joint_count(file.joint.len())?;
        // The readings each non-zero map was identified on.
        let ranges = (params.joint_maps.as_ref())
            .map(crate::model::joint_maps::JointMapsSection::ranges)
            .unwrap_or_default();
        let map_ranges = (0..file.joint.len())
            .map(|j| {
                let mapped = actual.maps.as_ref().is_some_and(|m| !m.is_zero(j));
                ranges.get(j).copied().filter(|_| mapped)
            })
            .collect();
        let request = self.request(map_ranges, file.compensation.as_ref(), robot)?;
        let nominal = file.to_model(robot)?;
        let outcomes =
            self.compensate_with((nominal, &actual), (params_path, &params), &request)?;
        Ok((outcomes, file.joint.len()))
    }

    /// The configuration request for a robot whose joint maps (if any) were identified on
    /// `map_ranges` (rad, per joint; `None` where a joint has no map); without a configuration
    /// asked, the nominal robot file's `[compensation]` default (`robot` names it), if any.
    fn request(
        &self,
        map_ranges: Vec<Option<[f64; 2]>>,
        default: Option<&CompensationSection>,
        robot: &Path,
    ) -> crate::Result<Request> {
        let robot = robot.display();
        let configuration = match (&self.configuration, default) {
            (Some(ConfigurationChoice::NearDeg(posture)), _) => Some(near(posture, "--near-deg")?),
            (Some(ConfigurationChoice::Branch(branch)), _) => Some(Configuration::Branch(*branch)),
            (None, Some(section)) => match (&section.near_deg, section.branch) {
                (Some(posture), None) => {
                    Some(near(posture, &format!("{robot}: [compensation] near_deg"))?)
                }
                (None, Some(branch)) => Some(Configuration::Branch(branch)),
                _ => {
                    return Err(crate::refused!(input robot;
                        "{robot}: [compensation] states the configuration of targets without joints: give near_deg = [...] (a posture, deg) or branch = 0-7, one of them"
                    ));
                }
            },
            (None, None) => None,
        };
        for (flag, value, most) in [
            ("--max-arm-angle-deg", self.max_arm_angle_deg, 180.0),
            ("--near-within-deg", self.near_within_deg, 360.0),
        ] {
            if let Some(v) = value.filter(|v| !(0.0..=most).contains(v)) {
                return Err(crate::refused!(option flag; "{flag} {v}: give 0 to {most} deg"));
            }
        }
        let stated_bounds = [
            ("--near-within-deg", self.near_within_deg.is_some()),
            ("--max-arm-angle-deg", self.max_arm_angle_deg.is_some()),
        ];
        Ok(Request {
            configuration,
            configuration_is_default: self.configuration.is_none(),
            map_ranges,
            allow_extrapolation: self.allow_extrapolation,
            bounds: ConfigurationBounds {
                max_arm_angle_rad: (self.max_arm_angle_deg)
                    .unwrap_or(DEFAULT_MAX_ARM_ANGLE_DEG)
                    .to_radians(),
                max_joint_distance_rad: (self.near_within_deg)
                    .unwrap_or(DEFAULT_MAX_JOINT_DISTANCE_DEG)
                    .to_radians(),
            },
            stated_bounds: (stated_bounds.iter())
                .filter(|(_, given)| *given)
                .map(|(flag, _)| *flag)
                .collect(),
        })
    }

    /// The outcomes for the identified robot `actual` (the file `params`), `nominal` the model
    /// the controller plans with: of its geometry, or, with joint maps or gravity compliance, of
    /// the controller's whole model.
    fn compensate_with(
        &self,
        (nominal, actual): (RobotModel, &ActualRobot),
        params: (&Path, &RobotFile),
        request: &Request,
    ) -> crate::Result<Vec<TargetOutcome>> {
        let (targets, settings) = self.inputs(&nominal, params)?;
        let geometry = &actual.model.robot;
        if actual.maps.is_none() && actual.compliance.is_none() {
            return compensate_targets(&nominal.robot, geometry, &targets, &settings, request);
        }
        let model = controller_model(*geometry, actual.maps.as_ref(), actual.compliance.as_ref())?;
        let real = model.kinematics()?;
        compensate_targets_of(&nominal.robot, &real, &targets, &settings, request)
    }

    /// The targets (through the registration of the identified file `params` for targets in the
    /// tracker's frame; the nominal poses of `nominal` for joint targets) and the settings,
    /// checked.
    fn inputs(
        &self,
        nominal: &RobotModel,
        params: (&Path, &RobotFile),
    ) -> crate::Result<(TrackerData, CompensationSettings<f64>)> {
        let text = self.targets_text.as_deref();
        let mut targets = match (self.joint_targets, text) {
            (true, _) => {
                if self.frame != TargetsFrame::Base {
                    return Err(crate::Error::conflict(
                        &["--joint-targets", "--targets-frame"],
                        "--joint-targets: the targets are the nominal poses of the joints, in the base frame; drop --targets-frame",
                    ));
                }
                nominal_poses_of(nominal, &self.targets, text)?
            }
            (false, Some(text)) => TrackerData::parse_targets(text, &self.targets)?,
            (false, None) => TrackerData::read_targets(&self.targets)?,
        };
        match self.frame {
            TargetsFrame::Tracker => targets_into_base(&mut targets, params, &self.targets)?,
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
            return Err(crate::refused!(input self.targets.display();
                "{}: targets need an orientation (qw..qz or rx_deg..rz_deg)",
                self.targets.display()
            ));
        }
        let joints = nominal.robot.joints.len();
        if targets.joints != 0 && targets.joints != joints {
            return Err(crate::refused!(input self.targets.display();
                "{}: has {} joint columns; give all of q1_deg..q{joints}_deg as start values, or none",
                self.targets.display(),
                targets.joints
            ));
        }
        for (name, v) in [
            ("--max-correction-mm", self.max_correction_mm),
            ("--max-correction-deg", self.max_correction_deg),
            ("--max-joint-correction-deg", self.max_joint_correction_deg),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(crate::refused!(option name;
                    "{name} must be a finite number > 0, got {v}"
                ));
            }
        }
        let settings = CompensationSettings {
            max_correction_mm: self.max_correction_mm,
            max_correction_rad: self.max_correction_deg.to_radians(),
            max_joint_correction_rad: self.max_joint_correction_deg.to_radians(),
            ..CompensationSettings::default()
        };
        Ok((targets, settings))
    }
}

/// Maps targets given in the tracker's frame into the robot's base frame through the registration
/// identified with the `params` file: `T_base = B^-1 T_tracker`, `B` its `[measurement]`
/// section's `tracker_base`. Refused without a registration, and for a target file that says
/// `# frame: base`.
fn targets_into_base(
    targets: &mut TrackerData,
    (params_path, params): (&Path, &RobotFile),
    targets_path: &Path,
) -> crate::Result<()> {
    if targets.base_frame {
        return Err(crate::refused!(input targets_path.display();
            "{}: says '# frame: base', but --targets-frame tracker says the targets are in the tracker's frame; remove one",
            targets_path.display()
        ));
    }
    let Some(measurement) = &params.measurement else {
        return Err(crate::refused!(input "the robot file";
            "{}: has no [measurement] section, the registration of the tracker that --targets-frame tracker maps the targets \
             through: give a file calibrated on data in the tracker's frame, or targets in the base frame",
            params_path.display()
        ));
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

/// The joint targets of the file at `path` (or its `text`) as target poses: each record's
/// position and orientation the nominal model's pose at its joints, in the base frame; its
/// joints stay as the start. Joints outside the nominal model's limits are refused with the line.
fn nominal_poses_of(
    nominal: &RobotModel,
    path: &Path,
    text: Option<&str>,
) -> crate::Result<TrackerData> {
    let profile = crate::io::profile::DataProfile::default();
    let mut targets = match text {
        Some(text) => TrackerData::parse_joints(text, path, &profile)?,
        None => TrackerData::read_joints(path, &profile)?,
    };
    let joints = nominal.robot.joints.len();
    if targets.joints != joints {
        return Err(crate::refused!(input path.display();
            "{}: has {} joint columns, the robot {} has {joints} joints",
            path.display(),
            targets.joints,
            nominal.path.display()
        ));
    }
    let kinematics = calib_core::Kinematics::nominal(&nominal.robot)?;
    for record in &mut targets.records {
        let q = calib_core::model::JointVec::from_slice(&record.q).ok_or_else(
            || crate::refused!(input path.display(); "{}: more than 9 joints", path.display()),
        )?;
        if let Some(outside) = nominal.outside_limits(&record.q) {
            return Err(crate::refused!(input path.display();
                "{}:{}: {outside}",
                path.display(),
                record.line
            ));
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
fn near(deg: &[f64], what: &str) -> crate::Result<Configuration> {
    if let Some(v) = deg.iter().find(|v| !v.is_finite()) {
        return Err(crate::refused!(option what; "{what}: {v} is not a finite angle"));
    }
    let Some(q) = calib_core::model::JointVec::from_slice(
        &deg.iter().map(|v| v.to_radians()).collect::<Vec<_>>(),
    ) else {
        return Err(crate::refused!(option what;
            "{what} has {} values; at most 9 joints",
            deg.len()
        ));
    };
    Ok(Configuration::Near(q))
}
