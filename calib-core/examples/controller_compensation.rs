//! The controller side, in f32 as on a Cortex-M4F: the identified model arrives as a parameter
//! block (what `calib export --format block` writes) in one of two flash slots; at start-up the
//! controller loads the newest valid block, then corrects every commanded pose by joint-space
//! compensation. Checks its own result: the identified (real) robot reaches each target within
//! the f32 tolerance of 1e-2 mm and 1e-5 rad, where the uncorrected joints miss by millimetres.
//!
//! `cargo run --release -p calib-core --example controller_compensation`

use calib_core::controller::compensate::{CompensationSettings, compensate_joints};
use calib_core::controller::storage::{self, FlashSlots, Slot, Source, StorageError};
use calib_core::kinematics::pose_error::PoseError;
use calib_core::model::paper;
use calib_core::{Kinematics, Robot};
use nalgebra::U6;
use std::process::ExitCode;

/// Two flash slots in RAM (on a controller: two flash sectors behind its driver).
struct Flash([Vec<u8>; 2]);

impl FlashSlots for Flash {
    fn read(&self, slot: Slot) -> &[u8] {
        self.0.get(slot as usize).map_or(&[], Vec::as_slice)
    }
    fn write(&mut self, slot: Slot, data: &[u8]) -> Result<(), StorageError> {
        let region = self.0.get_mut(slot as usize).ok_or(StorageError::Flash)?;
        *region = data.to_vec();
        Ok(())
    }
}

fn main() -> Result<ExitCode, Box<dyn std::error::Error>> {
    // The model the controller plans with, and the identified one (a tenth of Table 2's errors,
    // the size a calibrated production robot corrects).
    let nominal: Robot<f32, U6> = paper::er10l_c10();
    let errors = paper::table2::<f32>();
    let mut identified = nominal;
    for (joint, e) in identified.joints.iter_mut().zip(&errors.joints) {
        joint.a += 0.1 * e.da;
        joint.alpha += 0.1 * e.dalpha;
        joint.theta_offset += 0.1 * e.dtheta;
        joint.d += 0.1 * e.dd;
        joint.beta += 0.1 * e.dbeta;
    }
    // Commissioning: the block goes into the slot without the newest valid block.
    let mut flash = Flash([Vec::new(), Vec::new()]);
    let mut buffer = [0u8; storage::block_len::<f32>(6)];
    let (slot, sequence) = storage::store(&mut flash, &identified, &mut buffer)?;
    println!("stored the identified model in slot {slot:?}, sequence {sequence}");

    // Start-up: the newest valid block, or the nominal model when there is none.
    let (actual, source) = storage::load(&flash, &nominal);
    println!("loaded {source:?}");
    let mut ok = source == Source::Newest(Slot::A, 1) && actual == identified;

    let planned = Kinematics::nominal(&nominal)?;
    let real = Kinematics::nominal(&actual)?;
    let settings = CompensationSettings::<f32>::default();
    for q0 in [
        [0.3f32, -0.4, 0.5, 0.2, 0.9, -0.3],
        [-1.2, 0.3, -0.2, 1.0, -0.7, 2.0],
        [2.0, -0.9, 0.8, -1.5, 1.1, 0.4],
    ] {
        // The planner's joints for a target, by the nominal model.
        let target = planned.forward(&q0)?;
        let missed = PoseError::between(&target, &real.forward(&q0)?);
        let corrected =
            compensate_joints(&planned, &real, &nominal.limits, &target, &q0, &settings)?;
        let reached = PoseError::between(&target, &real.forward(&corrected.q)?);
        let (mm, rad) = (reached.position.norm(), reached.rotation.norm());
        let good = mm <= 1e-2 && rad <= 1e-5 && missed.position.norm() > 0.5;
        ok &= good;
        println!(
            "target {q0:?}: uncorrected {:.3} mm off, compensated {mm:.2e} mm, {rad:.2e} rad in {} iterations {}",
            missed.position.norm(),
            corrected.iterations,
            if good { "ok" } else { "WRONG" }
        );
    }
    println!("{}", if ok { "PASS" } else { "FAIL" });
    Ok(if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
