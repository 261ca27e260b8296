//! The robot of the source paper, the Efort ER10L-C10: nominal geometry (Table 1) and the
//! geometric errors of its simulation (Table 2). Used by the paper's simulation, the benchmarks
//! and the firmware; the tests check these values against the copies of the paper's tables.

use crate::model::parameters::{JointErrors, ParameterErrors};
use crate::model::{MdhJoint, Robot};
use crate::scalar::Real;
use nalgebra::U6;

const DEG: f64 = core::f64::consts::PI / 180.0;

/// Table 1: (a mm, alpha deg, theta_offset deg, d mm).
const TABLE1: [(f64, f64, f64, f64); 6] = [
    (170.0, -90.0, 0.0, 0.0),
    (780.0, 0.0, -90.0, 0.0),
    (140.0, -90.0, 0.0, 0.0),
    (0.0, 90.0, 0.0, 1060.0),
    (0.0, -90.0, 0.0, 0.0),
    (0.0, 0.0, 0.0, 125.0),
];

/// Table 2: (da mm, dalpha rad, dtheta rad, dd mm, dbeta rad).
const TABLE2: [(f64, f64, f64, f64, f64); 6] = [
    (-0.4751, 0.0058, 0.0091, -0.4221, 0.0),
    (0.2565, 0.0092, -0.0003, 0.0, -0.0028),
    (-0.3366, 0.0031, 0.0060, 0.3409, 0.0),
    (-0.1827, -0.0093, -0.0072, 0.1420, 0.0),
    (-0.1117, 0.0070, -0.0016, 0.1753, 0.0),
    (-0.2536, 0.0087, 0.0083, 0.1531, 0.0),
];

/// The nominal ER10L-C10 of Table 1 (mm, rad): no joint limits, identity base and tool.
pub fn er10l_c10<T: Real>() -> Robot<T, U6> {
    Robot::from_joints(TABLE1.map(|(a, alpha, offset, d)| MdhJoint {
        a: T::of(a),
        alpha: T::of(alpha * DEG),
        theta_offset: T::of(offset * DEG),
        d: T::of(d),
        beta: T::zero(),
    }))
}

/// The parameter errors of Table 2 (mm, rad); base and tool errors zero.
pub fn table2<T: Real>() -> ParameterErrors<T, U6> {
    let mut errors = ParameterErrors::zero();
    errors.joints = TABLE2.map(|(da, dalpha, dtheta, dd, dbeta)| JointErrors {
        da: T::of(da),
        dalpha: T::of(dalpha),
        dtheta: T::of(dtheta),
        dd: T::of(dd),
        dbeta: T::of(dbeta),
    });
    errors
}

/// The ER10L-C10 on a tilted base with an offset probe, to exercise the frame terms in tests.
#[cfg(test)]
pub(crate) fn er10l_with_frames() -> Robot<f64, U6> {
    let mut robot = er10l_c10::<f64>();
    robot.base = crate::model::FramePose {
        xyz: [1500.0, -300.0, 250.0],
        rpy: [0.2, -0.4, 2.5],
    };
    robot.tool = crate::model::FramePose {
        xyz: [12.0, -30.0, 85.0],
        rpy: [1.1, 0.3, -0.7],
    };
    robot
}

/// The noise-free simulation of the paper's section 3.1 for tests: 32 joint vectors uniform in
/// [-pi, pi] (seeded), measured as full poses of the robot with Table 2 errors.
#[cfg(test)]
pub(crate) fn paper_measurements<T: Real>(
    seed: u64,
) -> crate::identify::objective::MeasurementSet<T, U6, 32> {
    use crate::identify::objective::{Measurement, MeasurementSet};
    use rand_core::{Rng, SeedableRng};
    let truth = crate::Kinematics::new(&er10l_c10::<T>(), &table2::<T>()).unwrap();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut set = MeasurementSet::new();
    for _ in 0..32 {
        let q = [(); 6].map(|_| {
            T::of(core::f64::consts::PI * (2.0 * f64::unit_from_bits(rng.next_u64()) - 1.0))
        });
        let m = Measurement::from_pose(&q, &truth.forward(&q).unwrap()).unwrap();
        set.push(m).unwrap();
    }
    set
}
