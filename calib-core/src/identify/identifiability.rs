//! Identifiability of the identified parameters from a set of measurements: which parameters the
//! data determine, which they cannot determine at all, and which are redundant with others.
//!
//! Works on the scaled Jacobian `J S^-1` (every column scaled to unit norm, so units and lever arms
//! do not matter) through its triangular factor `R` (`J = Q R`, as built by least squares):
//! - the singular values of `R S^-1` give the numerical rank, the condition number and the
//!   observability index O1 of Borm and Menq, `(s_1 s_2 ... s_D)^(1/D) / sqrt(M)` (M poses);
//! - a QR factorisation with column pivoting (largest remaining column first; the earlier
//!   parameter in canonical order on ties) orders the parameters by how much new information each
//!   adds. The first `rank` pivots are determined; every later one is either not identifiable (its
//!   column is numerically zero: it changes no residual) or redundant with the pivots before it
//!   (only a combination with them is determined). [`Identifiability::combination`] names those.

use crate::scalar::Real;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OMatrix, OVector, U1};

/// Relative singular value below which a direction counts as undetermined. In f64 the scaled
/// Jacobian of exactly redundant parameters has values near 1e-15; determined ones stay above
/// about 1e-3 even for poor pose sets.
pub const DEFAULT_RANK_TOLERANCE: f64 = 1e-8;

/// How a parameter is determined by the data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Status {
    /// Determined on its own.
    Identifiable,
    /// Changes no residual: the data say nothing about it.
    NotIdentifiable,
    /// Determined only in a combination with parameters pivoted before it.
    Redundant,
}

/// The identifiability analysis of `D` parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Identifiability<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D> + Allocator<D, U1>,
{
    /// Singular values of the scaled Jacobian, largest first.
    pub singular_values: OVector<T, D>,
    /// Numerical rank.
    pub rank: usize,
    /// Condition number `s_max / s_min` of the scaled Jacobian (infinite if rank-deficient).
    pub condition_number: T,
    /// Observability index O1 (Borm and Menq): geometric mean of the singular values / sqrt(M).
    pub observability: T,
    /// The least determined direction: the unit right singular vector of the smallest singular
    /// value of the scaled Jacobian (one component per parameter, scaled units). An
    /// ill-conditioned pose set leaves the parameters with large components uncertain.
    pub weakest_direction: OVector<T, D>,
    /// Parameter indices in pivot order: the first `rank` are determined.
    pub pivots: OVector<usize, D>,
    /// Status of every parameter (set order).
    pub status: OVector<Status, D>,
    /// Pivoted triangular factor of the scaled Jacobian (columns in pivot order).
    pivoted: OMatrix<T, D, D>,
}

impl<T: Real, D: Dim> Identifiability<T, D>
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    /// Analyses the triangular factor `r` of the (unscaled) Jacobian of `poses` measurements.
    pub fn from_factor(r: &OMatrix<T, D, D>, poses: usize, tolerance: T) -> Self {
        // Scale every column to unit norm. A column that is zero up to rounding (relative to the
        // largest column) is set to zero: scaling it would blow rounding noise up to a unit column.
        let mut scaled = r.clone();
        let (dim, _) = r.shape_generic();
        let d = dim.value();
        let largest_column = r
            .column_iter()
            .map(|c| c.norm())
            .fold(T::zero(), |a, b| a.max(b));
        for mut column in scaled.column_iter_mut() {
            let norm = column.norm();
            if norm > tolerance * largest_column {
                column /= norm;
            } else {
                column.fill(T::zero());
            }
        }
        let (values, vectors) = singular_values_and_vectors(&scaled);
        let weakest = (0..d).fold(0, |best, i| match (values.get(i), values.get(best)) {
            (Some(v), Some(b)) if v < b => i,
            _ => best,
        });
        let weakest_direction = vectors.column(weakest).into_owned();
        let mut sorted = values;
        sorted
            .as_mut_slice()
            .sort_unstable_by(|a, b| b.partial_cmp(a).unwrap_or(core::cmp::Ordering::Equal));
        let largest = sorted.iter().copied().fold(T::zero(), |a, b| a.max(b));
        let rank = sorted.iter().filter(|s| **s > tolerance * largest).count();
        let smallest = sorted.iter().copied().fold(largest, |a, b| a.min(b));
        let condition_number = if rank == d && smallest > T::zero() {
            largest / smallest
        } else {
            T::of(f64::INFINITY)
        };
        let log_mean = sorted
            .iter()
            .map(|s| s.max(T::of(f64::MIN_POSITIVE)).ln())
            .fold(T::zero(), |a, b| a + b)
            / T::of(d as f64);
        // The geometric mean is 0 as soon as one direction is undetermined.
        let observability = if rank == d {
            log_mean.exp() / T::of(poses.max(1) as f64).sqrt()
        } else {
            T::zero()
        };

        let (pivots, pivoted) = pivoted_qr(&scaled);
        let mut status = OVector::<Status, D>::from_element_generic(dim, U1, Status::Identifiable);
        for index in pivots.iter().skip(rank) {
            // The remaining norm of its pivoted column says whether it has any effect at all.
            let column_norm = scaled.column(*index).norm();
            if let Some(s) = status.get_mut(*index) {
                *s = if column_norm <= tolerance {
                    Status::NotIdentifiable
                } else {
                    Status::Redundant
                };
            }
        }
        Self {
            singular_values: sorted,
            weakest_direction,
            rank,
            condition_number,
            observability,
            pivots,
            status,
            pivoted,
        }
    }

    /// For a redundant parameter p: the coefficients `c` (one per parameter, zero for those not
    /// involved) such that its scaled column equals `sum_j c_j column_j` over the determined
    /// pivots: changing p by `delta` (scaled units) is indistinguishable from changing every
    /// determined `x_j` by `c_j delta`. Entries below `threshold` in magnitude are set to zero.
    /// `None` for a determined parameter.
    pub fn combination(&self, parameter: usize, threshold: T) -> Option<OVector<T, D>> {
        let position = self.pivots.iter().position(|p| *p == parameter)?;
        if position < self.rank {
            return None;
        }
        // Solve R11 c = r12 for the pivoted column at `position`.
        let dim = self.weakest_direction.shape_generic().0;
        let mut c = OVector::<T, D>::zeros_generic(dim, U1);
        for i in (0..self.rank).rev() {
            let mut value = self
                .pivoted
                .get((i, position))
                .copied()
                .unwrap_or_else(T::zero);
            for j in (i + 1)..self.rank {
                let rij = self.pivoted.get((i, j)).copied().unwrap_or_else(T::zero);
                value -= rij * c.get(j).copied().unwrap_or_else(T::zero);
            }
            let rii = self.pivoted.get((i, i)).copied().unwrap_or_else(T::one);
            if let Some(ci) = c.get_mut(i) {
                *ci = value / rii;
            }
        }
        let mut out = OVector::<T, D>::zeros_generic(dim, U1);
        for (ci, index) in c.iter().zip(self.pivots.iter()).take(self.rank) {
            if ci.abs() >= threshold
                && let Some(o) = out.get_mut(*index)
            {
                *o = *ci;
            }
        }
        Some(out)
    }
}

/// Singular values and right singular vectors of a square matrix by one-sided Jacobi rotations
/// (Hestenes): columns are rotated pairwise until mutually orthogonal; their norms are then the
/// singular values, with high relative accuracy, and the accumulated rotations `V` (with
/// `A V = U S`) hold the right singular vectors in the same column order. At most 64 sweeps, so it
/// ends on any input. (nalgebra's SVD needs dimension arithmetic, `DimMin` and `DimSub`, beyond
/// the bounds the core's algorithms carry for `D`.)
fn singular_values_and_vectors<T: Real, D: Dim>(
    a: &OMatrix<T, D, D>,
) -> (OVector<T, D>, OMatrix<T, D, D>)
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let mut u = a.clone();
    let (dim, _) = a.shape_generic();
    let d = dim.value();
    let mut v = OMatrix::<T, D, D>::identity_generic(dim, dim);
    let epsilon = T::default_epsilon();
    for _sweep in 0..64 {
        let mut rotated = false;
        for p in 0..d {
            for q in (p + 1)..d {
                let (alpha, beta, gamma) = {
                    let cp = u.column(p);
                    let cq = u.column(q);
                    (cp.norm_squared(), cq.norm_squared(), cp.dot(&cq))
                };
                if gamma.abs() <= epsilon * (alpha * beta).sqrt() || gamma == T::zero() {
                    continue;
                }
                rotated = true;
                let zeta = (beta - alpha) / (T::of(2.0) * gamma);
                let sign = if zeta >= T::zero() {
                    T::one()
                } else {
                    -T::one()
                };
                let t = sign / (zeta.abs() + T::one().hypot(zeta));
                let c = T::one() / T::one().hypot(t);
                let s = c * t;
                rotate_columns(&mut u, p, q, c, s);
                rotate_columns(&mut v, p, q, c, s);
            }
        }
        if !rotated {
            break;
        }
    }
    let values = OVector::from_iterator_generic(dim, U1, u.column_iter().map(|c| c.norm()));
    (values, v)
}

/// Columns `p, q` of `m` replaced by `c p - s q` and `s p + c q`.
fn rotate_columns<T: Real, D: Dim>(m: &mut OMatrix<T, D, D>, p: usize, q: usize, c: T, s: T)
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    for i in 0..m.nrows() {
        let (Some(mp), Some(mq)) = (m.get((i, p)).copied(), m.get((i, q)).copied()) else {
            continue;
        };
        if let Some(x) = m.get_mut((i, p)) {
            *x = c * mp - s * mq;
        }
        if let Some(x) = m.get_mut((i, q)) {
            *x = s * mp + c * mq;
        }
    }
}

/// Householder QR with column pivoting of a square matrix: the pivot order and the triangular
/// factor with its columns in that order.
fn pivoted_qr<T: Real, D: Dim>(a: &OMatrix<T, D, D>) -> (OVector<usize, D>, OMatrix<T, D, D>)
where
    DefaultAllocator: Allocator<D> + Allocator<D, D>,
{
    let mut m = a.clone();
    let (dim, _) = a.shape_generic();
    let d = dim.value();
    let mut pivots = OVector::<usize, D>::from_iterator_generic(dim, U1, 0..d);
    // One Householder vector, reused for every column.
    let mut v = OVector::<T, D>::zeros_generic(dim, U1);
    for k in 0..d {
        // Column with the largest remaining norm (rows k..); first on ties.
        let remaining = |m: &OMatrix<T, D, D>, j: usize| -> T {
            (k..d)
                .map(|i| m.get((i, j)).copied().unwrap_or_else(T::zero))
                .map(|v| v * v)
                .fold(T::zero(), |s, v| s + v)
        };
        let mut best = k;
        let mut best_norm = remaining(&m, k);
        for j in (k + 1)..d {
            let n = remaining(&m, j);
            if n > best_norm {
                best = j;
                best_norm = n;
            }
        }
        if best != k {
            m.swap_columns(k, best);
            pivots.as_mut_slice().swap(k, best);
        }
        // Householder reflection zeroing rows k+1.. of column k.
        let norm = best_norm.sqrt();
        if norm == T::zero() {
            continue;
        }
        let akk = m.get((k, k)).copied().unwrap_or_else(T::zero);
        let alpha = if akk > T::zero() { -norm } else { norm };
        v.fill(T::zero());
        for i in k..d {
            if let (Some(vi), Some(mi)) = (v.get_mut(i), m.get((i, k))) {
                *vi = *mi;
            }
        }
        if let Some(vk) = v.get_mut(k) {
            *vk -= alpha;
        }
        let vnorm2 = v.norm_squared();
        if vnorm2 == T::zero() {
            continue;
        }
        for j in k..d {
            let dot = (k..d)
                .map(|i| {
                    v.get(i).copied().unwrap_or_else(T::zero)
                        * m.get((i, j)).copied().unwrap_or_else(T::zero)
                })
                .fold(T::zero(), |s, x| s + x);
            let factor = T::of(2.0) * dot / vnorm2;
            for i in k..d {
                let vi = v.get(i).copied().unwrap_or_else(T::zero);
                if let Some(mij) = m.get_mut((i, j)) {
                    *mij -= factor * vi;
                }
            }
        }
    }
    (pivots, m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::paper::{er10l_c10, paper_measurements};
    use crate::model::parameters::{ParameterErrors, ParameterMask, ParameterSet};
    use crate::{LeastSquares, Problem};
    use nalgebra::U6;
    use nalgebra::{U24, U30};
    extern crate std;
    use std::string::{String, ToString};
    use std::vec::Vec;

    fn analyse(position_only: bool) -> (Identifiability<f64, U24>, ParameterSet<U6, U24>) {
        let robot = er10l_c10::<f64>();
        let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
        let mut data = paper_measurements::<f64>(1);
        let mut list: Vec<_> = data.as_slice().to_vec();
        if position_only {
            for m in &mut list {
                m.rotation = None;
            }
        }
        data = crate::identify::objective::MeasurementSet::new();
        for m in list {
            data.push(m).unwrap();
        }
        let problem =
            Problem::new(&robot, &ParameterErrors::zero(), set, data.as_slice(), 1e6).unwrap();
        let least_squares = LeastSquares::new(&problem);
        let r = least_squares
            .jacobian_factor(&nalgebra::SVector::zeros())
            .unwrap();
        (
            Identifiability::from_factor(&r, 32, DEFAULT_RANK_TOLERANCE),
            set,
        )
    }

    fn names(
        set: &ParameterSet<U6, U24>,
        id: &Identifiability<f64, U24>,
        status: Status,
    ) -> Vec<String> {
        set.parameters()
            .iter()
            .zip(id.status.iter())
            .filter(|(_, s)| **s == status)
            .map(|(p, _)| p.to_string())
            .collect()
    }

    #[test]
    fn full_poses_determine_all_24_parameters() {
        let (id, _) = analyse(false);
        std::println!(
            "full pose: rank {}, condition {:.3}, O1 {:.4e}",
            id.rank,
            id.condition_number,
            id.observability
        );
        assert_eq!(id.rank, 24);
        assert!(
            id.condition_number > 1.0 && id.condition_number < 20.0,
            "{}",
            id.condition_number
        );
        assert!(id.status.iter().all(|s| *s == Status::Identifiable));
    }

    #[test]
    fn position_only_data_has_rank_20_with_the_expected_gaps() {
        let (id, set) = analyse(true);
        std::println!(
            "position only: rank {}, singular values {:?}",
            id.rank,
            id.singular_values.as_slice()
        );
        assert_eq!(id.rank, 20);
        assert_eq!(
            names(&set, &id, Status::NotIdentifiable),
            ["dalpha6", "dtheta6"]
        );
        let redundant = names(&set, &id, Status::Redundant);
        assert_eq!(redundant.len(), 2, "{redundant:?}");
        // One of each pair (dd5, dalpha5) and (da5, dtheta5) is redundant with the other.
        let pairs = [("dd5", "dalpha5"), ("da5", "dtheta5")];
        for (a, b) in pairs {
            let (dropped, kept) = if redundant.iter().any(|r| r == a) {
                (a, b)
            } else {
                (b, a)
            };
            assert!(redundant.iter().any(|r| r == dropped), "{redundant:?}");
            let index = set
                .parameters()
                .iter()
                .position(|p| p.to_string() == dropped)
                .unwrap();
            let partner = set
                .parameters()
                .iter()
                .position(|p| p.to_string() == kept)
                .unwrap();
            let c = id.combination(index, 1e-6).unwrap();
            assert!(c[partner].abs() > 0.1, "{dropped} with {kept}: {c}");
        }
    }

    #[test]
    fn with_the_base_frame_identified_dtheta1_and_dd1_are_redundant() {
        use crate::model::parameters::{FrameParameter, Parameter};
        let robot = er10l_c10::<f64>();
        let mut mask = ParameterMask::default_for(&robot);
        for kind in FrameParameter::ALL {
            mask.set(Parameter::Base(kind), true);
        }
        let set = ParameterSet::<U6, U30>::from_mask(&mask).unwrap();
        let data = paper_measurements::<f64>(1);
        let problem =
            Problem::new(&robot, &ParameterErrors::zero(), set, data.as_slice(), 1e6).unwrap();
        let least_squares = LeastSquares::new(&problem);
        let id = Identifiability::from_factor(
            &least_squares
                .jacobian_factor(&nalgebra::SVector::zeros())
                .unwrap(),
            32,
            DEFAULT_RANK_TOLERANCE,
        );
        assert_eq!(id.rank, 28);
        let undetermined: Vec<String> = set
            .parameters()
            .iter()
            .zip(id.status.iter())
            .filter(|(_, s)| **s != Status::Identifiable)
            .map(|(p, _)| p.to_string())
            .collect();
        // Pivoting keeps the earlier parameter of a tie: the joint terms come first in canonical
        // order, so the base's z translation and z rotation are the ones reported.
        std::println!("with base: undetermined {undetermined:?}");
        assert_eq!(undetermined.len(), 2);
        let pairs = [("dd1", "base_tz"), ("dtheta1", "base_rz")];
        for (joint, base) in pairs {
            assert!(
                undetermined.iter().any(|u| u == joint || u == base),
                "{undetermined:?}"
            );
        }
    }

    #[test]
    fn jacobi_singular_values_of_a_known_matrix() {
        // Upper triangular with known singular values: diag(3, 2) rotated.
        let a = nalgebra::Matrix2::new(3.0f64, 0.0, 0.0, 2.0);
        let rot = nalgebra::Matrix2::new(0.6, -0.8, 0.8, 0.6);
        let m = rot * a * rot.transpose();
        let (values, vectors) = singular_values_and_vectors(&m);
        let mut s = values.as_slice().to_vec();
        s.sort_by(|x, y| y.partial_cmp(x).unwrap());
        assert!(
            (s[0] - 3.0).abs() < 1e-14 && (s[1] - 2.0).abs() < 1e-14,
            "{s:?}"
        );
        // Right singular vectors: orthonormal, |M v_i| = s_i, and the one of 2 is the rotation's
        // second column up to sign.
        assert!(
            (vectors.transpose() * vectors - nalgebra::Matrix2::identity())
                .abs()
                .max()
                < 1e-14
        );
        for i in 0..2 {
            assert!(((m * vectors.column(i)).norm() - values[i]).abs() < 1e-14);
        }
        let i = if values[0] < values[1] { 0 } else { 1 };
        let v = vectors.column(i);
        assert!((v[0] * 0.6 + v[1] * 0.8).abs() < 1e-14, "{v:?}"); // orthogonal to (0.6, 0.8)
    }
}
