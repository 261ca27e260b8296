//! The joint count as a nalgebra dimension, like the parameter count.
//!
//! A controller knows its robot when it is built: its joint count is `Const<N>` and every
//! per-joint table is a plain array `[X; N]` (sizes, and so the code, fixed at compile time). A
//! host learns the count from a robot file at run time: its count is [`nalgebra::Dyn`] and its
//! tables are [`JointVec`]s, inline arrays of capacity [`MAX_JOINTS`] with a run-time length, so
//! that the host compiles every algorithm once and still never touches the heap inside an
//! objective evaluation.

use crate::scalar::Loggable;
use crate::scalar::Real;
use core::fmt::Debug;
use nalgebra::{Const, Dim, Dyn, Matrix6, SMatrix, Vector6};

/// The most joints a run-time joint count ([`Dyn`]) holds.
pub const MAX_JOINTS: usize = 9;

/// What a per-joint table holds: plain copyable values (that the controller's logs can print).
pub trait Element: Copy + PartialEq + Debug + Loggable {}
impl<X: Copy + PartialEq + Debug + Loggable> Element for X {}

/// A table of one value per joint, joint 1 first: `[X; N]` for `Const<N>`, [`JointVec`] for
/// [`Dyn`].
pub trait JointTable<X: Element>: Element {
    /// The values, joint 1 first.
    fn as_slice(&self) -> &[X];
    /// The values, joint 1 first, to change.
    fn as_mut_slice(&mut self) -> &mut [X];

    /// The values, joint 1 first (as a slice's `iter`; an array's own method where the count
    /// is fixed).
    #[inline(always)]
    fn iter(&self) -> core::slice::Iter<'_, X> {
        self.as_slice().iter()
    }

    /// The values, joint 1 first, to change (as a slice's `iter_mut`).
    #[inline(always)]
    fn iter_mut(&mut self) -> core::slice::IterMut<'_, X> {
        self.as_mut_slice().iter_mut()
    }

    /// The joint count.
    #[inline(always)]
    fn len(&self) -> usize {
        self.as_slice().len()
    }

    /// `true` for a table of no joint.
    #[inline(always)]
    fn is_empty(&self) -> bool {
        self.as_slice().is_empty()
    }

    /// Sets every joint's value to `value`.
    #[inline(always)]
    fn fill(&mut self, value: X) {
        self.as_mut_slice().fill(value);
    }
}

impl<X: Element, const N: usize> JointTable<X> for [X; N] {
    #[inline(always)]
    fn as_slice(&self) -> &[X] {
        self
    }
    #[inline(always)]
    fn as_mut_slice(&mut self) -> &mut [X] {
        self
    }
}

/// The joint count of a robot: `Const<N>` (a controller) or [`Dyn`] (a host, at most
/// [`MAX_JOINTS`]).
pub trait JointCount: Dim + Copy + PartialEq + Debug {
    /// A table of one `X` per joint.
    type Table<X: Element>: JointTable<X>;

    /// A table with every joint's value `fill`.
    fn table<X: Element>(self, fill: X) -> Self::Table<X>;

    /// The count of a table's joints.
    fn of<X: Element>(table: &Self::Table<X>) -> Self;

    /// The geometric Jacobian of a robot of this joint count (6 x N: `[v; omega]` per joint):
    /// nalgebra's `SMatrix<T, 6, N>` for `Const<N>` (the controller's code as it was written
    /// for fixed sizes), a [`JointVec`] of columns for [`Dyn`].
    type Jacobian<T: Real>: JacobianColumns<T>;

    /// A Jacobian of zeros of this many joints.
    fn jacobian<T: Real>(self) -> Self::Jacobian<T>;

    /// The count `joints` as this type: `None` unless it is `N` (`Const<N>`) or within
    /// `1..=`[`MAX_JOINTS`] ([`Dyn`]).
    fn checked(joints: usize) -> Option<Self>;
}

impl<const N: usize> JointCount for Const<N> {
    type Table<X: Element> = [X; N];

    #[inline(always)]
    fn table<X: Element>(self, fill: X) -> [X; N] {
        [fill; N]
    }

    #[inline(always)]
    fn of<X: Element>(_: &[X; N]) -> Self {
        Const
    }

    #[inline(always)]
    fn checked(joints: usize) -> Option<Self> {
        (joints == N).then_some(Const)
    }

    type Jacobian<T: Real> = SMatrix<T, 6, N>;

    #[inline(always)]
    fn jacobian<T: Real>(self) -> SMatrix<T, 6, N> {
        SMatrix::zeros()
    }
}

impl JointCount for Dyn {
    type Table<X: Element> = JointVec<X>;

    /// A table of `self.0` joints, at most [`MAX_JOINTS`] (a larger count is cut to it: check
    /// counts with [`joint_count`] where they enter).
    fn table<X: Element>(self, fill: X) -> JointVec<X> {
        JointVec {
            values: [fill; MAX_JOINTS],
            len: self.0.min(MAX_JOINTS) as u8,
        }
    }

    fn of<X: Element>(table: &JointVec<X>) -> Self {
        Dyn(table.as_slice().len())
    }

    fn checked(joints: usize) -> Option<Self> {
        joint_count(joints)
    }

    type Jacobian<T: Real> = JointVec<Vector6<T>>;

    fn jacobian<T: Real>(self) -> JointVec<Vector6<T>> {
        self.table(Vector6::zeros())
    }
}

/// The columns of a geometric Jacobian (6 x N, `[v; omega]` per joint) and the products the
/// compensation's damped least squares needs, with the same bits for a fixed and a run-time
/// joint count: the run-time count sums in the order of nalgebra's fixed-size products (each
/// entry the first column's product, then each next one added).
pub trait JacobianColumns<T: Real>: Copy + Debug + PartialEq {
    /// Column `j` (0-based joint), zeros beyond the last joint.
    fn column(&self, j: usize) -> Vector6<T>;
    /// Sets column `j` to `column(j)` for every joint.
    fn fill_columns(&mut self, column: impl FnMut(usize) -> Vector6<T>);
    /// Multiplies column `j` by `factor`.
    fn scale_column(&mut self, j: usize, factor: T);
    /// Divides the position rows (the first three) by `length`.
    fn divide_position_rows(&mut self, length: T);
    /// `J J^T`, 6 x 6.
    fn outer_product_sum(&self) -> Matrix6<T>;
    /// `J^T y` into `out`, one value per joint.
    fn transpose_times(&self, y: &Vector6<T>, out: &mut [T]);
}

impl<T: Real, const N: usize> JacobianColumns<T> for SMatrix<T, 6, N> {
    #[inline(always)]
    fn column(&self, j: usize) -> Vector6<T> {
        if j < N {
            self.column(j).into_owned()
        } else {
            Vector6::zeros()
        }
    }
    #[inline(always)]
    fn fill_columns(&mut self, mut column: impl FnMut(usize) -> Vector6<T>) {
        for (j, mut c) in self.column_iter_mut().enumerate() {
            c.copy_from(&column(j));
        }
    }
    #[inline(always)]
    fn scale_column(&mut self, j: usize, factor: T) {
        if let Some(mut c) = self.column_iter_mut().nth(j) {
            c *= factor;
        }
    }
    #[inline(always)]
    fn divide_position_rows(&mut self, length: T) {
        for mut row in self.rows_mut(0, 3).row_iter_mut() {
            row /= length;
        }
    }
    #[inline(always)]
    fn outer_product_sum(&self) -> Matrix6<T> {
        self * self.transpose()
    }
    #[inline(always)]
    fn transpose_times(&self, y: &Vector6<T>, out: &mut [T]) {
        for (o, v) in out.iter_mut().zip((self.transpose() * y).iter()) {
            *o = *v;
        }
    }
}

impl<T: Real> JacobianColumns<T> for JointVec<Vector6<T>> {
    fn column(&self, j: usize) -> Vector6<T> {
        self.as_slice()
            .get(j)
            .copied()
            .unwrap_or_else(Vector6::zeros)
    }
    fn fill_columns(&mut self, mut column: impl FnMut(usize) -> Vector6<T>) {
        for (j, c) in self.as_mut_slice().iter_mut().enumerate() {
            *c = column(j);
        }
    }
    fn scale_column(&mut self, j: usize, factor: T) {
        if let Some(c) = self.as_mut_slice().get_mut(j) {
            *c *= factor;
        }
    }
    fn divide_position_rows(&mut self, length: T) {
        for column in self.as_mut_slice() {
            for v in column.iter_mut().take(3) {
                *v /= length;
            }
        }
    }
    fn outer_product_sum(&self) -> Matrix6<T> {
        let mut sum = Matrix6::<T>::zeros();
        let Some((first, rest)) = self.as_slice().split_first() else {
            return sum;
        };
        for (mut out, scale) in sum.column_iter_mut().zip(first.iter()) {
            out.copy_from(&(first * *scale));
        }
        for column in rest {
            for (mut out, scale) in sum.column_iter_mut().zip(column.iter()) {
                out += column * *scale;
            }
        }
        sum
    }
    fn transpose_times(&self, y: &Vector6<T>, out: &mut [T]) {
        for (value, column) in out.iter_mut().zip(self.as_slice()) {
            let mut terms = column.iter().zip(y.iter());
            if let Some((c, v)) = terms.next() {
                *value = terms.fold(*c * *v, |sum, (c, v)| sum + *c * *v);
            }
        }
    }
}

/// `table` as a table of the joint count type `M` (the same values): `None` when `M` cannot
/// hold its count (another fixed count, more than [`MAX_JOINTS`] for [`Dyn`], or no joint).
/// Converts between a controller's fixed count and a host's run-time one.
pub fn recount<X: Element, N: JointCount, M: JointCount>(
    table: &N::Table<X>,
) -> Option<M::Table<X>> {
    let values = table.as_slice();
    let mut out = M::checked(values.len())?.table(*values.first()?);
    out.as_mut_slice().copy_from_slice(values);
    Some(out)
}

/// The run-time joint count `joints`, or `None` beyond [`MAX_JOINTS`] or for no joint. (A count
/// of 1 serves the host's joint-by-joint checks of a file's joint maps; its commands take robots
/// of 2 or more: `host_tools::model::counts::JOINT_COUNTS`.)
pub fn joint_count(joints: usize) -> Option<Dyn> {
    (1..=MAX_JOINTS).contains(&joints).then_some(Dyn(joints))
}

/// One value per joint of a robot whose joint count is known at run time: an inline array of
/// [`MAX_JOINTS`] values and a length (no heap, `Copy`).
#[derive(Clone, Copy)]
pub struct JointVec<X> {
    values: [X; MAX_JOINTS],
    len: u8,
}

impl<X: Element + Default> JointVec<X> {
    /// The table of `joints` values `f(0), f(1), ...` (at most [`MAX_JOINTS`]: check counts with
    /// [`joint_count`] where they enter).
    pub fn from_fn(joints: usize, mut f: impl FnMut(usize) -> X) -> Self {
        let mut table = Dyn(joints).table(X::default());
        for (j, value) in table.as_mut_slice().iter_mut().enumerate() {
            *value = f(j);
        }
        table
    }
}

impl<X: Element> JointVec<X> {
    /// The values mapped by `f`, joint by joint (`f` also maps the unused slots' copies of a
    /// value, so it should not count its calls).
    pub fn map<Y: Element>(&self, f: impl FnMut(X) -> Y) -> JointVec<Y> {
        JointVec {
            values: self.values.map(f),
            len: self.len,
        }
    }

    /// The table of `values`, or `None` for more than [`MAX_JOINTS`] of them.
    pub fn from_slice(values: &[X]) -> Option<Self> {
        let first = *values.first()?;
        let mut table = Dyn(values.len()).table(first);
        if table.as_slice().len() != values.len() {
            return None;
        }
        table.as_mut_slice().copy_from_slice(values);
        Some(table)
    }
}

impl<X: Element> JointTable<X> for JointVec<X> {
    #[inline(always)]
    fn as_slice(&self) -> &[X] {
        self.values.get(..usize::from(self.len)).unwrap_or(&[])
    }
    #[inline(always)]
    fn as_mut_slice(&mut self) -> &mut [X] {
        self.values
            .get_mut(..usize::from(self.len))
            .unwrap_or(&mut [])
    }
}

impl<X: Element> core::ops::Deref for JointVec<X> {
    type Target = [X];
    fn deref(&self) -> &[X] {
        self.as_slice()
    }
}

impl<X: Element> core::ops::DerefMut for JointVec<X> {
    fn deref_mut(&mut self) -> &mut [X] {
        self.as_mut_slice()
    }
}

impl<'a, X: Element> IntoIterator for &'a JointVec<X> {
    type Item = &'a X;
    type IntoIter = core::slice::Iter<'a, X>;
    fn into_iter(self) -> Self::IntoIter {
        self.as_slice().iter()
    }
}

impl<'a, X: Element> IntoIterator for &'a mut JointVec<X> {
    type Item = &'a mut X;
    type IntoIter = core::slice::IterMut<'a, X>;
    fn into_iter(self) -> Self::IntoIter {
        self.as_mut_slice().iter_mut()
    }
}

impl<X: Element> PartialEq for JointVec<X> {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl<X: Element> Debug for JointVec<X> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.as_slice().fmt(f)
    }
}

#[cfg(feature = "defmt")]
impl<X: Element> defmt::Format for JointVec<X> {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "{=[?]}", self.as_slice());
    }
}
