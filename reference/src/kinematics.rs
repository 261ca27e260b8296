//! An independent float64 reference of the kinematics, used only to check the core.
//!
//! Written plainly from the elementary homogeneous transforms `Rz, Tz, Tx, Rx, Ry` as 4x4 arrays,
//! with `std` trigonometry, no nalgebra and no call into `calib-core`, so that agreement between
//! the two means something. Slow on purpose: clarity over speed.

/// A homogeneous transform, row-major: `m[row][col]`.
pub type Mat4 = [[f64; 4]; 4];

/// The identity transform.
pub const IDENTITY: Mat4 = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// Product `a * b`.
pub fn mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut m = [[0.0; 4]; 4];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, value) in row.iter_mut().enumerate() {
            *value = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// Rotation about x by `t` rad.
pub fn rx(t: f64) -> Mat4 {
    let (s, c) = t.sin_cos();
    [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, c, -s, 0.0],
        [0.0, s, c, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// Rotation about y by `t` rad.
pub fn ry(t: f64) -> Mat4 {
    let (s, c) = t.sin_cos();
    [
        [c, 0.0, s, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [-s, 0.0, c, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// Rotation about z by `t` rad.
pub fn rz(t: f64) -> Mat4 {
    let (s, c) = t.sin_cos();
    [
        [c, -s, 0.0, 0.0],
        [s, c, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// Translation by `(x, y, z)` mm.
pub fn trans(x: f64, y: f64, z: f64) -> Mat4 {
    let mut m = IDENTITY;
    m[0][3] = x;
    m[1][3] = y;
    m[2][3] = z;
    m
}

/// One joint in mm and rad.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefJoint {
    /// Link length, mm.
    pub a: f64,
    /// Twist about x, rad.
    pub alpha: f64,
    /// Joint zero offset, rad.
    pub theta_offset: f64,
    /// Offset along z, mm.
    pub d: f64,
    /// Twist about y, rad.
    pub beta: f64,
}

/// A frame error: `[tx, ty, tz]` mm added to the translation, `[rx, ry, rz]` rad composed as
/// `R_nominal Rz(rz) Ry(ry) Rx(rx)`.
pub type RefFrameErrors = [f64; 6];

/// A nominal frame (base or tool): translation in mm, then the rotation `Rz(rz) Ry(ry) Rx(rx)`
/// of `rpy = [rx, ry, rz]` in rad.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RefFrame {
    /// Translation, mm.
    pub xyz_mm: [f64; 3],
    /// Roll, pitch, yaw about x, y, z, rad.
    pub rpy_rad: [f64; 3],
}

/// A nominal robot as a robot file states it, in mm and rad: joint 1 first, base and tool.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RefRobot {
    /// Nominal joints, joint 1 first.
    pub joints: Vec<RefJoint>,
    /// Nominal base frame.
    pub base: RefFrame,
    /// Nominal tool frame.
    pub tool: RefFrame,
}

/// The reference model: joints, base and tool as homogeneous transforms.
#[derive(Clone, Debug, PartialEq)]
pub struct RefModel {
    /// Joints, joint 1 first.
    pub joints: Vec<RefJoint>,
    /// Base transform.
    pub base: Mat4,
    /// Tool transform.
    pub tool: Mat4,
}

fn frame(nominal: &RefFrame, errors: &RefFrameErrors) -> Mat4 {
    let [x, y, z] = nominal.xyz_mm;
    let [roll, pitch, yaw] = nominal.rpy_rad;
    let t = trans(x + errors[0], y + errors[1], z + errors[2]);
    let rotation = mul(&mul(&rz(yaw), &ry(pitch)), &rx(roll));
    let error = mul(&mul(&rz(errors[5]), &ry(errors[4])), &rx(errors[3]));
    mul(&t, &mul(&rotation, &error))
}

impl RefModel {
    /// The actual model of a nominal robot plus errors: per joint `[da, dalpha, dtheta, dd,
    /// dbeta]` (mm, rad), base and tool errors. Missing joint errors count as zero.
    pub fn new(
        robot: &RefRobot,
        joint_errors: &[[f64; 5]],
        base_errors: &RefFrameErrors,
        tool_errors: &RefFrameErrors,
    ) -> Self {
        let joints = robot
            .joints
            .iter()
            .enumerate()
            .map(|(i, j)| {
                let e = joint_errors.get(i).copied().unwrap_or([0.0; 5]);
                RefJoint {
                    a: j.a + e[0],
                    alpha: j.alpha + e[1],
                    theta_offset: j.theta_offset + e[2],
                    d: j.d + e[3],
                    beta: j.beta + e[4],
                }
            })
            .collect();
        Self {
            joints,
            base: frame(&robot.base, base_errors),
            tool: frame(&robot.tool, tool_errors),
        }
    }

    /// End pose `T_base A_1 ... A_N T_tool` for joint readings `q` (rad), eq. (1)-(3).
    pub fn forward(&self, q: &[f64]) -> Mat4 {
        let mut t = self.base;
        for (j, qi) in self.joints.iter().zip(q) {
            let a = mul(
                &mul(
                    &mul(
                        &mul(&rz(qi + j.theta_offset), &trans(0.0, 0.0, j.d)),
                        &trans(j.a, 0.0, 0.0),
                    ),
                    &rx(j.alpha),
                ),
                &ry(j.beta),
            );
            t = mul(&t, &a);
        }
        mul(&t, &self.tool)
    }
}

/// Unit quaternion `[w, x, y, z]` of the rotation part, `w >= 0` (Shepperd's method).
pub fn quaternion(m: &Mat4) -> [f64; 4] {
    let trace = m[0][0] + m[1][1] + m[2][2];
    let q = if trace > 0.0 {
        let s = 2.0 * (1.0 + trace).sqrt();
        [
            s / 4.0,
            (m[2][1] - m[1][2]) / s,
            (m[0][2] - m[2][0]) / s,
            (m[1][0] - m[0][1]) / s,
        ]
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = 2.0 * (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt();
        [
            (m[2][1] - m[1][2]) / s,
            s / 4.0,
            (m[0][1] + m[1][0]) / s,
            (m[0][2] + m[2][0]) / s,
        ]
    } else if m[1][1] > m[2][2] {
        let s = 2.0 * (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt();
        [
            (m[0][2] - m[2][0]) / s,
            (m[0][1] + m[1][0]) / s,
            s / 4.0,
            (m[1][2] + m[2][1]) / s,
        ]
    } else {
        let s = 2.0 * (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt();
        [
            (m[1][0] - m[0][1]) / s,
            (m[0][2] + m[2][0]) / s,
            (m[1][2] + m[2][1]) / s,
            s / 4.0,
        ]
    };
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
    q.map(|v| sign * v / norm)
}

/// Rotation vector (rad) of the rotation part, through the quaternion: `2 atan2(|v|, w) v / |v|`.
pub fn rotation_vector(m: &Mat4) -> [f64; 3] {
    let [w, x, y, z] = quaternion(m);
    let norm = (x * x + y * y + z * z).sqrt();
    if norm == 0.0 {
        return [0.0; 3];
    }
    let angle = 2.0 * norm.atan2(w);
    [x * angle / norm, y * angle / norm, z * angle / norm]
}

/// Pose error of docs/ARCHITECTURE.md: `[dp (mm); dr (rad)]` with `dp = p_m - p_p`, `dr = log(R_m R_p^T)`.
pub fn pose_error(measured: &Mat4, predicted: &Mat4) -> [f64; 6] {
    // R_m R_p^T as a 4x4 with zero translation.
    let mut relative = IDENTITY;
    for (i, row) in relative.iter_mut().take(3).enumerate() {
        for (j, value) in row.iter_mut().take(3).enumerate() {
            *value = (0..3).map(|k| measured[i][k] * predicted[j][k]).sum();
        }
    }
    let r = rotation_vector(&relative);
    [
        measured[0][3] - predicted[0][3],
        measured[1][3] - predicted[1][3],
        measured[2][3] - predicted[2][3],
        r[0],
        r[1],
        r[2],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elementary_rotations_are_right_handed() {
        // Rz(90 deg) maps x to y; Rx(90 deg) maps y to z; Ry(90 deg) maps z to x.
        let h = std::f64::consts::FRAC_PI_2;
        assert!((rz(h)[1][0] - 1.0).abs() < 1e-15);
        assert!((rx(h)[2][1] - 1.0).abs() < 1e-15);
        assert!((ry(h)[0][2] - 1.0).abs() < 1e-15);
    }

    #[test]
    fn rotation_vector_of_a_known_rotation() {
        let m = mul(&trans(1.0, 2.0, 3.0), &rz(0.7));
        let r = rotation_vector(&m);
        assert!((r[2] - 0.7).abs() < 1e-15 && r[0] == 0.0 && r[1] == 0.0);
    }
}
