//! Forward kinematics of the actual model: `T = T_base A_1 ... A_N T_tool` (paper eq. 2-3).

use crate::kinematics::mdh::{LaneFrame, Lanes, PreparedJoint};
use crate::math::so3;
use crate::math::trig;
use crate::model::KinematicsError;
use crate::model::parameters::{FrameErrors, ParameterErrors};
use crate::model::{JointCount, JointTable};
use crate::model::{Robot, check_count, joint_number};
use crate::scalar::Real;
use nalgebra::{IsometryMatrix3, Matrix3, Rotation3, Translation3, Vector3};

/// A rigid pose: rotation matrix and translation (mm).
pub type Pose<T> = IsometryMatrix3<T>;

/// Sine and cosine of N joint readings, computed once per measured pose (no trig afterwards).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointAngles<T: Real, N: JointCount> {
    /// `cos q_i`.
    pub cos: N::Table<T>,
    /// `sin q_i`.
    pub sin: N::Table<T>,
}

impl<T: Real, N: JointCount> JointAngles<T, N> {
    /// From joint readings `q` (rad); an error names the first non-finite reading.
    pub fn new(q: &N::Table<T>) -> Result<Self, KinematicsError> {
        let joints = N::of(q);
        let mut angles = Self {
            cos: joints.table(T::one()),
            sin: joints.table(T::zero()),
        };
        for (j, ((qi, c), s)) in q
            .iter()
            .zip(angles.cos.iter_mut())
            .zip(angles.sin.iter_mut())
            .enumerate()
        {
            if !qi.finite() {
                return Err(KinematicsError::NonFiniteJoint {
                    joint: joint_number(j),
                });
            }
            (*s, *c) = qi.sin_cos_fast();
        }
        Ok(angles)
    }
}

/// The actual model (nominal + errors) prepared for evaluation: constant trigonometry done once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kinematics<T: Real, N: JointCount> {
    joints: N::Table<PreparedJoint<T>>,
    base: Pose<T>,
    tool: Pose<T>,
    /// World axes of the base rotation errors `rx, ry, rz` (columns), relative to the parent.
    base_axes: Matrix3<T>,
    /// Axes of the tool rotation errors `rx, ry, rz` (columns) in the flange frame.
    tool_axes: Matrix3<T>,
    /// The tool frame is exactly the identity (its product is skipped).
    tool_is_identity: bool,
}

/// A frame with the rotation-error axes of its `R_nominal Rz(rz) Ry(ry) Rx(rx)` parametrisation.
#[cfg_attr(not(target_arch = "arm"), inline(always))]
fn frame_with_errors<T: Real>(nominal: &Pose<T>, errors: &FrameErrors<T>) -> (Pose<T>, Matrix3<T>) {
    let zero = |v: &[T; 3]| v.iter().all(|x| *x == T::zero());
    if zero(&errors.translation) && zero(&errors.rotation) {
        // Rz(0) = I: the error axes are the nominal frame's own axes.
        return (*nominal, *nominal.rotation.matrix());
    }
    let [tx, ty, tz] = errors.translation;
    let [rx, ry, rz] = errors.rotation;
    let r_nominal = nominal.rotation.matrix();
    let rotation = nominal.rotation * so3::rotation_rpy(rx, ry, rz);
    let yaw_then = r_nominal * so3::rotation_rpy(T::zero(), T::zero(), rz).matrix();
    let axes = Matrix3::from_columns(&[
        rotation.matrix().column(0).into_owned(),
        yaw_then.column(1).into_owned(),
        r_nominal.column(2).into_owned(),
    ]);
    let translation = nominal.translation.vector + Vector3::new(tx, ty, tz);
    (
        Pose::from_parts(Translation3::from(translation), rotation),
        axes,
    )
}

/// The nominal robot with its constant trigonometry done once, ready to produce the actual model
/// for many candidate error vectors (the swarm and least squares evaluate thousands).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedRobot<T: Real, N: JointCount> {
    joints: N::Table<NominalJoint<T>>,
    base: Pose<T>,
    tool: Pose<T>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct NominalJoint<T> {
    a: T,
    d: T,
    /// `(cos, sin)` of the nominal alpha, beta and theta_offset.
    alpha: (T, T),
    beta: (T, T),
    offset: (T, T),
}

impl<T: Real, N: JointCount> PreparedRobot<T, N> {
    /// Prepares a nominal robot (not validated: see [`Robot::validate`]).
    pub fn new(robot: &Robot<T, N>) -> Self {
        let cos_sin = |x: T| {
            let (s, c) = x.sin_cos_fast();
            (c, s)
        };
        let mut joints = robot.joint_count().table(NominalJoint {
            a: T::zero(),
            d: T::zero(),
            alpha: (T::one(), T::zero()),
            beta: (T::one(), T::zero()),
            offset: (T::one(), T::zero()),
        });
        for (prepared, joint) in joints.iter_mut().zip(robot.joints.iter()) {
            *prepared = NominalJoint {
                a: joint.a,
                d: joint.d,
                alpha: cos_sin(joint.alpha),
                beta: cos_sin(joint.beta),
                offset: cos_sin(joint.theta_offset),
            };
        }
        Self {
            joints,
            base: robot.base.isometry(),
            tool: robot.tool.isometry(),
        }
    }

    /// The actual model for `errors` (mm, rad). The trigonometry of the joint errors uses angle
    /// addition and the small-angle polynomial of `trig::sin_cos_small`, so for errors within
    /// 0.1 rad no libm call is made. Non-finite errors give a model that evaluates to NaN (no panic);
    /// [`Kinematics::new`] checks them first.
    #[cfg_attr(not(target_arch = "arm"), inline(always))]
    pub fn actual(&self, errors: &ParameterErrors<T, N>) -> Kinematics<T, N> {
        let mut joints = N::of(&self.joints).table(PreparedJoint::from_trig(
            T::zero(),
            T::zero(),
            (T::one(), T::zero()),
            (T::one(), T::zero()),
            (T::one(), T::zero()),
        ));
        for (prepared, (n, e)) in joints
            .iter_mut()
            .zip(self.joints.iter().zip(errors.joints.iter()))
        {
            let with_error = |nominal: (T, T), error: T| {
                if error == T::zero() {
                    return nominal;
                }
                let (s, c) = trig::sin_cos_small(error);
                trig::add(nominal, (c, s))
            };
            *prepared = PreparedJoint::from_trig(
                n.a + e.da,
                n.d + e.dd,
                with_error(n.alpha, e.dalpha),
                with_error(n.beta, e.dbeta),
                with_error(n.offset, e.dtheta),
            );
        }
        let (base, base_axes) = frame_with_errors(&self.base, &errors.base);
        let (tool, tool_axes) = frame_with_errors(&self.tool, &errors.tool);
        Kinematics {
            joints,
            base,
            tool,
            base_axes,
            tool_axes,
            tool_is_identity: tool == Pose::identity(),
        }
    }
}

/// Every intermediate quantity of one forward kinematics, kept for the Jacobians.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Chain<T: Real, N: JointCount> {
    /// Origin of the frame before joint i (`o_{i-1}`), world, mm.
    pub before_origin: N::Table<Vector3<T>>,
    /// z axis of the frame before joint i (`z_{i-1}`): the axis of `theta` and `d`.
    pub before_z: N::Table<Vector3<T>>,
    /// x axis of `F_{i-1} Rz(theta_i)`: the axis of `a` and `alpha`.
    pub x_axis: N::Table<Vector3<T>>,
    /// Origin of the frame of joint i (`o_i`), world, mm.
    pub origin: N::Table<Vector3<T>>,
    /// y axis of the frame of joint i: the axis of `beta`.
    pub y_axis: N::Table<Vector3<T>>,
    /// Flange frame `T_base A_1 ... A_N`.
    pub flange: Pose<T>,
    /// End pose, flange * tool.
    pub end: Pose<T>,
}

impl<T: Real, N: JointCount> Kinematics<T, N> {
    /// The actual model `robot + errors`; an error names the first non-finite value.
    pub fn new(
        robot: &Robot<T, N>,
        errors: &ParameterErrors<T, N>,
    ) -> Result<Self, KinematicsError> {
        robot.validate()?;
        errors.validate()?;
        check_count(robot.joints.len(), errors.joints.len())?;
        Ok(PreparedRobot::new(robot).actual(errors))
    }

    /// The nominal model (all errors zero).
    pub fn nominal(robot: &Robot<T, N>) -> Result<Self, KinematicsError> {
        Self::new(robot, &ParameterErrors::zeros_for(robot.joint_count()))
    }

    /// The base frame of the actual model.
    pub fn base(&self) -> &Pose<T> {
        &self.base
    }

    /// The tool frame of the actual model.
    pub fn tool(&self) -> &Pose<T> {
        &self.tool
    }

    /// The prepared joints, joint 1 first.
    pub(crate) fn joints(&self) -> &N::Table<PreparedJoint<T>> {
        &self.joints
    }

    /// The joint count.
    pub fn joint_count(&self) -> N {
        N::of(&self.joints)
    }

    /// End pose (mm) for joint readings `q` (rad). Error: a non-finite reading, or another
    /// joint count than the model's.
    pub fn forward(&self, q: &N::Table<T>) -> Result<Pose<T>, KinematicsError> {
        check_count(self.joints.len(), q.len())?;
        Ok(self.forward_angles(&JointAngles::new(q)?))
    }

    /// End pose (mm) for precomputed joint sines and cosines; does no trigonometry.
    pub fn forward_angles(&self, angles: &JointAngles<T, N>) -> Pose<T> {
        let mut rotation = *self.base.rotation.matrix();
        let mut origin = self.base.translation.vector;
        for ((joint, c), s) in self
            .joints
            .iter()
            .zip(angles.cos.iter())
            .zip(angles.sin.iter())
        {
            let (ct, st) = joint.theta(*c, *s);
            joint.append(&mut rotation, &mut origin, ct, st);
        }
        if !self.tool_is_identity {
            origin += rotation * self.tool.translation.vector;
            rotation *= self.tool.rotation.matrix();
        }
        Pose::from_parts(
            Translation3::from(origin),
            Rotation3::from_matrix_unchecked(rotation),
        )
    }

    /// End frames of `L` poses at once from their joint cosines and sines as lanes (the
    /// structure-of-arrays form of [`Kinematics::forward_angles`], which the compiler vectorises).
    #[inline(always)] // into `Objective::value_of_lanes` and wherever that is inlined
    pub(crate) fn forward_lanes<const L: usize>(
        &self,
        cos: &N::Table<Lanes<T, L>>,
        sin: &N::Table<Lanes<T, L>>,
    ) -> LaneFrame<T, L> {
        let r = self.base.rotation.matrix();
        let t = &self.base.translation.vector;
        let repeat = Lanes::<T, L>::repeat;
        let column = |j: usize| [0, 1, 2].map(|i| repeat(r[(i, j)]));
        let mut frame = LaneFrame {
            columns: [column(0), column(1), column(2)],
            origin: [repeat(t.x), repeat(t.y), repeat(t.z)],
        };
        for ((joint, c), s) in self.joints.iter().zip(cos.iter()).zip(sin.iter()) {
            joint.append_lanes(&mut frame, c, s);
        }
        if !self.tool_is_identity {
            let rt = self.tool.rotation.matrix();
            let tt = &self.tool.translation.vector;
            let [c0, c1, c2] = frame.columns;
            let mix = |a: T, b: T, c: T| -> [Lanes<T, L>; 3] {
                [0, 1, 2].map(|i| {
                    let pick =
                        |col: &[Lanes<T, L>; 3]| col.get(i).copied().unwrap_or_else(Lanes::zeros);
                    pick(&c0) * a + pick(&c1) * b + pick(&c2) * c
                })
            };
            let offset = mix(tt.x, tt.y, tt.z);
            for (o, d) in frame.origin.iter_mut().zip(offset.iter()) {
                *o += d;
            }
            frame.columns = [0, 1, 2].map(|j| mix(rt[(0, j)], rt[(1, j)], rt[(2, j)]));
        }
        frame
    }

    /// Forward kinematics keeping every joint's axes and origins (for the Jacobians).
    pub(crate) fn chain(&self, angles: &JointAngles<T, N>) -> Chain<T, N> {
        let zero: N::Table<Vector3<T>> = N::of(&self.joints).table(Vector3::zeros());
        let mut chain: Chain<T, N> = Chain {
            before_origin: zero,
            before_z: zero,
            x_axis: zero,
            origin: zero,
            y_axis: zero,
            flange: self.base,
            end: self.base,
        };
        let mut rotation = *self.base.rotation.matrix();
        let mut origin = self.base.translation.vector;
        let per_joint = chain
            .before_origin
            .iter_mut()
            .zip(chain.before_z.iter_mut())
            .zip(chain.x_axis.iter_mut())
            .zip(chain.origin.iter_mut())
            .zip(chain.y_axis.iter_mut());
        let inputs = self
            .joints
            .iter()
            .zip(angles.cos.iter())
            .zip(angles.sin.iter());
        for (((((o_prev, z_prev), x_axis), o), y_axis), ((joint, c), s)) in per_joint.zip(inputs) {
            *o_prev = origin;
            *z_prev = rotation.column(2).into_owned();
            let (ct, st) = joint.theta(*c, *s);
            *x_axis = joint.append(&mut rotation, &mut origin, ct, st);
            *o = origin;
            *y_axis = rotation.column(1).into_owned();
        }
        chain.flange = Pose::from_parts(
            Translation3::from(origin),
            Rotation3::from_matrix_unchecked(rotation),
        );
        chain.end = chain.flange * self.tool;
        chain
    }

    pub(crate) fn base_axes(&self) -> &Matrix3<T> {
        &self.base_axes
    }

    pub(crate) fn tool_axes(&self) -> &Matrix3<T> {
        &self.tool_axes
    }
}
