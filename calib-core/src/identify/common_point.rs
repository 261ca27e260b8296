//! Common points: a measurement kind without an instrument. A point of the tool (a ball on the
//! flange: the robot's tool frame) is held at one fixed but unknown point (a socket) while the
//! arm takes several configurations; only the joint readings are recorded, each with the point
//! it touched ([`Touch`]). A model is right when it puts the ball at one place for all
//! configurations of a point.
//!
//! The unknown point positions are not parameters of the fit: for given robot parameters the
//! best position of a point is the weighted mean of the ball positions the model predicts for
//! its touches, so the residual of a touch is its distance from that mean,
//! `r_i = sqrt(w_i) (c_g - p_i)` with `c_g = sum_j w_j p_j / sum_j w_j` over the touches `j` of
//! point `g` (variable projection: the centres eliminated in closed form). `r = W^1/2 (M - I) p`
//! with the constant averaging `M`, so the exact Jacobian is `sqrt(w_i) (mean_g J - J_i)`, with
//! `J_i` the position rows of the parameter Jacobian at touch `i`. The residual has three rows
//! per touch and `3 (touches - points)` degrees of freedom, which [`Residuals::rows`] counts.
//!
//! A known distance between two points ([`KnownDistance`]: the two sockets of one printed tool)
//! adds the row `sqrt(weight) (mm - |c_a - c_b|)` between their centres and fixes the scale.
//!
//! Plane contacts ([`CommonPoints::with_planes`]: the ball pressed on a flat surface from many
//! configurations, a [`Touch`] whose `point` numbers the plane) are common planes: the ball's
//! centres of a plane lie on one plane (the surface moved out by the ball's radius), unknown.
//! It is eliminated the same way: for given parameters the best plane passes through the
//! weighted mean `c_g` of its centres with the normal `n_g` of least weighted scatter (the
//! eigenvector of the smallest eigenvalue of `S_g = sum w_i (p_i - c_g)(p_i - c_g)^T`), and the
//! residual of a contact is its signed distance `r_i = sqrt(w_i) n_g^T d_i`, `d_i = p_i - c_g`:
//! one row per contact, `contacts - 3` degrees of freedom per plane (planes with fewer than four
//! contacts, or contacts along one line, give none). Its exact Jacobian row is
//! `sqrt(w_i) (n_g^T G_i + d_i^T N)` with `G_i = J_i - mean_g J` and `N` the normal's own change,
//! from the eigenvector's perturbation: `N = -(S_g - lambda I)^+ sum_j w_j (G_j (d_j^T n_g) +
//! d_j (n_g^T G_j))` (the pseudo-inverse on the plane's two directions). Leaving `N` out
//! (Kaufman's approximation) keeps the gradient exact but not the Gauss-Newton matrix: the
//! contacts lie up to a hundred millimetres from their centre, and least squares then crawls.
//! A plane determines one direction per contact where a socket determines three, and leaves
//! free what common points do.
//!
//! What such data cannot determine: where the robot stands (a rigid motion of the base moves
//! every point along: the base frame, and the first joint's `theta` and `d`, which turn and lift
//! the whole arm about the first axis), what comes after the last axis apart from the ball's
//! offset (the last joint's parameters: the offset takes them) and, without a known length, the
//! scale (a robot scaled uniformly, ball offset included, keeps each point one point; fixing one
//! length fixes it only weakly). The identifiability analysis of the fit's Jacobian says so; the
//! caller leaves those out of the set.

use crate::identify::Problem;
use crate::identify::ProblemError;
use crate::identify::objective::MeasurementError;
use crate::identify::residuals::{Residuals, is_left_out};
use crate::kinematics::{JointAngles, Kinematics};
use crate::model::parameters::{ParameterErrors, ParameterSet, ShapeError};
use crate::model::{JointCount, JointTable, Robot, check_count};
use crate::scalar::Real;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, Matrix3, OMatrix, OVector, U3, U6, Vector3};

/// One configuration of the arm with the ball in a socket.
#[derive(Clone, Debug, PartialEq)]
pub struct Touch<T: Real, N: JointCount> {
    /// Joint readings as sine and cosine.
    pub angles: JointAngles<T, N>,
    /// The point (socket) touched, numbered from 0.
    pub point: u16,
    /// Weight of the touch in the fit (1 by default).
    pub weight: T,
}

impl<T: Real, N: JointCount> Touch<T, N> {
    /// A touch of `point` at the joint readings `q` (rad) with `weight` (>= 0). Refused: a
    /// reading or the weight not finite, a negative weight.
    pub fn new(q: &N::Table<T>, point: u16, weight: T) -> Result<Self, MeasurementError> {
        let angles = JointAngles::new(q).map_err(MeasurementError::Joint)?;
        if !weight.finite() {
            return Err(MeasurementError::NonFinite);
        }
        if weight < T::zero() {
            return Err(MeasurementError::NegativeWeight);
        }
        Ok(Self {
            angles,
            point,
            weight,
        })
    }
}

/// A known distance between two points (a gauge: two sockets of one printed tool, a ball bar).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KnownDistance<T> {
    /// The two points, by number.
    pub points: [u16; 2],
    /// Their distance, mm.
    pub mm: T,
    /// Weight of its residual row, against the touches' rows of weight 1: the square of (the
    /// touches' scatter / the distance's uncertainty), such as `(0.1 / 0.05)^2 = 4` for balls
    /// within 0.1 mm and a distance known to 0.05 mm.
    pub weight: T,
}

/// Why a known distance was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum DistanceError {
    /// A point no touch names.
    UnknownPoint(u16),
    /// A point's distance from itself.
    SamePoint(u16),
    /// A distance not finite or not above zero, or a weight not finite or negative.
    Value,
}

impl core::fmt::Display for DistanceError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::UnknownPoint(p) => write!(f, "no touch names point {p} of a known distance"),
            Self::SamePoint(p) => write!(f, "a known distance from point {p} to itself"),
            Self::Value => f.write_str(
                "a known distance must be finite and above 0 mm, its weight finite and >= 0",
            ),
        }
    }
}

impl core::error::Error for DistanceError {}

/// Which measurements a helper goes over: the touches of points or the contacts with planes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Group {
    Points,
    Planes,
}

/// The touches of one calibration with the robot and the identified parameters, checked once:
/// the common-point kind of measurement for [`crate::identify::lm::LeastSquares`].
#[derive(Clone, Debug)]
pub struct CommonPoints<'a, T: Real, N: JointCount, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// The robot (its tool frame is the ball), the fixed errors and the identified set (a
    /// problem without pose measurements).
    model: Problem<'a, T, N, D>,
    touches: &'a [Touch<T, N>],
    /// One more than the largest point number.
    points: u16,
    /// Known distances between the points.
    distances: &'a [KnownDistance<T>],
    /// Contacts of the ball with planes, each `point` numbering its plane.
    planes: &'a [Touch<T, N>],
    /// One more than the largest plane number.
    plane_count: u16,
}

impl<'a, T: Real, N: JointCount, D: Dim> CommonPoints<'a, T, N, D>
where
    DefaultAllocator: Allocator<D> + Allocator<U6, D> + Allocator<U3, D>,
{
    /// The problem of identifying the parameters of `set` of `robot` (whose tool frame is the
    /// ball's centre) from `touches`; the other parameters keep the values of `fixed`.
    pub fn new(
        robot: &Robot<T, N>,
        fixed: &ParameterErrors<T, N>,
        set: ParameterSet<N, D>,
        touches: &'a [Touch<T, N>],
    ) -> Result<Self, ProblemError> {
        let model = Problem::new(robot, fixed, set, &[], T::zero())?;
        for t in touches {
            check_count(robot.joints.len(), t.angles.cos.len())?;
        }
        let points = touches.iter().map(|t| t.point).max().map_or(0, |p| p + 1);
        Ok(Self {
            model,
            touches,
            points,
            distances: &[],
            planes: &[],
            plane_count: 0,
        })
    }

    /// The same problem with the known `distances` between its points, each a residual row
    /// `sqrt(weight) (mm - |c_a - c_b|)` between the points' centres: a length that fixes the
    /// scale. (The centres stay the means of their touches; with a distance the exact optimum
    /// would move them by a share of its residual, which the weight keeps small.)
    pub fn with_distances(self, distances: &'a [KnownDistance<T>]) -> Result<Self, DistanceError> {
        for d in distances {
            let [a, b] = d.points;
            for p in [a, b] {
                if !self.touches.iter().any(|t| t.point == p) {
                    return Err(DistanceError::UnknownPoint(p));
                }
            }
            if a == b {
                return Err(DistanceError::SamePoint(a));
            }
            if !(d.mm.finite() && d.mm > T::zero() && d.weight.finite() && d.weight >= T::zero()) {
                return Err(DistanceError::Value);
            }
        }
        Ok(Self { distances, ..self })
    }

    /// The same problem with the ball's `contacts` with planes (each touch's `point` numbering
    /// its plane, unknown): a row per contact, its distance from the best plane through its
    /// plane's centres. Refused: a contact of another joint count than the robot's.
    pub fn with_planes(self, contacts: &'a [Touch<T, N>]) -> Result<Self, ProblemError> {
        for t in contacts {
            check_count(self.model.joint_count().value(), t.angles.cos.len())?;
        }
        let plane_count = contacts.iter().map(|t| t.point).max().map_or(0, |p| p + 1);
        Ok(Self {
            planes: contacts,
            plane_count,
            ..self
        })
    }

    /// The identified parameters.
    pub fn set(&self) -> &ParameterSet<N, D> {
        self.model.set()
    }

    /// The touches.
    pub fn touches(&self) -> &'a [Touch<T, N>] {
        self.touches
    }

    /// The actual model at the packed errors `x`; a vector of another length than the set is
    /// refused.
    pub fn kinematics(&self, x: &OVector<T, D>) -> Result<Kinematics<T, N>, ShapeError> {
        self.model.kinematics(x)
    }

    /// The centre of `point` at `x`: the weighted mean of the ball positions the model predicts
    /// for its touches (mm), `None` without touches of positive weight; a vector of another
    /// length than the set is refused.
    pub fn centre_at(
        &self,
        x: &OVector<T, D>,
        point: u16,
    ) -> Result<Option<Vector3<T>>, ShapeError> {
        let model = self.kinematics(x)?;
        Ok(self.centre(&model, point, &[], &[]))
    }

    /// The touches of `point` taken into account (not `left_out`), with their indices.
    fn of_point<'s>(
        &'s self,
        point: u16,
        left_out: &'s [bool],
    ) -> impl Iterator<Item = (usize, &'a Touch<T, N>)> + 's {
        self.of(Group::Points, point, left_out)
    }

    /// The touches (or plane contacts) of `point` (or plane) taken into account (not
    /// `left_out`), with their measurement indices (the contacts' after the touches').
    fn of<'s>(
        &'s self,
        group: Group,
        point: u16,
        left_out: &'s [bool],
    ) -> impl Iterator<Item = (usize, &'a Touch<T, N>)> + 's {
        let (touches, offset) = match group {
            Group::Points => (self.touches, 0),
            Group::Planes => (self.planes, self.touches.len()),
        };
        (touches.iter().enumerate())
            .map(move |(i, t)| (i + offset, t))
            .filter(move |(i, t)| t.point == point && !is_left_out(left_out, *i))
    }

    /// The best plane through the centres `model` puts at the contacts of `plane`: their
    /// weighted mean, the unit normal of least weighted scatter and `(S - lambda I)^+` on the
    /// plane's directions; `None` below four contacts of positive weight (three always lie on a
    /// plane), for contacts along one line, or when the eigen-solver does not settle.
    fn best_plane(
        &self,
        model: &Kinematics<T, N>,
        plane: u16,
        left_out: &[bool],
        robust: &[T],
    ) -> Option<(Vector3<T>, Vector3<T>, Matrix3<T>)> {
        let centre = self.mean(Group::Planes, model, plane, left_out, robust)?;
        let mut scatter = Matrix3::zeros();
        let mut contacts = 0u32;
        for (i, t) in self.of(Group::Planes, plane, left_out) {
            let w = t.weight * robust.get(i).copied().unwrap_or_else(T::one);
            let d = model.forward_angles(&t.angles).translation.vector - centre;
            scatter += d * d.transpose() * w;
            contacts += u32::from(w > T::zero());
        }
        if contacts < 4 {
            return None;
        }
        let eigen = scatter.try_symmetric_eigen(T::default_epsilon(), 200)?;
        let (values, vectors) = (eigen.eigenvalues, eigen.eigenvectors);
        let mut pairs = [
            (values.x, vectors.column(0).into_owned()),
            (values.y, vectors.column(1).into_owned()),
            (values.z, vectors.column(2).into_owned()),
        ];
        pairs.sort_unstable_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(core::cmp::Ordering::Equal));
        let [(smallest, normal), (middle, v), (largest, u)] = pairs;
        // Contacts along a line (or at one point) leave the plane's turn about it free.
        if middle - smallest <= largest * T::of(1e-12) {
            return None;
        }
        let inverse =
            v * v.transpose() / (middle - smallest) + u * u.transpose() / (largest - smallest);
        Some((centre, normal, inverse))
    }

    /// The normal's change `N` (3 x parameters) of the plane through the contacts of `plane`:
    /// `-(S - lambda I)^+ sum_j w_j (G_j (d_j^T n) + d_j (n^T G_j))`.
    fn normal_jacobian(
        &self,
        model: &Kinematics<T, N>,
        plane: u16,
        (centre, normal, inverse): (&Vector3<T>, &Vector3<T>, &Matrix3<T>),
        mean: &OMatrix<T, U3, D>,
        (left_out, robust): (&[bool], &[T]),
    ) -> OMatrix<T, U3, D> {
        let set = self.model.set();
        let mut sum = OMatrix::<T, U3, D>::zeros_generic(U3, set.dim());
        for (i, t) in self.of(Group::Planes, plane, left_out) {
            let w = t.weight * robust.get(i).copied().unwrap_or_else(T::one);
            let (pose, twist) = model.parameter_jacobian(set, &t.angles);
            let d = pose.translation.vector - centre;
            let g = twist.fixed_rows::<3>(0) - mean;
            let along = g.tr_mul(normal);
            sum += g * (d.dot(normal) * w);
            for (k, a) in along.iter().enumerate() {
                let mut column = sum.column_mut(k);
                column += d * (*a * w);
            }
        }
        -(inverse * sum)
    }

    /// The plane contacts' rows: `sqrt(w) n^T (p - c)` per contact, its exact Jacobian row
    /// `sqrt(w) (n^T G_i + d_i^T N)` when `with_jacobian`.
    fn for_each_plane_row(
        &self,
        model: &Kinematics<T, N>,
        left_out: &[bool],
        robust: &[T],
        with_jacobian: bool,
        row: &mut impl FnMut(&OVector<T, D>, T),
    ) {
        let set = self.model.set();
        let zero = set.zeros::<T>();
        let mut scaled = zero.clone();
        for plane in 0..self.plane_count {
            let Some((centre, normal, inverse)) = self.best_plane(model, plane, left_out, robust)
            else {
                continue;
            };
            let jacobians = if with_jacobian {
                (self.centre_and_jacobian_of(Group::Planes, model, plane, left_out, robust)).map(
                    |(_, mean)| {
                        let fitted = (&centre, &normal, &inverse);
                        let turn =
                            self.normal_jacobian(model, plane, fitted, &mean, (left_out, robust));
                        (mean, turn)
                    },
                )
            } else {
                None
            };
            for (i, t) in self.of(Group::Planes, plane, left_out) {
                let w = (t.weight * robust.get(i).copied().unwrap_or_else(T::one)).sqrt();
                match &jacobians {
                    Some((mean, turn)) => {
                        let (pose, twist) = model.parameter_jacobian(set, &t.angles);
                        let d = pose.translation.vector - centre;
                        let gradient =
                            (twist.fixed_rows::<3>(0) - mean).tr_mul(&normal) + turn.tr_mul(&d);
                        for (s, g) in scaled.iter_mut().zip(gradient.iter()) {
                            *s = *g * w;
                        }
                        row(&scaled, normal.dot(&d) * w);
                    }
                    None => {
                        let p = model.forward_angles(&t.angles).translation.vector;
                        row(&zero, normal.dot(&(p - centre)) * w);
                    }
                }
            }
        }
    }

    /// The weighted mean of the ball positions `model` predicts for the touches of `point`
    /// (weights `weight * robust`), or `None` when their weights sum to zero.
    fn centre(
        &self,
        model: &Kinematics<T, N>,
        point: u16,
        left_out: &[bool],
        robust: &[T],
    ) -> Option<Vector3<T>> {
        self.mean(Group::Points, model, point, left_out, robust)
    }

    /// The weighted mean of the ball positions `model` predicts for the touches (or contacts) of
    /// `point` (or plane) of `group`, or `None` when their weights sum to zero.
    fn mean(
        &self,
        group: Group,
        model: &Kinematics<T, N>,
        point: u16,
        left_out: &[bool],
        robust: &[T],
    ) -> Option<Vector3<T>> {
        let (mut sum, mut weights) = (Vector3::zeros(), T::zero());
        for (i, t) in self.of(group, point, left_out) {
            let w = t.weight * robust.get(i).copied().unwrap_or_else(T::one);
            sum += model.forward_angles(&t.angles).translation.vector * w;
            weights += w;
        }
        (weights > T::zero()).then(|| sum / weights)
    }

    /// The weighted mean of the ball positions and of their Jacobians (the position rows of
    /// the parameter Jacobian) over the touches of `point`, or `None` when their weights sum to
    /// zero.
    fn centre_and_jacobian(
        &self,
        model: &Kinematics<T, N>,
        point: u16,
        left_out: &[bool],
        robust: &[T],
    ) -> Option<(Vector3<T>, OMatrix<T, U3, D>)> {
        self.centre_and_jacobian_of(Group::Points, model, point, left_out, robust)
    }

    /// [`Self::centre_and_jacobian`] over the touches or the plane contacts.
    fn centre_and_jacobian_of(
        &self,
        group: Group,
        model: &Kinematics<T, N>,
        point: u16,
        left_out: &[bool],
        robust: &[T],
    ) -> Option<(Vector3<T>, OMatrix<T, U3, D>)> {
        let set = self.model.set();
        let mut sum = Vector3::zeros();
        let mut jacobian = OMatrix::<T, U3, D>::zeros_generic(U3, set.dim());
        let mut weights = T::zero();
        for (i, t) in self.of(group, point, left_out) {
            let w = t.weight * robust.get(i).copied().unwrap_or_else(T::one);
            let (pose, twist) = model.parameter_jacobian(set, &t.angles);
            sum += pose.translation.vector * w;
            jacobian += twist.fixed_rows::<3>(0) * w;
            weights += w;
        }
        (weights > T::zero()).then(|| (sum / weights, jacobian / weights))
    }
}

impl<T: Real, N: JointCount, D: Dim> Residuals for CommonPoints<'_, T, N, D>
where
    DefaultAllocator: Allocator<D> + Allocator<U6, D> + Allocator<U3, D>,
{
    type Real = T;
    type Dim = D;

    fn dim(&self) -> D {
        self.model.set().dim()
    }

    fn parameters(&self) -> usize {
        self.model.set().len()
    }

    fn check_shape(&self, x: &OVector<T, D>) -> Result<(), ShapeError> {
        self.model.set().check_shape(x)
    }

    fn measurements(&self) -> usize {
        self.touches.len() + self.planes.len()
    }

    /// The degrees of freedom: 3 per touch, less 3 per point touched (its centre is fitted),
    /// 1 per known distance between points touched, and 1 per plane contact less 3 per plane
    /// of at least four contacts (its position and normal are fitted).
    fn rows(&self, left_out: &[bool]) -> u32 {
        let touched = |p: u16| self.of_point(p, left_out).next().is_some();
        let distances = (self.distances.iter())
            .filter(|d| d.points.iter().all(|p| touched(*p)))
            .count();
        (0..self.points)
            .map(|point| self.of_point(point, left_out).count())
            .map(|n| 3 * u32::try_from(n.saturating_sub(1)).unwrap_or(u32::MAX))
            .fold(0, u32::saturating_add)
            .saturating_add(u32::try_from(distances).unwrap_or(u32::MAX))
            .saturating_add(
                (0..self.plane_count)
                    .map(|plane| self.of(Group::Planes, plane, left_out).count())
                    .filter(|n| *n >= 4)
                    .map(|n| u32::try_from(n - 3).unwrap_or(u32::MAX))
                    .fold(0, u32::saturating_add),
            )
    }

    fn for_each_row(
        &self,
        x: &OVector<T, D>,
        left_out: &[bool],
        robust: &[T],
        with_jacobian: bool,
        mut row: impl FnMut(&OVector<T, D>, T),
    ) {
        let model = self.model.kinematics_unchecked(x);
        let set = self.model.set();
        let zero = set.zeros::<T>();
        let mut scaled = zero.clone();
        for point in 0..self.points {
            let (centre, mean_jacobian) = if with_jacobian {
                match self.centre_and_jacobian(&model, point, left_out, robust) {
                    Some((c, j)) => (c, Some(j)),
                    None => continue,
                }
            } else {
                match self.centre(&model, point, left_out, robust) {
                    Some(c) => (c, None),
                    None => continue,
                }
            };
            for (i, t) in self.of_point(point, left_out) {
                let w = (t.weight * robust.get(i).copied().unwrap_or_else(T::one)).sqrt();
                match &mean_jacobian {
                    Some(mean) => {
                        let (pose, twist) = model.parameter_jacobian(set, &t.angles);
                        let error = centre - pose.translation.vector;
                        for k in 0..3 {
                            for (s, (m, j)) in
                                (scaled.iter_mut()).zip(mean.row(k).iter().zip(twist.row(k).iter()))
                            {
                                *s = (*m - *j) * w;
                            }
                            row(&scaled, error.get(k).copied().unwrap_or_else(T::zero) * w);
                        }
                    }
                    None => {
                        let p = model.forward_angles(&t.angles).translation.vector;
                        for value in (centre - p).iter() {
                            row(&zero, *value * w);
                        }
                    }
                }
            }
        }
        // A distance's centres are computed again (the loop above kept none: the core has no heap
        // for a run-time number of points); it costs the touches of its two points once more.
        for d in self.distances {
            let [a, b] = d.points;
            let w = d.weight.sqrt();
            if with_jacobian {
                let (Some((ca, ja)), Some((cb, jb))) = (
                    self.centre_and_jacobian(&model, a, left_out, robust),
                    self.centre_and_jacobian(&model, b, left_out, robust),
                ) else {
                    continue;
                };
                let between = ca - cb;
                let length = between.norm();
                // d(mm - |c_a - c_b|)/dx = -u^T (J_a - J_b), u the unit vector from b to a.
                let u = if length > T::zero() {
                    between / length
                } else {
                    between
                };
                let gradient = (ja - jb).tr_mul(&u);
                for (s, g) in scaled.iter_mut().zip(gradient.iter()) {
                    *s = -*g * w;
                }
                row(&scaled, (d.mm - length) * w);
            } else {
                let (Some(ca), Some(cb)) = (
                    self.centre(&model, a, left_out, robust),
                    self.centre(&model, b, left_out, robust),
                ) else {
                    continue;
                };
                row(&zero, (d.mm - (ca - cb).norm()) * w);
            }
        }
        self.for_each_plane_row(&model, left_out, robust, with_jacobian, &mut row);
    }

    /// The distance (mm) of each touch's ball from its point's centre (weights 1 for the centre).
    fn for_each_norm(&self, x: &OVector<T, D>, left_out: &[bool], mut visit: impl FnMut(usize, T)) {
        let model = self.model.kinematics_unchecked(x);
        for point in 0..self.points {
            let Some(centre) = self.centre(&model, point, left_out, &[]) else {
                continue;
            };
            for (i, t) in self.of_point(point, left_out) {
                let p = model.forward_angles(&t.angles).translation.vector;
                visit(i, (centre - p).norm());
            }
        }
        for plane in 0..self.plane_count {
            let Some((centre, normal, _)) = self.best_plane(&model, plane, left_out, &[]) else {
                continue;
            };
            for (i, t) in self.of(Group::Planes, plane, left_out) {
                let p = model.forward_angles(&t.angles).translation.vector;
                visit(i, normal.dot(&(p - centre)).abs());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Parameter;
    use crate::controller::numerical_ik::{NumericalIkSettings, numerical_inverse_kinematics};
    use crate::identify::lm::{LeastSquares, LmSettings};
    use crate::kinematics::Pose;
    use crate::model::paper::{er10l_c10, table2};
    use crate::model::parameters::{FrameParameter, JointParameter};
    use crate::model::{FramePose, JointLimits};
    use nalgebra::{Dyn, Rotation3, U6};
    extern crate std;
    use std::vec::Vec;

    /// The five parameters of a joint.
    const EVERY_KIND: [JointParameter; 5] = [
        JointParameter::A,
        JointParameter::Alpha,
        JointParameter::Theta,
        JointParameter::D,
        JointParameter::Beta,
    ];

    /// The ER10L-C10 with a ball 150 mm off its flange as the tool.
    fn robot() -> Robot<f64, U6> {
        let mut robot = er10l_c10::<f64>();
        robot.tool = FramePose {
            xyz: [20.0, -10.0, 150.0],
            rpy: [0.0, 0.0, 0.0],
        };
        robot
    }

    /// What touches can identify (our joints are standard DH, `Rz(theta) Tz(d) Tx(a) Rx(alpha)
    /// Ry(beta)`): not joint 1's theta and d (they turn and lift the whole arm about the first
    /// axis, every point along), nor joint 6's parameters (they come after the last axis: the
    /// ball's offset takes them), nor da3 (the scale: a robot scaled uniformly keeps each point
    /// one point); the ball's offset (tool x, y, z) instead.
    fn identifiable() -> ParameterSet<U6, Dyn> {
        let robot = robot();
        let mut mask = ParameterSet::<U6, Dyn>::default_for(&robot).unwrap().mask();
        for kind in [JointParameter::Theta, JointParameter::D] {
            mask.set(Parameter::Joint { joint: 1, kind }, false);
        }
        let joint = |joint, kind| Parameter::Joint { joint, kind };
        for kind in EVERY_KIND {
            mask.set(joint(6, kind), false);
        }
        mask.set(joint(3, JointParameter::A), false);
        for axis in [FrameParameter::Tx, FrameParameter::Ty, FrameParameter::Tz] {
            mask.set(Parameter::Tool(axis), true);
        }
        ParameterSet::from_mask(&mask).unwrap()
    }

    /// Table 2's errors, those of the parameters `identifiable` leaves out (but joint 1's) at
    /// zero, and the ball 0.8, -0.5, 1.2 mm off its nominal offset.
    fn truth() -> ParameterErrors<f64, U6> {
        let mut errors = table2::<f64>();
        let joint = |joint, kind| Parameter::Joint { joint, kind };
        for kind in EVERY_KIND {
            errors.set(joint(6, kind), 0.0);
        }
        errors.set(joint(3, JointParameter::A), 0.0);
        errors.set(Parameter::Tool(FrameParameter::Tx), 0.8);
        errors.set(Parameter::Tool(FrameParameter::Ty), -0.5);
        errors.set(Parameter::Tool(FrameParameter::Tz), 1.2);
        errors
    }

    /// Twelve configurations of the true robot per socket, the ball at the socket's centre and
    /// the flange turned by up to 0.5 rad about each axis (joint readings from the numerical
    /// inverse kinematics of the true robot, to 1e-9 mm): three sockets, the second 60 mm
    /// from the first.
    fn touches() -> Vec<Touch<f64, U6>> {
        let truth = Kinematics::new(&robot(), &truth()).unwrap();
        let reference = [0.3, -0.4, 0.6, 0.2, 0.9, -0.3];
        let start = truth.forward(&reference).unwrap();
        let settings = NumericalIkSettings {
            position_tolerance_mm: 1e-9,
            rotation_tolerance_rad: 1e-11,
            ..NumericalIkSettings::default()
        };
        let limits = [JointLimits::unlimited(); 6];
        let mut touches = Vec::new();
        for (point, offset) in [[0.0, 0.0, 0.0], [60.0, 0.0, 0.0], [-150.0, 200.0, -120.0]]
            .iter()
            .enumerate()
        {
            let socket = start.translation.vector + Vector3::from(*offset);
            for (a, b, c) in [-0.35, 0.35]
                .iter()
                .flat_map(|a| [-0.3, 0.0, 0.3].map(move |b| (*a, b)))
                .flat_map(|(a, b)| [-0.5, 0.5].map(move |c| (a, b, c)))
            {
                let turned = start.rotation * Rotation3::from_euler_angles(a, b, c);
                let target = Pose::from_parts(socket.into(), turned);
                let ik =
                    numerical_inverse_kinematics(&truth, &limits, &target, &reference, &settings)
                        .unwrap();
                touches.push(Touch::new(&ik.q, point as u16, 1.0).unwrap());
            }
        }
        touches
    }

    /// Every residual row and Jacobian row at `x` (the Jacobian rows zero unless asked for).
    fn rows(
        problem: &CommonPoints<'_, f64, U6, Dyn>,
        x: &OVector<f64, Dyn>,
        robust: &[f64],
        with_jacobian: bool,
    ) -> (Vec<f64>, Vec<Vec<f64>>) {
        let (mut values, mut jacobian) = (Vec::new(), Vec::new());
        problem.for_each_row(x, &[], robust, with_jacobian, |j, r| {
            values.push(r);
            jacobian.push(j.iter().copied().collect());
        });
        (values, jacobian)
    }

    /// The known distance of the first two sockets (60 mm in the truth), weight 4.
    const GAUGE: [KnownDistance<f64>; 1] = [KnownDistance {
        points: [0, 1],
        mm: 60.0,
        weight: 4.0,
    }];

    /// The Jacobian of the residual is that of central differences, with unequal weights (the
    /// centre's dependence on the parameters included) and a known distance, to 1e-7 of its
    /// largest entry.
    #[test]
    fn the_jacobian_is_that_of_the_residual() {
        let robot = robot();
        let touches = touches();
        let set = identifiable();
        let problem = CommonPoints::new(&robot, &ParameterErrors::zero(), set.clone(), &touches)
            .unwrap()
            .with_distances(&GAUGE)
            .unwrap();
        let robust: Vec<f64> = (0..touches.len())
            .map(|i| 0.5 + (i % 5) as f64 / 4.0)
            .collect();
        let x = set.pack(&table2::<f64>()) * 0.5;
        assert_jacobian_of_differences(&problem, &x, &robust);
    }

    /// The Jacobian rows of `problem` at `x` (with `robust` weights) are those of central
    /// differences of its residual rows, to 1e-7 of the largest entry; returns the rows.
    fn assert_jacobian_of_differences(
        problem: &CommonPoints<'_, f64, U6, Dyn>,
        x: &OVector<f64, Dyn>,
        robust: &[f64],
    ) -> (Vec<f64>, Vec<Vec<f64>>) {
        let set = problem.set();
        let (values, jacobian) = rows(problem, x, robust, true);
        assert_eq!(values, rows(problem, x, robust, false).0);
        let largest = jacobian
            .iter()
            .flatten()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        for k in 0..set.len() {
            let h = if set.parameters()[k].is_angle() {
                1e-7
            } else {
                1e-5
            };
            let mut up = x.clone();
            up[k] += h;
            let mut down = x.clone();
            down[k] -= h;
            let (plus, minus) = (
                rows(problem, &up, robust, false).0,
                rows(problem, &down, robust, false).0,
            );
            for (row, (p, m)) in plus.iter().zip(&minus).enumerate() {
                let numeric = (p - m) / (2.0 * h);
                let analytic = jacobian[row][k];
                assert!(
                    (numeric - analytic).abs() < 1e-7 * largest,
                    "{}: row {row}: {analytic} against {numeric}",
                    set.parameters()[k]
                );
            }
        }
        (values, jacobian)
    }

    /// Least squares on `problem` from zero errors: the fit, and the largest residual norm of
    /// its `measurements` before and after.
    fn fit_from_zero(
        problem: &CommonPoints<'_, f64, U6, Dyn>,
        measurements: usize,
    ) -> (crate::identify::lm::LmResult<f64, Dyn>, f64, f64) {
        let least_squares = LeastSquares::new(problem);
        let start = problem.set().zeros::<f64>();
        let largest = |x: &OVector<f64, Dyn>| {
            let mut norms = std::vec![0.0; measurements];
            least_squares.pose_residual_norms(x, &mut norms).unwrap();
            norms.iter().fold(0.0f64, |m, d| m.max(*d))
        };
        let fit = least_squares.solve(&start, &LmSettings::default()).unwrap();
        let (before, after) = (largest(&start), largest(&fit.x));
        (fit, before, after)
    }

    /// Least squares from the nominal robot makes the three sockets one point each again: the
    /// balls up to 1.75 mm from their socket's centre (measured) come within 1e-7 mm (7.4e-10
    /// measured), the identified errors are the true ones (the data determine every parameter
    /// of the set; the least determined direction is the scale, singular value 6e-3 against
    /// 1e3 for the best), and the degrees of freedom are three per touch less three per socket.
    #[test]
    fn least_squares_makes_each_socket_one_point_again() {
        let robot = robot();
        let touches = touches();
        let set = identifiable();
        let problem =
            CommonPoints::new(&robot, &ParameterErrors::zero(), set.clone(), &touches).unwrap();
        let (fit, before, after) = fit_from_zero(&problem, touches.len());
        std::println!(
            "{} touches, {} parameters: largest distance from the centre {before:.3} -> {after:.2e} mm, {} iterations, {:?}",
            touches.len(),
            set.len(),
            fit.iterations,
            fit.stop
        );
        assert!(before > 0.4 && after < 1e-7, "{before} {after}");
        assert_eq!(fit.rows, 3 * (36 - 3));
        let truth = set.pack(&truth());
        let (mm, rad) = set.largest_differences(&fit.x, &truth).unwrap();
        assert!(mm < 1e-6 && rad < 1e-9, "{mm} mm, {rad} rad");
        // The first socket's centre is where the true ball was, up to the rigid motion joint 1's
        // errors make (the same for every socket): the distances between centres are the true ones.
        let centre = |p| problem.centre_at(&fit.x, p).unwrap().unwrap();
        assert!(((centre(1) - centre(0)).norm() - 60.0).abs() < 1e-6);
    }

    /// A touch with a non-finite reading or weight, or a negative weight, is refused; a robot of
    /// another joint count than the touches is refused, not read past.
    #[test]
    fn bad_touches_are_refused() {
        assert!(Touch::<f64, U6>::new(&[0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0], 0, 1.0).is_err());
        assert_eq!(
            Touch::<f64, U6>::new(&[0.0; 6], 0, -1.0),
            Err(MeasurementError::NegativeWeight)
        );
        assert_eq!(
            Touch::<f64, U6>::new(&[0.0; 6], 0, f64::INFINITY),
            Err(MeasurementError::NonFinite)
        );
        let q = crate::model::JointVec::from_slice(&[0.0; 5]).unwrap();
        let short = [Touch::<f64, Dyn>::new(&q, 0, 1.0).unwrap()];
        let robot = robot().recount::<Dyn>().unwrap();
        let set = ParameterSet::<Dyn, Dyn>::default_for(&robot).unwrap();
        let fixed = ParameterErrors::<f64, Dyn>::zeros_for(Dyn(6));
        assert!(CommonPoints::new(&robot, &fixed, set, &short).is_err());
    }

    /// With the known distance of two sockets the scale is determined: `da3`, left out without
    /// it, is identified too, and least squares from the nominal robot finds the true errors of
    /// all 21 parameters and the true distance; the distance adds one degree of freedom.
    #[test]
    fn a_known_distance_determines_the_scale() {
        let robot = robot();
        let touches = touches();
        let mut mask = identifiable().mask();
        let da3 = Parameter::Joint {
            joint: 3,
            kind: JointParameter::A,
        };
        mask.set(da3, true);
        let set = ParameterSet::<U6, Dyn>::from_mask(&mask).unwrap();
        let problem = CommonPoints::new(&robot, &ParameterErrors::zero(), set.clone(), &touches)
            .unwrap()
            .with_distances(&GAUGE)
            .unwrap();
        let least_squares = LeastSquares::new(&problem);
        let fit = least_squares
            .solve(&set.zeros(), &LmSettings::default())
            .unwrap();
        assert_eq!(fit.rows, 3 * (36 - 3) + 1);
        let (mm, rad) = set
            .largest_differences(&fit.x, &set.pack(&truth()))
            .unwrap();
        std::println!(
            "{} parameters with the distance: {mm:.2e} mm, {rad:.2e} rad from the truth, {} iterations",
            set.len(),
            fit.iterations
        );
        assert!(mm < 1e-6 && rad < 1e-9, "{mm} mm, {rad} rad");
        let centre = |p| problem.centre_at(&fit.x, p).unwrap().unwrap();
        assert!(((centre(1) - centre(0)).norm() - 60.0).abs() < 1e-9);
        // A distance naming a point no touch names, or a point twice, or not above zero: refused.
        let refused = |d: KnownDistance<f64>| {
            let problem =
                CommonPoints::new(&robot, &ParameterErrors::zero(), set.clone(), &touches);
            problem.unwrap().with_distances(&[d]).err()
        };
        let gauge = GAUGE[0];
        assert_eq!(
            refused(KnownDistance {
                points: [0, 7],
                ..gauge
            }),
            Some(DistanceError::UnknownPoint(7))
        );
        assert_eq!(
            refused(KnownDistance {
                points: [1, 1],
                ..gauge
            }),
            Some(DistanceError::SamePoint(1))
        );
        assert_eq!(
            refused(KnownDistance { mm: 0.0, ..gauge }),
            Some(DistanceError::Value)
        );
        assert_eq!(
            refused(KnownDistance {
                weight: f64::NAN,
                ..gauge
            }),
            Some(DistanceError::Value)
        );
    }

    /// What touches cannot determine, found by the identifiability analysis of the fit's
    /// Jacobian (not chosen by hand): of every joint parameter of the default set and the ball's
    /// offset, at the truth, seven directions are left undetermined: joint 1's `theta` and `d`
    /// (the arm turned and lifted about its first axis), four after the last axis (joint 6's four
    /// and the ball's offset take each other's place: the pivoting names three of the offset's and
    /// one of joint 6's) and one length (the scale); with the known distance, six.
    #[test]
    fn the_analysis_finds_the_base_the_last_joint_and_the_scale() {
        use crate::identify::identifiability::{DEFAULT_RANK_TOLERANCE, Identifiability};
        let robot = robot();
        let touches = touches();
        let mut mask = ParameterSet::<U6, Dyn>::default_for(&robot).unwrap().mask();
        for axis in [FrameParameter::Tx, FrameParameter::Ty, FrameParameter::Tz] {
            mask.set(Parameter::Tool(axis), true);
        }
        let set = ParameterSet::<U6, Dyn>::from_mask(&mask).unwrap();
        let x = set.pack(&truth());
        let undetermined = |distances: &[KnownDistance<f64>]| {
            let problem =
                CommonPoints::new(&robot, &ParameterErrors::zero(), set.clone(), &touches)
                    .unwrap()
                    .with_distances(distances)
                    .unwrap();
            let r = LeastSquares::new(&problem).jacobian_factor(&x).unwrap();
            let id = Identifiability::from_factor(&r, touches.len(), DEFAULT_RANK_TOLERANCE);
            let mut names: Vec<std::string::String> = (id.pivots.iter().skip(id.rank))
                .map(|i| std::format!("{}", set.parameters()[*i]))
                .collect();
            names.sort();
            names
        };
        let without = undetermined(&[]);
        let with = undetermined(&GAUGE);
        std::println!("undetermined without the distance {without:?}, with it {with:?}");
        let last_joint = ["da6", "dalpha6", "dd6", "dtheta6"];
        assert_eq!(without.len(), 2 + last_joint.len() + 1, "{without:?}");
        assert_eq!(with.len(), 2 + last_joint.len(), "{with:?}");
        for name in ["dd1", "dtheta1"] {
            assert!(with.iter().any(|n| n == name), "{with:?}");
        }
    }

    /// Contacts of the true robot's ball with three planes (normals along x, y and z through
    /// points near the arm's reach), 16 each: the ball centre on the plane at in-plane offsets
    /// of up to 120 mm, the flange turned by up to 0.5 rad (the numerical inverse kinematics of
    /// the true robot, to 1e-9 mm).
    fn contacts() -> Vec<Touch<f64, U6>> {
        let truth = Kinematics::new(&robot(), &truth()).unwrap();
        let reference = [0.3, -0.4, 0.6, 0.2, 0.9, -0.3];
        let start = truth.forward(&reference).unwrap();
        let settings = NumericalIkSettings {
            position_tolerance_mm: 1e-9,
            rotation_tolerance_rad: 1e-11,
            ..NumericalIkSettings::default()
        };
        let limits = [JointLimits::unlimited(); 6];
        let mut contacts = Vec::new();
        for plane in 0..3usize {
            let (u, v) = ((plane + 1) % 3, (plane + 2) % 3);
            for k in 0..27 {
                let mut offset = Vector3::zeros();
                offset[plane] = [40.0, -60.0, 30.0][plane];
                offset[u] = [-120.0, 0.0, 120.0][k % 3];
                offset[v] = [-100.0, 10.0, 110.0][k / 3 % 3];
                let turn = |i: usize| [-0.6, 0.0, 0.6][(k / 9 + i * (k % 3) + plane) % 3];
                let turned =
                    start.rotation * Rotation3::from_euler_angles(turn(0), turn(1), turn(2));
                let target = Pose::from_parts((start.translation.vector + offset).into(), turned);
                let ik =
                    numerical_inverse_kinematics(&truth, &limits, &target, &reference, &settings)
                        .unwrap();
                contacts.push(Touch::new(&ik.q, plane as u16, 1.0).unwrap());
            }
        }
        contacts
    }

    /// The plane contacts' Jacobian (the normal's turn included) is that of central
    /// differences row by row, with unequal weights, to 1e-7 of its largest entry; and leaving
    /// the turn out (Kaufman's approximation) would miss it by more than 1 %.
    #[test]
    fn the_plane_contacts_jacobian_is_that_of_the_residual() {
        let robot = robot();
        let contacts = contacts();
        let set = identifiable();
        let problem = CommonPoints::new(&robot, &ParameterErrors::zero(), set.clone(), &[])
            .unwrap()
            .with_planes(&contacts)
            .unwrap();
        let robust: Vec<f64> = (0..contacts.len())
            .map(|i| 0.5 + (i % 5) as f64 / 4.0)
            .collect();
        let x = set.pack(&table2::<f64>()) * 0.5;
        let (values, jacobian) = assert_jacobian_of_differences(&problem, &x, &robust);
        assert_eq!(values.len(), contacts.len());
        let largest = jacobian
            .iter()
            .flatten()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        // Kaufman's rows: the same without the turn, n^T G_i.
        let model = problem.kinematics(&x).unwrap();
        let (_, normal, _) = problem.best_plane(&model, 0, &[], &robust).unwrap();
        let (_, mean) =
            (problem.centre_and_jacobian_of(Group::Planes, &model, 0, &[], &robust)).unwrap();
        let (_, twist) = model.parameter_jacobian(problem.set(), &contacts[0].angles);
        let kaufman = (twist.fixed_rows::<3>(0) - mean).tr_mul(&normal) * robust[0].sqrt();
        let missed = (kaufman.iter().zip(&jacobian[0]))
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f64, f64::max);
        assert!(missed > 0.01 * largest, "{missed} against {largest}");
    }

    /// Least squares on plane contacts alone puts every ball centre back on its plane (within
    /// 1e-7 mm) and finds the true errors: three planes of different normals determine what
    /// sockets do; the degrees of freedom are one per contact less three per plane.
    #[test]
    fn least_squares_puts_the_contacts_back_on_their_planes() {
        let robot = robot();
        let contacts = contacts();
        let set = identifiable();
        let problem = CommonPoints::new(&robot, &ParameterErrors::zero(), set.clone(), &[])
            .unwrap()
            .with_planes(&contacts)
            .unwrap();
        let (fit, before, after) = fit_from_zero(&problem, contacts.len());
        std::println!(
            "{} contacts, {} parameters: largest distance from the plane {before:.3} -> {after:.2e} mm, {} iterations",
            contacts.len(),
            set.len(),
            fit.iterations
        );
        assert!(before > 0.1 && after < 1e-7, "{before} {after}");
        assert_eq!(fit.rows, 81 - 3 * 3);
        let (mm, rad) = set
            .largest_differences(&fit.x, &set.pack(&truth()))
            .unwrap();
        assert!(mm < 1e-5 && rad < 1e-8, "{mm} mm, {rad} rad");
    }
}
