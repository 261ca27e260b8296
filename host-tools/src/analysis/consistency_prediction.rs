//! What consistency a calibration from touches predicts on a placement it did not fit, from its
//! own uncertainty: the touches' scatter (the fit's residual standard deviation per coordinate,
//! `sigma`) and the identified parameters' covariance `Sigma`. Set beside the measured
//! consistency, it says whether the held-out placement behaves as the model and the scatter
//! explain, or whether something the model leaves out (elasticity under gravity, backlash, a
//! moved tool) shows there.
//!
//! A touch `i` of a socket with `n` touches lies, under the identified model, at
//! `d_i = (eps_i - mean eps) + (J_i - mean J) delta` from its socket's mean: the ball's play
//! `eps ~ N(0, sigma^2 I)` and the parameters' error `delta ~ N(0, Sigma)` (linearised: `J_i` the
//! position rows of the parameter Jacobian at the touch). So `d_i ~ N(0, C_i)`,
//! `C_i = sigma^2 (1 - 1/n) I + G_i Sigma G_i^T`, `G_i = J_i - mean J`. The expected distance
//! `E|d_i|` of an anisotropic Gaussian has no closed form: it is averaged over a fixed set of
//! standard normal draws (the same for every touch, seeded: the prediction is deterministic),
//! and the 95th percentile is taken over every touch's draws pooled.

use crate::analysis::consistency::quantile;
use calib_core::identify::common_point::Touch;
use calib_core::{Kinematics, ParameterSet};
use nalgebra::{DMatrix, Dyn, Matrix3, Matrix3xX, Vector3};
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::Serialize;

/// Standard normal draws per touch: with a few hundred touches the mean is known to well under
/// one per cent.
const DRAWS: usize = 512;

/// The consistency a fit predicts on a placement, mm.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct PredictedConsistency {
    /// Expected mean distance of a ball centre from its socket's mean, mm.
    pub mean_mm: f64,
    /// The 95th percentile of that distance, mm.
    pub p95_mm: f64,
    /// The expected mean from the touches' scatter alone (a perfectly known model), mm.
    pub scatter_mean_mm: f64,
}

/// The consistency `model` (the identified one, the ball its tool) should reach on `touches`,
/// given the fit's residual standard deviation `sigma_mm` (per coordinate) and the covariance
/// of its parameters `set` (in the set's order, mm and rad). `None`: no touches, or a covariance
/// of another size than the set.
pub fn predict_consistency(
    model: &Kinematics<f64, Dyn>,
    set: &ParameterSet<Dyn, Dyn>,
    covariance: &DMatrix<f64>,
    sigma_mm: f64,
    touches: &[Touch<f64, Dyn>],
) -> Option<PredictedConsistency> {
    if touches.is_empty() || covariance.shape() != (set.len(), set.len()) {
        return None;
    }
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(54);
    let draws: Vec<Vector3<f64>> = (0..DRAWS)
        .map(|_| Vector3::from_fn(|_, _| StandardNormal.sample(&mut rng)))
        .collect();
    let mean_norm = draws.iter().map(|z| z.norm()).sum::<f64>() / DRAWS as f64;
    let mut distances = Vec::with_capacity(touches.len() * DRAWS);
    let mut scatter_sum = 0.0;
    for point in crate::analysis::consistency::points(touches) {
        let jacobians: Vec<Matrix3xX<f64>> = (touches.iter())
            .filter(|t| t.point == point)
            .map(|t| {
                let (_, twist) = model.parameter_jacobian(set, &t.angles);
                Matrix3xX::from_fn(set.len(), |r, c| twist[(r, c)])
            })
            .collect();
        let n = jacobians.len() as f64;
        let mean = jacobians
            .iter()
            .fold(Matrix3xX::zeros(set.len()), |sum, j| sum + j)
            / n;
        let play = sigma_mm * sigma_mm * (1.0 - 1.0 / n);
        scatter_sum += play.sqrt() * mean_norm * n;
        for j in &jacobians {
            let g = j - &mean;
            let c = Matrix3::identity() * play + &g * covariance * g.transpose();
            let eigen = c.symmetric_eigen();
            let root = eigen.eigenvectors
                * Matrix3::from_diagonal(&eigen.eigenvalues.map(|v| v.max(0.0).sqrt()));
            distances.extend(draws.iter().map(|z| (root * z).norm()));
        }
    }
    Some(PredictedConsistency {
        mean_mm: distances.iter().sum::<f64>() / distances.len() as f64,
        p95_mm: quantile(&distances, 0.95),
        scatter_mean_mm: scatter_sum / touches.len() as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With a perfectly known model the prediction is the touches' scatter: the expected
    /// distance of a 3-D Gaussian point with `sigma^2 (1 - 1/n)` per axis from the origin is
    /// `sqrt(8/pi)` times its standard deviation (the Maxwell distribution's mean), its 95th
    /// percentile `2.7955` times (the chi distribution with 3 degrees of freedom).
    #[test]
    fn a_known_model_predicts_the_scatter_alone() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/er10l-c10.toml");
        let file = crate::io::robot_file::RobotFile::read(&path).unwrap();
        let robot = file.to_model(&path).unwrap();
        let model = Kinematics::nominal(&robot.robot).unwrap();
        let set = crate::model::counts::solvable_set(&robot.mask).unwrap();
        let covariance = DMatrix::zeros(set.len(), set.len());
        let touches: Vec<Touch<f64, Dyn>> = (0..10)
            .map(|i| {
                let q = calib_core::model::JointVec::from_slice(&[0.1 * f64::from(i); 6]).unwrap();
                Touch::new(&q, 0, 1.0).unwrap()
            })
            .collect();
        let p = predict_consistency(&model, &set, &covariance, 0.05, &touches).unwrap();
        let sd = 0.05 * (0.9f64).sqrt();
        let maxwell = sd * (8.0 / std::f64::consts::PI).sqrt();
        assert!(
            (p.mean_mm / maxwell - 1.0).abs() < 0.03,
            "{p:?} against {maxwell}"
        );
        assert!((p.p95_mm / (2.7955 * sd) - 1.0).abs() < 0.05, "{p:?}");
        assert!((p.scatter_mean_mm - p.mean_mm).abs() < 1e-12);
    }
}
