//! What limits a calibration's accuracy statement, gathered for the certificate so that a reader
//! who looks only there sees it: the plan check that missed its prediction, a cross-validation
//! that predicts new poses worse than the nominal model, held-out poses outside the joint ranges
//! the calibration poses cover (their figures are extrapolated), held-out errors beyond the band
//! the uncertainty predicts, and a result kept although implausible.

use serde::Serialize;

/// The share of held-out poses inside the predicted 95 % band below which the band is said to
/// miss an error, %.
/// A convention, not fitted to data (docs/RESULTS.md, "Thresholds set from data").
pub(crate) const COVERAGE_BELOW_PERCENT: f64 = 90.0;

/// Lines a caveat lists (in the text; the JSON has them all).
const LISTED: usize = 8;

/// What a caveat is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CaveatKind {
    /// The plan's verification poses missed the plan's prediction.
    PlanCheck,
    /// Cross-validation predicts new poses worse than the nominal model.
    CrossValidation,
    /// Held-out poses outside the joint ranges of the calibration poses.
    Extrapolation,
    /// Held-out errors beyond the predicted band.
    Uncertainty,
    /// The result failed the plausibility check and was kept (`--accept-implausible`).
    Implausible,
}

/// One caveat: what, in words, and the data file lines it concerns.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Caveat {
    /// What it is about.
    pub kind: CaveatKind,
    /// The statement for people.
    pub text: String,
    /// The data file lines of the poses concerned (empty when it is about the whole set).
    pub lines: Vec<u64>,
}

impl Caveat {
    /// The line for people, with the first lines concerned.
    pub fn line(&self) -> String {
        if self.lines.is_empty() {
            return self.text.clone();
        }
        let shown: Vec<String> = self.lines.iter().take(LISTED).map(u64::to_string).collect();
        let more = self.lines.len().saturating_sub(LISTED);
        format!(
            "{} (lines {}{})",
            self.text,
            shown.join(", "),
            if more > 0 {
                format!(" and {more} more")
            } else {
                String::new()
            }
        )
    }
}

/// The joint range (rad) each joint covers over `q` (one row per pose); empty without poses.
pub(crate) fn joint_ranges(q: &[Vec<f64>]) -> Vec<[f64; 2]> {
    let joints = q.first().map_or(0, Vec::len);
    (0..joints)
        .map(|j| {
            q.iter().fold([f64::INFINITY, f64::NEG_INFINITY], |r, row| {
                let v = row.get(j).copied().unwrap_or(f64::NAN);
                [r[0].min(v), r[1].max(v)]
            })
        })
        .collect()
}

/// The held-out poses (`held_out` joints in rad and their `lines`) with a joint outside the
/// `ranges` the calibration poses cover (rad; a margin of 1e-9 rad): a caveat naming the joints
/// and lines, `None` when every held-out pose lies within.
pub fn extrapolation(ranges: &[[f64; 2]], held_out: &[Vec<f64>], lines: &[u64]) -> Option<Caveat> {
    const MARGIN: f64 = 1e-9;
    let mut joints_outside = vec![false; ranges.len()];
    let mut outside = Vec::new();
    for (q, line) in held_out.iter().zip(lines) {
        let mut any = false;
        for (j, (v, r)) in q.iter().zip(ranges).enumerate() {
            if *v < r[0] - MARGIN || *v > r[1] + MARGIN {
                joints_outside[j] = true;
                any = true;
            }
        }
        if any {
            outside.push(*line);
        }
    }
    if outside.is_empty() {
        return None;
    }
    let joints: Vec<String> = (joints_outside.iter().enumerate())
        .filter(|(_, o)| **o)
        .map(|(j, _)| {
            format!(
                "q{} calibrated over {:.1} .. {:.1} deg",
                j + 1,
                ranges[j][0].to_degrees(),
                ranges[j][1].to_degrees()
            )
        })
        .collect();
    Some(Caveat {
        kind: CaveatKind::Extrapolation,
        text: format!(
            "{} of {} held-out poses have a joint outside the range the calibration poses cover ({}): \
             the model is extrapolated there",
            outside.len(),
            held_out.len(),
            joints.join("; ")
        ),
        lines: outside,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn held_out_poses_beyond_the_calibrated_joint_ranges_are_named() {
        let calibration = vec![vec![0.0, -1.0], vec![1.0, 0.5], vec![0.5, 0.0]];
        let ranges = joint_ranges(&calibration);
        assert_eq!(ranges, vec![[0.0, 1.0], [-1.0, 0.5]]);
        let held_out = vec![
            vec![0.5, 0.0],
            vec![1.2, 0.0],
            vec![0.5, -1.5],
            vec![1.0, 0.5],
        ];
        let caveat = extrapolation(&ranges, &held_out, &[10, 11, 12, 13]).unwrap();
        assert_eq!(caveat.kind, CaveatKind::Extrapolation);
        assert_eq!(caveat.lines, vec![11, 12]);
        assert!(
            caveat.text.starts_with("2 of 4 held-out poses")
                && caveat.text.contains(
                    "q1 calibrated over 0.0 .. 57.3 deg; q2 calibrated over -57.3 .. 28.6 deg"
                ),
            "{}",
            caveat.text
        );
        assert!(caveat.line().ends_with("(lines 11, 12)"));
        // Within the ranges (the edges included): no caveat.
        assert!(extrapolation(&ranges, &calibration, &[1, 2, 3]).is_none());
    }
}
