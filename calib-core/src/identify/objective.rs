//! The paper's objective, eq. (7): `f = sum_j w_j sqrt(k |dr_j|^2 + |dp_j|^2)` over the measured
//! poses, with `dp` in mm, `|dr|` the exact rotation angle in rad, and `k` in mm^2/rad^2.
//! A position-only measurement (spherical reflector) contributes `w_j |dp_j|`.
//!
//! The measurements live in a fixed-capacity set (no heap). Everything that does not depend on the
//! parameters is computed once per pose (the sine and cosine of the joint readings), and a
//! candidate's model is prepared without libm calls for errors within 0.1 rad, so one evaluation
//! does no trigonometry per pose.
//!
//! # Default `k`
//!
//! [`DEFAULT_K`] = 1e6 mm^2/rad^2: an orientation error of 1 mrad then weighs like a position
//! error of 1 mm, which is what a 1 mrad tilt does to a point about 1 m away, the size of the
//! ER10L-C10's links. With `k = 1` the orientation term is a thousand times weaker and the
//! swarm stalls near 0.3 mm (measured by an independent implementation of the method).

use crate::identify::Problem;
use crate::kinematics::mdh::{GROUP, LANES, Lanes};
use crate::kinematics::pose_error::PoseError;
use crate::kinematics::{JointAngles, Kinematics};
use crate::math::so3;
use crate::model::parameters::ShapeError;
use crate::model::{JointCount, JointTable};
use crate::scalar::Real;
use crate::{KinematicsError, Pose};
use core::borrow::Borrow;
use core::fmt;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, Matrix3, OVector, Vector3};

/// Default orientation weight `k` of eq. (7), mm^2/rad^2 (see the module docs).
pub const DEFAULT_K: f64 = 1e6;

/// Why a measurement was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum MeasurementError {
    /// A joint reading is NaN or infinite (the joint is named).
    Joint(KinematicsError),
    /// A position, rotation or weight of a measurement is NaN or infinite.
    NonFinite,
    /// A weight is negative.
    NegativeWeight,
    /// The measured rotation is not a rotation matrix (orthonormality off by more than 1e-3).
    NotARotation,
    /// The measurement set is full (its capacity is the const generic `M`).
    Full,
}

impl fmt::Display for MeasurementError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Joint(e) => write!(f, "{e}"),
            Self::NonFinite => f.write_str("a measurement value is NaN or infinite"),
            Self::NegativeWeight => f.write_str("a measurement weight is negative"),
            Self::NotARotation => f.write_str("a measured rotation is not orthonormal"),
            Self::Full => f.write_str("the measurement set is full"),
        }
    }
}

impl core::error::Error for MeasurementError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Joint(e) => Some(e),
            _ => None,
        }
    }
}

/// One measured pose, prepared: the sine and cosine of its joint readings are computed once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement<T: Real, N: JointCount> {
    /// Joint readings as sine and cosine.
    pub angles: JointAngles<T, N>,
    /// Measured position of the tool point, mm (measurement frame).
    pub position: Vector3<T>,
    /// Measured orientation, or `None` for a position-only measurement.
    pub rotation: Option<Matrix3<T>>,
    /// Weight of the pose in the objective (1 by default).
    pub weight: T,
}

impl<T: Real, N: JointCount> Measurement<T, N> {
    /// A measurement from joint readings `q` (rad), a position (mm), an optional rotation matrix
    /// and a weight (>= 0).
    pub fn new(
        q: &N::Table<T>,
        position: Vector3<T>,
        rotation: Option<Matrix3<T>>,
        weight: T,
    ) -> Result<Self, MeasurementError> {
        let angles = JointAngles::new(q).map_err(MeasurementError::Joint)?;
        let finite = |v: &[T]| v.iter().all(|x| x.finite());
        if !finite(position.as_slice()) || !weight.finite() {
            return Err(MeasurementError::NonFinite);
        }
        if weight < T::zero() {
            return Err(MeasurementError::NegativeWeight);
        }
        if let Some(r) = &rotation {
            if !finite(r.as_slice()) {
                return Err(MeasurementError::NonFinite);
            }
            let off = (r.transpose() * r - Matrix3::identity()).abs().max();
            // Entries were checked finite above, so `off` is not NaN.
            if off > T::of(1e-3) || r.determinant() < T::zero() {
                return Err(MeasurementError::NotARotation);
            }
        }
        Ok(Self {
            angles,
            position,
            rotation,
            weight,
        })
    }

    /// The measured pose; a position-only measurement gets the identity rotation (its rotation
    /// rows are never used).
    pub fn pose(&self) -> Pose<T> {
        Pose::from_parts(
            self.position.into(),
            nalgebra::Rotation3::from_matrix_unchecked(
                self.rotation.unwrap_or_else(Matrix3::identity),
            ),
        )
    }

    /// The pose error of the prediction `predicted` against this measurement (docs/ARCHITECTURE.md); the
    /// rotation error is zero for a position-only measurement.
    pub fn error_of(&self, predicted: &Pose<T>) -> PoseError<T> {
        match self.rotation {
            Some(_) => PoseError::between(&self.pose(), predicted),
            None => PoseError {
                position: self.position - predicted.translation.vector,
                rotation: Vector3::zeros(),
            },
        }
    }

    /// The same measurement with the joint count as the type `M`: `None` when `M` cannot hold
    /// it.
    pub fn recount<M: JointCount>(&self) -> Option<Measurement<T, M>> {
        use crate::model::joint_count::recount;
        Some(Measurement {
            angles: JointAngles {
                cos: recount::<_, N, M>(&self.angles.cos)?,
                sin: recount::<_, N, M>(&self.angles.sin)?,
            },
            position: self.position,
            rotation: self.rotation,
            weight: self.weight,
        })
    }

    /// A measurement taken from a pose (position and rotation), weight 1.
    pub fn from_pose(q: &N::Table<T>, pose: &Pose<T>) -> Result<Self, MeasurementError> {
        Self::new(
            q,
            pose.translation.vector,
            Some(*pose.rotation.matrix()),
            T::one(),
        )
    }
}

/// At most `M` measurements, stored inline.
#[derive(Clone, Debug)]
pub struct MeasurementSet<T: Real, N: JointCount, const M: usize> {
    items: heapless::Vec<Measurement<T, N>, M>,
}

impl<T: Real, N: JointCount, const M: usize> Default for MeasurementSet<T, N, M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Real, N: JointCount, const M: usize> MeasurementSet<T, N, M> {
    /// An empty set.
    pub const fn new() -> Self {
        Self {
            items: heapless::Vec::new(),
        }
    }

    /// Adds a measurement; when the set is full, gives it back.
    pub fn push(&mut self, measurement: Measurement<T, N>) -> Result<(), Measurement<T, N>> {
        self.items.push(measurement)
    }

    /// The measurements, in insertion order.
    pub fn as_slice(&self) -> &[Measurement<T, N>] {
        &self.items
    }

    /// Number of measurements.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// `true` when there is no measurement.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}

/// At most `L` measurements in lane layout (structure of arrays), as the objective reads them:
/// lane `i` of every field belongs to the same pose. `L` is `LANES` (4 on a PC, 1 on ARM) unless
/// said otherwise. Unused lanes hold a pose of weight 0 (joints at zero, identity rotation), whose
/// term is exactly zero.
// Public only as a host's speed-up hook (host-tools' swarm team); hidden from the docs because
// it is not part of the supported API: its layout may change with the lane width.
#[doc(hidden)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseLanes<T: Real, N: JointCount, const L: usize = LANES> {
    cos: N::Table<Lanes<T, L>>,
    sin: N::Table<Lanes<T, L>>,
    position: [Lanes<T, L>; 3],
    /// Measured rotation columns; the identity for position-only poses.
    rotation: [[Lanes<T, L>; 3]; 3],
    weight: Lanes<T, L>,
    /// 1 where the pose has a measured rotation, 0 otherwise.
    orientation: Lanes<T, L>,
}

impl<T: Real, N: JointCount, const L: usize> PoseLanes<T, N, L> {
    /// The first `L` measurements of `chunk`, of a robot of `joints` joints, in lanes (more are
    /// ignored).
    #[inline(always)]
    pub fn gather(joints: N, chunk: &[Measurement<T, N>]) -> Self {
        let zero = Lanes::<T, L>::zeros();
        let one = Lanes::<T, L>::repeat(T::one());
        let mut rotation = [[zero; 3]; 3];
        for (j, column) in rotation.iter_mut().enumerate() {
            if let Some(entry) = column.get_mut(j) {
                *entry = one;
            }
        }
        let mut poses = Self {
            cos: joints.table(one),
            sin: joints.table(zero),
            position: [zero; 3],
            rotation,
            weight: zero,
            orientation: zero,
        };
        for (m, lane) in chunk.iter().zip(0..L) {
            let set = |lanes: &mut Lanes<T, L>, value: T| {
                if let Some(v) = lanes.get_mut(lane) {
                    *v = value;
                }
            };
            for ((c, s), (mc, ms)) in poses
                .cos
                .iter_mut()
                .zip(poses.sin.iter_mut())
                .zip(m.angles.cos.iter().zip(m.angles.sin.iter()))
            {
                set(c, *mc);
                set(s, *ms);
            }
            for (p, v) in poses.position.iter_mut().zip(m.position.iter()) {
                set(p, *v);
            }
            set(&mut poses.weight, m.weight);
            if let Some(r) = &m.rotation {
                set(&mut poses.orientation, T::one());
                for (column, r_column) in poses.rotation.iter_mut().zip(r.column_iter()) {
                    for (entry, v) in column.iter_mut().zip(r_column.iter()) {
                        set(entry, *v);
                    }
                }
            }
        }
        poses
    }
}

/// Eq. (7) for the parameters of a [`ParameterSet`](crate::ParameterSet) over a set of measurements: the swarm's
/// view of a [`Problem`].
#[derive(Clone, Copy, Debug)]
pub struct Objective<'p, T: Real, N: JointCount, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    problem: &'p Problem<'p, T, N, D>,
}

impl<'p, T: Real, N: JointCount, D: Dim> Objective<'p, T, N, D>
where
    DefaultAllocator: Allocator<D>,
{
    /// The objective of `problem`: its identified parameters over its measurements, with its `k`
    /// ([`DEFAULT_K`] by default).
    pub fn new(problem: &'p Problem<'p, T, N, D>) -> Self {
        Self { problem }
    }

    /// The problem: identified parameters, measurements, `k`.
    pub fn problem(&self) -> &'p Problem<'p, T, N, D> {
        self.problem
    }

    /// Eq. (7) at the packed errors `x` (mm, rad). Non-finite `x`, or an `x` of another length
    /// than the problem's parameter set (a run-time `Dyn` dimension can hold any), gives
    /// +infinity: no value of a truncated or padded vector.
    ///
    /// The poses are evaluated `LANES` (4 on a PC, 1 on ARM) at a time in structure-of-arrays form (vectorised on a
    /// PC; on a controller the same scalar operations in a different order of memory accesses).
    /// Each group of `LANES` measurements is gathered into lanes on every call; a caller that
    /// evaluates many candidates keeps [`Objective::lanes`] and calls [`Objective::value_of_lanes`]
    /// (the same bits).
    #[inline(never)]
    pub fn value(&self, x: &OVector<T, D>) -> T {
        if !x.iter().all(|v| v.finite()) {
            return T::of(f64::INFINITY);
        }
        let joints = self.problem.joint_count();
        let lanes = self.problem.measurements().chunks(LANES);
        self.sum_in_groups(
            x,
            lanes.map(|chunk| PoseLanes::<T, N>::gather(joints, chunk)),
        )
    }

    /// The measurements in lane layout, `L` poses per item in measurement order (the last one
    /// padded with poses that weigh nothing): what [`Objective::value_of_lanes`] reads. `L` is
    /// `LANES` (4 on a PC, 1 on ARM) for the layout [`Objective::value`] uses; any width gives
    /// the same bits (eight lanes in AVX-512's 512-bit registers measured slower than four:
    /// `cargo bench -p calib-core --bench calibration -- lanes`).
    /// Zero lanes do not compile.
    // Public only as a host's speed-up hook (host-tools' swarm team); hidden from the docs because
    // it is not part of the supported API: its layout may change with the lane width.
    #[doc(hidden)]
    pub fn lanes<const L: usize>(&self) -> impl Iterator<Item = PoseLanes<T, N, L>> + 'p {
        const { assert!(L > 0, "at least one lane") };
        let joints = self.problem.joint_count();
        self.problem
            .measurements()
            .chunks(L)
            .map(move |chunk| PoseLanes::gather(joints, chunk))
    }

    /// Eq. (7) at `x` over measurements already in lane layout: `lanes` must be
    /// [`Objective::lanes`] of this objective, collected once, with any number `L` of lanes. Bit
    /// for bit [`Objective::value`] (the poses' terms are summed in its groups of `GROUP` (4)
    /// whatever `L`), without gathering the poses on every call. Always inlined, so that a
    /// caller compiled for wider vectors (AVX2, AVX-512) gets the whole evaluation in them.
    // Public only as a host's speed-up hook (host-tools' swarm team); hidden from the docs because
    // it is not part of the supported API: its layout may change with the lane width.
    #[doc(hidden)]
    #[inline(always)]
    pub fn value_of_lanes<const L: usize>(
        &self,
        x: &OVector<T, D>,
        lanes: &[PoseLanes<T, N, L>],
    ) -> T {
        self.sum_in_groups(x, lanes)
    }

    /// Eq. (7) at `x` over poses in lanes: the terms summed within groups of `GROUP` poses, then
    /// the groups, the same order for every lane width (the padding's terms are +0, which
    /// changes no sum). Non-finite `x`, or one of another length, gives +infinity. Plain loops:
    /// a `fold` taking a closure stayed a function of its own, compiled without the caller's
    /// AVX2 (measured: two thirds of the run in it).
    #[inline(always)]
    fn sum_in_groups<const L: usize, P: Borrow<PoseLanes<T, N, L>>>(
        &self,
        x: &OVector<T, D>,
        lanes: impl IntoIterator<Item = P>,
    ) -> T {
        if x.len() != self.problem.set().len() || !x.iter().all(|v| v.finite()) {
            return T::of(f64::INFINITY);
        }
        let kinematics = self.problem.kinematics_unchecked(x);
        let mut total = T::zero();
        let mut group = T::zero();
        let mut in_group = 0;
        for poses in lanes {
            let terms = lane_terms(self.problem.k(), &kinematics, poses.borrow());
            for term in terms.iter() {
                group += *term;
                in_group += 1;
                if in_group == GROUP {
                    total += group;
                    group = T::zero();
                    in_group = 0;
                }
            }
        }
        total + group
    }

    /// The pose error of every measurement at `x`, in measurement order, passed to `visit`
    /// (rotation zero for position-only measurements); a vector of another length than the set
    /// is refused.
    pub fn pose_errors(
        &self,
        x: &OVector<T, D>,
        mut visit: impl FnMut(&Measurement<T, N>, PoseError<T>),
    ) -> Result<(), ShapeError> {
        let kinematics = self.problem.kinematics(x)?;
        for m in self.problem.measurements() {
            visit(m, m.error_of(&kinematics.forward_angles(&m.angles)));
        }
        Ok(())
    }
}

/// Eq. (7)'s term (orientation weight `k`) of each of the `L` poses of `poses` (0 in padding lanes).
#[inline(always)]
fn lane_terms<T: Real, N: JointCount, const L: usize>(
    k: T,
    kinematics: &Kinematics<T, N>,
    poses: &PoseLanes<T, N, L>,
) -> Lanes<T, L> {
    let zero = Lanes::<T, L>::zeros();
    let frame = kinematics.forward_lanes(&poses.cos, &poses.sin);
    let mut dp2 = zero;
    for (measured, predicted) in poses.position.iter().zip(frame.origin.iter()) {
        let d = measured - predicted;
        dp2 += d.component_mul(&d);
    }
    // Column by column, entry by entry (nested loops over arrays of 3 unroll; a flattened
    // iterator kept its bookkeeping: 15 instructions per entry on the controller).
    let mut chord2 = zero;
    for (measured, predicted) in poses.rotation.iter().zip(frame.columns.iter()) {
        for (m, p) in measured.iter().zip(predicted) {
            let d = m - p;
            chord2 += d.component_mul(&d);
        }
    }
    let mut terms = zero;
    for ((((term, dp2), chord2), w), has_rotation) in terms
        .iter_mut()
        .zip(dp2.iter())
        .zip(chord2.iter())
        .zip(poses.weight.iter())
        .zip(poses.orientation.iter())
    {
        let angle2 = so3::angle_squared_from_chord(*chord2) * *has_rotation;
        *term = *w * (k * angle2 + *dp2).sqrt_ieee();
    }
    terms
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::U6;
    use nalgebra::{SVector, U24};
    extern crate std;
    use crate::identify::ipso::{self, IpsoSettings, SearchSpace, Silent};
    use crate::model::paper::{er10l_c10, paper_measurements, table2};
    use crate::{ParameterErrors, ParameterSet, Problem};

    /// Runs the paper's swarm (20 particles, 2000 generations, plain Halton, seed 0, bounds 10
    /// times the initial range) on the noise-free 32-pose scenario; returns the worst length error
    /// (mm), the worst angle error (rad) against Table 2, and the initial and final objective.
    fn paper_run<T: Real>() -> (f64, f64, f64, f64) {
        let robot = er10l_c10::<T>();
        let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
        let data = paper_measurements::<T>(1);
        let problem = Problem::new(
            &robot,
            &ParameterErrors::zero(),
            set,
            data.as_slice(),
            T::of(DEFAULT_K),
        )
        .unwrap();
        let objective = Objective::new(&problem);
        let space = SearchSpace::paper(&set);
        let mut cost = |x: &SVector<T, 24>| objective.value(x);
        let r =
            ipso::optimize::<T, 20, U24>(&mut cost, &space, &IpsoSettings::paper(), &mut Silent)
                .unwrap();
        let truth = set.pack(&table2::<T>());
        let (worst_mm, worst_rad) = set.largest_differences(&r.best, &truth).unwrap();
        (
            worst_mm.to_f64(),
            worst_rad.to_f64(),
            r.initial_cost.to_f64(),
            r.best_cost.to_f64(),
        )
    }

    /// `value_of_lanes` over lanes of `L` poses, collected once, gives `value` bit for bit.
    fn check_lanes_of<const L: usize>(objective: &Objective<'_, f64, U6, U24>, poses: usize) {
        let lanes: std::vec::Vec<PoseLanes<f64, U6, L>> = objective.lanes().collect();
        assert_eq!(lanes.len(), poses.div_ceil(L));
        for i in 0..5 {
            let x = SVector::<f64, 24>::from_fn(|j, _| 1e-3 * (i as f64 - 2.0) * (j as f64 - 11.0));
            let (gathered, collected) = (objective.value(&x), objective.value_of_lanes(&x, &lanes));
            assert_eq!(
                gathered.to_bits(),
                collected.to_bits(),
                "{L} lanes, {poses} poses: {gathered} {collected}"
            );
            assert!(gathered > 0.0);
        }
        let mut nan = SVector::<f64, 24>::zeros();
        nan[3] = f64::NAN;
        assert_eq!(objective.value_of_lanes(&nan, &lanes), f64::INFINITY);
    }

    /// `value_of_lanes` gives `value` bit for bit for 1, 2, 4 and 8 lanes, with a last group that
    /// is not full (29 poses), padding that fills a group of its own (17 poses in lanes of 8) and
    /// position-only poses among full ones.
    #[test]
    fn lanes_collected_once_give_the_same_bits() {
        let robot = er10l_c10::<f64>();
        let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
        for poses in [29, 17] {
            let mut data: std::vec::Vec<_> = paper_measurements::<f64>(1).as_slice().to_vec();
            data.truncate(poses);
            for m in data.iter_mut().step_by(3) {
                m.rotation = None;
                m.weight = 0.5;
            }
            let problem =
                Problem::new(&robot, &ParameterErrors::zero(), set, &data, DEFAULT_K).unwrap();
            let objective = Objective::new(&problem);
            check_lanes_of::<1>(&objective, poses);
            check_lanes_of::<2>(&objective, poses);
            check_lanes_of::<LANES>(&objective, poses);
            check_lanes_of::<8>(&objective, poses);
        }
    }

    #[test]
    fn paper_scenario_recovers_table2_in_f64() {
        let (mm, rad, initial, last) = paper_run::<f64>();
        std::println!(
            "f64: worst {mm:.2e} mm, {rad:.2e} rad; objective {initial:.4e} -> {last:.3e}"
        );
        assert!(mm < 1e-6, "worst length error {mm} mm");
        assert!(rad < 1e-9, "worst angle error {rad} rad");
    }

    #[test]
    fn paper_scenario_recovers_table2_in_f32() {
        let (mm, rad, initial, last) = paper_run::<f32>();
        std::println!(
            "f32: worst {mm:.2e} mm, {rad:.2e} rad; objective {initial:.4e} -> {last:.3e}"
        );
        // Single precision: the f32 measurements carry about 1e-4 mm of rounding and the f32
        // objective stalls near 1e-2. Measured with seeds 0 to 7: 2.1e-5 to 1.5e-3 mm and
        // 8.5e-8 to 2.4e-6 rad (seed 0: 1.2e-4 mm, 1.4e-7 rad); the bounds cover all eight.
        assert!(mm < 2e-3, "worst length error {mm} mm");
        assert!(rad < 3e-6, "worst angle error {rad} rad");
    }
}
