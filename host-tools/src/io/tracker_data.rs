//! Tracker data files (CSV, docs/ARCHITECTURE.md): a header row whose column names carry their unit, `#`
//! comment lines, and one measured pose per row.
//!
//! Columns: joints `q1_deg..qN_deg` (or `_rad`), position `x_mm, y_mm, z_mm` (or `_m`), optional
//! orientation as a unit quaternion `qw, qx, qy, qz` or fixed-axis angles `rx_deg, ry_deg, rz_deg`
//! (`R = Rz Ry Rx`), optional `id`, `weight`, `role`, `configuration`, `time_s` (or `time_ms`) and `temperature_c`
//! (the air temperature at the instrument, deg C, stated on the certificate).
//! A comment line `# frame: base` says the
//! measurements are in the robot's base frame. Line numbers in errors are the file's physical lines
//! (the header, and any comment above it, count).

use crate::io::columns::{Column, parse_column};
use crate::io::outputs::write_atomic;
use crate::io::profile::{DataFrame, DataProfile};
use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion};

/// The file's text; invalid UTF-8 is reported with its line.
fn read_text(path: &Path) -> Result<String, DataError> {
    let bytes = crate::io::input::read(path, crate::io::input::Input::Data).map_err(|source| {
        DataError::Read {
            path: path.to_owned(),
            source,
        }
    })?;
    String::from_utf8(bytes).map_err(|e| {
        let valid = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        let line = bytes[..valid].iter().filter(|b| **b == b'\n').count() as u64 + 1;
        DataError::At {
            path: path.to_owned(),
            line,
            column: None,
            message: format!(
                "byte {:#04x} is not UTF-8 text; save the file as UTF-8 (or plain ASCII)",
                bytes[valid]
            ),
        }
    })
}
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Largest magnitude of an Euler angle of a measured orientation, rad (two turns: tracker
/// software writes one turn at most).
pub(crate) const MAX_EULER_ANGLE_RAD: f64 = 4.0 * std::f64::consts::PI;

/// Largest measured coordinate accepted, mm: 100 m, beyond any laser tracker's range.
pub(crate) const MAX_POSITION_MM: f64 = 100_000.0;

/// Largest joint reading accepted, degrees: ten turns.
pub(crate) const MAX_JOINT_DEG: f64 = 3600.0;

/// Largest pose weight accepted (weights are relative; 1 is the default).
pub(crate) const MAX_WEIGHT: f64 = 1e6;

/// How far a quaternion's norm may be from 1 before it is refused.
pub(crate) const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// A problem with a tracker data file, located by file, line and column.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// The file could not be read.
    #[error("{path}: cannot read the data file")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A problem at a place in the file.
    #[error("{path}:{line}{}: {message}", column.as_ref().map(|c| format!(": column {c}")).unwrap_or_default())]
    At {
        /// The file.
        path: PathBuf,
        /// Physical line, 1-based.
        line: u64,
        /// Column name (and number), if the problem is in one column.
        column: Option<String>,
        /// What was expected.
        message: String,
    },
}

/// How the orientation of each pose is given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OrientationColumns {
    /// Position only (a spherical reflector).
    None,
    /// `qw, qx, qy, qz`.
    Quaternion,
    /// `rx_deg, ry_deg, rz_deg`, `R = Rz Ry Rx`.
    FixedAngles,
}

/// One measured pose.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    /// Physical line in the file.
    pub line: u64,
    /// The `id` column, or the line number.
    pub id: String,
    /// Joint readings, rad.
    pub q: Vec<f64>,
    /// Measured position, mm.
    pub position: [f64; 3],
    /// Measured orientation (rotation matrix), if the file has orientation columns.
    pub rotation: Option<Matrix3<f64>>,
    /// Weight (1 when there is no weight column).
    pub weight: f64,
    /// The pose's role in a measurement plan (the `role` column), if the file has one.
    pub role: Option<Role>,
    /// A target's arm configuration, the closed-form branch 0-7 (the `configuration` column,
    /// `branch B`), if the file has one.
    pub configuration: Option<u8>,
    /// When the row was measured or logged, s (the `time_s` or `time_ms` column), if the file
    /// has one.
    pub time_s: Option<f64>,
    /// The air temperature when the row was measured, deg C (the `temperature_c` column), if the
    /// file has one.
    pub temperature_c: Option<f64>,
}

/// The air temperatures a `temperature_c` column may hold, deg C.
pub(crate) const TEMPERATURE_C: std::ops::RangeInclusive<f64> = -40.0..=80.0;

/// A pose's role in a measurement plan (`calib plan`; the `role` column of a data file).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// A pose of the D-optimal core: among the most informative for the identified parameters.
    Core,
    /// A fill pose: drawn at random from the working region, keeps the fit representative of it.
    Fill,
    /// A verification pose: measured, kept out of the fit, compared with the plan's prediction.
    Verify,
}

impl Role {
    /// The name in the `role` column.
    pub fn name(self) -> &'static str {
        match self {
            Self::Core => "core",
            Self::Fill => "fill",
            Self::Verify => "verify",
        }
    }

    /// The role named `name` (`core`, `fill`, `verify`, any case).
    pub fn parse(name: &str) -> Option<Self> {
        [Self::Core, Self::Fill, Self::Verify]
            .into_iter()
            .find(|r| r.name().eq_ignore_ascii_case(name))
    }
}

/// A `configuration` field: `branch B` or `B` (0-7), or empty for none.
fn parse_configuration(field: &str) -> Result<Option<u8>, String> {
    let text = field.trim();
    if text.is_empty() {
        return Ok(None);
    }
    let number = text.strip_prefix("branch").unwrap_or(text).trim();
    number
        .parse::<u8>()
        .ok()
        .filter(|b| *b < 8)
        .map(Some)
        .ok_or_else(|| {
            format!(
                "\"{field}\" is not an arm configuration: give the closed-form branch as `branch B`, B from 0 to 7 (bit 4 shoulder back, bit 2 elbow down, bit 1 wrist flipped)"
            )
        })
}

/// What a plan predicted for its verification poses, from its `# plan prediction:` comment line
/// (written by `calib plan`, read back by `calibrate` to put the measured error next to it).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PlannedVerification {
    /// Predicted mean position error of the verification poses, mm.
    pub mean_mm: f64,
    /// Lower end of the predicted 95 % range of that mean, mm.
    pub low_mm: f64,
    /// Upper end of the predicted 95 % range of that mean, mm.
    pub high_mm: f64,
    /// The noise level the prediction assumed (per coordinate, 1 sigma), mm.
    pub noise_mm: f64,
}

impl PlannedVerification {
    /// The comment line's start.
    pub(crate) const PREFIX: &'static str = "plan prediction:";

    /// The comment line (without `#`).
    pub fn comment(&self) -> String {
        format!(
            "{} verification_mean_mm={} low_mm={} high_mm={} noise_mm={}",
            Self::PREFIX,
            self.mean_mm,
            self.low_mm,
            self.high_mm,
            self.noise_mm
        )
    }

    /// The prediction of a comment line's text after `#`; `Ok(None)` for another comment.
    fn parse(comment: &str) -> Result<Option<Self>, String> {
        let Some(rest) = comment.trim().strip_prefix(Self::PREFIX) else {
            return Ok(None);
        };
        let mut values = std::collections::HashMap::new();
        for pair in rest.split_whitespace() {
            let (key, value) = pair
                .split_once('=')
                .ok_or_else(|| format!("\"{pair}\" is not key=value"))?;
            let value: f64 = value
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite() && *v >= 0.0)
                .ok_or_else(|| format!("{key} = \"{value}\" is not a length in mm"))?;
            values.insert(key, value);
        }
        let get = |key: &str| {
            values.get(key).copied().ok_or_else(|| {
                format!(
                    "{key} is missing (the line is written by calib plan; restore it or delete it)"
                )
            })
        };
        let planned = Self {
            mean_mm: get("verification_mean_mm")?,
            low_mm: get("low_mm")?,
            high_mm: get("high_mm")?,
            noise_mm: get("noise_mm")?,
        };
        if !(planned.low_mm <= planned.mean_mm && planned.mean_mm <= planned.high_mm) {
            return Err("the range low_mm..high_mm does not hold verification_mean_mm".into());
        }
        Ok(Some(planned))
    }
}

/// A parsed tracker data file.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackerData {
    /// The file.
    pub path: PathBuf,
    /// `true` when a `# frame: base` line (or the data profile) says the data are in the robot's
    /// base frame.
    pub base_frame: bool,
    /// Physical line of the header row.
    pub header_line: u64,
    /// Number of joint columns.
    pub joints: usize,
    /// The orientation columns.
    pub orientation: OrientationColumns,
    /// The poses, in file order.
    pub records: Vec<Record>,
    /// What the plan the file was measured from predicted (its `# plan prediction:` line).
    pub planned: Option<PlannedVerification>,
    /// `true` when the file has an `id` column; without one each record's id is its line.
    pub has_ids: bool,
    /// `true` when the file has a time column (`time_s`, `time_ms`).
    pub has_times: bool,
    /// The instrument that measured the data, as the data profile states it.
    pub instrument: Option<crate::io::profile::Instrument>,
}

impl TrackerData {
    /// Poses held in memory (joints in rad, positions in mm, rotations as matrices), named
    /// `<memory>`; `base_frame` says the positions are already in the robot's base frame. Either
    /// every pose has an orientation or none has.
    pub fn from_records(records: Vec<Record>, base_frame: bool) -> crate::Result<Self> {
        let joints = records.first().map_or(0, |r| r.q.len());
        let orientation = if records.iter().any(|r| r.rotation.is_some()) {
            OrientationColumns::Quaternion
        } else {
            OrientationColumns::None
        };
        if records
            .iter()
            .any(|r| r.rotation.is_some() != (orientation != OrientationColumns::None))
        {
            return Err(crate::refused!(input "poses";
                "either every pose has an orientation or none has"
            ));
        }
        Ok(TrackerData {
            path: PathBuf::from("<memory>"),
            base_frame,
            header_line: 0,
            joints,
            orientation,
            records,
            planned: None,
            has_ids: true,
            has_times: false,
            instrument: None,
        })
    }

    /// Reads and checks a tracker data file in our format (docs/ARCHITECTURE.md).
    pub fn read(path: &Path) -> Result<Self, DataError> {
        Self::read_with(path, &DataProfile::default())
    }

    /// Reads and checks a tracker data file through a data profile.
    pub fn read_with(path: &Path, profile: &DataProfile) -> Result<Self, DataError> {
        let text = read_text(path)?;
        Self::parse_with(&text, path, Needs::Measurements, profile)
    }

    /// Parses tracker-data text in our format; `path` only names the source in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, DataError> {
        Self::parse_with(text, path, Needs::Measurements, &DataProfile::default())
    }

    /// Parses tracker-data text through a data profile; `path` only names the source in errors.
    pub fn parse_profiled(
        text: &str,
        path: &Path,
        profile: &DataProfile,
    ) -> Result<Self, DataError> {
        Self::parse_with(text, path, Needs::Measurements, profile)
    }

    /// Reads a file of target poses: like [`TrackerData::read`], but the joint columns are
    /// optional (when present they are start values).
    pub(crate) fn read_targets(path: &Path) -> Result<Self, DataError> {
        let text = read_text(path)?;
        Self::parse_targets(&text, path)
    }

    /// Parses the text of a file of target poses, as [`read_targets`](Self::read_targets) reads
    /// it; `path` only names the source in errors.
    pub(crate) fn parse_targets(text: &str, path: &Path) -> Result<Self, DataError> {
        Self::parse_with(text, path, Needs::Targets, &DataProfile::default())
    }

    /// Reads a file of candidate joint configurations (`calib plan --candidates`) through a data
    /// profile: only the joint columns are read (and `id`); any measurement columns are ignored,
    /// so a measured file or a plan not yet measured serves as well. Records' positions are zero.
    pub fn read_joints(path: &Path, profile: &DataProfile) -> Result<Self, DataError> {
        let text = read_text(path)?;
        Self::parse_joints(&text, path, profile)
    }

    /// Reads a robot's log of when it stood at each planned pose (`calib merge --by time`): a time
    /// column (`time_s`, `time_ms`; numbers or ISO 8601 UTC timestamps), an optional `id`, joint
    /// columns optional.
    pub fn read_log(path: &Path, profile: &DataProfile) -> Result<Self, DataError> {
        let text = read_text(path)?;
        Self::parse_with(&text, path, Needs::Log, profile)
    }

    /// Reads a tracker's export of measured points through a data profile: positions (and
    /// orientations) required, joints optional (a robot log merged in), for `calib merge`.
    pub fn read_measured(path: &Path, profile: &DataProfile) -> Result<Self, DataError> {
        let text = read_text(path)?;
        Self::parse_with(&text, path, Needs::Targets, profile)
    }

    /// Parses the text of a file of candidate joint configurations, as
    /// [`read_joints`](Self::read_joints) reads it; `path` only names the source in errors.
    pub fn parse_joints(text: &str, path: &Path, profile: &DataProfile) -> Result<Self, DataError> {
        Self::parse_with(text, path, Needs::Joints, profile)
    }

    fn parse_with(
        text: &str,
        path: &Path,
        needs: Needs,
        profile: &DataProfile,
    ) -> Result<Self, DataError> {
        // A UTF-8 byte order mark (from some Windows editors) is not part of the first line.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let source = Source::new(text, path);
        if text.contains('\r') && !text.contains('\n') {
            return Err(source.at(
                1,
                None,
                "the lines end in CR only (old Mac line endings); save the file with LF or CRLF line endings".into(),
            ));
        }
        let base_frame = match profile.frame {
            Some(frame) => frame == DataFrame::Base,
            None => text.lines().any(|l| {
                l.strip_prefix('#')
                    .is_some_and(|c| c.trim().replace(' ', "") == "frame:base")
            }),
        };
        let mut planned = None;
        for (i, line) in text.lines().enumerate() {
            let Some(comment) = line.strip_prefix('#') else {
                continue;
            };
            if let Some(p) =
                PlannedVerification::parse(comment).map_err(|m| source.at(i as u64 + 1, None, m))?
            {
                planned = Some(p);
            }
        }
        let mut reader = csv::ReaderBuilder::new()
            .comment(Some(b'#'))
            .delimiter(profile.delimiter)
            .trim(csv::Trim::All)
            .flexible(true)
            .from_reader(text.as_bytes());
        let layout = Layout::read(&mut reader, &source, needs, profile)?;
        let mut records = Vec::new();
        let mut ids = std::collections::HashMap::new();
        for result in reader.records() {
            let row = result.map_err(|e| {
                let line = e.position().map_or(0, |p| source.line_of(p.byte()));
                source.at(line, None, format!("cannot read the row: {e}"))
            })?;
            let record = layout.record(&row, &source, profile)?;
            if let Some(previous) = ids.insert(record.id.clone(), record.line) {
                return Err(source.at(
                    record.line,
                    Some("id".into()),
                    format!("id \"{}\" already used on line {previous}", record.id),
                ));
            }
            records.push(record);
        }
        if records.is_empty() {
            return Err(source.at(layout.header_line, None, "the file has no data rows".into()));
        }
        Ok(Self {
            path: path.to_owned(),
            base_frame,
            header_line: layout.header_line,
            joints: layout.joints,
            orientation: layout.orientation,
            records,
            planned,
            has_ids: layout.columns.contains(&Column::Id),
            has_times: layout.columns.iter().any(|c| matches!(c, Column::Time(_))),
            instrument: profile.instrument.clone(),
        })
    }
}

/// The columns a file must have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Needs {
    /// Measured poses: joints and positions.
    Measurements,
    /// Target poses: positions; joints optional (start values).
    Targets,
    /// Joint configurations: joints; anything else ignored.
    Joints,
    /// A robot's log for merging by time: its time column, joints optional; anything else
    /// ignored.
    Log,
}

/// The text being parsed and its file, for errors with physical line numbers.
struct Source<'t> {
    text: &'t str,
    path: &'t Path,
    /// Byte offset of the start of each line.
    line_starts: Vec<usize>,
}

impl<'t> Source<'t> {
    fn new(text: &'t str, path: &'t Path) -> Self {
        let line_starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Self {
            text,
            path,
            line_starts,
        }
    }

    /// An error at a physical line (and column, when the problem is in one).
    fn at(&self, line: u64, column: Option<String>, message: String) -> DataError {
        DataError::At {
            path: self.path.to_owned(),
            line,
            column,
            message,
        }
    }

    /// Physical line of a byte offset (the csv crate's own line count is one short after a CRLF
    /// header, so lines are counted here).
    fn line_of(&self, byte: u64) -> u64 {
        // After a CRLF the record may start at the '\n' of the previous line's end.
        let mut byte = usize::try_from(byte).unwrap_or(usize::MAX);
        while matches!(self.text.as_bytes().get(byte), Some(b'\r' | b'\n')) {
            byte += 1;
        }
        self.line_starts.partition_point(|start| *start <= byte) as u64
    }
}

/// The header row understood: our meaning of every source column.
struct Layout {
    /// The source column names.
    header: csv::StringRecord,
    /// Our column for each source column, then for each derived column.
    columns: Vec<Column>,
    /// The derived columns and the indices of their two source columns.
    derived: Vec<(crate::io::profile::Derived, [usize; 2])>,
    /// Physical line of the header.
    header_line: u64,
    /// Number of joint columns.
    joints: usize,
    /// How the orientation is given.
    orientation: OrientationColumns,
}

impl Layout {
    /// Reads the header and checks it: known (or mapped) names, no duplicates, every joint up
    /// to the highest, the three positions, a complete orientation or none.
    fn read(
        reader: &mut csv::Reader<&[u8]>,
        source: &Source<'_>,
        needs: Needs,
        profile: &DataProfile,
    ) -> Result<Self, DataError> {
        let header = reader
            .headers()
            .map_err(|e| source.at(1, None, format!("cannot read the header: {e}")))?
            .clone();
        // The header is the first line that is neither empty nor a comment.
        let header_line = source
            .text
            .lines()
            .position(|l| !l.trim().is_empty() && !l.starts_with('#'))
            .map_or(1, |i| i as u64 + 1);
        let at = |column: Option<String>, message: String| source.at(header_line, column, message);
        if header.is_empty() || (header.len() == 1 && header.get(0) == Some("")) {
            return Err(at(None, "the file has no header row".into()));
        }
        if header.len() == 1 && header.get(0).is_some_and(|h| h.contains(';')) {
            return Err(at(
                None,
                "the header is one column holding semicolons: the file looks semicolon-separated; read it through a data profile with delimiter = \";\" (--profile, see host-tools/profiles/)".into(),
            ));
        }
        let mut columns = columns_of(&header, profile, &at)?;
        // Derived columns: ours, computed from two source columns, after the source columns.
        let mut header = header;
        let mut derived = Vec::with_capacity(profile.derived.len());
        for d in &profile.derived {
            let index = |source: &str| {
                header.iter().position(|h| h == source).ok_or_else(|| {
                    at(
                        None,
                        format!(
                            "missing column \"{source}\", which the data profile combines into {} = {}",
                            d.ours,
                            d.describe()
                        ),
                    )
                })
            };
            let sources = [index(&d.sources[0])?, index(&d.sources[1])?];
            let column = parse_column(&d.ours)
                .ok_or_else(|| at(None, format!("{} is not one of our columns", d.ours)))?;
            derived.push((d.clone(), sources));
            columns.push(column);
        }
        for d in &profile.derived {
            header.push_field(&format!("{} = {}", d.ours, d.describe()));
        }
        if matches!(needs, Needs::Joints | Needs::Log) {
            for c in &mut columns {
                if !matches!(
                    c,
                    Column::Joint(..) | Column::Id | Column::Role | Column::Time(_)
                ) {
                    *c = Column::Ignored;
                }
            }
        }
        let joints = check_columns(&header, &columns, needs, &at)?;
        let count = |f: fn(&Column) -> bool| columns.iter().filter(|c| f(c)).count();
        let quaternions = count(|c| matches!(c, Column::Quaternion(_)));
        let angles = count(|c| matches!(c, Column::Angle(..)));
        let orientation = match (quaternions, angles) {
            (0, 0) => OrientationColumns::None,
            (4, 0) => OrientationColumns::Quaternion,
            (0, 3) => OrientationColumns::FixedAngles,
            _ => {
                return Err(at(
                    None,
                    "orientation needs all of qw, qx, qy, qz or all of rx_deg, ry_deg, rz_deg, not a mix".into(),
                ));
            }
        };
        Ok(Self {
            header,
            columns,
            derived,
            header_line,
            joints,
            orientation,
        })
    }

    /// One data row as a record, every value checked.
    fn record(
        &self,
        row: &csv::StringRecord,
        source: &Source<'_>,
        profile: &DataProfile,
    ) -> Result<Record, DataError> {
        let line = row.position().map_or(0, |p| source.line_of(p.byte()));
        let fields = self.columns.len() - self.derived.len();
        if row.len() != fields {
            return Err(source.at(
                line,
                None,
                format!("has {} fields, the header has {fields}", row.len()),
            ));
        }
        let mut extra = Vec::with_capacity(self.derived.len());
        for (d, [a, b]) in &self.derived {
            let value = |i: usize| {
                let field = row.get(i).unwrap_or("");
                number(field, profile.decimal).map_err(|m| {
                    let name = self.header.get(i).unwrap_or("");
                    source.at(
                        line,
                        Some(format!("{} (\"{name}\", part of {})", i + 1, d.ours)),
                        m,
                    )
                })
            };
            extra.push(d.combine(value(*a)?, value(*b)?).to_string());
        }
        let mut record = Record {
            line,
            id: line.to_string(),
            q: vec![0.0; self.joints],
            position: [0.0; 3],
            rotation: None,
            weight: 1.0,
            role: None,
            configuration: None,
            time_s: None,
            temperature_c: None,
        };
        let mut quaternion = [0.0; 4];
        let mut angle = [0.0; 3];
        for (i, ((field, column), name)) in row
            .iter()
            .chain(extra.iter().map(String::as_str))
            .zip(&self.columns)
            .zip(self.header.iter())
            .enumerate()
        {
            let at =
                |message: String| source.at(line, Some(format!("{} (\"{name}\")", i + 1)), message);
            match column {
                Column::Ignored => continue,
                Column::Id => {
                    record.id = field.to_string();
                    continue;
                }
                Column::Configuration => {
                    record.configuration = parse_configuration(field).map_err(at)?;
                    continue;
                }
                Column::Role => {
                    record.role = Some(Role::parse(field).ok_or_else(|| {
                        at(format!(
                            "\"{field}\" is not a role of a measurement plan (core, fill or verify)"
                        ))
                    })?);
                    continue;
                }
                Column::Position(..) | Column::Quaternion(_) | Column::Angle(..)
                    if field.is_empty() =>
                {
                    return Err(at(
                        "empty: this pose has not been measured. A plan written by calib plan is filled in by the tracker software before it is calibrated; delete the rows of poses that could not be measured".into(),
                    ));
                }
                _ => {}
            }
            // A time column may hold ISO 8601 timestamps, as tracker software writes them.
            if let (Column::Time(_), Some(seconds)) = (column, iso_8601_seconds(field)) {
                record.time_s = Some(seconds);
                continue;
            }
            let value = number(field, profile.decimal).map_err(at)?;
            match *column {
                Column::Joint(j, scale) => {
                    // A reading beyond one turn in a radian column is almost surely degrees.
                    if scale == 1.0 && value.abs() > 2.0 * std::f64::consts::PI {
                        return Err(at(format!(
                            "{value} is beyond one turn for a radian column; are these degrees (q{}_deg)?",
                            j + 1
                        )));
                    }
                    if (value * scale).abs() > MAX_JOINT_DEG.to_radians() {
                        return Err(at(format!(
                            "{field} is beyond ten turns ({MAX_JOINT_DEG} deg); check the value and the column's unit"
                        )));
                    }
                    record.q[j] = value * scale
                }
                Column::Position(k, scale) => {
                    if (value * scale).abs() > MAX_POSITION_MM {
                        return Err(at(format!(
                            "{field} is {:e} mm, beyond the 100 m range of a laser tracker; check the value and the column's unit",
                            value * scale
                        )));
                    }
                    record.position[k] = value * scale
                }
                Column::Quaternion(k) => quaternion[k] = value,
                Column::Angle(k, scale) => {
                    // A measured orientation's Euler angle: within two turns either way.
                    if (value * scale).abs() > MAX_EULER_ANGLE_RAD {
                        return Err(at(format!(
                            "{field} is {:e} deg, beyond the +-720 deg of an Euler angle; check the value and the column's unit",
                            (value * scale).to_degrees()
                        )));
                    }
                    angle[k] = value * scale
                }
                Column::Weight => {
                    if !(0.0..=MAX_WEIGHT).contains(&value) {
                        return Err(at(format!(
                            "weight {field} must be between 0 and {MAX_WEIGHT:e} (weights are relative, 1 by default)"
                        )));
                    }
                    record.weight = value;
                }
                Column::Time(scale) => record.time_s = Some(value * scale),
                Column::Temperature => {
                    if !(TEMPERATURE_C.contains(&value)) {
                        return Err(at(format!(
                            "temperature {field} deg C is outside {} to {} deg C, the air of a measured robot cell; \
                             check the column holds degrees Celsius",
                            TEMPERATURE_C.start(),
                            TEMPERATURE_C.end()
                        )));
                    }
                    record.temperature_c = Some(value);
                }
                Column::Id | Column::Role | Column::Configuration | Column::Ignored => {}
            }
        }
        record.rotation = match self.orientation {
            OrientationColumns::None => None,
            OrientationColumns::Quaternion => Some(
                rotation_of_quaternion(quaternion)
                    .map_err(|m| source.at(line, Some("qw..qz".into()), m))?,
            ),
            OrientationColumns::FixedAngles => Some(*profile.euler.rotation(angle).matrix()),
        };
        Ok(record)
    }
}

/// A finite number from a field, with a decimal point or, for `decimal == b','`, a comma.
fn number(field: &str, decimal: u8) -> Result<f64, String> {
    let decimal_comma;
    let text = if decimal == b',' {
        decimal_comma = field.replace(',', ".");
        decimal_comma.as_str()
    } else {
        field
    };
    let value: f64 = text
        .parse()
        .map_err(|_| format!("\"{field}\" is not a number"))?;
    if !value.is_finite() {
        return Err(format!("{field} is not a finite number"));
    }
    Ok(value)
}

/// The rotation of a unit quaternion `[w, x, y, z]` (norm within [`QUATERNION_NORM_TOLERANCE`]).
fn rotation_of_quaternion([w, x, y, z]: [f64; 4]) -> Result<Matrix3<f64>, String> {
    let norm = (w * w + x * x + y * y + z * z).sqrt();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
        return Err(format!(
            "quaternion norm {norm:.6} is not 1 (tolerance {QUATERNION_NORM_TOLERANCE})"
        ));
    }
    let unit = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
    Ok(*unit.to_rotation_matrix().matrix())
}

/// Our column for each source column: with a column mapping, the mapped source columns are
/// renamed to ours (every mapped column must exist) and the rest ignored.
fn columns_of(
    header: &csv::StringRecord,
    profile: &DataProfile,
    at: &impl Fn(Option<String>, String) -> DataError,
) -> Result<Vec<Column>, DataError> {
    let mut names: Vec<String> = header.iter().map(str::to_string).collect();
    if let Some(mapping) = &profile.columns {
        let profile_name = profile
            .path
            .as_ref()
            .map_or_else(String::new, |p| format!(" (data profile {})", p.display()));
        for (ours, source) in mapping {
            if !header.iter().any(|h| h == source) {
                return Err(at(
                    None,
                    format!(
                        "missing column \"{source}\", which the data profile maps to {ours}{profile_name}"
                    ),
                ));
            }
        }
        for name in &mut names {
            *name = mapping
                .iter()
                .find(|(_, source)| source == name)
                .map_or_else(String::new, |(ours, _)| ours.clone());
        }
    }
    let mut columns = Vec::with_capacity(header.len());
    for (i, (name, source)) in names.iter().zip(header.iter()).enumerate() {
        if profile.columns.is_some() && name.is_empty() {
            columns.push(Column::Ignored);
            continue;
        }
        let column = parse_column(name).ok_or_else(|| {
            at(
                Some(format!("{} (\"{source}\")", i + 1)),
                "unknown column; expected q<i>_deg or q<i>_rad, x_mm/y_mm/z_mm (or _m), qw/qx/qy/qz, rx_deg/ry_deg/rz_deg, id, weight, role, configuration, time_s (or time_ms), temperature_c".into(),
            )
        })?;
        columns.push(column);
    }
    Ok(columns)
}

/// Checks that no column appears twice, that the joints run from q1 to the highest without a
/// gap (and exist unless `needs` targets), and that x, y and z are there (unless `needs` joints
/// only); returns the joint count.
fn check_columns(
    header: &csv::StringRecord,
    columns: &[Column],
    needs: Needs,
    at: &impl Fn(Option<String>, String) -> DataError,
) -> Result<usize, DataError> {
    let mut seen = std::collections::HashSet::new();
    for (name, column) in header.iter().zip(columns) {
        let key = match column {
            Column::Ignored => continue,
            Column::Joint(j, _) => format!("q{}", j + 1),
            Column::Position(k, _) => ["x", "y", "z"][*k].to_string(),
            Column::Angle(k, _) => ["rx", "ry", "rz"][*k].to_string(),
            _ => name.to_string(),
        };
        if !seen.insert(key.clone()) {
            return Err(at(Some(name.into()), format!("{key} appears twice")));
        }
    }
    let joints = columns
        .iter()
        .filter(|c| matches!(c, Column::Joint(..)))
        .count();
    if joints == 0 && !matches!(needs, Needs::Targets | Needs::Log) {
        return Err(at(None, "no joint columns (q1_deg, q2_deg, ...)".into()));
    }
    for j in 0..joints {
        if !seen.contains(&format!("q{}", j + 1)) {
            return Err(at(
                None,
                format!("missing joint column q{}_deg (or q{}_rad)", j + 1, j + 1),
            ));
        }
    }
    for axis in ["x", "y", "z"] {
        if !seen.contains(axis) && !matches!(needs, Needs::Joints | Needs::Log) {
            return Err(at(
                None,
                format!("missing position column {axis}_mm (or {axis}_m)"),
            ));
        }
    }
    Ok(joints)
}

/// An ISO 8601 (RFC 3339) UTC timestamp as seconds since 1970-01-01 (`2026-11-27T10:15:30.25Z`,
/// `2026-11-27 10:15:30`, `T` or a space, `Z` or no zone); `None` for anything else.
fn iso_8601_seconds(field: &str) -> Option<f64> {
    let field = field.trim();
    // A plain number is not a timestamp (humantime would not take it either).
    if !field.contains('-') || !field.contains(':') {
        return None;
    }
    let time = humantime::parse_rfc3339_weak(field).ok()?;
    Some(
        time.duration_since(std::time::UNIX_EPOCH)
            .ok()?
            .as_secs_f64(),
    )
}

impl TrackerData {
    /// `true` when the file has no orientation columns.
    pub fn rows_without_orientation(&self) -> bool {
        self.orientation == OrientationColumns::None
    }
}

/// One pose to write: joints (rad), position (mm), optional rotation.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseRow {
    /// Identifier written in the `id` column.
    pub id: String,
    /// Joint readings, rad (written in degrees).
    pub q: Vec<f64>,
    /// Position, mm.
    pub position: [f64; 3],
    /// Orientation, written as a quaternion with `qw >= 0`.
    pub rotation: Option<Matrix3<f64>>,
}

/// Writes poses as tracker CSV (atomically): `comments` become `#` lines at the top.
pub fn write_tracker_csv(path: &Path, comments: &[String], rows: &[PoseRow]) -> crate::Result<()> {
    write_atomic(path, tracker_csv(comments, rows)?.as_bytes())
}

/// Poses as tracker CSV text: `comments` become `#` lines at the top.
pub(crate) fn tracker_csv(comments: &[String], rows: &[PoseRow]) -> crate::Result<String> {
    tracker_csv_with_roles(comments, rows, None)
}

/// Poses as tracker CSV text, with a `role` column after `id` when `roles` (one per row) are
/// given: a measured plan that `calibrate` reads with its verification poses held out.
pub(crate) fn tracker_csv_with_roles(
    comments: &[String],
    rows: &[PoseRow],
    roles: Option<&[Role]>,
) -> crate::Result<String> {
    let joints = rows.first().map_or(0, |r| r.q.len());
    let orientation = rows.first().is_some_and(|r| r.rotation.is_some());
    let mut text = String::new();
    for c in comments {
        let _ = writeln!(text, "# {}", super::text::one_line(c));
    }
    let mut header: Vec<String> = vec!["id".into()];
    if roles.is_some() {
        header.push("role".into());
    }
    header.extend((1..=joints).map(|i| format!("q{i}_deg")));
    header.extend(["x_mm", "y_mm", "z_mm"].map(String::from));
    if orientation {
        header.extend(["qw", "qx", "qy", "qz"].map(String::from));
    }
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(&header)?;
    for (i, row) in rows.iter().enumerate() {
        let mut fields = vec![row.id.clone()];
        if let Some(role) = roles.and_then(|r| r.get(i)) {
            fields.push(role.name().to_string());
        }
        fields.extend(row.q.iter().map(|q| q.to_degrees().to_string()));
        fields.extend(row.position.iter().map(f64::to_string));
        if let Some(r) = &row.rotation {
            let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r));
            let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
            fields.extend([q.w, q.i, q.j, q.k].map(|v| (sign * v + 0.0).to_string()));
        }
        writer.write_record(&fields)?;
    }
    text.push_str(std::str::from_utf8(
        &writer.into_inner().map_err(|e| e.into_error())?,
    )?);
    Ok(text)
}
