//! Handing the model to where it is used (issue 16): the URDF and the UR kinematics YAML, checked
//! against forward kinematics computed independently of the export (the `k` crate's URDF loader
//! and kinematics; the YAML's transforms composed here).

use crate::common;

use calib_core::{Kinematics, Robot};
use common::{UR10, calib_in, ok};
use host_tools::io::robot_file::{RobotFile, RobotModel};
use nalgebra::Dyn;
use nalgebra::{IsometryMatrix3, Matrix3, Rotation3, Translation3, Vector3};
use rand::{RngExt, SeedableRng};
use std::path::Path;

const ER10: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/er10l-c10.toml");
const SERIES_B: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../onboard/data/ur10-series-b-compliance.toml"
);

fn model(path: &Path) -> Robot<f64, Dyn> {
    let file = RobotFile::read(path).unwrap();
    let model: RobotModel = file.to_model(path).unwrap();
    model.robot
}

/// A robot with every parameter of the chain in use: the ER10L-C10 with the paper's errors
/// (beta, offsets), a base and a tool turned about every axis, written as a robot file.
fn everything_in_use(dir: &Path) -> std::path::PathBuf {
    let mut text = std::fs::read_to_string(ER10).unwrap();
    text.push_str(
        "\n[base]\nxyz_mm = [812.5, -143.25, 460.0]\nrpy_deg = [3.5, -7.25, 121.0]\n\
         \n[tool]\nxyz_mm = [12.5, -4.0, 151.75]\nrpy_deg = [-20.0, 35.0, 95.0]\n",
    );
    // The paper's errors on the nominal joints (Table 2 in the robot file's units).
    let paper = calib_core::model::paper::table2::<f64>();
    let mut file = RobotFile::parse(&text, Path::new("e.toml")).unwrap();
    for (entry, e) in file.joint.iter_mut().zip(&paper.joints) {
        entry.a_mm += e.da;
        entry.d_mm += e.dd;
        entry.alpha_deg += e.dalpha.to_degrees();
        entry.beta_deg += e.dbeta.to_degrees();
        entry.theta_offset_deg += e.dtheta.to_degrees();
    }
    let path = dir.join("everything.toml");
    std::fs::write(&path, file.to_toml("test")).unwrap();
    path
}

/// Largest position (mm) and rotation (rad) difference over 1000 random configurations (within
/// the joint limits and +-3.1 rad) between our forward kinematics of `robot` and `other(q)`.
fn largest_difference(
    robot: &Robot<f64, Dyn>,
    mut other: impl FnMut(&[f64]) -> IsometryMatrix3<f64>,
) -> (f64, f64) {
    let ours = Kinematics::nominal(robot).unwrap();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(16);
    let (mut position, mut rotation) = (0.0f64, 0.0f64);
    for _ in 0..1000 {
        let q = calib_core::model::JointVec::<f64>::from_fn(robot.joints.len(), |j| {
            let l = robot.limits[j];
            rng.random_range(l.lower.max(-3.1)..l.upper.min(3.1))
        });
        let a = ours.forward(&q).unwrap();
        let b = other(&q);
        position = position.max((a.translation.vector - b.translation.vector).norm());
        // |R_a - R_b|_F / sqrt(2) is the angle between them (to third order).
        rotation = rotation
            .max((a.rotation.matrix() - b.rotation.matrix()).norm() / std::f64::consts::SQRT_2);
    }
    (position, rotation)
}

/// The URDF's tool0 through the `k` crate (its URDF reader and kinematics), in mm.
fn through_k(urdf: &Path, joints: usize) -> impl FnMut(&[f64]) -> IsometryMatrix3<f64> {
    let chain = k::Chain::<f64>::from_urdf_file(urdf).unwrap();
    assert_eq!(chain.dof(), joints);
    move |q| {
        chain.set_joint_positions(q).unwrap();
        chain.update_transforms();
        let t = chain.find_link("tool0").unwrap().world_transform().unwrap();
        let r = t.rotation.to_rotation_matrix();
        IsometryMatrix3::from_parts(
            Translation3::new(
                t.translation.vector[0] * 1000.0,
                t.translation.vector[1] * 1000.0,
                t.translation.vector[2] * 1000.0,
            ),
            Rotation3::from_matrix_unchecked(Matrix3::from_fn(|i, j| r[(i, j)])),
        )
    }
}

/// The URDF of the nominal UR10, the identified Series B UR10 (geometry only) and a robot with
/// every parameter in use reproduces our forward kinematics of the tool to 1e-9 mm and 1e-12 rad
/// on 1,000 random configurations, read and evaluated by the `k` crate.
#[test]
fn the_urdf_reproduces_our_forward_kinematics() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let everything = everything_in_use(d);
    for (robot, extra) in [
        (Path::new(UR10), &[][..]),
        (Path::new(SERIES_B), &["--geometry-only"][..]),
        (everything.as_path(), &[][..]),
    ] {
        let args = [
            &[
                "export",
                "--params",
                robot.to_str().unwrap(),
                "--format",
                "urdf",
                "--out",
                "r.urdf",
            ][..],
            extra,
        ]
        .concat();
        ok(&calib_in(d, &args));
        let (position, rotation) =
            largest_difference(&model(robot), through_k(&d.join("r.urdf"), 6));
        println!(
            "{}: URDF through k, largest difference {position:.3e} mm, {rotation:.3e} rad",
            robot.display()
        );
        assert!(position < 1e-9 && rotation < 1e-12, "{position} {rotation}");
    }
}

/// 7-joint arms: the URDF of the KUKA LBR iiwa 14, the Franka Panda (from its Craig-convention
/// file) and the Barrett WAM reproduces our forward kinematics to 1e-9 mm and 1e-12 rad through
/// the `k` crate; the Panda's f32 block decodes to the file's robot rounded to f32; a UR
/// kinematics file of a 7-joint robot is refused.
#[test]
fn seven_joint_robots_export_to_urdf_and_blocks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for file in ["kuka-iiwa14.toml", "franka-panda.toml", "barrett-wam.toml"] {
        let robot = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("robots")
            .join(file);
        let args = [
            "export",
            "--params",
            robot.to_str().unwrap(),
            "--format",
            "urdf",
            "--out",
            "r.urdf",
        ];
        ok(&calib_in(d, &args));
        let model: RobotModel = RobotFile::read(&robot).unwrap().to_model(&robot).unwrap();
        let (position, rotation) =
            largest_difference(&model.robot, through_k(&d.join("r.urdf"), 7));
        println!(
            "{file}: URDF through k, largest difference {position:.3e} mm, {rotation:.3e} rad"
        );
        assert!(position < 1e-9 && rotation < 1e-12, "{position} {rotation}");
    }
    let panda = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/franka-panda.toml");
    let block = d.join("panda.calb");
    ok(&calib_in(
        d,
        &[
            "export",
            "--params",
            panda.to_str().unwrap(),
            "--format",
            "block",
            "--sequence",
            "3",
            "--out",
            block.to_str().unwrap(),
        ],
    ));
    let bytes = std::fs::read(&block).unwrap();
    let (decoded, sequence) = calib_core::controller::storage::decode::<f32, Dyn>(&bytes).unwrap();
    let model: RobotModel = RobotFile::read(&panda).unwrap().to_model(&panda).unwrap();
    assert_eq!(sequence, 3);
    assert_eq!(decoded, host_tools::formats::export::to_f32(&model.robot));
    let out = calib_in(
        d,
        &[
            "export",
            "--params",
            panda.to_str().unwrap(),
            "--format",
            "ur-kinematics-yaml",
            "--out",
            "panda.yaml",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("has 7 joints"), "{stderr}");
    assert!(!d.join("panda.yaml").exists());
}

/// Names, the joints-only fragment, and the refusals: a model with joint maps or compliance
/// (unless --geometry-only), wrong or duplicate names; a refused export writes nothing.
#[test]
fn urdf_names_fragment_and_refusals() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let names = "shoulder_link,upper_arm_link,forearm_link,wrist_1_link,wrist_2_link,wrist_3_link";
    let joints = "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint";
    ok(&calib_in(
        d,
        &[
            "export",
            "--params",
            UR10,
            "--format",
            "urdf",
            "--out",
            "j.xml",
            "--joints-only",
            "--link-names",
            names,
            "--joint-names",
            joints,
            "--base-link",
            "base_link_inertia",
        ],
    ));
    let text = std::fs::read_to_string(d.join("j.xml")).unwrap();
    assert_eq!(text.matches("<joint ").count(), 8);
    assert!(!text.contains("<link ") && !text.contains("<robot"));
    assert!(text.contains("<joint name=\"shoulder_pan_joint\" type=\"revolute\">"));
    assert!(text.contains("<parent link=\"base_link_inertia\"/>"));
    assert!(text.contains("<joint name=\"wrist_3_link-flange\" type=\"fixed\">"));
    for (args, says) in [
        (
            &["--params", SERIES_B][..],
            "joint maps and gravity compliance, which a URDF cannot carry",
        ),
        (
            &["--params", UR10, "--link-names", "a,b"][..],
            "need 6 names",
        ),
        (
            &["--params", UR10, "--link-names", "a,b,c,d,e,a"][..],
            "\"a\" is used twice",
        ),
        (
            &["--params", UR10, "--tool-link", "tool 0"][..],
            "letters, digits",
        ),
    ] {
        let out = calib_in(
            d,
            &[&["export", "--format", "urdf", "--out", "x.urdf"][..], args].concat(),
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert!(!d.join("x.urdf").exists());
    }
}

/// The UR kinematics YAML, read back here and composed as ur_description's URDF chains it
/// (segment origin, then rotation about z; tool0 is joint 6's frame), reproduces our forward
/// kinematics of the flange to 1e-9 mm and 1e-12 rad: for the nominal UR10 and the identified
/// Series B UR10 (geometry only). A model with a transform after joint 6 is refused.
#[test]
fn the_ur_kinematics_yaml_reproduces_our_forward_kinematics() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (robot, extra) in [(UR10, &[][..]), (SERIES_B, &["--geometry-only"][..])] {
        let args = [
            &[
                "export",
                "--params",
                robot,
                "--format",
                "ur-kinematics-yaml",
                "--out",
                "k.yaml",
            ][..],
            extra,
        ]
        .concat();
        ok(&calib_in(d, &args));
        let text = std::fs::read_to_string(d.join("k.yaml")).unwrap();
        let segments = read_segments(&text);
        assert_eq!(segments.len(), 6);
        assert!(text.contains("  hash: calib_"));
        let mut flange_model = model(Path::new(robot));
        flange_model.tool = calib_core::FramePose::identity();
        let compose = |q: &[f64]| {
            segments
                .iter()
                .zip(q)
                .fold(IsometryMatrix3::identity(), |t, (s, qi)| {
                    t * s * Rotation3::from_axis_angle(&Vector3::z_axis(), *qi)
                })
        };
        let (position, rotation) = largest_difference(&flange_model, compose);
        println!(
            "{robot}: UR YAML composed, largest difference {position:.3e} mm, {rotation:.3e} rad"
        );
        assert!(position < 1e-9 && rotation < 1e-12, "{position} {rotation}");
    }
    // The nominal UR10's segments are those of ur_description's UR10 default_kinematics.yaml
    // (numbers of Universal Robots' ROS description package, BSD-3-Clause; wrist_3's rotation
    // written there as roll pi/2, pitch pi, yaw pi, the same as ours, roll -pi/2).
    ok(&calib_in(
        d,
        &[
            "export",
            "--params",
            UR10,
            "--format",
            "ur-kinematics-yaml",
            "--out",
            "nominal.yaml",
        ],
    ));
    let ours = read_segments(&std::fs::read_to_string(d.join("nominal.yaml")).unwrap());
    let pi = std::f64::consts::PI;
    let published = [
        [0.0, 0.0, 0.1273, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, pi / 2.0, 0.0, 0.0],
        [-0.612, 0.0, 0.0, 0.0, 0.0, 0.0],
        [-0.5723, 0.0, 0.163941, 0.0, 0.0, 0.0],
        [0.0, -0.1157, 0.0, pi / 2.0, 0.0, 0.0],
        [0.0, 0.0922, 0.0, pi / 2.0, pi, pi],
    ];
    for (i, (a, [x, y, z, roll, pitch, yaw])) in ours.iter().zip(published).enumerate() {
        let b = IsometryMatrix3::from_parts(
            Translation3::new(x * 1000.0, y * 1000.0, z * 1000.0),
            Rotation3::from_euler_angles(roll, pitch, yaw),
        );
        let position = (a.translation.vector - b.translation.vector).norm();
        let rotation = (a.rotation.matrix() - b.rotation.matrix()).norm();
        assert!(
            position < 1e-9 && rotation < 1e-12,
            "segment {i}: {position} {rotation}"
        );
    }
    // a6 of 0.5 mm: no frame for it in a UR description.
    let text = std::fs::read_to_string(UR10).unwrap();
    let mut file = RobotFile::parse(&text, Path::new("u.toml")).unwrap();
    file.joint[5].a_mm = 0.5;
    std::fs::write(d.join("a6.toml"), file.to_toml("test")).unwrap();
    let out = calib_in(
        d,
        &[
            "export",
            "--params",
            "a6.toml",
            "--format",
            "ur-kinematics-yaml",
            "--out",
            "x.yaml",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("a6 = 0.5 mm"), "{stderr}");
    assert!(!d.join("x.yaml").exists());
}

/// The segments of a UR kinematics YAML (`x, y, z` m, `roll, pitch, yaw` rad) as transforms in
/// mm, read line by line (the file's fixed layout).
fn read_segments(text: &str) -> Vec<IsometryMatrix3<f64>> {
    let mut values: Vec<f64> = Vec::new();
    let mut out = Vec::new();
    for line in text.lines().filter(|l| l.starts_with("    ")) {
        let (_, value) = line.trim().split_once(": ").unwrap();
        values.push(value.parse().unwrap());
        if let [x, y, z, roll, pitch, yaw] = values[..] {
            out.push(IsometryMatrix3::from_parts(
                Translation3::new(x * 1000.0, y * 1000.0, z * 1000.0),
                Rotation3::from_euler_angles(roll, pitch, yaw),
            ));
            values.clear();
        }
    }
    out
}

/// The classic DH forward kinematics of a UR calibration, computed here: the nominal file's
/// values plus the `calibration.conf` deltas (read with a minimal parser of its own),
/// `T = prod Rz(q_i + theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`, mm.
fn classic_dh(robot: &Robot<f64, Dyn>, conf: &Path) -> impl Fn(&[f64]) -> IsometryMatrix3<f64> {
    let text = std::fs::read_to_string(conf).unwrap();
    let deltas = |key: &str| -> Vec<f64> {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("{key} =")))
            .unwrap();
        let list = line.split(['[', ']']).nth(1).unwrap();
        list.split(',').map(|v| v.trim().parse().unwrap()).collect()
    };
    let (theta, a, d, alpha) = (
        deltas("delta_theta"),
        deltas("delta_a"),
        deltas("delta_d"),
        deltas("delta_alpha"),
    );
    let joints: Vec<[f64; 4]> = (0..6)
        .map(|i| {
            let j = &robot.joints[i];
            [
                j.theta_offset + theta[i],
                j.d + d[i] * 1000.0,
                j.a + a[i] * 1000.0,
                j.alpha + alpha[i],
            ]
        })
        .collect();
    move |q| {
        joints.iter().zip(q).fold(
            IsometryMatrix3::identity(),
            |t, ([theta, d, a, alpha], qi)| {
                t * IsometryMatrix3::from_parts(
                    Translation3::identity(),
                    Rotation3::from_axis_angle(&Vector3::z_axis(), qi + theta),
                ) * Translation3::new(*a, 0.0, *d)
                    * Rotation3::from_axis_angle(&Vector3::x_axis(), *alpha)
            },
        )
    }
}

/// The four real UR factory calibrations (`host-tools/data/ur-factory-calibration/`, with
/// classic DH offsets of up to 446 m) imported as Hayati robot files reproduce their classic DH
/// forward kinematics to 1e-6 mm and 1e-9 rad on 1,000 random configurations, every parameter
/// error below 5 mm and 2 deg. Measured: to 2.2e-10 mm and 5.1e-15 rad at most; largest errors
/// 1.66 mm (UR5) and 0.77 deg (dalpha3, UR10 set 1), where classic DH has d2, d3 up to 446 m.
#[test]
fn ur_factory_calibrations_import_exactly_with_small_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/data/ur-factory-calibration");
    let robots = concat!(env!("CARGO_MANIFEST_DIR"), "/robots");
    for (set, robot) in [
        ("ur10-test-set-1", "ur10"),
        ("ur10-test-set-2", "ur10"),
        ("ur10e-real", "ur10e"),
        ("ur5-issue457", "ur5"),
    ] {
        let conf = Path::new(data).join(format!("{set}.conf"));
        let nominal_path = Path::new(robots).join(format!("{robot}.toml"));
        let out = ok(&calib_in(
            d,
            &[
                "import-ur-calibration",
                "--robot",
                nominal_path.to_str().unwrap(),
                "--calibration",
                conf.to_str().unwrap(),
                "--out",
                "imported.toml",
            ],
        ));
        assert!(out.contains("reproduces it to"), "{out}");
        let imported = model(&d.join("imported.toml"));
        let nominal = model(&nominal_path);
        let (position, rotation) = largest_difference(&imported, classic_dh(&nominal, &conf));
        let (mut length, mut angle) = (0.0f64, 0.0f64);
        for (a, b) in imported.joints.iter().zip(&nominal.joints) {
            length = length.max((a.a - b.a).abs()).max((a.d - b.d).abs());
            angle = angle
                .max((a.alpha - b.alpha).abs())
                .max((a.beta - b.beta).abs())
                .max((a.theta_offset - b.theta_offset).abs());
        }
        println!(
            "{set}: imported to {position:.2e} mm, {rotation:.2e} rad; largest errors {length:.3} mm, {:.3} deg",
            angle.to_degrees()
        );
        assert!(position < 1e-6 && rotation < 1e-9, "{position} {rotation}");
        assert!(length < 5.0 && angle.to_degrees() < 2.0, "{length} {angle}");
        // The file keeps its geometry where the import put it: the UR YAML of it composes to the
        // same classic DH (a6, alpha6 and beta6 stay zero).
        ok(&calib_in(
            d,
            &[
                "export",
                "--params",
                "imported.toml",
                "--format",
                "ur-kinematics-yaml",
                "--out",
                "imported.yaml",
            ],
        ));
    }
    // Not a calibration.conf, or a broken one: said, nothing written.
    std::fs::write(
        d.join("broken.conf"),
        "[mounting]\ndelta_theta = [1, 2, 3]\n",
    )
    .unwrap();
    for (conf, says) in [
        (UR10, "no delta_theta in a [mounting] section"),
        ("broken.conf", "delta_theta has 3 values, expected 6"),
    ] {
        let out = calib_in(
            d,
            &[
                "import-ur-calibration",
                "--robot",
                UR10,
                "--calibration",
                conf,
                "--out",
                "x.toml",
            ],
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(says), "{stderr}");
        assert!(!d.join("x.toml").exists());
    }
}

/// Issue 39 N3, N4, N13, N14: paths and robot names are written into other formats' comments,
/// headers and markup. A file name with a line feed, a carriage return, U+2028, NEL and a control
/// character, and a robot named `a---b` with a line break and `# frame: base` in it, inject
/// nothing: the UR YAML has no line the name or path started, the URDF loads (the `k` crate's
/// reader) with the robot's name as given (escaped), the plan CSV has no `# frame: base` line,
/// and the robot file `calibrate` writes from such a data path reads back.
#[test]
fn names_and_paths_cannot_break_the_formats_they_are_written_into() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = std::fs::read_to_string(UR10).unwrap().replacen(
        "name = \"",
        "name = \"a---b\\n# frame: base\\u0001 ",
        1,
    );
    let params = d.join("p\ninjected: 1\r\u{2028}x\u{85}y\u{1}.toml");
    std::fs::write(&params, text).unwrap();
    let params = params.to_str().unwrap();

    ok(&calib_in(
        d,
        &[
            "export",
            "--params",
            params,
            "--format",
            "ur-kinematics-yaml",
            "--out",
            "ur.yaml",
        ],
    ));
    let yaml = std::fs::read_to_string(d.join("ur.yaml")).unwrap();
    assert!(
        !yaml.contains(['\r', '\u{2028}', '\u{85}', '\u{1}']),
        "{yaml}"
    );
    assert!(
        yaml.lines()
            .all(|l| !l.starts_with("injected") && !l.starts_with('x')),
        "{yaml}"
    );

    ok(&calib_in(
        d,
        &[
            "export", "--params", params, "--format", "urdf", "--out", "r.urdf",
        ],
    ));
    let urdf = std::fs::read_to_string(d.join("r.urdf")).unwrap();
    assert!(
        urdf.contains("<robot name=\"a---b\\u{000a}# frame: base\\u{0001} "),
        "{urdf}"
    );
    let comment = &urdf[urdf.find("<!--").unwrap() + 4..urdf.find("-->").unwrap()];
    assert!(!comment.contains("--"), "{comment}");
    k::Chain::<f64>::from_urdf_file(d.join("r.urdf")).expect("a well-formed URDF");

    ok(&calib_in(
        d,
        &[
            "plan",
            "--robot",
            params,
            "--generate",
            "300",
            "--poses",
            "30",
            "--measure",
            "position",
            "--noise-mm",
            "0.02",
            "--out",
            "plan.csv",
        ],
    ));
    let plan = std::fs::read_to_string(d.join("plan.csv")).unwrap();
    assert!(
        plan.lines()
            .all(|l| l != "# frame: base" && !l.starts_with("injected")),
        "{plan}"
    );

    let data = d.join("data\u{1}\n# frame: tracker.csv");
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/data/er10l-c10-sim32.csv"),
        &data,
    )
    .unwrap();
    ok(&calib_in(
        d,
        &[
            "calibrate",
            "--robot",
            ER10,
            "--data",
            data.to_str().unwrap(),
            "--out",
            "id.toml",
        ],
    ));
    RobotFile::read(&d.join("id.toml")).expect("the identified robot file reads back");
}

/// Issue 39, N6: `import-ur-calibration` judges what it imports. Deltas no calibration reaches
/// (`delta_theta` 1e300, `delta_alpha` 100, `delta_d` 1e300) are refused with the file, line and
/// key; deltas that convert to Hayati errors beyond a robot's (`delta_a` 0.5 m: `da2` over a
/// metre) and a nominal file of another robot (the ER10L-C10 with a UR10 calibration moves the
/// flange by metres) are refused unless `--accept-implausible`; nothing is written when refused.
#[test]
fn n6_implausible_ur_calibrations_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let good = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/ur-factory-calibration/ur10-test-set-1.conf"
    ))
    .unwrap();
    let with = |key: &str, index: usize, value: &str| -> String {
        good.lines()
            .map(|line| {
                if line.starts_with(key) {
                    let (head, list) = line.split_once('[').unwrap();
                    let mut values: Vec<&str> = list
                        .trim_end_matches(']')
                        .split(',')
                        .map(str::trim)
                        .collect();
                    values[index] = value;
                    format!("{head}[{}]\n", values.join(", "))
                } else {
                    format!("{line}\n")
                }
            })
            .collect()
    };
    let import = |robot: &str, text: &str, extra: &[&str]| {
        std::fs::write(d.join("c.conf"), text).unwrap();
        let mut args = vec![
            "import-ur-calibration",
            "--robot",
            robot,
            "--calibration",
            "c.conf",
            "--out",
            "x.toml",
        ];
        args.extend_from_slice(extra);
        calib_in(d, &args)
    };
    for (text, says) in [
        (
            with("delta_theta", 0, "1e300"),
            "c.conf:3: delta_theta[1] = 1e300 rad: beyond two turns",
        ),
        (
            with("delta_alpha", 2, "100"),
            "c.conf:6: delta_alpha[3] = 1e2 rad: beyond two turns",
        ),
        (
            with("delta_d", 1, "1e300"),
            "c.conf:5: delta_d[2] = 1e300 m: beyond 10 km",
        ),
        (
            with("delta_a", 1, "0.5"),
            "da2 = -184.889 mm is beyond 5 mm",
        ),
    ] {
        let out = import(UR10, &text, &[]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(says), "{says}: {stderr}");
        assert!(!d.join("x.toml").exists());
    }
    let out = import(UR10, &with("delta_a", 1, "0.5"), &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("is not a plausible calibration, nothing written")
            && stderr.contains("--accept-implausible"),
        "{stderr}"
    );
    let out = import(ER10, &good, &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("moves the flange by up to") && stderr.contains("another robot"),
        "{stderr}"
    );
    let moved: f64 = stderr
        .split("moves the flange by up to ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    assert!(moved > 1000.0, "{moved} mm");
    assert!(!d.join("x.toml").exists());
    // Accepted when asked, with the problems printed.
    let out = ok(&import(
        UR10,
        &with("delta_a", 1, "0.5"),
        &["--accept-implausible"],
    ));
    assert!(
        out.contains("warning: implausible, written as asked: da2 = "),
        "{out}"
    );
    assert!(d.join("x.toml").exists());
    // The real calibrations stay plausible.
    let out = ok(&import(UR10, &good, &[]));
    assert!(!out.contains("warning"), "{out}");
}
