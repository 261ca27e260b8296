//! The Cholesky factorisation `A = L L^T` of a small symmetric positive-definite matrix of fixed
//! size, and the solve of `A x = b` with it: the damped least-squares step of on-line
//! compensation (`controller::compensate::solve_joints`, a 6 x 6 system per iteration).
//!
//! Why not nalgebra's `Cholesky`: on the controller the compensation's cost and the firmware's
//! flash depend on how this small factorisation is compiled, and nalgebra's took libm's software
//! `sqrtf` and was inlined or not as LLVM's inlining threshold decided. Here the factorisation is
//! one copy out of line (the two factorisations of an iteration share it), the solve is left to
//! the inliner, and the square roots are the FPU's ([`Real::sqrt_ieee`]). The operations and
//! their order are nalgebra's (`Cholesky::new`, then `solve`: forward substitution by columns,
//! back substitution by dot products summed from zero in row order), and both square roots are
//! correctly rounded, so the bits are nalgebra's (test
//! `factor_and_solve_equal_nalgebra_bit_for_bit`).

use nalgebra::{SMatrix, SVector};

use crate::scalar::Real;

/// The lower-triangular factor `L` of `A = L L^T` (only the entries on and below the diagonal
/// are meaningful).
#[derive(Clone, Copy, Debug)]
pub struct Factor<T, const D: usize> {
    /// Column-major: `columns[c][r]` is `L[(r, c)]`, as in nalgebra's storage.
    columns: [[T; D]; D],
}

/// Factors `a` (only its lower triangle is read). `None` when a pivot is zero, negative or NaN:
/// `a` is not positive definite (as nalgebra's `cholesky()`).
#[inline(never)] // one copy for both factorisations of a compensation step (controller flash)
pub fn factor<T: Real, const D: usize>(a: &SMatrix<T, D, D>) -> Option<Factor<T, D>> {
    let mut l = a.data.0;
    for j in 0..D {
        for k in 0..j {
            // Column j from row j down, minus L[(j, k)] times column k (nalgebra's `axpy`).
            let (left, right) = l.split_at_mut(j);
            let (Some(column_k), Some(column_j)) = (left.get(k), right.first_mut()) else {
                return None;
            };
            let minus_factor = -*column_k.get(j)?;
            let (Some(ys), Some(xs)) = (column_j.get_mut(j..), column_k.get(j..)) else {
                return None;
            };
            for (y, x) in ys.iter_mut().zip(xs) {
                *y = minus_factor * *x + *y;
            }
        }
        let column = l.get_mut(j)?;
        let diagonal = *column.get(j)?;
        // nalgebra's `try_sqrt` takes the root of `x >= 0` only; a zero pivot is refused first.
        #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must be refused as well
        if diagonal == T::zero() || !(diagonal >= T::zero()) {
            return None;
        }
        let root = diagonal.sqrt_ieee();
        let (above, below) = column.split_at_mut(j + 1);
        *above.last_mut()? = root;
        for v in below {
            *v /= root;
        }
    }
    Some(Factor { columns: l })
}

impl<T: Real, const D: usize> Factor<T, D> {
    /// The product of the diagonal of `L`, first to last: `sqrt(det A)`.
    #[inline(always)]
    pub fn diagonal_product(&self) -> T {
        let mut product = T::one();
        for (j, column) in self.columns.iter().enumerate() {
            if let Some(d) = column.get(j) {
                product *= *d;
            }
        }
        product
    }

    /// The solution `x` of `A x = b`: `L y = b` forward, then `L^T x = y` backward.
    #[inline]
    pub fn solve(&self, b: &SVector<T, D>) -> SVector<T, D> {
        let [mut x] = b.data.0;
        let l = &self.columns;
        // Forward, by columns: x_i /= L_ii, then the rows below minus x_i times column i.
        for i in 0..D {
            let (Some(column), Some(xi)) = (l.get(i), x.get_mut(i)) else {
                continue;
            };
            let Some(diagonal) = column.get(i) else {
                continue;
            };
            let coefficient = *xi / *diagonal;
            *xi = coefficient;
            let minus_coefficient = -coefficient;
            for k in i + 1..D {
                if let (Some(xk), Some(lk)) = (x.get_mut(k), column.get(k)) {
                    *xk = minus_coefficient * *lk + *xk;
                }
            }
        }
        // Backward, by dot products of column i below the diagonal, summed from zero.
        for i in (0..D).rev() {
            let Some(column) = l.get(i) else {
                continue;
            };
            let mut dot = T::zero();
            for k in i + 1..D {
                if let (Some(lk), Some(xk)) = (column.get(k), x.get(k)) {
                    dot += *lk * *xk;
                }
            }
            if let (Some(diagonal), Some(xi)) = (column.get(i), x.get_mut(i)) {
                *xi = (*xi - dot) / *diagonal;
            }
        }
        SVector::from(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix6, Vector6};
    use rand_core::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// `J J^T + lambda^2 I` of a random 6 x 7 Jacobian-like matrix, as the compensation forms it.
    fn damped_gram<T: Real>(rng: &mut Xoshiro256PlusPlus, lambda: f64) -> (Matrix6<T>, Vector6<T>) {
        let mut unit = || T::of(T::unit_from_bits(rng.next_u64()).to_f64() * 2.0 - 1.0);
        let j = SMatrix::<T, 6, 7>::from_fn(|_, _| unit());
        let b = Vector6::from_fn(|_, _| unit());
        let a = j * j.transpose() + Matrix6::identity() * T::of(lambda * lambda);
        (a, b)
    }

    fn equal_nalgebra<T: Real>(seed: u64) {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        for case in 0..2000 {
            let lambda = [0.0, 1e-3, 0.1, 1.0][case % 4];
            let (a, b) = damped_gram::<T>(&mut rng, lambda);
            let ours = factor(&a).expect("positive definite");
            let theirs = a.cholesky().expect("positive definite");
            let l = theirs.l_dirty();
            for c in 0..6 {
                for r in c..6 {
                    assert_eq!(ours.columns[c][r], l[(r, c)], "L[({r}, {c})], case {case}");
                }
            }
            let product = l.diagonal().iter().fold(T::one(), |p, d| p * *d);
            assert_eq!(ours.diagonal_product(), product);
            assert_eq!(ours.solve(&b), theirs.solve(&b), "case {case}");
        }
    }

    #[test]
    fn factor_and_solve_equal_nalgebra_bit_for_bit() {
        equal_nalgebra::<f64>(1);
        equal_nalgebra::<f32>(2);
    }

    #[test]
    fn solves_a_known_system() {
        // A = L L^T with L = [[2, 0], [1, 3]]: A = [[4, 2], [2, 10]]; A x = b for x = (1, -2).
        let a = SMatrix::<f64, 2, 2>::new(4.0, 2.0, 2.0, 10.0);
        let f = factor(&a).unwrap();
        // The upper triangle keeps A's entry, as nalgebra's `l_dirty`.
        assert_eq!(f.columns, [[2.0, 1.0], [2.0, 3.0]]);
        assert_eq!(f.diagonal_product(), 6.0); // sqrt(det A) = sqrt(36)
        let x = f.solve(&SVector::<f64, 2>::new(0.0, -18.0));
        assert_eq!(x, SVector::<f64, 2>::new(1.0, -2.0));
    }

    #[test]
    fn refuses_what_is_not_positive_definite() {
        let singular = SMatrix::<f32, 2, 2>::new(1.0, 1.0, 1.0, 1.0);
        assert!(factor(&singular).is_none());
        let indefinite = SMatrix::<f32, 2, 2>::new(1.0, 2.0, 2.0, 1.0);
        assert!(factor(&indefinite).is_none());
        let nan = SMatrix::<f32, 2, 2>::new(f32::NAN, 0.0, 0.0, 1.0);
        assert!(factor(&nan).is_none());
        assert!(singular.cholesky().is_none() && indefinite.cholesky().is_none());
    }
}
