//! The robot model file (TOML, docs/ARCHITECTURE.md): nominal MDH joints in mm and degrees, optional joint
//! limits and identification lists, optional base and tool frames.
//!
//! ```toml
//! name = "Efort ER10L-C10"
//! [[joint]]
//! a_mm = 170.0
//! alpha_deg = -90.0
//! theta_offset_deg = 0.0
//! d_mm = 0.0
//! beta_deg = 0.0                      # optional, default 0
//! limits_deg = [-170.0, 170.0]        # optional, default unlimited
//! identify = ["a", "alpha", "theta", "d"]   # optional, default: the rule of docs/ARCHITECTURE.md
//! [base]                              # optional, default identity
//! xyz_mm = [0.0, 0.0, 0.0]
//! rpy_deg = [0.0, 0.0, 0.0]           # R = Rz(yaw) Ry(pitch) Rx(roll)
//! ```
//!
//! A robot published in Craig's modified DH convention is written as it is published, with
//! `[[craig_joint]]` tables (`alpha_prev_deg`, `a_prev_mm`, `d_mm`, `theta_offset_deg`, and the
//! optional `limits_deg` and `identify`) and an optional `[craig_flange]` row instead of
//! `[[joint]]`; reading converts it exactly into our joints and frames ([`craig`]), and
//! files written back (identified robots) are in our convention.

use calib_core::model::JointCount;
use calib_core::{
    FramePose, JointLimits, JointParameter, MdhJoint, Parameter, ParameterErrors, ParameterMask,
    Robot,
};
use nalgebra::{Dim, Dyn};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub mod craig;

/// The nominal Efort ER10L-C10 of the paper (Table 1), as the robot file `robots/er10l-c10.toml`.
pub const ER10L_C10_TOML: &str = include_str!("../../robots/er10l-c10.toml");

/// Largest length accepted in a robot file (`a_mm`, `d_mm`, frame `xyz_mm`), mm: 100 m, beyond
/// any serial robot and any laser tracker's range. A larger value is a typing or unit error.
pub(crate) const MAX_LENGTH_MM: f64 = 100_000.0;

/// Largest angle accepted in a robot file (`alpha_deg`, `beta_deg`, `theta_offset_deg`, frame
/// `rpy_deg`), degrees: one turn each way.
pub(crate) const MAX_ANGLE_DEG: f64 = 360.0;

/// Largest joint limit accepted in a robot file (`limits_deg`), degrees: ten turns each way.
pub(crate) const MAX_LIMIT_DEG: f64 = 3600.0;

/// `Err` naming `field` when `value` is not finite or beyond `max` in magnitude (`unit` is the
/// field's unit, for the message).
fn plausible(field: &str, value: f64, max: f64, unit: &str) -> Result<(), String> {
    if !value.is_finite() {
        return Err(format!("{field} = {value} is not a finite number"));
    }
    if value.abs() > max {
        let shown = if value.abs() < 1e9 {
            value.to_string()
        } else {
            format!("{value:e}")
        };
        return Err(format!(
            "{field} = {shown} is beyond the plausible range of +-{max} {unit}; check the value and its unit"
        ));
    }
    Ok(())
}

/// Why a robot file could not be used. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum RobotFileError {
    /// The file could not be read.
    #[error("{path}: cannot read the robot file")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The TOML is malformed, has an unknown key, misses a field or has a wrong type.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message with line, column and the field.
        message: String,
    },
    /// The content is well-formed but not a valid model (joint count, values, names).
    #[error("{path}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong, naming the field.
        message: String,
    },
}

/// A joint of the robot file (mm, degrees).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct JointEntry {
    /// Link length, mm.
    pub a_mm: f64,
    /// Link twist, degrees.
    pub alpha_deg: f64,
    /// Joint zero offset, degrees.
    pub theta_offset_deg: f64,
    /// Link offset, mm.
    pub d_mm: f64,
    /// Hayati twist about y, degrees (default 0).
    #[serde(default)]
    pub beta_deg: f64,
    /// `[lower, upper]` joint limits, degrees (default: unlimited).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limits_deg: Option<Vec<f64>>,
    /// Parameters to identify, from `a`, `d`, `alpha`, `beta`, `theta` (default: the rule of docs/ARCHITECTURE.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identify: Option<Vec<String>>,
}

/// A base or tool frame of the robot file (mm, degrees).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FrameEntry {
    /// Translation, mm.
    pub xyz_mm: [f64; 3],
    /// `[roll, pitch, yaw]`, degrees, `R = Rz(yaw) Ry(pitch) Rx(roll)`.
    pub rpy_deg: [f64; 3],
}

/// The robot file as written on disk.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RobotFile {
    /// Human-readable robot name.
    pub name: String,
    /// The robot's serial number, stated on its calibration certificate. Optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub serial: Option<String>,
    /// The manufacturer's pose repeatability (ISO 9283), mm: how closely the robot returns to a
    /// commanded pose. No model fits the robot better than it repeats: the plausibility check of
    /// a calibration allows a fit of twice this (at least 2 mm RMS). Optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repeatability_mm: Option<f64>,
    /// The largest geometric length error (mm) a calibration of this robot may identify before
    /// it is refused as implausible; default 20 mm. Optional, at most 100 mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_length_error_mm: Option<f64>,
    /// The largest geometric angle error (deg) a calibration of this robot may identify before it
    /// is refused as implausible; default 3 deg. Optional, at most 10 deg: an arm built to looser
    /// tolerances (cable drives) says so here, with its reason.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_angle_error_deg: Option<f64>,
    /// Joints, joint 1 first (after reading, also those converted from `[[craig_joint]]`).
    #[serde(default)]
    pub joint: Vec<JointEntry>,
    /// Joints in Craig's modified DH convention, as published; [`RobotFile::parse`] converts
    /// them into `joint`, `base` and `tool` and leaves this empty.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub craig_joint: Vec<craig::CraigJointEntry>,
    /// The fixed row after the last Craig joint (a flange), converted with `craig_joint`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub craig_flange: Option<craig::CraigFlangeEntry>,
    /// Base frame (default identity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<FrameEntry>,
    /// Tool frame (default identity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool: Option<FrameEntry>,
    /// Present in a file of identified (or simulated true) parameters: the errors that were added
    /// to the nominal model to give the values above.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<CalibrationSection>,
    /// Present in a file identified from data in a tracker's frame: the measurement setup found
    /// with the geometry. Informational: the model (export, compensate, the controller) uses
    /// `[base]` and `[tool]`, the controller's own frames.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measurement: Option<MeasurementSection>,
    /// Present in a file identified with `calib calibrate --model joint-maps`: each joint's
    /// angle-error map, part of the model (see [`crate::model::joint_maps`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_maps: Option<crate::model::joint_maps::JointMapsSection>,
    /// Link masses and centres of mass, the measured load and gravity (see
    /// [`crate::model::compliance`]): needed by `calibrate --model joint-maps+compliance`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dynamics: Option<crate::model::compliance::DynamicsSection>,
    /// Present in a file identified with `--model joint-maps+compliance`: the gravity compliance
    /// gains, part of the model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compliance: Option<crate::model::compliance::ComplianceSection>,
    /// The arm configuration `calib compensate` gives targets without joints when no option
    /// names one (`[compensation] near_deg = [...]` or `branch = B`). Optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compensation: Option<CompensationSection>,
}

/// The arm configuration of targets without joints, stated once for a robot (its home, say):
/// either a posture whose configuration they keep or a closed-form branch.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CompensationSection {
    /// A posture (deg, one value per joint) whose configuration targets keep, as `--near-deg`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub near_deg: Option<Vec<f64>>,
    /// A closed-form branch 0-7, as `--branch`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub branch: Option<usize>,
}

/// The measurement setup identified with the geometry: where the tracker saw the robot's base,
/// and the reflector or probe on the flange. Not part of the robot's model.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MeasurementSection {
    /// The frames identified (`base` or `base+tool`).
    pub frames: String,
    /// The robot's base frame in the tracker's frame (mm, degrees).
    pub tracker_base: FrameEntry,
    /// The reflector or probe on the flange (mm, degrees), when identified.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flange_tool: Option<FrameEntry>,
    /// When the frames were registered (RFC 3339, UTC).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub registered_at: Option<String>,
    /// A re-registration (`calib calibrate --identify frames`): the robot file whose geometry was
    /// kept (its `[calibration]` says where that geometry came from).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geometry_from: Option<crate::io::provenance::InputFile>,
    /// The files the frames were registered from, with their SHA-256.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inputs: Vec<crate::io::provenance::InputFile>,
}

/// The errors behind a file of identified parameters. Units follow the parameter: mm for `da`,
/// `dd` and frame translations, rad for `dalpha`, `dbeta`, `dtheta` and frame rotations.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationSection {
    /// How the values were obtained (`ipso`, `simulated truth`, ...).
    pub method: String,
    /// The nominal robot file the errors were added to.
    pub nominal: String,
    /// Error of each parameter (name -> mm or rad), in canonical order when written.
    pub errors: toml::Table,
    /// Standard error of each identified parameter (mm or rad), when known.
    #[serde(default, skip_serializing_if = "toml::Table::is_empty")]
    pub std_errors: toml::Table,
    /// When the geometry was identified (RFC 3339, UTC), for files written by `calib calibrate`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibrated_at: Option<String>,
    /// The files the geometry was identified from (nominal robot file, data, profile, held-out
    /// data), with their SHA-256, for files written by `calib calibrate`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inputs: Vec<crate::io::provenance::InputFile>,
    /// The identified parameters' covariance from least squares, the frames of the measurement
    /// setup included (`calib uncertainty` propagates it to any pose).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<CovarianceEntry>,
}

/// A covariance in a robot file: the parameters (rows and columns, in order) and the matrix by
/// rows, in their units (mm, rad) squared and crossed.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CovarianceEntry {
    /// Parameter names (`da2`, `dtheta3`, ...).
    pub parameters: Vec<String>,
    /// The matrix by rows.
    pub matrix: Vec<Vec<f64>>,
}

/// A robot file checked and converted to the core's units (mm, rad).
#[derive(Clone, Debug, PartialEq)]
pub struct RobotModel {
    /// Human-readable robot name.
    pub name: String,
    /// The file it came from.
    pub path: PathBuf,
    /// Nominal model in mm and rad.
    pub robot: Robot<f64, Dyn>,
    /// Identification mask: the file's `identify` lists, or the default rule.
    pub mask: ParameterMask<Dyn>,
}

impl RobotFile {
    /// Reads and parses a robot file.
    pub fn read(path: &Path) -> Result<Self, RobotFileError> {
        let text = crate::io::input::read_text(path, crate::io::input::Input::Document).map_err(
            |source| RobotFileError::Read {
                path: path.to_owned(),
                source,
            },
        )?;
        Self::parse(&text, path)
    }

    /// Parses robot-file text; `path` only names the source in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, RobotFileError> {
        let mut file: Self = toml::from_str(text).map_err(|e| RobotFileError::Parse {
            path: path.to_owned(),
            message: e.to_string().trim_end().to_owned(),
        })?;
        let invalid = |message: &str| RobotFileError::Invalid {
            path: path.to_owned(),
            message: message.to_owned(),
        };
        if !file.craig_joint.is_empty() {
            if !file.joint.is_empty() {
                return Err(invalid(
                    "has both [[joint]] and [[craig_joint]] tables: describe the robot in one \
                     convention (standard DH in [[joint]], Craig's modified DH in [[craig_joint]])",
                ));
            }
            craig::check(&file.craig_joint, file.craig_flange.as_ref()).map_err(|m| invalid(&m))?;
            let (joints, base, tool) = craig::to_standard(
                &file.craig_joint,
                file.craig_flange.as_ref(),
                file.base.as_ref(),
                file.tool.as_ref(),
            );
            (file.joint, file.base, file.tool) = (joints, base, tool);
            file.craig_joint.clear();
            file.craig_flange = None;
        } else if file.craig_flange.is_some() {
            return Err(invalid(
                "has a [craig_flange] without [[craig_joint]] tables: the flange row belongs to a \
                 robot described in Craig's convention",
            ));
        } else if file.joint.is_empty() {
            return Err(invalid(
                "has no joints: add a [[joint]] table per joint (or [[craig_joint]] tables for \
                 Craig's modified DH convention)",
            ));
        }
        for (name, value, most) in [
            ("repeatability_mm", file.repeatability_mm, 20.0),
            ("max_length_error_mm", file.max_length_error_mm, 100.0),
            ("max_angle_error_deg", file.max_angle_error_deg, 10.0),
        ] {
            if let Some(v) = value
                && !(v.is_finite() && v > 0.0 && v <= most)
            {
                return Err(invalid(&format!(
                    "{name} = {v} is out of range: give a value above 0 and at most {most}"
                )));
            }
        }
        Ok(file)
    }

    /// The joint count, checked against what the tool handles ([`crate::model::counts::JOINT_COUNTS`]).
    pub fn joint_count(&self, path: &Path) -> Result<Dyn, RobotFileError> {
        let joints = self.joint.len();
        crate::model::counts::joint_count(joints).map_err(|_| RobotFileError::Invalid {
            path: path.to_owned(),
            message: format!(
                "has {joints} [[joint]] tables; calib handles robots of {} to {} joints",
                crate::model::counts::JOINT_COUNTS.start(),
                crate::model::counts::JOINT_COUNTS.end()
            ),
        })
    }

    /// `Ok` when the file describes a robot of `joints` joints, the robot it goes with (`robot`
    /// names it in the error, e.g. "the robot calibrated"): the joint count is each file's own,
    /// so two files used together are checked against each other.
    pub fn expect_joints(
        &self,
        path: &Path,
        joints: usize,
        robot: &str,
    ) -> Result<(), RobotFileError> {
        if self.joint.len() == joints {
            return Ok(());
        }
        Err(RobotFileError::Invalid {
            path: path.to_owned(),
            message: format!(
                "has {} [[joint]] tables, expected {joints} ({robot} has {joints} joints)",
                self.joint.len()
            ),
        })
    }

    /// Checks the content and converts it to the core's model (mm, rad).
    pub fn to_model(&self, path: &Path) -> Result<RobotModel, RobotFileError> {
        let invalid = |message: String| RobotFileError::Invalid {
            path: path.to_owned(),
            message,
        };
        let count = self.joint_count(path)?;
        let mut joints = count.table(MdhJoint {
            a: 0.0,
            alpha: 0.0,
            theta_offset: 0.0,
            d: 0.0,
            beta: 0.0,
        });
        let mut limits = count.table(JointLimits::<f64>::unlimited());
        for (i, (entry, (joint, limit))) in self
            .joint
            .iter()
            .zip(joints.iter_mut().zip(limits.iter_mut()))
            .enumerate()
        {
            (*joint, *limit) = entry.to_joint(i + 1).map_err(invalid)?;
        }
        let robot = Robot {
            joints,
            limits,
            base: frame_pose(self.base.as_ref(), "base").map_err(invalid)?,
            tool: frame_pose(self.tool.as_ref(), "tool").map_err(invalid)?,
        };
        robot.validate().map_err(|e| invalid(e.to_string()))?;
        // The errors a file of identified parameters lists: numbers within the joints' own
        // bounds, so that a file is never written on from a section it could not stand behind.
        self.calibration_errors(path)?;
        if let Some(maps) = &self.joint_maps {
            maps.to_maps(count.value()).map_err(invalid)?;
        }
        if let Some(dynamics) = &self.dynamics {
            dynamics.to_gravity(count.value()).map_err(invalid)?;
        }
        if let Some(compliance) = &self.compliance {
            compliance.to_gains(count.value()).map_err(invalid)?;
            if self.dynamics.is_none() {
                return Err(invalid(
                    "[compliance] needs the [dynamics] it was identified with".to_string(),
                ));
            }
        }
        let mask = self.mask(&robot).map_err(invalid)?;
        Ok(RobotModel {
            name: self.name.clone(),
            path: path.to_owned(),
            robot,
            mask,
        })
    }

    /// The identification mask: the default rule, replaced per joint by its `identify` list.
    fn mask(&self, robot: &Robot<f64, Dyn>) -> Result<ParameterMask<Dyn>, String> {
        let mut mask = ParameterMask::default_for(robot);
        for (i, entry) in self.joint.iter().enumerate() {
            let Some(names) = &entry.identify else {
                continue;
            };
            let joint = u8::try_from(i + 1).map_err(|_| "too many joints".to_string())?;
            for kind in JointParameter::ALL {
                mask.set(Parameter::Joint { joint, kind }, false);
            }
            for name in names {
                let kind = JointParameter::ALL
                    .into_iter()
                    .find(|k| k.name() == name)
                    .ok_or_else(|| {
                        format!(
                            "joint {}: identify: unknown parameter \"{name}\", expected one of a, d, alpha, beta, theta",
                            i + 1
                        )
                    })?;
                mask.set(Parameter::Joint { joint, kind }, true);
            }
        }
        Ok(mask)
    }
}

impl JointEntry {
    /// The joint (mm, rad) and its limits; `number` (1-based) names it in errors.
    fn to_joint(&self, number: usize) -> Result<(MdhJoint<f64>, JointLimits<f64>), String> {
        let deg = f64::to_radians;
        let fields = [
            ("a_mm", self.a_mm, MAX_LENGTH_MM, "mm"),
            ("alpha_deg", self.alpha_deg, MAX_ANGLE_DEG, "deg"),
            (
                "theta_offset_deg",
                self.theta_offset_deg,
                MAX_ANGLE_DEG,
                "deg",
            ),
            ("d_mm", self.d_mm, MAX_LENGTH_MM, "mm"),
            ("beta_deg", self.beta_deg, MAX_ANGLE_DEG, "deg"),
        ];
        for (field, value, max, unit) in fields {
            plausible(field, value, max, unit).map_err(|m| format!("joint {number}: {m}"))?;
        }
        let joint = MdhJoint {
            a: self.a_mm,
            alpha: deg(self.alpha_deg),
            theta_offset: deg(self.theta_offset_deg),
            d: self.d_mm,
            beta: deg(self.beta_deg),
        };
        let limits = match self.limits_deg.as_deref() {
            None => JointLimits::unlimited(),
            Some(&[lower, upper]) => {
                for value in [lower, upper] {
                    plausible("limits_deg", value, MAX_LIMIT_DEG, "deg")
                        .map_err(|m| format!("joint {number}: {m}"))?;
                }
                if lower > upper {
                    return Err(format!(
                        "joint {number}: limits_deg = [{lower}, {upper}] must be [lower, upper] with lower <= upper"
                    ));
                }
                JointLimits {
                    lower: deg(lower),
                    upper: deg(upper),
                }
            }
            Some(other) => {
                return Err(format!(
                    "joint {number}: limits_deg has {} values, expected two: [lower, upper] in degrees",
                    other.len()
                ));
            }
        };
        Ok((joint, limits))
    }
}

impl FrameEntry {
    /// The frame as an isometry (mm, `R = Rz(yaw) Ry(pitch) Rx(roll)`).
    pub fn isometry(&self) -> nalgebra::Isometry3<f64> {
        let [roll, pitch, yaw] = self.rpy_deg.map(f64::to_radians);
        nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::from(nalgebra::Vector3::from(self.xyz_mm)),
            nalgebra::UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        )
    }
}

/// A `[base]` or `[tool]` table as a frame (mm, rad); absent: identity.
fn frame_pose(entry: Option<&FrameEntry>, which: &str) -> Result<FramePose<f64>, String> {
    let Some(entry) = entry else {
        return Ok(FramePose::identity());
    };
    for value in entry.xyz_mm {
        plausible("xyz_mm", value, MAX_LENGTH_MM, "mm").map_err(|m| format!("[{which}]: {m}"))?;
    }
    for value in entry.rpy_deg {
        plausible("rpy_deg", value, MAX_ANGLE_DEG, "deg").map_err(|m| format!("[{which}]: {m}"))?;
    }
    Ok(FramePose {
        xyz: entry.xyz_mm,
        rpy: entry.rpy_deg.map(f64::to_radians),
    })
}

impl RobotFile {
    /// The model as the tracker saw it: `[base]` and `[tool]` replaced by the `[measurement]`
    /// section's tracker base and flange tool (when the file has one), to compare the model with
    /// the data it was identified from. Not a model for the controller.
    pub fn in_measurement_setup(&self) -> Self {
        let mut out = self.clone();
        if let Some(m) = &self.measurement {
            out.base = Some(m.tracker_base.clone());
            if m.flange_tool.is_some() {
                out.tool = m.flange_tool.clone();
            }
        }
        out.measurement = None;
        out
    }
}

impl RobotFile {
    /// The joint maps of the file (`[joint_maps]`), checked; `None` without them.
    pub fn joint_maps(
        &self,
        path: &Path,
    ) -> Result<Option<crate::model::joint_maps::JointMaps>, RobotFileError> {
        self.joint_maps
            .as_ref()
            .map(|m| {
                m.to_maps(self.joint.len())
                    .map_err(|message| RobotFileError::Invalid {
                        path: path.to_owned(),
                        message,
                    })
            })
            .transpose()
    }

    /// The gravity compliance of the file of a robot of `joints` joints (`[compliance]` with the
    /// `[dynamics]` it was identified with), checked; `None` without it.
    pub fn gravity_compliance(
        &self,
        path: &Path,
        joints: usize,
    ) -> Result<Option<crate::model::compliance::FileCompliance>, RobotFileError> {
        let invalid = |message: String| RobotFileError::Invalid {
            path: path.to_owned(),
            message,
        };
        let Some(section) = &self.compliance else {
            return Ok(None);
        };
        let Some(dynamics) = &self.dynamics else {
            return Err(invalid(
                "[compliance] needs the [dynamics] it was identified with".to_string(),
            ));
        };
        Ok(Some(crate::model::compliance::FileCompliance {
            gravity: dynamics.to_gravity(joints).map_err(invalid)?,
            gains: section.to_gains(joints).map_err(invalid)?,
        }))
    }

    /// Refuses a file with gravity compliance for `what` (a command that cannot apply it:
    /// `simulate`), so that no result silently leaves it out.
    pub fn refuse_compliance(&self, path: &Path, what: &str) -> crate::Result<()> {
        if self.compliance.is_some() {
            return Err(crate::refused!(unsupported "gravity compliance";
                "{}: this robot file has gravity compliance ([compliance], from calibrate --model joint-maps+compliance), \
                 which {what} cannot apply yet; leaving it out would make the result silently less accurate. \
                 Use a file without it here (calibrate --model geometric or joint-maps)",
                path.display()
            ));
        }
        Ok(())
    }

    /// Refuses a file with joint maps for `what` (a command or an output that cannot apply them
    /// yet), so that no result silently leaves the maps out.
    pub fn refuse_joint_maps(&self, path: &Path, what: &str) -> crate::Result<()> {
        if self.joint_maps.is_some() {
            return Err(crate::refused!(unsupported "joint maps";
                "{}: this robot file has joint maps ([joint_maps], from calibrate --model joint-maps), \
                 which {what} cannot apply yet; leaving them out would make the result silently less accurate. \
                 Use the geometric calibration's file (calibrate --model geometric) here",
                path.display()
            ));
        }
        Ok(())
    }
}

impl RobotModel {
    /// Reads, checks and converts the robot file at `path`.
    pub fn load(path: &Path) -> Result<Self, RobotFileError> {
        RobotFile::read(path)?.to_model(path)
    }

    /// The first of the joint readings `q` (rad) outside this robot's limits, in words: `q3 =
    /// 400.0000 deg is outside the joint limits [-360, 360] deg of FILE`; `None` when all are
    /// within.
    pub fn outside_limits(&self, q: &[f64]) -> Option<String> {
        let (j, (q, l)) =
            (q.iter().zip(&self.robot.limits).enumerate()).find(|(_, (q, l))| !l.contains(**q))?;
        Some(format!(
            "q{} = {:.4} deg is outside the joint limits [{}, {}] deg of {}",
            j + 1,
            q.to_degrees(),
            l.lower.to_degrees(),
            l.upper.to_degrees(),
            self.path.display()
        ))
    }
}

impl RobotFile {
    /// The errors of the `[calibration]` section for the file's robot (zero when absent); [`RobotFile::expect_joints`] checks it against another robot's.
    pub fn calibration_errors(
        &self,
        path: &Path,
    ) -> Result<ParameterErrors<f64, Dyn>, RobotFileError> {
        let count = self.joint_count(path)?;
        let mut errors = ParameterErrors::zeros_for(count);
        let Some(section) = &self.calibration else {
            return Ok(errors);
        };
        for (name, value) in &section.errors {
            let invalid = |message: String| RobotFileError::Invalid {
                path: path.to_owned(),
                message,
            };
            let parameter = Parameter::from_name(name, count.value()).ok_or_else(|| {
                invalid(format!(
                    "[calibration.errors]: unknown parameter \"{name}\""
                ))
            })?;
            let value = value
                .as_float()
                .or_else(|| value.as_integer().map(|i| i as f64))
                .ok_or_else(|| invalid(format!("[calibration.errors]: {name} must be a number")))?;
            let (max, unit) = if parameter.is_angle() {
                (MAX_ANGLE_DEG.to_radians(), "rad")
            } else {
                (MAX_LENGTH_MM, "mm")
            };
            plausible(name, value, max, unit)
                .map_err(|m| invalid(format!("[calibration.errors]: {m}")))?;
            errors.set(parameter, value);
        }
        Ok(errors)
    }

    /// The file of the actual robot `nominal + errors`: every joint value, base and tool replaced
    /// by the actual one, and a `[calibration]` section listing the errors (all errors of the
    /// `listed` parameters, in canonical order) and their standard errors.
    pub fn with_errors(
        &self,
        errors: &ParameterErrors<f64, Dyn>,
        listed: impl IntoIterator<Item = Parameter>,
        std_errors: &[(Parameter, f64)],
        method: &str,
        nominal: &str,
    ) -> Self {
        let mut out = self.clone();
        out.measurement = None;
        for (entry, e) in out.joint.iter_mut().zip(&errors.joints) {
            entry.a_mm += e.da;
            entry.alpha_deg += e.dalpha.to_degrees();
            entry.theta_offset_deg += e.dtheta.to_degrees();
            entry.d_mm += e.dd;
            entry.beta_deg += e.dbeta.to_degrees();
        }
        let frame =
            |entry: &Option<FrameEntry>, e: &calib_core::FrameErrors<f64>| -> Option<FrameEntry> {
                if e.translation == [0.0; 3] && e.rotation == [0.0; 3] {
                    return entry.clone();
                }
                let (xyz, rpy) = entry.as_ref().map_or(([0.0; 3], [0.0; 3]), |f| {
                    (f.xyz_mm, f.rpy_deg.map(f64::to_radians))
                });
                let nominal = nalgebra::Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]);
                let [rx, ry, rz] = e.rotation;
                let (roll, pitch, yaw) =
                    (nominal * nalgebra::Rotation3::from_euler_angles(rx, ry, rz)).euler_angles();
                Some(FrameEntry {
                    xyz_mm: [
                        xyz[0] + e.translation[0],
                        xyz[1] + e.translation[1],
                        xyz[2] + e.translation[2],
                    ],
                    rpy_deg: [roll, pitch, yaw].map(f64::to_degrees),
                })
            };
        out.base = frame(&self.base, &errors.base);
        out.tool = frame(&self.tool, &errors.tool);
        let mut table = toml::Table::new();
        for p in listed {
            table.insert(
                p.to_string(),
                toml::Value::Float(errors.get(p).unwrap_or(0.0)),
            );
        }
        let mut std_table = toml::Table::new();
        for (p, s) in std_errors {
            std_table.insert(p.to_string(), toml::Value::Float(*s));
        }
        out.calibration = Some(CalibrationSection {
            method: method.to_string(),
            nominal: nominal.to_string(),
            errors: table,
            std_errors: std_table,
            calibrated_at: None,
            inputs: Vec::new(),
            covariance: None,
        });
        out
    }

    /// The file as TOML text, with a comment header.
    pub fn to_toml(&self, comment: &str) -> String {
        let body = toml::to_string(self).unwrap_or_default();
        let mut text = String::new();
        for line in comment.lines() {
            text.push_str("# ");
            text.push_str(&super::text::one_line(line));
            text.push('\n');
        }
        text.push_str(&body);
        text
    }
}
