//! The `[joint_maps]` section of a robot file: each joint's map as written (sine and cosine
//! coefficients in rad, the range of readings it was identified on in degrees), read back with
//! every value checked.

use super::JointMaps;
use serde::{Deserialize, Serialize};

/// Largest magnitude of one map coefficient accepted in a robot file, rad (10 mrad; identified
/// maps are below 1 mrad in all).
pub(crate) const MAX_COEFFICIENT_RAD: f64 = 0.01;

/// Most harmonics accepted in a robot file.
pub(crate) const MAX_FILE_HARMONICS: usize = 200;

/// The `[joint_maps]` section of a robot file: each joint's angle-error map,
/// `dq(q) = sum_h sin_rad[h-1] sin(h q) + cos_rad[h-1] cos(h q)` (rad, `q` the joint reading),
/// added to the reading before the kinematics, and the range of readings it was identified on.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct JointMapsSection {
    /// Harmonics per joint, `H`.
    pub harmonics: usize,
    /// One map per joint, joint 1 first.
    pub joint: Vec<JointMapEntry>,
}

/// One joint's map in a robot file.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct JointMapEntry {
    /// `[lowest, highest]` reading of the poses the map was identified on, degrees: outside it
    /// the map is extrapolated.
    pub range_deg: [f64; 2],
    /// Coefficients of `sin(h q)`, `h = 1..H`, rad.
    pub sin_rad: Vec<f64>,
    /// Coefficients of `cos(h q)`, `h = 1..H`, rad.
    pub cos_rad: Vec<f64>,
}

impl JointMapsSection {
    /// The section of `maps`, identified on readings within `ranges` (rad, per joint).
    pub fn new(maps: &JointMaps, ranges: &[[f64; 2]]) -> Self {
        let h = maps.harmonics;
        Self {
            harmonics: h,
            joint: maps
                .coefficients
                .iter()
                .zip(ranges)
                .map(|(c, range)| JointMapEntry {
                    range_deg: range.map(f64::to_degrees),
                    sin_rad: c[..h].to_vec(),
                    cos_rad: c[h..].to_vec(),
                })
                .collect(),
        }
    }

    /// The maps of a robot of `joints` joints, checked: one per joint, `harmonics` finite
    /// coefficients within [`MAX_COEFFICIENT_RAD`] each. The error names the joint and the field.
    pub(crate) fn to_maps(&self, joints: usize) -> Result<JointMaps, String> {
        let h = self.harmonics;
        if h == 0 || h > MAX_FILE_HARMONICS {
            return Err(format!(
                "[joint_maps]: harmonics = {h}, expected 1 to {MAX_FILE_HARMONICS}"
            ));
        }
        if self.joint.len() != joints {
            return Err(format!(
                "[joint_maps]: {} [[joint_maps.joint]] tables, expected {joints} (one per joint)",
                self.joint.len()
            ));
        }
        let mut maps = JointMaps::zero(joints, h);
        for (j, (entry, c)) in self.joint.iter().zip(&mut maps.coefficients).enumerate() {
            let joint = j + 1;
            for (name, values) in [("sin_rad", &entry.sin_rad), ("cos_rad", &entry.cos_rad)] {
                if values.len() != h {
                    return Err(format!(
                        "[joint_maps] joint {joint}: {name} has {} values, expected harmonics = {h}",
                        values.len()
                    ));
                }
                if let Some(v) = values
                    .iter()
                    .find(|v| !(v.is_finite() && v.abs() <= MAX_COEFFICIENT_RAD))
                {
                    return Err(format!(
                        "[joint_maps] joint {joint}: {name} holds {v}, beyond the plausible +-{MAX_COEFFICIENT_RAD} rad of a joint's angle error"
                    ));
                }
            }
            if !(entry.range_deg.iter().all(|v| v.is_finite())
                && entry.range_deg[0] <= entry.range_deg[1])
            {
                return Err(format!(
                    "[joint_maps] joint {joint}: range_deg = {:?} is not [lowest, highest]",
                    entry.range_deg
                ));
            }
            c[..h].copy_from_slice(&entry.sin_rad);
            c[h..].copy_from_slice(&entry.cos_rad);
            // The core's checks, joint by joint (the joint count is known here at run time).
            let one = JointMaps {
                harmonics: h,
                coefficients: vec![c.clone()],
            };
            one.to_core::<f64, MAX_FILE_HARMONICS>()
                .map_err(|e| match e {
                    calib_core::KinematicsError::InvalidJointMap { .. } => {
                        calib_core::KinematicsError::InvalidJointMap {
                            joint: u8::try_from(joint).unwrap_or(u8::MAX),
                        }
                    }
                    other => other,
                })
                .map_err(|e| format!("[joint_maps]: {e}"))?;
        }
        Ok(maps)
    }

    /// Per joint, `[lowest, highest]` reading the map was identified on, rad.
    pub fn ranges(&self) -> Vec<[f64; 2]> {
        self.joint
            .iter()
            .map(|e| e.range_deg.map(f64::to_radians))
            .collect()
    }
}
