//! The comparison of identified parameters against a known truth (simulated data, or a robot
//! file of the errors): one row per parameter, in mm or rad.

use calib_core::Parameter;
use serde::Serialize;

/// One row of the comparison against a known truth (mm or rad).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct TruthRow {
    /// Parameter name.
    pub name: String,
    /// Unit: `mm` or `rad`.
    pub unit: String,
    /// Identified error.
    pub identified: f64,
    /// True error.
    pub truth: f64,
    /// `identified - truth`.
    pub difference: f64,
}

impl TruthRow {
    /// A comparison row.
    pub fn new(parameter: Parameter, identified: f64, truth: f64) -> Self {
        Self {
            name: parameter.to_string(),
            unit: unit_of(parameter).to_string(),
            identified,
            truth,
            difference: identified - truth,
        }
    }
}

/// `mm` for lengths, `rad` for angles.
pub fn unit_of(parameter: Parameter) -> &'static str {
    if parameter.is_angle() { "rad" } else { "mm" }
}
