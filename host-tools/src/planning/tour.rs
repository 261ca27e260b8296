//! The order a plan is measured in: nearest neighbour, then 2-opt, on the largest joint move
//! between poses, so that the robot's motion between poses stays short.

use super::*;

/// The largest joint move between two configurations, degrees (what a move takes when the
/// joints move together).
pub(super) fn move_deg(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        .to_degrees()
}

/// The poses in an order that keeps the joint motion short: nearest neighbour from the first
/// (in the candidates' order), then 2-opt moves while any shortens the path.
pub(super) fn measurement_order(poses: &[(usize, Role)], q: &[Vec<f64>]) -> Vec<(usize, Role)> {
    let d = |a: &(usize, Role), b: &(usize, Role)| move_deg(&q[a.0], &q[b.0]);
    let mut left: Vec<(usize, Role)> = poses.to_vec();
    let mut path = Vec::with_capacity(poses.len());
    if left.is_empty() {
        return path;
    }
    path.push(left.remove(0));
    while !left.is_empty() {
        let Some(last) = path.last() else { break };
        let (next, _) = left
            .iter()
            .enumerate()
            .map(|(i, p)| (i, d(last, p)))
            .fold((0, f64::INFINITY), |b, c| if c.1 < b.1 { c } else { b });
        path.push(left.remove(next));
    }
    // 2-opt on the open path: reverse path[i+1..=j] when that shortens it.
    let n = path.len();
    for _ in 0..100 {
        let mut improved = false;
        for i in 0..n.saturating_sub(2) {
            for j in i + 2..n {
                let before = d(&path[i], &path[i + 1])
                    + if j + 1 < n {
                        d(&path[j], &path[j + 1])
                    } else {
                        0.0
                    };
                let after = d(&path[i], &path[j])
                    + if j + 1 < n {
                        d(&path[i + 1], &path[j + 1])
                    } else {
                        0.0
                    };
                if after < before - 1e-9 {
                    path[i + 1..=j].reverse();
                    improved = true;
                }
            }
        }
        if !improved {
            break;
        }
    }
    path
}
