//! Parameter errors, the identification mask, and the packed parameter vector.
//!
//! The actual robot is the nominal model plus [`ParameterErrors`]: per joint `da, dalpha, dtheta,
//! dd, dbeta` (mm, rad), and 3 translations (mm) and 3 rotations (rad) for each of the base and tool
//! frames. The frame rotation errors compose on the nominal frame's own axes:
//! `R_actual = R_nominal * Rz(rz) Ry(ry) Rx(rx)`, translation errors add in the parent frame.
//!
//! # Canonical order and names
//!
//! All `5 N + 12` parameters have one fixed order, the order of the paper's list of the 24
//! ER10L-C10 parameters: by kind first, then by joint:
//!
//! `da1..daN, dd1..ddN, dalpha1..dalphaN, dbeta1..dbetaN, dtheta1..dthetaN,`
//! `base_tx, base_ty, base_tz, base_rx, base_ry, base_rz, tool_tx, ..., tool_rz`.
//!
//! A [`ParameterSet`] keeps the parameters selected by a [`ParameterMask`] in this order; that is
//! the order of the packed vector, of the Jacobian columns and of every report.

use crate::model::KinematicsError;
use crate::model::Robot;
use crate::model::{JointCount, JointTable};
use crate::scalar::Real;
use core::fmt;
use nalgebra::allocator::Allocator;
use nalgebra::{Const, DefaultAllocator, Dim, OMatrix, OVector, SVector, U1};

/// The five MDH parameters of a joint, in canonical order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum JointParameter {
    /// Link length `a`, mm.
    A,
    /// Link offset `d`, mm.
    D,
    /// Link twist `alpha`, rad.
    Alpha,
    /// Hayati twist `beta`, rad.
    Beta,
    /// Joint angle offset `theta`, rad.
    Theta,
}

impl JointParameter {
    /// The five kinds in canonical order.
    pub const ALL: [Self; 5] = [Self::A, Self::D, Self::Alpha, Self::Beta, Self::Theta];

    /// The name without the `d` prefix and joint number: `a`, `d`, `alpha`, `beta`, `theta`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::A => "a",
            Self::D => "d",
            Self::Alpha => "alpha",
            Self::Beta => "beta",
            Self::Theta => "theta",
        }
    }

    const fn bit(self) -> u8 {
        1 << (self as u8)
    }
}

/// The six parameters of a base or tool frame, in canonical order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameParameter {
    /// Translation along x of the parent frame, mm.
    Tx,
    /// Translation along y of the parent frame, mm.
    Ty,
    /// Translation along z of the parent frame, mm.
    Tz,
    /// Rotation about the frame's own x axis (roll), rad.
    Rx,
    /// Rotation about the frame's own y axis (pitch), rad.
    Ry,
    /// Rotation about the frame's own z axis (yaw), rad.
    Rz,
}

impl FrameParameter {
    /// The six kinds in canonical order.
    pub const ALL: [Self; 6] = [Self::Tx, Self::Ty, Self::Tz, Self::Rx, Self::Ry, Self::Rz];

    /// The name suffix: `tx`, `ty`, `tz`, `rx`, `ry`, `rz`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Tx => "tx",
            Self::Ty => "ty",
            Self::Tz => "tz",
            Self::Rx => "rx",
            Self::Ry => "ry",
            Self::Rz => "rz",
        }
    }

    /// `true` for the three rotations.
    pub const fn is_rotation(self) -> bool {
        matches!(self, Self::Rx | Self::Ry | Self::Rz)
    }

    const fn bit(self) -> u8 {
        1 << (self as u8)
    }
}

/// One geometric parameter of the model. Displayed as `da1`, `dalpha3`, `base_tx`, `tool_rz`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Parameter {
    /// A joint parameter.
    Joint {
        /// Joint number, 1-based.
        joint: u8,
        /// Which of the five MDH parameters.
        kind: JointParameter,
    },
    /// A base frame parameter.
    Base(FrameParameter),
    /// A tool frame parameter.
    Tool(FrameParameter),
}

impl Parameter {
    /// `true` for angles (rad), `false` for lengths (mm).
    pub const fn is_angle(self) -> bool {
        match self {
            Self::Joint { kind, .. } => matches!(
                kind,
                JointParameter::Alpha | JointParameter::Beta | JointParameter::Theta
            ),
            Self::Base(k) | Self::Tool(k) => k.is_rotation(),
        }
    }

    /// Parses a name such as `da1`, `dbeta2`, `base_rz` for a robot of `joints` joints.
    pub fn from_name(name: &str, joints: usize) -> Option<Self> {
        if let Some(rest) = name.strip_prefix("base_") {
            return frame_kind(rest).map(Self::Base);
        }
        if let Some(rest) = name.strip_prefix("tool_") {
            return frame_kind(rest).map(Self::Tool);
        }
        let rest = name.strip_prefix('d')?;
        let digits = rest.find(|c: char| c.is_ascii_digit())?;
        let (kind, number) = rest.split_at(digits);
        let kind = JointParameter::ALL.into_iter().find(|k| k.name() == kind)?;
        let joint: u8 = number.parse().ok()?;
        (joint >= 1 && usize::from(joint) <= joints).then_some(Self::Joint { joint, kind })
    }
}

fn frame_kind(name: &str) -> Option<FrameParameter> {
    FrameParameter::ALL.into_iter().find(|k| k.name() == name)
}

impl fmt::Display for Parameter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Joint { joint, kind } => write!(f, "d{}{joint}", kind.name()),
            Self::Base(k) => write!(f, "base_{}", k.name()),
            Self::Tool(k) => write!(f, "tool_{}", k.name()),
        }
    }
}

/// Errors of one joint's MDH parameters (mm, rad).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointErrors<T> {
    /// Error of `a`, mm.
    pub da: T,
    /// Error of `alpha`, rad.
    pub dalpha: T,
    /// Error of the joint zero `theta_offset`, rad.
    pub dtheta: T,
    /// Error of `d`, mm.
    pub dd: T,
    /// Error of `beta`, rad.
    pub dbeta: T,
}

/// Errors of a base or tool frame: translation (mm, parent frame) and rotation (rad,
/// `R_actual = R_nominal Rz(rz) Ry(ry) Rx(rx)`).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrameErrors<T> {
    /// `[tx, ty, tz]`, mm.
    pub translation: [T; 3],
    /// `[rx, ry, rz]`, rad.
    pub rotation: [T; 3],
}

/// All parameter errors of an N-joint robot: actual model = nominal + these.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParameterErrors<T: Real, N: JointCount> {
    /// Per joint errors, joint 1 first.
    pub joints: N::Table<JointErrors<T>>,
    /// Base frame errors.
    pub base: FrameErrors<T>,
    /// Tool frame errors.
    pub tool: FrameErrors<T>,
}

impl<T: Real, const N: usize> Default for ParameterErrors<T, Const<N>> {
    fn default() -> Self {
        Self::zero()
    }
}

impl<T: Real, const N: usize> ParameterErrors<T, Const<N>> {
    /// All errors zero: the actual model equals the nominal one (a joint count fixed at compile
    /// time; [`ParameterErrors::zeros_for`] takes any).
    pub fn zero() -> Self {
        Self::zeros_for(Const)
    }
}

impl<T: Real, N: JointCount> ParameterErrors<T, N> {
    /// All errors of a robot of `joints` joints zero: the actual model equals the nominal one.
    pub fn zeros_for(joints: N) -> Self {
        let joint = JointErrors {
            da: T::zero(),
            dalpha: T::zero(),
            dtheta: T::zero(),
            dd: T::zero(),
            dbeta: T::zero(),
        };
        let frame = FrameErrors {
            translation: [T::zero(); 3],
            rotation: [T::zero(); 3],
        };
        Self {
            joints: joints.table(joint),
            base: frame,
            tool: frame,
        }
    }

    /// The joint count.
    pub fn joint_count(&self) -> N {
        N::of(&self.joints)
    }

    /// The same errors with the joint count as the type `M`: `None` when `M` cannot hold it.
    pub fn recount<M: JointCount>(&self) -> Option<ParameterErrors<T, M>> {
        Some(ParameterErrors {
            joints: crate::model::joint_count::recount::<_, N, M>(&self.joints)?,
            base: self.base,
            tool: self.tool,
        })
    }

    /// The error of one parameter (mm or rad); `None` for a joint number outside `1..=N`.
    pub fn get(&self, parameter: Parameter) -> Option<T> {
        match parameter {
            Parameter::Joint { joint, kind } => {
                let e = self
                    .joints
                    .as_slice()
                    .get(usize::from(joint).checked_sub(1)?)?;
                Some(match kind {
                    JointParameter::A => e.da,
                    JointParameter::D => e.dd,
                    JointParameter::Alpha => e.dalpha,
                    JointParameter::Beta => e.dbeta,
                    JointParameter::Theta => e.dtheta,
                })
            }
            Parameter::Base(k) => Some(frame_value(&self.base, k)),
            Parameter::Tool(k) => Some(frame_value(&self.tool, k)),
        }
    }

    /// Sets the error of one parameter; returns `false` (and changes nothing) for a joint number
    /// outside `1..=N`.
    #[cfg_attr(not(target_arch = "arm"), inline(always))]
    pub fn set(&mut self, parameter: Parameter, value: T) -> bool {
        let slot = match parameter {
            Parameter::Joint { joint, kind } => {
                let Some(e) = usize::from(joint)
                    .checked_sub(1)
                    .and_then(|j| self.joints.as_mut_slice().get_mut(j))
                else {
                    return false;
                };
                match kind {
                    JointParameter::A => &mut e.da,
                    JointParameter::D => &mut e.dd,
                    JointParameter::Alpha => &mut e.dalpha,
                    JointParameter::Beta => &mut e.dbeta,
                    JointParameter::Theta => &mut e.dtheta,
                }
            }
            Parameter::Base(k) => frame_slot(&mut self.base, k),
            Parameter::Tool(k) => frame_slot(&mut self.tool, k),
        };
        *slot = value;
        true
    }

    /// Checks that every error is finite.
    pub fn validate(&self) -> Result<(), KinematicsError> {
        for parameter in all_parameters(N::of(&self.joints)) {
            if !self.get(parameter).is_some_and(Real::finite) {
                return Err(KinematicsError::NonFiniteError(parameter));
            }
        }
        Ok(())
    }
}

fn frame_value<T: Copy>(frame: &FrameErrors<T>, kind: FrameParameter) -> T {
    *frame_slot_ref(frame, kind)
}

fn frame_slot_ref<T>(frame: &FrameErrors<T>, kind: FrameParameter) -> &T {
    let [tx, ty, tz] = &frame.translation;
    let [rx, ry, rz] = &frame.rotation;
    match kind {
        FrameParameter::Tx => tx,
        FrameParameter::Ty => ty,
        FrameParameter::Tz => tz,
        FrameParameter::Rx => rx,
        FrameParameter::Ry => ry,
        FrameParameter::Rz => rz,
    }
}

fn frame_slot<T>(frame: &mut FrameErrors<T>, kind: FrameParameter) -> &mut T {
    let [tx, ty, tz] = &mut frame.translation;
    let [rx, ry, rz] = &mut frame.rotation;
    match kind {
        FrameParameter::Tx => tx,
        FrameParameter::Ty => ty,
        FrameParameter::Tz => tz,
        FrameParameter::Rx => rx,
        FrameParameter::Ry => ry,
        FrameParameter::Rz => rz,
    }
}

/// All `5 N + 12` parameters of a robot of `joints` joints in canonical order (see the module
/// docs).
pub fn all_parameters<N: JointCount>(joints: N) -> impl Iterator<Item = Parameter> {
    let count = joints.value();
    let total = JointParameter::ALL.len() * count + 2 * FrameParameter::ALL.len();
    // One index over the whole order rather than chained iterators: on the controller the
    // chain's `next` alone took 302 bytes of flash.
    (0..total).filter_map(move |i| canonical_parameter(count, i))
}

/// The `i`-th parameter (from 0) of the canonical order for `count` joints: the joints' kinds
/// (each for joints 1 to `count`), then the base's and the tool's frame parameters.
fn canonical_parameter(count: usize, i: usize) -> Option<Parameter> {
    let frames = FrameParameter::ALL.len();
    let frame = |k: usize| FrameParameter::ALL.get(k).copied();
    match i.checked_sub(JointParameter::ALL.len() * count) {
        None => Some(Parameter::Joint {
            joint: crate::model::joint_number(i.checked_rem(count)?),
            kind: *JointParameter::ALL.get(i.checked_div(count)?)?,
        }),
        Some(k) if k < frames => frame(k).map(Parameter::Base),
        Some(k) => frame(k - frames).map(Parameter::Tool),
    }
}

/// Which parameters are identified: one bit per parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParameterMask<N: JointCount> {
    joints: N::Table<u8>,
    base: u8,
    tool: u8,
}

/// Twist below which a joint's axis is taken as nominally parallel to the next one, rad (0.57
/// deg): designed twists are 0 or several degrees, and an identified robot's parallel axes stay
/// within a few milliradians of parallel, so that a file written by a calibration keeps the
/// parallel joints' `beta` (with `d` there the set is ill-conditioned: `d_i` and `d_(i+1)` move
/// the chain almost alike).
pub const PARALLEL_AXES_TOLERANCE: f64 = 1e-2;

impl<const N: usize> ParameterMask<Const<N>> {
    /// Nothing identified (a joint count fixed at compile time; [`ParameterMask::empty_for`]
    /// takes any).
    pub const fn empty() -> Self {
        Self {
            joints: [0; N],
            base: 0,
            tool: 0,
        }
    }
}

impl<N: JointCount> ParameterMask<N> {
    /// Nothing identified of a robot of `joints` joints.
    pub fn empty_for(joints: N) -> Self {
        Self {
            joints: joints.table(0),
            base: 0,
            tool: 0,
        }
    }

    /// The joint count.
    pub fn joint_count(&self) -> N {
        N::of(&self.joints)
    }

    /// The default rule (docs/ARCHITECTURE.md): for joint i identify `a, alpha, theta`, and `d` unless the
    /// axes of joints i and i+1 are nominally parallel (`|alpha_i| <` [`PARALLEL_AXES_TOLERANCE`]
    /// and `i < N`), in which
    /// case `beta` replaces `d` (Hayati's fix for parallel axes). Base and tool are not identified.
    /// For the ER10L-C10 this gives the paper's 24 parameters.
    pub fn default_for<T: Real>(robot: &Robot<T, N>) -> Self {
        let mut mask = Self::empty_for(robot.joint_count());
        let tolerance = T::of(PARALLEL_AXES_TOLERANCE);
        let count = robot.joints.len();
        for (j, (bits, joint)) in mask.joints.iter_mut().zip(robot.joints.iter()).enumerate() {
            let parallel_to_next = joint.alpha.abs() < tolerance && j + 1 < count;
            let fourth = if parallel_to_next {
                JointParameter::Beta
            } else {
                JointParameter::D
            };
            *bits = JointParameter::A.bit()
                | JointParameter::Alpha.bit()
                | JointParameter::Theta.bit()
                | fourth.bit();
        }
        mask
    }

    /// Whether `parameter` is identified (`false` for a joint number outside `1..=N`).
    pub fn contains(&self, parameter: Parameter) -> bool {
        match parameter {
            Parameter::Joint { joint, kind } => usize::from(joint)
                .checked_sub(1)
                .and_then(|j| self.joints.as_slice().get(j))
                .is_some_and(|bits| bits & kind.bit() != 0),
            Parameter::Base(k) => self.base & k.bit() != 0,
            Parameter::Tool(k) => self.tool & k.bit() != 0,
        }
    }

    /// Selects or deselects `parameter`; returns `false` for a joint number outside `1..=N`.
    pub fn set(&mut self, parameter: Parameter, identified: bool) -> bool {
        let (bits, bit) = match parameter {
            Parameter::Joint { joint, kind } => {
                match usize::from(joint)
                    .checked_sub(1)
                    .and_then(|j| self.joints.as_mut_slice().get_mut(j))
                {
                    Some(bits) => (bits, kind.bit()),
                    None => return false,
                }
            }
            Parameter::Base(k) => (&mut self.base, k.bit()),
            Parameter::Tool(k) => (&mut self.tool, k.bit()),
        };
        if identified {
            *bits |= bit;
        } else {
            *bits &= !bit;
        }
        true
    }

    /// Selected parameters in canonical order.
    pub fn iter(&self) -> impl Iterator<Item = Parameter> + '_ {
        all_parameters(self.joint_count()).filter(|p| self.contains(*p))
    }

    /// Number of selected parameters.
    pub fn count(&self) -> usize {
        self.iter().count()
    }
}

/// A packed vector whose length is not its parameter set's: a run-time dimension
/// ([`nalgebra::Dyn`]) holds any length, and the core refuses it where the vector enters rather
/// than truncating it or letting nalgebra panic (a fixed `Const<D>` has its length by type, and
/// the check folds away: see [`crate::numerics`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ShapeError {
    /// The parameters of the set.
    pub expected: usize,
    /// The vector's length.
    pub got: usize,
}

impl fmt::Display for ShapeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "a packed parameter vector of {} values for a set of {} parameters",
            self.got, self.expected
        )
    }
}

impl core::error::Error for ShapeError {}

/// The `D` identified parameters of an N-joint robot, in canonical order: the meaning of every
/// entry of a packed parameter vector `OVector<T, D>` and every column of a parameter Jacobian.
///
/// The count `D` is a nalgebra dimension: `Const<24>` on the controller (the sizes, and so the
/// code, fixed at compile time, no heap), [`nalgebra::Dyn`] on a host that learns the count from
/// a robot file at run time (one compiled solver for every count; the vectors on the heap).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParameterSet<N: JointCount, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    parameters: OVector<Parameter, D>,
    joints: N,
}

/// A fixed-size set (`Const<D>`) is `Copy`, as the controller's code expects.
impl<N: JointCount, D: Dim> Copy for ParameterSet<N, D>
where
    DefaultAllocator: Allocator<D>,
    OVector<Parameter, D>: Copy,
{
}

#[cfg(feature = "defmt")]
impl<N: JointCount, D: Dim> defmt::Format for ParameterSet<N, D>
where
    DefaultAllocator: Allocator<D>,
{
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "ParameterSet({=[?]})", self.parameters.as_slice());
    }
}

impl<N: JointCount, D: Dim> ParameterSet<N, D>
where
    DefaultAllocator: Allocator<D>,
{
    /// The default identification set of `robot` ([`ParameterMask::default_for`]: the paper's
    /// 24 parameters for the ER10L-C10); for a fixed `D` an error unless it selects exactly `D`
    /// parameters.
    pub fn default_for<T: Real>(robot: &Robot<T, N>) -> Result<Self, KinematicsError> {
        Self::from_mask(&ParameterMask::default_for(robot))
    }

    /// The set selected by `mask`; for a fixed `D` an error unless it selects exactly `D`
    /// parameters ([`nalgebra::Dyn`] takes the count the mask selects).
    pub fn from_mask(mask: &ParameterMask<N>) -> Result<Self, KinematicsError> {
        let found = mask.count();
        // A fixed `D` is built from its own value (nalgebra's check of it then folds away: no
        // panic can remain in the controller's code), `Dyn` from the count found.
        let dim = match D::try_to_usize() {
            Some(expected) if found != expected => {
                return Err(KinematicsError::ParameterCount {
                    expected: u16::try_from(expected).unwrap_or(u16::MAX),
                    found: u16::try_from(found).unwrap_or(u16::MAX),
                });
            }
            Some(expected) => D::from_usize(expected),
            None => D::from_usize(found),
        };
        // Mapped from zeros: nalgebra's fill from an iterator of the enum kept a length check
        // (a panicking branch) on the controller.
        let mut parameters =
            OVector::<u8, D>::zeros_generic(dim, U1).map(|_| Parameter::Base(FrameParameter::Tx));
        for (slot, parameter) in parameters.as_mut_slice().iter_mut().zip(mask.iter()) {
            *slot = parameter;
        }
        Ok(Self {
            parameters,
            joints: mask.joint_count(),
        })
    }

    /// The parameters in packed order.
    pub fn parameters(&self) -> &[Parameter] {
        self.parameters.as_slice()
    }

    /// The number of parameters (the length of a packed vector).
    pub fn len(&self) -> usize {
        self.parameters.len()
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.parameters.is_empty()
    }

    /// The dimension of a packed vector, as nalgebra's generic constructors take it.
    pub fn dim(&self) -> D {
        self.parameters.shape_generic().0
    }

    /// A packed vector of zeros (mm, rad).
    pub fn zeros<T: Real>(&self) -> OVector<T, D> {
        OVector::<T, D>::zeros_generic(self.dim(), U1)
    }

    /// The joint count of the robot the set belongs to.
    pub fn joint_count(&self) -> N {
        self.joints
    }

    /// The mask that selects this set.
    pub fn mask(&self) -> ParameterMask<N> {
        let mut mask = ParameterMask::empty_for(self.joints);
        for p in self.parameters() {
            mask.set(*p, true);
        }
        mask
    }

    /// Position of `parameter` in the packed vector, if identified.
    pub fn index_of(&self, parameter: Parameter) -> Option<usize> {
        self.parameters().iter().position(|p| *p == parameter)
    }

    /// Packs the identified errors into a vector (mm and rad, canonical order).
    pub fn pack<T: Real>(&self, errors: &ParameterErrors<T, N>) -> OVector<T, D> {
        let mut x = self.zeros();
        for (xi, p) in x.iter_mut().zip(self.parameters()) {
            *xi = errors.get(*p).unwrap_or_else(T::zero);
        }
        x
    }

    /// `Ok` when `x` has one value per parameter of the set, else the [`ShapeError`].
    #[inline(always)]
    pub fn check_shape<T: Real>(&self, x: &OVector<T, D>) -> Result<(), ShapeError> {
        if x.len() == self.len() {
            Ok(())
        } else {
            Err(ShapeError {
                expected: self.len(),
                got: x.len(),
            })
        }
    }

    /// Writes the packed values into `errors`, leaving parameters outside the set unchanged; a
    /// vector of another length is refused and `errors` left as it was.
    #[cfg_attr(not(target_arch = "arm"), inline(always))]
    pub fn unpack_into<T: Real>(
        &self,
        x: &OVector<T, D>,
        errors: &mut ParameterErrors<T, N>,
    ) -> Result<(), ShapeError> {
        self.check_shape(x)?;
        self.write_into(x, errors);
        Ok(())
    }

    /// [`Self::unpack_into`] of a vector whose length the caller checked where it entered.
    #[cfg_attr(not(target_arch = "arm"), inline(always))]
    pub(crate) fn write_into<T: Real>(
        &self,
        x: &OVector<T, D>,
        errors: &mut ParameterErrors<T, N>,
    ) {
        // A plain slice: nalgebra's iterator checks for a column's end at every step, which a
        // run-time count (`Dyn`) does not fold away.
        for (xi, p) in x.as_slice().iter().zip(self.parameters()) {
            errors.set(*p, *xi);
        }
    }

    /// The errors with the packed values set and every other error zero; a vector of another
    /// length is refused.
    pub fn unpack<T: Real>(&self, x: &OVector<T, D>) -> Result<ParameterErrors<T, N>, ShapeError> {
        let mut errors = ParameterErrors::zeros_for(self.joints);
        self.unpack_into(x, &mut errors)?;
        Ok(errors)
    }

    /// The largest length difference (mm) and the largest angle difference (rad) between two
    /// packed vectors of this set, such as identified errors against the truth. A non-finite
    /// difference is returned as such, never hidden by a finite one; a vector of another length
    /// is refused.
    pub fn largest_differences<T: Real>(
        &self,
        a: &OVector<T, D>,
        b: &OVector<T, D>,
    ) -> Result<(T, T), ShapeError> {
        self.check_shape(a)?;
        self.check_shape(b)?;
        let (mut length, mut angle) = (T::zero(), T::zero());
        for (p, (x, y)) in self.parameters().iter().zip(a.iter().zip(b.iter())) {
            let d = (*x - *y).abs();
            let largest = if p.is_angle() {
                &mut angle
            } else {
                &mut length
            };
            if !d.finite() || (largest.finite() && d > *largest) {
                *largest = d;
            }
        }
        Ok((length, angle))
    }

    /// Builds an `R x D` matrix whose column k is `column(parameters[k])`.
    pub(crate) fn columns<T: Real, const R: usize>(
        &self,
        mut column: impl FnMut(Parameter) -> SVector<T, R>,
    ) -> OMatrix<T, Const<R>, D>
    where
        DefaultAllocator: Allocator<Const<R>, D>,
    {
        let mut m = OMatrix::<T, Const<R>, D>::zeros_generic(Const::<R>, self.dim());
        for (mut col, p) in m.column_iter_mut().zip(self.parameters()) {
            col.copy_from(&column(*p));
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::paper::{er10l_c10 as er10l, table2};
    use nalgebra::U6;
    use nalgebra::{U23, U24};
    extern crate std;
    use std::string::ToString;
    use std::vec::Vec;

    #[test]
    fn largest_differences_split_lengths_and_angles_and_keep_nan() {
        let set =
            ParameterSet::<U6, U24>::default_for(&crate::model::paper::er10l_c10::<f64>()).unwrap();
        let truth = set.pack(&crate::model::paper::table2::<f64>());
        let mut found = truth;
        found[0] += 0.25; // da1, mm
        found[1] -= 0.5; // da2, mm
        found[11] += 1e-3; // dalpha1, rad
        assert_eq!(set.largest_differences(&found, &truth), Ok((0.5, 1e-3)));
        found[23] = f64::NAN; // dtheta6
        assert!(set.largest_differences(&found, &truth).unwrap().1.is_nan());
        assert!(set.largest_differences(&truth, &found).unwrap().1.is_nan());
    }

    #[test]
    fn default_mask_gives_the_papers_24_parameters_in_order() {
        let mask = ParameterMask::default_for(&er10l::<f64>());
        let names: Vec<_> = mask.iter().map(|p| p.to_string()).collect();
        let expected = "da1 da2 da3 da4 da5 da6 dd1 dd3 dd4 dd5 dd6 dalpha1 dalpha2 dalpha3 dalpha4 \
                        dalpha5 dalpha6 dbeta2 dtheta1 dtheta2 dtheta3 dtheta4 dtheta5 dtheta6";
        assert_eq!(names.join(" "), expected);
        assert_eq!(mask.count(), 24);
    }

    #[test]
    fn all_parameters_are_in_the_canonical_order() {
        for count in [0, 1, 6, 7] {
            let names: Vec<_> = all_parameters(nalgebra::Dyn(count))
                .map(|p| p.to_string())
                .collect();
            let mut expected = Vec::new();
            for kind in ["da", "dd", "dalpha", "dbeta", "dtheta"] {
                expected.extend((1..=count).map(|j| std::format!("{kind}{j}")));
            }
            for frame in ["base", "tool"] {
                expected.extend(
                    ["tx", "ty", "tz", "rx", "ry", "rz"].map(|k| std::format!("{frame}_{k}")),
                );
            }
            assert_eq!(names, expected, "{count} joints");
        }
    }

    #[test]
    fn names_round_trip_for_all_parameters() {
        let all: Vec<_> = all_parameters(U6).collect();
        assert_eq!(all.len(), 5 * 6 + 12);
        for p in &all {
            assert_eq!(Parameter::from_name(&p.to_string(), 6), Some(*p));
        }
        assert_eq!(Parameter::from_name("da7", 6), None);
        assert_eq!(Parameter::from_name("da0", 6), None);
        assert_eq!(Parameter::from_name("dgamma1", 6), None);
        assert_eq!(Parameter::from_name("base_qx", 6), None);
        assert_eq!(all[0].to_string(), "da1");
        assert_eq!(all[41].to_string(), "tool_rz");
    }

    #[test]
    fn pack_and_unpack_round_trip_table2() {
        let mask = ParameterMask::default_for(&er10l::<f64>());
        let set = ParameterSet::<U6, U24>::from_mask(&mask).unwrap();
        let errors = table2::<f64>();
        let x = set.pack(&errors);
        // Packed order: da1 first, dd1 at index 6, dbeta2 at 17, dtheta6 last.
        assert_eq!(x[0], -0.4751);
        assert_eq!(x[6], -0.4221);
        assert_eq!(x[17], -0.0028);
        assert_eq!(x[23], 0.0083);
        // Table 2 has no error outside the 24 identified parameters, so unpack restores it exactly.
        assert_eq!(set.unpack(&x), Ok(errors));
        assert_eq!(set.mask(), mask);
        assert_eq!(
            set.index_of(Parameter::from_name("dbeta2", 6).unwrap()),
            Some(17)
        );
        assert_eq!(set.index_of(Parameter::from_name("dd2", 6).unwrap()), None);
    }

    #[test]
    fn wrong_parameter_count_is_an_error() {
        let mask = ParameterMask::default_for(&er10l::<f64>());
        assert_eq!(
            ParameterSet::<U6, U23>::from_mask(&mask),
            Err(KinematicsError::ParameterCount {
                expected: 23,
                found: 24
            })
        );
    }

    #[test]
    fn non_finite_error_is_named() {
        let mut errors = table2::<f64>();
        errors.joints[2].dbeta = f64::NAN;
        let err = errors.validate().unwrap_err();
        assert_eq!(err.to_string(), "parameter error dbeta3 is not finite");
        assert!(!errors.set(
            Parameter::Joint {
                joint: 7,
                kind: JointParameter::A
            },
            1.0
        ));
        assert_eq!(
            errors.get(Parameter::Joint {
                joint: 0,
                kind: JointParameter::A
            }),
            None
        );
    }
}
