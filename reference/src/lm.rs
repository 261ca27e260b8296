//! An independent float64 reference optimiser, used only to check the core's least squares: the
//! `levenberg-marquardt` crate (MINPACK's algorithm, on its own nalgebra version) minimising the
//! same residual `[dp; sqrt(k) dr]` (times `sqrt(weight)`) with the reference kinematics of
//! [`super::kinematics`] and a central-difference Jacobian. No calib-core code is involved.

use super::kinematics::{Mat4, RefModel, RefRobot, pose_error};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra034::{DMatrix, DVector, Dyn, Owned};

/// Where a named parameter lives in the reference model's error arrays.
#[derive(Clone, Copy, Debug)]
enum Slot {
    /// (joint index, index in `[da, dalpha, dtheta, dd, dbeta]`).
    Joint(usize, usize),
    /// Index in the base errors `[tx, ty, tz, rx, ry, rz]`.
    Base(usize),
    /// Index in the tool errors.
    Tool(usize),
}

fn slot(name: &str) -> Option<Slot> {
    const FRAME: [&str; 6] = ["tx", "ty", "tz", "rx", "ry", "rz"];
    if let Some(rest) = name.strip_prefix("base_") {
        return FRAME.iter().position(|f| *f == rest).map(Slot::Base);
    }
    if let Some(rest) = name.strip_prefix("tool_") {
        return FRAME.iter().position(|f| *f == rest).map(Slot::Tool);
    }
    let rest = name.strip_prefix('d')?;
    let split = rest.find(|c: char| c.is_ascii_digit())?;
    let (kind, number) = rest.split_at(split);
    let joint: usize = number.parse().ok()?;
    let index = ["a", "alpha", "theta", "d", "beta"]
        .iter()
        .position(|k| *k == kind)?;
    (joint >= 1).then_some(Slot::Joint(joint - 1, index))
}

/// One measured pose: joint readings (rad), the measured transform (translation in mm), whether
/// its orientation was measured, and its weight.
#[derive(Clone, Debug, PartialEq)]
pub struct Observation {
    /// Joint readings, rad.
    pub q: Vec<f64>,
    /// The measured pose; its rotation counts only when `oriented`.
    pub pose: Mat4,
    /// Whether the orientation was measured.
    pub oriented: bool,
    /// The residual's weight (its square root multiplies the residual).
    pub weight: f64,
}

/// A parameter name the reference does not know.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error(
    "unknown parameter {0} (known: da1, dalpha1, dtheta1, dd1, dbeta1, ..., base_tx..base_rz, tool_tx..tool_rz)"
)]
pub struct UnknownParameter(pub String);

/// The fitting problem.
struct Problem<'a> {
    robot: &'a RefRobot,
    slots: Vec<Slot>,
    /// (q rad, measured transform, has orientation, sqrt weight).
    poses: Vec<(Vec<f64>, Mat4, bool, f64)>,
    sqrt_k: f64,
    x: DVector<f64>,
}

impl Problem<'_> {
    fn model(&self, x: &DVector<f64>) -> RefModel {
        let joints = self.robot.joints.len();
        let mut joint_errors = vec![[0.0; 5]; joints];
        let mut base = [0.0; 6];
        let mut tool = [0.0; 6];
        for (slot, value) in self.slots.iter().zip(x.iter()) {
            match *slot {
                Slot::Joint(j, i) => {
                    if let Some(e) = joint_errors.get_mut(j) {
                        e[i] = *value;
                    }
                }
                Slot::Base(i) => base[i] = *value,
                Slot::Tool(i) => tool[i] = *value,
            }
        }
        RefModel::new(self.robot, &joint_errors, &base, &tool)
    }

    fn residuals_at(&self, x: &DVector<f64>) -> DVector<f64> {
        let model = self.model(x);
        let mut r = Vec::with_capacity(self.poses.len() * 6);
        for (q, measured, oriented, w) in &self.poses {
            let e = pose_error(measured, &model.forward(q));
            r.extend(e[..3].iter().map(|v| v * w));
            if *oriented {
                r.extend(e[3..].iter().map(|v| v * w * self.sqrt_k));
            }
        }
        DVector::from_vec(r)
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.x.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.x.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        Some(self.residuals_at(&self.x))
    }

    /// Five-point central differences, `(8 (r(x+h) - r(x-h)) - (r(x+2h) - r(x-2h))) / 12h` with
    /// `h = 1e-3` (mm or rad): truncation error `h^4/30` times the fifth derivative, rounding
    /// about `eps |r| / h`, both near 1e-13 of the derivative for arm-sized models. The stationary
    /// point of noisy data moves with the Jacobian's error times the residual, so the two-point
    /// rule with `h = 1e-6` (rounding 1e-10 of it) put the reference 1.2e-9 rad from the exact
    /// minimum on the Barrett WAM's real data (2.4 mm residuals).
    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let base = self.residuals_at(&self.x);
        let mut jacobian = DMatrix::zeros(base.len(), self.x.len());
        let h = 1e-3;
        let at = |j: usize, step: f64| {
            let mut x = self.x.clone();
            x[j] += step;
            self.residuals_at(&x)
        };
        for j in 0..self.x.len() {
            let near = at(j, h) - at(j, -h);
            let far = at(j, 2.0 * h) - at(j, -2.0 * h);
            jacobian.set_column(j, &((near * 8.0 - far) / (12.0 * h)));
        }
        Some(jacobian)
    }
}

/// The reference fit of the named parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceFit {
    /// (name, error in mm or rad), in the order asked for.
    pub errors: Vec<(String, f64)>,
    /// `0.5 |r|^2` at the result.
    pub cost: f64,
    /// Residual evaluations reported by the crate.
    pub evaluations: usize,
}

/// Fits the errors of `names` (names such as `da1`, `dbeta2`) of `robot` to `observations`
/// from `start`; `k` weighs the orientation residual (rad) against the position residual (mm).
pub fn fit(
    robot: &RefRobot,
    names: &[String],
    observations: &[Observation],
    k: f64,
    start: &[f64],
) -> Result<ReferenceFit, UnknownParameter> {
    let slots = names
        .iter()
        .map(|n| slot(n).ok_or_else(|| UnknownParameter(n.clone())))
        .collect::<Result<Vec<_>, _>>()?;
    let poses = observations
        .iter()
        .map(|o| (o.q.clone(), o.pose, o.oriented, o.weight.sqrt()))
        .collect();
    let problem = Problem {
        robot,
        slots,
        poses,
        sqrt_k: k.sqrt(),
        x: DVector::from_column_slice(start),
    };
    let (solved, report) = LevenbergMarquardt::new()
        .with_ftol(1e-15)
        .with_xtol(1e-15)
        .with_gtol(1e-15)
        .with_patience(200)
        .minimize(problem);
    let residuals = solved.residuals_at(&solved.x);
    Ok(ReferenceFit {
        errors: names
            .iter()
            .cloned()
            .zip(solved.x.iter().copied())
            .collect(),
        cost: 0.5 * residuals.norm_squared(),
        evaluations: report.number_of_evaluations,
    })
}

/// Root mean square of the absolute position error `|dp|` (mm) of `model` on `observations`.
pub fn rms_position_error(model: &RefModel, observations: &[Observation]) -> f64 {
    let sum: f64 = observations
        .iter()
        .map(|o| {
            let t = model.forward(&o.q);
            (0..3)
                .map(|i| (o.pose[i][3] - t[i][3]).powi(2))
                .sum::<f64>()
        })
        .sum();
    (sum / observations.len().max(1) as f64).sqrt()
}
