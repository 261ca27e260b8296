//! Our tracker-data column names (docs/ARCHITECTURE.md): every name carries its unit, such as
//! `q3_deg`, `x_m` or `rz_rad`. Shared by the data reader and the data profiles (whose column
//! mappings must name one of them).

/// What a column of tracker data holds, with the factor to mm or rad.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Column {
    /// Joint reading: joint index (0-based), factor to rad.
    Joint(usize, f64),
    /// Position: axis (0 = x), factor to mm.
    Position(usize, f64),
    /// Quaternion component: 0 = w, 1 = x, 2 = y, 3 = z.
    Quaternion(usize),
    /// Fixed-axis angle: axis (0 = x), factor to rad.
    Angle(usize, f64),
    /// The pose's identifier.
    Id,
    /// The pose's weight.
    Weight,
    /// The pose's role in a measurement plan (`core`, `fill`, `verify`; `calib plan`).
    Role,
    /// A target's arm configuration (`branch B`; `calib compensate`).
    Configuration,
    /// When the row was measured or logged: factor to seconds (`time_s`, `time_ms`; any epoch,
    /// the same in the files merged by time, `calib merge --by time`).
    Time(f64),
    /// The air temperature at the instrument when the row was measured, deg C (`temperature_c`;
    /// stated on the calibration certificate, not modelled).
    Temperature,
    /// A source column the data profile does not map.
    Ignored,
}

/// `true` when `name` is one of our column names (docs/ARCHITECTURE.md), such as `q3_deg` or `x_m`.
pub(crate) fn is_known_column(name: &str) -> bool {
    parse_column(name).is_some()
}

/// The meaning of one of our column names; `None` for any other name.
pub(crate) fn parse_column(name: &str) -> Option<Column> {
    let deg = std::f64::consts::PI / 180.0;
    if let Some(rest) = name.strip_prefix('q') {
        if let Some((number, unit)) = rest.split_once('_') {
            let i: usize = number.parse().ok()?;
            let scale = match unit {
                "deg" => deg,
                "rad" => 1.0,
                _ => return None,
            };
            return (i >= 1).then(|| Column::Joint(i - 1, scale));
        }
        return match rest {
            "w" => Some(Column::Quaternion(0)),
            "x" => Some(Column::Quaternion(1)),
            "y" => Some(Column::Quaternion(2)),
            "z" => Some(Column::Quaternion(3)),
            _ => None,
        };
    }
    Some(match name {
        "x_mm" => Column::Position(0, 1.0),
        "y_mm" => Column::Position(1, 1.0),
        "z_mm" => Column::Position(2, 1.0),
        "x_m" => Column::Position(0, 1000.0),
        "y_m" => Column::Position(1, 1000.0),
        "z_m" => Column::Position(2, 1000.0),
        "rx_deg" => Column::Angle(0, deg),
        "ry_deg" => Column::Angle(1, deg),
        "rz_deg" => Column::Angle(2, deg),
        "rx_rad" => Column::Angle(0, 1.0),
        "ry_rad" => Column::Angle(1, 1.0),
        "rz_rad" => Column::Angle(2, 1.0),
        "id" => Column::Id,
        "weight" => Column::Weight,
        "role" => Column::Role,
        "configuration" => Column::Configuration,
        "time_s" => Column::Time(1.0),
        "time_ms" => Column::Time(1e-3),
        "temperature_c" => Column::Temperature,
        _ => return None,
    })
}
