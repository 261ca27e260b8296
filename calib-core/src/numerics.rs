//! The numerics contract: what the core promises about its arithmetic, and the rules its code keeps
//! to hold those promises. Nothing here is compiled; the rules are enforced where they apply
//! (linked), and the tests named check them.
//!
//! # Promises
//!
//! 1. **The same bits for a fixed and a run-time size.** A controller compiles the joint count and
//!    the parameter count as `Const<N>`, `Const<D>`; a host runs `Dyn`. Every result (the
//!    objective, a least-squares step and its covariance, a swarm run, a compensation) has the same
//!    bits for both (tests `parameter_count`, `swarm_golden`, `joint_count` in `tests/`).
//! 2. **The same bits on every target.** x86_64 and the Cortex-M4F compute the same bits for the
//!    same input and scalar type (`onboard/expected.bin`, checked in QEMU).
//! 3. **No panic on any input**, and no silent wrong result from a vector of the wrong length:
//!    a run-time `Dyn` vector of another length than its parameter set is refused where it enters
//!    ([`crate::model::parameters::ShapeError`], `LmError::Shape`, `IpsoError::InvalidSize`), or,
//!    for the objective, valued +infinity (test `no_panic`, its `Dyn` case).
//!
//! # Rules
//!
//! - **Same operations, same order.** The code for `Const` and `Dyn` is one generic function; where
//!   nalgebra would take another path for `Dyn`, the core takes the fixed-size one itself:
//!   - matrix products: nalgebra hands `Dyn` products larger than 5 to a blocked kernel that sums
//!     in another order; the core forms them column by column with `gemv`
//!     (`identify::lm::product_by_columns`, the covariance) and sums the Jacobian products
//!     entry by entry in the fixed-size order ([`crate::model::joint_count::JacobianColumns`]);
//!   - sums over poses: the objective's terms are summed in groups of
//!     `kinematics::mdh::GROUP` (4) poses, then the groups, whatever the lane width
//!     (`kinematics::mdh::LANES`: 4 on a PC, 1 on ARM), so SIMD lanes change no bit;
//!   - a least-squares factor takes its rows in the same order, several at a time as a
//!     wavefront (`identify::lm::RowBatch`), with every entry's operations in the order of one
//!     row at a time.
//! - **Math functions from fixed implementations.** Sine, cosine, square roots and the rest come
//!   from `libm` (nalgebra with `libm-force`) or the core's own tested routines
//!   ([`crate::scalar`]), never from the host's C library.
//! - **Lengths checked where a vector enters, not in the inner loops.** Public functions that take
//!   a packed vector check its length first ([`crate::model::parameters::ParameterSet::check_shape`])
//!   and then run unchecked code (`Problem::kinematics_unchecked`, `ParameterSet::write_into`);
//!   for `Const` the check compares two constants and folds away, so the controller's code and
//!   its instruction counts do not change.
//! - **Plain slices in hot loops.** nalgebra's iterators check for a column's end at every step,
//!   which a run-time count does not fold away; the inner loops read `as_slice()`.
