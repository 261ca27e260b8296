//! Import of a Universal Robots controller's factory calibration: the `[mounting]`
//! section of its `calibration.conf`, `delta_theta`, `delta_a`, `delta_d`, `delta_alpha` (six
//! values each, m and rad), added to the nominal classic DH `T_i = Rz(q_i + theta_i) Tz(d_i)
//! Tx(a_i) Rx(alpha_i)`.
//!
//! Classic DH cannot describe the nearly parallel axes 2-4 of a real UR well: the common normal
//! of two nearly parallel axes lies far away, so the calibrated `d2`, `d3` are hundreds of metres
//! (`d2 = +439 m`, `d3 = -446 m` for a real UR10e) that cancel each other. The same geometry in
//! our Hayati parameters (`beta` instead of `d` for the parallel joints, the default
//! identification set of the nominal file) is small and finite. The conversion is exact: both
//! describe the same joint axes, and the flange frames coincide (joints 4-6 are not parallel, so
//! their frames are fixed by the axes alike). It is computed by least squares: the Hayati errors
//! whose forward kinematics match the calibrated classic DH's on [`FIT_POSES`] random
//! configurations (full poses), then checked on [`CHECK_POSES`] others; an import that does not
//! reproduce them to [`POSITION_TOLERANCE_MM`] and [`ROTATION_TOLERANCE_RAD`] is refused.

use crate::JOINTS;
use crate::error::Context;
use calib_core::identify::lm::{LeastSquares, LmSettings};
use calib_core::model::JointVec;
use calib_core::{
    JointParameter, Kinematics, MdhJoint, Measurement, Parameter, ParameterErrors, ParameterMask,
    Problem, Robot,
};
use nalgebra::Dyn;
use rand::{RngExt, SeedableRng};
use std::path::Path;

/// Random configurations the Hayati parameters are fitted on.
pub const FIT_POSES: usize = 200;
/// Other random configurations the result is checked on.
pub const CHECK_POSES: usize = 1000;
/// Largest accepted position difference between the import and the calibrated classic DH, mm.
pub const POSITION_TOLERANCE_MM: f64 = 1e-6;
/// Largest accepted rotation difference, rad.
pub const ROTATION_TOLERANCE_RAD: f64 = 1e-9;

/// Largest magnitude, unit and reason of each key's values (`delta_theta`, `delta_a`,
/// `delta_d`, `delta_alpha`). Classic DH puts the common normal of nearly parallel axes far
/// away, so real `delta_d` reach hundreds of metres and `delta_a`, `delta_theta` tenths of a
/// metre and radians (the bundled UR10e: 446 m, 0.63 m, 1.69 rad); whether the deltas are
/// plausible is judged on the Hayati errors they convert to.
const BOUNDS: [(f64, &str, &str); 4] = [
    (TWO_TURNS, "rad", "two turns"),
    (1e4, "m", "10 km"),
    (1e4, "m", "10 km"),
    (TWO_TURNS, "rad", "two turns"),
];

/// Two turns, rad: the bound of an angle delta (ur_calibration's test set 2 has 7.13 rad).
const TWO_TURNS: f64 = 2.0 * std::f64::consts::TAU;

/// The keys of `[mounting]`, in the order of [`BOUNDS`].
const KEYS: [&str; 4] = ["delta_theta", "delta_a", "delta_d", "delta_alpha"];

/// The six values of key `KEYS[slot]` from the text after its `=`, each finite and within its
/// bound; `at` (`file:line`) names the place in errors.
fn values_of(value: &str, slot: usize, at: &str) -> crate::Result<[f64; JOINTS]> {
    let list = value
        .trim()
        .strip_prefix('[')
        .and_then(|v| v.strip_suffix(']'))
        .ok_or_else(
            || crate::refused!(input at; "{}: {} must be a list [v1, ..., v6]", at, KEYS[slot]),
        )?;
    let values = list
        .split(',')
        .map(|v| {
            v.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    crate::refused!(input at;
                        "{}: {}: \"{}\" is not a finite number",
                        at,
                        KEYS[slot],
                        v.trim()
                    )
                })
        })
        .collect::<crate::Result<Vec<f64>>>()?;
    let bound = BOUNDS[slot];
    if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| v.abs() > bound.0) {
        return Err(crate::refused!(input at;
            "{}: {}[{}] = {v:e} {}: beyond {} (a real calibration's deltas are far smaller)",
            at,
            KEYS[slot],
            i + 1,
            bound.1,
            bound.2
        ));
    }
    values.try_into().map_err(|v: Vec<f64>| {
        crate::refused!(input at;
            "{}: {} has {} values, expected {JOINTS}",
            at,
            KEYS[slot],
            v.len()
        )
    })
}

/// The deltas of a `calibration.conf` (m, rad), joint 1 first.
#[derive(Clone, Debug, PartialEq)]
pub struct UrCalibration {
    /// `delta_theta`, rad.
    pub delta_theta: [f64; JOINTS],
    /// `delta_a`, m.
    pub delta_a: [f64; JOINTS],
    /// `delta_d`, m.
    pub delta_d: [f64; JOINTS],
    /// `delta_alpha`, rad.
    pub delta_alpha: [f64; JOINTS],
}

impl UrCalibration {
    /// Reads a `calibration.conf`.
    pub fn read(path: &Path) -> crate::Result<Self> {
        let text = crate::io::input::read_text(path, crate::io::input::Input::Document)
            .with_context(|| format!("{}: cannot read the UR calibration", path.display()))?;
        Self::parse(&text, path)
    }

    /// Parses `calibration.conf` text: the four arrays of its `[mounting]` section (other keys
    /// and sections are ignored); `path` names the source in errors.
    pub fn parse(text: &str, path: &Path) -> crate::Result<Self> {
        let mut section = String::new();
        let mut found: [Option<[f64; JOINTS]>; 4] = [None; 4];
        for (number, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            let at = || format!("{}:{}", path.display(), number + 1);
            if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
                section = name.trim().to_string();
                continue;
            }
            let Some((key, value)) = line.split_once('=') else {
                continue;
            };
            let Some(slot) = KEYS.iter().position(|k| *k == key.trim()) else {
                continue;
            };
            if section != "mounting" {
                continue;
            }
            let values = values_of(value, slot, &at())?;
            if found[slot].replace(values).is_some() {
                return Err(crate::refused!(input at(); "{}: {} is given twice", at(), KEYS[slot]));
            }
        }
        let get = |slot: usize| {
            found[slot].ok_or_else(|| {
                crate::refused!(input path.display();
                    "{}: no {} in a [mounting] section: not a UR controller's calibration.conf",
                    path.display(),
                    KEYS[slot]
                )
            })
        };
        Ok(Self {
            delta_theta: get(0)?,
            delta_a: get(1)?,
            delta_d: get(2)?,
            delta_alpha: get(3)?,
        })
    }

    /// The calibrated classic DH robot: `nominal` (classic DH: every `beta` zero) plus the
    /// deltas, in mm and rad (with its base and tool).
    pub fn classic_dh(&self, nominal: &Robot<f64, Dyn>) -> crate::Result<Robot<f64, Dyn>> {
        if nominal.joints.len() != JOINTS {
            return Err(crate::refused!(unsupported "UR calibration";
                "a UR calibration describes a {JOINTS}-joint UR robot; the nominal robot has {} joints",
                nominal.joints.len()
            ));
        }
        if let Some(j) = nominal.joints.iter().position(|j| j.beta != 0.0) {
            return Err(crate::refused!(input "the nominal robot file";
                "the nominal robot file must be in classic DH, as UR publishes it (beta = 0), but joint {} has beta {} deg",
                j + 1,
                nominal.joints[j].beta.to_degrees()
            ));
        }
        let mut robot = *nominal;
        for (i, joint) in robot.joints.iter_mut().enumerate() {
            *joint = MdhJoint {
                a: joint.a + self.delta_a[i] * 1000.0,
                alpha: joint.alpha + self.delta_alpha[i],
                theta_offset: joint.theta_offset + self.delta_theta[i],
                d: joint.d + self.delta_d[i] * 1000.0,
                beta: 0.0,
            };
        }
        Ok(robot)
    }
}

/// The import: Hayati errors on the nominal robot, and how well they reproduce the calibration.
#[derive(Clone, Debug)]
pub struct Import {
    /// The errors (mm, rad) of the nominal file's default identification set.
    pub errors: ParameterErrors<f64, Dyn>,
    /// The parameters that carry them.
    pub mask: ParameterMask<Dyn>,
    /// Largest position difference from the calibrated classic DH on the check poses, mm.
    pub max_position_mm: f64,
    /// Largest rotation difference, rad.
    pub max_rotation_rad: f64,
    /// Largest flange position difference between the calibrated and the nominal robot on the
    /// check poses, mm (what the calibration changes).
    pub max_change_mm: f64,
}

/// Converts `calibration` on the `nominal` robot into Hayati errors (module documentation).
pub fn import(nominal: &Robot<f64, Dyn>, calibration: &UrCalibration) -> crate::Result<Import> {
    let classic = calibration.classic_dh(nominal)?;
    let dh = Kinematics::nominal(&classic)?;
    let mut mask = ParameterMask::default_for(nominal);
    // With a6 = alpha6 = 0 (every UR: its tool0 is joint 6's frame) the Hayati a6 and alpha6 are
    // zero too (the flange frames coincide): not fitted, so they stay exactly zero and the
    // model keeps its UR form (`calib export --format ur-kinematics-yaml`).
    if let Some(last) = classic.joints.last()
        && last.a == 0.0
        && last.alpha == 0.0
    {
        for kind in [JointParameter::A, JointParameter::Alpha] {
            mask.set(
                Parameter::Joint {
                    joint: JOINTS as u8,
                    kind,
                },
                false,
            );
        }
    }
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(16);
    let mut configuration =
        || -> JointVec<f64> { JointVec::from_fn(JOINTS, |_| rng.random_range(-3.1..3.1)) };
    let mut measurements = Vec::with_capacity(FIT_POSES);
    for _ in 0..FIT_POSES {
        let q = configuration();
        let pose = dh.forward(&q)?;
        measurements.push(Measurement::new(
            &q,
            pose.translation.vector,
            Some(*pose.rotation.matrix()),
            1.0,
        )?);
    }
    let errors = fit(nominal, &mask, &measurements)?;
    let imported = Kinematics::new(nominal, &errors)?;
    let plain = Kinematics::nominal(nominal)?;
    let (mut max_position_mm, mut max_rotation_rad, mut max_change_mm) = (0.0f64, 0.0f64, 0.0f64);
    for _ in 0..CHECK_POSES {
        let q = configuration();
        let (a, b) = (imported.forward(&q)?, dh.forward(&q)?);
        max_position_mm = max_position_mm.max((a.translation.vector - b.translation.vector).norm());
        let turn = a.rotation.matrix().transpose() * b.rotation.matrix();
        max_rotation_rad = max_rotation_rad.max(calib_core::math::so3::log(&turn).norm());
        let n = plain.forward(&q)?;
        max_change_mm = max_change_mm.max((n.translation.vector - b.translation.vector).norm());
    }
    if !(max_position_mm <= POSITION_TOLERANCE_MM && max_rotation_rad <= ROTATION_TOLERANCE_RAD) {
        return Err(crate::refused!(unsupported "UR calibration";
            "the Hayati parameters reproduce the UR calibration only to {max_position_mm:.3e} mm and \
             {max_rotation_rad:.3e} rad (needed: {POSITION_TOLERANCE_MM:e} mm, {ROTATION_TOLERANCE_RAD:e} rad): \
             is the nominal robot file the robot's model (UR5, UR10, UR10e, ...)?"
        ));
    }
    Ok(Import {
        errors,
        mask,
        max_position_mm,
        max_rotation_rad,
        max_change_mm,
    })
}

/// Least squares of the parameters of `mask` to `measurements` from the nominal robot.
fn fit(
    nominal: &Robot<f64, Dyn>,
    mask: &ParameterMask<Dyn>,
    measurements: &[Measurement<f64, Dyn>],
) -> crate::Result<ParameterErrors<f64, Dyn>> {
    let set = crate::model::counts::solvable_set(mask)?;
    let problem = Problem::new(
        nominal,
        &ParameterErrors::zeros_for(nominal.joint_count()),
        set,
        measurements,
        calib_core::identify::objective::DEFAULT_K,
    )?;
    let set = problem.set();
    let settings = LmSettings {
        max_iterations: 200,
        ..LmSettings::default()
    };
    let fit = LeastSquares::new(&problem)
        .solve(&set.zeros(), &settings)
        .context("fitting the Hayati parameters to the UR calibration")?;
    Ok(set.unpack(&fit.x)?)
}
