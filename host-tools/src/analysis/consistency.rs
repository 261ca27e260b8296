//! What a model says of implicit measurements (a ball touched in sockets, issue 54), under their
//! own names: consistency, how far each ball centre the model puts at a touch lies from the mean
//! of its socket's centres, and distortion, how far the distance between two sockets' means is
//! from a known distance. Neither is absolute accuracy: a model that is wrong by a rigid motion
//! or (without a known distance) a uniform scale is perfectly consistent.
//!
//! Two protocols side by side: ours keeps every touch; the MUKCa authors' (their
//! `kinematics_calibration` evaluation) keeps, per socket, the centres within two interquartile
//! ranges of the quartiles on every axis, and averages the distances from the kept centres' mean.

use calib_core::Kinematics;
use calib_core::identify::common_point::{KnownDistance, Touch};
use nalgebra::{Dyn, Vector3};
use serde::Serialize;

/// The consistency of one socket's touches, mm.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct SocketConsistency {
    /// The socket (the touches' point).
    pub point: u16,
    /// Its touches.
    pub touches: usize,
    /// Mean distance of the ball centres from their mean, every touch, mm.
    pub mean_mm: f64,
    /// The 95th percentile of those distances (linearly interpolated), mm.
    pub p95_mm: f64,
    /// Touches the authors' rule keeps (within two interquartile ranges on every axis).
    pub kept: usize,
    /// Sum of the kept centres' distances from their own mean, mm (for the protocol's mean).
    kept_sum_mm: f64,
    /// The mean of the kept centres (base frame of the model), mm.
    pub kept_centre_mm: [f64; 3],
}

/// Consistency and distortion of a model on a set of touches (a placement), mm.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Consistency {
    /// Per socket, in the order of their points.
    pub sockets: Vec<SocketConsistency>,
    /// Mean distance of every ball centre from its socket's mean (our protocol), mm.
    pub mean_mm: f64,
    /// The 95th percentile of those distances, mm.
    pub p95_mm: f64,
    /// The authors' protocol: the mean over the kept touches of every socket, mm.
    pub authors_mean_mm: f64,
    /// Per known distance between two sockets touched here: its points, and the distance between
    /// their kept centres minus the known one, mm.
    pub distortion_mm: Vec<([u16; 2], f64)>,
    /// Per plane touched here, how far the ball centres lie from their best plane.
    pub planes: Vec<PlaneFlatness>,
    /// Per known plane touched here, how far the ball centres lie from it (not from their best
    /// plane: a known plane's distance is the model's error along its normal).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub known_planes: Vec<PlaneFlatness>,
}

/// How flat one plane's contacts are under a model: the distances of the ball centres from the
/// plane fitted through them (least squares, orthogonal), mm. Like consistency, not accuracy.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct PlaneFlatness {
    /// The plane (the contacts' `point`).
    pub plane: u16,
    /// Its contacts.
    pub contacts: usize,
    /// Mean distance of the ball centres from the best plane, mm (0 below four contacts).
    pub mean_mm: f64,
    /// The 95th percentile of those distances, mm.
    pub p95_mm: f64,
}

/// How far `model`'s ball centres of `contacts` lie from the known `planes` each names (its
/// `point` an index of `planes`), per plane touched: mean and 95th percentile of the absolute
/// distances, mm.
pub fn off_known_planes(
    model: &Kinematics<f64, Dyn>,
    contacts: &[Touch<f64, Dyn>],
    planes: &[calib_core::identify::known_plane::KnownPlane<f64>],
) -> Vec<PlaneFlatness> {
    (points(contacts).into_iter())
        .filter_map(|plane| {
            let known = planes.get(usize::from(plane))?;
            let normal = Vector3::from(known.normal);
            let distances: Vec<f64> = (contacts.iter())
                .filter(|t| t.point == plane)
                .map(|t| {
                    let p = model.forward_angles(&t.angles).translation.vector;
                    (normal.dot(&p) - known.offset_mm).abs()
                })
                .collect();
            Some(PlaneFlatness {
                plane,
                contacts: distances.len(),
                mean_mm: distances.iter().sum::<f64>() / distances.len().max(1) as f64,
                p95_mm: quantile(&distances, 0.95),
            })
        })
        .collect()
}

/// The flatness of `model`'s ball centres on each plane of `contacts` (their `point` numbering
/// the plane): the distances from the best plane through them (the normal of least scatter).
pub fn flatness(model: &Kinematics<f64, Dyn>, contacts: &[Touch<f64, Dyn>]) -> Vec<PlaneFlatness> {
    (points(contacts).into_iter())
        .map(|plane| {
            let balls: Vec<Vector3<f64>> = (contacts.iter())
                .filter(|t| t.point == plane)
                .map(|t| model.forward_angles(&t.angles).translation.vector)
                .collect();
            let centre = mean(&balls);
            let scatter: nalgebra::Matrix3<f64> = balls
                .iter()
                .map(|b| (b - centre) * (b - centre).transpose())
                .sum();
            let eigen = scatter.symmetric_eigen();
            let smallest = eigen.eigenvalues.imin();
            let normal = eigen.eigenvectors.column(smallest).into_owned();
            let distances: Vec<f64> = if balls.len() < 4 {
                vec![0.0; balls.len()]
            } else {
                balls
                    .iter()
                    .map(|b| normal.dot(&(b - centre)).abs())
                    .collect()
            };
            PlaneFlatness {
                plane,
                contacts: balls.len(),
                mean_mm: distances.iter().sum::<f64>() / distances.len().max(1) as f64,
                p95_mm: quantile(&distances, 0.95),
            }
        })
        .collect()
}

/// The distinct points (sockets) `touches` name, in order.
pub(crate) fn points(touches: &[Touch<f64, Dyn>]) -> Vec<u16> {
    let mut points: Vec<u16> = touches.iter().map(|t| t.point).collect();
    points.sort_unstable();
    points.dedup();
    points
}

/// The linearly interpolated `p` quantile of `values` (numpy's default); 0 for none.
pub fn quantile(values: &[f64], p: f64) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let Some(last) = sorted.len().checked_sub(1) else {
        return 0.0;
    };
    let rank = p.clamp(0.0, 1.0) * last as f64;
    let (low, high) = (rank.floor() as usize, rank.ceil() as usize);
    sorted[low] + (sorted[high] - sorted[low]) * (rank - low as f64)
}

fn mean(points: &[Vector3<f64>]) -> Vector3<f64> {
    points.iter().sum::<Vector3<f64>>() / points.len().max(1) as f64
}

/// The consistency of the ball centres `balls` (mm) of socket `point`.
fn socket(point: u16, balls: &[Vector3<f64>]) -> (SocketConsistency, Vec<f64>) {
    let centre = mean(balls);
    let distances: Vec<f64> = balls.iter().map(|b| (b - centre).norm()).collect();
    let bounds: Vec<(f64, f64)> = (0..3)
        .map(|axis| {
            let values: Vec<f64> = balls.iter().map(|b| b[axis]).collect();
            let (q1, q3) = (quantile(&values, 0.25), quantile(&values, 0.75));
            (q1 - 2.0 * (q3 - q1), q3 + 2.0 * (q3 - q1))
        })
        .collect();
    let kept: Vec<Vector3<f64>> = (balls.iter())
        .filter(|b| (0..3).all(|a| (bounds[a].0..=bounds[a].1).contains(&b[a])))
        .copied()
        .collect();
    let kept_centre = mean(&kept);
    let consistency = SocketConsistency {
        point,
        touches: balls.len(),
        mean_mm: distances.iter().sum::<f64>() / balls.len().max(1) as f64,
        p95_mm: quantile(&distances, 0.95),
        kept: kept.len(),
        kept_sum_mm: kept.iter().map(|b| (b - kept_centre).norm()).sum(),
        kept_centre_mm: kept_centre.into(),
    };
    (consistency, distances)
}

/// The consistency of `model` on `touches` (one placement, or any set of them), and its
/// distortion on the `known` distances whose two sockets are both touched.
pub fn consistency(
    model: &Kinematics<f64, Dyn>,
    touches: &[Touch<f64, Dyn>],
    known: &[KnownDistance<f64>],
) -> Consistency {
    let points = points(touches);
    let mut all = Vec::with_capacity(touches.len());
    let sockets: Vec<SocketConsistency> = (points.iter())
        .map(|point| {
            let balls: Vec<Vector3<f64>> = (touches.iter())
                .filter(|t| t.point == *point)
                .map(|t| model.forward_angles(&t.angles).translation.vector)
                .collect();
            let (socket, distances) = socket(*point, &balls);
            all.extend(distances);
            socket
        })
        .collect();
    let kept: usize = sockets.iter().map(|s| s.kept).sum();
    let centre = |point: u16| {
        (sockets.iter().find(|s| s.point == point)).map(|s| Vector3::from(s.kept_centre_mm))
    };
    let distortion_mm = (known.iter())
        .filter_map(|k| {
            let (a, b) = (centre(k.points[0])?, centre(k.points[1])?);
            Some((k.points, (a - b).norm() - k.mm))
        })
        .collect();
    Consistency {
        mean_mm: all.iter().sum::<f64>() / all.len().max(1) as f64,
        p95_mm: quantile(&all, 0.95),
        authors_mean_mm: sockets.iter().map(|s| s.kept_sum_mm).sum::<f64>() / kept.max(1) as f64,
        sockets,
        distortion_mm,
        planes: Vec::new(),
        known_planes: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_are_numpys_linear_ones() {
        assert_eq!(quantile(&[4.0, 1.0, 3.0, 2.0], 0.25), 1.75);
        let tenths: Vec<f64> = (0..=10).map(f64::from).collect();
        assert!((quantile(&tenths, 0.95) - 9.5).abs() < 1e-12);
        assert_eq!(quantile(&[], 0.5), 0.0);
    }

    /// A cube's eight corners (1 mm from its centre on every axis) and a touch 50 mm off: every
    /// touch counts in our mean; the authors' rule drops the stray one and finds the cube's.
    #[test]
    fn the_authors_rule_drops_a_stray_touch_and_ours_keeps_it() {
        let mut balls: Vec<Vector3<f64>> = (0..8)
            .map(|i| Vector3::from_fn(|axis, _| if i >> axis & 1 == 1 { 1.0 } else { -1.0 }))
            .collect();
        balls.push(Vector3::new(0.0, 0.0, 50.0));
        let (s, distances) = socket(3, &balls);
        assert_eq!((s.point, s.touches, s.kept), (3, 9, 8));
        assert_eq!(s.kept_centre_mm, [0.0; 3]);
        assert!((s.kept_sum_mm / 8.0 - 3f64.sqrt()).abs() < 1e-12);
        // Every touch about their mean (0, 0, 50/9).
        let centre = Vector3::new(0.0, 0.0, 50.0 / 9.0);
        let expected: f64 = balls.iter().map(|b| (b - centre).norm()).sum::<f64>() / 9.0;
        assert!((s.mean_mm - expected).abs() < 1e-12);
        assert!((distances[8] - 50.0 * 8.0 / 9.0).abs() < 1e-12);
    }
}
