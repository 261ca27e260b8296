//! Calibration without an instrument (issue 54): a ball on the flange touched in sockets from
//! many arm configurations, joint readings only, with known distances between the sockets. The
//! measurements are the [`Touches`] kind; the stages are the ones every kind shares: what the kind
//! leaves free taken out and the rest checked on its Jacobian ([`super::select_parameters_of`]),
//! least squares from the nominal model with covariance and standard errors
//! ([`super::fit::least_squares_of`]), and the kind's held-out statistic (consistency and
//! distortion, [`crate::analysis::consistency`]) per placement, fitted and held out.
//!
//! Contacts of the ball with planes (`plane_<n>.csv`, unknown planes) join the same fit as the
//! core's common planes; their figure is each plane's flatness under the model.
//!
//! A known distance fixes the scale the touches alone leave free. Its weight against the touches
//! is the ratio of their uncertainties, squared: the touches' scatter is estimated from a fit
//! without the distance (the residual standard deviation per coordinate, mm), the distance's is
//! given (`sd_mm`).
//!
//! What leaves: the identified geometry as a robot file (the joints' errors with their standard
//! errors; the controller's base and tool as given, the sockets and the ball are the measurement
//! setup) and the figures, under their own names: never absolute accuracy.

use super::fit::{KindFit, least_squares_of};
use super::torsion::{Rated, TorsionModel, TorsionReport, Turned, try_torsion};
use super::{CalibrationConfig, Selection, select_parameters_of};
use crate::analysis::consistency::Consistency;
use crate::analysis::consistency_prediction::{PredictedConsistency, predict_consistency};
use crate::analysis::kind::{MeasurementKind, Touches};
use crate::io::robot_file::RobotFile;
use crate::io::sockets::Placement;
use calib_core::identify::common_point::{KnownDistance, Touch};
use calib_core::model::JointVec;
use calib_core::model::parameters::FrameParameter;
use calib_core::{Kinematics, Parameter};
use nalgebra::Dyn;
use serde::Serialize;
use std::path::PathBuf;

/// A known distance between two sockets of every placement (such as MUKCa's 50 mm between
/// `hole_0` and `hole_1`), with its standard uncertainty.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Gauge {
    /// The two sockets, numbered as their files (`hole_<n>.csv`).
    pub sockets: [u16; 2],
    /// The distance between their centres, mm.
    pub mm: f64,
    /// Its standard uncertainty, mm (> 0).
    pub sd_mm: f64,
}

/// A plane of every placement whose place in the robot's base frame is known (a datum: the
/// table the robot stands on, a surface plate measured once): its contacts (`plane_<n>.csv`)
/// are judged by their distance from it, not from their best plane.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct DatumPlane {
    /// The plane's number in every placement (`plane_<n>.csv`, the column `plane`).
    pub plane: u16,
    /// Its unit normal in the robot's base frame.
    pub normal: [f64; 3],
    /// Where the ball's centre lies on it (the surface moved out by the ball's radius): its
    /// signed distance from the base's origin along the normal, mm.
    pub offset_mm: f64,
}

/// One calibration from touches: the robot, the ball, the placements, which are fitted.
#[derive(Clone, Debug)]
pub struct TouchSession {
    /// The nominal robot file.
    pub robot: RobotFile,
    /// Where it was read from (named in errors and in the identified file).
    pub robot_path: PathBuf,
    /// The ball's centre in the robot file's tool frame (its flange when the file gives no
    /// `[tool]`), nominal, mm (identified with the geometry).
    pub ball_mm: [f64; 3],
    /// The placements of the sockets, with their touches.
    pub placements: Vec<Placement>,
    /// The placements fitted (by name); the others are held out. Empty: every placement fitted.
    pub train: Vec<String>,
    /// The known distance between sockets of every placement, if any.
    pub gauge: Option<Gauge>,
    /// Planes of the placements known in the robot's base frame (the others are unknown).
    pub datums: Vec<DatumPlane>,
    /// The settings used: `lm_iterations`, `keep_ill_conditioned` (touches of one placement
    /// determine the scale weakly by nature: keep the set, and see the condition reported).
    pub config: CalibrationConfig,
    /// Try the joints' torsion under gravity with the geometry (`calib sockets --compliance`;
    /// the robot file's `[dynamics]` masses), kept when it predicts left-out touches better
    /// ([`super::torsion`]).
    pub compliance: bool,
}

/// The figures of one placement: consistency and distortion under the nominal and the
/// identified model.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct PlacementFigures {
    /// The placement's name.
    pub placement: String,
    /// Under the nominal model.
    pub nominal: Consistency,
    /// Under the identified model.
    pub identified: Consistency,
    /// What the fit's scatter and covariance predict under the identified model, for a
    /// held-out placement (`None`: fitted, or a singular covariance).
    pub predicted: Option<PredictedConsistency>,
}

/// The robot a calibration from touches fits: the nominal model with the ball as its tool.
#[derive(Clone, Debug)]
pub struct BallModel {
    /// The nominal robot; its tool frame is the ball's centre.
    pub robot: calib_core::Robot<f64, Dyn>,
    /// The robot file's parameter mask.
    pub mask: calib_core::ParameterMask<Dyn>,
    /// The robot file's tool frame (its flange, after a Craig file's flange row, when the file
    /// gives no `[tool]`), in the base frame: the ball is given in it and the identified ball is
    /// expressed back in it.
    pub flange: nalgebra::IsometryMatrix3<f64>,
}

/// A calibration from touches: the identified file and what was found.
#[derive(Clone, Debug)]
pub struct TouchCalibrated {
    /// The identified robot file: nominal plus the joints' identified errors, with their
    /// standard errors; the controller's base and tool as given.
    pub file: RobotFile,
    /// The fit: the parameters with their standard errors, least squares, time.
    pub fit: KindFit,
    /// The ball's centre in the robot file's tool frame, identified, mm.
    pub ball_mm: [f64; 3],
    /// The parameters selected and the analysis (what touches leave free, what the data could
    /// not determine, the condition).
    pub selection: Selection,
    /// The gauge's weight against a touch's coordinate: `(touch sd / gauge sd)^2`.
    pub gauge_weight: Option<f64>,
    /// The touches' scatter per coordinate estimated without the gauge, mm.
    pub touch_sd_mm: Option<f64>,
    /// The fitted placements' figures.
    pub fitted: Vec<PlacementFigures>,
    /// The held-out placements' figures.
    pub held_out: Vec<PlacementFigures>,
    /// When the calibration finished, RFC 3339 (UTC, to the second).
    pub calibrated_at: String,
    /// The datum planes (known in the base frame); each placement's `known_planes` figures
    /// are numbered by their index here.
    pub datums: Vec<DatumPlane>,
    /// The joints' torsion under gravity, when tried (`compliance`).
    pub torsion: Option<TorsionReport>,
}

/// The joints' torsion tried in a fit: its model, its report, and the gains (urad per N m).
type TriedTorsion = (TorsionModel, TorsionReport, Vec<f64>);

/// Touches, known distances and plane contacts, as the core's common points take them.
#[derive(Clone, Debug, Default)]
pub(super) struct ImplicitData {
    pub(super) touches: Vec<Touch<f64, Dyn>>,
    pub(super) distances: Vec<KnownDistance<f64>>,
    pub(super) planes: Vec<Touch<f64, Dyn>>,
    pub(super) known_contacts: Vec<Touch<f64, Dyn>>,
    pub(super) known_planes: Vec<calib_core::identify::known_plane::KnownPlane<f64>>,
}

impl ImplicitData {
    /// These data as the touches kind of `robot` (the ball its tool).
    pub(super) fn kind<'a>(&'a self, robot: &'a calib_core::Robot<f64, Dyn>) -> Touches<'a> {
        Touches {
            robot,
            touches: &self.touches,
            distances: &self.distances,
            planes: &self.planes,
            known_contacts: &self.known_contacts,
            known_planes: &self.known_planes,
        }
    }
}

/// The readings of `socket` (a file of touches or contacts) as the core's touches of `point`.
fn touches_in(
    socket: &crate::io::sockets::Socket,
    point: u16,
    into: &mut Vec<Touch<f64, Dyn>>,
) -> crate::Result<()> {
    for reading in &socket.readings {
        let q = JointVec::from_slice(&reading.q_rad).ok_or_else(|| {
            crate::refused!(input socket.path.display();
                "{}:{}: not a joint vector", socket.path.display(), reading.line)
        })?;
        let touch = Touch::new(&q, point, 1.0).map_err(|e| {
            crate::refused!(input socket.path.display();
                "{}:{}: {e}", socket.path.display(), reading.line)
        })?;
        into.push(touch);
    }
    Ok(())
}

/// The touches of `placements` as the core's common points and planes, every placement's
/// sockets (and planes) points (planes) of their own (placement `p`'s socket `s` is point
/// `offset_p + s`), and the gauge between each placement's two sockets; a plane of `datums`
/// is known (its contacts name the datum's index), the others unknown.
pub(super) fn touches_of(
    placements: &[&Placement],
    gauge: Option<(&Gauge, f64)>,
    datums: &[DatumPlane],
) -> crate::Result<ImplicitData> {
    let mut data = ImplicitData {
        known_planes: (datums.iter())
            .map(|d| calib_core::identify::known_plane::KnownPlane {
                normal: d.normal,
                offset_mm: d.offset_mm,
            })
            .collect(),
        ..ImplicitData::default()
    };
    let (mut offset, mut plane_offset) = (0u16, 0u16);
    for placement in placements {
        for (s, socket) in placement.sockets.iter().enumerate() {
            touches_in(socket, offset.saturating_add(s as u16), &mut data.touches)?;
        }
        for (k, plane) in placement.planes.iter().enumerate() {
            match datums.iter().position(|d| usize::from(d.plane) == k) {
                Some(datum) => touches_in(plane, datum as u16, &mut data.known_contacts)?,
                None => touches_in(
                    plane,
                    plane_offset.saturating_add(k as u16),
                    &mut data.planes,
                )?,
            }
        }
        if let Some((g, weight)) = gauge {
            let count = placement.sockets.len() as u16;
            if g.sockets.iter().all(|s| *s < count) {
                data.distances.push(KnownDistance {
                    points: g.sockets.map(|s| offset.saturating_add(s)),
                    mm: g.mm,
                    weight,
                });
            }
        }
        offset = offset.saturating_add(placement.sockets.len() as u16);
        plane_offset = plane_offset.saturating_add(placement.planes.len() as u16);
    }
    Ok(data)
}

/// The touches' scatter per coordinate, mm: the residual standard deviation of a fit of the
/// touches of `placements` alone (no distance), the parameters of `mask` selected as for the
/// calibration.
pub(super) fn touch_scatter(
    robot: &calib_core::Robot<f64, Dyn>,
    (placements, datums): (&[&Placement], &[DatumPlane]),
    mask: &calib_core::ParameterMask<Dyn>,
    config: &CalibrationConfig,
) -> crate::Result<f64> {
    let data = touches_of(placements, None, datums)?;
    let kind = data.kind(robot);
    let selection = select_parameters_of(&kind, *mask, config)?;
    Ok(least_squares_of(&kind, &selection, config)?.sigma_mm)
}

/// What placements are judged by: the ball's robot, its identified geometry, the fit (for the
/// prediction) and the gauge with its weight.
pub(super) struct Judged<'a> {
    pub(super) robot: &'a calib_core::Robot<f64, Dyn>,
    pub(super) identified: &'a Kinematics<f64, Dyn>,
    pub(super) fit: &'a KindFit,
    pub(super) gauge: Option<(&'a Gauge, f64)>,
    pub(super) datums: &'a [DatumPlane],
    /// The torsions kept and their gains (urad per N m): the identified model turns the
    /// readings by them.
    pub(super) torsion: Option<(&'a TorsionModel, &'a [f64])>,
}

impl Judged<'_> {
    /// The figures of each of `placements` under the nominal and the identified model, with the
    /// prediction when `held` out.
    pub(super) fn figures(
        &self,
        placements: &[&Placement],
        held: bool,
    ) -> crate::Result<Vec<PlacementFigures>> {
        let nominal = Kinematics::nominal(self.robot)?;
        (placements.iter())
            .map(|p| {
                let data = touches_of(&[p], self.gauge, self.datums)?;
                let kind = data.kind(self.robot);
                let turned = match self.torsion {
                    Some((model, gains)) => {
                        Some(Rated::new(kind, model, &self.fit.errors)?.turned(gains))
                    }
                    None => None,
                };
                let identified = turned.as_ref().map_or(kind, Turned::kind);
                let fit = self.fit;
                let predicted = (fit.covariance.as_ref().filter(|_| held)).and_then(|c| {
                    let touches = identified.touches;
                    predict_consistency(self.identified, &fit.set, c, fit.sigma_mm, touches)
                });
                Ok(PlacementFigures {
                    placement: p.name.clone(),
                    nominal: kind.statistic(&nominal)?,
                    identified: identified.statistic(self.identified)?,
                    predicted,
                })
            })
            .collect()
    }
}

impl TouchSession {
    /// Calibrates: fits the placements of `train` (all without), judges every placement.
    pub fn run(&self) -> crate::Result<TouchCalibrated> {
        self.check()?;
        let BallModel {
            robot,
            mut mask,
            flange,
        } = self.ball_model()?;
        let (fitted, held): (Vec<&Placement>, Vec<&Placement>) = (self.placements.iter())
            .partition(|p| self.train.is_empty() || self.train.contains(&p.name));
        for axis in [FrameParameter::Tx, FrameParameter::Ty, FrameParameter::Tz] {
            mask.set(Parameter::Tool(axis), true);
        }
        let config = CalibrationConfig {
            auto_mask: true,
            ..self.config.clone()
        };
        // The touches' scatter, from a fit without the gauge: the gauge's weight.
        let touch_sd_mm = match &self.gauge {
            Some(_) => Some(touch_scatter(
                &robot,
                (&fitted, &self.datums),
                &mask,
                &config,
            )?),
            None => None,
        };
        let gauge = (self.gauge.as_ref())
            .zip(touch_sd_mm)
            .map(|(g, sd)| (g, (sd / g.sd_mm).powi(2)));
        let data = touches_of(&fitted, gauge, &self.datums)?;
        let kind = data.kind(&robot);
        let selection = select_parameters_of(&kind, mask, &config)?;
        let (fit, torsion) = self.fit(kind, &selection, &config)?;
        let identified = Kinematics::new(&robot, &fit.errors)?;
        let kept = (torsion.as_ref())
            .and_then(|(model, report, gains)| report.kept.then_some((model, gains.as_slice())));
        let judged = Judged {
            robot: &robot,
            identified: &identified,
            fit: &fit,
            gauge,
            datums: &self.datums,
            torsion: kept,
        };
        let ball = flange.inverse_transform_point(&identified.tool().translation.vector.into());
        let mut file = self.identified_file(&fit);
        if let Some((model, gains)) = kept {
            let joints = robot.joints.len();
            let all = model.all_gains(joints, gains);
            file.compliance = Some(crate::model::compliance::ComplianceSection::new(
                &all, joints,
            ));
        }
        Ok(TouchCalibrated {
            torsion: torsion.as_ref().map(|(_, report, _)| report.clone()),
            file,
            ball_mm: ball.coords.into(),
            fitted: judged.figures(&fitted, false)?,
            held_out: judged.figures(&held, true)?,
            fit,
            selection,
            gauge_weight: gauge.map(|(_, w)| w),
            touch_sd_mm,
            calibrated_at: humantime::format_rfc3339_seconds(std::time::SystemTime::now())
                .to_string(),
            datums: self.datums.clone(),
        })
    }

    /// The fit of the parameters of `selection` to `kind`: the geometry's alone, or with the
    /// joints' torsion when asked for (with its model, report and gains; the geometry's fit is
    /// the torsion's only when kept).
    fn fit(
        &self,
        kind: Touches<'_>,
        selection: &Selection,
        config: &CalibrationConfig,
    ) -> crate::Result<(KindFit, Option<TriedTorsion>)> {
        if !self.compliance {
            return Ok((least_squares_of(&kind, selection, config)?, None));
        }
        let joints = kind.robot.joints.len();
        let gravity = (self.robot.dynamics.as_ref())
            .ok_or_else(|| crate::refused!(option "--compliance";
                "--compliance: {} has no [dynamics] (the links' masses and centres the gravity moments come from); add it, as robots/franka-panda.toml has", self.robot_path.display()))?
            .to_gravity(joints)
            .map_err(|e| crate::refused!(input self.robot_path.display(); "{}: {e}", self.robot_path.display()))?;
        let model = TorsionModel::new(gravity, joints)?;
        let nominal = calib_core::ParameterErrors::zeros_for(kind.robot.joint_count());
        let rated = Rated::new(kind, &model, &nominal)?;
        let (report, fit) = try_torsion(&rated, &model, selection, config)?;
        let geometry = match report.kept {
            true => fit.geometry,
            false => least_squares_of(&kind, selection, config)?,
        };
        Ok((geometry, Some((model, report, fit.gains))))
    }

    /// The nominal model with the ball as its tool, the robot file's parameter mask, and the
    /// frame the ball is given in.
    pub fn ball_model(&self) -> crate::Result<BallModel> {
        let mut robot = self.robot.to_model(&self.robot_path)?;
        let flange = robot.robot.tool.isometry();
        let ball = flange * nalgebra::Point3::from(self.ball_mm);
        robot.robot.tool = calib_core::FramePose {
            xyz: ball.coords.into(),
            rpy: robot.robot.tool.rpy,
        };
        Ok(BallModel {
            robot: robot.robot,
            mask: robot.mask,
            flange,
        })
    }

    /// Leave one placement out: each placement judged by a calibration of all the others (the
    /// session's `train` ignored), in the data's order. Refused: fewer than two placements.
    pub fn leave_one_out(&self) -> crate::Result<Vec<PlacementFigures>> {
        if self.placements.len() < 2 {
            return Err(crate::refused!(option "--leave-one-out";
                "--leave-one-out: {} placement(s) in the data; leaving one out needs at least two",
                self.placements.len()));
        }
        (self.placements.iter())
            .map(|left_out| {
                let fold = TouchSession {
                    train: (self.placements.iter())
                        .filter(|p| p.name != left_out.name)
                        .map(|p| p.name.clone())
                        .collect(),
                    ..self.clone()
                };
                let mut calibrated = fold.run()?;
                calibrated.held_out.pop().ok_or_else(|| {
                    crate::refused!(input left_out.name.as_str();
                        "placement {}: no figures left out", left_out.name)
                })
            })
            .collect()
    }

    /// Refuses what cannot be calibrated: no placement, a placement to fit that is not in the
    /// data, nothing left to fit, a gauge without a positive uncertainty or length.
    pub(super) fn check(&self) -> crate::Result<()> {
        let names: Vec<&str> = self.placements.iter().map(|p| p.name.as_str()).collect();
        for name in &self.train {
            if !names.contains(&name.as_str()) {
                return Err(crate::refused!(option "--train";
                    "--train {name}: no such placement; the data have {}", names.join(", ")));
            }
        }
        if names.is_empty() {
            return Err(crate::refused!(input "the touches"; "no placements of sockets to fit"));
        }
        let sockets: usize = self.placements.iter().map(|p| p.sockets.len()).sum();
        let planes: usize = self.placements.iter().map(|p| p.planes.len()).sum();
        if sockets.max(planes) >= usize::from(u16::MAX) {
            return Err(crate::refused!(unsupported "socket count";
                "{sockets} sockets and {planes} planes over all placements: at most {} of each in one calibration", u16::MAX - 1));
        }
        if let Some(g) = &self.gauge {
            let has_both =
                |p: &Placement| g.sockets.iter().all(|s| usize::from(*s) < p.sockets.len());
            if !self.placements.iter().any(has_both) {
                return Err(crate::refused!(option "--distance-between";
                    "--distance-between {},{}: no placement has both sockets (hole_{}.csv and hole_{}.csv)",
                    g.sockets[0], g.sockets[1], g.sockets[0], g.sockets[1]));
            }
            if !(g.mm.is_finite() && g.mm > 0.0 && g.sd_mm.is_finite() && g.sd_mm > 0.0) {
                return Err(crate::refused!(option "--distance";
                    "--distance {} mm +- {} mm: give a positive length and a positive standard uncertainty",
                    g.mm, g.sd_mm));
            }
            if g.sockets[0] == g.sockets[1] {
                return Err(crate::refused!(option "--distance-between";
                    "--distance-between {0},{0}: a distance is between two different sockets", g.sockets[0]));
            }
        }
        if !self.ball_mm.iter().all(|v| v.is_finite()) {
            return Err(
                crate::refused!(option "--ball-mm"; "--ball-mm: give three finite numbers, mm"),
            );
        }
        Ok(())
    }

    /// The identified robot file: the joints' identified errors (and standard errors) on the
    /// nominal file; its base and tool are the controller's, as given (the ball is the
    /// measurement setup: in the report, not in the controller's tool).
    pub(super) fn identified_file(&self, fit: &KindFit) -> RobotFile {
        let is_joint = |p: &Parameter| matches!(p, Parameter::Joint { .. });
        let mut joints = fit.errors;
        joints.base = calib_core::FrameErrors::default();
        joints.tool = calib_core::FrameErrors::default();
        let std_errors: Vec<(Parameter, f64)> = (fit.parameters.iter())
            .filter(|p| is_joint(&p.parameter))
            .filter_map(|p| p.std_error.map(|s| (p.parameter, s)))
            .collect();
        self.robot.with_errors(
            &joints,
            fit.parameters.iter().map(|p| p.parameter).filter(is_joint),
            &std_errors,
            "least squares (touches in sockets)",
            &self.robot_path.display().to_string(),
        )
    }
}

/// What a calibration's tracker positions add to its touches: where the robot stands in the
/// tracker's frame, and how well the positions fit.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrackerFigures {
    /// The tracker positions fitted.
    pub positions: usize,
    /// The tracker's standard uncertainty per coordinate, mm (as given).
    pub sd_mm: f64,
    /// A touch coordinate's weight against a tracker coordinate: `(tracker sd / touch sd)^2`.
    pub touch_weight: f64,
    /// The robot's base frame in the tracker's frame, identified (measurement setup): the
    /// translation, mm.
    pub registration_xyz_mm: [f64; 3],
    /// Its roll, pitch and yaw, rad (`R = Rz(yaw) Ry(pitch) Rx(roll)`).
    pub registration_rpy_rad: [f64; 3],
    /// RMS of the positions' residuals (distance) under the identified model, mm.
    pub rms_mm: f64,
    /// The largest, mm.
    pub max_mm: f64,
}

/// The JSON report of a calibration from touches (`calib sockets --report`), which `calib
/// report --from` renders as a certificate ([`crate::report::touch_certificate`]).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct TouchReport {
    /// The robot file calibrated.
    pub robot: PathBuf,
    /// The placements fitted.
    pub fitted_placements: Vec<String>,
    /// The identified parameters (name -> value, unit, standard error), the ball's offset among
    /// them as `tool_tx`, `tool_ty`, `tool_tz`.
    pub parameters: super::Parameters,
    /// The ball's centre in the robot file's tool frame, identified, mm.
    pub ball_mm: [f64; 3],
    /// The known distance, its weight against a touch's coordinate and the touches' scatter
    /// it was weighed by.
    pub gauge: Option<Gauge>,
    /// `(touch sd / gauge sd)^2`.
    pub gauge_weight: Option<f64>,
    /// The touches' scatter per coordinate, fitted without the gauge, mm.
    pub touch_sd_mm: Option<f64>,
    /// What the touches leave free and what the data could not determine.
    pub identifiability: crate::analysis::identifiability::IdentifiabilityReport,
    /// Parameters dropped as undetermined by these data.
    pub dropped: Vec<String>,
    /// Least squares.
    pub least_squares: super::LeastSquaresReport,
    /// Wall-clock time of the fit, s.
    pub seconds: f64,
    /// Consistency and distortion of the fitted placements (not accuracy).
    pub fitted: Vec<PlacementFigures>,
    /// Consistency and distortion of the held-out placements (not accuracy).
    pub held_out: Vec<PlacementFigures>,
    /// Leave one placement out (`calib sockets --leave-one-out`): each placement judged by a
    /// calibration of all the others; empty when not asked for.
    pub leave_one_out: Vec<PlacementFigures>,
    /// When the calibration finished, RFC 3339 (UTC, to the second).
    #[serde(default)]
    pub calibrated_at: String,
    /// The software that wrote the report: its version and the git commit it was built from.
    #[serde(default)]
    pub software: String,
    /// The command line that ran the calibration (empty for a library call).
    #[serde(default)]
    pub command_line: Vec<String>,
    /// The input files (the robot file, every file of touches read) with their SHA-256; empty
    /// for data from memory.
    #[serde(default)]
    pub inputs: Vec<crate::io::provenance::InputFile>,
    /// With tracker positions of the ball in the fit (`calib sockets --tracker`): what they add.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracker: Option<TrackerFigures>,
    /// The datum planes (known in the base frame); each placement's `known_planes` figures
    /// are numbered by their index here.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub datums: Vec<DatumPlane>,
    /// The joints' torsion under gravity, when tried (`calib sockets --compliance`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torsion: Option<TorsionReport>,
}

impl TouchReport {
    /// The JSON report at `path` (written by `calib sockets --report`). Refused, naming the
    /// field and line, when it is not one this version reads.
    pub fn read(path: &std::path::Path) -> crate::Result<Self> {
        let text = crate::io::input::read_text(path, crate::io::input::Input::Data)?;
        Self::from_json(&text, path)
    }

    /// The report in `text`, read from `path` (named in messages).
    pub fn from_json(text: &str, path: &std::path::Path) -> crate::Result<Self> {
        serde_json::from_str(text).map_err(|e| {
            crate::refused!(input path.display();
                "{}: not a JSON report of calib sockets that this version reads ({e}); write one with calib sockets --report",
                path.display())
        })
    }
}

impl TouchCalibrated {
    /// The JSON report of this calibration of `session`'s data.
    pub fn report(&self, session: &TouchSession) -> TouchReport {
        TouchReport {
            robot: session.robot_path.clone(),
            fitted_placements: self.fitted.iter().map(|f| f.placement.clone()).collect(),
            parameters: self
                .fit
                .parameters
                .iter()
                .map(super::result::reported)
                .collect(),
            ball_mm: self.ball_mm,
            gauge: session.gauge,
            gauge_weight: self.gauge_weight,
            touch_sd_mm: self.touch_sd_mm,
            identifiability: self.selection.identifiability.clone(),
            dropped: self
                .selection
                .dropped
                .iter()
                .map(ToString::to_string)
                .collect(),
            least_squares: self.fit.least_squares.clone(),
            seconds: self.fit.seconds,
            fitted: self.fitted.clone(),
            held_out: self.held_out.clone(),
            leave_one_out: Vec::new(),
            calibrated_at: self.calibrated_at.clone(),
            software: format!(
                "calib {} (commit {})",
                env!("CARGO_PKG_VERSION"),
                env!("CALIB_COMMIT")
            ),
            command_line: Vec::new(),
            inputs: Vec::new(),
            tracker: None,
            datums: self.datums.clone(),
            torsion: self.torsion.clone(),
        }
    }
}
