//! `calib verify`: the same calibration three ways, the f32 core (as on the controller), the f64
//! core and the independent float64 reference optimiser (the `levenberg-marquardt` crate with
//! the reference kinematics), and their largest differences in parameters and validation error.
//!
//! All three fit the same parameters from the same start (zero errors on the robot with its
//! frames registered and fitted, and the parameters selected, by the calibration's own stages)
//! by least squares.

use crate::error::Context;
use crate::measurement::dataset::{Dataset, Seen};
use crate::measurement::frames::Frames;
use calib_core::Problem;
use calib_core::identify::lm::{LeastSquares, LmSettings};
use calib_core::identify::objective::Measurement;
use calib_core::model::JointVec;
use calib_core::{Kinematics, Parameter, ParameterErrors, ParameterMask, ParameterSet};
use nalgebra::{DVector, Dyn};
use serde::Serialize;

/// Tolerances of `calib verify`; past any of them it exits non-zero.
pub mod tolerance {
    /// f64 core against the reference optimiser: lengths, mm.
    pub(crate) const F64_LENGTH_MM: f64 = 1e-6;
    /// f64 core against the reference optimiser: angles, rad.
    pub(crate) const F64_ANGLE_RAD: f64 = 1e-9;
    /// f64 core against the reference optimiser: validation RMS position error, mm.
    pub(crate) const F64_VALIDATION_MM: f64 = 1e-6;
    /// f32 core against the f64 core: lengths, mm (f32 resolves about 1e-4 mm at 1 m, and the
    /// least-squares solution amplifies that by the condition number).
    pub(crate) const F32_LENGTH_MM: f64 = 0.05;
    /// f32 core against the f64 core: angles, rad.
    pub(crate) const F32_ANGLE_RAD: f64 = 5e-5;
    /// f32 core against the f64 core: validation RMS position error, mm.
    pub(crate) const F32_VALIDATION_MM: f64 = 1e-3;
}

/// The largest differences found.
#[derive(Debug, Serialize)]
pub struct Verification {
    /// Parameters fitted.
    pub parameters: usize,
    /// Calibration and validation poses.
    pub poses: (usize, usize),
    /// Validation RMS position error of the f32 core, the f64 core and the reference, mm.
    pub validation_rms_mm: [f64; 3],
    /// f64 core vs reference: largest length difference (mm) and its parameter.
    pub f64_length: (f64, String),
    /// f64 core vs reference: largest angle difference (rad) and its parameter.
    pub f64_angle: (f64, String),
    /// f32 core vs f64 core: largest length difference (mm) and its parameter.
    pub f32_length: (f64, String),
    /// f32 core vs f64 core: largest angle difference (rad) and its parameter.
    pub f32_angle: (f64, String),
    /// Scaled condition number of the calibration poses (`None`: rank-deficient).
    pub condition_number: Option<f64>,
    /// Every check passed.
    pub passed: bool,
}

impl Verification {
    /// Text for people.
    pub fn text(&self) -> String {
        use tolerance::*;
        let mark = |ok: bool| if ok { "ok" } else { "FAILED" };
        let [r32, r64, rref] = self.validation_rms_mm;
        format!(
            "verified {} parameters on {} calibration poses, validation on {} held-out poses; scaled condition number {}{}\n\
             validation RMS |dp|: f32 core {r32:.6} mm, f64 core {r64:.6} mm, reference {rref:.6} mm\n\
             {:<32} {:>12} {:>12} {:>8}  {}\n\
             {:<32} {:>12.3e} {:>12.0e} {:>8}  {}\n\
             {:<32} {:>12.3e} {:>12.0e} {:>8}  {}\n\
             {:<32} {:>12.3e} {:>12.0e} {:>8}  \n\
             {:<32} {:>12.3e} {:>12.0e} {:>8}  {}\n\
             {:<32} {:>12.3e} {:>12.0e} {:>8}  {}\n\
             {:<32} {:>12.3e} {:>12.0e} {:>8}  \n\
             {}\n",
            self.parameters,
            self.poses.0,
            self.poses.1,
            self.condition_number
                .map_or_else(|| "infinite".to_string(), |c| format!("{c:.3e}")),
            if self
                .condition_number
                .is_some_and(|c| c <= crate::analysis::identifiability::ILL_CONDITIONED)
            {
                ""
            } else {
                " (ill-conditioned: the solutions may legitimately differ; see calib check)"
            },
            "largest difference",
            "value",
            "tolerance",
            "",
            "parameter",
            "f64 core - reference, mm",
            self.f64_length.0,
            F64_LENGTH_MM,
            mark(self.f64_length.0 <= F64_LENGTH_MM),
            self.f64_length.1,
            "f64 core - reference, rad",
            self.f64_angle.0,
            F64_ANGLE_RAD,
            mark(self.f64_angle.0 <= F64_ANGLE_RAD),
            self.f64_angle.1,
            "f64 core - reference, valid. mm",
            (r64 - rref).abs(),
            F64_VALIDATION_MM,
            mark((r64 - rref).abs() <= F64_VALIDATION_MM),
            "f32 core - f64 core, mm",
            self.f32_length.0,
            F32_LENGTH_MM,
            mark(self.f32_length.0 <= F32_LENGTH_MM),
            self.f32_length.1,
            "f32 core - f64 core, rad",
            self.f32_angle.0,
            F32_ANGLE_RAD,
            mark(self.f32_angle.0 <= F32_ANGLE_RAD),
            self.f32_angle.1,
            "f32 core - f64 core, valid. mm",
            (r32 - r64).abs(),
            F32_VALIDATION_MM,
            mark((r32 - r64).abs() <= F32_VALIDATION_MM),
            if self.passed {
                "all within tolerance"
            } else {
                "VERIFICATION FAILED: a difference is past its tolerance"
            }
        )
    }
}

/// Calibrates the poses of `calibration` by least squares with the f32 core, the f64 core and
/// the reference optimiser and compares the three, also on the held-out `validation` poses. The
/// robot and the parameters come from the session's own stages, as `calib calibrate --method lm
/// --keep-ill-conditioned` with `frames` (`None` choosing from the data) and the weight `k` has
/// them: the frames registered, a stored probe's undetermined parameters held, the parameters
/// the data cannot determine refused. An ill-conditioned set is kept (where the optimisers may
/// legitimately part, which the verification says) rather than thinned as `calibrate` does.
pub fn verify(
    calibration: &Dataset,
    validation: &Dataset,
    frames: Option<Frames>,
    k: f64,
) -> crate::Result<Verification> {
    let config = super::CalibrationConfig {
        method: super::Method::Lm,
        frames,
        k,
        keep_ill_conditioned: true,
        ..super::CalibrationConfig::default()
    };
    let registered = super::register_and_select(calibration, &config)?;
    // A robot file's gravity compliance is held fixed and taken off the measured poses at the
    // registered frames: all three fit the same geometry to the same poses.
    let robot = &registered.robot;
    let zero = ParameterErrors::zeros_for(robot.model.robot.joint_count());
    run(
        &calibration.seen_by_geometry(robot, &zero)?,
        &validation.seen_by_geometry(robot, &zero)?,
        &registered.selection.mask,
        k,
    )
}

fn run(
    calibration: &Seen<'_>,
    validation: &Seen<'_>,
    mask: &ParameterMask<Dyn>,
    k: f64,
) -> crate::Result<Verification> {
    let set = crate::model::counts::solvable_set(mask)?;
    let parameters = set.len();
    let condition_number =
        crate::analysis::identifiability::analyse(calibration, mask, k)?.condition_number;
    let settings = LmSettings::default();
    // f64 core.
    let problem = calibration.problem(set.clone(), k)?;
    let least_squares = LeastSquares::new(&problem);
    let x64 = least_squares
        .solve(&set.zeros(), &settings)
        .context("f64 core")?
        .x;
    let x32 = solve_f32(calibration, set.clone(), k)?;
    // Reference optimiser.
    let names: Vec<String> = set.parameters().iter().map(ToString::to_string).collect();
    let fit = crate::analysis::reference::fit(
        &calibration.robot.file,
        &names,
        &calibration.as_tracker_data(),
        k,
        &vec![0.0; parameters],
    )?;
    let xref: Vec<f64> = fit.errors.iter().map(|(_, v)| *v).collect();

    let rms = |x: &DVector<f64>| -> crate::Result<f64> {
        let kinematics = Kinematics::new(&validation.robot.model.robot, &set.unpack(x)?)?;
        let (table, _) =
            crate::measurement::statistics::table3(&kinematics, validation.measurements());
        Ok(table.position_mm.rms)
    };
    let x32_64 = x32.map(f64::from);
    let xref_v = DVector::<f64>::from_vec(xref);
    let validation_rms_mm = [rms(&x32_64)?, rms(&x64)?, rms(&xref_v)?];
    let largest = |a: &DVector<f64>, b: &DVector<f64>, angles: bool| -> (f64, String) {
        set.parameters()
            .iter()
            .zip(a.iter().zip(b.iter()))
            .filter(|(p, _)| Parameter::is_angle(**p) == angles)
            .map(|(p, (x, y))| ((x - y).abs(), p.to_string()))
            .fold((0.0, String::new()), |m, c| if c.0 > m.0 { c } else { m })
    };
    let f64_length = largest(&x64, &xref_v, false);
    let f64_angle = largest(&x64, &xref_v, true);
    let f32_length = largest(&x32_64, &x64, false);
    let f32_angle = largest(&x32_64, &x64, true);
    use tolerance::*;
    let [r32, r64, rref] = validation_rms_mm;
    let passed = f64_length.0 <= F64_LENGTH_MM
        && f64_angle.0 <= F64_ANGLE_RAD
        && (r64 - rref).abs() <= F64_VALIDATION_MM
        && f32_length.0 <= F32_LENGTH_MM
        && f32_angle.0 <= F32_ANGLE_RAD
        && (r32 - r64).abs() <= F32_VALIDATION_MM;
    Ok(Verification {
        parameters,
        poses: (
            calibration.measurements().len(),
            validation.measurements().len(),
        ),
        validation_rms_mm,
        f64_length,
        f64_angle,
        f32_length,
        f32_angle,
        condition_number,
        passed,
    })
}

/// The least-squares solution of the f32 core (the controller's), from zero errors.
fn solve_f32(
    calibration: &Seen<'_>,
    set: ParameterSet<Dyn, Dyn>,
    k: f64,
) -> crate::Result<DVector<f32>> {
    let robot32 = crate::formats::export::to_f32(&calibration.robot.model.robot);
    // The kinematic angles (with the maps), rounded to f32 as a controller holds them.
    let seen = calibration.as_tracker_data();
    let measurements32 = calibration
        .measurements()
        .iter()
        .zip(&seen.records)
        .map(|(m, r)| {
            let q =
                JointVec::<f32>::from_fn(r.q.len(), |i| r.q.get(i).copied().unwrap_or(0.0) as f32);
            Measurement::new(
                &q,
                m.position.map(|v| v as f32),
                m.rotation.map(|r| r.map(|v| v as f32)),
                m.weight as f32,
            )
            .map_err(crate::Error::from)
        })
        .collect::<crate::Result<Vec<_>>>()?;
    let problem32 = Problem::new(
        &robot32,
        &ParameterErrors::zeros_for(robot32.joint_count()),
        set,
        &measurements32,
        k as f32,
    )?;
    let settings32 = LmSettings::<f32>::default();
    let x32 = LeastSquares::new(&problem32)
        .solve(&problem32.set().zeros(), &settings32)
        .context("f32 core")?
        .x;
    Ok(x32)
}
