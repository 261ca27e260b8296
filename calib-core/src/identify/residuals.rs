//! What a least-squares fit minimises, by kind of measurement: a measurement kind gives its
//! residual rows and their Jacobian with respect to the identified parameters, and the residual
//! norm of each measurement (for robust weights and outliers). [`LeastSquares`] is generic over
//! it, so a new kind of measurement is a new implementation of [`Residuals`] and nothing in the
//! solver changes; a controller that fits poses only links the pose kind alone.
//!
//! The kinds:
//!
//! - measured poses ([`Problem`]): per pose `[dp; sqrt(k) dr]` (mm; 3 rows for a position-only
//!   pose), the pose error of docs/ARCHITECTURE.md, each row scaled by `sqrt(weight)`;
//! - common points ([`crate::identify::common_point::CommonPoints`]): a point of the tool (a
//!   ball) held at one unknown point (a socket) from several configurations, its rows the
//!   distances of each predicted point from the group's mean;
//! - two kinds in one fit ([`Stacked`]): the rows of the first, then those of the second, over
//!   one parameter vector (tracker positions and touches sharing the joints' parameters).
//!
//! [`LeastSquares`]: crate::identify::lm::LeastSquares

use crate::identify::Problem;
use crate::kinematics::pose_error::pose_error_jacobian;
use crate::model::JointCount;
use crate::model::parameters::ShapeError;
use crate::scalar::Real;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OVector, U6};

/// A kind of measurement as least squares sees it: residual rows, their Jacobian, and one
/// residual norm per measurement.
///
/// `left_out` marks the measurements a fit leaves out (a cross-validation fold; a shorter mask
/// keeps those past its end); `robust` holds one weight per measurement (empty: all 1). Rows
/// are produced in the same order on every call, so that a fit is reproducible to the bit.
pub trait Residuals
where
    DefaultAllocator: Allocator<Self::Dim>,
{
    /// The scalar type.
    type Real: Real;
    /// The dimension of the packed parameter vector.
    type Dim: Dim;

    /// The dimension of the packed parameter vector.
    fn dim(&self) -> Self::Dim;

    /// The number of identified parameters.
    fn parameters(&self) -> usize;

    /// Refuses a vector of another length than the parameters.
    fn check_shape(&self, x: &OVector<Self::Real, Self::Dim>) -> Result<(), ShapeError>;

    /// The number of measurements (each has one robust weight and one residual norm).
    fn measurements(&self) -> usize;

    /// The number of residual rows without the measurements `left_out`.
    fn rows(&self, left_out: &[bool]) -> u32;

    /// Calls `row(jacobian_row, residual)` for every residual row at `x` (length checked by the
    /// caller), in a fixed order; the Jacobian row is zero unless `with_jacobian`.
    fn for_each_row(
        &self,
        x: &OVector<Self::Real, Self::Dim>,
        left_out: &[bool],
        robust: &[Self::Real],
        with_jacobian: bool,
        row: impl FnMut(&OVector<Self::Real, Self::Dim>, Self::Real),
    );

    /// Calls `visit(index, norm)` with the unweighted residual norm of every measurement not
    /// `left_out` at `x` (length checked by the caller).
    fn for_each_norm(
        &self,
        x: &OVector<Self::Real, Self::Dim>,
        left_out: &[bool],
        visit: impl FnMut(usize, Self::Real),
    );
}

/// `true` when the measurement `index` is left out by `left_out`.
pub(crate) fn is_left_out(left_out: &[bool], index: usize) -> bool {
    left_out.get(index).copied().unwrap_or(false)
}

/// Measured poses: per pose `[dp; sqrt(k) dr]` (3 rows for a position-only pose), each row scaled
/// by `sqrt(weight * robust_weight)`, its Jacobian the analytic pose-error Jacobian; the norm of a
/// pose is `sqrt(|dp|^2 + k |dr|^2)` (mm; `|dp|` for a position-only pose).
impl<T: Real, N: JointCount, D: Dim> Residuals for Problem<'_, T, N, D>
where
    DefaultAllocator: Allocator<D> + Allocator<U6, D>,
{
    type Real = T;
    type Dim = D;

    fn dim(&self) -> D {
        self.set().dim()
    }

    fn parameters(&self) -> usize {
        self.set().len()
    }

    fn check_shape(&self, x: &OVector<T, D>) -> Result<(), ShapeError> {
        self.set().check_shape(x)
    }

    fn measurements(&self) -> usize {
        Problem::measurements(self).len()
    }

    fn rows(&self, left_out: &[bool]) -> u32 {
        (Problem::measurements(self).iter().enumerate())
            .filter(|(index, _)| !is_left_out(left_out, *index))
            .map(|(_, m)| if m.rotation.is_some() { 6 } else { 3 })
            .sum()
    }

    fn for_each_row(
        &self,
        x: &OVector<T, D>,
        left_out: &[bool],
        robust: &[T],
        with_jacobian: bool,
        mut row: impl FnMut(&OVector<T, D>, T),
    ) {
        let sqrt_k = self.k().sqrt();
        let kinematics = self.kinematics_unchecked(x);
        let zero = self.set().zeros::<T>();
        // One scaled Jacobian row at a time, in one buffer (no allocation per row for `Dyn`).
        let mut scaled = zero.clone();
        for (index, m) in Problem::measurements(self).iter().enumerate() {
            if is_left_out(left_out, index) {
                continue;
            }
            let robust_weight = robust.get(index).copied().unwrap_or_else(T::one);
            let w = (m.weight * robust_weight).sqrt();
            let (error, jacobian) = if with_jacobian {
                let (e, j) = pose_error_jacobian(&kinematics, self.set(), &m.angles, &m.pose());
                (e, Some(j))
            } else {
                (m.error_of(&kinematics.forward_angles(&m.angles)), None)
            };
            let rows = if m.rotation.is_some() { 6 } else { 3 };
            for i in 0..rows {
                let (scale, value) = if i < 3 {
                    (w, error.position.get(i).copied())
                } else {
                    (w * sqrt_k, error.rotation.get(i - 3).copied())
                };
                let value = value.unwrap_or_else(T::zero) * scale;
                match &jacobian {
                    Some(j) => {
                        scaled.tr_copy_from(&j.row(i));
                        scaled *= scale;
                        row(&scaled, value)
                    }
                    None => row(&zero, value),
                }
            }
        }
    }

    fn for_each_norm(&self, x: &OVector<T, D>, left_out: &[bool], mut visit: impl FnMut(usize, T)) {
        let sqrt_k = self.k().sqrt();
        let kinematics = self.kinematics_unchecked(x);
        for (index, m) in Problem::measurements(self).iter().enumerate() {
            if is_left_out(left_out, index) {
                continue;
            }
            let predicted = kinematics.forward_angles(&m.angles);
            let dp2 = (m.position - predicted.translation.vector).norm_squared();
            let norm = match &m.rotation {
                Some(r) => {
                    let angle2 =
                        crate::math::so3::angle_squared_between(r, predicted.rotation.matrix());
                    (dp2 + sqrt_k * sqrt_k * angle2).sqrt()
                }
                None => dp2.sqrt(),
            };
            visit(index, norm);
        }
    }
}

/// Two kinds of measurement in one fit over one parameter vector: the rows (and measurements) of
/// `first`, then those of `second`. Each keeps its own weights; a measurement index past
/// `first`'s measurements is `second`'s, in `left_out` and `robust` as in the norms visited.
/// Both must be built on the same parameter set ([`Stacked::new`] checks their dimensions).
#[derive(Clone, Debug)]
pub struct Stacked<A, B> {
    /// The first kind (its rows come first).
    pub first: A,
    /// The second kind.
    pub second: B,
}

impl<A, B> Stacked<A, B>
where
    A: Residuals,
    B: Residuals<Real = A::Real, Dim = A::Dim>,
    DefaultAllocator: Allocator<A::Dim>,
{
    /// Both kinds in one fit. Refused: their parameter vectors differ in length.
    pub fn new(first: A, second: B) -> Result<Self, ShapeError> {
        if first.parameters() != second.parameters() {
            return Err(ShapeError {
                expected: first.parameters(),
                got: second.parameters(),
            });
        }
        Ok(Self { first, second })
    }

    /// The measurement masks (or weights) of `first` and of `second` in `all`.
    fn split<'m, V>(&self, all: &'m [V]) -> (&'m [V], &'m [V]) {
        let at = self.first.measurements().min(all.len());
        all.split_at_checked(at).unwrap_or((all, &[]))
    }
}

impl<A, B> Residuals for Stacked<A, B>
where
    A: Residuals,
    B: Residuals<Real = A::Real, Dim = A::Dim>,
    DefaultAllocator: Allocator<A::Dim>,
{
    type Real = A::Real;
    type Dim = A::Dim;

    fn dim(&self) -> A::Dim {
        self.first.dim()
    }

    fn parameters(&self) -> usize {
        self.first.parameters()
    }

    fn check_shape(&self, x: &OVector<A::Real, A::Dim>) -> Result<(), ShapeError> {
        self.first.check_shape(x)?;
        self.second.check_shape(x)
    }

    fn measurements(&self) -> usize {
        self.first.measurements() + self.second.measurements()
    }

    fn rows(&self, left_out: &[bool]) -> u32 {
        let (a, b) = self.split(left_out);
        self.first.rows(a).saturating_add(self.second.rows(b))
    }

    fn for_each_row(
        &self,
        x: &OVector<A::Real, A::Dim>,
        left_out: &[bool],
        robust: &[A::Real],
        with_jacobian: bool,
        mut row: impl FnMut(&OVector<A::Real, A::Dim>, A::Real),
    ) {
        let (left_a, left_b) = self.split(left_out);
        let (robust_a, robust_b) = self.split(robust);
        self.first
            .for_each_row(x, left_a, robust_a, with_jacobian, &mut row);
        self.second
            .for_each_row(x, left_b, robust_b, with_jacobian, &mut row);
    }

    fn for_each_norm(
        &self,
        x: &OVector<A::Real, A::Dim>,
        left_out: &[bool],
        mut visit: impl FnMut(usize, A::Real),
    ) {
        let (left_a, left_b) = self.split(left_out);
        let offset = self.first.measurements();
        self.first.for_each_norm(x, left_a, &mut visit);
        self.second
            .for_each_norm(x, left_b, |index, norm| visit(offset + index, norm));
    }
}
