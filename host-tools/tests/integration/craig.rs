//! Robot files in Craig's modified DH convention: the converted model reproduces the published
//! forward kinematics (products of `Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)` computed
//! here from the published table, independently of the conversion); the shipped 7-joint robots
//! read and stand straight at their zero posture; a file mixing conventions is refused.

use calib_core::Kinematics;
use host_tools::io::robot_file::{RobotFile, RobotModel};
use nalgebra::{Matrix4, Vector3};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::path::Path;

fn rx(angle: f64) -> Matrix4<f64> {
    let (s, c) = angle.sin_cos();
    Matrix4::new(
        1.0, 0.0, 0.0, 0.0, 0.0, c, -s, 0.0, 0.0, s, c, 0.0, 0.0, 0.0, 0.0, 1.0,
    )
}

fn rz(angle: f64) -> Matrix4<f64> {
    let (s, c) = angle.sin_cos();
    Matrix4::new(
        c, -s, 0.0, 0.0, s, c, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    )
}

fn translation(x: f64, y: f64, z: f64) -> Matrix4<f64> {
    Matrix4::new_translation(&Vector3::new(x, y, z))
}

/// `Rz(yaw) Ry(pitch) Rx(roll)` with a translation, as a robot file's frame.
fn frame(xyz: [f64; 3], rpy_deg: [f64; 3]) -> Matrix4<f64> {
    let [r, p, y] = rpy_deg.map(f64::to_radians);
    let ry = {
        let (s, c) = p.sin_cos();
        Matrix4::new(
            c, 0.0, s, 0.0, 0.0, 1.0, 0.0, 0.0, -s, 0.0, c, 0.0, 0.0, 0.0, 0.0, 1.0,
        )
    };
    translation(xyz[0], xyz[1], xyz[2]) * rz(y) * ry * rx(r)
}

/// A Craig row `(alpha_{i-1} deg, a_{i-1} mm, d_i mm)` at joint angle `theta` (rad).
fn craig(row: (f64, f64, f64), theta: f64) -> Matrix4<f64> {
    let (alpha, a, d) = row;
    rx(alpha.to_radians()) * translation(a, 0.0, 0.0) * rz(theta) * translation(0.0, 0.0, d)
}

/// The largest position (mm) and rotation-matrix element differences of our model's forward
/// kinematics from `expected` over `samples` random joint vectors within the joint limits (and
/// one turn).
fn worst_difference(
    model: &RobotModel,
    samples: usize,
    expected: impl Fn(&[f64; 7]) -> Matrix4<f64>,
) -> (f64, f64) {
    let kinematics = Kinematics::nominal(&model.robot).unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
    let (mut position, mut rotation) = (0.0f64, 0.0f64);
    for _ in 0..samples {
        let q = calib_core::model::JointVec::<f64>::from_fn(7, |j| {
            let limits = model.robot.limits[j];
            let bound = |v: f64| v.clamp(-std::f64::consts::PI, std::f64::consts::PI);
            rng.random_range(bound(limits.lower)..bound(limits.upper))
        });
        let ours = kinematics.forward(&q).unwrap().to_homogeneous();
        let theirs = expected(&<[f64; 7]>::try_from(&q[..]).unwrap());
        let d = ours - theirs;
        position = position.max(d.fixed_view::<3, 1>(0, 3).norm());
        rotation = rotation.max(d.fixed_view::<3, 3>(0, 0).amax());
    }
    (position, rotation)
}

/// Franka's published table (alpha_{i-1} deg, a_{i-1} mm, d_i mm), written here again from the
/// documentation, not from the file; the flange row is `(0, 0, 107)`.
const PANDA_CRAIG_ROWS: [(f64, f64, f64); 7] = [
    (0.0, 0.0, 333.0),
    (-90.0, 0.0, 0.0),
    (90.0, 0.0, 316.0),
    (90.0, 82.5, 0.0),
    (-90.0, -82.5, 384.0),
    (90.0, 0.0, 0.0),
    (90.0, 88.0, 0.0),
];

fn read7(relative: &str) -> RobotModel {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(relative);
    RobotFile::read(&path).unwrap().to_model(&path).unwrap()
}

#[test]
fn franka_panda_from_its_published_craig_table_to_1e_9_mm() {
    let model = read7("robots/franka-panda.toml");
    let rows = PANDA_CRAIG_ROWS;
    let (position, rotation) = worst_difference(&model, 2000, |q| {
        let chain = rows
            .iter()
            .zip(q)
            .fold(Matrix4::<f64>::identity(), |t, (row, qi)| {
                t * craig(*row, *qi)
            });
        chain * craig((0.0, 0.0, 107.0), 0.0)
    });
    println!("Panda: worst position difference {position:e} mm, rotation element {rotation:e}");
    assert!(position <= 1e-9, "{position:e} mm");
    assert!(rotation <= 1e-12, "{rotation:e}");
    // The published zero posture: flange at x = 88 mm, z = 333 + 316 + 384 - 107 = 926 mm.
    let zero = Kinematics::nominal(&model.robot)
        .unwrap()
        .forward(&calib_core::model::JointVec::from_fn(7, |_| 0.0))
        .unwrap();
    let p = zero.translation.vector;
    assert!((p - Vector3::new(88.0, 0.0, 926.0)).norm() < 1e-9, "{p}");
}

#[test]
fn craig_first_row_and_flange_go_into_the_base_and_tool_frames_exactly() {
    // Every part the conversion moves is non-zero: alpha_0 and a_0, the flange's twist, length,
    // offset and angle, and the file's own base and tool frames.
    let text = r#"
name = "Craig test arm"
[base]
xyz_mm = [10.0, -20.0, 30.0]
rpy_deg = [5.0, -10.0, 15.0]
[tool]
xyz_mm = [1.0, 2.0, 150.0]
rpy_deg = [0.0, 20.0, -30.0]
[[craig_joint]]
alpha_prev_deg = 30.0
a_prev_mm = 50.0
d_mm = 300.0
theta_offset_deg = 10.0
[[craig_joint]]
alpha_prev_deg = -90.0
a_prev_mm = 20.0
d_mm = 5.0
theta_offset_deg = -5.0
[[craig_joint]]
alpha_prev_deg = 0.0
a_prev_mm = 400.0
d_mm = 0.0
theta_offset_deg = 0.0
[[craig_joint]]
alpha_prev_deg = 90.0
a_prev_mm = 35.0
d_mm = 420.0
theta_offset_deg = 90.0
[[craig_joint]]
alpha_prev_deg = -90.0
a_prev_mm = 0.0
d_mm = 0.0
theta_offset_deg = 0.0
[[craig_joint]]
alpha_prev_deg = 90.0
a_prev_mm = 0.0
d_mm = 80.0
theta_offset_deg = 0.0
[[craig_joint]]
alpha_prev_deg = -90.0
a_prev_mm = 12.0
d_mm = 0.0
theta_offset_deg = 0.0
[craig_flange]
alpha_prev_deg = 45.0
a_prev_mm = 7.0
d_mm = 60.0
theta_deg = 25.0
"#;
    let path = Path::new("craig-test.toml");
    let file = RobotFile::parse(text, path).unwrap();
    assert!(file.craig_joint.is_empty() && file.craig_flange.is_none());
    let model: RobotModel = file.to_model(path).unwrap();
    let rows: [(f64, f64, f64, f64); 7] = [
        (30.0, 50.0, 300.0, 10.0),
        (-90.0, 20.0, 5.0, -5.0),
        (0.0, 400.0, 0.0, 0.0),
        (90.0, 35.0, 420.0, 90.0),
        (-90.0, 0.0, 0.0, 0.0),
        (90.0, 0.0, 80.0, 0.0),
        (-90.0, 12.0, 0.0, 0.0),
    ];
    let (position, rotation) = worst_difference(&model, 500, |q| {
        let chain = rows
            .iter()
            .zip(q)
            .fold(Matrix4::<f64>::identity(), |t, ((al, a, d, off), qi)| {
                t * craig((*al, *a, *d), qi + off.to_radians())
            });
        frame([10.0, -20.0, 30.0], [5.0, -10.0, 15.0])
            * chain
            * craig((45.0, 7.0, 60.0), 25f64.to_radians())
            * frame([1.0, 2.0, 150.0], [0.0, 20.0, -30.0])
    });
    println!("test arm: worst position difference {position:e} mm, rotation element {rotation:e}");
    assert!(position <= 1e-9, "{position:e} mm");
    assert!(rotation <= 1e-12, "{rotation:e}");
}

#[test]
fn seven_joint_robots_stand_straight_at_zero() {
    // KUKA LBR iiwa 14: all axes on one line at zero, flange 360 + 420 + 400 + 126 mm up.
    let iiwa = read7("robots/kuka-iiwa14.toml");
    let p = Kinematics::nominal(&iiwa.robot)
        .unwrap()
        .forward(&calib_core::model::JointVec::from_fn(7, |_| 0.0))
        .unwrap()
        .translation
        .vector;
    assert!((p - Vector3::new(0.0, 0.0, 1306.0)).norm() < 1e-9, "{p}");
    // Barrett WAM: the elbow's +-45 mm offsets cancel at zero, tool plate 550 + 300 + 60 mm up.
    let wam = read7("robots/barrett-wam.toml");
    let p = Kinematics::nominal(&wam.robot)
        .unwrap()
        .forward(&calib_core::model::JointVec::from_fn(7, |_| 0.0))
        .unwrap()
        .translation
        .vector;
    assert!((p - Vector3::new(0.0, 0.0, 910.0)).norm() < 1e-9, "{p}");
}

#[test]
fn a_file_mixing_conventions_is_refused_with_the_fix() {
    let both = "name = \"x\"\n[[joint]]\na_mm = 0.0\nalpha_deg = 0.0\ntheta_offset_deg = 0.0\n\
                d_mm = 0.0\n[[craig_joint]]\nalpha_prev_deg = 0.0\na_prev_mm = 0.0\nd_mm = 0.0\n\
                theta_offset_deg = 0.0\n";
    let e = RobotFile::parse(both, Path::new("both.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("both [[joint]] and [[craig_joint]]"), "{e}");
    let flange = "name = \"x\"\n[[joint]]\na_mm = 0.0\nalpha_deg = 0.0\ntheta_offset_deg = 0.0\n\
                  d_mm = 0.0\n[craig_flange]\nalpha_prev_deg = 0.0\na_prev_mm = 0.0\nd_mm = 9.0\n";
    let e = RobotFile::parse(flange, Path::new("flange.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("[craig_flange] without [[craig_joint]]"), "{e}");
    let none = "name = \"x\"\n";
    let e = RobotFile::parse(none, Path::new("none.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("has no joints"), "{e}");
}

/// Issue 39, N18: an error in a Craig row names that row. Row 4's `a_prev_mm` becomes joint 3's
/// `a_mm` in our convention, and a value of 1e300 was reported as joint 3's.
#[test]
fn an_error_in_a_craig_row_names_the_row() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/robots/franka-panda.toml"
    ))
    .unwrap()
    .replacen("a_prev_mm = 82.5", "a_prev_mm = 1e300", 1);
    let path = Path::new("panda.toml");
    let e = RobotFile::parse(&text, path)
        .and_then(|f| f.to_model(path))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("craig_joint 4: a_prev_mm = 1e300 is beyond the plausible range"),
        "{e}"
    );
    assert!(!e.contains("joint 3"), "{e}");
}

/// The Panda's `[dynamics]` (centres converted into our frames) give the gravity torques of
/// franka_description's inertials in Craig's link frames, computed here from the published
/// table: each joint's torsion column (the end frame's turn per urad/(N m)) is `1e-6 tau_j z_j`,
/// `tau_j = z_j . sum_{k >= j} m_k (c_k - o_j) x g`.
#[test]
fn franka_panda_masses_give_the_published_gravity_torques() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/franka-panda.toml");
    let file = RobotFile::read(&path).unwrap();
    let model = file.to_model(&path).unwrap();
    let gravity = file.dynamics.as_ref().unwrap().to_gravity(7).unwrap();
    let rows = PANDA_CRAIG_ROWS;
    // franka_description: kg, and m in Craig's frame i.
    let inertials: [(f64, [f64; 3]); 7] = [
        (4.970684, [3.875e-3, 2.081e-3, -4.762e-2]),
        (0.646926, [-3.141e-3, -2.872e-2, 3.495e-3]),
        (3.228604, [2.7518e-2, 3.9252e-2, -6.6502e-2]),
        (3.587895, [-5.317e-2, 1.04419e-1, 2.7454e-2]),
        (1.225946, [-1.1953e-2, 4.1065e-2, -3.8437e-2]),
        (1.666555, [6.0149e-2, -1.4117e-2, -1.0517e-2]),
        (0.735522, [1.0517e-2, -4.252e-3, 6.1597e-2]),
    ];
    let errors = calib_core::ParameterErrors::zeros_for(model.robot.joint_count());
    let gains = host_tools::model::compliance::gains(7);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
    let mut worst = 0.0f64;
    for _ in 0..200 {
        let q: [f64; 7] = std::array::from_fn(|_| rng.random_range(-2.5..2.5));
        let frames: Vec<Matrix4<f64>> = (rows.iter().zip(q))
            .scan(Matrix4::identity(), |t, (row, qi)| {
                *t *= craig(*row, qi);
                Some(*t)
            })
            .collect();
        let centre = |k: usize| {
            let c = inertials[k].1.map(|v| v * 1000.0);
            frames[k].transform_point(&c.into()).coords
        };
        let g = Vector3::new(0.0, 0.0, -9.81);
        for (index, gain) in gains.iter().enumerate() {
            let host_tools::model::compliance::Gain::Torsion(j) = *gain else {
                continue;
            };
            let (z, o) = (
                frames[j - 1].fixed_view::<3, 1>(0, 2).into_owned(),
                frames[j - 1].fixed_view::<3, 1>(0, 3).into_owned(),
            );
            let moment: Vector3<f64> = (j - 1..7)
                .map(|k| ((centre(k) - o) * 1e-3).cross(&g) * inertials[k].0)
                .sum();
            let expected = z * (1e-6 * z.dot(&moment));
            let mut unit = vec![0.0; gains.len()];
            unit[index] = 1.0;
            let q = calib_core::model::JointVec::from_slice(&q).unwrap();
            let d = gravity
                .deflection(&unit, &model.robot, &errors, &q)
                .unwrap();
            worst = worst.max((Vector3::new(d[3], d[4], d[5]) - expected).norm());
        }
    }
    println!("Panda torsion columns from the converted masses: worst {worst:e} rad per urad/(N m)");
    assert!(worst < 1e-15, "{worst:e}");
}
