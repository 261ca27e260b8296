//! Tracker positions and touches in one calibration (issue 54, item 5): a handful of positions
//! of the ball measured by a laser tracker fix what touches cannot (where the robot stands, and
//! the scale), many touches of the same ball in sockets the rest. One fit of the [`Mixed`] kind
//! over the joints' parameters, the ball's offset and the base frame (the tracker's
//! registration, started by a rigid registration of the nominal ball positions onto the
//! measured ones).
//!
//! The tracker measures the ball touched in the sockets (a tracker's reflector is a ball: the
//! same sphere in a nest on the flange and in the sockets). Weights: a tracker coordinate weighs
//! 1, a touch's coordinate `(tracker sd / touch sd)^2` and the known distance `(tracker sd /
//! distance sd)^2`, the touch sd estimated from a fit of the touches alone, the tracker's given
//! (its instrument's figure). The tracker registration is measurement setup: reported, never
//! written as the controller's base.

use super::fit::least_squares_of;
pub use super::touches::TrackerFigures;
use super::touches::{BallModel, Judged, TouchCalibrated, TouchSession, touch_scatter, touches_of};
use super::{CalibrationConfig, select_parameters_of};
use crate::analysis::kind::Mixed;
use crate::io::sockets::Placement;
use calib_core::identify::objective::Measurement;
use calib_core::model::JointVec;
use calib_core::model::parameters::FrameParameter;
use calib_core::{FramePose, Kinematics, Parameter};
use nalgebra::{Dyn, Vector3};

pub use crate::io::sockets::TrackerPoint;

/// One calibration from tracker positions and touches of the same ball.
#[derive(Clone, Debug)]
pub struct MixedSession {
    /// The touches: robot, ball, placements, which are fitted, the known distance, settings.
    pub touches: TouchSession,
    /// The tracker's positions of the ball (at least three, not on a line).
    pub tracker: Vec<TrackerPoint>,
    /// The tracker's standard uncertainty per coordinate, mm (> 0).
    pub tracker_sd_mm: f64,
}

/// A calibration from tracker positions and touches: the calibration as one from touches reads
/// (the identified file, the fit, the ball, the selection, the placements' figures), and what
/// the tracker adds.
#[derive(Clone, Debug)]
pub struct MixedCalibrated {
    /// The calibration: its fit in a tracker coordinate's units (`sigma_mm` compares with the
    /// tracker's sd), `gauge_weight` against a touch's coordinate, `touch_sd_mm` from a fit of
    /// the touches alone.
    pub calibrated: TouchCalibrated,
    /// What the tracker positions add.
    pub tracker: TrackerFigures,
}

impl MixedSession {
    /// Calibrates: the touches of the fitted placements and every tracker position in one fit;
    /// every placement judged as a calibration from touches judges it.
    pub fn run(&self) -> crate::Result<MixedCalibrated> {
        let session = &self.touches;
        session.check()?;
        if session.compliance {
            return Err(crate::refused!(unsupported "--compliance with --tracker";
                "--compliance with tracker positions: the joints' torsion is fitted from touches alone; leave out --tracker or --compliance"));
        }
        let BallModel {
            mut robot,
            mut mask,
            flange,
        } = session.ball_model()?;
        let positions = self.positions(&robot)?;
        robot.base = registration(&robot, &positions)?;
        for axis in [FrameParameter::Tx, FrameParameter::Ty, FrameParameter::Tz] {
            mask.set(Parameter::Tool(axis), true);
        }
        for axis in FrameParameter::ALL {
            mask.set(Parameter::Base(axis), true);
        }
        let config = CalibrationConfig {
            auto_mask: true,
            ..session.config.clone()
        };
        let (fitted, held): (Vec<&Placement>, Vec<&Placement>) = (session.placements.iter())
            .partition(|p| session.train.is_empty() || session.train.contains(&p.name));
        let mut touch_mask = mask;
        for axis in FrameParameter::ALL {
            touch_mask.set(Parameter::Base(axis), false);
        }
        let touch_sd_mm = touch_scatter(&robot, (&fitted, &session.datums), &touch_mask, &config)?;
        let touch_weight = (self.tracker_sd_mm / touch_sd_mm).powi(2);
        let gauge = (session.gauge.as_ref()).map(|g| (g, (self.tracker_sd_mm / g.sd_mm).powi(2)));
        let mut data = touches_of(&fitted, gauge, &session.datums)?;
        for touch in (data.touches.iter_mut())
            .chain(data.planes.iter_mut())
            .chain(data.known_contacts.iter_mut())
        {
            touch.weight = touch_weight;
        }
        let kind = Mixed {
            positions: &positions,
            touches: data.kind(&robot),
        };
        let selection = select_parameters_of(&kind, mask, &config)?;
        let fit = least_squares_of(&kind, &selection, &config)?;
        let identified = Kinematics::new(&robot, &fit.errors)?;
        // The touches' figures in their own units: the gauge weighed against a touch.
        let judged = Judged {
            robot: &robot,
            identified: &identified,
            fit: &fit,
            gauge: gauge.map(|(g, w)| (g, w / touch_weight)),
            datums: &session.datums,
            torsion: None,
        };
        let ball = flange.inverse_transform_point(&identified.tool().translation.vector.into());
        let tracker = self.figures(&identified, &positions, touch_weight);
        Ok(MixedCalibrated {
            calibrated: TouchCalibrated {
                file: session.identified_file(&fit),
                ball_mm: ball.coords.into(),
                fitted: judged.figures(&fitted, false)?,
                held_out: judged.figures(&held, true)?,
                gauge_weight: gauge.map(|(_, w)| w / touch_weight),
                touch_sd_mm: Some(touch_sd_mm),
                calibrated_at: humantime::format_rfc3339_seconds(std::time::SystemTime::now())
                    .to_string(),
                datums: session.datums.clone(),
                torsion: None,
                fit,
                selection,
            },
            tracker,
        })
    }

    /// The tracker's figures under `identified`, a touch weighing `touch_weight`: the
    /// registration and the positions' residuals.
    fn figures(
        &self,
        identified: &Kinematics<f64, Dyn>,
        positions: &[Measurement<f64, Dyn>],
        touch_weight: f64,
    ) -> TrackerFigures {
        let residuals: Vec<f64> = (positions.iter())
            .map(|m| (identified.forward_angles(&m.angles).translation.vector - m.position).norm())
            .collect();
        let registration = frame_pose(identified.base());
        TrackerFigures {
            positions: positions.len(),
            sd_mm: self.tracker_sd_mm,
            touch_weight,
            registration_xyz_mm: registration.xyz,
            registration_rpy_rad: registration.rpy,
            rms_mm: (residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len().max(1) as f64)
                .sqrt(),
            max_mm: residuals.iter().copied().fold(0.0, f64::max),
        }
    }

    /// The tracker's positions as the core's position-only measurements (weight 1). Refused:
    /// fewer than three, a reading that is not a joint vector of the robot, a position or the
    /// tracker's sd not finite.
    fn positions(
        &self,
        robot: &calib_core::Robot<f64, Dyn>,
    ) -> crate::Result<Vec<Measurement<f64, Dyn>>> {
        if !(self.tracker_sd_mm.is_finite() && self.tracker_sd_mm > 0.0) {
            return Err(crate::refused!(option "--tracker-sd";
                "--tracker-sd {} mm: give the tracker's positive standard uncertainty per coordinate", self.tracker_sd_mm));
        }
        if self.tracker.len() < 3 {
            return Err(crate::refused!(input "the tracker positions";
                "{} tracker position(s): at least three, not on a line, are needed to place the robot in the tracker's frame",
                self.tracker.len()));
        }
        (self.tracker.iter().enumerate())
            .map(|(i, p)| {
                let position = Vector3::from(p.position_mm);
                let q = JointVec::from_slice(&p.q_rad)
                    .filter(|q| q.len() == robot.joints.len())
                    .ok_or_else(|| {
                        crate::refused!(input "the tracker positions";
                            "tracker position {}: {} joint readings for a robot of {} joints", i + 1, p.q_rad.len(), robot.joints.len())
                    })?;
                Measurement::new(&q, position, None, 1.0).map_err(|e| {
                    crate::refused!(input "the tracker positions"; "tracker position {}: {e}", i + 1)
                })
            })
            .collect()
    }
}

/// The robot's base in the tracker's frame: the nominal ball positions of `robot` rigidly
/// registered onto the measured `positions` (Kabsch), composed with the robot's own base.
/// Refused: positions on a line, or the registration's RMS far above a robot's errors.
fn registration(
    robot: &calib_core::Robot<f64, Dyn>,
    positions: &[Measurement<f64, Dyn>],
) -> crate::Result<FramePose<f64>> {
    let nominal = Kinematics::nominal(robot)?;
    let predicted: Vec<Vector3<f64>> = (positions.iter())
        .map(|m| nominal.forward_angles(&m.angles).translation.vector)
        .collect();
    let measured: Vec<Vector3<f64>> = positions.iter().map(|m| m.position).collect();
    let (rotation, translation) = crate::measurement::frames::kabsch(&predicted, &measured)
        .ok_or_else(|| {
            crate::refused!(input "the tracker positions";
                "the tracker positions lie on a line (or coincide): they cannot place the robot in the tracker's frame; measure at least three positions spread over the workspace")
        })?;
    let rms = ((predicted.iter().zip(&measured))
        .map(|(p, m)| (rotation * p + translation - m).norm_squared())
        .sum::<f64>()
        / predicted.len() as f64)
        .sqrt();
    if rms > crate::measurement::frames::MAX_REGISTRATION_RMS_MM {
        return Err(crate::refused!(input "the tracker positions";
            "the nominal robot registered onto the tracker positions leaves {rms:.1} mm RMS, far above a robot's geometric errors: check the joint order and units of the readings (rad) and that the positions are the ball's centre in mm"));
    }
    let registered = nalgebra::IsometryMatrix3::from_parts(translation.into(), rotation);
    Ok(frame_pose(&(registered * robot.base.isometry())))
}

/// `pose` as a frame: translation, mm, and roll, pitch, yaw, rad (`R = Rz(yaw) Ry(pitch)
/// Rx(roll)`, as [`FramePose::isometry`] reads them).
fn frame_pose(pose: &nalgebra::IsometryMatrix3<f64>) -> FramePose<f64> {
    let (roll, pitch, yaw) = pose.rotation.euler_angles();
    FramePose {
        xyz: pose.translation.vector.into(),
        rpy: [roll, pitch, yaw],
    }
}
