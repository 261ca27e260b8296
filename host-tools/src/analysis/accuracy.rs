//! The accuracy a calibration reaches, as a certificate states it: on the held-out poses (never
//! used to calibrate), the position error's percentiles and its signed mean and spread along each
//! axis of the robot's base frame, before and after calibration; the held-out poses of largest
//! error named by their file line, and those a robust rule flags; and the user's acceptance
//! criterion judged on them.
//!
//! Percentiles interpolate linearly between the order statistics (`p` of `n` sorted values is at
//! rank `p (n - 1)`, as numpy's default). A held-out pose is flagged when its error lies more than
//! three robust standard deviations above the median (`median + 3 * 1.4826 * MAD`): for a normal
//! error of every coordinate that flags fewer than 1 % of the poses.

use serde::Serialize;

/// How many of the largest held-out errors are named.
pub const LARGEST_NAMED: usize = 5;

/// How many poses a text line lists (the JSON report has them all).
const LISTED: usize = 8;

/// Robust standard deviations above the median beyond which a held-out pose is flagged.
pub(crate) const FLAG_ROBUST_Z: f64 = 3.0;

/// The MAD of a normal distribution in standard deviations: `1 / 1.4826`.
const MAD_TO_SD: f64 = 1.4826;

/// Percentiles of the position error `|dp|`, mm.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Percentiles {
    /// Median, mm.
    pub p50_mm: f64,
    /// 95th percentile, mm.
    pub p95_mm: f64,
    /// 99th percentile, mm.
    pub p99_mm: f64,
    /// Largest, mm.
    pub max_mm: f64,
}

/// The signed error along one axis: mean and sample standard deviation, mm.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct AxisError {
    /// Mean of `measured - predicted` along the axis, mm.
    pub mean_mm: f64,
    /// Sample standard deviation (n - 1), mm.
    pub std_mm: f64,
}

/// The accuracy of one model on a set of poses.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Accuracy {
    /// Number of poses.
    pub poses: usize,
    /// Percentiles of `|dp|`.
    pub position: Percentiles,
    /// Signed error along x, y and z of the robot's base frame.
    pub axes: [AxisError; 3],
}

/// A held-out pose named by its data file's line.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct NamedPose {
    /// The pose's id.
    pub id: String,
    /// Its line in the data file.
    pub line: u64,
    /// `|dp|` after calibration, mm.
    pub error_mm: f64,
    /// `measured - predicted` along x, y, z of the robot's base frame, mm.
    pub xyz_mm: [f64; 3],
}

/// The accuracy on the held-out poses before and after calibration, with the poses to look at.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct HeldOutAccuracy {
    /// With the nominal model (frames fitted, when identified).
    pub before: Accuracy,
    /// With the identified model.
    pub after: Accuracy,
    /// The held-out poses of largest error after calibration, largest first ([`LARGEST_NAMED`]).
    pub largest: Vec<NamedPose>,
    /// The error beyond which a held-out pose is flagged: median + 3 robust standard deviations,
    /// mm.
    pub flag_above_mm: f64,
    /// The held-out poses flagged, largest first (empty when none is).
    pub flagged: Vec<NamedPose>,
    /// ISO 9283-style accuracy and repeatability from repeated held-out poses; `None`: not
    /// measured (no pose repeats).
    pub iso9283: Option<Iso9283>,
    /// Where in the workspace the held-out error after calibration is.
    pub workspace: Option<crate::analysis::workspace::WorkspaceMap>,
}

/// The `p`-quantile (0 to 1) of `sorted` (ascending, not empty), interpolated linearly between
/// the order statistics.
pub(crate) fn quantile(sorted: &[f64], p: f64) -> f64 {
    let Some(last) = sorted.len().checked_sub(1) else {
        return f64::NAN;
    };
    let rank = p.clamp(0.0, 1.0) * last as f64;
    let below = rank.floor() as usize;
    let above = (below + 1).min(last);
    let fraction = rank - below as f64;
    sorted[below] + fraction * (sorted[above] - sorted[below])
}

impl Accuracy {
    /// The accuracy of the signed errors `xyz` (mm, base-frame axes), one per pose.
    pub fn of(xyz: &[[f64; 3]]) -> Self {
        let mut norms: Vec<f64> = xyz
            .iter()
            .map(|e| (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt())
            .collect();
        norms.sort_by(f64::total_cmp);
        let n = xyz.len() as f64;
        let axes = [0, 1, 2].map(|k| {
            let mean = xyz.iter().map(|e| e[k]).sum::<f64>() / n;
            let variance =
                xyz.iter().map(|e| (e[k] - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
            AxisError {
                mean_mm: mean,
                std_mm: variance.sqrt(),
            }
        });
        Self {
            poses: xyz.len(),
            position: Percentiles {
                p50_mm: quantile(&norms, 0.50),
                p95_mm: quantile(&norms, 0.95),
                p99_mm: quantile(&norms, 0.99),
                max_mm: norms.last().copied().unwrap_or(f64::NAN),
            },
            axes,
        }
    }
}

impl HeldOutAccuracy {
    /// The accuracy of the held-out poses `(id, line)` with their signed errors `before` and
    /// `after` (mm, base-frame axes, in the same order); `None` without poses.
    pub fn of(poses: &[(String, u64)], before: &[[f64; 3]], after: &[[f64; 3]]) -> Option<Self> {
        if poses.is_empty() || poses.len() != before.len() || poses.len() != after.len() {
            return None;
        }
        let named = |i: usize| {
            let e = after[i];
            NamedPose {
                id: poses[i].0.clone(),
                line: poses[i].1,
                error_mm: (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt(),
                xyz_mm: e,
            }
        };
        let mut all: Vec<NamedPose> = (0..poses.len()).map(named).collect();
        all.sort_by(|a, b| b.error_mm.total_cmp(&a.error_mm).then(a.line.cmp(&b.line)));
        let mut norms: Vec<f64> = all.iter().map(|p| p.error_mm).collect();
        norms.sort_by(f64::total_cmp);
        let median = quantile(&norms, 0.5);
        let mut deviations: Vec<f64> = norms.iter().map(|v| (v - median).abs()).collect();
        deviations.sort_by(f64::total_cmp);
        let flag_above_mm = median + FLAG_ROBUST_Z * MAD_TO_SD * quantile(&deviations, 0.5);
        let flagged = all
            .iter()
            .filter(|p| p.error_mm > flag_above_mm)
            .cloned()
            .collect();
        all.truncate(LARGEST_NAMED);
        Some(Self {
            before: Accuracy::of(before),
            after: Accuracy::of(after),
            largest: all,
            flag_above_mm,
            flagged,
            iso9283: None,
            workspace: None,
        })
    }

    /// The lines for people: percentiles and axes before and after, the largest and the flagged
    /// poses.
    pub fn text(&self) -> String {
        let percentiles = |a: &Accuracy| {
            let p = a.position;
            format!(
                "50 % {:.4}, 95 % {:.4}, 99 % {:.4}, max {:.4}",
                p.p50_mm, p.p95_mm, p.p99_mm, p.max_mm
            )
        };
        let axes = |a: &Accuracy| {
            let [x, y, z] = a.axes;
            format!(
                "x {:+.4} +- {:.4}, y {:+.4} +- {:.4}, z {:+.4} +- {:.4}",
                x.mean_mm, x.std_mm, y.mean_mm, y.std_mm, z.mean_mm, z.std_mm
            )
        };
        let list = |poses: &[NamedPose]| {
            let shown: Vec<String> = (poses.iter().take(LISTED))
                .map(|p| {
                    let id = if p.id == p.line.to_string() {
                        String::new()
                    } else {
                        format!(" ({})", p.id)
                    };
                    format!("line {}{id} {:.4} mm", p.line, p.error_mm)
                })
                .collect();
            let more = poses.len().saturating_sub(LISTED);
            let more = if more > 0 {
                format!(" and {more} more (in the JSON report)")
            } else {
                String::new()
            };
            shown.join(", ") + &more
        };
        let flagged = if self.flagged.is_empty() {
            format!(
                "no held-out pose is flagged (none above {:.4} mm, the median + {FLAG_ROBUST_Z} robust standard deviations)",
                self.flag_above_mm
            )
        } else {
            format!(
                "flagged (above {:.4} mm, the median + {FLAG_ROBUST_Z} robust standard deviations): {}",
                self.flag_above_mm,
                list(&self.flagged)
            )
        };
        format!(
            "\nheld-out accuracy ({} poses), |dp| percentiles (mm): before {}; after {}\n  \
             signed error along the robot's base axes, mean +- std (mm): before {}; after {}\n  \
             largest held-out errors: {}\n  {flagged}\n{}{}",
            self.after.poses,
            percentiles(&self.before),
            percentiles(&self.after),
            axes(&self.before),
            axes(&self.after),
            list(&self.largest),
            Iso9283::text(self.iso9283.as_ref()),
            self.workspace.as_ref().map_or(
                String::new(),
                crate::analysis::workspace::WorkspaceMap::text
            ),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 52: RP and the largest AP come from poses repeated at least 10 times only. One pose
    /// measured 10 times with errors 0.00, 0.01, ..., 0.09 mm along x (barycentre 0.045 mm: AP
    /// 0.045 mm, distances |e - 0.045|, RP their mean plus three sample deviations), and one pose
    /// twice (errors 1 and 3 mm along y: AP 2 mm, counted in the mean AP only).
    #[test]
    fn repeatability_needs_ten_cycles() {
        let (a, b) = (vec![0.1, 0.2], vec![0.3, 0.4]);
        let mut q = vec![a; 10];
        q.extend([b.clone(), b]);
        let mut after: Vec<[f64; 3]> = (0..10).map(|j| [j as f64 * 0.01, 0.0, 0.0]).collect();
        after.extend([[0.0, 1.0, 0.0], [0.0, 3.0, 0.0]]);
        let lines: Vec<u64> = (1..=12).collect();
        let iso = Iso9283::of(&q, &lines, &after).unwrap();
        let l: Vec<f64> = (0..10).map(|j| (j as f64 * 0.01 - 0.045).abs()).collect();
        let mean = l.iter().sum::<f64>() / 10.0;
        let sd = (l.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / 9.0).sqrt();
        assert_eq!(
            (iso.groups, iso.groups_with_cycles, iso.most_repeats),
            (2, 1, 10)
        );
        assert!((iso.ap_mean_mm - (0.045 + 2.0) / 2.0).abs() < 1e-12);
        assert!((iso.ap_max_mm.unwrap() - 0.045).abs() < 1e-12);
        assert!((iso.rp_max_mm.unwrap() - (mean + 3.0 * sd)).abs() < 1e-12);
        assert_eq!(iso.rp_mean_mm, iso.rp_max_mm);
        assert_eq!(iso.rp_max_lines, (1..=10).collect::<Vec<u64>>());
        // The pair alone: no RP, no largest AP, and the text says why.
        let pair = Iso9283::of(&q[10..], &lines[10..], &after[10..]).unwrap();
        assert_eq!((pair.rp_max_mm, pair.ap_max_mm), (None, None));
        assert!(pair.repeatability_text().contains("at least 10 times"));
    }

    /// Quantiles at the ranks of a known list (the numpy "linear" definition: rank p (n - 1)).
    #[test]
    fn quantiles_interpolate_between_order_statistics() {
        let sorted = [1.0, 2.0, 4.0, 8.0, 16.0];
        assert_eq!(quantile(&sorted, 0.0), 1.0);
        assert_eq!(quantile(&sorted, 0.5), 4.0);
        assert_eq!(quantile(&sorted, 1.0), 16.0);
        // rank 0.95 * 4 = 3.8: 8 + 0.8 * 8.
        assert!((quantile(&sorted, 0.95) - 14.4).abs() < 1e-12);
        assert_eq!(quantile(&[3.0], 0.99), 3.0);
        assert!(quantile(&[], 0.5).is_nan());
    }

    /// Per-axis means and spreads, and the flag rule, on a hand-made set: nine errors of 1 mm
    /// along x and one of 10 mm (median 1, MAD 0: flagged above 1 mm).
    #[test]
    fn axes_and_flags_of_a_known_set() {
        let mut after = vec![[1.0, 0.0, 0.0]; 9];
        after.push([0.0, 0.0, -10.0]);
        let poses: Vec<(String, u64)> = (0..10).map(|i| (format!("P{i}"), 2 + i)).collect();
        let held = HeldOutAccuracy::of(&poses, &after, &after).unwrap();
        assert_eq!(held.after.poses, 10);
        assert!((held.after.axes[0].mean_mm - 0.9).abs() < 1e-12);
        assert!((held.after.axes[2].mean_mm + 1.0).abs() < 1e-12);
        // z: nine zeros and -10, mean -1: variance (9 * 1 + 81) / 9 = 10.
        assert!((held.after.axes[2].std_mm - 10f64.sqrt()).abs() < 1e-12);
        assert_eq!(held.flag_above_mm, 1.0);
        assert_eq!(held.flagged.len(), 1);
        assert_eq!((held.flagged[0].line, held.flagged[0].error_mm), (11, 10.0));
        assert_eq!(held.largest.len(), LARGEST_NAMED);
        assert_eq!(held.largest[1].line, 2);
        assert!(HeldOutAccuracy::of(&[], &[], &[]).is_none());
    }

    /// The criterion's syntax, its refusals, and its judgement by counting.
    #[test]
    fn criteria_are_read_and_judged_by_counting_the_poses_within() {
        for text in ["95% <= 0.5 mm", "95 %<=0.5mm", "95% within 0.5 mm"] {
            let c: Criterion = text.parse().unwrap();
            assert_eq!((c.percent, c.within_mm), (95.0, 0.5), "{text}");
        }
        for text in [
            "95 <= 0.5 mm",
            "95% < 0.5 mm",
            "95% <= 0.5",
            "0% <= 1 mm",
            "101% <= 1 mm",
            "95% <= -1 mm",
            "95% <= inf mm",
        ] {
            assert!(text.parse::<Criterion>().is_err(), "{text}");
        }
        // 19 of 20 within 0.5 mm: 95 % is met exactly, 96 % is not.
        let mut errors = vec![0.1; 19];
        errors.push(0.9);
        let met = Acceptance::judge(&["95% <= 0.5 mm".parse().unwrap()], &errors).unwrap();
        assert!(met.pass && met.criteria[0].measured_percent == 95.0);
        let failed = Acceptance::judge(
            &[
                "95% <= 0.5 mm".parse().unwrap(),
                "96% <= 0.5 mm".parse().unwrap(),
            ],
            &errors,
        )
        .unwrap();
        assert!(!failed.pass && failed.criteria[0].pass && !failed.criteria[1].pass);
        assert!(failed.text().starts_with("acceptance: FAIL"));
        assert!(Acceptance::judge(&[], &errors).is_none());
    }
}

/// An acceptance criterion the user states (`calib calibrate --accept "95% <= 0.5 mm"`): at least
/// `percent` % of the held-out poses within `within_mm` of their prediction after calibration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Criterion {
    /// The share of held-out poses that must be within the bound, % (0 to 100].
    pub percent: f64,
    /// The bound on `|dp|`, mm.
    pub within_mm: f64,
}

impl std::str::FromStr for Criterion {
    type Err = String;

    /// `P% <= X mm` or `P% within X mm` (spaces optional), such as `95% <= 0.5 mm`.
    fn from_str(text: &str) -> Result<Self, String> {
        let wrong = || {
            format!(
                "\"{text}\" is not an acceptance criterion: write the share of held-out poses and the bound on their position \
                 error, as \"95% <= 0.5 mm\" (or \"95% within 0.5 mm\")"
            )
        };
        let compact: String = text.split_whitespace().collect::<String>().to_lowercase();
        let (percent, rest) = compact.split_once('%').ok_or_else(wrong)?;
        let rest = (rest.strip_prefix("<="))
            .or_else(|| rest.strip_prefix("within"))
            .ok_or_else(wrong)?;
        let bound = rest.strip_suffix("mm").ok_or_else(wrong)?;
        let percent: f64 = percent.parse().map_err(|_| wrong())?;
        let within_mm: f64 = bound.parse().map_err(|_| wrong())?;
        if !(percent > 0.0 && percent <= 100.0) {
            return Err(format!(
                "\"{text}\": the share of held-out poses must be above 0 and at most 100 %"
            ));
        }
        if !(within_mm.is_finite() && within_mm > 0.0) {
            return Err(format!(
                "\"{text}\": the bound must be a finite length above 0 mm"
            ));
        }
        Ok(Self { percent, within_mm })
    }
}

impl std::fmt::Display for Criterion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}% of held-out poses <= {} mm",
            self.percent, self.within_mm
        )
    }
}

/// One criterion judged on the held-out poses.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Judged {
    /// The criterion.
    #[serde(flatten)]
    pub criterion: Criterion,
    /// As the user wrote it (normalised).
    pub text: String,
    /// The share of held-out poses within the bound after calibration, %.
    pub measured_percent: f64,
    /// Whether the criterion is met: `measured_percent >= percent`.
    pub pass: bool,
}

/// The acceptance statement: every criterion judged, and whether all are met.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Acceptance {
    /// Each criterion with its measured share.
    pub criteria: Vec<Judged>,
    /// `true` when every criterion is met.
    pub pass: bool,
    /// How many held-out poses they were judged on.
    pub poses: usize,
}

impl Acceptance {
    /// `criteria` judged on the held-out errors `after_mm` (`|dp|` after calibration, mm);
    /// `None` without criteria or without held-out poses.
    pub(crate) fn judge(criteria: &[Criterion], after_mm: &[f64]) -> Option<Self> {
        if criteria.is_empty() || after_mm.is_empty() {
            return None;
        }
        let judged: Vec<Judged> = criteria
            .iter()
            .map(|c| {
                let within = after_mm.iter().filter(|e| **e <= c.within_mm).count();
                let measured_percent = 100.0 * within as f64 / after_mm.len() as f64;
                Judged {
                    criterion: *c,
                    text: c.to_string(),
                    measured_percent,
                    pass: measured_percent >= c.percent,
                }
            })
            .collect();
        Some(Self {
            pass: judged.iter().all(|j| j.pass),
            criteria: judged,
            poses: after_mm.len(),
        })
    }

    /// The statement for people: PASS or FAIL, each criterion with its measured share.
    pub fn text(&self) -> String {
        let each: Vec<String> = self
            .criteria
            .iter()
            .map(|j| {
                format!(
                    "{} (measured: {:.2} % of {} poses, {})",
                    j.text,
                    j.measured_percent,
                    self.poses,
                    if j.pass { "met" } else { "NOT met" }
                )
            })
            .collect();
        format!(
            "acceptance: {}: {}\n",
            if self.pass { "PASS" } else { "FAIL" },
            each.join("; ")
        )
    }
}

/// Commanded joints closer than this (each joint, deg) are the same pose repeated.
pub const REPEAT_TOLERANCE_DEG: f64 = 0.01;

/// Fewest cycles of one pose from which its repeatability `RP` and the largest `AP` are stated
/// (ISO 9283 asks for 30): from two, `mean(l) + 3 S_l` is half the distance of the two points
/// plus three times a spread of none, whatever the robot's repeatability, and the largest of a
/// hundred such pairs is an outlier's, not the robot's.
pub const MIN_CYCLES: usize = 10;

/// ISO 9283-style pose accuracy and repeatability (positions) from the held-out poses that repeat
/// a commanded pose: per group of `n >= 2` poses with the same joints (each within
/// [`REPEAT_TOLERANCE_DEG`], rounded to it), `AP = |mean(measured - predicted)|` (its mean over
/// the groups), and from the groups of at least [`MIN_CYCLES`] poses the largest `AP` and `RP =
/// mean(l) + 3 S_l`, `l_j` each pose's distance from the group's barycentre (ISO 9283: 30 cycles
/// per pose; from 10 to 29 `RP` is indicative).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Iso9283 {
    /// Groups of repeated poses.
    pub groups: usize,
    /// Poses in them.
    pub poses: usize,
    /// Most repeats of one pose.
    pub most_repeats: usize,
    /// The fewest cycles of a pose from which `RP` and the largest `AP` are stated
    /// ([`MIN_CYCLES`]).
    pub cycles_needed: usize,
    /// Groups of at least that many poses.
    pub groups_with_cycles: usize,
    /// Mean pose accuracy `AP` over all the groups, mm.
    pub ap_mean_mm: f64,
    /// Largest `AP` of the groups with enough cycles, mm; `None` when there are none.
    pub ap_max_mm: Option<f64>,
    /// Mean of the repeatability `RP` of the groups with enough cycles, mm; `None`: none.
    pub rp_mean_mm: Option<f64>,
    /// Largest of them, mm.
    pub rp_max_mm: Option<f64>,
    /// The data file's lines of the group of largest `RP` (empty: none).
    pub rp_max_lines: Vec<u64>,
}

impl Iso9283 {
    /// Of the held-out poses with commanded joints `q` (rad), lines `lines` and signed errors
    /// `after` (mm); `None` when no pose repeats.
    pub fn of(q: &[Vec<f64>], lines: &[u64], after: &[[f64; 3]]) -> Option<Self> {
        let step = REPEAT_TOLERANCE_DEG.to_radians();
        let mut groups: std::collections::BTreeMap<Vec<i64>, Vec<usize>> = Default::default();
        for (i, joints) in q.iter().enumerate() {
            let key = joints.iter().map(|v| (v / step).round() as i64).collect();
            groups.entry(key).or_default().push(i);
        }
        let repeated: Vec<&Vec<usize>> = groups.values().filter(|g| g.len() >= 2).collect();
        if repeated.is_empty() || q.len() != after.len() || q.len() != lines.len() {
            return None;
        }
        // Per group: AP, and RP with the group's lines when it has enough cycles.
        let mut ap = Vec::new();
        let mut cycled: Vec<(f64, f64, Vec<u64>)> = Vec::new();
        for group in &repeated {
            let n = group.len() as f64;
            let mean = [0, 1, 2].map(|k| group.iter().map(|i| after[*i][k]).sum::<f64>() / n);
            let group_ap = (mean[0] * mean[0] + mean[1] * mean[1] + mean[2] * mean[2]).sqrt();
            ap.push(group_ap);
            if group.len() < MIN_CYCLES {
                continue;
            }
            let l: Vec<f64> = (group.iter())
                .map(|i| {
                    let d = [0, 1, 2].map(|k| after[*i][k] - mean[k]);
                    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
                })
                .collect();
            let l_mean = l.iter().sum::<f64>() / n;
            let s = (l.iter().map(|v| (v - l_mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            let group_lines = group.iter().map(|i| lines[*i]).collect();
            cycled.push((group_ap, l_mean + 3.0 * s, group_lines));
        }
        let worst = cycled.iter().max_by(|a, b| a.1.total_cmp(&b.1));
        let count = cycled.len() as f64;
        Some(Self {
            groups: repeated.len(),
            poses: repeated.iter().map(|g| g.len()).sum(),
            most_repeats: repeated.iter().map(|g| g.len()).max().unwrap_or(0),
            cycles_needed: MIN_CYCLES,
            groups_with_cycles: cycled.len(),
            ap_mean_mm: ap.iter().sum::<f64>() / repeated.len() as f64,
            ap_max_mm: worst.map(|_| cycled.iter().map(|c| c.0).fold(0.0, f64::max)),
            rp_mean_mm: worst.map(|_| cycled.iter().map(|c| c.1).sum::<f64>() / count),
            rp_max_mm: worst.map(|w| w.1),
            rp_max_lines: worst.map(|w| w.2.clone()).unwrap_or_default(),
        })
    }

    /// The repeatability statement in words, the largest `AP` with it: the figures, or why they
    /// are not stated.
    pub fn repeatability_text(&self) -> String {
        match (self.ap_max_mm, self.rp_mean_mm, self.rp_max_mm) {
            (Some(ap_max), Some(rp_mean), Some(rp_max)) => format!(
                "from the {} groups of at least {} cycles: AP max {ap_max:.4} mm; repeatability RP mean {rp_mean:.4} mm, max {rp_max:.4} mm (lines {})",
                self.groups_with_cycles,
                self.cycles_needed,
                self.rp_max_lines
                    .iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            _ => format!(
                "repeatability RP and the largest AP not stated: they need a pose repeated at least {} times (ISO 9283: 30 cycles), and the most here is {}",
                self.cycles_needed, self.most_repeats
            ),
        }
    }

    /// The line for people; `None` says the figures were not measured.
    pub fn text(iso: Option<&Self>) -> String {
        match iso {
            None => "  ISO 9283 pose accuracy and repeatability: not measured (no held-out pose repeats a commanded pose)\n".to_string(),
            Some(i) => format!(
                "  ISO 9283-style, from {} held-out poses repeated in {} groups (at most {} times; ISO asks for 30 cycles): \
                 accuracy AP mean {:.4} mm; {}\n",
                i.poses,
                i.groups,
                i.most_repeats,
                i.ap_mean_mm,
                i.repeatability_text()
            ),
        }
    }
}
