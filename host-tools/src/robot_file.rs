//! The robot model file (TOML, DESIGN.md): nominal MDH joints in mm and degrees, optional joint
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
//! identify = ["a", "alpha", "theta", "d"]   # optional, default: the rule of DESIGN.md
//! [base]                              # optional, default identity
//! xyz_mm = [0.0, 0.0, 0.0]
//! rpy_deg = [0.0, 0.0, 0.0]           # R = Rz(yaw) Ry(pitch) Rx(roll)
//! ```

use calib_core::{
    FramePose, JointLimits, JointParameter, MdhJoint, Parameter, ParameterMask, Robot,
};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Why a robot file could not be used. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum RobotFileError {
    /// The file could not be read.
    #[error("{path}: cannot read the robot file: {source}")]
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
    pub limits_deg: Option<[f64; 2]>,
    /// Parameters to identify, from `a`, `d`, `alpha`, `beta`, `theta` (default: DESIGN.md rule).
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
    /// Joints, joint 1 first.
    pub joint: Vec<JointEntry>,
    /// Base frame (default identity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<FrameEntry>,
    /// Tool frame (default identity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool: Option<FrameEntry>,
}

/// A robot file checked and converted to the core's units (mm, rad).
#[derive(Clone, Debug, PartialEq)]
pub struct RobotModel<const N: usize> {
    /// Human-readable robot name.
    pub name: String,
    /// The file it came from.
    pub path: PathBuf,
    /// Nominal model in mm and rad.
    pub robot: Robot<f64, N>,
    /// Identification mask: the file's `identify` lists, or the default rule.
    pub mask: ParameterMask<N>,
}

impl RobotFile {
    /// Reads and parses a robot file.
    pub fn read(path: &Path) -> Result<Self, RobotFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| RobotFileError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses robot-file text; `path` only names the source in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, RobotFileError> {
        toml::from_str(text).map_err(|e| RobotFileError::Parse {
            path: path.to_owned(),
            message: e.to_string().trim_end().to_owned(),
        })
    }

    /// Checks the content and converts it for a robot of `N` joints.
    pub fn to_model<const N: usize>(&self, path: &Path) -> Result<RobotModel<N>, RobotFileError> {
        let invalid = |message: String| RobotFileError::Invalid {
            path: path.to_owned(),
            message,
        };
        if self.joint.len() != N {
            return Err(invalid(format!(
                "has {} [[joint]] tables, expected {N} (this tool handles {N}-joint robots)",
                self.joint.len()
            )));
        }
        let deg = f64::to_radians;
        let mut joints = [MdhJoint {
            a: 0.0,
            alpha: 0.0,
            theta_offset: 0.0,
            d: 0.0,
            beta: 0.0,
        }; N];
        let mut limits = [JointLimits::<f64>::unlimited(); N];
        for (i, (entry, (joint, limit))) in self
            .joint
            .iter()
            .zip(joints.iter_mut().zip(limits.iter_mut()))
            .enumerate()
        {
            let number = i + 1;
            let fields = [
                ("a_mm", entry.a_mm),
                ("alpha_deg", entry.alpha_deg),
                ("theta_offset_deg", entry.theta_offset_deg),
                ("d_mm", entry.d_mm),
                ("beta_deg", entry.beta_deg),
            ];
            if let Some((field, value)) = fields.iter().find(|(_, v)| !v.is_finite()) {
                return Err(invalid(format!(
                    "joint {number}: {field} = {value} is not a finite number"
                )));
            }
            *joint = MdhJoint {
                a: entry.a_mm,
                alpha: deg(entry.alpha_deg),
                theta_offset: deg(entry.theta_offset_deg),
                d: entry.d_mm,
                beta: deg(entry.beta_deg),
            };
            if let Some([lower, upper]) = entry.limits_deg {
                if lower.is_nan() || upper.is_nan() || lower > upper {
                    return Err(invalid(format!(
                        "joint {number}: limits_deg = [{lower}, {upper}] must be [lower, upper] with lower <= upper"
                    )));
                }
                *limit = JointLimits {
                    lower: deg(lower),
                    upper: deg(upper),
                };
            }
        }
        let frame =
            |entry: &Option<FrameEntry>, which: &str| -> Result<FramePose<f64>, RobotFileError> {
                let Some(entry) = entry else {
                    return Ok(FramePose::identity());
                };
                if entry
                    .xyz_mm
                    .iter()
                    .chain(&entry.rpy_deg)
                    .any(|v| !v.is_finite())
                {
                    return Err(invalid(format!(
                        "[{which}]: xyz_mm and rpy_deg must be finite numbers"
                    )));
                }
                Ok(FramePose {
                    xyz: entry.xyz_mm,
                    rpy: entry.rpy_deg.map(deg),
                })
            };
        let robot = Robot {
            joints,
            limits,
            base: frame(&self.base, "base")?,
            tool: frame(&self.tool, "tool")?,
        };
        robot.validate().map_err(|e| invalid(e.to_string()))?;
        let mut mask = ParameterMask::default_for(&robot);
        for (i, entry) in self.joint.iter().enumerate() {
            let Some(names) = &entry.identify else {
                continue;
            };
            let joint = u8::try_from(i + 1).map_err(|_| invalid("too many joints".into()))?;
            for kind in JointParameter::ALL {
                mask.set(Parameter::Joint { joint, kind }, false);
            }
            for name in names {
                let kind = JointParameter::ALL
                    .into_iter()
                    .find(|k| k.name() == name)
                    .ok_or_else(|| {
                        invalid(format!(
                            "joint {}: identify: unknown parameter \"{name}\", expected one of a, d, alpha, beta, theta",
                            i + 1
                        ))
                    })?;
                mask.set(Parameter::Joint { joint, kind }, true);
            }
        }
        Ok(RobotModel {
            name: self.name.clone(),
            path: path.to_owned(),
            robot,
            mask,
        })
    }
}

impl<const N: usize> RobotModel<N> {
    /// Reads, checks and converts the robot file at `path`.
    pub fn load(path: &Path) -> Result<Self, RobotFileError> {
        RobotFile::read(path)?.to_model(path)
    }
}
