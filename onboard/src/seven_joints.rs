//! Compensation for a 7-joint robot on the controller: the KUKA LBR iiwa 14 R820 in
//! f32 (the shipped robot file `host-tools/robots/kuka-iiwa14.toml`: standard DH after Faria et
//! al. 2018 with KUKA's link lengths), an actual robot with errors of a few tenths of a
//! millimetre and milliradian on every joint, and four targets: the nominal poses at four
//! planned joint vectors. The firmware's `seven-joints` binary runs it and counts instructions;
//! the host computes the same bits (`tests/tests/firmware_qemu.rs` compares them).

use crate::{Error, Marks, Stage};
use calib_core::controller::compensate::{CompensationSettings, compensate_joints};
use calib_core::kinematics::pose_error::PoseError;
use calib_core::{JointErrors, JointLimits, MdhJoint};
use calib_core::{Kinematics, ParameterErrors, Robot};
use nalgebra::Const;

/// Joints of the robot.
pub const JOINTS: usize = 7;
/// Targets compensated.
pub const TARGETS: usize = 4;

/// The planned joint readings of the targets, rad (within the limits, away from singularities).
pub const TARGET_JOINTS: [[f32; JOINTS]; TARGETS] = [
    [0.3, 0.6, -0.4, -1.2, 0.5, 0.8, 0.2],
    [-1.0, -0.5, 0.7, 1.4, -0.6, -0.9, 1.1],
    [1.6, 0.9, 0.2, -0.8, 1.2, 1.0, -1.5],
    [-0.2, 1.1, -1.3, 0.6, -1.4, -0.4, 0.0],
];

/// The KUKA LBR iiwa 14 R820 in f32: a = 0, alpha = -90, 90, 90, -90, -90, 90, 0 deg, d = 360,
/// 0, 420, 0, 400, 0, 126 mm, limits +-170, +-120, +-170, +-120, +-170, +-120, +-175 deg.
pub fn iiwa14() -> Robot<f32, Const<JOINTS>> {
    let alpha = [-90.0f32, 90.0, 90.0, -90.0, -90.0, 90.0, 0.0];
    let d = [360.0f32, 0.0, 420.0, 0.0, 400.0, 0.0, 126.0];
    let limit = [170.0f32, 120.0, 170.0, 120.0, 170.0, 120.0, 175.0];
    let mut robot = Robot::<f32, Const<JOINTS>>::from_joints(core::array::from_fn(|i| MdhJoint {
        a: 0.0,
        alpha: alpha.get(i).copied().unwrap_or(0.0).to_radians(),
        theta_offset: 0.0,
        d: d.get(i).copied().unwrap_or(0.0),
        beta: 0.0,
    }));
    for (l, deg) in robot.limits.iter_mut().zip(limit) {
        *l = JointLimits {
            lower: -deg.to_radians(),
            upper: deg.to_radians(),
        };
    }
    robot
}

/// The actual robot's errors: per joint `da` and `dd` of +-0.2 to 0.5 mm and `dalpha`, `dtheta`
/// of +-0.4 to 1.0 mrad (alternating signs), no base or tool error.
pub fn errors() -> ParameterErrors<f32, Const<JOINTS>> {
    let mut errors = ParameterErrors::zero();
    for (i, e) in errors.joints.iter_mut().enumerate() {
        let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
        let step = (i % 4) as f32 + 2.0;
        *e = JointErrors {
            da: sign * 0.1 * step,
            dalpha: -sign * 2e-4 * step,
            dtheta: sign * 2e-4 * step,
            dd: -sign * 0.1 * step,
            dbeta: 0.0,
        };
    }
    errors
}

/// What the job computes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// Compensated joint readings of each target, rad (NaN where refused).
    pub compensated: [[f32; JOINTS]; TARGETS],
    /// Position residual of the actual robot at them, mm (NaN where refused).
    pub residual_mm: [f32; TARGETS],
    /// Position error of the actual robot at the planned joints (uncompensated), mm.
    pub uncompensated_mm: [f32; TARGETS],
}

impl Outcome {
    /// The bit patterns of the compensated joints, in order (what the firmware logs and the host
    /// compares).
    pub fn bits(&self) -> [u32; JOINTS * TARGETS] {
        let mut out = [0u32; JOINTS * TARGETS];
        for (o, q) in out.iter_mut().zip(self.compensated.iter().flatten()) {
            *o = q.to_bits();
        }
        out
    }
}

/// Compensates the four targets with the actual robot, each between `marks`'
/// [`Stage::Compensation`] begin and end.
pub fn run(marks: &mut impl Marks) -> Result<Outcome, Error> {
    let robot = iiwa14();
    let nominal = Kinematics::nominal(&robot).map_err(|_| Error::Problem)?;
    let actual = Kinematics::new(&robot, &errors()).map_err(|_| Error::Problem)?;
    let settings = CompensationSettings::default();
    let mut outcome = Outcome {
        compensated: [[f32::NAN; JOINTS]; TARGETS],
        residual_mm: [f32::NAN; TARGETS],
        uncompensated_mm: [f32::NAN; TARGETS],
    };
    for (((joints, out), residual), before) in TARGET_JOINTS
        .iter()
        .zip(outcome.compensated.iter_mut())
        .zip(outcome.residual_mm.iter_mut())
        .zip(outcome.uncompensated_mm.iter_mut())
    {
        let target = nominal.forward(joints).map_err(|_| Error::Problem)?;
        let reached = actual.forward(joints).map_err(|_| Error::Problem)?;
        *before = PoseError::between(&target, &reached).position.norm();
        marks.begin(Stage::Compensation);
        let result =
            compensate_joints(&nominal, &actual, &robot.limits, &target, joints, &settings);
        marks.end(Stage::Compensation);
        if let Ok(c) = result {
            let reached = actual.forward(&c.q).map_err(|_| Error::Problem)?;
            *out = c.q;
            *residual = PoseError::between(&target, &reached).position.norm();
        }
    }
    Ok(outcome)
}
