//! Contacts with a known plane: the ball on the flange pressed on a flat surface whose place in
//! the robot's base frame is known (the table the robot stands on, a surface plate measured
//! once), joint readings only. Where [`crate::identify::common_point`] eliminates an unknown
//! plane, a known one is not a nuisance: each contact's residual is the signed distance of the
//! ball's centre from it, `r_i = sqrt(w_i) (n^T p_i - offset)`, one row per contact, its exact
//! Jacobian row `sqrt(w_i) n^T J_i` (`J_i` the position rows of the parameter Jacobian).
//!
//! The plane is the one the ball's centre lies on (the surface moved out along its normal by
//! the ball's radius). Unlike common points, a known plane sees where the arm stands along its
//! normal: joint 1's lift against a horizontal plane, and the scale through the plane's offset
//! from the base's origin; what it still cannot see, the identifiability analysis of the
//! stacked Jacobian says.

use crate::identify::common_point::Touch;
use crate::identify::residuals::{Residuals, is_left_out};
use crate::identify::{Problem, ProblemError};
use crate::model::parameters::{ParameterErrors, ParameterSet, ShapeError};
use crate::model::{JointCount, JointTable, Robot, check_count};
use crate::scalar::Real;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OVector, U3, U6, Vector3};

/// A plane known in the robot's base frame: the ball's centre `p` on it has `normal^T p =
/// offset_mm`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KnownPlane<T> {
    /// The unit normal, in the base frame.
    pub normal: [T; 3],
    /// The plane's signed distance from the base's origin along the normal, mm.
    pub offset_mm: T,
}

/// Why a known plane or its contacts were refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum KnownPlaneError {
    /// A contact names a plane that is not given (its number).
    UnknownPlane(u16),
    /// A normal not of unit length (within 1e-6) or an offset not finite.
    Value,
    /// A contact of another joint count than the robot's, or another problem of the model.
    Problem(ProblemError),
}

impl core::fmt::Display for KnownPlaneError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::UnknownPlane(p) => write!(f, "a contact names known plane {p}, which is not given"),
            Self::Value => f.write_str(
                "a known plane needs a unit normal (length 1 within 1e-6) and a finite offset in mm",
            ),
            Self::Problem(e) => write!(f, "{e}"),
        }
    }
}

impl core::error::Error for KnownPlaneError {}

/// Contacts of the ball with known planes, with the robot and the identified parameters: a
/// kind of measurement for [`crate::identify::lm::LeastSquares`].
#[derive(Clone, Debug)]
pub struct KnownPlaneContacts<'a, T: Real, N: JointCount, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// The robot (its tool frame is the ball), the fixed errors and the identified set.
    model: Problem<'a, T, N, D>,
    /// The contacts, each `point` numbering its plane in `planes`.
    contacts: &'a [Touch<T, N>],
    /// The planes.
    planes: &'a [KnownPlane<T>],
}

impl<'a, T: Real, N: JointCount, D: Dim> KnownPlaneContacts<'a, T, N, D>
where
    DefaultAllocator: Allocator<D> + Allocator<U6, D> + Allocator<U3, D>,
{
    /// The problem of identifying the parameters of `set` of `robot` (whose tool frame is the
    /// ball's centre) from `contacts` with `planes`; the other parameters keep `fixed`.
    /// Refused: a contact naming a plane not given, a plane's normal not of unit length or its
    /// offset not finite, a contact of another joint count than the robot's.
    pub fn new(
        robot: &Robot<T, N>,
        fixed: &ParameterErrors<T, N>,
        set: ParameterSet<N, D>,
        contacts: &'a [Touch<T, N>],
        planes: &'a [KnownPlane<T>],
    ) -> Result<Self, KnownPlaneError> {
        let model =
            Problem::new(robot, fixed, set, &[], T::zero()).map_err(KnownPlaneError::Problem)?;
        let tolerance = T::of(1e-6);
        for plane in planes {
            let length = Vector3::from(plane.normal).norm();
            if !(plane.offset_mm.finite() && (length - T::one()).abs() <= tolerance) {
                return Err(KnownPlaneError::Value);
            }
        }
        for contact in contacts {
            check_count(robot.joints.len(), contact.angles.cos.len())
                .map_err(|e| KnownPlaneError::Problem(ProblemError::Model(e)))?;
            if usize::from(contact.point) >= planes.len() {
                return Err(KnownPlaneError::UnknownPlane(contact.point));
            }
        }
        Ok(Self {
            model,
            contacts,
            planes,
        })
    }

    /// The plane a contact names (checked in [`Self::new`]).
    fn plane_of(&self, contact: &Touch<T, N>) -> Option<(Vector3<T>, T)> {
        (self.planes.get(usize::from(contact.point)))
            .map(|p| (Vector3::from(p.normal), p.offset_mm))
    }
}

/// One row per contact: `sqrt(w) (n^T p - offset)`, its Jacobian row `sqrt(w) n^T J`; the norm
/// of a contact is `|n^T p - offset|` (mm).
impl<T: Real, N: JointCount, D: Dim> Residuals for KnownPlaneContacts<'_, T, N, D>
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
        self.contacts.len()
    }

    fn rows(&self, left_out: &[bool]) -> u32 {
        let kept = (0..self.contacts.len())
            .filter(|i| !is_left_out(left_out, *i))
            .count();
        u32::try_from(kept).unwrap_or(u32::MAX)
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
        for (i, contact) in self.contacts.iter().enumerate() {
            let Some((normal, offset)) = self.plane_of(contact) else {
                continue;
            };
            if is_left_out(left_out, i) {
                continue;
            }
            let w = (contact.weight * robust.get(i).copied().unwrap_or_else(T::one)).sqrt();
            if with_jacobian {
                let (pose, twist) = model.parameter_jacobian(set, &contact.angles);
                let gradient = twist.fixed_rows::<3>(0).tr_mul(&normal);
                for (s, g) in scaled.iter_mut().zip(gradient.iter()) {
                    *s = *g * w;
                }
                row(&scaled, (normal.dot(&pose.translation.vector) - offset) * w);
            } else {
                let p = model.forward_angles(&contact.angles).translation.vector;
                row(&zero, (normal.dot(&p) - offset) * w);
            }
        }
    }

    fn for_each_norm(&self, x: &OVector<T, D>, left_out: &[bool], mut visit: impl FnMut(usize, T)) {
        let model = self.model.kinematics_unchecked(x);
        for (i, contact) in self.contacts.iter().enumerate() {
            let Some((normal, offset)) = self.plane_of(contact) else {
                continue;
            };
            if !is_left_out(left_out, i) {
                let p = model.forward_angles(&contact.angles).translation.vector;
                visit(i, (normal.dot(&p) - offset).abs());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::residuals::Stacked;
    use crate::model::FramePose;
    use crate::model::paper::{er10l_c10, table2};
    use nalgebra::{Dyn, U6};
    extern crate std;
    use std::vec::Vec;

    /// The ER10L-C10 with a ball 150 mm off its flange as the tool.
    fn robot() -> Robot<f64, U6> {
        let mut robot = er10l_c10::<f64>();
        robot.tool = FramePose {
            xyz: [20.0, -10.0, 150.0],
            rpy: [0.0, 0.0, 0.0],
        };
        robot
    }

    /// Ten configurations spread over the joints, each touching plane 0 or 1.
    fn contacts() -> Vec<Touch<f64, U6>> {
        (0..10)
            .map(|i| {
                let t = f64::from(i);
                let q = [
                    0.3 * t - 1.2,
                    -0.4 + 0.05 * t,
                    0.6 - 0.07 * t,
                    0.2 * t,
                    0.9,
                    -0.3 + 0.1 * t,
                ];
                Touch::new(&q, (i % 2) as u16, 1.0 + 0.1 * t).unwrap()
            })
            .collect()
    }

    const PLANES: [KnownPlane<f64>; 2] = [
        KnownPlane {
            normal: [0.0, 0.0, 1.0],
            offset_mm: -40.0,
        },
        KnownPlane {
            normal: [0.6, 0.0, 0.8],
            offset_mm: 900.0,
        },
    ];

    /// The rows equal `sqrt(w) (n^T p - offset)` from the forward kinematics, and the Jacobian
    /// equals central differences of them, at Table 2's errors; stacked after themselves, the
    /// rows come twice and a measurement left out of the second copy leaves its row out there.
    #[test]
    fn rows_and_jacobian_of_contacts_with_known_planes() {
        let robot = robot();
        let set = ParameterSet::<U6, Dyn>::default_for(&robot).unwrap();
        let fixed = ParameterErrors::zero();
        let contacts = contacts();
        let problem =
            KnownPlaneContacts::new(&robot, &fixed, set.clone(), &contacts, &PLANES).unwrap();
        let x = set.pack(&table2::<f64>());
        let rows = |x: &OVector<f64, Dyn>, jacobian: bool| {
            let (mut values, mut rows) = (Vec::new(), Vec::new());
            problem.for_each_row(x, &[], &[], jacobian, |j, r| {
                values.push(r);
                rows.push(j.iter().copied().collect::<Vec<f64>>());
            });
            (values, rows)
        };
        let (values, jacobian) = rows(&x, true);
        let model = crate::Kinematics::new(&robot, &table2::<f64>()).unwrap();
        for ((c, value), (i, _)) in contacts
            .iter()
            .zip(&values)
            .zip(contacts.iter().enumerate())
        {
            let plane = PLANES[usize::from(c.point)];
            let p = model.forward_angles(&c.angles).translation.vector;
            let expected =
                (Vector3::from(plane.normal).dot(&p) - plane.offset_mm) * c.weight.sqrt();
            assert!(
                (value - expected).abs() < 1e-9,
                "contact {i}: {value} against {expected}"
            );
        }
        for k in 0..set.len() {
            let h = if set.parameters()[k].is_angle() {
                1e-7
            } else {
                1e-5
            };
            let (mut up, mut down) = (x.clone(), x.clone());
            up[k] += h;
            down[k] -= h;
            let (plus, minus) = (rows(&up, false).0, rows(&down, false).0);
            for row in 0..values.len() {
                let numeric = (plus[row] - minus[row]) / (2.0 * h);
                assert!(
                    (numeric - jacobian[row][k]).abs() < 1e-5 * (1.0 + numeric.abs()),
                    "row {row}, parameter {k}"
                );
            }
        }
        let stacked = Stacked::new(problem.clone(), problem.clone()).unwrap();
        assert_eq!(stacked.measurements(), 20);
        let mut left_out = [false; 20];
        left_out[13] = true;
        assert_eq!(stacked.rows(&left_out), 19);
        let mut stacked_values = Vec::new();
        stacked.for_each_row(&x, &left_out, &[], false, |_, r| stacked_values.push(r));
        let mut expected = values.clone();
        expected.extend(
            values
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != 3)
                .map(|(_, v)| *v),
        );
        assert_eq!(stacked_values, expected);
        let mut norms = Vec::new();
        stacked.for_each_norm(&x, &left_out, |i, n| norms.push((i, n)));
        assert_eq!(norms.len(), 19);
        assert_eq!(norms[12].0, 12);
        assert_eq!(norms[13].0, 14);
    }

    /// A contact naming a plane not given, and a normal not of unit length, are refused.
    #[test]
    fn a_missing_plane_or_a_normal_not_of_unit_length_is_refused() {
        let robot = robot();
        let set = ParameterSet::<U6, Dyn>::default_for(&robot).unwrap();
        let fixed = ParameterErrors::zero();
        let contacts = contacts();
        let one = &PLANES[..1];
        let refused = KnownPlaneContacts::new(&robot, &fixed, set.clone(), &contacts, one);
        assert_eq!(refused.err(), Some(KnownPlaneError::UnknownPlane(1)));
        let long = [KnownPlane {
            normal: [0.0, 0.0, 2.0],
            offset_mm: 0.0,
        }; 2];
        let refused = KnownPlaneContacts::new(&robot, &fixed, set, &contacts, &long);
        assert_eq!(refused.err(), Some(KnownPlaneError::Value));
    }
}
