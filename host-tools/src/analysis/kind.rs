//! The kinds of measurement a calibration is generic over. A kind states four things, and the
//! stages they serve ([`analyse_kind`], [`crate::calibration::select_parameters_of`],
//! [`crate::calibration::fit::least_squares_of`], the held-out figures) ask nothing else of it:
//!
//! - its residuals and their Jacobian, as the core's least squares takes them
//!   ([`calib_core::identify::residuals::Residuals`]);
//! - what it leaves free whatever the spread of the data ([`MeasurementKind::left_free`]): a
//!   ball touched in sockets does not see the arm turned about or lifted along joint 1's axis
//!   (the sockets would move along), nor anything after the last axis the ball's offset does not
//!   already hold; position-only poses of a reflector on the last axis cannot tell some of that
//!   axis' neighbours apart. What the data's spread leaves undetermined the identifiability
//!   analysis finds on the kind's Jacobian, the same for every kind;
//! - the statistic held-out measurements of the kind are judged by
//!   ([`MeasurementKind::statistic`]): Table 3 for poses; consistency and distortion for common
//!   points, never called absolute accuracy.
//!
//! A new kind (points on a plane, say) is an implementation of the trait here, beside its
//! residuals in the core; the selection and the fit do not change.
//!
//! Three kinds today: measured poses in a tracker's frame ([`Poses`]), a ball touched in
//! sockets ([`Touches`]: common points and known distances between them), and both in one fit
//! ([`Mixed`]: a tracker's positions of the same ball with its touches).

use crate::analysis::identifiability::{FreeParameter, IdentifiabilityReport, ReflectorOnAxis};
use crate::measurement::dataset::Seen;
use calib_core::identify::common_point::{CommonPoints, KnownDistance, Touch};
use calib_core::identify::known_plane::{KnownPlane, KnownPlaneContacts};
use calib_core::identify::residuals::{Residuals, Stacked};
use calib_core::model::parameters::{FrameParameter, JointParameter};
use calib_core::{Kinematics, Parameter, ParameterErrors, ParameterMask, ParameterSet, Robot};
use nalgebra::Dyn;

/// What a kind of measurement leaves free of a parameter mask.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LeftFree {
    /// The parameters, with why.
    pub parameters: Vec<FreeParameter>,
    /// Position-only poses of a reflector on the last joint's axis: that finding and the
    /// parameters it leaves out (poses only; not repeated in `parameters`).
    pub reflector_on_last_axis: Option<ReflectorOnAxis>,
}

impl LeftFree {
    /// Every parameter left free.
    pub fn all(&self) -> impl Iterator<Item = Parameter> + '_ {
        let reflector = self.reflector_on_last_axis.iter();
        (self.parameters.iter().map(|p| p.parameter))
            .chain(reflector.flat_map(|r| r.not_identified.iter().map(|u| u.parameter)))
    }
}

/// A kind of measurement: its residuals, what it leaves free, its held-out statistic.
pub trait MeasurementKind {
    /// The core's residuals of these measurements.
    type Residuals<'a>: Residuals<Real = f64, Dim = Dyn>
    where
        Self: 'a;
    /// What held-out measurements of this kind are judged by.
    type Statistic;

    /// The residuals of the parameters of `set` of the kind's model, the others at zero error.
    fn residuals(&self, set: ParameterSet<Dyn, Dyn>) -> crate::Result<Self::Residuals<'_>>;

    /// The number of residual rows (equations), before any parameter is fitted.
    fn equations(&self) -> usize;

    /// The number of measurements (poses, touches, distances).
    fn count(&self) -> usize;

    /// What the measurements are called in messages ("poses", "touches").
    fn noun(&self) -> &'static str;

    /// The parameters of `mask` these measurements leave free whatever their spread (`k`: the
    /// orientation weight of the analysis, mm^2/rad^2).
    fn left_free(&self, mask: &ParameterMask<Dyn>, k: f64) -> crate::Result<LeftFree>;

    /// The statistic of the geometry `model` on these measurements.
    fn statistic(&self, model: &Kinematics<f64, Dyn>) -> crate::Result<Self::Statistic>;
}

/// Measured poses (6-DoF or position) in the frame the robot's model sees them in, with the
/// orientation weight `k`, mm^2/rad^2 (eq. 7).
#[derive(Clone)]
pub struct Poses<'s, 'a> {
    /// The poses as the model sees them.
    pub seen: &'s Seen<'a>,
    /// The orientation weight, mm^2/rad^2.
    pub k: f64,
}

impl<'a> MeasurementKind for Poses<'_, 'a> {
    type Residuals<'r>
        = calib_core::Problem<'r, f64, Dyn, Dyn>
    where
        Self: 'r;
    type Statistic = crate::measurement::statistics::Table3;

    fn residuals(&self, set: ParameterSet<Dyn, Dyn>) -> crate::Result<Self::Residuals<'_>> {
        self.seen.problem(set, self.k)
    }

    fn equations(&self) -> usize {
        self.seen.rows()
    }

    fn count(&self) -> usize {
        self.seen.measurements().len()
    }

    fn noun(&self) -> &'static str {
        "poses"
    }

    fn left_free(&self, mask: &ParameterMask<Dyn>, k: f64) -> crate::Result<LeftFree> {
        Ok(LeftFree {
            parameters: Vec::new(),
            reflector_on_last_axis: crate::analysis::identifiability::reflector_on_last_axis(
                self.seen, mask, k,
            )?,
        })
    }

    fn statistic(&self, model: &Kinematics<f64, Dyn>) -> crate::Result<Self::Statistic> {
        Ok(crate::measurement::statistics::table3(model, self.seen.measurements()).0)
    }
}

/// A ball on the flange touched in sockets (common points) from several configurations, known
/// distances between the sockets, and contacts of the ball with planes: joint readings only, no
/// instrument. The sockets' centres and the planes are not parameters (the core eliminates
/// them); the ball's offset is the model's tool.
#[derive(Clone, Copy, Debug)]
pub struct Touches<'a> {
    /// The nominal robot, the ball's nominal offset from the flange as its tool.
    pub robot: &'a Robot<f64, Dyn>,
    /// The touches: configuration, socket, weight.
    pub touches: &'a [Touch<f64, Dyn>],
    /// Known distances between sockets, mm.
    pub distances: &'a [KnownDistance<f64>],
    /// Contacts with planes: configuration, plane (its `point`), weight.
    pub planes: &'a [Touch<f64, Dyn>],
    /// Contacts with known planes: configuration, plane (its `point`, an index of
    /// `known_planes`), weight.
    pub known_contacts: &'a [Touch<f64, Dyn>],
    /// The known planes, in the robot's base frame.
    pub known_planes: &'a [KnownPlane<f64>],
}

/// Why touches leave joint 1's turn and lift free.
const ABOUT_JOINT_1: &str = "turns or lifts the whole arm about joint 1's axis, and the sockets, unknown, move along: touches cannot see it";
/// Why touches leave the last joint's parameters free.
const AFTER_LAST_AXIS: &str = "lies after the last joint's axis, where the ball's offset (the tool's position) already holds every effect on a point";
/// Why touches leave the tool's orientation free.
const BALL_HAS_NO_ORIENTATION: &str = "a ball is a point: its orientation changes no touch";

impl<'a> MeasurementKind for Touches<'a> {
    type Residuals<'r>
        = Stacked<CommonPoints<'r, f64, Dyn, Dyn>, KnownPlaneContacts<'r, f64, Dyn, Dyn>>
    where
        Self: 'r;
    type Statistic = crate::analysis::consistency::Consistency;

    fn residuals(&self, set: ParameterSet<Dyn, Dyn>) -> crate::Result<Self::Residuals<'_>> {
        let fixed = ParameterErrors::zeros_for(self.robot.joint_count());
        let points = CommonPoints::new(self.robot, &fixed, set.clone(), self.touches)
            .map_err(|e| crate::refused!(implausible format!("{e}"); "the touches' model: {e}"))?;
        let points = points
            .with_distances(self.distances)
            .map_err(|e| crate::refused!(input "the known distances"; "the known distances: {e}"))?
            .with_planes(self.planes)
            .map_err(|e| crate::refused!(implausible format!("{e}"); "the plane contacts: {e}"))?;
        let known = KnownPlaneContacts::new(
            self.robot,
            &fixed,
            set,
            self.known_contacts,
            self.known_planes,
        )
        .map_err(|e| crate::refused!(input "the known planes"; "the known planes: {e}"))?;
        Stacked::new(points, known).map_err(
            |e| crate::refused!(implausible format!("{e}"); "touches and known planes: {e}"),
        )
    }

    fn equations(&self) -> usize {
        let sockets = crate::analysis::consistency::points(self.touches).len();
        let planes: usize = (crate::analysis::consistency::points(self.planes).iter())
            .map(|plane| self.planes.iter().filter(|t| t.point == *plane).count())
            .map(|contacts| contacts.saturating_sub(3))
            .sum();
        3 * self.touches.len().saturating_sub(sockets)
            + self.distances.len()
            + planes
            + self.known_contacts.len()
    }

    fn count(&self) -> usize {
        self.touches.len() + self.planes.len() + self.known_contacts.len()
    }

    fn noun(&self) -> &'static str {
        "touches"
    }

    fn left_free(&self, mask: &ParameterMask<Dyn>, _k: f64) -> crate::Result<LeftFree> {
        let last = u8::try_from(self.robot.joints.len()).unwrap_or(u8::MAX);
        let joint = |joint: u8, kind| Parameter::Joint { joint, kind };
        let mut free = Vec::new();
        // A known plane sees where the arm stands along its normal: joint 1's turn and lift
        // are then left to the analysis of the Jacobian.
        let known = !self.known_planes.is_empty();
        if !known {
            for kind in [JointParameter::Theta, JointParameter::D] {
                free.push((joint(1, kind), ABOUT_JOINT_1));
            }
        }
        for kind in [
            JointParameter::A,
            JointParameter::Alpha,
            JointParameter::Theta,
            JointParameter::D,
            JointParameter::Beta,
        ] {
            free.push((joint(last, kind), AFTER_LAST_AXIS));
        }
        for axis in [FrameParameter::Rx, FrameParameter::Ry, FrameParameter::Rz] {
            free.push((Parameter::Tool(axis), BALL_HAS_NO_ORIENTATION));
        }
        let base = [
            FrameParameter::Tx,
            FrameParameter::Ty,
            FrameParameter::Tz,
            FrameParameter::Rx,
            FrameParameter::Ry,
            FrameParameter::Rz,
        ];
        const BASE: &str =
            "places the whole arm, and the sockets, unknown, move along: touches cannot see it";
        const BASE_OF_KNOWN: &str =
            "the controller's base, kept as given: the known planes are given in its frame";
        for axis in base {
            free.push((
                Parameter::Base(axis),
                if known { BASE_OF_KNOWN } else { BASE },
            ));
        }
        let mut free: Vec<(Parameter, &'static str)> = free
            .into_iter()
            .filter(|(p, _)| mask.contains(*p))
            .collect();
        if self.distances.is_empty()
            && !known
            && let Some(length) = scale_holder(self.robot, mask, &free)
        {
            free.push((length, SCALE));
        }
        Ok(LeftFree {
            parameters: (free.into_iter())
                .map(|(parameter, why)| FreeParameter {
                    parameter,
                    why: why.to_string(),
                })
                .collect(),
            reflector_on_last_axis: None,
        })
    }

    fn statistic(&self, model: &Kinematics<f64, Dyn>) -> crate::Result<Self::Statistic> {
        let mut statistic =
            crate::analysis::consistency::consistency(model, self.touches, self.distances);
        statistic.planes = crate::analysis::consistency::flatness(model, self.planes);
        statistic.known_planes = crate::analysis::consistency::off_known_planes(
            model,
            self.known_contacts,
            self.known_planes,
        );
        Ok(statistic)
    }
}

/// A tracker's positions of the ball on the flange and touches of the same ball in sockets, in
/// one fit over the joints' parameters, the ball's offset and the base frame (the tracker's
/// registration): a few tracker points fix where the robot stands and the scale, many touches
/// the rest. Each tracker coordinate weighs 1; the touches and distances carry their weights
/// against it (`(tracker sd / touch sd)^2`).
#[derive(Clone, Copy, Debug)]
pub struct Mixed<'a> {
    /// The tracker's positions of the ball, position-only (the robot's base frame registered in
    /// the tracker's: `touches.robot`'s base).
    pub positions: &'a [calib_core::identify::objective::Measurement<f64, Dyn>],
    /// The touches, their robot the ball's (base: the tracker's registration).
    pub touches: Touches<'a>,
}

/// Why tracker positions of the ball and touches leave joint 1's turn and lift free.
const WITH_THE_BASE: &str = "turns or lifts the whole arm about joint 1's axis, as the base frame (the tracker's registration, identified) does: the base holds it";

impl<'a> MeasurementKind for Mixed<'a> {
    type Residuals<'r>
        = Stacked<
        calib_core::Problem<'r, f64, Dyn, Dyn>,
        <Touches<'a> as MeasurementKind>::Residuals<'r>,
    >
    where
        Self: 'r;
    type Statistic = crate::analysis::consistency::Consistency;

    fn residuals(&self, set: ParameterSet<Dyn, Dyn>) -> crate::Result<Self::Residuals<'_>> {
        let fixed = ParameterErrors::zeros_for(self.touches.robot.joint_count());
        let tracker =
            calib_core::Problem::new(self.touches.robot, &fixed, set.clone(), self.positions, 0.0)?;
        let touches = self.touches.residuals(set)?;
        calib_core::identify::residuals::Stacked::new(tracker, touches).map_err(
            |e| crate::refused!(implausible format!("{e}"); "tracker positions and touches: {e}"),
        )
    }

    fn equations(&self) -> usize {
        3 * self.positions.len() + self.touches.equations()
    }

    fn count(&self) -> usize {
        self.positions.len() + self.touches.count()
    }

    fn noun(&self) -> &'static str {
        "tracker positions and touches"
    }

    fn left_free(&self, mask: &ParameterMask<Dyn>, k: f64) -> crate::Result<LeftFree> {
        let touches = self.touches.left_free(mask, k)?;
        let parameters = (touches.parameters.into_iter())
            .filter(|f| !matches!(f.parameter, Parameter::Base(_)) && f.why != SCALE)
            .map(|f| match f.parameter {
                Parameter::Joint { joint: 1, .. } => FreeParameter {
                    why: WITH_THE_BASE.to_string(),
                    ..f
                },
                _ => f,
            })
            .collect();
        Ok(LeftFree {
            parameters,
            reflector_on_last_axis: None,
        })
    }

    fn statistic(&self, model: &Kinematics<f64, Dyn>) -> crate::Result<Self::Statistic> {
        self.touches.statistic(model)
    }
}

/// Why touches without a known distance leave one length free.
const SCALE: &str = "holds the scale: touches without a known distance are consistent under a uniform scaling of every length, which shrinking the arm would exploit; the longest identified length is kept at its nominal value";

/// The identified length (`a` or `d` of a joint) of `mask` not already `free` with the largest
/// nominal value: fixing it holds the scale that common points alone leave free.
fn scale_holder(
    robot: &Robot<f64, Dyn>,
    mask: &ParameterMask<Dyn>,
    free: &[(Parameter, &'static str)],
) -> Option<Parameter> {
    let mut best: Option<(f64, Parameter)> = None;
    for (i, joint) in robot.joints.iter().enumerate() {
        let number = u8::try_from(i + 1).ok()?;
        for (kind, length) in [(JointParameter::A, joint.a), (JointParameter::D, joint.d)] {
            let p = Parameter::Joint {
                joint: number,
                kind,
            };
            if mask.contains(p)
                && !free.iter().any(|(f, _)| *f == p)
                && best.is_none_or(|(b, _)| length.abs() > b)
            {
                best = Some((length.abs(), p));
            }
        }
    }
    best.map(|(_, p)| p)
}

/// The identifiability of the parameters selected by `mask` on measurements of any kind, at the
/// kind's nominal model: the core's analysis of the kind's Jacobian
/// ([`crate::analysis::identifiability::analyse_residuals`]). Refused: fewer equations than
/// parameters.
pub fn analyse_kind<K: MeasurementKind>(
    kind: &K,
    mask: &ParameterMask<Dyn>,
) -> crate::Result<IdentifiabilityReport> {
    let set = crate::model::counts::analysable_set(mask)?;
    crate::analysis::identifiability::enough_equations(
        set.len(),
        (kind.count(), kind.noun(), kind.equations()),
    )?;
    let names = set.parameters().to_vec();
    let residuals = kind.residuals(set)?;
    crate::analysis::identifiability::analyse_residuals(&residuals, names, kind.count())
}
