//! Robot files in Craig's modified DH convention, converted exactly into our model.
//!
//! Craig (and Franka, KUKA's research community and many textbooks) publishes a joint as
//! `alpha_{i-1}, a_{i-1}, d_i, theta_i`: frame `i` is reached from frame `i-1` by
//! `Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)`. Our joint is the standard DH transform (with
//! Hayati's `beta`) `A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)`. Regrouping the
//! product of `N` Craig joints and a fixed flange row `Rx(alpha_N) Tx(a_N) Rz(theta_F) Tz(d_F)`,
//! and using that `Rx` and `Tx` commute:
//!
//! ```text
//! [Rx(alpha_0) Tx(a_0)] [Rz(theta_1) Tz(d_1) Tx(a_1) Rx(alpha_1)] ... [Rz(theta_N) Tz(d_N) Tx(a_N) Rx(alpha_N)] [Rz(theta_F) Tz(d_F)]
//!   base frame            our joint 1                                  our joint N                                   tool frame
//! ```
//!
//! so our joint `i` takes `d_i` and `theta_i` of Craig's row `i` and `a_i`, `alpha_i` of row
//! `i + 1` (the flange row for the last joint, or zero without one), the base frame absorbs row
//! 1's `alpha_0, a_0` (after the file's own `[base]`), and the tool frame the flange's
//! `theta_F, d_F` (before the file's own `[tool]`). Every step is exact: the converted model
//! reproduces the published forward kinematics to rounding (test: `tests/craig.rs`, Franka Panda).

use super::{FrameEntry, JointEntry};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

/// A joint in Craig's modified DH convention (mm, degrees).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CraigJointEntry {
    /// `alpha_{i-1}`: twist about the previous frame's x axis, degrees.
    pub alpha_prev_deg: f64,
    /// `a_{i-1}`: length along the previous frame's x axis, mm.
    pub a_prev_mm: f64,
    /// `d_i`: offset along this joint's axis, mm.
    pub d_mm: f64,
    /// Zero offset of `theta_i`, degrees.
    pub theta_offset_deg: f64,
    /// `[lower, upper]` joint limits, degrees (default: unlimited).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limits_deg: Option<Vec<f64>>,
    /// Parameters of our converted joint to identify (`a`, `d`, `alpha`, `beta`, `theta`; see
    /// the robot file's `identify`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identify: Option<Vec<String>>,
}

/// The fixed row after the last joint in Craig's convention (Franka's "flange"): frame `F` is
/// reached from the last joint's frame by `Rx(alpha_prev) Tx(a_prev) Rz(theta) Tz(d)`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CraigFlangeEntry {
    /// `alpha_N`, degrees.
    pub alpha_prev_deg: f64,
    /// `a_N`, mm.
    pub a_prev_mm: f64,
    /// `d_F`, mm.
    pub d_mm: f64,
    /// `theta_F`, degrees (default 0).
    #[serde(default)]
    pub theta_deg: f64,
}

/// An isometry as a frame entry (the inverse of [`FrameEntry::isometry`]).
pub(crate) fn frame_entry(frame: &Isometry3<f64>) -> FrameEntry {
    let (roll, pitch, yaw) = frame.rotation.euler_angles();
    FrameEntry {
        xyz_mm: frame.translation.vector.into(),
        rpy_deg: [roll, pitch, yaw].map(f64::to_degrees),
    }
}

/// Checks every value of the Craig tables where the file has it: a `[[craig_joint]]` row's
/// `a_prev_mm` and `alpha_prev_deg` become the joint before's in our convention, so an error
/// found after the conversion would name the wrong joint. The message names the row
/// (`craig_joint 3: a_prev_mm = ...`) or `craig_flange`.
pub(crate) fn check(
    joints: &[CraigJointEntry],
    flange: Option<&CraigFlangeEntry>,
) -> Result<(), String> {
    use super::{MAX_ANGLE_DEG, MAX_LENGTH_MM, plausible};
    for (i, j) in joints.iter().enumerate() {
        for (field, value, max, unit) in [
            ("alpha_prev_deg", j.alpha_prev_deg, MAX_ANGLE_DEG, "deg"),
            ("a_prev_mm", j.a_prev_mm, MAX_LENGTH_MM, "mm"),
            ("d_mm", j.d_mm, MAX_LENGTH_MM, "mm"),
            ("theta_offset_deg", j.theta_offset_deg, MAX_ANGLE_DEG, "deg"),
        ] {
            plausible(field, value, max, unit)
                .map_err(|m| format!("craig_joint {}: {m}", i + 1))?;
        }
    }
    if let Some(f) = flange {
        for (field, value, max, unit) in [
            ("alpha_prev_deg", f.alpha_prev_deg, MAX_ANGLE_DEG, "deg"),
            ("a_prev_mm", f.a_prev_mm, MAX_LENGTH_MM, "mm"),
            ("d_mm", f.d_mm, MAX_LENGTH_MM, "mm"),
            ("theta_deg", f.theta_deg, MAX_ANGLE_DEG, "deg"),
        ] {
            plausible(field, value, max, unit).map_err(|m| format!("craig_flange: {m}"))?;
        }
    }
    Ok(())
}

/// Our model of a robot published in Craig's convention: the joints in our convention, and the
/// base and tool frames that absorb what a chain of our joints cannot (`base` and `tool` are the
/// file's own frames, applied before and after the chain). Frames that stay the identity are
/// `None`.
pub(crate) fn to_standard(
    joints: &[CraigJointEntry],
    flange: Option<&CraigFlangeEntry>,
    base: Option<&FrameEntry>,
    tool: Option<&FrameEntry>,
) -> (Vec<JointEntry>, Option<FrameEntry>, Option<FrameEntry>) {
    let next = |i: usize| -> (f64, f64) {
        match (joints.get(i + 1), flange) {
            (Some(j), _) => (j.a_prev_mm, j.alpha_prev_deg),
            (None, Some(f)) => (f.a_prev_mm, f.alpha_prev_deg),
            (None, None) => (0.0, 0.0),
        }
    };
    let converted = joints
        .iter()
        .enumerate()
        .map(|(i, joint)| {
            let (a_mm, alpha_deg) = next(i);
            JointEntry {
                a_mm,
                alpha_deg,
                theta_offset_deg: joint.theta_offset_deg,
                d_mm: joint.d_mm,
                beta_deg: 0.0,
                limits_deg: joint.limits_deg.clone(),
                identify: joint.identify.clone(),
            }
        })
        .collect();
    // Row 1's Rx(alpha_0) Tx(a_0): rotation about x, then a translation along the unchanged x.
    let (a0, alpha0) = joints
        .first()
        .map_or((0.0, 0.0), |j| (j.a_prev_mm, j.alpha_prev_deg));
    let base = if a0 == 0.0 && alpha0 == 0.0 {
        base.cloned()
    } else {
        let first = Isometry3::from_parts(
            Translation3::new(a0, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(alpha0.to_radians(), 0.0, 0.0),
        );
        Some(frame_entry(
            &(base.map_or(Isometry3::identity(), FrameEntry::isometry) * first),
        ))
    };
    // The flange's Rz(theta_F) Tz(d_F).
    let tool = match flange_isometry(flange) {
        Some(last) => Some(frame_entry(
            &(last * tool.map_or(Isometry3::identity(), FrameEntry::isometry)),
        )),
        None => tool.cloned(),
    };
    (converted, base, tool)
}

/// The flange row's `Rz(theta_F) Tz(d_F)` (`None` when it is the identity).
fn flange_isometry(flange: Option<&CraigFlangeEntry>) -> Option<Isometry3<f64>> {
    match flange {
        Some(f) if f.d_mm != 0.0 || f.theta_deg != 0.0 => Some(Isometry3::from_parts(
            Translation3::new(0.0, 0.0, f.d_mm),
            UnitQuaternion::from_euler_angles(0.0, 0.0, f.theta_deg.to_radians()),
        )),
        _ => None,
    }
}
