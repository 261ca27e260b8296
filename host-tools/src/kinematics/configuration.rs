//! The arm configuration of a posture on a robot without a closed-form inverse kinematics
//! (7-joint arms such as the KUKA iiwa, the Franka Panda and the Barrett WAM, and geometries no
//! closed form covers), so that a numerical solution is accepted only in the configuration the
//! caller asked for. Robots with a closed form name their configurations by branch
//! ([`super::compensate`]); here a configuration is what a robot program keeps:
//!
//! - **The side of each configuration joint.** A configuration joint is one at whose angle `c`
//!   (zero or a half turn) two joint axes of the arm fall on one line, or the arm is singular,
//!   whatever the other joints read. They are found numerically from the nominal geometry
//!   ([`ConfigurationJoints::of`]): on the KUKA iiwa joints 2, 4 and 6 at 0 deg, the shoulder,
//!   elbow and wrist bits of KUKA's `Status`. The numerical inverse kinematics reaches the other
//!   side only through the alignment, where a robot program would turn the joints around (a wrist
//!   flip: joint 6 crossing 0, joints 5 and 7 turning by half a turn), so a solution keeps the sign
//!   of `sin(q - c)` of the posture.
//! - **The arm angle** (7-joint arms): the elbow's turn about the line from the shoulder to the
//!   wrist, measured from the plane through that line and the first joint's axis (the shoulder
//!   is where axes 1 and 2 meet, the elbow where axes 3 and 4 do, the wrist where axes 5 and 6 do:
//!   the feet of their common perpendiculars). The signs leave the arm free to swing its elbow
//!   about that line (the redundancy); a solution keeps the posture's arm angle within
//!   [`DEFAULT_MAX_ARM_ANGLE_DEG`] (`calib compensate --max-arm-angle-deg`).
//!
//! - **Every joint near the posture**: within [`DEFAULT_MAX_JOINT_DISTANCE_DEG`] of it
//!   (`--near-within-deg`). Near an alignment the signs and the arm angle still leave joints free
//!   to trade half turns (joints 1 and 3 of an iiwa at a small joint 2); a program never wants
//!   those.
//!
//! A posture within [`BOUNDARY_MARGIN_DEG`] of a configuration joint's angle names no side, and is
//! refused as a posture.

use calib_core::Kinematics;
use calib_core::kinematics::jacobian::JointJacobian;
use calib_core::model::{JacobianColumns, JointLimits, JointVec};
use nalgebra::{Dyn, Vector3};
use std::f64::consts::{PI, TAU};

/// The default bound on the arm angle's change from the posture, deg (`--max-arm-angle-deg`):
/// a compensation moves the elbow by hundredths of a degree; another solution of the same pose
/// with the same signs is a swing of the elbow through the workspace.
pub const DEFAULT_MAX_ARM_ANGLE_DEG: f64 = 15.0;

/// The default bound on any joint's distance from the posture, deg (`--near-within-deg`).
pub const DEFAULT_MAX_JOINT_DISTANCE_DEG: f64 = 90.0;

/// How close to a configuration joint's angle a posture names no side, deg.
pub const BOUNDARY_MARGIN_DEG: f64 = 1.0;

/// Postures sampled (within the joint limits) to decide whether a joint angle is a configuration
/// boundary: it must be one at every sample.
const SAMPLES: usize = 6;

/// Two axes are one line when their directions differ by less than this (rad) and their
/// distance is below [`SAME_LINE_MM`].
const SAME_DIRECTION: f64 = 1e-9;

/// See [`SAME_DIRECTION`], mm.
const SAME_LINE_MM: f64 = 1e-6;

/// The arm is singular at a sample when the manipulability of its scaled Jacobian falls below
/// this fraction of the manipulability at the sample before the joint was set.
const SINGULAR_FRACTION: f64 = 1e-9;

/// The configuration joints of a robot and whether its arm angle is defined (7 joints).
#[derive(Clone, Debug, PartialEq)]
pub struct ConfigurationJoints {
    /// Each configuration joint (0-based) with its boundary angle (rad, within the limits).
    pub boundaries: Vec<(usize, f64)>,
    /// Whether the arm angle is part of the configuration (7 joints).
    pub arm_angle: bool,
}

/// How far a solution may be from the posture and stay in its configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConfigurationBounds {
    /// The largest change of the arm angle, rad (7-joint arms).
    pub max_arm_angle_rad: f64,
    /// The largest distance of any joint from the posture, rad.
    pub max_joint_distance_rad: f64,
}

impl Default for ConfigurationBounds {
    /// [`DEFAULT_MAX_ARM_ANGLE_DEG`] and [`DEFAULT_MAX_JOINT_DISTANCE_DEG`].
    fn default() -> Self {
        Self {
            max_arm_angle_rad: DEFAULT_MAX_ARM_ANGLE_DEG.to_radians(),
            max_joint_distance_rad: DEFAULT_MAX_JOINT_DISTANCE_DEG.to_radians(),
        }
    }
}

/// The configuration of one posture: the configuration joints' sides and the arm angle.
#[derive(Clone, Debug, PartialEq)]
pub struct PostureConfiguration {
    /// The posture, rad.
    pub posture: JointVec<f64>,
    /// Its arm angle, rad (`None`: not a 7-joint arm, or the arm stretched or its shoulder-wrist
    /// line along the first axis, where the angle is not defined).
    pub arm_angle_rad: Option<f64>,
    /// The bounds of the configuration: the arm angle's change and any joint's distance, rad.
    pub bounds: ConfigurationBounds,
    /// The robot's configuration joints.
    pub joints: ConfigurationJoints,
}

impl ConfigurationJoints {
    /// The configuration joints of the nominal robot `planned` with `limits` (see the module
    /// documentation), found at six postures spread over the limits.
    pub fn of(planned: &Kinematics<f64, Dyn>, limits: &JointVec<JointLimits<f64>>) -> Self {
        let n = limits.len();
        let samples: Vec<JointVec<f64>> = (0..SAMPLES)
            .map(|s| {
                JointVec::from_fn(n, |j| {
                    // An additive recurrence (golden ratio), shifted per joint: spread, fixed.
                    let u =
                        ((s + 1) as f64 * 0.618_033_988_749_895 + j as f64 * 0.414_213_562).fract();
                    let (lo, hi) = (limits[j].lower.max(-PI), limits[j].upper.min(PI));
                    lo + (0.1 + 0.8 * u) * (hi - lo)
                })
            })
            .collect();
        let mut boundaries = Vec::new();
        for j in 0..n {
            for c in [0.0, PI] {
                let Some(c) = within_limits(c, &limits[j]) else {
                    continue;
                };
                let is_boundary = samples.iter().all(|sample| {
                    let mut q = *sample;
                    q[j] = c;
                    aligned_or_singular(planned, &q) && !aligned_or_singular(planned, sample)
                });
                if is_boundary {
                    boundaries.push((j, c));
                }
            }
        }
        Self {
            boundaries,
            arm_angle: n == 7,
        }
    }
}

impl PostureConfiguration {
    /// The configuration of `posture` (rad) on `planned`. A posture within
    /// [`BOUNDARY_MARGIN_DEG`] of a configuration joint's angle names no side: an error when
    /// `strict` (a posture the caller chose), else that joint's side is left free (the
    /// controller's own joints for a target, from which a compensation moves by the joint bound
    /// at most, through the alignment only where the arm already is).
    pub fn of(
        planned: &Kinematics<f64, Dyn>,
        mut joints: ConfigurationJoints,
        posture: JointVec<f64>,
        bounds: ConfigurationBounds,
        strict: bool,
    ) -> Result<Self, String> {
        let at_boundary = |&(j, c): &(usize, f64)| {
            wrapped(posture[j] - c).abs() < BOUNDARY_MARGIN_DEG.to_radians()
        };
        if !strict {
            joints.boundaries.retain(|b| !at_boundary(b));
        }
        if let Some(&(j, c)) = joints.boundaries.iter().find(|b| at_boundary(b)) {
            return Err(format!(
                "the posture's joint {} at {:.3} deg is within {BOUNDARY_MARGIN_DEG} deg of {:.0} deg, where two joint axes align and the arm's configuration changes: it names no configuration; name a posture away from it",
                j + 1,
                posture[j].to_degrees(),
                c.to_degrees()
            ));
        }
        let arm_angle_rad = if joints.arm_angle {
            arm_angle(planned, &posture)
        } else {
            None
        };
        Ok(Self {
            posture,
            arm_angle_rad,
            bounds,
            joints,
        })
    }

    /// Why joints `q` (rad) are in another configuration than the posture's; `None` when they
    /// are in it.
    pub fn departure(&self, planned: &Kinematics<f64, Dyn>, q: &JointVec<f64>) -> Option<String> {
        if let Some((j, distance)) = q
            .iter()
            .zip(&self.posture)
            .map(|(q, p)| (q - p).abs())
            .enumerate()
            .find(|(_, d)| *d > self.bounds.max_joint_distance_rad)
        {
            return Some(format!(
                "joint {} at {:.3} deg is {:.3} deg from the posture's {:.3} deg (bound {:.3} deg, --near-within-deg)",
                j + 1,
                q[j].to_degrees(),
                distance.to_degrees(),
                self.posture[j].to_degrees(),
                self.bounds.max_joint_distance_rad.to_degrees()
            ));
        }
        for &(j, c) in &self.joints.boundaries {
            let (side, posture_side) = ((q[j] - c).sin(), (self.posture[j] - c).sin());
            if side * posture_side < 0.0 {
                return Some(format!(
                    "joint {} at {:.3} deg is on the other side of {:.0} deg than the posture's {:.3} deg (a flip of the arm's configuration)",
                    j + 1,
                    q[j].to_degrees(),
                    c.to_degrees(),
                    self.posture[j].to_degrees()
                ));
            }
        }
        let (Some(posture), Some(angle)) = (self.arm_angle_rad, arm_angle(planned, q)) else {
            return None;
        };
        let change = wrapped(angle - posture);
        (change.abs() > self.bounds.max_arm_angle_rad).then(|| {
            format!(
                "the arm angle is {:.3} deg, the posture's {:.3} deg: the elbow swings by {:.3} deg about the shoulder-wrist line (bound {:.3} deg, --max-arm-angle-deg)",
                angle.to_degrees(),
                posture.to_degrees(),
                change.abs().to_degrees(),
                self.bounds.max_arm_angle_rad.to_degrees()
            )
        })
    }

    /// The configuration in words, for the output's `configuration` column.
    pub fn describe(&self) -> String {
        let mut parts = Vec::new();
        if !self.joints.boundaries.is_empty() {
            let signs: Vec<String> = self
                .joints
                .boundaries
                .iter()
                .map(|(j, c)| {
                    let side = if (self.posture[*j] - c).sin() > 0.0 {
                        "+"
                    } else {
                        "-"
                    };
                    format!("q{}{side}", j + 1)
                })
                .collect();
            parts.push(format!("sides {}", signs.join(" ")));
        }
        if let Some(angle) = self.arm_angle_rad {
            parts.push(format!(
                "arm angle {:.1} deg within {:.1} deg",
                angle.to_degrees(),
                self.bounds.max_arm_angle_rad.to_degrees()
            ));
        }
        parts.push(format!(
            "joints within {:.1} deg",
            self.bounds.max_joint_distance_rad.to_degrees()
        ));
        format!("the posture's ({})", parts.join(", "))
    }
}

/// `angle` turned by whole turns into `limits`, if it can be.
fn within_limits(angle: f64, limits: &JointLimits<f64>) -> Option<f64> {
    [angle, angle - TAU, angle + TAU]
        .into_iter()
        .find(|a| limits.contains(*a))
}

/// An angle wrapped into (-pi, pi], rad (whole turns aside).
pub(crate) fn wrapped(angle: f64) -> f64 {
    let w = (angle + PI).rem_euclid(TAU) - PI;
    if w <= -PI { w + TAU } else { w }
}

/// A joint axis as a line: a point on it (mm) and its unit direction.
type Line = (Vector3<f64>, Vector3<f64>);

/// The joint axes of an arm at some joint readings, and the Jacobian they come from.
struct Axes {
    /// Each joint's axis as a line.
    lines: Vec<Line>,
    /// The end point, mm.
    end: Vector3<f64>,
    /// The geometric Jacobian.
    jacobian: JointJacobian<f64, Dyn>,
}

/// The joint axes of `planned` at `q` as lines (from the geometric Jacobian's columns: the
/// direction `omega` and `v = omega x (end - o)`, so `end + omega x v` lies on the axis).
fn axes(planned: &Kinematics<f64, Dyn>, q: &JointVec<f64>) -> Option<Axes> {
    let (end, jacobian) = planned.geometric_jacobian(q).ok()?;
    let end = end.translation.vector;
    let lines = (0..q.len())
        .map(|j| {
            let c = jacobian.column(j);
            let (v, w) = (
                c.fixed_rows::<3>(0).into_owned(),
                c.fixed_rows::<3>(3).into_owned(),
            );
            (end + w.cross(&v), w)
        })
        .collect();
    Some(Axes {
        lines,
        end,
        jacobian,
    })
}

/// Whether, at `q`, two joint axes of `planned` are one line or the arm is singular: the
/// manipulability `sqrt(det(J_s J_s^T))` of the Jacobian with its position rows scaled by the
/// arm's length below [`SINGULAR_FRACTION`] (the caller compares with the sample before a joint
/// was set).
fn aligned_or_singular(planned: &Kinematics<f64, Dyn>, q: &JointVec<f64>) -> bool {
    let Some(Axes {
        lines,
        end,
        mut jacobian,
    }) = axes(planned, q)
    else {
        return true;
    };
    let aligned = lines.iter().enumerate().any(|(a, (pa, wa))| {
        lines[a + 1..].iter().any(|(pb, wb)| {
            wa.cross(wb).norm() < SAME_DIRECTION && (pb - pa).cross(wa).norm() < SAME_LINE_MM
        })
    });
    let length = lines
        .iter()
        .map(|(p, _)| (p - end).norm())
        .fold(1.0, f64::max);
    jacobian.divide_position_rows(length);
    let manipulability = jacobian.outer_product_sum().determinant().max(0.0).sqrt();
    aligned || manipulability < SINGULAR_FRACTION
}

/// The foot, on the first line, of the common perpendicular of two lines, and the one on the
/// second; their middle. `None` for parallel lines.
fn meeting_point((p1, d1): &Line, (p2, d2): &Line) -> Option<Vector3<f64>> {
    let w = p1 - p2;
    let (a, b, c) = (d1.dot(d1), d1.dot(d2), d2.dot(d2));
    let (d, e) = (d1.dot(&w), d2.dot(&w));
    let den = a * c - b * b;
    if den.abs() < 1e-12 {
        return None;
    }
    let s = (b * e - c * d) / den;
    let t = (a * e - b * d) / den;
    Some(0.5 * ((p1 + d1 * s) + (p2 + d2 * t)))
}

/// The arm angle of a 7-joint arm at `q`, rad (see the module documentation); `None` where it is
/// not defined: the elbow within 1 mm of the shoulder-wrist line (the arm stretched), that line
/// within 3 deg of the first axis, or axes that do not meet in the shoulder, elbow or wrist.
pub fn arm_angle(planned: &Kinematics<f64, Dyn>, q: &JointVec<f64>) -> Option<f64> {
    let lines = axes(planned, q)?.lines;
    if lines.len() != 7 {
        return None;
    }
    let shoulder = meeting_point(&lines[0], &lines[1])?;
    let elbow = meeting_point(&lines[2], &lines[3])?;
    let wrist = meeting_point(&lines[4], &lines[5])?;
    let u = (wrist - shoulder).try_normalize(1e-9)?;
    let to_elbow = elbow - shoulder;
    let e = to_elbow - u * to_elbow.dot(&u);
    let first = lines[0].1;
    let r = first - u * first.dot(&u);
    if e.norm() < 1.0 || r.norm() < 3f64.to_radians().sin() {
        return None;
    }
    Some(r.cross(&e).dot(&u).atan2(r.dot(&e)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn robot(name: &str) -> (Kinematics<f64, Dyn>, JointVec<JointLimits<f64>>) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("robots")
            .join(name);
        let model = crate::io::robot_file::RobotModel::load(&path).unwrap();
        (
            Kinematics::nominal(&model.robot).unwrap(),
            model.robot.limits,
        )
    }

    /// The iiwa's configuration joints are 2, 4 and 6 at 0 deg (KUKA's Status bits: the axes 1
    /// and 3, 3 and 5, 5 and 7 fall on one line there), and nothing else; the WAM's the same.
    #[test]
    fn the_iiwa_configuration_joints_are_its_shoulder_elbow_and_wrist() {
        let (planned, limits) = robot("kuka-iiwa14.toml");
        let joints = ConfigurationJoints::of(&planned, &limits);
        assert_eq!(joints.boundaries, vec![(1, 0.0), (3, 0.0), (5, 0.0)]);
        assert!(joints.arm_angle);
        let (planned, limits) = robot("barrett-wam.toml");
        let joints = ConfigurationJoints::of(&planned, &limits);
        // The WAM's elbow offsets (a3 = 45, a4 = -45 mm) cancel at q4 = 0: axes 3 and 5 align.
        assert_eq!(joints.boundaries, vec![(1, 0.0), (3, 0.0), (5, 0.0)]);
    }

    /// The issue's posture on the iiwa: a small change stays in its configuration; joint 6 on the
    /// other side of zero departs by its sign (with the distance bound lifted), joint 3 turned by
    /// 40 deg by the arm angle (the elbow swung about the shoulder-wrist line), and the issue's
    /// flipped wrist (joint 5 at 159 deg) by its distance under the default bounds.
    #[test]
    fn a_wrist_flip_and_an_elbow_swing_depart_from_the_posture() {
        let (planned, limits) = robot("kuka-iiwa14.toml");
        let joints = ConfigurationJoints::of(&planned, &limits);
        let deg = |v: [f64; 7]| JointVec::from_slice(&v.map(f64::to_radians)).unwrap();
        let posture = deg([10.0, 30.0, 0.0, -60.0, 0.0, 60.0, 0.0]);
        let of = |bounds| {
            PostureConfiguration::of(&planned, joints.clone(), posture, bounds, true).unwrap()
        };
        let config = of(ConfigurationBounds::default());
        assert_eq!(config.departure(&planned, &posture), None);
        let small = deg([10.3, 30.2, 0.4, -60.1, 0.3, 60.2, 0.1]);
        assert_eq!(config.departure(&planned, &small), None);
        let unbounded = of(ConfigurationBounds {
            max_joint_distance_rad: TAU,
            ..ConfigurationBounds::default()
        });
        let flipped = deg([10.0, 30.0, 0.0, -60.0, 20.0, -60.0, 10.0]);
        let why = unbounded.departure(&planned, &flipped).unwrap();
        assert!(
            why.starts_with("joint 6 at -60.000 deg is on the other side of 0 deg"),
            "{why}"
        );
        let swung = deg([10.0, 30.0, 40.0, -60.0, 0.0, 60.0, 0.0]);
        let why = config.departure(&planned, &swung).unwrap();
        assert!(why.contains("arm angle"), "{why}");
        let issue = deg([-6.6, 32.3, 30.0, -59.9, 159.1, -61.4, -169.6]);
        let why = config.departure(&planned, &issue).unwrap();
        assert!(
            why.starts_with("joint 5 at 159.100 deg is 159.100 deg from"),
            "{why}"
        );
    }

    /// The arm angle of the iiwa at q1 = q3 = 0 (the elbow in the plane of the first axis and the
    /// shoulder-wrist line) is 0 or a half turn; joint 3 turned by 90 deg swings the elbow out of
    /// that plane; straight up, the angle is not defined.
    #[test]
    fn the_arm_angle_is_zero_in_the_plane_of_the_first_axis() {
        let (planned, _) = robot("kuka-iiwa14.toml");
        let deg = |v: [f64; 7]| JointVec::from_slice(&v.map(f64::to_radians)).unwrap();
        let psi = arm_angle(&planned, &deg([0.0, 30.0, 0.0, -60.0, 0.0, 30.0, 0.0])).unwrap();
        assert!(
            wrapped(psi).abs() < 1e-9 || (wrapped(psi).abs() - PI).abs() < 1e-9,
            "{psi}"
        );
        let swung = arm_angle(&planned, &deg([0.0, 30.0, 90.0, -60.0, 0.0, 30.0, 0.0])).unwrap();
        assert!(
            wrapped(swung - psi).abs() > 20f64.to_radians(),
            "{swung} {psi}"
        );
        // Straight up: no shoulder-wrist line off the first axis, no angle.
        assert_eq!(arm_angle(&planned, &deg([0.0; 7])), None);
    }
}
