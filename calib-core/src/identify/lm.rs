//! Levenberg-Marquardt least squares on the stacked residual of docs/ARCHITECTURE.md: per pose
//! `[dp; sqrt(k) dr]` (mm; 3 rows for position-only poses), each row scaled by `sqrt(weight)`,
//! with the analytic parameter Jacobian.
//!
//! Each step is solved by a QR factorisation built with Givens rotations, one residual row at a
//! time, so `J^T J` is never formed (it would square the condition number, fatal in f32) and the
//! memory is `O(D^2)` (the triangular factor `R`, `Q^T r` and one row), whatever the number of poses.
//! The damped step solves `[R; sqrt(lambda) S] delta = -[Q^T r; 0]` by `D` more rotations, with
//! Moré's scaling `S` (the largest column norms of `J` seen so far) and Nielsen's update of lambda.
//!
//! Stops on: zero residual, scaled gradient (`max_i |J_i^T r| / (|J_i| |r|) <= gtol`, MINPACK's
//! test), step (`|S delta| <= xtol (|S x| + xtol)`), relative cost change (actual and predicted
//! below `ftol`), or the iteration cap. The result carries `R` at the solution, from which the
//! covariance `sigma^2 (J^T J)^-1 = sigma^2 R^-1 R^-T` and the standard errors follow.

use crate::identify::residuals::Residuals;
use crate::model::parameters::ShapeError;
use crate::scalar::Real;
use core::fmt;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OMatrix, OVector, U1};

/// Settings of a least-squares run.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LmSettings<T> {
    /// Iteration cap (accepted or rejected steps; one Jacobian each at most).
    pub max_iterations: u32,
    /// Relative cost change tolerance.
    pub ftol: T,
    /// Scaled step tolerance.
    pub xtol: T,
    /// Scaled gradient tolerance (cosine between residual and Jacobian columns).
    pub gtol: T,
    /// Initial damping relative to the scaled diagonal (Nielsen's tau).
    pub initial_damping: T,
}

impl<T: Real> Default for LmSettings<T> {
    fn default() -> Self {
        // f32 resolves relative changes only down to about 1e-7.
        let tight = if core::mem::size_of::<T>() >= 8 {
            1e-14
        } else {
            1e-7
        };
        Self {
            max_iterations: 100,
            ftol: T::of(tight),
            xtol: T::of(tight),
            gtol: T::of(tight),
            initial_damping: T::of(1e-3),
        }
    }
}

/// Why least squares stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LmStop {
    /// The residual is exactly zero.
    ZeroResidual,
    /// The scaled gradient fell below `gtol`.
    Gradient,
    /// The scaled step fell below `xtol`.
    Step,
    /// The relative cost change fell below `ftol`.
    CostChange,
    /// The iteration cap was reached.
    MaxIterations,
    /// The damping grew without a cost decrease (rounding floor reached).
    NoProgress,
}

/// Why least squares could not run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum LmError {
    /// Fewer residual rows than parameters.
    TooFewResiduals {
        /// Residual rows.
        rows: u32,
        /// Parameters.
        parameters: u16,
    },
    /// A parameter does not change any residual (its Jacobian column is zero): index in the set.
    UnobservableParameter(u16),
    /// The start point or a residual is not finite.
    NonFinite,
    /// The robust weight buffer does not have one entry per measurement.
    WeightBuffer,
    /// The robust loss scale is not a finite positive number.
    InvalidLossScale,
    /// The start vector's length is not the parameter count of the problem's set (a run-time
    /// `Dyn` dimension can hold any length).
    Shape {
        /// The parameters of the set.
        expected: u16,
        /// The start vector's length.
        got: u32,
    },
}

impl fmt::Display for LmError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooFewResiduals { rows, parameters } => write!(
                f,
                "{rows} residual rows cannot determine {parameters} parameters"
            ),
            Self::UnobservableParameter(i) => {
                write!(f, "parameter {i} of the set does not affect any residual")
            }
            Self::NonFinite => f.write_str("a parameter or residual is not finite"),
            Self::WeightBuffer => f.write_str("the weight buffer needs one entry per measurement"),
            Self::InvalidLossScale => f.write_str("the loss scale must be a finite number > 0"),
            Self::Shape { expected, got } => write!(
                f,
                "the start vector has {got} values; the parameter set has {expected}"
            ),
        }
    }
}

impl core::error::Error for LmError {}

impl From<ShapeError> for LmError {
    fn from(e: ShapeError) -> Self {
        Self::Shape {
            expected: u16::try_from(e.expected).unwrap_or(u16::MAX),
            got: u32::try_from(e.got).unwrap_or(u32::MAX),
        }
    }
}

/// At most this many reweightings of the robust loss.
pub const MAX_REWEIGHTINGS: u32 = 30;

/// Loss applied to each pose's residual norm `sqrt(|dp|^2 + k |dr|^2)` (mm).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Loss<T> {
    /// Plain least squares.
    L2,
    /// Huber: weight 1 up to the scale (mm), `scale / norm` beyond.
    Huber(T),
    /// Cauchy: weight `1 / (1 + (norm / scale)^2)`.
    Cauchy(T),
}

impl<T: Real> Loss<T> {
    /// The IRLS weight of a pose with residual norm `norm` (mm).
    pub fn weight(self, norm: T) -> T {
        match self {
            Self::L2 => T::one(),
            Self::Huber(c) => {
                if norm <= c {
                    T::one()
                } else {
                    c / norm
                }
            }
            Self::Cauchy(c) => {
                let u = norm / c;
                T::one() / (T::one() + u * u)
            }
        }
    }
}

/// The outcome of a robust least-squares run.
#[derive(Clone, Debug, PartialEq)]
pub struct RobustResult<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// The final weighted least-squares run.
    pub result: LmResult<T, D>,
    /// Reweightings done.
    pub reweightings: u32,
    /// Poses whose residual norm exceeds the loss scale at the result.
    pub outliers: u32,
}

/// `Copy` for a fixed dimension (`Const<D>`).
impl<T: Real, D: Dim> Copy for RobustResult<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
    LmResult<T, D>: Copy,
{
}

/// The outcome of a least-squares run.
#[derive(Clone, Debug, PartialEq)]
pub struct LmResult<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// The parameters (mm, rad).
    pub x: OVector<T, D>,
    /// `0.5 |r|^2` at the start.
    pub initial_cost: T,
    /// `0.5 |r|^2` at the result.
    pub cost: T,
    /// Iterations (steps tried).
    pub iterations: u32,
    /// Residual evaluations (with or without Jacobian).
    pub evaluations: u32,
    /// Residual rows.
    pub rows: u32,
    /// Why it stopped.
    pub stop: LmStop,
    /// The triangular factor of `J` at the result (`J = Q R`).
    pub r: OMatrix<T, D, D>,
}

/// `Copy` for a fixed dimension (`Const<D>`).
impl<T: Real, D: Dim> Copy for LmResult<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
    OVector<T, D>: Copy,
    OMatrix<T, D, D>: Copy,
{
}

impl<T: Real, D: Dim> LmResult<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// Residual standard deviation `sqrt(|r|^2 / (m - D))` (mm-equivalent units).
    pub fn sigma(&self) -> T {
        let dof = self
            .rows
            .saturating_sub(u32::try_from(self.x.len()).unwrap_or(u32::MAX));
        if dof == 0 {
            return T::zero();
        }
        (T::of(2.0) * self.cost / T::of(f64::from(dof))).sqrt()
    }

    /// Covariance of the parameters, `sigma^2 (J^T J)^-1 = sigma^2 R^-1 R^-T` (mm^2, mm rad,
    /// rad^2), computed from `R` without forming `J^T J`. `None` if `R` is singular.
    pub fn covariance(&self) -> Option<OMatrix<T, D, D>> {
        let r_inv = self.r_inverse()?;
        let sigma = self.sigma();
        Some(product_by_columns(&r_inv, &r_inv.transpose()) * (sigma * sigma))
    }

    /// Standard error of every parameter, `sigma sqrt(diag((J^T J)^-1))`: `sigma` times the row
    /// norms of `R^-1` (mm, rad). `None` if `R` is singular.
    pub fn standard_errors(&self) -> Option<OVector<T, D>> {
        let r_inv = self.r_inverse()?;
        let sigma = self.sigma();
        Some(OVector::<T, D>::from_iterator_generic(
            r_inv.shape_generic().0,
            U1,
            r_inv.row_iter().map(|row| sigma * row.norm()),
        ))
    }

    /// `R^-1`, or `None` if `R` is singular.
    fn r_inverse(&self) -> Option<OMatrix<T, D, D>> {
        let (rows, columns) = self.r.shape_generic();
        self.r
            .solve_upper_triangular(&OMatrix::<T, D, D>::identity_generic(rows, columns))
    }
}

/// Least squares over the residuals of a kind of measurement ([`Residuals`]: measured poses, a
/// [`Problem`](crate::identify::Problem), or common points): its identified parameters over its measurements.
#[derive(Debug)]
pub struct LeastSquares<'p, R: Residuals>
where
    DefaultAllocator: Allocator<R::Dim>,
{
    problem: &'p R,
    /// `true` at the measurements left out ([`LeastSquares::leaving_out`]); empty: none.
    left_out: &'p [bool],
}

impl<R: Residuals> Clone for LeastSquares<'_, R>
where
    DefaultAllocator: Allocator<R::Dim>,
{
    fn clone(&self) -> Self {
        *self
    }
}

impl<R: Residuals> Copy for LeastSquares<'_, R> where DefaultAllocator: Allocator<R::Dim> {}

/// Triangular factor, `Q^T r` and `|r|^2` of the stacked residual, accumulated row by row.
struct Factor<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// `R` transposed: column `i` holds row `i` of `R`, contiguous in memory, which is what a
    /// rotation updates (so the update is a loop over two slices, vectorised on a PC).
    rt: OMatrix<T, D, D>,
    qtr: OVector<T, D>,
    sum_squares: T,
}

impl<T: Real, D: Dim> Factor<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    fn new(dim: D) -> Self {
        Self {
            rt: OMatrix::zeros_generic(dim, dim),
            qtr: OVector::zeros_generic(dim, U1),
            sum_squares: T::zero(),
        }
    }

    /// The upper triangular factor `R`.
    #[inline(never)] // several call sites: one copy (controller flash)
    fn r(&self) -> OMatrix<T, D, D> {
        self.rt.transpose()
    }

    /// Rotates the row `(a, b)` (Jacobian row and residual) into `R` and `Q^T r`.
    fn add_row(&mut self, mut a: OVector<T, D>, mut b: T) {
        self.sum_squares += b * b;
        for i in 0..self.qtr.len() {
            self.rotate(i, &mut a, &mut b);
        }
    }

    /// [`Factor::add_row`] for each of `rows` in order, with the same operations in the same
    /// order on every entry (so the same bits), but interleaved as a wavefront: row `r` takes
    /// column `i` while row `r + 1` takes column `i - 1`. A row's rotations form one chain
    /// of square roots and divisions (each column's rotation waits for the previous one); the
    /// rows' chains are independent, so a processor that runs instructions out of order
    /// overlaps them.
    fn add_rows(&mut self, rows: &mut [(OVector<T, D>, T)]) {
        for (_, b) in rows.iter() {
            self.sum_squares += *b * *b;
        }
        let d = self.qtr.len();
        for step in 0..(d + rows.len()).saturating_sub(1) {
            for (r, (a, b)) in rows.iter_mut().enumerate() {
                if let Some(i) = step.checked_sub(r).filter(|i| *i < d) {
                    self.rotate(i, a, b);
                }
            }
        }
    }

    /// The Givens rotation of row `(a, b)` against row `i` of `R` that zeroes `a[i]`.
    #[inline(always)]
    fn rotate(&mut self, i: usize, a: &mut OVector<T, D>, b: &mut T) {
        let ai = a.get(i).copied().unwrap_or_else(T::zero);
        if ai == T::zero() {
            return;
        }
        let d = self.qtr.len();
        let (Some(r_row), Some(a_row)) = (
            self.rt.as_mut_slice().get_mut(i * d + i..(i + 1) * d),
            a.as_mut_slice().get_mut(i..),
        ) else {
            return;
        };
        let rii = r_row.first().copied().unwrap_or_else(T::zero);
        let h = rii.hypot(ai);
        let (c, s) = (rii / h, ai / h);
        for (rij, aj) in r_row.iter_mut().zip(a_row.iter_mut()) {
            let (r, a) = (*rij, *aj);
            *rij = c * r + s * a;
            *aj = c * a - s * r;
        }
        if let Some(q) = self.qtr.get_mut(i) {
            let qi = *q;
            *q = c * qi + s * *b;
            *b = c * *b - s * qi;
        }
    }
}

/// Rows rotated into the factor at once ([`Factor::add_rows`]): 8 on a PC, whose processors
/// overlap the rows' rotations; 1 on ARM (the controller's core runs in order: the rows one
/// after the other, [`Factor::add_row`]).
const ROWS_AT_ONCE: usize = if cfg!(target_arch = "arm") { 1 } else { 8 };

/// Rows on their way into a [`Factor`], rotated in [`ROWS_AT_ONCE`] at a time: the same bits as
/// adding them one by one.
struct RowBatch<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    rows: [(OVector<T, D>, T); ROWS_AT_ONCE],
    held: usize,
}

impl<T: Real, D: Dim> RowBatch<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    fn new(dim: D) -> Self {
        Self {
            rows: core::array::from_fn(|_| (OVector::zeros_generic(dim, U1), T::zero())),
            held: 0,
        }
    }

    /// Adds the row `(a, b)`, rotating the batch into `factor` once it is full.
    #[inline(always)]
    fn push(&mut self, factor: &mut Factor<T, D>, a: &OVector<T, D>, b: T) {
        if ROWS_AT_ONCE == 1 {
            factor.add_row(a.clone(), b);
            return;
        }
        if let Some((row, row_b)) = self.rows.get_mut(self.held) {
            row.copy_from(a);
            *row_b = b;
            self.held += 1;
        }
        if self.held == ROWS_AT_ONCE {
            factor.add_rows(&mut self.rows);
            self.held = 0;
        }
    }

    /// Rotates the rows still held into `factor`.
    fn finish(mut self, factor: &mut Factor<T, D>) {
        if ROWS_AT_ONCE == 1 {
            return;
        }
        if let Some(rest) = self.rows.get_mut(..self.held) {
            factor.add_rows(rest);
        }
    }
}

impl<'p, T: Real, D: Dim, R: Residuals<Real = T, Dim = D>> LeastSquares<'p, R>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// Least squares over `problem` (for measured poses, a [`crate::identify::Problem`], whose `k` (mm^2/rad^2)
    /// weights the orientation rows as in eq. (7)).
    pub fn new(problem: &'p R) -> Self {
        Self {
            problem,
            left_out: &[],
        }
    }

    /// The same least squares without the measurements at which `left_out` is `true` (a shorter
    /// mask keeps the measurements past its end): a cross-validation fold over the problem's
    /// measurements without a copy of them. The result has the bits of a problem built on the
    /// other measurements alone; weight buffers and per-measurement outputs keep one entry per
    /// measurement (the left-out measurements' entries are not written).
    pub fn leaving_out(self, left_out: &'p [bool]) -> Self {
        Self { left_out, ..self }
    }

    /// The problem: identified parameters and measurements.
    pub fn problem(&self) -> &'p R {
        self.problem
    }

    /// Number of residual rows (for measured poses: 6 per full pose, 3 per position-only pose).
    pub fn rows(&self) -> u32 {
        self.problem.rows(self.left_out)
    }

    /// Calls `row(jacobian_row, residual)` for every residual row at `x` (see
    /// [`Residuals::for_each_row`]).
    fn for_each_row(
        &self,
        x: &OVector<T, D>,
        robust: &[T],
        with_jacobian: bool,
        row: impl FnMut(&OVector<T, D>, T),
    ) {
        (self.problem).for_each_row(x, self.left_out, robust, with_jacobian, row);
    }

    /// Residual norm of every measurement at `x` (for measured poses `sqrt(|dp|^2 + k |dr|^2)`,
    /// mm; `|dp|` for position-only poses), without weights, into `out` (one entry per
    /// measurement: refused with [`LmError::WeightBuffer`] otherwise, as is an `x` of another
    /// length than the set).
    pub fn pose_residual_norms(&self, x: &OVector<T, D>, out: &mut [T]) -> Result<(), LmError> {
        self.problem.check_shape(x)?;
        if out.len() != self.problem.measurements() {
            return Err(LmError::WeightBuffer);
        }
        self.for_each_pose_norm(x, |index, norm| {
            if let Some(o) = out.get_mut(index) {
                *o = norm;
            }
        });
        Ok(())
    }

    /// Calls `visit(index, norm)` with the residual norm of every measurement at `x` (its length
    /// checked by the caller).
    fn for_each_pose_norm(&self, x: &OVector<T, D>, visit: impl FnMut(usize, T)) {
        self.problem.for_each_norm(x, self.left_out, visit);
    }

    /// `0.5 |r|^2` at `x`; a vector of another length than the set is refused.
    pub fn cost(&self, x: &OVector<T, D>) -> Result<T, LmError> {
        self.problem.check_shape(x)?;
        let mut sum = T::zero();
        self.for_each_row(x, &[], false, |_, r| sum += r * r);
        Ok(sum / T::of(2.0))
    }

    fn weighted_cost(&self, x: &OVector<T, D>, robust: &[T]) -> T {
        let mut sum = T::zero();
        self.for_each_row(x, robust, false, |_, r| sum += r * r);
        sum / T::of(2.0)
    }

    /// The triangular factor `R` of the Jacobian at `x` (`J = Q R`), for the identifiability
    /// analysis; a vector of another length than the set is refused.
    pub fn jacobian_factor(&self, x: &OVector<T, D>) -> Result<OMatrix<T, D, D>, LmError> {
        self.problem.check_shape(x)?;
        Ok(self.factor(x, &[]).r())
    }

    fn factor(&self, x: &OVector<T, D>, robust: &[T]) -> Factor<T, D> {
        let dim = self.problem.dim();
        let mut factor = Factor::new(dim);
        let mut batch = RowBatch::new(dim);
        self.for_each_row(x, robust, true, |a, b| batch.push(&mut factor, a, b));
        batch.finish(&mut factor);
        factor
    }

    /// Runs Levenberg-Marquardt from `x0`.
    pub fn solve(
        &self,
        x0: &OVector<T, D>,
        settings: &LmSettings<T>,
    ) -> Result<LmResult<T, D>, LmError> {
        self.solve_weighted(x0, settings, &[])
    }

    /// Runs Levenberg-Marquardt with a robust loss by iteratively reweighted least squares:
    /// solve, weight every pose by the loss at its residual norm, solve again, until no weight
    /// changes by more than 1e-6 (at most 30 reweightings). `weights` (one per measurement) is the
    /// caller's buffer and holds the final robust weights; poses whose residual norm exceeds the
    /// loss scale are counted as outliers.
    pub fn solve_robust(
        &self,
        x0: &OVector<T, D>,
        settings: &LmSettings<T>,
        loss: Loss<T>,
        weights: &mut [T],
    ) -> Result<RobustResult<T, D>, LmError> {
        if weights.len() != self.problem.measurements() {
            return Err(LmError::WeightBuffer);
        }
        if let Loss::Huber(c) | Loss::Cauchy(c) = loss
            && !(c.finite() && c > T::zero())
        {
            return Err(LmError::InvalidLossScale);
        }
        weights.fill(T::one());
        let mut result = self.solve_weighted(x0, settings, weights)?;
        let mut reweightings = 0;
        if loss != Loss::L2 {
            while reweightings < MAX_REWEIGHTINGS {
                reweightings += 1;
                let mut change = T::zero();
                self.for_each_pose_norm(&result.x, |index, norm| {
                    if let Some(w) = weights.get_mut(index) {
                        let new = loss.weight(norm);
                        change = change.max((new - *w).abs());
                        *w = new;
                    }
                });
                result = self.solve_weighted(&result.x, settings, weights)?;
                if change < T::of(1e-6) {
                    break;
                }
            }
        }
        let mut outliers = 0;
        if let Loss::Huber(c) | Loss::Cauchy(c) = loss {
            self.for_each_pose_norm(&result.x, |_, norm| {
                if norm > c {
                    outliers += 1;
                }
            });
        }
        Ok(RobustResult {
            result,
            reweightings,
            outliers,
        })
    }

    /// The residual rows, after checking that the start has one value per parameter, that they
    /// can determine the parameters and that the start is finite.
    fn check_start(&self, x0: &OVector<T, D>) -> Result<u32, LmError> {
        let parameters = self.problem.parameters();
        self.problem.check_shape(x0)?;
        let rows = self.rows();
        if (rows as usize) < parameters {
            return Err(LmError::TooFewResiduals {
                rows,
                parameters: u16::try_from(parameters).unwrap_or(u16::MAX),
            });
        }
        if !x0.iter().all(|v| v.finite()) {
            return Err(LmError::NonFinite);
        }
        Ok(rows)
    }

    fn solve_weighted(
        &self,
        x0: &OVector<T, D>,
        settings: &LmSettings<T>,
        robust: &[T],
    ) -> Result<LmResult<T, D>, LmError> {
        let rows = self.check_start(x0)?;
        let half = T::of(0.5);
        let mut x = x0.clone();
        let mut factor = self.factor(&x, robust);
        let mut evaluations = 1;
        let mut cost = factor.sum_squares * half;
        if !cost.finite() {
            return Err(LmError::NonFinite);
        }
        let initial_cost = cost;
        let mut r = factor.r();
        let mut scale = column_norms(&r);
        if let Some(i) = scale.iter().position(|s| *s == T::zero()) {
            return Err(LmError::UnobservableParameter(
                u16::try_from(i).unwrap_or(u16::MAX),
            ));
        }
        let mut lambda = settings.initial_damping;
        let mut nu = T::of(2.0);
        let mut iterations = 0;
        let stop = loop {
            if cost == T::zero() {
                break LmStop::ZeroResidual;
            }
            if gradient_cosine(&factor, &r, cost) <= settings.gtol {
                break LmStop::Gradient;
            }
            if iterations >= settings.max_iterations {
                break LmStop::MaxIterations;
            }
            iterations += 1;
            let Some(delta) = damped_step(&factor, &scale, lambda) else {
                break LmStop::NoProgress;
            };
            let scaled_step = delta.component_mul(&scale).norm();
            let scaled_x = x.component_mul(&scale).norm();
            if scaled_step <= settings.xtol * (scaled_x + settings.xtol) {
                break LmStop::Step;
            }
            // Predicted reduction 0.5 (|Q^T r|^2 - |R delta + Q^T r|^2).
            let predicted =
                half * (factor.qtr.norm_squared() - (&r * &delta + &factor.qtr).norm_squared());
            let candidate = &x + &delta;
            let candidate_cost = self.weighted_cost(&candidate, robust);
            evaluations += 1;
            let actual = cost - candidate_cost;
            let rho = if predicted > T::zero() {
                actual / predicted
            } else {
                -T::one()
            };
            if candidate_cost.finite() && rho > T::zero() {
                x = candidate;
                let previous = cost;
                factor = self.factor(&x, robust);
                r = factor.r();
                evaluations += 1;
                cost = factor.sum_squares * half;
                for (s, n) in scale.iter_mut().zip(column_norms(&r).iter()) {
                    *s = s.max(*n);
                }
                let t = T::of(2.0) * rho - T::one();
                lambda *= T::of(1.0 / 3.0).max(T::one() - t * t * t);
                nu = T::of(2.0);
                if actual <= settings.ftol * previous && predicted <= settings.ftol * previous {
                    break LmStop::CostChange;
                }
            } else {
                lambda *= nu;
                nu *= T::of(2.0);
                if !lambda.finite() || lambda > T::of(1e30) {
                    break LmStop::NoProgress;
                }
            }
        };
        Ok(LmResult {
            x,
            initial_cost,
            cost,
            iterations,
            evaluations,
            rows,
            stop,
            r,
        })
    }
}

/// MINPACK's scaled gradient test value `max_i |J_i^T r| / (|J_i| |r|)` at a factor with
/// `0.5 |r|^2 = cost` whose triangular factor is `r`; `J^T r = R^T Q^T r`.
fn gradient_cosine<T: Real, D: Dim>(factor: &Factor<T, D>, r: &OMatrix<T, D, D>, cost: T) -> T
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let gradient = r.transpose() * &factor.qtr;
    let r_norm = (T::of(2.0) * cost).sqrt();
    gradient
        .iter()
        .zip(column_norms(r).iter())
        .map(|(g, n)| {
            if *n > T::zero() {
                g.abs() / (*n * r_norm)
            } else {
                T::zero()
            }
        })
        .fold(T::zero(), |a, b| a.max(b))
}

/// Column norms of `R` (equal to those of `J`, since `Q` is orthogonal).
#[inline(never)] // three call sites: one copy (controller flash)
fn column_norms<T: Real, D: Dim>(r: &OMatrix<T, D, D>) -> OVector<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    OVector::from_iterator_generic(r.shape_generic().1, U1, r.column_iter().map(|c| c.norm()))
}

/// `a b` column by column (`a` times each column of `b`): the order of operations nalgebra uses
/// for fixed sizes, also for `Dyn` (whose products nalgebra hands to a blocked kernel that sums
/// in another order), so that a covariance has the same bits for `Const` and `Dyn`.
pub(crate) fn product_by_columns<T: Real, D: Dim>(
    a: &OMatrix<T, D, D>,
    b: &OMatrix<T, D, D>,
) -> OMatrix<T, D, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let (rows, columns) = b.shape_generic();
    let mut out = OMatrix::<T, D, D>::zeros_generic(rows, columns);
    for (mut column, b_column) in out.column_iter_mut().zip(b.column_iter()) {
        column.gemv(T::one(), a, &b_column, T::zero());
    }
    out
}

/// Solves `[R; sqrt(lambda) S] delta = -[Q^T r; 0]` in the least-squares sense.
fn damped_step<T: Real, D: Dim>(
    factor: &Factor<T, D>,
    scale: &OVector<T, D>,
    lambda: T,
) -> Option<OVector<T, D>>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let mut damped = Factor {
        rt: factor.rt.clone(),
        qtr: factor.qtr.clone(),
        sum_squares: T::zero(),
    };
    let root = lambda.sqrt();
    let dim = scale.shape_generic().0;
    let mut batch = RowBatch::new(dim);
    let mut row = OVector::<T, D>::zeros_generic(dim, U1);
    for (i, s) in scale.iter().enumerate() {
        row.fill(T::zero());
        if let Some(v) = row.get_mut(i) {
            *v = root * *s;
        }
        batch.push(&mut damped, &row, T::zero());
    }
    batch.finish(&mut damped);
    let solution = damped.r().solve_upper_triangular(&damped.qtr)?;
    let delta = -solution;
    delta.iter().all(|v| v.finite()).then_some(delta)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::Problem;
    use crate::identify::objective::Measurement;
    use crate::model::paper::{er10l_c10, paper_measurements, table2};
    use crate::{JointParameter, Parameter, ParameterErrors, ParameterSet};
    use nalgebra::{SMatrix, SVector, U3, U6, U24};
    extern crate std;

    /// LM from the nominal model (zero errors) on the noise-free paper scenario; returns the worst
    /// length (mm) and angle (rad) errors against Table 2 and the result.
    fn recover<T: Real>() -> (f64, f64, LmResult<T, U24>) {
        let robot = er10l_c10::<T>();
        let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
        let data = paper_measurements::<T>(1);
        let problem = Problem::new(
            &robot,
            &ParameterErrors::zero(),
            set,
            data.as_slice(),
            T::of(1e6),
        )
        .unwrap();
        let least_squares = LeastSquares::new(&problem);
        let result = least_squares
            .solve(&SVector::zeros(), &LmSettings::default())
            .unwrap();
        let truth = set.pack(&table2::<T>());
        let (mm, rad) = set.largest_differences(&result.x, &truth).unwrap();
        (mm.to_f64(), rad.to_f64(), result)
    }

    #[test]
    fn recovers_table2_from_nominal_in_f64() {
        let (mm, rad, r) = recover::<f64>();
        extern crate std;
        std::println!(
            "lm f64: {mm:.2e} mm {rad:.2e} rad, {} iterations, {:?}, cost {:.3e} -> {:.3e}",
            r.iterations,
            r.stop,
            r.initial_cost,
            r.cost
        );
        assert!(mm < 1e-6 && rad < 1e-9, "{mm} mm, {rad} rad");
        assert_eq!(r.rows, 32 * 6);
    }

    #[test]
    fn recovers_table2_from_nominal_in_f32() {
        let (mm, rad, r) = recover::<f32>();
        extern crate std;
        std::println!(
            "lm f32: {mm:.2e} mm {rad:.2e} rad, {} iterations, {:?}, cost {:.3e} -> {:.3e}",
            r.iterations,
            r.stop,
            r.initial_cost,
            r.cost
        );
        assert!(mm < 2e-3 && rad < 2e-6, "{mm} mm, {rad} rad");
    }

    #[test]
    fn ipso_then_lm_recovers_table2_in_f32() {
        use crate::identify::ipso::{self, IpsoSettings, SearchSpace, Silent};
        use crate::identify::objective::Objective;
        let robot = er10l_c10::<f32>();
        let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
        let data = paper_measurements::<f32>(1);
        let problem =
            Problem::new(&robot, &ParameterErrors::zero(), set, data.as_slice(), 1e6).unwrap();
        let objective = Objective::new(&problem);
        let mut cost = |x: &SVector<f32, 24>| objective.value(x);
        let swarm = ipso::optimize::<f32, 20, U24>(
            &mut cost,
            &SearchSpace::paper(&set),
            &IpsoSettings::paper(),
            &mut Silent,
        )
        .unwrap();
        let least_squares = LeastSquares::new(&problem);
        let result = least_squares
            .solve(&swarm.best, &LmSettings::default())
            .unwrap();
        let truth = set.pack(&table2::<f32>());
        let (mm, rad) = set.largest_differences(&result.x, &truth).unwrap();
        extern crate std;
        std::println!(
            "ipso+lm f32: {mm:.2e} mm {rad:.2e} rad ({} iterations)",
            result.iterations
        );
        assert!(mm < 2e-3 && rad < 2e-6, "{mm} mm, {rad} rad");
    }

    #[test]
    fn poses_left_out_give_the_bits_of_the_other_poses_alone() {
        let robot = er10l_c10::<f64>();
        let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
        let data = paper_measurements::<f64>(1);
        // Measurement noise (and three gross errors), so that every subset has its own fit.
        let noisy: std::vec::Vec<Measurement<f64, U6>> = data
            .as_slice()
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let mut m = *m;
                let i = i as f64;
                m.position += nalgebra::Vector3::new(0.05 * i.sin(), 0.04 * (2.0 * i).cos(), 0.03);
                if i as usize % 11 == 3 {
                    m.position.x += 2.0;
                }
                m
            })
            .collect();
        let left_out: std::vec::Vec<bool> = (0..noisy.len()).map(|i| i % 5 == 2).collect();
        let kept: std::vec::Vec<_> = noisy
            .iter()
            .zip(&left_out)
            .filter(|(_, l)| !**l)
            .map(|(m, _)| *m)
            .collect();
        let settings = LmSettings::default();
        let loss = Loss::Huber(0.5);
        let all = Problem::new(&robot, &ParameterErrors::zero(), set, &noisy, 1e6).unwrap();
        let alone = Problem::new(&robot, &ParameterErrors::zero(), set, &kept, 1e6).unwrap();
        let mut weights = std::vec![0.0; noisy.len()];
        let masked = LeastSquares::new(&all)
            .leaving_out(&left_out)
            .solve_robust(&SVector::zeros(), &settings, loss, &mut weights)
            .unwrap();
        let mut kept_weights = std::vec![0.0; kept.len()];
        let copied = LeastSquares::new(&alone)
            .solve_robust(&SVector::zeros(), &settings, loss, &mut kept_weights)
            .unwrap();
        assert_eq!(masked.result.x, copied.result.x);
        assert_eq!(masked.result.cost.to_bits(), copied.result.cost.to_bits());
        assert_eq!(masked.result.rows, 6 * kept.len() as u32);
        assert_eq!(masked.outliers, copied.outliers);
        assert!(masked.outliers >= 2, "the gross errors are outliers");
        let masked_kept: std::vec::Vec<f64> = weights
            .iter()
            .zip(&left_out)
            .filter(|(_, l)| !**l)
            .map(|(w, _)| *w)
            .collect();
        assert_eq!(masked_kept, kept_weights);
        // And the whole set fits otherwise.
        let whole = LeastSquares::new(&all)
            .solve(&SVector::zeros(), &settings)
            .unwrap();
        assert_ne!(whole.x, copied.result.x);
    }

    #[test]
    fn covariance_diagonal_is_the_square_of_the_standard_errors() {
        let (_, _, r) = recover::<f64>();
        let mut noisy = r;
        noisy.cost = 0.5 * 0.01 * f64::from(noisy.rows - 24);
        let se = noisy.standard_errors().unwrap();
        let cov = noisy.covariance().unwrap();
        for i in 0..24 {
            assert!((cov[(i, i)] - se[i] * se[i]).abs() <= 1e-12 * cov[(i, i)]);
        }
        assert!((noisy.sigma() - 0.1).abs() < 1e-15);
    }

    #[test]
    fn givens_factor_matches_the_normal_equations() {
        // R^T R = J^T J and R^T Q^T r = J^T r for a small random system.
        let rows = [
            ([1.0, 2.0, 0.0], 1.0),
            ([0.5, -1.0, 3.0], -2.0),
            ([2.0, 0.0, 1.0], 0.5),
            ([-1.0, 1.0, 1.0], 3.0),
        ];
        let mut factor = Factor::<f64, U3>::new(U3);
        let mut jtj = SMatrix::<f64, 3, 3>::zeros();
        let mut jtr = SVector::<f64, 3>::zeros();
        for (a, b) in rows {
            let a = SVector::from(a);
            jtj += a * a.transpose();
            jtr += a * b;
            factor.add_row(a, b);
        }
        assert!((factor.r().transpose() * factor.r() - jtj).abs().max() < 1e-13);
        assert!((factor.r().transpose() * factor.qtr - jtr).abs().max() < 1e-13);
        // Upper triangular: every entry below the diagonal is exactly zero, the diagonal is not.
        for i in 0..3 {
            for j in 0..i {
                assert_eq!(factor.r()[(i, j)], 0.0, "R[({i}, {j})]");
            }
            assert!(factor.r()[(i, i)].abs() > 0.1, "R[({i}, {i})]");
        }
        // |r|^2 is accumulated exactly as the sum of the squared residuals (1 + 4 + 0.25 + 9).
        assert_eq!(factor.sum_squares, 14.25);
    }

    #[test]
    fn rows_at_once_give_the_bits_of_rows_one_by_one() {
        // Dense rows with a few zeros (skipped rotations), added one by one and in batches of
        // 1 to 5 (a batch of 5 runs its wavefront past the last column).
        let rows: std::vec::Vec<(SVector<f64, 6>, f64)> = (0..13)
            .map(|r| {
                let a = SVector::<f64, 6>::from_fn(|j, _| {
                    if (r + j) % 5 == 3 {
                        0.0
                    } else {
                        ((r * 6 + j) as f64 * 1.618_034).sin() * 10f64.powi((j % 3) as i32)
                    }
                });
                (a, (r as f64 * 0.7).cos())
            })
            .collect();
        let mut one_by_one = Factor::<f64, U6>::new(U6);
        for (a, b) in &rows {
            one_by_one.add_row(*a, *b);
        }
        for size in 1..=5 {
            let mut batched = Factor::<f64, U6>::new(U6);
            for chunk in rows.chunks(size) {
                let mut chunk = chunk.to_vec();
                batched.add_rows(&mut chunk);
            }
            let bits = |f: &Factor<f64, U6>| {
                let mut v: std::vec::Vec<u64> = f.rt.iter().map(|x| x.to_bits()).collect();
                v.extend(f.qtr.iter().map(|x| x.to_bits()));
                v.push(f.sum_squares.to_bits());
                v
            };
            assert_eq!(bits(&batched), bits(&one_by_one), "batches of {size}");
        }
        let mut batch = RowBatch::new(U6);
        let mut pushed = Factor::<f64, U6>::new(U6);
        for (a, b) in &rows {
            batch.push(&mut pushed, a, *b);
        }
        batch.finish(&mut pushed);
        assert_eq!(pushed.rt, one_by_one.rt);
        assert_eq!(pushed.qtr, one_by_one.qtr);
    }

    #[test]
    fn too_few_poses_and_unobservable_parameters_are_errors() {
        let robot = er10l_c10::<f64>();
        let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
        let data = paper_measurements::<f64>(1);
        let three = &data.as_slice()[..3];
        let problem = Problem::new(&robot, &ParameterErrors::zero(), set, three, 1e6).unwrap();
        let least_squares = LeastSquares::new(&problem);
        assert_eq!(
            least_squares.solve(&SVector::zeros(), &LmSettings::default()),
            Err(LmError::TooFewResiduals {
                rows: 18,
                parameters: 24
            })
        );
        // With position-only data, dalpha6 (a rotation about x6 after joint 6's last
        // translation) moves no measured point: its Jacobian column is exactly zero, and it is
        // the first such parameter in canonical order (dtheta6 is the other one).
        let positions: std::vec::Vec<_> = data
            .as_slice()
            .iter()
            .map(|m| Measurement {
                rotation: None,
                ..*m
            })
            .collect();
        let problem = Problem::new(&robot, &ParameterErrors::zero(), set, &positions, 1e6).unwrap();
        let dalpha6 = Parameter::Joint {
            joint: 6,
            kind: JointParameter::Alpha,
        };
        assert_eq!(set.index_of(dalpha6), Some(16));
        assert_eq!(
            LeastSquares::new(&problem).solve(&SVector::zeros(), &LmSettings::default()),
            Err(LmError::UnobservableParameter(16))
        );
    }
}
