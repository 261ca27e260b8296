//! Where in the workspace the remaining error is. The held-out poses (never used to calibrate)
//! are placed at their positions in the robot's base frame and binned into regions: the terciles
//! of their x, y and z coordinates cut the workspace they cover into up to 27 boxes of about
//! equal pose counts, so that every region has poses to judge it by. Each region states the
//! measured held-out error after calibration (mean and largest, with the largest pose's data
//! file line) and, when the parameters' covariance is known, the error it predicts there
//! (`analysis::uncertainty`). The regions of largest measured mean error are named worst.
//!
//! Terciles adapt the boxes to where the poses are; a box's bounds are those of the poses inside
//! it, so a region never claims space no pose measured.

use serde::Serialize;

/// Cuts per axis: terciles.
pub(crate) const BINS: usize = 3;

/// Regions named worst.
pub const WORST_NAMED: usize = 3;

/// Poses a region needs to be named worst (fewer make a mean that one pose decides).
pub const MIN_POSES: usize = 3;

/// One box of the workspace and the held-out error inside it.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Region {
    /// The x range of its poses in the robot's base frame, mm.
    pub x_mm: [f64; 2],
    /// The y range, mm.
    pub y_mm: [f64; 2],
    /// The z range, mm.
    pub z_mm: [f64; 2],
    /// Held-out poses inside.
    pub poses: usize,
    /// Mean held-out position error after calibration, mm.
    pub mean_mm: f64,
    /// Largest, mm.
    pub max_mm: f64,
    /// The data file line of the pose of largest error.
    pub max_line: u64,
    /// Mean over its poses of the position error the parameters' covariance predicts (RMS, from
    /// the parameters alone), mm; `None` without a covariance.
    pub predicted_rms_mm: Option<f64>,
}

impl Region {
    /// "x 412..893, y -310..-12, z 95..402 mm".
    pub fn bounds_text(&self) -> String {
        let range = |r: [f64; 2]| format!("{:.0}..{:.0}", r[0], r[1]);
        format!(
            "x {}, y {}, z {} mm",
            range(self.x_mm),
            range(self.y_mm),
            range(self.z_mm)
        )
    }
}

/// The held-out error over the workspace.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct WorkspaceMap {
    /// Held-out poses mapped.
    pub poses: usize,
    /// Every region with a pose, worst measured mean first.
    pub regions: Vec<Region>,
    /// The [`WORST_NAMED`] regions of largest measured mean error among those with at least
    /// [`MIN_POSES`] poses.
    pub worst: Vec<Region>,
    /// The region of largest predicted error (with at least [`MIN_POSES`] poses), when predicted.
    pub worst_predicted: Option<Region>,
}

/// Where `value` falls among the cuts: 0 below the first, `cuts.len()` above the last.
fn bin_of(value: f64, cuts: &[f64]) -> usize {
    cuts.iter().take_while(|c| value >= **c).count()
}

/// The `BINS - 1` cuts at the terciles of `values`.
fn cuts(values: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut sorted: Vec<f64> = values.collect();
    sorted.sort_by(f64::total_cmp);
    (1..BINS)
        .filter_map(|k| sorted.get(k * sorted.len() / BINS).copied())
        .collect()
}

impl WorkspaceMap {
    /// The map of held-out poses at `positions` (robot base frame, mm) with position errors
    /// `errors_mm` after calibration, their data file `lines` and, when known, the predicted RMS
    /// error `predicted_mm` of each; `None` without poses or when the lengths differ.
    pub fn of(
        positions: &[[f64; 3]],
        errors_mm: &[f64],
        lines: &[u64],
        predicted_mm: Option<&[f64]>,
    ) -> Option<Self> {
        let n = positions.len();
        if n == 0 || errors_mm.len() != n || lines.len() != n {
            return None;
        }
        let predicted = predicted_mm.filter(|p| p.len() == n);
        let axis_cuts: Vec<Vec<f64>> = (0..3)
            .map(|a| cuts(positions.iter().map(|p| p[a])))
            .collect();
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); BINS * BINS * BINS];
        for (i, p) in positions.iter().enumerate() {
            let [bx, by, bz] = [0, 1, 2].map(|a| bin_of(p[a], &axis_cuts[a]).min(BINS - 1));
            members[(bx * BINS + by) * BINS + bz].push(i);
        }
        let mut regions: Vec<Region> = members
            .iter()
            .filter(|m| !m.is_empty())
            .map(|m| region(m, positions, errors_mm, lines, predicted))
            .collect();
        regions.sort_by(|a, b| b.mean_mm.total_cmp(&a.mean_mm));
        let judged = || regions.iter().filter(|r| r.poses >= MIN_POSES);
        let worst = judged().take(WORST_NAMED).cloned().collect();
        let worst_predicted = judged()
            .filter_map(|r| Some((r.predicted_rms_mm?, r)))
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, r)| r)
            .cloned();
        Some(Self {
            poses: n,
            regions,
            worst,
            worst_predicted,
        })
    }

    /// Text for people: the worst regions measured and predicted.
    pub fn text(&self) -> String {
        let mut out = format!(
            "  held-out error over the workspace ({} poses in {} regions, terciles of x, y and z in the base frame); worst regions:\n",
            self.poses,
            self.regions.len()
        );
        for r in &self.worst {
            let predicted = r
                .predicted_rms_mm
                .map_or(String::new(), |p| format!(", predicted {p:.4} mm RMS"));
            out.push_str(&format!(
                "    {}: mean {:.4} mm over {} poses, max {:.4} mm (line {}){predicted}\n",
                r.bounds_text(),
                r.mean_mm,
                r.poses,
                r.max_mm,
                r.max_line
            ));
        }
        if let Some(r) = &self.worst_predicted {
            out.push_str(&format!(
                "    largest predicted: {}: {:.4} mm RMS (measured mean {:.4} mm)\n",
                r.bounds_text(),
                r.predicted_rms_mm.unwrap_or(f64::NAN),
                r.mean_mm
            ));
        }
        out
    }
}

/// The region of the poses `members` (indices into the other slices).
fn region(
    members: &[usize],
    positions: &[[f64; 3]],
    errors_mm: &[f64],
    lines: &[u64],
    predicted: Option<&[f64]>,
) -> Region {
    let range = |a: usize| {
        members
            .iter()
            .fold([f64::INFINITY, f64::NEG_INFINITY], |r, i| {
                [r[0].min(positions[*i][a]), r[1].max(positions[*i][a])]
            })
    };
    let count = members.len() as f64;
    let mean = members.iter().map(|i| errors_mm[*i]).sum::<f64>() / count;
    let largest = members
        .iter()
        .copied()
        .max_by(|a, b| errors_mm[*a].total_cmp(&errors_mm[*b]))
        .unwrap_or(0);
    Region {
        x_mm: range(0),
        y_mm: range(1),
        z_mm: range(2),
        poses: members.len(),
        mean_mm: mean,
        max_mm: errors_mm[largest],
        max_line: lines[largest],
        predicted_rms_mm: predicted.map(|p| members.iter().map(|i| p[*i]).sum::<f64>() / count),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 27 poses on a 3 x 3 x 3 grid, one per region; errors grow with x + 2y + 4z.
    #[test]
    fn terciles_put_one_pose_of_a_grid_in_each_region_and_name_the_worst() {
        let mut positions = Vec::new();
        let mut errors = Vec::new();
        for x in 0..3 {
            for y in 0..3 {
                for z in 0..3 {
                    positions.push([x as f64 * 100.0, y as f64 * 100.0, z as f64 * 100.0]);
                    errors.push(f64::from(x + 2 * y + 4 * z) * 0.01);
                }
            }
        }
        let lines: Vec<u64> = (2..29).collect();
        let map = WorkspaceMap::of(&positions, &errors, &lines, None).unwrap();
        assert_eq!(map.regions.len(), 27);
        assert!(map.regions.iter().all(|r| r.poses == 1));
        // One pose per region: none is named worst.
        assert!(map.worst.is_empty());
        // The corner (200, 200, 200) has the largest error, 0.14 mm, at the last line.
        let top = &map.regions[0];
        assert_eq!((top.x_mm, top.max_line), ([200.0, 200.0], 28));
        assert!((top.mean_mm - 0.14).abs() < 1e-12);
    }

    /// Three clusters of 4 poses: the worst is the cluster of largest mean, its bounds those of
    /// its poses, its predicted error their mean.
    #[test]
    fn a_cluster_of_large_errors_is_named_worst_with_its_bounds() {
        let mut positions = Vec::new();
        let mut errors = Vec::new();
        let mut predicted = Vec::new();
        for (c, error) in [(0.0, 0.1), (500.0, 0.9), (1000.0, 0.2)] {
            for k in 0..4 {
                let d = f64::from(k) * 10.0;
                positions.push([c + d, c - d, c]);
                errors.push(error + f64::from(k) * 0.01);
                predicted.push(error / 10.0);
            }
        }
        let lines: Vec<u64> = (10..22).collect();
        let map = WorkspaceMap::of(&positions, &errors, &lines, Some(&predicted)).unwrap();
        let worst = &map.worst[0];
        assert_eq!(worst.poses, 4);
        assert_eq!(
            (worst.x_mm, worst.y_mm, worst.z_mm),
            ([500.0, 530.0], [470.0, 500.0], [500.0, 500.0])
        );
        assert!((worst.mean_mm - 0.915).abs() < 1e-12);
        assert_eq!((worst.max_mm, worst.max_line), (0.93, 17));
        assert!((worst.predicted_rms_mm.unwrap() - 0.09).abs() < 1e-12);
        assert_eq!(map.worst_predicted.as_ref(), Some(worst));
        assert!(
            map.text()
                .contains("x 500..530, y 470..500, z 500..500 mm: mean 0.9150 mm over 4 poses")
        );
        // Lengths that differ give no map.
        assert!(WorkspaceMap::of(&positions, &errors[1..], &lines, None).is_none());
    }
}
