//! Bad robot files are errors that name the file, the field and, for syntax, the line.

use host_tools::io::robot_file::{RobotFile, RobotModel};
use std::path::Path;

const GOOD_JOINT: &str =
    "[[joint]]\na_mm = 1.0\nalpha_deg = 0.0\ntheta_offset_deg = 0.0\nd_mm = 0.0\n";

fn six_joints() -> String {
    format!("name = \"test\"\n{}", GOOD_JOINT.repeat(6))
}

fn error_of(text: &str) -> String {
    let path = Path::new("robots/bad.toml");
    match RobotFile::parse(text, path).and_then(|f| f.to_model(path)) {
        Ok(_) => panic!("accepted a bad robot file:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_good_file_parses_and_defaults_apply() {
    let path = Path::new("robots/ok.toml");
    let model: RobotModel = RobotFile::parse(&six_joints(), path)
        .unwrap()
        .to_model(path)
        .unwrap();
    assert_eq!(model.robot.joints[0].beta, 0.0);
    assert!(model.robot.limits[0].lower.is_infinite());
    // All twists are zero: joints 1-5 get beta instead of d, joint 6 keeps d.
    let names: Vec<String> = model.mask.iter().map(|p| p.to_string()).collect();
    assert!(names.contains(&"dbeta5".to_string()) && names.contains(&"dd6".to_string()));
    assert!(!names.contains(&"dd5".to_string()) && !names.contains(&"dbeta6".to_string()));
}

#[test]
fn unknown_key_is_named_with_its_line() {
    let text = six_joints().replacen("d_mm = 0.0\n", "d_mm = 0.0\nd_m = 0.0\n", 1);
    let e = error_of(&text);
    assert!(e.starts_with("robots/bad.toml: "), "{e}");
    assert!(e.contains("unknown field `d_m`"), "{e}");
    assert!(e.contains("line 7"), "{e}");
}

#[test]
fn missing_field_is_named() {
    let text = six_joints().replacen("alpha_deg = 0.0\n", "", 1);
    let e = error_of(&text);
    assert!(e.contains("missing field `alpha_deg`"), "{e}");
}

#[test]
fn wrong_joint_count_is_an_error() {
    // The joint count is the file's (a run-time count): 5 joints are a robot of 5 joints, with
    // 4 parameters per joint by the default rule (a, alpha, theta, and d or beta).
    let path = Path::new("robots/five.toml");
    let five = format!("name = \"x\"\n{}", GOOD_JOINT.repeat(5));
    let model = RobotFile::parse(&five, path)
        .unwrap()
        .to_model(path)
        .unwrap();
    assert_eq!(model.robot.joints.len(), 5);
    assert_eq!(model.mask.count(), 20);
    // Beyond what the tool handles: refused, naming the count and the range.
    for joints in [1, 10] {
        let text = format!("name = \"x\"\n{}", GOOD_JOINT.repeat(joints));
        let e = error_of(&text);
        assert!(
            e.contains(&format!(
                "has {joints} [[joint]] tables; calib handles robots of 2 to 9 joints"
            )),
            "{e}"
        );
    }
}

#[test]
fn wrong_type_is_an_error() {
    let text = six_joints().replacen("a_mm = 1.0", "a_mm = \"long\"", 1);
    let e = error_of(&text);
    assert!(e.contains("a_mm") || e.contains("invalid type"), "{e}");
    assert!(e.contains("line 3"), "{e}");
}

#[test]
fn non_finite_value_is_named() {
    let text = six_joints().replacen("d_mm = 0.0", "d_mm = nan", 2);
    let e = error_of(&text);
    assert!(
        e.contains("joint 1: d_mm = NaN is not a finite number"),
        "{e}"
    );
}

#[test]
fn reversed_limits_are_an_error() {
    let text = six_joints().replacen(
        "d_mm = 0.0\n",
        "d_mm = 0.0\nlimits_deg = [90.0, -90.0]\n",
        1,
    );
    let e = error_of(&text);
    assert!(e.contains("joint 1: limits_deg = [90, -90]"), "{e}");
}

#[test]
fn unknown_identify_name_is_an_error() {
    let text = six_joints().replacen(
        "d_mm = 0.0\n",
        "d_mm = 0.0\nidentify = [\"a\", \"gamma\"]\n",
        1,
    );
    let e = error_of(&text);
    assert!(
        e.contains("joint 1: identify: unknown parameter \"gamma\""),
        "{e}"
    );
}

#[test]
fn identify_list_overrides_the_default_rule() {
    let text = six_joints().replacen("d_mm = 0.0\n", "d_mm = 0.0\nidentify = [\"theta\"]\n", 1);
    let path = Path::new("x.toml");
    let model: RobotModel = RobotFile::parse(&text, path)
        .unwrap()
        .to_model(path)
        .unwrap();
    let joint1: Vec<String> = model
        .mask
        .iter()
        .map(|p| p.to_string())
        .filter(|n| n.ends_with('1'))
        .collect();
    assert_eq!(joint1, ["dtheta1"]);
}

#[test]
fn missing_file_is_named() {
    let e = RobotModel::load(Path::new("no/such/robot.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("no/such/robot.toml: cannot read the robot file"),
        "{e}"
    );
}
