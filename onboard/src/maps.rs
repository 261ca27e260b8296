//! The controller's compensation beyond geometry, in f32, exactly as the firmware runs it: the
//! UR10's nominal model (a version 1 parameter block, the controller's plan) and its model with
//! joint maps identified on 50 poses of Series B (a version 2 block), or with joint maps and
//! gravity compliance (a version 2 block with the compliance section), are loaded from embedded
//! bytes, and four targets (the nominal pose at joint readings within Series B's ranges) are
//! compensated with the model.
//!
//! The blocks are `calib export --format block --scalar f32` of `data/ur10-series-b-maps.toml`,
//! `data/ur10-series-b-compliance.toml` and `host-tools/robots/ur10.toml` (the host test
//! `tests/tests/onboard.rs` checks that they still are).

use crate::{Error, Marks, Stage, TARGETS};
use calib_core::Kinematics;
use calib_core::controller::compensate::{CompensationSettings, compensate_joints};
use calib_core::controller::storage::{ControllerModel, decode, decode_model_into};
use nalgebra::U6;

/// The UR10's nominal model, version 1 block (f32).
pub const NOMINAL_BLOCK: &[u8] = include_bytes!("../data/ur10-nominal.calb");

/// The UR10 with joint maps from Series B (50 poses), version 2 block (f32, 30 harmonics).
pub const MAPS_BLOCK: &[u8] = include_bytes!("../data/ur10-series-b-maps.calb");

/// The UR10 with joint maps and gravity compliance from Series B (the same 50 poses), version 2
/// block with the compliance section (f32, 30 harmonics).
pub const COMPLIANCE_BLOCK: &[u8] = include_bytes!("../data/ur10-series-b-compliance.calb");

/// Harmonics per joint this build has room for.
pub const CAPACITY: usize = 64;

/// Joint readings of the targets, rad: within Series B's ranges, where the maps were identified.
pub const TARGET_JOINTS: [[f32; 6]; TARGETS] = [
    [-1.7, -1.0, 0.4, -1.8, -1.0, 0.2],
    [-1.4, -1.6, 1.2, -1.2, -0.8, 0.4],
    [-2.2, -0.5, -0.6, -2.5, -1.6, -0.3],
    [-1.2, -2.0, 1.8, -0.6, -0.4, 0.5],
];

/// What the compensation with maps computes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapsOutcome {
    /// Harmonics per joint of the loaded maps.
    pub harmonics: u32,
    /// Compensated joint readings per target, rad (NaN where compensation failed).
    pub compensated: [[f32; 6]; TARGETS],
    /// Remaining position error per target, mm (NaN where compensation failed).
    pub residual_mm: [f32; TARGETS],
}

/// Length of [`MapsOutcome::encode`]'s output, bytes.
pub const MAPS_ENCODED_LEN: usize = 4 * (1 + TARGETS * 6 + TARGETS);

/// The expected outcome, written by the host test `tests/tests/onboard.rs`. On the controller in
/// the job's data region (`.calib_data`, with the measurements): test data, not program.
#[cfg_attr(target_os = "none", unsafe(link_section = ".calib_data"))]
pub static MAPS_EXPECTED: [u8; include_bytes!("../expected-maps.bin").len()] =
    *include_bytes!("../expected-maps.bin");

/// The expected outcome with [`COMPLIANCE_BLOCK`], as [`MAPS_EXPECTED`].
#[cfg_attr(target_os = "none", unsafe(link_section = ".calib_data"))]
pub static COMPLIANCE_EXPECTED: [u8; include_bytes!("../expected-compliance.bin").len()] =
    *include_bytes!("../expected-compliance.bin");

impl MapsOutcome {
    /// Little-endian bytes of every field, in declaration order.
    pub fn encode(&self) -> [u8; MAPS_ENCODED_LEN] {
        let words = core::iter::once(self.harmonics)
            .chain(self.compensated.iter().flatten().map(|v| v.to_bits()))
            .chain(self.residual_mm.iter().map(|v| v.to_bits()));
        crate::encode_words(words)
    }

    /// `true` when the encoded outcome equals `expected` ([`MAPS_EXPECTED`],
    /// [`COMPLIANCE_EXPECTED`]) bit for bit.
    pub fn matches(&self, expected: &[u8]) -> bool {
        self.encode().as_slice() == expected
    }
}

/// Loads both blocks ([`NOMINAL_BLOCK`] and [`MAPS_BLOCK`], or the firmware's copies in its
/// parameter region) and compensates the targets with the maps.
pub fn compensate_with_maps(
    nominal_block: &[u8],
    maps_block: &[u8],
    marks: &mut impl Marks,
) -> Result<MapsOutcome, Error> {
    let (nominal_robot, _) = decode::<f32, U6>(nominal_block).map_err(|_| Error::Block)?;
    // The model starts as the nominal one and is replaced in place by the block's.
    let mut model = ControllerModel::<f32, U6, CAPACITY>::geometric(nominal_robot);
    decode_model_into(maps_block, &mut model).map_err(|_| Error::Block)?;
    let nominal = Kinematics::nominal(&nominal_robot).map_err(|_| Error::Block)?;
    let actual = model.kinematics().map_err(|_| Error::Block)?;
    let settings = CompensationSettings::default();
    let mut out = MapsOutcome {
        harmonics: u32::try_from(model.maps.harmonics()).unwrap_or(u32::MAX),
        compensated: [[f32::NAN; 6]; TARGETS],
        residual_mm: [f32::NAN; TARGETS],
    };
    for ((joints, q), residual) in TARGET_JOINTS
        .iter()
        .zip(out.compensated.iter_mut())
        .zip(out.residual_mm.iter_mut())
    {
        let Ok(target) = nominal.forward(joints) else {
            continue;
        };
        marks.begin(Stage::MapsCompensation);
        let result = compensate_joints(
            &nominal,
            &actual,
            &nominal_robot.limits,
            &target,
            joints,
            &settings,
        );
        marks.end(Stage::MapsCompensation);
        if let Ok(c) = result {
            *q = c.q;
            *residual = c.residual_mm;
        }
    }
    Ok(out)
}
