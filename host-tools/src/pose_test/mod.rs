//! The ISO 9283 pose test, proper (issue 55, item 4): the test cube and its five points planned
//! in a stated region of the workspace, the program that runs them for `n` cycles (30 by
//! default), and the evaluation of the measured run with the standard's definitions: pose
//! accuracy and repeatability `AP`, `RP` per point, distance accuracy and repeatability `AD`,
//! `RD`, and the drift of the pose characteristics over the cycles.
//!
//! The held-out figures of a calibration (`analysis::accuracy::Iso9283`) are "ISO 9283-style":
//! whatever poses repeat among the held-out ones. This module is the test itself: `calib iso9283
//! plan` writes the commanded poses (a targets file), the run to measure and the program;
//! `calib iso9283 evaluate` judges the measured run against the commanded poses.

pub mod characteristics;
pub mod cube;

use crate::io::robot_file::RobotFile;
use crate::io::tracker_data::TrackerData;
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A commanded pose of the tool: its id, position in the base frame (mm) and orientation.
#[derive(Clone, Debug, PartialEq)]
pub struct Target {
    /// The point's id (`P1`..`P5`).
    pub id: String,
    /// The position, base frame, mm.
    pub position_mm: [f64; 3],
    /// The orientation (rotation matrix, base frame).
    pub rotation: Matrix3<f64>,
}

/// An evaluated pose test: the characteristics with what they were computed from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseTest {
    /// The robot (its file's name) and serial, when the file states one.
    pub robot: String,
    /// The robot's serial number, when its file states one.
    pub serial: Option<String>,
    /// The measured run, as given.
    pub data: String,
    /// The run's SHA-256.
    pub data_sha256: String,
    /// The commanded poses' file, as given.
    pub targets: String,
    /// Its SHA-256.
    pub targets_sha256: String,
    /// How the measurements were brought into the base frame, and what point they measure.
    pub setup: String,
    /// The instrument that measured the run, as its data profile states it.
    #[serde(default)]
    pub instrument: Option<crate::io::profile::Instrument>,
    /// The characteristics.
    pub characteristics: characteristics::Characteristics,
}

impl PoseTest {
    /// Evaluates the run `data` (read through `profile`) against the commanded poses of the
    /// targets file `targets` (base frame, with orientation), in the measurement setup of the
    /// identified robot file `robot`.
    pub fn evaluate(
        targets: &Path,
        data: &Path,
        robot: &Path,
        profile: &crate::io::profile::DataProfile,
    ) -> crate::Result<Self> {
        let (target_bytes, target_text) = read_text(targets, "--targets")?;
        let (data_bytes, data_text) = read_text(data, "--data")?;
        let file = RobotFile::read(robot)?;
        let commanded = TrackerData::parse_targets(&target_text, targets)?;
        let list = targets_of(&commanded, targets)?;
        let run = TrackerData::parse_profiled(&data_text, data, profile)?;
        let setup = characteristics::MeasurementSetup::of(&file, robot, &run)?;
        let characteristics = characteristics::characteristics(&list, &run, &setup)?;
        Ok(Self {
            robot: file.name.clone(),
            serial: file.serial.clone(),
            data: data.display().to_string(),
            data_sha256: crate::io::provenance::sha256(&data_bytes),
            targets: targets.display().to_string(),
            targets_sha256: crate::io::provenance::sha256(&target_bytes),
            setup: setup.text,
            instrument: run.instrument.clone(),
            characteristics,
        })
    }

    /// The instrument in words: name, serial and maximum permissible error, or "not stated".
    pub fn instrument_text(&self) -> String {
        match &self.instrument {
            None => "instrument not stated ([instrument] in the data profile)".to_string(),
            Some(i) => format!(
                "measured with {}{}, MPE {} um + {} um/m",
                i.name.as_deref().unwrap_or("an instrument not named"),
                i.serial
                    .as_ref()
                    .map_or(String::new(), |s| format!(" (serial {s})")),
                i.mpe_um,
                i.mpe_um_per_m
            ),
        }
    }

    /// The test for people: per point `AP` and `RP`, the distance and drift characteristics.
    pub fn text(&self) -> String {
        use std::fmt::Write as _;
        let c = &self.characteristics;
        let mut text = format!(
            "ISO 9283 pose test of {}{} from {}\n  {}\n  {}\n  point  cycles  AP mm    APx mm    APy mm    APz mm    RP mm\n",
            self.robot,
            self.serial
                .as_ref()
                .map_or(String::new(), |s| format!(" (serial {s})")),
            self.data,
            self.setup,
            self.instrument_text()
        );
        for p in &c.points {
            let _ = writeln!(
                text,
                "  {:<5} {:>7}  {:.4}  {:+.4}  {:+.4}  {:+.4}  {:.4}",
                p.point, p.cycles, p.ap_mm, p.ap_xyz_mm[0], p.ap_xyz_mm[1], p.ap_xyz_mm[2], p.rp_mm
            );
            if let (Some(ap), Some(rp)) = (p.ap_abc_deg, p.rp_abc_deg) {
                let _ = writeln!(
                    text,
                    "        orientation AP a,b,c {:+.4}, {:+.4}, {:+.4} deg; RP +-{:.4}, +-{:.4}, +-{:.4} deg",
                    ap[0], ap[1], ap[2], rp[0], rp[1], rp[2]
                );
            }
        }
        match &c.distance {
            Some(d) => {
                let _ = writeln!(
                    text,
                    "  distance {}-{} ({} cycles): commanded {:.4} mm, AD {:+.4} mm, RD +-{:.4} mm",
                    d.points[0], d.points[1], d.cycles, d.commanded_mm, d.ad_mm, d.rd_mm
                );
            }
            None => text.push_str(
                "  distance accuracy: not measured (P2 and P4 in fewer than 2 common cycles)\n",
            ),
        }
        match &c.drift {
            Some(d) => {
                let _ = writeln!(
                    text,
                    "  drift at {} (first and last {} cycles{}): AP {:.4} -> {:.4} mm, dAP {:.4} mm; RP {:.4} -> {:.4} mm, dRP {:.4} mm",
                    d.point,
                    d.block_cycles,
                    d.span_s
                        .map_or(String::new(), |s| format!(", {:.0} s apart", s)),
                    d.ap_mm[0],
                    d.ap_mm[1],
                    d.dap_mm,
                    d.rp_mm[0],
                    d.rp_mm[1],
                    d.drp_mm
                );
            }
            None => text.push_str("  drift: not measured (P1 in fewer than 6 cycles)\n"),
        }
        for note in &c.notes {
            let _ = writeln!(text, "  note: {note}");
        }
        text
    }
}

/// A file's bytes and its text (UTF-8).
fn read_text(path: &Path, option: &str) -> crate::Result<(Vec<u8>, String)> {
    let bytes = crate::io::input::read(path, crate::io::input::Input::Data)
        .map_err(|e| crate::refused!(input path.display(); "{option} {}: {e}", path.display()))?;
    let text = String::from_utf8(bytes.clone()).map_err(|e| {
        crate::refused!(input path.display();
            "{option} {}: byte {} is not UTF-8 text; save the file as UTF-8", path.display(), e.utf8_error().valid_up_to())
    })?;
    Ok((bytes, text))
}

/// The commanded poses of a targets file; refused without orientation or with an id twice.
fn targets_of(data: &TrackerData, path: &Path) -> crate::Result<Vec<Target>> {
    let mut targets: Vec<Target> = Vec::with_capacity(data.records.len());
    for r in &data.records {
        let rotation = r.rotation.ok_or_else(|| {
            crate::refused!(input path.display();
                "{} line {}: the commanded pose has no orientation; the targets file of calib iso9283 plan has qw, qx, qy, qz",
                path.display(), r.line)
        })?;
        if targets.iter().any(|t| t.id == r.id) {
            return Err(crate::refused!(input path.display();
                "{} line {}: target {} is given twice", path.display(), r.line, r.id));
        }
        targets.push(Target {
            id: r.id.clone(),
            position_mm: r.position,
            rotation,
        });
    }
    Ok(targets)
}
