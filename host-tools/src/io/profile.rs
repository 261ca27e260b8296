//! Data profiles (TOML): how to read a tracker export that is not in our CSV format, without
//! editing it. A profile gives the field delimiter, the decimal separator, which source column is
//! which of our columns (our column names carry the unit, so the mapping also gives the unit),
//! the Euler-angle convention of the orientation, and the frame of the measurements.
//!
//! ```toml
//! delimiter = ";"
//! decimal = ","
//! frame = "tracker"            # or "base"
//! [columns]                    # our column = source column; unmapped source columns are ignored
//! q1_rad = "shoulder_pan_joint"
//! x_mm = "measurement_x"
//! rx_deg = "measurement_rx"
//! y_mm = { sum = ["target_y", "error_y"] }   # derived: source + source (or difference = [a, b])
//! [orientation]
//! euler = "intrinsic"          # or "fixed" (extrinsic)
//! order = "xyz"                # the order in which the three rotations are applied
//! ```

use nalgebra::{Rotation3, Vector3};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A problem with a profile file.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// The file could not be read.
    #[error("{path}: cannot read the data profile")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not valid TOML or has a wrong field.
    #[error("{path}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// Whether the three angles rotate about fixed (extrinsic) or moving (intrinsic) axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EulerKind {
    /// About the fixed axes of the measuring frame: order `xyz` gives `R = Rz Ry Rx`.
    Fixed,
    /// About the axes of the frame being rotated: order `xyz` gives `R = Rx Ry Rz`.
    Intrinsic,
}

/// How `rx, ry, rz` angle columns make a rotation matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EulerConvention {
    /// Fixed or intrinsic axes.
    pub kind: EulerKind,
    /// The axes (0 = x, 1 = y, 2 = z) in the order the rotations are applied.
    pub order: [usize; 3],
}

impl EulerConvention {
    /// the ARCHITECTURE conventions' `rx_deg, ry_deg, rz_deg`: fixed axes x, then y, then z (`R = Rz Ry Rx`).
    pub(crate) const FIXED_XYZ: Self = Self {
        kind: EulerKind::Fixed,
        order: [0, 1, 2],
    };

    /// The rotation for the angles about x, y and z (rad).
    pub fn rotation(&self, angles: [f64; 3]) -> Rotation3<f64> {
        let about = |axis: usize| {
            let mut v = Vector3::zeros();
            v[axis] = 1.0;
            Rotation3::from_axis_angle(
                &nalgebra::Unit::new_unchecked(v),
                angles.get(axis).copied().unwrap_or(0.0),
            )
        };
        let [first, second, third] = self.order.map(about);
        match self.kind {
            EulerKind::Fixed => third * second * first,
            EulerKind::Intrinsic => first * second * third,
        }
    }

    /// The angles about x, y and z (rad) that give `r` under this convention (the solution with
    /// the middle rotation within +-90 deg).
    pub fn angles(&self, r: &Rotation3<f64>) -> [f64; 3] {
        // Fixed (i, j, k) is intrinsic (k, j, i): R = R_k R_j R_i.
        let [i, j, k] = match self.kind {
            EulerKind::Intrinsic => self.order,
            EulerKind::Fixed => [self.order[2], self.order[1], self.order[0]],
        };
        // R = R_i(a) R_j(b) R_k(c); e = +1 for a cyclic order (xyz, yzx, zxy), -1 otherwise.
        let m = r.matrix();
        let e = if (j + 3 - i) % 3 == 1 { 1.0 } else { -1.0 };
        let b = (e * m[(i, k)]).clamp(-1.0, 1.0).asin();
        let a = (-e * m[(j, k)]).atan2(m[(k, k)]);
        let c = (-e * m[(i, j)]).atan2(m[(i, i)]);
        let mut angles = [0.0; 3];
        angles[i] = a;
        angles[j] = b;
        angles[k] = c;
        angles
    }

    /// Every convention with three distinct axes: fixed and intrinsic, six orders each.
    pub fn all() -> Vec<Self> {
        let orders = [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ];
        [EulerKind::Fixed, EulerKind::Intrinsic]
            .into_iter()
            .flat_map(|kind| orders.map(|order| Self { kind, order }))
            .collect()
    }

    /// The convention as a data profile writes it: `euler = "fixed", order = "xyz"`.
    pub fn name(&self) -> String {
        let order: String = self.order.iter().map(|a| ['x', 'y', 'z'][*a % 3]).collect();
        let kind = match self.kind {
            EulerKind::Fixed => "fixed",
            EulerKind::Intrinsic => "intrinsic",
        };
        format!("euler = \"{kind}\", order = \"{order}\"")
    }

    fn parse(kind: EulerKind, order: &str) -> Option<Self> {
        let mut axes = [0; 3];
        let mut chars = order.chars();
        for axis in &mut axes {
            *axis = match chars.next()?.to_ascii_lowercase() {
                'x' => 0,
                'y' => 1,
                'z' => 2,
                _ => return None,
            };
        }
        let distinct = axes[0] != axes[1] && axes[1] != axes[2] && axes[0] != axes[2];
        (chars.next().is_none() && distinct).then_some(Self { kind, order: axes })
    }
}

/// The frame the measurements are expressed in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DataFrame {
    /// The robot's base frame (simulated data, or data already transformed).
    Base,
    /// The tracker's own frame: the base frame is identified.
    Tracker,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileFile {
    #[serde(default)]
    description: Option<String>,
    #[serde(default = "comma")]
    delimiter: String,
    #[serde(default = "point")]
    decimal: String,
    #[serde(default)]
    frame: Option<DataFrame>,
    #[serde(default)]
    columns: Option<toml::Table>,
    #[serde(default)]
    orientation: Option<OrientationEntry>,
    #[serde(default)]
    instrument: Option<Instrument>,
}

/// The measuring instrument (`[instrument]` of a data profile): its name and its maximum
/// permissible error as its maker states it, `MPE = mpe_um + mpe_um_per_m * distance` (a laser
/// tracker's, such as 15 um + 6 um/m), read as a 95 % bound (k = 2) on each coordinate of a
/// measured point: the noise of a point at `distance` from the instrument is `MPE / 2` (1 sigma).
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Instrument {
    /// What measured the data (maker, model, probe).
    #[serde(default)]
    pub name: Option<String>,
    /// The instrument's serial number (stated on the calibration certificate).
    #[serde(default)]
    pub serial: Option<String>,
    /// The constant part of the maximum permissible error, um.
    pub mpe_um: f64,
    /// The part that grows with the distance from the instrument, um per m.
    #[serde(default)]
    pub mpe_um_per_m: f64,
    /// The number of the instrument's own calibration certificate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub certificate: Option<String>,
    /// The date the instrument's calibration falls due, `YYYY-MM-DD`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration_due: Option<String>,
}

impl Instrument {
    /// The noise (1 sigma per coordinate, mm) of a point `distance_mm` from the instrument.
    pub fn sigma_mm(&self, distance_mm: f64) -> f64 {
        (self.mpe_um + self.mpe_um_per_m * distance_mm / 1000.0) / 1000.0 / 2.0
    }

    /// Checked: finite, the constant part above 0 and below 10 mm, the distance part 0 to 1 mm/m.
    fn check(&self) -> Result<(), String> {
        if !(self.mpe_um.is_finite() && self.mpe_um > 0.0 && self.mpe_um <= 10_000.0) {
            return Err(format!(
                "[instrument]: mpe_um = {} is not a maximum permissible error above 0 and at most 10000 um",
                self.mpe_um
            ));
        }
        if !(self.mpe_um_per_m.is_finite() && (0.0..=1000.0).contains(&self.mpe_um_per_m)) {
            return Err(format!(
                "[instrument]: mpe_um_per_m = {} is not 0 to 1000 um per m",
                self.mpe_um_per_m
            ));
        }
        if let Some(due) = &self.calibration_due {
            crate::io::dates::date(due)
                .map_err(|e| format!("[instrument]: calibration_due = {due:?}: {e}"))?;
        }
        Ok(())
    }

    /// Whether its calibration was due before `date` (`YYYY-MM-DD` or RFC 3339); `None` when
    /// either date is unknown.
    pub fn overdue_on(&self, date: &str) -> Option<bool> {
        let due = crate::io::dates::date(self.calibration_due.as_deref()?).ok()?;
        let on = crate::io::dates::date(date.get(..10)?).ok()?;
        Some(on > due)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OrientationEntry {
    euler: EulerKind,
    order: String,
}

fn comma() -> String {
    ",".into()
}
fn point() -> String {
    ".".into()
}

/// How a derived column combines its two source columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Combination {
    /// `first + second`.
    Sum,
    /// `first - second`.
    Difference,
}

/// One of our columns computed from two source columns, in the unit of our column (for
/// example a reached position given as the commanded target plus the measured deviation).
#[derive(Clone, Debug, PartialEq)]
pub struct Derived {
    /// Our column (`x_mm`, ...).
    pub ours: String,
    /// Sum or difference.
    pub combination: Combination,
    /// The two source columns.
    pub sources: [String; 2],
}

impl Derived {
    /// `{ sum = ["a", "b"] }` or `{ difference = ["a", "b"] }` for our column `ours`.
    fn parse(ours: &str, table: &toml::Table) -> Result<Self, String> {
        let usage = format!(
            "[columns]: {ours} = {{ sum = [\"a\", \"b\"] }} or {{ difference = [\"a\", \"b\"] }} (two source columns)"
        );
        let mut entries = table.iter();
        let (Some((kind, sources)), None) = (entries.next(), entries.next()) else {
            return Err(usage);
        };
        let combination = match kind.as_str() {
            "sum" => Combination::Sum,
            "difference" => Combination::Difference,
            _ => return Err(usage),
        };
        let names: Vec<&str> = sources
            .as_array()
            .map(|a| a.iter().filter_map(toml::Value::as_str).collect())
            .unwrap_or_default();
        match names[..] {
            [a, b] if sources.as_array().is_some_and(|s| s.len() == 2) => Ok(Self {
                ours: ours.to_string(),
                combination,
                sources: [a.to_string(), b.to_string()],
            }),
            _ => Err(usage),
        }
    }

    /// The combined value.
    pub(crate) fn combine(&self, first: f64, second: f64) -> f64 {
        match self.combination {
            Combination::Sum => first + second,
            Combination::Difference => first - second,
        }
    }

    /// `a + b` or `a - b`, for messages.
    pub fn describe(&self) -> String {
        let sign = match self.combination {
            Combination::Sum => '+',
            Combination::Difference => '-',
        };
        format!("{} {sign} {}", self.sources[0], self.sources[1])
    }
}

/// How to read a tracker data file.
#[derive(Clone, Debug, PartialEq)]
pub struct DataProfile {
    /// Where the profile came from (`None`: our built-in format, docs/ARCHITECTURE.md).
    pub path: Option<PathBuf>,
    /// What the profile is for.
    pub description: Option<String>,
    /// Field delimiter.
    pub delimiter: u8,
    /// Decimal separator, `.` or `,`.
    pub decimal: u8,
    /// The frame of the data, when the profile says it (overrides a `# frame:` comment).
    pub frame: Option<DataFrame>,
    /// `(our column name, source column name)`; `None`: the file uses our column names.
    pub columns: Option<Vec<(String, String)>>,
    /// Our columns computed from two source columns each (`x_mm = { sum = ["target_x", "dx"] }`).
    pub derived: Vec<Derived>,
    /// The Euler convention of `rx, ry, rz` columns.
    pub euler: EulerConvention,
    /// The measuring instrument and its stated error (`[instrument]`), when the profile names it.
    pub instrument: Option<Instrument>,
}

impl Default for DataProfile {
    fn default() -> Self {
        Self {
            path: None,
            description: None,
            delimiter: b',',
            decimal: b'.',
            frame: None,
            columns: None,
            derived: Vec::new(),
            euler: EulerConvention::FIXED_XYZ,
            instrument: None,
        }
    }
}

impl DataProfile {
    /// Reads and checks a profile file.
    pub fn read(path: &Path) -> Result<Self, ProfileError> {
        let text = crate::io::input::read_text(path, crate::io::input::Input::Document).map_err(
            |source| ProfileError::Read {
                path: path.to_owned(),
                source,
            },
        )?;
        Self::parse(&text, path)
    }

    /// Parses profile text; `path` only names the source in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ProfileError> {
        let invalid = |message: String| ProfileError::Invalid {
            path: path.to_owned(),
            message,
        };
        let file: ProfileFile = toml::from_str(text)
            .map_err(|e| invalid(e.to_string().trim_end().replace('\n', " ")))?;
        let single = |value: &str, what: &str| -> Result<u8, ProfileError> {
            match value.as_bytes() {
                [b] if b.is_ascii() && *b != b'\n' && *b != b'"' => Ok(*b),
                _ => Err(invalid(format!(
                    "{what} must be one ASCII character, got \"{value}\""
                ))),
            }
        };
        let delimiter = if file.delimiter == "\\t" || file.delimiter == "tab" {
            b'\t'
        } else {
            single(&file.delimiter, "delimiter")?
        };
        let decimal = single(&file.decimal, "decimal")?;
        if decimal != b'.' && decimal != b',' {
            return Err(invalid(format!(
                "decimal must be \".\" or \",\", got \"{}\"",
                file.decimal
            )));
        }
        if decimal == delimiter {
            return Err(invalid(
                "decimal and delimiter are the same character; a file with decimal commas needs another delimiter (e.g. \";\")".into(),
            ));
        }
        let mut derived = Vec::new();
        let columns = match file.columns {
            None => None,
            Some(table) => {
                let mut list = Vec::with_capacity(table.len());
                for (ours, source) in table {
                    if let Some(combined) = source.as_table() {
                        if !crate::io::columns::is_known_column(&ours) {
                            return Err(invalid(format!(
                                "[columns]: \"{ours}\" is not one of our columns"
                            )));
                        }
                        derived.push(Derived::parse(&ours, combined).map_err(invalid)?);
                        continue;
                    }
                    let source = source.as_str().ok_or_else(|| {
                        invalid(format!(
                            "[columns]: {ours} must name a source column as a string, or combine two: {ours} = {{ sum = [\"a\", \"b\"] }} or {{ difference = [\"a\", \"b\"] }}"
                        ))
                    })?;
                    if !crate::io::columns::is_known_column(&ours) {
                        return Err(invalid(format!(
                            "[columns]: \"{ours}\" is not one of our columns; expected q<i>_deg or q<i>_rad, x_mm/y_mm/z_mm (or _m), qw/qx/qy/qz, rx_deg/ry_deg/rz_deg (or _rad), id, weight"
                        )));
                    }
                    if let Some((other, _)) = list.iter().find(|(_, s)| s == source) {
                        return Err(invalid(format!(
                            "[columns]: source column \"{source}\" is mapped twice ({other} and {ours})"
                        )));
                    }
                    list.push((ours, source.to_string()));
                }
                Some(list)
            }
        };
        let euler = match file.orientation {
            None => EulerConvention::FIXED_XYZ,
            Some(o) => EulerConvention::parse(o.euler, &o.order).ok_or_else(|| {
                invalid(format!(
                    "[orientation]: order must be three distinct axes such as \"xyz\" or \"zyx\", got \"{}\"",
                    o.order
                ))
            })?,
        };
        if let Some(instrument) = &file.instrument {
            instrument.check().map_err(invalid)?;
        }
        Ok(Self {
            path: Some(path.to_owned()),
            description: file.description,
            delimiter,
            decimal,
            frame: file.frame,
            columns,
            derived,
            euler,
            instrument: file.instrument,
        })
    }

    /// Reads the profile at `path`, or the built-in format without one.
    pub fn load(path: Option<&Path>) -> Result<Self, ProfileError> {
        path.map_or_else(|| Ok(Self::default()), Self::read)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_convention_recovers_its_angles() {
        // Every angle within +-90 deg, so that each is the middle one of some convention.
        let angles = [0.3, -0.7, 1.2];
        for convention in EulerConvention::all() {
            let r = convention.rotation(angles);
            let back = convention.angles(&r);
            assert!(
                (convention.rotation(back).matrix() - r.matrix()).norm() < 1e-12,
                "{}",
                convention.name()
            );
            for (a, b) in angles.iter().zip(back) {
                assert!((a - b).abs() < 1e-12, "{}: {back:?}", convention.name());
            }
        }
    }

    #[test]
    fn conventions_compose_in_the_stated_order() {
        let (a, b, c) = (0.3, -0.7, 1.1);
        let rx = Rotation3::from_axis_angle(&Vector3::x_axis(), a);
        let ry = Rotation3::from_axis_angle(&Vector3::y_axis(), b);
        let rz = Rotation3::from_axis_angle(&Vector3::z_axis(), c);
        let fixed = EulerConvention::FIXED_XYZ.rotation([a, b, c]);
        assert!((fixed.matrix() - (rz * ry * rx).matrix()).norm() < 1e-15);
        // nalgebra's from_euler_angles(roll, pitch, yaw) is R = Rz Ry Rx as well.
        let nalgebra = Rotation3::from_euler_angles(a, b, c);
        assert!((fixed.matrix() - nalgebra.matrix()).norm() < 1e-15);
        let intrinsic = EulerConvention::parse(EulerKind::Intrinsic, "XYZ").unwrap();
        assert!((intrinsic.rotation([a, b, c]).matrix() - (rx * ry * rz).matrix()).norm() < 1e-15);
        let zyx = EulerConvention::parse(EulerKind::Intrinsic, "zyx").unwrap();
        assert!((zyx.rotation([a, b, c]).matrix() - (rz * ry * rx).matrix()).norm() < 1e-15);
        assert!(EulerConvention::parse(EulerKind::Fixed, "xyx").is_none());
        assert!(EulerConvention::parse(EulerKind::Fixed, "xy").is_none());
    }

    #[test]
    fn bad_profiles_are_refused_with_the_reason() {
        let p = Path::new("p.toml");
        let err = |t: &str| DataProfile::parse(t, p).unwrap_err().to_string();
        assert!(err("delimiter = \";;\"").contains("one ASCII character"));
        assert!(err("decimal = \",\"").contains("same character"));
        assert!(err("[columns]\nq1 = \"a\"").contains("\"q1\" is not one of our columns"));
        assert!(err("[columns]\nq1_rad = \"a\"\nq2_rad = \"a\"").contains("mapped twice"));
        assert!(
            err("[orientation]\neuler = \"intrinsic\"\norder = \"xxz\"")
                .contains("three distinct axes")
        );
        assert!(err("unknown = 1").contains("unknown field"));
        assert!(err("frame = \"world\"").contains("unknown variant"));
    }
}
