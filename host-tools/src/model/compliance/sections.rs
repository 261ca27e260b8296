//! The robot file's sections of the gravity compliance: `[dynamics]` (the masses gravity pulls
//! on) and `[compliance]` (an identified file's gains), read back with every value checked.

use super::{GAIN_COUNT, GAINS, Gain, Gravity, MAX_GAIN_URAD_PER_NM};
use crate::JOINTS;
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
    /// The masses, checked: one link per joint, masses 0-1000 kg, centres within 5 m, gravity
    /// 9-10.5 m/s^2. The error names the field.
    pub fn to_gravity(&self) -> Result<Gravity, String> {
        if self.link.len() != JOINTS {
            return Err(format!(
                "[dynamics]: {} [[dynamics.link]] tables, expected {JOINTS} (one per joint)",
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
        let mut links = [(0.0, Vector3::zeros()); JOINTS];
        for (j, (slot, entry)) in links.iter_mut().zip(&self.link).enumerate() {
            *slot = check(format!("link {}", j + 1), entry)?;
        }
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

/// The `[compliance]` section of an identified robot file, urad per N m, joint 1 first (zero
/// where not identified).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ComplianceSection {
    /// Torsion gains (joints 2-4).
    pub torsion_urad_per_nm: Vec<f64>,
    /// Tilt gains about x (joints 1-4).
    pub tilt_x_urad_per_nm: Vec<f64>,
    /// Tilt gains about y (joints 1-4).
    pub tilt_y_urad_per_nm: Vec<f64>,
}

impl ComplianceSection {
    /// The section of `gains` (in the order of [`GAINS`]).
    pub fn new(gains: &[f64; GAIN_COUNT]) -> Self {
        let mut out = Self {
            torsion_urad_per_nm: vec![0.0; JOINTS],
            tilt_x_urad_per_nm: vec![0.0; JOINTS],
            tilt_y_urad_per_nm: vec![0.0; JOINTS],
        };
        for (gain, value) in GAINS.iter().zip(gains) {
            let (list, j) = match gain {
                Gain::Torsion(j) => (&mut out.torsion_urad_per_nm, j),
                Gain::TiltX(j) => (&mut out.tilt_x_urad_per_nm, j),
                Gain::TiltY(j) => (&mut out.tilt_y_urad_per_nm, j),
            };
            list[j - 1] = *value;
        }
        out
    }

    /// The gains, checked: finite, within [`MAX_GAIN_URAD_PER_NM`], zero where the model has no
    /// gain. The error names the gain.
    pub fn to_gains(&self) -> Result<[f64; GAIN_COUNT], String> {
        for (name, list) in [
            ("torsion_urad_per_nm", &self.torsion_urad_per_nm),
            ("tilt_x_urad_per_nm", &self.tilt_x_urad_per_nm),
            ("tilt_y_urad_per_nm", &self.tilt_y_urad_per_nm),
        ] {
            if list.len() != JOINTS {
                return Err(format!(
                    "[compliance]: {name} has {} values, expected {JOINTS}",
                    list.len()
                ));
            }
        }
        let gains: [f64; GAIN_COUNT] = std::array::from_fn(|i| match GAINS[i] {
            Gain::Torsion(j) => self.torsion_urad_per_nm[j - 1],
            Gain::TiltX(j) => self.tilt_x_urad_per_nm[j - 1],
            Gain::TiltY(j) => self.tilt_y_urad_per_nm[j - 1],
        });
        if let Some((gain, value)) = GAINS
            .iter()
            .zip(&gains)
            .find(|(_, v)| !(v.is_finite() && v.abs() <= MAX_GAIN_URAD_PER_NM))
        {
            return Err(format!(
                "[compliance]: the {gain} is {value} urad/(N m), beyond the plausible +-{MAX_GAIN_URAD_PER_NM}"
            ));
        }
        if ComplianceSection::new(&gains) != *self {
            return Err(
                "[compliance]: a gain is set where the model has none (torsion: joints 2-4; tilts: joints 1-4)"
                    .into(),
            );
        }
        Ok(gains)
    }
}
