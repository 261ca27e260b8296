//! One calibration as the registry keeps it: what a report (`calib calibrate --report` or
//! `calib sockets --report`) and the files beside it say, read and hashed once.

use crate::calibration::Report;
use crate::calibration::touches::TouchReport;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Which kind of calibration a record holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// From tracker measurements (`calib calibrate`).
    Tracker,
    /// From touches in sockets (`calib sockets`).
    Touches,
}

impl Kind {
    /// Its name in the database and in listings.
    pub fn name(self) -> &'static str {
        match self {
            Self::Tracker => "tracker",
            Self::Touches => "touches",
        }
    }

    /// The kind named `name` in the database.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "tracker" => Some(Self::Tracker),
            "touches" => Some(Self::Touches),
            _ => None,
        }
    }
}

/// A calibration to register: every field the registry stores, from the report and the files
/// beside it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NewRecord {
    /// The robot's serial number.
    pub serial: String,
    /// The robot's model (`--model`, else the identified file's name, else the report's robot).
    pub model: String,
    /// Tracker or touches.
    pub kind: Kind,
    /// When the calibration finished (the report's `calibrated_at`, RFC 3339; empty when the
    /// report predates it).
    pub calibrated_at: String,
    /// The software that calibrated (version and commit).
    pub software: String,
    /// The headline held-out figure, mm: a tracker calibration's held-out position error's
    /// median after calibration; touches' mean held-out consistency by the authors' rule (not
    /// accuracy). `None`: nothing was held out.
    pub held_out_mm: Option<f64>,
    /// The held-out figures as the report gives them (JSON).
    pub held_out: serde_json::Value,
    /// The identified parameters' covariance (JSON; `null` when the report has none).
    pub covariance: serde_json::Value,
    /// The calibration's input files with their SHA-256 (JSON).
    pub inputs: serde_json::Value,
    /// The identified robot file as written, when given.
    pub identified_toml: Option<String>,
    /// Its SHA-256.
    pub identified_sha256: Option<String>,
    /// The certificate's SHA-256 (HTML or PDF), when given.
    pub certificate_sha256: Option<String>,
    /// The controller block's SHA-256 (`calib export --format block`), when given.
    pub block_sha256: Option<String>,
    /// The report as registered, compact, without the per-pose and per-iteration lists
    /// ([`NOT_KEPT`]).
    pub report: String,
    /// The SHA-256 of the report file as registered (whole).
    pub report_sha256: String,
}

/// The files of one calibration to register, and what the command line adds.
#[derive(Clone, Debug, Default)]
pub struct RecordFiles<'a> {
    /// The JSON report.
    pub report: Option<&'a Path>,
    /// The identified robot file.
    pub identified: Option<&'a Path>,
    /// The certificate (HTML or PDF).
    pub certificate: Option<&'a Path>,
    /// The controller block.
    pub block: Option<&'a Path>,
    /// The robot's serial number (needed when the report does not state it).
    pub serial: Option<&'a str>,
    /// The robot's model.
    pub model: Option<&'a str>,
}

pub use crate::io::provenance::sha256;

/// The bytes of `path` (an input the user named with `flag`), read whole.
fn bytes_of(flag: &str, path: &Path) -> crate::Result<Vec<u8>> {
    crate::io::input::read(path, crate::io::input::Input::Data)
        .map_err(|e| crate::refused!(input path.display(); "{flag} {}: {e}", path.display()))
}

impl NewRecord {
    /// The record of `files`. Refused: no report, a report neither `calib calibrate` nor `calib
    /// sockets` wrote, no serial (the report states none and `--serial` is not given) or two
    /// that differ, an identified file that is not a robot file.
    pub fn from_files(files: &RecordFiles<'_>) -> crate::Result<Self> {
        let report_path = files.report.ok_or_else(
            || crate::refused!(option "REPORT"; "registry add: name the calibration's JSON report"),
        )?;
        let report = bytes_of("REPORT", report_path)?;
        let text = String::from_utf8(report.clone()).map_err(|_| {
            crate::refused!(input report_path.display(); "REPORT {}: not a JSON report (not UTF-8 text)", report_path.display())
        })?;
        let mut record = if text.contains("\"fitted_placements\"") {
            Self::of_touches(&TouchReport::from_json(&text, report_path)?, &text)?
        } else {
            Self::of_tracker(&Report::from_json(&text, report_path)?, &text)?
        };
        record.report_sha256 = sha256(&report);
        let stated = record.serial.clone();
        record.serial = match (files.serial, stated.as_str()) {
            (Some(given), "") => given.to_string(),
            (Some(given), stated) if given != stated => {
                return Err(crate::refused!(option "--serial";
                    "--serial {given}: {} states the robot's serial {stated}; give that, or no --serial", report_path.display()));
            }
            (_, "") => {
                return Err(crate::refused!(option "--serial";
                    "{} states no robot serial: give --serial (the robot's serial number, as on its plate)", report_path.display()));
            }
            (_, stated) => stated.to_string(),
        };
        if let Some(path) = files.identified {
            let bytes = bytes_of("--identified", path)?;
            let text = String::from_utf8(bytes.clone()).map_err(|_| {
                crate::refused!(input path.display(); "--identified {}: not a robot file (not UTF-8 text)", path.display())
            })?;
            let file = crate::io::robot_file::RobotFile::parse(&text, path)?;
            if files.model.is_none() && !file.name.is_empty() {
                record.model = file.name.clone();
            }
            record.identified_sha256 = Some(sha256(&bytes));
            record.identified_toml = Some(text);
        }
        if let Some(model) = files.model {
            record.model = model.to_string();
        }
        record.certificate_sha256 = match files.certificate {
            Some(path) => Some(sha256(&bytes_of("--certificate", path)?)),
            None => None,
        };
        record.block_sha256 = match files.block {
            Some(path) => Some(sha256(&bytes_of("--block", path)?)),
            None => None,
        };
        Ok(record)
    }

    /// A record of the report `text` with nothing else known yet.
    fn blank(text: &str) -> crate::Result<Self> {
        Ok(Self {
            serial: String::new(),
            model: String::new(),
            kind: Kind::Tracker,
            calibrated_at: String::new(),
            software: String::new(),
            held_out_mm: None,
            held_out: serde_json::Value::Null,
            covariance: serde_json::Value::Null,
            inputs: serde_json::Value::Null,
            identified_toml: None,
            identified_sha256: None,
            certificate_sha256: None,
            block_sha256: None,
            report: kept_report(text)?,
            report_sha256: String::new(),
        })
    }

    /// A tracker calibration's record (serial from its conditions, empty when not stated).
    fn of_tracker(report: &Report, text: &str) -> crate::Result<Self> {
        Ok(Self {
            serial: (report.conditions.as_ref())
                .and_then(|c| c.robot_serial.clone())
                .unwrap_or_default(),
            model: report.robot.clone(),
            kind: Kind::Tracker,
            calibrated_at: report.calibrated_at.clone(),
            software: report.software.clone(),
            held_out_mm: (report.held_out.as_ref()).map(|h| h.after.position.p50_mm),
            held_out: to_json(&report.held_out)?,
            covariance: to_json(&report.covariance)?,
            inputs: to_json(&report.inputs)?,
            ..Self::blank(text)?
        })
    }

    /// A calibration from touches' record (its report states no serial).
    fn of_touches(report: &TouchReport, text: &str) -> crate::Result<Self> {
        let held: Vec<f64> = (report.held_out.iter())
            .map(|f| f.identified.authors_mean_mm)
            .collect();
        Ok(Self {
            model: report.robot.display().to_string(),
            kind: Kind::Touches,
            calibrated_at: report.calibrated_at.clone(),
            software: report.software.clone(),
            held_out_mm: (!held.is_empty()).then(|| held.iter().sum::<f64>() / held.len() as f64),
            held_out: to_json(&report.held_out)?,
            inputs: to_json(&report.inputs)?,
            ..Self::blank(text)?
        })
    }
}

/// A report's parts that list every pose or iteration: recomputable from the inputs (whose
/// SHA-256 the record keeps), and nine tenths of a tracker report (about 700 of 760 kB for 1495
/// poses), so the registry does not keep them.
pub const NOT_KEPT: [&str; 3] = ["per_pose", "poses", "convergence"];

/// The report `text` as the registry keeps it: without [`NOT_KEPT`], compact JSON.
fn kept_report(text: &str) -> crate::Result<String> {
    let mut value: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| crate::numerical!("a report read once as JSON: {e}"))?;
    if let Some(object) = value.as_object_mut() {
        for key in NOT_KEPT {
            object.shift_remove(key);
        }
    }
    Ok(value.to_string())
}

/// A part of a report as a JSON value.
fn to_json<T: Serialize>(value: &T) -> crate::Result<serde_json::Value> {
    serde_json::to_value(value).map_err(|e| crate::numerical!("a report's part as JSON: {e}"))
}

/// A registered calibration: its number, when it was registered, and what was registered.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// The record's number in the registry.
    pub id: i64,
    /// When it was registered, RFC 3339 (UTC, to the second).
    pub registered_at: String,
    /// What was registered.
    #[serde(flatten)]
    pub calibration: NewRecord,
}

impl Record {
    /// The identified robot file the record keeps, parsed, with the path messages name it by
    /// (`record N (its identified file)`); `None` when it keeps none.
    pub fn identified_file(
        &self,
    ) -> Option<crate::Result<(crate::io::robot_file::RobotFile, std::path::PathBuf)>> {
        let text = self.calibration.identified_toml.as_deref()?;
        let path = std::path::PathBuf::from(format!("record {} (its identified file)", self.id));
        Some(
            crate::io::robot_file::RobotFile::parse(text, &path)
                .map(|file| (file, path))
                .map_err(crate::Error::from),
        )
    }
}

/// A line of a listing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// The record's number.
    pub id: i64,
    /// The robot's serial number.
    pub serial: String,
    /// The robot's model.
    pub model: String,
    /// Tracker or touches.
    pub kind: Kind,
    /// When the calibration finished.
    pub calibrated_at: String,
    /// The headline held-out figure, mm ([`NewRecord::held_out_mm`]).
    pub held_out_mm: Option<f64>,
    /// The software that calibrated.
    pub software: String,
}
