//! "Is the right calibration on the controller?" (`calib registry verify`, issue 55 item 5): a
//! controller's parameter block (`calib export --format block`, read back from the controller)
//! or a robot file checked against the robot's registered calibrations.
//!
//! The answer, in the order a technician needs it: the file is byte for byte one the registry
//! holds (its SHA-256 is a record's block or identified file); else it holds the model of a
//! record (each record's identified file exported as a block of the same scalar type and
//! sequence number, or for a robot file as double-precision blocks of both, compared byte for
//! byte: geometry, limits, frames, joint maps and compliance); else it holds none, and the
//! nearest record is named with every value that differs and what the difference moves the tool
//! by over the workspace. It passes only when the match is the robot's latest calibration: a
//! match to an older one names the newer.

use super::record::{Record, sha256};
use crate::formats::export::{BlockScalar, ExportFormat, ExportRequest};
use crate::io::robot_file::RobotFile;
use calib_core::controller::storage::{self, StorageError};
use calib_core::{Kinematics, Real, Robot};
use nalgebra::Dyn;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Configurations the movement between a controller's model and the nearest record's is
/// computed at.
pub const POSES: usize = 1000;

/// What is checked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Given {
    /// A controller's parameter block.
    Block(PathBuf),
    /// A robot file.
    Robot(PathBuf),
}

/// How the given file matches a record.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Match {
    /// The record's number.
    pub id: i64,
    /// When it was calibrated.
    pub calibrated_at: String,
    /// `identical file` (the same SHA-256) or `same model` (the same values; the file differs
    /// in its sequence number, text or comments).
    pub how: String,
}

/// One value that differs from the nearest record's.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Difference {
    /// `a2`, `alpha3`, `theta_offset1`, `d4`, `beta2`, `base x`, `tool rz`, ...
    pub value: String,
    /// Its unit: `mm` or `deg`.
    pub unit: &'static str,
    /// On the controller (in the file given).
    pub given: f64,
    /// In the record.
    pub registered: f64,
}

/// The nearest record to a file that matches none.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Nearest {
    /// The record's number.
    pub id: i64,
    /// The values that differ (geometry and frames; limits, joint maps and compliance are
    /// compared only as a whole).
    pub differences: Vec<Difference>,
    /// The largest tool movement between the two geometries over the workspace, mm.
    pub max_movement_mm: f64,
    /// The mean, mm.
    pub mean_movement_mm: f64,
}

/// The verdict.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verification {
    /// The robot.
    pub serial: String,
    /// The file checked.
    pub given: String,
    /// Its SHA-256.
    pub sha256: String,
    /// The robot's calibrations registered (with identified files: those a model can be
    /// compared with).
    pub registered: usize,
    /// The robot's latest calibration's record.
    pub latest: i64,
    /// The record the file matches, if any.
    pub matched: Option<Match>,
    /// The nearest record, when none matches.
    pub nearest: Option<Nearest>,
    /// It matches the latest calibration.
    pub passed: bool,
}

/// Checks `given` against `records` (one robot's, oldest first). Refused: no records, a file
/// that is not a parameter block or robot file.
pub fn verify(serial: &str, records: &[Record], given: &Given) -> crate::Result<Verification> {
    let latest = records.last().ok_or_else(|| {
        crate::refused!(option "--serial";
            "no calibration of robot {serial} is registered: calib registry list shows the serials")
    })?;
    use crate::io::input::Input;
    let (path, kind) = match given {
        Given::Block(p) => (p, Input::Data),
        Given::Robot(p) => (p, Input::Document),
    };
    let bytes = crate::io::input::read(path, kind)
        .map_err(|e| crate::refused!(input path.display(); "{}: {e}", path.display()))?;
    let hash = sha256(&bytes);
    let given_model = GivenModel::read(given, &bytes)?;
    let identified: Vec<(&Record, RobotFile, PathBuf)> = (records.iter())
        .filter_map(|r| Some(r.identified_file()?.map(|(file, path)| (r, file, path))))
        .collect::<crate::Result<_>>()?;
    let by_hash = records.iter().rev().find(|r| {
        let c = &r.calibration;
        c.block_sha256.as_deref() == Some(&hash) || c.identified_sha256.as_deref() == Some(&hash)
    });
    let matched = match by_hash {
        Some(r) => Some((r, "identical file")),
        None => (identified.iter().rev())
            .map(|(r, file, path)| Ok((*r, given_model.same_as(file, path)?)))
            .collect::<crate::Result<Vec<_>>>()?
            .into_iter()
            .find(|(_, same)| *same)
            .map(|(r, _)| (r, "same model")),
    };
    let nearest = match matched {
        Some(_) => None,
        None => nearest(&given_model, &identified)?,
    };
    Ok(Verification {
        serial: serial.to_string(),
        given: path.display().to_string(),
        sha256: hash,
        registered: records.len(),
        latest: latest.id,
        passed: matched.is_some_and(|(r, _)| r.id == latest.id),
        matched: matched.map(|(r, how)| Match {
            id: r.id,
            calibrated_at: r.calibration.calibrated_at.clone(),
            how: how.to_string(),
        }),
        nearest,
    })
}

/// The given file's model, as block bytes to compare and as geometry to list differences of.
struct GivenModel {
    /// The file's block (a robot file: exported as a double-precision block, sequence 1).
    block: Vec<u8>,
    scalar: BlockScalar,
    sequence: u32,
    robot: Robot<f64, Dyn>,
}

impl GivenModel {
    fn read(given: &Given, bytes: &[u8]) -> crate::Result<Self> {
        match given {
            Given::Block(path) => Self::of_block(path, bytes),
            Given::Robot(path) => {
                let text = std::str::from_utf8(bytes).map_err(|_| {
                    crate::refused!(input path.display(); "--robot {}: not a robot file (not UTF-8 text)", path.display())
                })?;
                let file = RobotFile::parse(text, path)?;
                let block = block_of(&file, path, BlockScalar::F64, 1)?;
                Self::of_block(path, &block)
            }
        }
    }

    fn of_block(path: &Path, bytes: &[u8]) -> crate::Result<Self> {
        const H: usize = crate::model::joint_maps::MAX_FILE_HARMONICS;
        let not_a_block = |e: StorageError| {
            crate::refused!(input path.display();
                "--block {}: not a controller parameter block ({e}); give the block calib export --format block wrote, as read back from the controller", path.display())
        };
        match storage::decode_model::<f32, Dyn, H>(bytes) {
            Ok((model, sequence)) => Ok(Self {
                block: bytes.to_vec(),
                scalar: BlockScalar::F32,
                sequence,
                robot: widen(&model.robot),
            }),
            Err(StorageError::WrongScalar(8)) => {
                let (model, sequence) =
                    storage::decode_model::<f64, Dyn, H>(bytes).map_err(not_a_block)?;
                Ok(Self {
                    block: bytes.to_vec(),
                    scalar: BlockScalar::F64,
                    sequence,
                    robot: model.robot,
                })
            }
            Err(e) => Err(not_a_block(e)),
        }
    }

    /// Does the record's identified `file` export to this very block?
    fn same_as(&self, file: &RobotFile, path: &Path) -> crate::Result<bool> {
        Ok(block_of(file, path, self.scalar, self.sequence)? == self.block)
    }
}

/// `file`'s parameter block in `scalar` with `sequence`.
fn block_of(
    file: &RobotFile,
    path: &Path,
    scalar: BlockScalar,
    sequence: u32,
) -> crate::Result<Vec<u8>> {
    ExportRequest {
        scalar: Some(scalar),
        sequence: Some(sequence),
        ..ExportRequest::new(ExportFormat::Block)
    }
    .export(file, path)
}

/// `robot` in double precision (the inverse of [`crate::formats::export::to_f32`]).
fn widen<T: Real>(robot: &Robot<T, Dyn>) -> Robot<f64, Dyn> {
    let frame = |f: &calib_core::FramePose<T>| calib_core::FramePose {
        xyz: f.xyz.map(Real::to_f64),
        rpy: f.rpy.map(Real::to_f64),
    };
    Robot {
        joints: robot.joints.map(|j| calib_core::MdhJoint {
            a: j.a.to_f64(),
            alpha: j.alpha.to_f64(),
            theta_offset: j.theta_offset.to_f64(),
            d: j.d.to_f64(),
            beta: j.beta.to_f64(),
        }),
        limits: robot.limits.map(|l| calib_core::JointLimits {
            lower: l.lower.to_f64(),
            upper: l.upper.to_f64(),
        }),
        base: frame(&robot.base),
        tool: frame(&robot.tool),
    }
}

/// Every value of `robot` by name, with its unit, in mm and deg.
fn values(robot: &Robot<f64, Dyn>) -> Vec<(String, &'static str, f64)> {
    let mut out = Vec::new();
    for (i, j) in robot.joints.iter().enumerate() {
        let n = i + 1;
        out.push((format!("a{n}"), "mm", j.a));
        out.push((format!("alpha{n}"), "deg", j.alpha.to_degrees()));
        out.push((
            format!("theta_offset{n}"),
            "deg",
            j.theta_offset.to_degrees(),
        ));
        out.push((format!("d{n}"), "mm", j.d));
        out.push((format!("beta{n}"), "deg", j.beta.to_degrees()));
    }
    for (name, frame) in [("base", &robot.base), ("tool", &robot.tool)] {
        for (axis, v) in ["x", "y", "z"].iter().zip(frame.xyz) {
            out.push((format!("{name} {axis}"), "mm", v));
        }
        for (axis, v) in ["rx", "ry", "rz"].iter().zip(frame.rpy) {
            out.push((format!("{name} {axis}"), "deg", v.to_degrees()));
        }
    }
    out
}

/// The record nearest to `given` (smallest largest tool movement), with what differs.
fn nearest(
    given: &GivenModel,
    identified: &[(&Record, RobotFile, PathBuf)],
) -> crate::Result<Option<Nearest>> {
    let Some((_, first, first_path)) = identified.last() else {
        return Ok(None);
    };
    if first.joint.len() != given.robot.joints.len() {
        return Err(crate::refused!(input "the file given";
            "the file given is for a {}-joint robot, the registered calibrations for a {}-joint one: is it this robot's?",
            given.robot.joints.len(), first.joint.len()));
    }
    let configurations = crate::planning::generate(first, first_path, POSES, None)?;
    let controller = Kinematics::nominal(&given.robot)?;
    let mut best: Option<Nearest> = None;
    for (record, file, path) in identified.iter().rev() {
        let registered = file.to_model(path)?.robot;
        let kinematics = Kinematics::nominal(&registered)?;
        let mut moved = Vec::with_capacity(configurations.len());
        for (_, q) in &configurations {
            let q = calib_core::model::JointVec::from_slice(q).ok_or_else(
                || crate::refused!(unsupported "more than 9 joints"; "more than 9 joints"),
            )?;
            let d = kinematics.forward(&q)?.translation.vector
                - controller.forward(&q)?.translation.vector;
            moved.push(d.norm());
        }
        let max = moved.iter().copied().fold(0.0, f64::max);
        if best.as_ref().is_some_and(|b| b.max_movement_mm <= max) {
            continue;
        }
        let differences = (values(&given.robot).into_iter())
            .zip(values(&registered))
            .filter(|((_, unit, a), (_, _, b))| {
                let tolerance = if *unit == "mm" { 1e-4 } else { 1e-5 };
                (a - b).abs() > tolerance
            })
            .map(|((value, unit, a), (_, _, b))| Difference {
                value,
                unit,
                given: a,
                registered: b,
            })
            .collect();
        best = Some(Nearest {
            id: record.id,
            differences,
            max_movement_mm: max,
            mean_movement_mm: moved.iter().sum::<f64>() / moved.len().max(1) as f64,
        });
    }
    Ok(best)
}

impl Verification {
    /// The verdict for a technician.
    pub fn text(&self, records: &[Record]) -> String {
        let date = |id: i64| {
            (records.iter().find(|r| r.id == id))
                .map(|r| r.calibration.calibrated_at.clone())
                .filter(|d| !d.is_empty())
                .unwrap_or_else(|| "an unknown date".to_string())
        };
        let mut text = format!(
            "{} (SHA-256 {}) against the {} registered calibrations of robot {}:\n",
            self.given, self.sha256, self.registered, self.serial
        );
        match (&self.matched, &self.nearest) {
            (Some(m), _) if self.passed => text.push_str(&format!(
                "OK: {} of record {}, the robot's latest calibration ({})\n",
                if m.how == "identical file" { "the identical file" } else { "the same model as the file" },
                m.id,
                date(m.id)
            )),
            (Some(m), _) => text.push_str(&format!(
                "NOT THE LATEST: it holds record {}'s calibration ({}; {}), but record {} ({}) is newer: load record {}'s model (calib registry show {} --json has its identified file; calib export --format block writes its block)\n",
                m.id,
                date(m.id),
                m.how,
                self.latest,
                date(self.latest),
                self.latest,
                self.latest
            )),
            (None, Some(n)) => {
                text.push_str(&format!(
                    "NO MATCH: it holds none of the registered calibrations; the nearest is record {} ({}), from which it moves the tool by {:.4} mm on average and {:.4} mm at most over {POSES} configurations spread over the joint limits\n",
                    n.id,
                    date(n.id),
                    n.mean_movement_mm,
                    n.max_movement_mm
                ));
                for d in &n.differences {
                    text.push_str(&format!(
                        "  {:<14} {:>14.6} on the controller, {:>14.6} registered  {}\n",
                        d.value, d.given, d.registered, d.unit
                    ));
                }
                if n.differences.is_empty() {
                    text.push_str("  the geometry and frames agree (within 1e-4 mm and 1e-5 deg): the joint limits, joint maps or compliance differ\n");
                }
            }
            (None, None) => text.push_str(
                "NO MATCH: it is none of the registered files, and no calibration of this robot keeps its identified file to compare models with (register with --identified)\n",
            ),
        }
        text
    }
}
