//! The pose characteristics of ISO 9283:1998 from a measured run (clauses 7.2, 7.6 and 7.7):
//! for each point, pose accuracy `AP` and pose repeatability `RP`; between `P2` and `P4`,
//! distance accuracy `AD` and distance repeatability `RD`; at `P1`, the drift of pose accuracy
//! and repeatability over the run, `dAP` and `dRP`.
//!
//! With `n` cycles of a point, attained positions `x_j` (base frame) and the commanded position
//! `x_c`: the barycentre `x̄ = mean(x_j)`, `AP = |x̄ - x_c|` (and per axis `APx = x̄ - x_c`, ...),
//! `l_j = |x_j - x̄|`, `RP = mean(l) + 3 S_l` with `S_l` the sample standard deviation of `l`
//! (divisor `n - 1`). With orientation measured, `AP_a, AP_b, AP_c` are the mean deviation of
//! the attained orientation from the commanded one about the base's x, y and z axes (the
//! rotation vector of `R_j R_c^T`, equal to the standard's angle differences to first order,
//! which the millidegree-level deviations of a robot are) and `RP_a = +-3 S_a`, ....
//! Distance: per cycle `D_j = |x_j(P2) - x_j(P4)|` (the same cycle's two poses), `D_c` the
//! commanded distance, `AD = mean(D) - D_c`, `RD = +-3 S_D`. Drift: `AP` and `RP` of `P1` over
//! the first and over the last third of the cycles, `dAP = |AP_first - AP_last|` and
//! `dRP = |RP_first - RP_last|` (the standard cycles for 8 hours after a warm-up; the run's
//! length is the user's choice of cycles and its span in time is stated when the data carry
//! times).
//!
//! The measured point is the reflector or probe of the measurement setup; its commanded position
//! is the target pose carried to it (`target * tool^-1 * probe`, the controller's tool and the
//! identified probe on the flange), and the attained one the measurement brought into the base
//! frame through the identified tracker placement: the setup stays apart from the model.

use super::Target;
use crate::io::robot_file::RobotFile;
use crate::io::tracker_data::{Record, TrackerData};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

/// Cycles below which the standard's figures are indicative only (ISO 9283: 30).
pub const ISO_CYCLES: usize = 30;

/// How the measurements are brought into the base frame and which point they measure.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasurementSetup {
    /// The measurements' frame to the robot's base frame; identity when the data are in the base
    /// frame.
    pub to_base: Isometry3<f64>,
    /// The measured point (reflector or probe) in the controller's tool frame.
    pub point_in_tool: Isometry3<f64>,
    /// The setup in words, for the report.
    pub text: String,
}

impl MeasurementSetup {
    /// The setup of the identified robot `file` (read from `path`) for `data`: the tracker's
    /// placement (`[measurement] tracker_base`) and the probe on the flange (`flange_tool`, else
    /// the controller's tool itself), or no placement when the data say `# frame: base`. Refused:
    /// data in a tracker frame and a robot file without `[measurement]`.
    pub fn of(file: &RobotFile, path: &std::path::Path, data: &TrackerData) -> crate::Result<Self> {
        let base = file
            .base
            .as_ref()
            .map_or(Isometry3::identity(), |b| b.isometry());
        let tool = file
            .tool
            .as_ref()
            .map_or(Isometry3::identity(), |t| t.isometry());
        let measurement = file.measurement.as_ref();
        let probe = measurement.and_then(|m| m.flange_tool.as_ref());
        let point_in_tool = probe.map_or(Isometry3::identity(), |p| tool.inverse() * p.isometry());
        let probe_text = match probe {
            Some(p) => format!("the identified probe at {:?} mm on the flange", p.xyz_mm),
            None => "the controller's tool point itself".to_string(),
        };
        let (to_base, frame_text) = match (data.base_frame, measurement) {
            (true, _) => (
                Isometry3::identity(),
                "in the base frame (# frame: base)".to_string(),
            ),
            (false, Some(m)) => (
                base * m.tracker_base.isometry().inverse(),
                format!(
                    "through the tracker placement identified in {}",
                    path.display()
                ),
            ),
            (false, None) => {
                return Err(crate::refused!(input path.display();
                    "{} has no [measurement] section, so the tracker's placement against the robot is unknown and the \
                     run's positions cannot be brought into the base frame: give the identified robot file of the \
                     robot's calibration (calib calibrate --out), or data in the base frame (# frame: base)",
                    path.display()));
            }
        };
        Ok(Self {
            to_base,
            point_in_tool,
            text: format!("measured point: {probe_text}; positions {frame_text}"),
        })
    }
}

/// `AP` and `RP` of one point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointCharacteristics {
    /// The point's id (`P1`..`P5`, or a target's id).
    pub point: String,
    /// Cycles measured.
    pub cycles: usize,
    /// The measured point's commanded position, base frame, mm.
    pub commanded_mm: [f64; 3],
    /// The barycentre of the attained positions, base frame, mm.
    pub barycentre_mm: [f64; 3],
    /// `APx, APy, APz`: the barycentre minus the commanded position, mm.
    pub ap_xyz_mm: [f64; 3],
    /// Position accuracy `AP`, mm.
    pub ap_mm: f64,
    /// Position repeatability `RP = mean(l) + 3 S_l`, mm.
    pub rp_mm: f64,
    /// `AP_a, AP_b, AP_c`: the mean orientation deviation about the base's x, y, z axes, deg;
    /// `None` without orientation measured.
    pub ap_abc_deg: Option<[f64; 3]>,
    /// `RP_a, RP_b, RP_c = +-3 S`, deg; `None` without orientation measured.
    pub rp_abc_deg: Option<[f64; 3]>,
}

/// `AD` and `RD` between two points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DistanceCharacteristics {
    /// The two points.
    pub points: [String; 2],
    /// Cycles paired.
    pub cycles: usize,
    /// The commanded distance `D_c`, mm.
    pub commanded_mm: f64,
    /// The mean attained distance, mm.
    pub mean_mm: f64,
    /// Distance accuracy `AD = mean(D) - D_c`, mm.
    pub ad_mm: f64,
    /// Distance repeatability `RD = +-3 S_D`, mm.
    pub rd_mm: f64,
}

/// The drift of `AP` and `RP` of one point over the run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Drift {
    /// The point.
    pub point: String,
    /// Cycles in each of the first and the last block.
    pub block_cycles: usize,
    /// `AP` over the first block and over the last, mm.
    pub ap_mm: [f64; 2],
    /// `dAP = |AP_first - AP_last|`, mm.
    pub dap_mm: f64,
    /// `RP` over the first block and over the last, mm.
    pub rp_mm: [f64; 2],
    /// `dRP = |RP_first - RP_last|`, mm.
    pub drp_mm: f64,
    /// Time from the first block's first pose to the last block's last, s, when the data carry
    /// times.
    pub span_s: Option<f64>,
}

/// The characteristics of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Characteristics {
    /// Per point.
    pub points: Vec<PointCharacteristics>,
    /// Between `P2` and `P4`, when both were measured in at least two common cycles.
    pub distance: Option<DistanceCharacteristics>,
    /// Of `P1`, when it was measured in at least 6 cycles.
    pub drift: Option<Drift>,
    /// What limits the figures (too few cycles for the standard, rows left unpaired).
    pub notes: Vec<String>,
}

/// A point's attained poses in the base frame, in cycle order: position (mm), rotation, time.
type Attained = Vec<(Vector3<f64>, Option<Matrix3<f64>>, Option<f64>)>;

/// The characteristics of the run `run` against the commanded `targets` (base frame) in the
/// measurement `setup`. Each row belongs to the target whose id is the row's id or its part
/// before the first `-` (`P3-c07` is `P3`'s); rows of a point are its cycles in file order.
/// Refused: a row of no target, a target measured fewer than 2 times.
pub fn characteristics(
    targets: &[Target],
    run: &TrackerData,
    setup: &MeasurementSetup,
) -> crate::Result<Characteristics> {
    let mut attained: Vec<Attained> = vec![Vec::new(); targets.len()];
    for row in &run.records {
        let point = point_of(targets, row).ok_or_else(|| {
            crate::refused!(input run.path.display();
                "{} line {}: id {:?} names no target of the test ({}); the run's ids are <point>-c<cycle> as calib iso9283 plan writes them",
                run.path.display(), row.line, row.id,
                targets.iter().map(|t| t.id.as_str()).collect::<Vec<_>>().join(", "))
        })?;
        let position = setup.to_base * Point3::from(Vector3::from(row.position));
        let rotation = row
            .rotation
            .map(|r| setup.to_base.rotation.to_rotation_matrix().matrix() * r);
        attained[point].push((position.coords, rotation, row.time_s));
    }
    let mut notes = Vec::new();
    let mut points = Vec::with_capacity(targets.len());
    for (target, poses) in targets.iter().zip(&attained) {
        if poses.len() < 2 {
            return Err(crate::refused!(input run.path.display();
                "{}: target {} was measured {} time(s); its repeatability needs at least 2 cycles (ISO 9283: {ISO_CYCLES})",
                run.path.display(), target.id, poses.len()));
        }
        points.push(point(target, poses, setup));
    }
    let fewest = points.iter().map(|p| p.cycles).min().unwrap_or(0);
    if fewest < ISO_CYCLES {
        notes.push(format!(
            "{fewest} cycles of the least measured point: ISO 9283 asks for {ISO_CYCLES}; the repeatabilities are indicative"
        ));
    }
    let index = |id: &str| targets.iter().position(|t| t.id == id);
    let distance = match (index("P2"), index("P4")) {
        (Some(a), Some(b)) => distance(&points, (a, b), (&attained[a], &attained[b]), &mut notes),
        _ => None,
    };
    let drift = index("P1").and_then(|p| drift(&targets[p], &attained[p], setup));
    Ok(Characteristics {
        points,
        distance,
        drift,
        notes,
    })
}

/// The target a row belongs to (its index).
fn point_of(targets: &[Target], row: &Record) -> Option<usize> {
    let stem = row.id.split('-').next().unwrap_or(&row.id);
    (targets.iter()).position(|t| t.id == row.id || t.id == stem)
}

/// The commanded position (mm) and rotation of the measured point at `target`.
fn commanded(target: &Target, setup: &MeasurementSetup) -> (Vector3<f64>, Matrix3<f64>) {
    let rotation = Rotation3::from_matrix_unchecked(target.rotation);
    let pose = Isometry3::from_parts(
        Vector3::from(target.position_mm).into(),
        nalgebra::UnitQuaternion::from_rotation_matrix(&rotation),
    ) * setup.point_in_tool;
    (
        pose.translation.vector,
        *pose.rotation.to_rotation_matrix().matrix(),
    )
}

/// `AP` and `RP` of positions `x` against the commanded `c`: (barycentre, AP, RP), mm.
fn ap_rp(x: &[Vector3<f64>], c: &Vector3<f64>) -> (Vector3<f64>, f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<Vector3<f64>>() / n;
    let l: Vec<f64> = x.iter().map(|p| (p - mean).norm()).collect();
    let (l_mean, s) = mean_and_sd(&l);
    (mean, (mean - c).norm(), l_mean + 3.0 * s)
}

/// The mean and the sample standard deviation (divisor `n - 1`) of `v` (`n >= 2`).
fn mean_and_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let s = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    (mean, s)
}

/// One point's characteristics.
fn point(target: &Target, poses: &Attained, setup: &MeasurementSetup) -> PointCharacteristics {
    let (c, rc) = commanded(target, setup);
    let x: Vec<Vector3<f64>> = poses.iter().map(|p| p.0).collect();
    let (mean, ap, rp) = ap_rp(&x, &c);
    let deviations: Option<Vec<Vector3<f64>>> = (poses.iter())
        .map(|p| {
            p.1.map(|r| Rotation3::from_matrix(&(r * rc.transpose())).scaled_axis())
        })
        .collect();
    let orientation = deviations.map(|d| {
        let per_axis =
            |k: usize| mean_and_sd(&d.iter().map(|v| v[k].to_degrees()).collect::<Vec<_>>());
        let [a, b, cc] = [0, 1, 2].map(per_axis);
        ([a.0, b.0, cc.0], [3.0 * a.1, 3.0 * b.1, 3.0 * cc.1])
    });
    let d = mean - c;
    PointCharacteristics {
        point: target.id.clone(),
        cycles: poses.len(),
        commanded_mm: [c.x, c.y, c.z],
        barycentre_mm: [mean.x, mean.y, mean.z],
        ap_xyz_mm: [d.x, d.y, d.z],
        ap_mm: ap,
        rp_mm: rp,
        ap_abc_deg: orientation.map(|o| o.0),
        rp_abc_deg: orientation.map(|o| o.1),
    }
}

/// `AD` and `RD` between points `a` and `b`, their cycles paired in order.
fn distance(
    points: &[PointCharacteristics],
    (a, b): (usize, usize),
    (xa, xb): (&Attained, &Attained),
    notes: &mut Vec<String>,
) -> Option<DistanceCharacteristics> {
    let cycles = xa.len().min(xb.len());
    if xa.len() != xb.len() {
        notes.push(format!(
            "{} was measured {} times and {} {} times: the distance characteristics pair their first {cycles} cycles",
            points[a].point, xa.len(), points[b].point, xb.len()
        ));
    }
    if cycles < 2 {
        return None;
    }
    let commanded =
        (Vector3::from(points[a].commanded_mm) - Vector3::from(points[b].commanded_mm)).norm();
    let d: Vec<f64> = (0..cycles).map(|j| (xa[j].0 - xb[j].0).norm()).collect();
    let (mean, s) = mean_and_sd(&d);
    Some(DistanceCharacteristics {
        points: [points[a].point.clone(), points[b].point.clone()],
        cycles,
        commanded_mm: commanded,
        mean_mm: mean,
        ad_mm: mean - commanded,
        rd_mm: 3.0 * s,
    })
}

/// The drift of `AP` and `RP` at `target` over the first and the last third of its cycles
/// (at least 2 each: 6 cycles).
fn drift(target: &Target, poses: &Attained, setup: &MeasurementSetup) -> Option<Drift> {
    let block = poses.len() / 3;
    if block < 2 {
        return None;
    }
    let (c, _) = commanded(target, setup);
    let x: Vec<Vector3<f64>> = poses.iter().map(|p| p.0).collect();
    let (_, ap_first, rp_first) = ap_rp(&x[..block], &c);
    let (_, ap_last, rp_last) = ap_rp(&x[x.len() - block..], &c);
    let span_s = match (
        poses.first().and_then(|p| p.2),
        poses.last().and_then(|p| p.2),
    ) {
        (Some(first), Some(last)) => Some(last - first),
        _ => None,
    };
    Some(Drift {
        point: target.id.clone(),
        block_cycles: block,
        ap_mm: [ap_first, ap_last],
        dap_mm: (ap_first - ap_last).abs(),
        rp_mm: [rp_first, rp_last],
        drp_mm: (rp_first - rp_last).abs(),
        span_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Orientation measured: a point whose attained orientation turns about the base's z axis by
    /// 0.01, 0.02 and 0.03 deg in three cycles gives `AP_c` 0.02 deg and `RP_c = 3 S` = 0.03 deg,
    /// `AP_a`, `AP_b` zero; positions on the commanded point give `AP` and `RP` zero.
    #[test]
    fn orientation_characteristics_have_their_closed_form() {
        let commanded = Rotation3::from_euler_angles(0.1, -0.2, 0.3);
        let target = Target {
            id: "P1".into(),
            position_mm: [1000.0, 0.0, 500.0],
            rotation: *commanded.matrix(),
        };
        let records = (1..=3)
            .map(|c| Record {
                line: c,
                id: format!("P1-c{c}"),
                q: vec![0.0; 6],
                position: [1000.0, 0.0, 500.0],
                rotation: Some(
                    *(Rotation3::from_axis_angle(
                        &Vector3::z_axis(),
                        (0.01 * c as f64).to_radians(),
                    ) * commanded)
                        .matrix(),
                ),
                weight: 1.0,
                role: None,
                configuration: None,
                time_s: None,
                temperature_c: None,
            })
            .collect();
        let run = TrackerData::from_records(records, true).unwrap();
        let setup = MeasurementSetup {
            to_base: Isometry3::identity(),
            point_in_tool: Isometry3::identity(),
            text: String::new(),
        };
        let c = characteristics(&[target], &run, &setup).unwrap();
        let p = &c.points[0];
        assert!(p.ap_mm < 1e-9 && p.rp_mm < 1e-9);
        let [a, b, cz] = p.ap_abc_deg.unwrap();
        assert!(
            a.abs() < 1e-9 && b.abs() < 1e-9 && (cz - 0.02).abs() < 1e-9,
            "{a} {b} {cz}"
        );
        let rp = p.rp_abc_deg.unwrap();
        assert!(
            rp[0] < 1e-9 && rp[1] < 1e-9 && (rp[2] - 0.03).abs() < 1e-9,
            "{rp:?}"
        );
        assert!(c.distance.is_none() && c.drift.is_none());
    }
}
