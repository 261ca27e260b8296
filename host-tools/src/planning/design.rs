//! Which candidates a plan measures: the greedy D-optimal core, the random fill from the working
//! region and the verification poses, no two closer than the joint-space distance.

use super::*;

/// Whether candidate `i` is not chosen yet and at least `--min-distance-deg` from every chosen one.
pub(super) fn far_enough(
    q: &[Vec<f64>],
    chosen: &[(usize, Role)],
    i: usize,
    settings: &PlanSettings,
) -> bool {
    chosen
        .iter()
        .all(|(c, _)| *c != i && distance_deg(&q[*c], &q[i]) >= settings.min_distance_deg)
}

/// The D-optimal core: `settings.core` candidates chosen greedily on the log determinant of the
/// regularised information of the unit-scaled rows `scaled`.
pub(super) fn d_optimal_core(
    scaled: &[DMatrix<f64>],
    q: &[Vec<f64>],
    settings: &PlanSettings,
) -> crate::Result<Vec<(usize, Role)>> {
    let wanted = settings.poses.saturating_add(settings.verify);
    let parameters = scaled.first().map_or(0, DMatrix::ncols);
    let rows = settings.measure.rows();
    let mut chosen: Vec<(usize, Role)> = Vec::with_capacity(wanted);
    let mut information = DMatrix::<f64>::identity(parameters, parameters) * 1e-6;
    for _ in 0..settings.core {
        let inverse = information
            .clone()
            .cholesky()
            .map(|c| c.inverse())
            .ok_or_else(|| crate::numerical!("the information matrix lost its definiteness"))?;
        let mut best: Option<(usize, f64)> = None;
        for (i, j) in scaled.iter().enumerate() {
            if !far_enough(q, &chosen, i, settings) {
                continue;
            }
            let a = DMatrix::identity(rows, rows) + j * &inverse * j.transpose();
            let gain = a
                .cholesky()
                .map_or(f64::NEG_INFINITY, |c| c.l().diagonal().map(f64::ln).sum());
            if best.is_none_or(|(_, g)| gain > g) {
                best = Some((i, gain));
            }
        }
        let Some((i, _)) = best else {
            return Err(crate::refused!(too_few chosen.len(), wanted;
                "only {} candidates are at least {} deg apart; lower --min-distance-deg or give more candidates",
                chosen.len(),
                settings.min_distance_deg
            ));
        };
        information += scaled[i].transpose() * &scaled[i];
        chosen.push((i, Role::Core));
    }
    Ok(chosen)
}

/// Adds the fill and verification poses to `chosen`: random candidates, far enough from every
/// chosen pose; for joint maps the fill poses spread each joint's readings instead.
pub(super) fn fill_and_verify(
    chosen: &mut Vec<(usize, Role)>,
    q: &[Vec<f64>],
    settings: &PlanSettings,
) -> crate::Result<()> {
    let wanted = settings.poses.saturating_add(settings.verify);
    let order = crate::measurement::dataset::shuffled(q.len(), settings.seed);
    let mut random = order.clone().into_iter();
    let ranges = joint_ranges(q);
    for (role, count) in [
        (Role::Fill, settings.poses - settings.core),
        (Role::Verify, settings.verify),
    ] {
        for _ in 0..count {
            let next = if role == Role::Fill && settings.model == PlanModel::JointMaps {
                even_fill(q, &ranges, chosen, &order, |i| {
                    far_enough(q, chosen, i, settings)
                })
            } else {
                random
                    .by_ref()
                    .find(|i| far_enough(q, chosen, *i, settings))
            };
            let Some(i) = next else {
                return Err(crate::refused!(too_few chosen.len(), wanted;
                    "only {} candidates are at least {} deg apart, {wanted} are needed; lower --min-distance-deg or give more candidates",
                    chosen.len(),
                    settings.min_distance_deg
                ));
            };
            chosen.push((i, role));
        }
    }
    Ok(())
}

/// Each joint's range of readings over the candidates, rad (0 for a joint that does not move).
pub(super) fn joint_ranges(q: &[Vec<f64>]) -> Vec<f64> {
    let joints = q.first().map_or(0, Vec::len);
    (0..joints)
        .map(|j| {
            let (low, high) = q
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), c| {
                    (l.min(c[j]), h.max(c[j]))
                });
            (high - low).max(0.0)
        })
        .collect()
}

/// The fill pose for joint maps: of the candidates that `eligible` admits (tried in `order`, the
/// first wins a tie), the one whose readings are farthest, joint by joint, from the readings
/// already chosen: the sum over the joints of the distance to the nearest chosen reading, as a
/// fraction of the joint's range. Each map is identified from its own joint's readings, so the
/// fill covers every joint's range evenly instead of the extremes a D-optimal set favours.
pub(super) fn even_fill(
    q: &[Vec<f64>],
    ranges: &[f64],
    chosen: &[(usize, Role)],
    order: &[usize],
    eligible: impl Fn(usize) -> bool,
) -> Option<usize> {
    let spread = |i: usize| -> f64 {
        (ranges.iter().enumerate())
            .filter(|(_, r)| **r > 0.0)
            .map(|(j, r)| {
                let nearest = (chosen.iter())
                    .map(|(c, _)| (q[*c][j] - q[i][j]).abs())
                    .fold(f64::INFINITY, f64::min);
                nearest.min(*r) / r
            })
            .sum()
    };
    order
        .iter()
        .copied()
        .filter(|i| eligible(*i))
        .map(|i| (i, spread(i)))
        .fold(None, |best: Option<(usize, f64)>, (i, s)| match best {
            Some((_, b)) if b >= s => best,
            _ => Some((i, s)),
        })
        .map(|(i, _)| i)
}

/// Euclidean joint-space distance, degrees.
pub(super) fn distance_deg(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
        .to_degrees()
}
