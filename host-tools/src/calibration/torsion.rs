//! The joints' torsion under gravity in a calibration from touches (`calib sockets
//! --compliance`): what the geometry leaves out of a Panda's touches.
//!
//! A joint twisted by the gravity moment it carries turns everything beyond it about its own
//! axis, which is what a change of its reading does: the arm stands at the kinematic angles
//! `q_j + 1e-6 k_j tau_j(q)` (rad) when it reads `q`, `tau_j` the gravity moment about joint
//! `j`'s axis (N m, from the robot file's `[dynamics]` masses at the nominal geometry) and `k_j`
//! the gain (urad per N m), the torsion gain of [`crate::model::compliance`] (the controller's
//! `Compliance`). The torsions of joints 2 to N - 2 (the gains the controller applies) are
//! identified with the geometry in one least-squares fit (`TorsionTouches`: the touches at the
//! turned readings; the gains' columns by central differences, the geometry's the core's).
//!
//! Two guards against over-fitting one placement (a crude try with seven free gains fitted
//! `panda_3` better and predicted `panda_1` worse, some gains negative):
//!
//! - a gain is physical only when not negative: a negative one is set to zero and the rest
//!   fitted again (an active set);
//! - the torsion must earn its place on touches the fit did not see: the fitted touches are cut
//!   into [`FOLDS`] folds (every fifth touch of each socket), each fold's touches predicted by a
//!   fit of the others (their distance from their socket's centre as the others put it), with
//!   and without the torsion; it is kept only when it predicts them closer
//!   ([`TorsionReport::cross_validated_mm`]).
//!
//! The controller applies the deflection to first order at the identified geometry
//! (`Compliance::deflect`); the fit turns the joints exactly at the nominal geometry's moments.
//! Over the fitted touches the two differ by [`TorsionReport::controller_difference_mm`].

use super::fit::KindFit;
use super::{CalibrationConfig, Selection};
use crate::analysis::kind::{MeasurementKind, Touches};
use crate::model::compliance::{Gain, Gravity, gains};
use calib_core::identify::common_point::Touch;
use calib_core::identify::lm::{LeastSquares, LmSettings};
use calib_core::identify::residuals::Residuals;
use calib_core::model::parameters::ShapeError;
use calib_core::model::{JacobianColumns, JointVec};
use calib_core::{Kinematics, ParameterErrors, ParameterSet, Robot};
use nalgebra::{DVector, Dyn};
use serde::{Deserialize, Serialize};

/// Folds of the cross-validation that decides whether the torsion is kept.
pub const FOLDS: usize = 5;

/// Step of the central differences of the gains' columns, urad per N m (a turn of about
/// 5e-7 rad at 50 N m: the columns to about 1e-10 of their size).
const STEP_URAD_PER_NM: f64 = 1e-2;

/// What the torsion of the joints did in a calibration from touches.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TorsionReport {
    /// The joints whose torsion was tried (1-based).
    pub joints: Vec<usize>,
    /// Whether the torsion predicted left-out touches better and was kept (otherwise the
    /// calibration is the geometry's alone and the gains below are what the torsion would have
    /// been).
    pub kept: bool,
    /// Per joint, whether its torsion earned its place (removing it predicted the left-out
    /// touches worse) and came out positive; the others are zero.
    pub fitted: Vec<bool>,
    /// The identified gains, urad per N m (0: not fitted, or negative and set to zero).
    pub gains_urad_per_nm: Vec<f64>,
    /// Their standard errors, urad per N m (`None`: set to zero, or a singular covariance).
    pub std_errors_urad_per_nm: Vec<Option<f64>>,
    /// Mean distance of the left-out touches from their socket's centre over the
    /// [`FOLDS`] folds: `[geometry alone, with the torsions fitted]`, mm.
    pub cross_validated_mm: [f64; 2],
    /// The largest turn of a joint over the fitted touches, mrad.
    pub largest_turn_mrad: f64,
    /// The largest difference over the fitted touches between the ball where the fit puts it
    /// and where the controller's first-order deflection at the identified geometry puts it, mm.
    pub controller_difference_mm: f64,
}

/// The torsion gains of a robot's `[dynamics]`: the masses and which gains of
/// [`crate::model::compliance::gains`] are torsions.
#[derive(Clone, Debug)]
pub struct TorsionModel {
    /// The masses.
    pub gravity: Gravity,
    /// `(joint, index among the robot's gains)` of each torsion.
    pub torsions: Vec<(usize, usize)>,
}

impl TorsionModel {
    /// The torsions of a robot of `joints` joints with `gravity`'s masses. Refused: a robot
    /// without torsion gains (fewer than four joints).
    pub fn new(gravity: Gravity, joints: usize) -> crate::Result<Self> {
        let torsions: Vec<(usize, usize)> = (gains(joints).iter().enumerate())
            .filter_map(|(i, g)| match g {
                Gain::Torsion(j) => Some((*j, i)),
                _ => None,
            })
            .collect();
        if torsions.is_empty() {
            return Err(crate::refused!(unsupported "gravity compliance";
                "--compliance turns joints 2 to N - 2 under gravity, and this robot has {joints} joints"));
        }
        Ok(Self { gravity, torsions })
    }

    /// The joints (1-based).
    pub fn joints(&self) -> Vec<usize> {
        self.torsions.iter().map(|(j, _)| *j).collect()
    }

    /// Per torsion, the turn of its joint per urad/(N m) at the readings of `touch` of the
    /// geometry `robot + errors`, rad: `1e-6 tau_j`.
    fn rates(
        &self,
        geometry: (&Robot<f64, Dyn>, &ParameterErrors<f64, Dyn>),
        touch: &Touch<f64, Dyn>,
    ) -> crate::Result<Vec<f64>> {
        let q = JointVec::from_fn(touch.angles.cos.len(), |j| {
            touch.angles.sin[j].atan2(touch.angles.cos[j])
        });
        self.turns(geometry, &q)
    }

    /// Per torsion, the turn of its joint per urad/(N m) at the kinematic angles `q` (rad) of
    /// the geometry `robot + errors`, rad: `1e-6 tau_j`, `tau_j` the gravity moment about the
    /// joint's axis (N m).
    pub fn turns(
        &self,
        (robot, errors): (&Robot<f64, Dyn>, &ParameterErrors<f64, Dyn>),
        q: &JointVec<f64>,
    ) -> crate::Result<Vec<f64>> {
        let columns = crate::model::compliance::columns(&self.gravity, robot, errors, q)?;
        let (_, jacobian) = Kinematics::new(robot, errors)?.geometric_jacobian(q)?;
        Ok((self.torsions.iter())
            .map(|(joint, index)| {
                let w = columns.get(*index).map_or([0.0; 3], |c| [c[3], c[4], c[5]]);
                let z = JacobianColumns::column(&jacobian, joint - 1)
                    .fixed_rows::<3>(3)
                    .into_owned();
                w[0] * z.x + w[1] * z.y + w[2] * z.z
            })
            .collect())
    }

    /// Every gain of the robot's compliance (in the order of
    /// [`crate::model::compliance::gains`]) with the torsions `values` and no tilt.
    pub fn all_gains(&self, joints: usize, values: &[f64]) -> Vec<f64> {
        let mut all = vec![0.0; gains(joints).len()];
        for ((_, index), value) in self.torsions.iter().zip(values) {
            if let Some(slot) = all.get_mut(*index) {
                *slot = *value;
            }
        }
        all
    }
}

/// Touches with each reading's turn per unit gain of each torsion.
#[derive(Clone, Debug)]
pub struct Rated<'a> {
    /// The robot, distances and known planes (its lists are replaced by `lists`).
    kind: Touches<'a>,
    /// The touches, plane contacts and known-plane contacts as read.
    lists: [Vec<Touch<f64, Dyn>>; 3],
    /// Per entry of `lists`, the turn of each torsion's joint per urad/(N m), rad.
    rates: [Vec<Vec<f64>>; 3],
    /// Each torsion's joint, 0-based.
    joints: Vec<usize>,
}

/// Touches, plane contacts and known-plane contacts at turned readings.
#[derive(Clone, Debug)]
pub struct Turned<'a> {
    kind: Touches<'a>,
    lists: [Vec<Touch<f64, Dyn>>; 3],
}

impl Turned<'_> {
    /// The kind at the turned readings.
    pub fn kind(&self) -> Touches<'_> {
        let [touches, planes, known_contacts] = &self.lists;
        Touches {
            touches,
            planes,
            known_contacts,
            ..self.kind
        }
    }
}

impl<'a> Rated<'a> {
    /// The rates of `kind`'s readings under `model` at the geometry of `errors` on its robot.
    pub fn new(
        kind: Touches<'a>,
        model: &TorsionModel,
        errors: &ParameterErrors<f64, Dyn>,
    ) -> crate::Result<Self> {
        let rate = |list: &[Touch<f64, Dyn>]| -> crate::Result<Vec<Vec<f64>>> {
            (list.iter())
                .map(|t| model.rates((kind.robot, errors), t))
                .collect()
        };
        Ok(Self {
            rates: [
                rate(kind.touches)?,
                rate(kind.planes)?,
                rate(kind.known_contacts)?,
            ],
            lists: [
                kind.touches.to_vec(),
                kind.planes.to_vec(),
                kind.known_contacts.to_vec(),
            ],
            joints: model.torsions.iter().map(|(j, _)| j - 1).collect(),
            kind,
        })
    }

    /// The readings turned by the torsions `gains` (urad per N m, one per torsion).
    pub fn turned(&self, gains: &[f64]) -> Turned<'a> {
        let turn = |list: &[Touch<f64, Dyn>], rates: &[Vec<f64>]| -> Vec<Touch<f64, Dyn>> {
            (list.iter().zip(rates))
                .map(|(t, rates)| {
                    let mut out = t.clone();
                    for ((joint, rate), gain) in self.joints.iter().zip(rates).zip(gains) {
                        let (s, c) = (rate * gain).sin_cos();
                        let (s0, c0) = (t.angles.sin[*joint], t.angles.cos[*joint]);
                        out.angles.sin[*joint] = s0 * c + c0 * s;
                        out.angles.cos[*joint] = c0 * c - s0 * s;
                    }
                    out
                })
                .collect()
        };
        Turned {
            kind: self.kind,
            lists: [0, 1, 2].map(|i| turn(&self.lists[i], &self.rates[i])),
        }
    }

    /// The largest turn of a joint by `gains` over the touches, rad.
    fn largest_turn(&self, gains: &[f64]) -> f64 {
        (self.rates[0].iter())
            .flat_map(|rates| rates.iter().zip(gains).map(|(r, g)| (r * g).abs()))
            .fold(0.0, f64::max)
    }

    /// The same with only the touches of each socket whose index among its socket's touches
    /// is (`left_out`) or is not (`!left_out`) `fold` modulo [`FOLDS`].
    fn fold(&self, fold: usize, left_out: bool) -> Self {
        let mut seen = std::collections::HashMap::<u16, usize>::new();
        let (touches, rates): (Vec<_>, Vec<_>) = (self.lists[0].iter().zip(&self.rates[0]))
            .filter(|(t, _)| {
                let n = seen.entry(t.point).or_insert(0);
                let index = *n;
                *n += 1;
                (index % FOLDS == fold) == left_out
            })
            .map(|(t, r)| (t.clone(), r.clone()))
            .unzip();
        let mut out = self.clone();
        out.lists[0] = touches;
        out.rates[0] = rates;
        out
    }
}

/// The touches at readings turned by the torsions, over the geometry's parameters of `set`
/// and the active torsions' gains: the core's residuals of the turned touches, with one column
/// per active gain (central differences of the rows).
struct TorsionTouches<'r, 'a> {
    rated: &'r Rated<'a>,
    set: ParameterSet<Dyn, Dyn>,
    /// Which torsions are fitted (the others stay at zero).
    active: Vec<bool>,
}

impl TorsionTouches<'_, '_> {
    fn geometry(&self) -> usize {
        self.set.len()
    }

    fn gains(&self) -> usize {
        self.active.iter().filter(|a| **a).count()
    }

    /// Every torsion's gain from the packed vector `x` (inactive ones zero).
    fn all_gains(&self, x: &DVector<f64>) -> Vec<f64> {
        let mut packed = x.iter().skip(self.geometry());
        (self.active.iter())
            .map(|a| {
                if *a {
                    packed.next().copied().unwrap_or(0.0)
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// The rows (residuals only, or with the geometry's Jacobian) of the touches turned by
    /// `gains` at the geometry `x`.
    fn rows(
        &self,
        x: &DVector<f64>,
        gains: &[f64],
        (left_out, robust): (&[bool], &[f64]),
        with_jacobian: bool,
    ) -> Vec<(DVector<f64>, f64)> {
        let turned = self.rated.turned(gains);
        let kind = turned.kind();
        let mut out = Vec::new();
        if let Ok(residuals) = kind.residuals(self.set.clone()) {
            residuals.for_each_row(x, left_out, robust, with_jacobian, |j, r| {
                out.push((
                    if with_jacobian {
                        j.clone()
                    } else {
                        DVector::zeros(0)
                    },
                    r,
                ));
            });
        }
        out
    }
}

impl Residuals for TorsionTouches<'_, '_> {
    type Real = f64;
    type Dim = Dyn;

    fn dim(&self) -> Dyn {
        Dyn(self.geometry() + self.gains())
    }

    fn parameters(&self) -> usize {
        self.geometry() + self.gains()
    }

    fn check_shape(&self, x: &DVector<f64>) -> Result<(), ShapeError> {
        if x.len() == self.parameters() {
            Ok(())
        } else {
            Err(ShapeError {
                expected: self.parameters(),
                got: x.len(),
            })
        }
    }

    fn measurements(&self) -> usize {
        self.rated.kind.count()
    }

    fn rows(&self, left_out: &[bool]) -> u32 {
        let turned = self.rated.turned(&[]);
        let kind = turned.kind();
        kind.residuals(self.set.clone())
            .map_or(0, |r| r.rows(left_out))
    }

    fn for_each_row(
        &self,
        x: &DVector<f64>,
        left_out: &[bool],
        robust: &[f64],
        with_jacobian: bool,
        mut row: impl FnMut(&DVector<f64>, f64),
    ) {
        let geometry = x.rows(0, self.geometry().min(x.len())).into_owned();
        let gains = self.all_gains(x);
        let base = self.rows(&geometry, &gains, (left_out, robust), with_jacobian);
        let mut full = DVector::zeros(self.parameters());
        if !with_jacobian {
            for (_, r) in base {
                row(&full, r);
            }
            return;
        }
        // Each active gain's column: central differences of the rows.
        let columns: Vec<Vec<f64>> = (self.active.iter().enumerate())
            .filter(|(_, a)| **a)
            .map(|(g, _)| {
                let at = |sign: f64| {
                    let mut moved = gains.clone();
                    moved[g] += sign * STEP_URAD_PER_NM;
                    self.rows(&geometry, &moved, (left_out, robust), false)
                };
                let (plus, minus) = (at(1.0), at(-1.0));
                (plus.iter().zip(&minus))
                    .map(|((_, p), (_, m))| (p - m) / (2.0 * STEP_URAD_PER_NM))
                    .collect()
            })
            .collect();
        for (i, (jacobian, r)) in base.into_iter().enumerate() {
            full.rows_mut(0, jacobian.len()).copy_from(&jacobian);
            for (c, column) in columns.iter().enumerate() {
                full[jacobian.len() + c] = column.get(i).copied().unwrap_or(0.0);
            }
            row(&full, r);
        }
    }

    fn for_each_norm(&self, x: &DVector<f64>, left_out: &[bool], visit: impl FnMut(usize, f64)) {
        let geometry = x.rows(0, self.geometry().min(x.len())).into_owned();
        let turned = self.rated.turned(&self.all_gains(x));
        let kind = turned.kind();
        if let Ok(residuals) = kind.residuals(self.set.clone()) {
            residuals.for_each_norm(&geometry, left_out, visit);
        }
    }
}

/// A fit of the geometry with the torsions: the geometry's fit and the gains.
#[derive(Clone, Debug)]
pub struct TorsionFit {
    /// The geometry: its parameters, errors and covariance (the gains' rows and columns left
    /// out), least squares over geometry and gains.
    pub geometry: KindFit,
    /// Every torsion's gain, urad per N m (0: set to zero).
    pub gains: Vec<f64>,
    /// Their standard errors (`None`: set to zero, or a singular covariance).
    pub std_errors: Vec<Option<f64>>,
}

/// Fits the geometry's parameters of `selection` and the torsions' gains to `rated` from the
/// nominal model; a negative gain is set to zero and the rest fitted again.
pub fn fit_with_torsion(
    rated: &Rated<'_>,
    selection: &Selection,
    config: &CalibrationConfig,
    mut active: Vec<bool>,
) -> crate::Result<TorsionFit> {
    let set = crate::model::counts::solvable_set(&selection.mask)?;
    // The rows of the turned touches are those of these touches: refused here, not in the fit.
    rated.turned(&[]).kind().residuals(set.clone())?;
    loop {
        let residuals = TorsionTouches {
            rated,
            set: set.clone(),
            active: active.clone(),
        };
        let started = std::time::Instant::now();
        let settings = LmSettings {
            max_iterations: config.lm_iterations,
            ..LmSettings::default()
        };
        let fit = LeastSquares::new(&residuals)
            .solve(&DVector::zeros(residuals.parameters()), &settings)
            .map_err(|e| super::solve::lm_error(e, &set))?;
        let gains = residuals.all_gains(&fit.x);
        if gains.iter().any(|g| *g < 0.0) {
            for (a, g) in active.iter_mut().zip(&gains) {
                *a = *a && *g > 0.0;
            }
            continue;
        }
        let n = set.len();
        let standard_errors = fit.standard_errors();
        let mut errors_of_gains = standard_errors.iter().flat_map(|s| s.iter().skip(n));
        let std_errors = (active.iter())
            .map(|a| {
                if *a {
                    errors_of_gains.next().copied()
                } else {
                    None
                }
            })
            .collect();
        let geometry_x = fit.x.rows(0, n).into_owned();
        let geometry_se = standard_errors.map(|s| s.rows(0, n).into_owned());
        return Ok(TorsionFit {
            geometry: KindFit {
                parameters: super::solve::identified_parameters(
                    &set,
                    &geometry_x,
                    geometry_se.as_ref(),
                ),
                errors: set.unpack(&geometry_x)?,
                covariance: fit
                    .covariance()
                    .map(|c| c.view((0, 0), (n, n)).into_owned()),
                least_squares: super::result::LeastSquaresReport::of(&fit),
                sigma_mm: fit.sigma(),
                set,
                seconds: started.elapsed().as_secs_f64(),
            },
            gains,
            std_errors,
        });
    }
}

/// The mean distance (mm) of the touches of each fold from their socket's centre as a fit of
/// the other folds puts it, over [`FOLDS`] folds: with the torsions `active` (none: the
/// geometry alone).
fn cross_validated(
    rated: &Rated<'_>,
    selection: &Selection,
    config: &CalibrationConfig,
    active: &[bool],
) -> crate::Result<f64> {
    let (mut sum, mut count) = (0.0, 0usize);
    for fold in 0..FOLDS {
        let (training, left_out) = (rated.fold(fold, false), rated.fold(fold, true));
        let (errors, gains) = if active.iter().any(|a| *a) {
            let fit = fit_with_torsion(&training, selection, config, active.to_vec())?;
            (fit.geometry.errors, fit.gains)
        } else {
            let turned = training.turned(&[]);
            let fit = super::fit::least_squares_of(&turned.kind(), selection, config)?;
            (fit.errors, Vec::new())
        };
        let model = Kinematics::new(rated.kind.robot, &errors)?;
        let (training, left_out) = (training.turned(&gains), left_out.turned(&gains));
        let mut centres = std::collections::HashMap::<u16, (nalgebra::Vector3<f64>, f64)>::new();
        for t in training.kind().touches {
            let entry = centres
                .entry(t.point)
                .or_insert((nalgebra::Vector3::zeros(), 0.0));
            entry.0 += model.forward_angles(&t.angles).translation.vector;
            entry.1 += 1.0;
        }
        let centres: std::collections::HashMap<u16, nalgebra::Vector3<f64>> = (centres.into_iter())
            .map(|(p, (sum, n))| (p, sum / n))
            .collect();
        for t in left_out.kind().touches {
            if let Some(c) = centres.get(&t.point) {
                sum += (model.forward_angles(&t.angles).translation.vector - c).norm();
                count += 1;
            }
        }
    }
    Ok(sum / count.max(1) as f64)
}

/// Which torsions earn their place on `rated` (the fitted touches), and the fit with them:
/// from every torsion, the one whose removal predicts the left-out touches best is removed
/// while that improves the prediction (backward elimination on `cross_validated`); the
/// torsion is kept when what remains predicts better than the geometry alone.
pub fn try_torsion(
    rated: &Rated<'_>,
    model: &TorsionModel,
    selection: &Selection,
    config: &CalibrationConfig,
) -> crate::Result<(TorsionReport, TorsionFit)> {
    let mut counts = std::collections::BTreeMap::<u16, usize>::new();
    for t in &rated.lists[0] {
        *counts.entry(t.point).or_insert(0) += 1;
    }
    if let Some(n) = counts.values().find(|n| **n < FOLDS) {
        return Err(crate::refused!(option "--compliance";
            "--compliance: a socket of the fitted placements has {n} touches; the torsion is judged on touches left out in {FOLDS} folds, so give each socket at least {FOLDS}"));
    }
    let none = vec![false; rated.joints.len()];
    let geometry = cross_validated(rated, selection, config, &none)?;
    let mut active = vec![true; rated.joints.len()];
    let mut with_torsion = cross_validated(rated, selection, config, &active)?;
    while active.iter().filter(|a| **a).count() > 1 {
        let mut best: Option<(usize, f64)> = None;
        for i in (0..active.len()).filter(|i| active[*i]) {
            let mut fewer = active.clone();
            fewer[i] = false;
            let figure = cross_validated(rated, selection, config, &fewer)?;
            if best.is_none_or(|(_, b)| figure < b) {
                best = Some((i, figure));
            }
        }
        match best {
            Some((i, figure)) if figure < with_torsion => {
                active[i] = false;
                with_torsion = figure;
            }
            _ => break,
        }
    }
    // The moments at the identified geometry, which the controller's deflection takes: the
    // fit again with the readings' rates there.
    let first = fit_with_torsion(rated, selection, config, active.clone())?;
    let rated = &Rated::new(rated.kind, model, &first.geometry.errors)?;
    let fit = fit_with_torsion(rated, selection, config, active.clone())?;
    Ok((
        TorsionReport {
            joints: model.joints(),
            fitted: (active.iter().zip(&fit.gains))
                .map(|(a, g)| *a && *g > 0.0)
                .collect(),
            kept: with_torsion < geometry,
            gains_urad_per_nm: fit.gains.clone(),
            std_errors_urad_per_nm: fit.std_errors.clone(),
            cross_validated_mm: [geometry, with_torsion],
            largest_turn_mrad: rated.largest_turn(&fit.gains) * 1e3,
            controller_difference_mm: controller_difference(rated, model, &fit)?,
        },
        fit,
    ))
}

/// The largest distance over the touches of `rated` between the ball at the readings turned
/// by `fit`'s gains and the controller's: the identified geometry deflected to first order by
/// the same gains (`Compliance::forward`), mm.
fn controller_difference(
    rated: &Rated<'_>,
    model: &TorsionModel,
    fit: &TorsionFit,
) -> crate::Result<f64> {
    let robot = rated.kind.robot;
    let joints = robot.joints.len();
    let geometry = Kinematics::new(robot, &fit.geometry.errors)?;
    let controller =
        (model.gravity).to_core::<f64>(&model.all_gains(joints, &fit.gains), joints)?;
    let turned = rated.turned(&fit.gains);
    let mut worst = 0.0f64;
    for (read, turned) in rated.lists[0].iter().zip(turned.kind().touches) {
        let q = JointVec::from_fn(joints, |j| read.angles.sin[j].atan2(read.angles.cos[j]));
        let applied = controller.forward(&geometry, &q)?.translation.vector;
        let fitted = geometry.forward_angles(&turned.angles).translation.vector;
        worst = worst.max((applied - fitted).norm());
    }
    Ok(worst)
}
