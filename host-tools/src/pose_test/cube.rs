//! The ISO 9283 test cube and its five points (clause 6.8 of ISO 9283:1998), and the test's
//! program: `n` cycles through the points, each reached by the controller's own model.
//!
//! The cube stands in the base frame with edges parallel to its axes (as the standard asks), at
//! the centre and of the edge the user states (the largest cube in the part of the workspace the
//! application uses). The points lie in the diagonal plane through the cube's corners
//! `C1 = (-h, -h, -h)`, `C2 = (h, -h, -h)`, `C7 = (h, h, h)` and `C8 = (-h, h, h)` (`h` half the
//! edge, from the centre): `P1` is the centre, where the plane's diagonals cross; `P2` to `P5`
//! lie on those diagonals at [`CORNER_FRACTION`] of the diagonal's length from the corners `C1`,
//! `C2`, `C7` and `C8` (so `P2` and `P4` share the diagonal `C1-C7`, the distance
//! characteristics' pair). One cycle visits `P1, P5, P4, P3, P2` (the standard's order); the tool
//! keeps one orientation throughout.

use super::Target;
use crate::io::robot_file::RobotFile;
use crate::kinematics::targets::{CompensationRequest, ConfigurationChoice, TargetsFrame};
use nalgebra::{Rotation3, UnitQuaternion, Vector3};
use std::fmt::Write as _;
use std::path::Path;

/// The points' names, `P1` to `P5`.
pub const POINTS: [&str; 5] = ["P1", "P2", "P3", "P4", "P5"];

/// The order in which one cycle visits the points (indices into [`POINTS`]): `P1, P5, P4, P3,
/// P2`.
pub const CYCLE_ORDER: [usize; 5] = [0, 4, 3, 2, 1];

/// Cycles of the test unless stated (ISO 9283: 30).
pub const DEFAULT_CYCLES: usize = 30;

/// The most cycles a plan may have (the program's size: 5 moves per cycle).
pub const MAX_CYCLES: usize = 10_000;

/// How far `P2` to `P5` lie from their corners, as a fraction of the diagonal (ISO 9283: 10 % +-
/// 2 %).
pub const CORNER_FRACTION: f64 = 0.1;

/// The largest cube edge accepted, mm (a cube beyond any industrial robot's reach is a typo).
const MAX_EDGE_MM: f64 = 10_000.0;

/// The test cube: its centre in the robot's base frame and its edge, mm.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TestCube {
    /// The cube's centre (`P1`) in the base frame, mm.
    pub centre_mm: [f64; 3],
    /// The cube's edge, mm.
    pub edge_mm: f64,
}

impl TestCube {
    /// A cube of edge `edge_mm` centred on `centre_mm` (base frame, mm). Refused: a centre that
    /// is not finite, an edge not above 0 or beyond 10 m.
    pub fn new(centre_mm: [f64; 3], edge_mm: f64) -> crate::Result<Self> {
        if !centre_mm.iter().all(|v| v.is_finite()) {
            return Err(crate::refused!(option "--centre-mm";
                "--centre-mm {centre_mm:?}: give the cube's centre as three finite numbers X,Y,Z (mm, base frame)"));
        }
        if !(edge_mm.is_finite() && edge_mm > 0.0 && edge_mm <= MAX_EDGE_MM) {
            return Err(crate::refused!(option "--edge-mm";
                "--edge-mm {edge_mm}: give the cube's edge in mm, above 0 and at most {MAX_EDGE_MM}"));
        }
        Ok(Self { centre_mm, edge_mm })
    }

    /// The five points `P1` to `P5` in the base frame, mm.
    pub fn points(&self) -> [[f64; 3]; 5] {
        let h = self.edge_mm / 2.0;
        let c = Vector3::from(self.centre_mm);
        let corner = |x: f64, y: f64, z: f64| c + Vector3::new(x * h, y * h, z * h);
        let (c1, c2, c7, c8) = (
            corner(-1.0, -1.0, -1.0),
            corner(1.0, -1.0, -1.0),
            corner(1.0, 1.0, 1.0),
            corner(-1.0, 1.0, 1.0),
        );
        let near = |from: Vector3<f64>, to: Vector3<f64>| from + (to - from) * CORNER_FRACTION;
        [c, near(c1, c7), near(c2, c8), near(c7, c1), near(c8, c2)].map(|p| [p.x, p.y, p.z])
    }
}

/// The test planned: the cube, the tool's orientation, the points as targets and the joints
/// that reach them in the controller's model.
#[derive(Clone, Debug, PartialEq)]
pub struct TestPlan {
    /// The robot's name (the robot file's `name`).
    pub robot: String,
    /// The cube.
    pub cube: TestCube,
    /// The tool's orientation at every point, base frame, deg (`R = Rz Ry Rx`).
    pub rpy_deg: [f64; 3],
    /// Cycles.
    pub cycles: usize,
    /// The points as the tool's target poses (base frame), `P1` to `P5`.
    pub targets: Vec<Target>,
    /// The joints (rad) that put the tool on each target in the controller's model, `P1` to `P5`.
    pub joints: Vec<Vec<f64>>,
}

impl TestPlan {
    /// Plans the test for the robot `file` (read from `path`: the model the controller plans
    /// with): the `cube`'s points with the tool at orientation `rpy_deg` (base frame, deg; `None`:
    /// the tool's orientation at the posture of `configuration` when that is a posture), reached
    /// in `configuration`, `cycles` times. Refused: a point the robot cannot reach in that
    /// configuration (named), a robot of fewer than 6 joints, cycles outside 2 to
    /// [`MAX_CYCLES`].
    pub fn new(
        (file, path): (&RobotFile, &Path),
        cube: TestCube,
        rpy_deg: Option<[f64; 3]>,
        configuration: ConfigurationChoice,
        cycles: usize,
    ) -> crate::Result<Self> {
        if !(2..=MAX_CYCLES).contains(&cycles) {
            return Err(crate::refused!(option "--cycles";
                "--cycles {cycles}: give 2 to {MAX_CYCLES} cycles (ISO 9283: 30; repeatability needs at least 2)"));
        }
        let rpy_deg = match (rpy_deg, &configuration) {
            (Some(rpy), _) => rpy,
            (None, ConfigurationChoice::NearDeg(posture)) => orientation_at((file, path), posture)?,
            (None, ConfigurationChoice::Branch(_)) => {
                return Err(crate::refused!(option "--rpy-deg";
                    "the tool's orientation at the cube's points is not stated: give --rpy-deg R,P,Y (deg, base frame), or a posture with --near-deg whose orientation the tool keeps"));
            }
        };
        if !rpy_deg.iter().all(|v| v.is_finite()) {
            return Err(crate::refused!(option "--rpy-deg";
                "--rpy-deg {rpy_deg:?}: give three finite angles R,P,Y in degrees"));
        }
        let [roll, pitch, yaw] = rpy_deg.map(f64::to_radians);
        let rotation = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
        let targets: Vec<Target> = (POINTS.iter().zip(cube.points()))
            .map(|(id, position_mm)| Target {
                id: id.to_string(),
                position_mm,
                rotation: *rotation.to_rotation_matrix().matrix(),
            })
            .collect();
        let joints = reach((file, path), &targets, configuration)?;
        Ok(Self {
            robot: file.name.clone(),
            cube,
            rpy_deg,
            cycles,
            targets,
            joints,
        })
    }

    /// The program's moves in order: per cycle `c` (from 1) the points in [`CYCLE_ORDER`], each
    /// as its id `P<k>-c<c>` and joints (rad).
    pub fn moves(&self) -> Vec<(String, &[f64])> {
        let width = self.cycles.to_string().len();
        (1..=self.cycles)
            .flat_map(|cycle| {
                CYCLE_ORDER.iter().map(move |&p| {
                    (
                        format!("{}-c{cycle:0width$}", POINTS[p]),
                        self.joints[p].as_slice(),
                    )
                })
            })
            .collect()
    }

    /// The targets as a targets file (`id, x_mm, y_mm, z_mm, qw, qx, qy, qz`, base frame): the
    /// commanded poses `calib iso9283 evaluate` judges the run against, and which `calib
    /// compensate --targets` corrects for a compensated controller.
    pub fn targets_csv(&self) -> String {
        let mut text = format!(
            "# ISO 9283 test cube for {}: centre {:?} mm, edge {} mm, tool rpy {:?} deg, base frame\n\
             id,x_mm,y_mm,z_mm,qw,qx,qy,qz\n",
            crate::io::text::one_line(&self.robot),
            self.cube.centre_mm,
            self.cube.edge_mm,
            self.rpy_deg
        );
        for t in &self.targets {
            let q =
                UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(t.rotation));
            let [x, y, z] = t.position_mm;
            let _ = writeln!(
                text,
                "{},{x:.6},{y:.6},{z:.6},{:.12},{:.12},{:.12},{:.12}",
                t.id, q.w, q.i, q.j, q.k
            );
        }
        text
    }

    /// The run to measure, as a tracker CSV whose measurement columns (`x_mm, y_mm, z_mm`, tracker
    /// frame) the tracker software fills: one row per move, ids `P<k>-c<cycle>`, joints in deg.
    pub fn run_csv(&self) -> String {
        format!(
            "# ISO 9283 pose test of {}: {} cycles of P1, P5, P4, P3, P2; fill in the measurement columns (tracker frame)\n{}",
            crate::io::text::one_line(&self.robot),
            self.cycles,
            self.moves_csv(true)
        )
    }

    /// The program as joint targets for any controller (`id, q1_deg..qN_deg`, one row per move).
    pub fn joint_targets(&self) -> String {
        self.moves_csv(false)
    }

    /// One row per move: its id and joints (deg), with empty position columns when `measured`
    /// (the run to fill in).
    fn moves_csv(&self, measured: bool) -> String {
        let joints = self.joints.first().map_or(0, Vec::len);
        let mut text = String::from("id");
        for i in 1..=joints {
            let _ = write!(text, ",q{i}_deg");
        }
        text.push_str(if measured { ",x_mm,y_mm,z_mm\n" } else { "\n" });
        for (id, q) in self.moves() {
            text.push_str(&id);
            for v in q {
                let _ = write!(text, ",{}", v.to_degrees());
            }
            text.push_str(if measured { ",,,\n" } else { "\n" });
        }
        text
    }

    /// The program in URScript (Universal Robots, 6 joints): a `movej` to each move, a pause of
    /// the settle time for the tracker.
    pub fn urscript(&self, motion: &crate::formats::urscript::Motion) -> crate::Result<String> {
        let header = [
            format!(
                "ISO 9283 pose test of {}, written by calib iso9283 plan: {} cycles of P1, P5, P4, P3, P2.",
                self.robot, self.cycles
            ),
            format!(
                "Cube centre {:?} mm, edge {} mm (base frame); the robot stands still {} s at each point.",
                self.cube.centre_mm, self.cube.edge_mm, motion.settle_s
            ),
        ];
        let targets: Vec<(String, Vec<f64>)> = (self.moves().into_iter())
            .map(|(id, q)| (id, q.to_vec()))
            .collect();
        crate::formats::urscript::movej_program("iso9283_test", &header, &targets, motion)
    }
}

/// The tool's orientation (base frame, rpy deg) at the posture `posture_deg`.
fn orientation_at(
    (file, path): (&RobotFile, &Path),
    posture_deg: &[f64],
) -> crate::Result<[f64; 3]> {
    let model = file.to_model(path)?;
    let kinematics = calib_core::Kinematics::nominal(&model.robot)?;
    let q: Vec<f64> = posture_deg.iter().map(|v| v.to_radians()).collect();
    let q = calib_core::model::JointVec::from_slice(&q).ok_or_else(|| {
        crate::refused!(option "--near-deg"; "--near-deg: {} joints are more than a robot has", posture_deg.len())
    })?;
    if q.len() != file.joint.len() {
        return Err(crate::refused!(option "--near-deg";
            "--near-deg has {} joints and {} has {}: give one reading per joint",
            posture_deg.len(), path.display(), file.joint.len()));
    }
    let pose = kinematics.forward(&q)?;
    let (roll, pitch, yaw) = pose.rotation.euler_angles();
    Ok([roll, pitch, yaw].map(f64::to_degrees))
}

/// The joints (rad) that put the tool on each target in the model of `file`, in
/// `configuration`: the compensation's inverse kinematics with the model as its own actual robot.
fn reach(
    (file, path): (&RobotFile, &Path),
    targets: &[Target],
    configuration: ConfigurationChoice,
) -> crate::Result<Vec<Vec<f64>>> {
    let mut text = String::from("id,x_mm,y_mm,z_mm,qw,qx,qy,qz\n");
    for t in targets {
        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(t.rotation));
        let [x, y, z] = t.position_mm;
        let _ = writeln!(text, "{},{x},{y},{z},{},{},{},{}", t.id, q.w, q.i, q.j, q.k);
    }
    let mut request = CompensationRequest::new(path.to_path_buf());
    request.targets_text = Some(text);
    request.frame = TargetsFrame::Base;
    request.configuration = Some(configuration);
    let (outcomes, _) = request.outcomes((file.clone(), path), (file.clone(), path))?;
    (outcomes.into_iter())
        .map(|o| match o.result {
            Ok(c) => Ok(c.q.iter().copied().collect()),
            Err(why) => Err(crate::refused!(option "--centre-mm";
                "point {} of the cube cannot be reached in the configuration asked: {why}; choose a \
                 smaller --edge-mm or another --centre-mm (the cube must lie in the workspace)",
                o.id)),
        })
        .collect()
}
