//! The identifiability of the identified parameters on a dataset, in report form: rank,
//! scaled condition number, observability, the parameters the data cannot determine and what they
//! are confounded with (the core's [`Identifiability`]), and the least determined direction of an
//! ill-conditioned pose set.

use crate::measurement::dataset::{Dataset, Seen};

use calib_core::identify::identifiability::{DEFAULT_RANK_TOLERANCE, Identifiability, Status};
use calib_core::identify::lm::LeastSquares;
use calib_core::identify::residuals::Residuals;
use calib_core::{Kinematics, Parameter, ParameterMask};
use nalgebra::DVector;
use nalgebra::Dyn;
use serde::{Deserialize, Serialize};

/// Scaled condition number above which a pose set is reported as ill-conditioned: the weakest
/// parameter combination is then determined more than 1000 times worse than the best one, so
/// noise and unmodelled errors leak into it amplified.
/// A convention, not fitted to data (docs/RESULTS.md, "Thresholds set from data").
pub const ILL_CONDITIONED: f64 = 1000.0;

/// Serialises `(parameter, value)` pairs as `[name, value]`.
fn named_pairs<S: serde::Serializer>(pairs: &[(Parameter, f64)], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(pairs.iter().map(|(p, v)| (p.to_string(), *v)))
}

/// Serialises a parameter as its name.
pub(crate) fn named<S: serde::Serializer>(parameter: &Parameter, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(parameter)
}

/// A parameter read back from its name (a report read again).
fn by_name(name: &str) -> Result<Parameter, String> {
    Parameter::from_name(name, calib_core::model::joint_count::MAX_JOINTS).ok_or_else(|| {
        format!("`{name}` is not a parameter's name (such as da2, dtheta3, base_tx)")
    })
}

/// Reads a parameter written by [`named`].
pub(crate) fn from_name<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Parameter, D::Error> {
    let name = String::deserialize(d)?;
    by_name(&name).map_err(serde::de::Error::custom)
}

/// Reads pairs written by [`named_pairs`].
fn from_named_pairs<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<Vec<(Parameter, f64)>, D::Error> {
    let pairs = Vec::<(String, f64)>::deserialize(d)?;
    (pairs.into_iter())
        .map(|(name, v)| by_name(&name).map(|p| (p, v)))
        .collect::<Result<_, _>>()
        .map_err(serde::de::Error::custom)
}

/// A reflector closer than this to the last joint's axis (mm) is "on the last axis": the last
/// joint turns it on a circle too small to tell the previous joint's parameters apart (see
/// [`default_mask`]). Reflectors in a nest on the flange's centre sit a few millimetres
/// off the axis (the Barrett WAM data: 3.0 mm); a reflector meant to sense the last joint is
/// mounted tens of millimetres off it.
/// One of the thresholds set from data (docs/RESULTS.md, "Thresholds set from data").
pub(crate) const REFLECTOR_ON_AXIS_MM: f64 = 10.0;

/// A reflector on (or near) the last joint's axis, and what it leaves undetermined.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct ReflectorOnAxis {
    /// Distance of the reflector from the last joint's axis, mm (of the model with its frames
    /// fitted).
    pub distance_mm: f64,
    /// The parameters not identified, each with the parameters it acts like when the reflector
    /// is on the axis (as in [`Undetermined`]).
    pub not_identified: Vec<Undetermined>,
}

impl ReflectorOnAxis {
    /// The parameters left out, each with what it acts like: `dtheta5 (acts like da5)`, or
    /// `dd6 (does not move it)`.
    pub fn left_out(&self) -> Vec<String> {
        (self.not_identified.iter())
            .map(|u| {
                let with: Vec<String> = u.with.iter().map(|(p, _)| p.to_string()).collect();
                if with.is_empty() {
                    format!("{} (does not move it)", u.parameter)
                } else {
                    format!("{} (acts like {})", u.parameter, with.join(", "))
                }
            })
            .collect()
    }

    /// One line for people.
    pub fn text(&self) -> String {
        let names = self.left_out();
        format!(
            "reflector {:.1} mm from the last joint's axis (below {REFLECTOR_ON_AXIS_MM} mm): the last joint barely moves it, so position data cannot tell apart what moves it alike; not identified (kept nominal): {}\n",
            self.distance_mm,
            names.join(", ")
        )
    }
}

/// The default identification set on `dataset`: `mask` less what a reflector on the last joint's
/// axis leaves undetermined, and that finding. With position-only data and the reflector within
/// [`REFLECTOR_ON_AXIS_MM`] of that axis, the parameters that the analysis at the model with the
/// reflector moved onto the axis finds redundant are left out (on the Barrett WAM `dalpha6` and
/// `dtheta6`, which then act like `dd6` and `da6`). The one rule `calibrate`, `check` and
/// `verify` share; the analysis itself is private, so no caller can find it and not apply it.
pub(crate) fn default_mask(
    dataset: &Seen<'_>,
    mut mask: ParameterMask<Dyn>,
    k: f64,
) -> crate::Result<(ParameterMask<Dyn>, Option<ReflectorOnAxis>)> {
    let reflector = reflector_on_last_axis(dataset, &mask, k)?;
    for u in reflector.iter().flat_map(|r| &r.not_identified) {
        mask.set(u.parameter, false);
    }
    Ok((mask, reflector))
}

/// Position-only data of a reflector on (or within [`REFLECTOR_ON_AXIS_MM`] of) the last joint's
/// axis: the last joint does not move it, so parameters of the joints before it that move it
/// alike cannot be told apart (on a Barrett WAM or any arm whose second-last joint has a 90 deg
/// twist and no offset, the twist `dalpha6` moves it along the axis like `dd6`, the joint zero
/// `dtheta6` across it like `da6`; only their combinations are determined, and noise decides the
/// split). Which: the parameters of `mask` that the analysis at the model with the reflector
/// moved onto the axis finds redundant: the core's pivoting keeps the parameter of each group
/// the poses determine best, as `--auto-mask` does (on the WAM's grid `da6` and `dd6`, the
/// twist and zero of joint 6 left out; a subset of the poses may keep the twist instead).
/// `None`: 6-DoF data (orientations tell them apart), no such parameter, or the reflector
/// farther from the axis.
pub(crate) fn reflector_on_last_axis(
    dataset: &Seen<'_>,
    mask: &ParameterMask<Dyn>,
    k: f64,
) -> crate::Result<Option<ReflectorOnAxis>> {
    if dataset.measurements().iter().any(|m| m.rotation.is_some()) {
        return Ok(None);
    }
    let robot = &dataset.robot.model.robot;
    let with_tool = Kinematics::nominal(robot)?;
    let mut flange = *robot;
    flange.tool = calib_core::FramePose::identity();
    let flange = Kinematics::nominal(&flange)?;
    // The reflector at three turns of the last joint (within any limits of +-120 deg or more):
    // the centre of their circle is on the axis, its radius the distance from the axis.
    let turns = [-2.0, 0.0, 2.0].map(|third: f64| third * std::f64::consts::FRAC_PI_3);
    let mut q = calib_core::model::JointVec::<f64>::from_fn(robot.joints.len(), |_| 0.0);
    let mut points = Vec::with_capacity(3);
    for turn in turns {
        if let Some(last) = q.last_mut() {
            *last = turn;
        }
        points.push(with_tool.forward(&q)?.translation.vector);
    }
    let centre = points.iter().sum::<nalgebra::Vector3<f64>>() / 3.0;
    let distance_mm = points.first().map_or(0.0, |p| (p - centre).norm());
    if distance_mm >= REFLECTOR_ON_AXIS_MM {
        return Ok(None);
    }
    if let Some(last) = q.last_mut() {
        *last = 0.0;
    }
    let on_axis = flange.forward(&q)?.inverse_transform_point(&centre.into());
    let mut projected_robot = dataset.robot.clone();
    projected_robot.model.robot.tool.xyz = [on_axis.x, on_axis.y, on_axis.z];
    let analysis = analyse(&dataset.for_robot(&projected_robot), mask, k)?;
    if analysis.undetermined.is_empty() {
        return Ok(None);
    }
    Ok(Some(ReflectorOnAxis {
        distance_mm,
        not_identified: analysis.undetermined,
    }))
}

/// A parameter a kind of measurement cannot determine whatever the spread of the data, and why
/// (`analysis::kind`).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct FreeParameter {
    /// The parameter (its name in JSON).
    #[serde(
        rename = "name",
        serialize_with = "named",
        deserialize_with = "from_name"
    )]
    pub parameter: Parameter,
    /// Why these measurements leave it free.
    pub why: String,
}

/// A parameter the data do not determine.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Undetermined {
    /// The parameter (its name in JSON).
    #[serde(
        rename = "name",
        serialize_with = "named",
        deserialize_with = "from_name"
    )]
    pub parameter: Parameter,
    /// `not identifiable` (changes no residual) or `redundant`.
    pub status: String,
    /// For a redundant one: the determined parameters it is confounded with, and the coefficient
    /// in scaled units (its column equals the sum of coefficient times their columns).
    #[serde(serialize_with = "named_pairs", deserialize_with = "from_named_pairs")]
    pub with: Vec<(Parameter, f64)>,
}

/// The identifiability analysis in report form.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct IdentifiabilityReport {
    /// Number of identified parameters analysed.
    pub parameters: usize,
    /// Numerical rank of the scaled Jacobian.
    pub rank: usize,
    /// Condition number of the scaled Jacobian (null when rank-deficient).
    pub condition_number: Option<f64>,
    /// Observability index O1 (Borm and Menq) of the pose set, scaled Jacobian.
    pub observability_index: f64,
    /// Singular values of the scaled Jacobian, largest first.
    pub singular_values: Vec<f64>,
    /// Parameters the data cannot determine, in pivot order.
    pub undetermined: Vec<Undetermined>,
    /// The least determined direction: the right singular vector of the smallest singular value
    /// of the scaled Jacobian, as (parameter, component) for components of magnitude >= 0.2,
    /// largest first. These are the parameters an ill-conditioned pose set leaves uncertain.
    #[serde(serialize_with = "named_pairs", deserialize_with = "from_named_pairs")]
    pub weakest_direction: Vec<(Parameter, f64)>,
    /// `true` when the condition number exceeds [`ILL_CONDITIONED`] (or the rank is deficient).
    pub ill_conditioned: bool,
    /// With `--auto-mask`: the condition number after dropping parameters.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub condition_number_after_drop: Option<f64>,
    /// The analysed parameter names, in order.
    #[serde(skip)]
    pub names: Vec<Parameter>,
    /// A reflector on the last joint's axis and the parameters it leaves out of the
    /// identification (before this analysis).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reflector_on_last_axis: Option<ReflectorOnAxis>,
    /// The parameters the kind of measurement leaves free whatever the data's spread (touches:
    /// joint 1's turn and lift, the last joint's, the base), left out before this analysis.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub left_free: Vec<FreeParameter>,
}

impl IdentifiabilityReport {
    /// The parameters to drop so that the rest are determined.
    pub(crate) fn to_drop(&self) -> Vec<Parameter> {
        self.undetermined.iter().map(|u| u.parameter).collect()
    }

    /// A sentence naming what the data cannot determine.
    pub fn problem(&self) -> String {
        self.undetermined
            .iter()
            .map(|u| {
                if u.with.is_empty() {
                    format!("{} ({})", u.parameter, u.status)
                } else {
                    let with: Vec<String> = u.with.iter().map(|(p, _)| p.to_string()).collect();
                    format!("{} (redundant with {})", u.parameter, with.join(", "))
                }
            })
            .collect::<Vec<_>>()
            .join("; ")
    }

    /// The warning for an ill-conditioned pose set: the condition number and the parameters of
    /// the weakest direction.
    pub(crate) fn ill_conditioned_text(&self) -> String {
        let weakest: Vec<String> = self
            .weakest_direction
            .iter()
            .map(|(n, v)| format!("{v:+.2} {n}"))
            .collect();
        format!(
            "WARNING: the pose set is ill-conditioned (scaled condition number {}, above {ILL_CONDITIONED}): \
             the data barely determine the combination {}; its identified values follow the noise and unmodelled \
             errors. Add poses with other joint configurations (e.g. both wrist flips, both elbows), or drop those \
             parameters (identify = [...] in the robot file)\n",
            self.condition_number
                .map_or_else(|| "infinite".to_string(), |c| format!("{c:.3e}")),
            weakest.join(" ")
        )
    }

    /// Fixed-width text for people.
    pub fn text(&self) -> String {
        let mut out = format!(
            "identifiability of {} parameters: rank {}{}\n",
            self.parameters,
            self.rank,
            match self.condition_number {
                Some(c) => format!(", scaled condition number {c:.3}"),
                None => ", rank-deficient".to_string(),
            }
        );
        out.push_str(&format!(
            "observability index O1: {:.4e}\n",
            self.observability_index
        ));
        if self.ill_conditioned && self.rank == self.parameters {
            out.push_str(&self.ill_conditioned_text());
        }
        let values: Vec<String> = self
            .singular_values
            .iter()
            .map(|s| format!("{s:.3e}"))
            .collect();
        out.push_str(&format!("scaled singular values: {}\n", values.join(" ")));
        if let Some(reflector) = &self.reflector_on_last_axis {
            out.push_str(&reflector.text());
        }
        if self.undetermined.is_empty() {
            out.push_str("every parameter is determined by the data\n");
        }
        for u in &self.undetermined {
            if u.with.is_empty() {
                out.push_str(&format!(
                    "  {:<10} {}: it changes no residual\n",
                    u.parameter.to_string(),
                    u.status
                ));
            } else {
                let with: Vec<String> =
                    u.with.iter().map(|(n, c)| format!("{c:+.4} {n}")).collect();
                out.push_str(&format!(
                    "  {:<10} {}: acts like {} (scaled units); only their combination is determined\n",
                    u.parameter.to_string(),
                    u.status,
                    with.join(" ")
                ));
            }
        }
        out
    }
}

/// The identifiability of the robot's identified parameters on `dataset`, with the frames
/// identified as a calibration would (`frames`: `None` chooses from the data), at the nominal model.
pub fn check(
    dataset: &Dataset,
    frames: Option<crate::measurement::frames::Frames>,
    k: f64,
) -> crate::Result<IdentifiabilityReport> {
    let frames = crate::measurement::frames::Frames::chosen(frames, &dataset.data);
    let (robot, _, mask) = crate::measurement::frames::prepare(frames, &dataset.as_given()?, k)?;
    let seen = dataset.seen_by(&robot)?;
    let (mask, reflector) = default_mask(&seen, mask, k)?;
    let mut report = analyse(&seen, &mask, k)?;
    report.reflector_on_last_axis = reflector;
    Ok(report)
}

/// The identifiability of the parameters selected by `mask` at the nominal model.
pub(crate) fn analyse(
    dataset: &Seen<'_>,
    mask: &ParameterMask<Dyn>,
    k: f64,
) -> crate::Result<IdentifiabilityReport> {
    let set = crate::model::counts::analysable_set(mask)?;
    enough_equations(
        set.len(),
        (dataset.measurements().len(), "poses", dataset.rows()),
    )?;
    let names = set.parameters().to_vec();
    let problem = dataset.problem(set, k)?;
    analyse_residuals(&problem, names, dataset.measurements().len())
}

/// Refuses fewer equations than the `count` parameters: `measurements` `noun` (poses,
/// touches) giving `equations` residual rows.
pub(crate) fn enough_equations(
    count: usize,
    (measurements, noun, equations): (usize, &str, usize),
) -> crate::Result<()> {
    if equations < count {
        return Err(crate::refused!(too_few equations, count;
            "{measurements} {noun} give {equations} equations, fewer than the {count} identified parameters"
        ));
    }
    Ok(())
}

/// The identifiability of the parameters `names` of `residuals` (of any kind of measurement,
/// `measurements` of them) at zero errors: the core's analysis of their Jacobian.
pub fn analyse_residuals<R: Residuals<Real = f64, Dim = Dyn>>(
    residuals: &R,
    names: Vec<Parameter>,
    measurements: usize,
) -> crate::Result<IdentifiabilityReport> {
    let count = names.len();
    let least_squares = LeastSquares::new(residuals);
    let r = least_squares.jacobian_factor(&DVector::zeros(count))?;
    let id = Identifiability::from_factor(&r, measurements, DEFAULT_RANK_TOLERANCE);
    let mut undetermined = Vec::new();
    for index in id.pivots.iter().skip(id.rank) {
        let (Some(parameter), Some(status)) = (names.get(*index), id.status.get(*index)) else {
            continue;
        };
        let with = id
            .combination(*index, 1e-6)
            .map(|c| {
                c.iter()
                    .zip(&names)
                    .filter(|(v, _)| **v != 0.0)
                    .map(|(v, p)| (*p, *v))
                    .collect()
            })
            .unwrap_or_default();
        undetermined.push(Undetermined {
            parameter: *parameter,
            status: match status {
                Status::NotIdentifiable => "not identifiable".to_string(),
                _ => "redundant".to_string(),
            },
            with: if status == &Status::NotIdentifiable {
                Vec::new()
            } else {
                with
            },
        });
    }
    let weakest_direction = weakest_direction(&id.weakest_direction, &names);
    let ill_conditioned =
        !(id.condition_number.is_finite() && id.condition_number <= ILL_CONDITIONED);
    Ok(IdentifiabilityReport {
        weakest_direction,
        ill_conditioned,
        condition_number_after_drop: None,
        parameters: count,
        rank: id.rank,
        condition_number: id
            .condition_number
            .is_finite()
            .then_some(id.condition_number),
        observability_index: id.observability,
        singular_values: id.singular_values.iter().copied().collect(),
        undetermined,
        names,
        reflector_on_last_axis: None,
        left_free: Vec::new(),
    })
}

/// The components of the core's least determined direction of magnitude >= 0.2, largest first.
fn weakest_direction(direction: &DVector<f64>, names: &[Parameter]) -> Vec<(Parameter, f64)> {
    let mut out: Vec<(Parameter, f64)> = direction
        .iter()
        .zip(names)
        .filter(|(v, _)| v.abs() >= 0.2)
        .map(|(v, p)| (*p, *v))
        .collect();
    out.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    out
}
