//! The orientation-convention check of 6-DoF data, before any calibration: the rotation between
//! two measured poses, `R_i^T R_j`, is that of the robot's flange, `F_i^T F_j`, seen through the
//! probe's mounting (`R = R_base F R_tool`): it does not depend on the tracker's placement, and
//! the probe's rotation is fitted. The nominal model predicts these rotations to within its
//! geometric errors (a degree or two); data read under a wrong Euler convention, quaternion order
//! or inverted quaternions miss them by more. The check names the conventions under which the
//! data would agree.

use crate::io::profile::EulerConvention;
use crate::io::tracker_data::OrientationColumns;
use crate::measurement::dataset::Dataset;
use calib_core::Kinematics;
use nalgebra::Dyn;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// Median disagreement (deg) of the relative rotation angles beyond which the orientations are
/// refused: a nominal model misses them by at most a degree or two.
pub(crate) const MAX_MEDIAN_DISAGREEMENT_DEG: f64 = 5.0;

/// Median disagreement (deg) below which the data are accepted without trying other readings.
pub(crate) const MIN_CHECKED_DISAGREEMENT_DEG: f64 = 0.5;

/// Above [`MIN_CHECKED_DISAGREEMENT_DEG`], the data are refused when another reading agrees this
/// many times better (UR10 Series B read as fixed instead of intrinsic xyz: 2.35 deg against
/// 0.11 deg; Series D: 2.18 against 0.14 deg).
pub(crate) const BETTER_BY: f64 = 3.0;

/// Pose pairs compared at most.
const PAIRS: usize = 2000;

/// The rotation part of `m` as the vector of its skew-symmetric part, `vee(M - M^T) / 2`
/// (`sin(angle) * axis`): unambiguous at every angle, and `vee` of `A M A^T` is `A vee(M)`.
fn skew_vector(m: &Matrix3<f64>) -> Vector3<f64> {
    Vector3::new(
        m[(2, 1)] - m[(1, 2)],
        m[(0, 2)] - m[(2, 0)],
        m[(1, 0)] - m[(0, 1)],
    ) / 2.0
}

/// Median disagreement (deg) between the measured relative rotations `M = R_i^T R_j` and the
/// nominal flange's `N = F_i^T F_j`, over pose pairs `(i, i + n/3)` (poses far apart in the file,
/// so that consecutive poses differing in one angle only do not hide a wrong convention), for the
/// measured rotations `rotations` (one per pose, `None` without orientation).
///
/// With `R = R_base F R_tool`, `M = R_tool^T N R_tool`: the base cancels and the unknown probe
/// rotation conjugates. It is fitted from the pairs' rotation axes (orthogonal Procrustes: `A`
/// is the rotation nearest to `sum vee(M) vee(N)^T`), and the disagreement of a pair is the angle
/// of `(A N A^T)^T M`. For correct data `A` is the probe's rotation up to the geometric errors;
/// data read in a wrong convention or quaternion order keep the disagreement high. (The angle
/// of `M` alone would not see a wrong quaternion order or inverse quaternions: they leave every
/// relative angle unchanged.)
fn median_disagreement_deg(flanges: &[Rotation3<f64>], rotations: &[Option<Matrix3<f64>>]) -> f64 {
    let n = flanges.len().min(rotations.len());
    let step = (n / 3).max(1);
    let pairs: Vec<(Matrix3<f64>, Matrix3<f64>)> = (0..n)
        .take(PAIRS)
        .filter_map(|i| {
            let j = (i + step) % n;
            let (Some(r0), Some(r1)) = (rotations[i], rotations[j]) else {
                return None;
            };
            let nominal = (flanges[i].inverse() * flanges[j]).into_inner();
            Some((r0.transpose() * r1, nominal))
        })
        .collect();
    if pairs.is_empty() {
        return 0.0;
    }
    let nominal_axes: Vec<Vector3<f64>> = pairs.iter().map(|(_, nn)| skew_vector(nn)).collect();
    let measured_axes: Vec<Vector3<f64>> = pairs.iter().map(|(m, _)| skew_vector(m)).collect();
    let covariance: Matrix3<f64> = measured_axes
        .iter()
        .zip(&nominal_axes)
        .map(|(m, nn)| m * nn.transpose())
        .sum();
    let probe = crate::measurement::frames::nearest_rotation(&covariance)
        .map_or_else(Matrix3::identity, Rotation3::into_inner);
    let mut differences: Vec<f64> = pairs
        .iter()
        .map(|(m, nn)| {
            let predicted = probe * nn * probe.transpose();
            // The angle from the trace, clamped: rounding puts the trace of a rotation by
            // nothing just above 3, where `Rotation3::angle` gives NaN (data an identified
            // model fits exactly, as simulated data).
            let cos = (((predicted.transpose() * m).trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
            cos.acos().to_degrees()
        })
        .collect();
    differences.sort_by(f64::total_cmp);
    differences[differences.len() / 2]
}

/// Checks the orientations of `dataset` (read with the Euler convention `euler` when they are
/// angle columns) against the nominal model; an error names the conventions that would agree.
pub fn check(dataset: &Dataset, euler: &EulerConvention) -> crate::Result<()> {
    let rotations: Vec<Option<Matrix3<f64>>> =
        dataset.data.records.iter().map(|r| r.rotation).collect();
    if rotations.iter().filter(|r| r.is_some()).count() < 3 {
        return Ok(());
    }
    let mut bare = dataset.robot.model.robot;
    bare.base = calib_core::FramePose::identity();
    bare.tool = calib_core::FramePose::identity();
    let kinematics = Kinematics::<f64, Dyn>::nominal(&bare)?;
    let flanges: Vec<Rotation3<f64>> = dataset
        .as_given()?
        .measurements()
        .iter()
        .map(|m| kinematics.forward_angles(&m.angles).rotation)
        .collect();
    let disagreement = median_disagreement_deg(&flanges, &rotations);
    if disagreement <= MIN_CHECKED_DISAGREEMENT_DEG {
        return Ok(());
    }
    let candidates = other_readings(dataset, euler, &flanges, &rotations, disagreement);
    if candidates.is_empty() && disagreement <= MAX_MEDIAN_DISAGREEMENT_DEG {
        return Ok(());
    }
    let agree = if candidates.is_empty() {
        "no other Euler convention or quaternion order agrees either: check the joint order and signs against the robot \
         file, and the orientation columns"
            .to_string()
    } else {
        format!(
            "they agree better when read as: {}. Set that in the data profile ([orientation]) or the file",
            candidates
                .iter()
                .map(|(name, d)| format!("{name} ({d:.2} deg)"))
                .collect::<Vec<_>>()
                .join("; ")
        )
    };
    Err(crate::refused!(input dataset.data.path.display();
        "{}: the measured orientations do not move as the robot does: the rotation between two poses differs \
         from the nominal model's by {disagreement:.2} deg (median; a robot's geometric errors explain a degree or two). \
         The orientations were read as {}; {agree}",
        dataset.data.path.display(),
        match dataset.data.orientation {
            OrientationColumns::FixedAngles => euler.name(),
            _ => "quaternions (qw, qx, qy, qz)".to_string(),
        }
    ))
}

/// The other readings of the orientation columns (Euler conventions, quaternion order, inverse
/// rotations) under which the measured `rotations` agree with the nominal `flanges` much better
/// than the `disagreement` (deg) of the reading given, best first: (reading, median deg).
fn other_readings(
    dataset: &Dataset,
    euler: &EulerConvention,
    flanges: &[Rotation3<f64>],
    rotations: &[Option<Matrix3<f64>>],
    disagreement: f64,
) -> Vec<(String, f64)> {
    let mut candidates: Vec<(String, f64)> = Vec::new();
    let mut try_reading = |name: String, read: &dyn Fn(&Matrix3<f64>) -> Matrix3<f64>| {
        let reread: Vec<Option<Matrix3<f64>>> =
            rotations.iter().map(|r| r.map(|m| read(&m))).collect();
        let d = median_disagreement_deg(flanges, &reread);
        // Another reading must explain the data much better than the one given.
        if d <= MAX_MEDIAN_DISAGREEMENT_DEG && d * BETTER_BY < disagreement {
            candidates.push((name, d));
        }
    };
    match dataset.data.orientation {
        OrientationColumns::FixedAngles => {
            for other in EulerConvention::all() {
                if other != *euler {
                    try_reading(other.name(), &|m| {
                        let angles = euler.angles(&Rotation3::from_matrix_unchecked(*m));
                        *other.rotation(angles).matrix()
                    });
                }
            }
        }
        OrientationColumns::Quaternion => {
            try_reading(
                "the columns qw, qx, qy, qz hold x, y, z, w (scalar last)".into(),
                &|m| {
                    let q = UnitQuaternion::from_matrix(m);
                    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
                    // Read as (w, x, y, z), the file's columns were really (x, y, z, w).
                    let truth = nalgebra::Quaternion::new(z, w, x, y);
                    *UnitQuaternion::from_quaternion(truth)
                        .to_rotation_matrix()
                        .matrix()
                },
            );
            try_reading(
                "the quaternions are the inverse rotations (tracker in the probe's frame)".into(),
                &|m| m.transpose(),
            );
        }
        OrientationColumns::None => {}
    }
    candidates.sort_by(|a, b| a.1.total_cmp(&b.1));
    candidates
}
