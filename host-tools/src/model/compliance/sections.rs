//! The robot file's sections of the gravity compliance: `[dynamics]` (the masses gravity pulls
//! on) and `[compliance]` (an identified file's gains), read back with every value checked.

use super::{Gain, Gravity, MAX_GAIN_URAD_PER_NM, gains};
use crate::model::counts::JOINT_COUNTS;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// A mass and its centre, as a robot file gives it.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MassEntry {
    /// Mass, kg.
    pub mass_kg: f64,
    /// Centre of mass, mm: for a link in the frame after its joint's transform, for the tool's
    /// load in the flange frame.
    pub com_mm: [f64; 3],
}

/// The `[dynamics]` section of a robot file: what gravity pulls on.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsSection {
    /// Gravity in the robot's base frame, m/s^2 (upright: `[0, 0, -9.81]`).
    pub gravity_mps2: [f64; 3],
    /// One entry per link, link 1 (moved by joint 1) first.
    pub link: Vec<MassEntry>,
    /// What the flange carries while measured (probe or reflector and its mount).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool: Option<MassEntry>,
}

impl DynamicsSection {
    /// The masses, checked: one link per joint of a robot of `joints` joints, masses 0-1000 kg,
    /// centres within 5 m, gravity 9-10.5 m/s^2. The error names the field.
    pub fn to_gravity(&self, joints: usize) -> Result<Gravity, String> {
        if self.link.len() != joints || !JOINT_COUNTS.contains(&joints) {
            return Err(format!(
                "[dynamics]: {} [[dynamics.link]] tables, expected {joints} (one per joint)",
                self.link.len()
            ));
        }
        let g = Vector3::from(self.gravity_mps2);
        if !(g.iter().all(|v| v.is_finite()) && (9.0..=10.5).contains(&g.norm())) {
            return Err(format!(
                "[dynamics]: gravity_mps2 = {:?} is not a gravity vector (magnitude 9 to 10.5 m/s^2, in the base frame)",
                self.gravity_mps2
            ));
        }
        let check = |what: String, m: &MassEntry| -> Result<(f64, Vector3<f64>), String> {
            if !(m.mass_kg.is_finite() && (0.0..=1000.0).contains(&m.mass_kg)) {
                return Err(format!(
                    "[dynamics] {what}: mass_kg = {} is not 0 to 1000",
                    m.mass_kg
                ));
            }
            if !m.com_mm.iter().all(|v| v.is_finite() && v.abs() <= 5000.0) {
                return Err(format!(
                    "[dynamics] {what}: com_mm = {:?} is not within 5000 mm",
                    m.com_mm
                ));
            }
            Ok((m.mass_kg, Vector3::from(m.com_mm)))
        };
        let links = (self.link.iter().enumerate())
            .map(|(j, entry)| check(format!("link {}", j + 1), entry))
            .collect::<Result<Vec<_>, String>>()?;
        let tool = match &self.tool {
            Some(t) => check("tool".into(), t)?,
            None => (0.0, Vector3::zeros()),
        };
        Ok(Gravity {
            gravity: g,
            links,
            tool,
        })
    }
}

/// The `[compliance]` section of an identified robot file, urad per N m, one value per joint,
/// joint 1 first (zero where the model has no gain: [`gains`]).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ComplianceSection {
    /// Torsion gains (joints 2 to N - 2).
    pub torsion_urad_per_nm: Vec<f64>,
    /// Tilt gains about x (joints 1 to N - 2).
    pub tilt_x_urad_per_nm: Vec<f64>,
    /// Tilt gains about y (joints 1 to N - 2).
    pub tilt_y_urad_per_nm: Vec<f64>,
}

impl ComplianceSection {
    /// The section of `values` (in the order of [`gains`]) of a robot of `joints` joints.
    pub fn new(values: &[f64], joints: usize) -> Self {
        let mut out = Self {
            torsion_urad_per_nm: vec![0.0; joints],
            tilt_x_urad_per_nm: vec![0.0; joints],
            tilt_y_urad_per_nm: vec![0.0; joints],
        };
        for (gain, value) in gains(joints).iter().zip(values) {
            let (list, j) = match gain {
                Gain::Torsion(j) => (&mut out.torsion_urad_per_nm, j),
                Gain::TiltX(j) => (&mut out.tilt_x_urad_per_nm, j),
                Gain::TiltY(j) => (&mut out.tilt_y_urad_per_nm, j),
            };
            list[j - 1] = *value;
        }
        out
    }

    /// The gains of a robot of `joints` joints, checked: finite, within
    /// [`MAX_GAIN_URAD_PER_NM`], zero where the model has no gain. The error names the gain.
    pub fn to_gains(&self, joints: usize) -> Result<Vec<f64>, String> {
        for (name, list) in [
            ("torsion_urad_per_nm", &self.torsion_urad_per_nm),
            ("tilt_x_urad_per_nm", &self.tilt_x_urad_per_nm),
            ("tilt_y_urad_per_nm", &self.tilt_y_urad_per_nm),
        ] {
            if list.len() != joints {
                return Err(format!(
                    "[compliance]: {name} has {} values, expected {joints} (one per joint)",
                    list.len()
                ));
            }
        }
        let model = gains(joints);
        let values: Vec<f64> = (model.iter())
            .map(|gain| match gain {
                Gain::Torsion(j) => self.torsion_urad_per_nm[j - 1],
                Gain::TiltX(j) => self.tilt_x_urad_per_nm[j - 1],
                Gain::TiltY(j) => self.tilt_y_urad_per_nm[j - 1],
            })
            .collect();
        if let Some((gain, value)) = (model.iter().zip(&values))
            .find(|(_, v)| !(v.is_finite() && v.abs() <= MAX_GAIN_URAD_PER_NM))
        {
            return Err(format!(
                "[compliance]: the {gain} is {value} urad/(N m), beyond the plausible +-{MAX_GAIN_URAD_PER_NM}"
            ));
        }
        if ComplianceSection::new(&values, joints) != *self {
            let last = joints.saturating_sub(2);
            return Err(format!(
                "[compliance]: a gain is set where the model has none (torsion: joints 2-{last}; tilts: joints 1-{last})"
            ));
        }
        Ok(values)
    }
}
