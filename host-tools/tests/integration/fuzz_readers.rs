//! Fuzzing of the input readers (a proptest suite: cargo-fuzz needs a tool not installed here).
//! Every reader that takes a file gets arbitrary text and structured near-valid inputs: tracker
//! CSV (our format, through data profiles, and plans read back with their `role` column),
//! candidate configurations (`plan --candidates`), data profiles, robot files, UR
//! `calibration.conf` files and JSON reports (`report --from`, rendered); none may panic, and
//! whatever they accept must be usable (finite numbers, unit quaternions, valid robots).
//!
//! CI runs the default number of cases; the 10-minute run recorded in the README is
//! `PROPTEST_CASES=1300000 cargo test -p host-tools --test integration fuzz_readers:: -- --test-threads=1` (the test
//! profile keeps overflow checks, which found `q0_deg` underflowing a joint index).

use host_tools::formats::ur_calibration::UrCalibration;
use host_tools::io::profile::DataProfile;
use host_tools::io::robot_file::RobotFile;
use host_tools::io::tracker_data::TrackerData;
use proptest::prelude::*;
use std::path::Path;

fn accepted_data_are_usable(d: &TrackerData) {
    assert!(!d.records.is_empty());
    for r in &d.records {
        assert!(r.q.iter().chain(&r.position).all(|v| v.is_finite()));
        assert!(r.weight.is_finite() && r.weight >= 0.0);
        if let Some(m) = &r.rotation {
            assert!((m.transpose() * m - nalgebra::Matrix3::identity()).norm() < 1e-2);
        }
        assert!(r.line >= 2);
    }
}

/// A field: a number in some spelling, or something that is not one.
fn field() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|v| v.to_string()),
        (-1e4f64..1e4).prop_map(|v| format!("{v:.6}")),
        (-7f64..7.0).prop_map(|v| format!("{v:.4}").replace('.', ",")),
        Just(String::new()),
        Just("nan".to_string()),
        Just("-inf".to_string()),
        Just("1e999".to_string()),
        Just("\"1,5\"".to_string()),
        Just("core".to_string()),
        Just("verify".to_string()),
        "[ -~]{0,6}",
        "\\PC{0,4}",
    ]
}

const NAMES: [&str; 25] = [
    "id",
    "weight",
    "q1_deg",
    "q2_deg",
    "q3_deg",
    "q4_deg",
    "q5_deg",
    "q6_deg",
    "q1_rad",
    "q7_deg",
    "x_mm",
    "y_mm",
    "z_mm",
    "x_m",
    "qw",
    "qx",
    "qy",
    "qz",
    "rx_deg",
    "ry_deg",
    "rz_rad",
    "temperature",
    "role",
    "",
    "q0_deg",
];

fn header() -> impl Strategy<Value = Vec<String>> {
    prop_oneof![
        // Mostly valid headers, shuffled.
        Just(
            "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm,qw,qx,qy,qz"
                .split(',')
                .map(String::from)
                .collect::<Vec<_>>()
        )
        .prop_shuffle(),
        proptest::collection::vec(proptest::sample::select(&NAMES[..]), 0..16)
            .prop_map(|v| v.into_iter().map(String::from).collect()),
    ]
}

fn csv_text(delimiter: char) -> impl Strategy<Value = String> {
    (
        header(),
        proptest::collection::vec(proptest::collection::vec(field(), 0..16), 0..6),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(move |(header, rows, comment, crlf)| {
            let end = if crlf { "\r\n" } else { "\n" };
            let mut text = String::new();
            if comment {
                text.push_str("# frame: base");
                text.push_str(end);
            }
            text.push_str(&header.join(&delimiter.to_string()));
            for row in rows {
                text.push_str(end);
                text.push_str(&row.join(&delimiter.to_string()));
            }
            text
        })
}

const PROFILE: &str = r#"
delimiter = ";"
decimal = ","
[columns]
q1_rad = "a"
q2_rad = "b"
q3_rad = "c"
q4_rad = "d"
q5_rad = "e"
q6_rad = "f"
x_mm = "x"
y_mm = "y"
z_mm = "z"
rx_deg = "u"
ry_deg = "v"
rz_deg = "w"
[orientation]
euler = "intrinsic"
order = "zyx"
"#;

proptest! {
    #[test]
    fn tracker_csv_never_panics_on_arbitrary_text(text in "\\PC{0,400}") {
        if let Ok(d) = TrackerData::parse(&text, Path::new("f.csv")) {
            accepted_data_are_usable(&d);
        }
    }

    #[test]
    fn tracker_csv_never_panics_on_near_valid_files(text in csv_text(',')) {
        if let Ok(d) = TrackerData::parse(&text, Path::new("f.csv")) {
            accepted_data_are_usable(&d);
        }
    }

    #[test]
    fn profiled_exports_never_panic(
        rows in proptest::collection::vec(proptest::collection::vec(field(), 12..14), 0..5),
        shuffle in Just("a;b;c;d;e;f;x;y;z;u;v;w;t".split(';').map(String::from).collect::<Vec<_>>()).prop_shuffle(),
    ) {
        let profile = DataProfile::parse(PROFILE, Path::new("p.toml")).unwrap();
        let mut text = shuffle.join(";");
        for row in rows {
            text.push('\n');
            text.push_str(&row.join(";"));
        }
        if let Ok(d) = TrackerData::parse_profiled(&text, Path::new("f.csv"), &profile) {
            accepted_data_are_usable(&d);
        }
    }

    #[test]
    fn profiles_never_panic(text in "\\PC{0,300}", key in proptest::sample::select(&["delimiter", "decimal", "frame", "[columns]\nq1_rad", "[orientation]\neuler", "[orientation]\norder"][..]), value in "[ -~]{0,6}") {
        let _ = DataProfile::parse(&text, Path::new("p.toml"));
        let _ = DataProfile::parse(&format!("{key} = \"{}\"", value.replace(['"', '\\'], "")), Path::new("p.toml"));
    }

    #[test]
    fn robot_files_never_panic(
        text in "\\PC{0,300}",
        values in proptest::collection::vec(prop_oneof![any::<f64>(), -1e3f64..1e3], 36),
        joints in 0usize..8,
    ) {
        let _ = RobotFile::parse(&text, Path::new("r.toml")).map(|f| f.to_model(Path::new("r.toml")));
        let mut toml = String::from("name = \"fuzz\"\n");
        for j in 0..joints {
            let v = |i: usize| values[(j * 5 + i) % values.len()];
            // TOML has no NaN/inf spelled like Rust's Display, so use TOML's own.
            let t = |x: f64| if x.is_nan() { "nan".to_string() } else if x.is_infinite() { if x > 0.0 { "inf".into() } else { "-inf".into() } } else { format!("{x:?}") };
            toml.push_str(&format!(
                "[[joint]]\na_mm = {}\nalpha_deg = {}\ntheta_offset_deg = {}\nd_mm = {}\nbeta_deg = {}\nlimits_deg = [{}, {}]\n",
                t(v(0)), t(v(1)), t(v(2)), t(v(3)), t(v(4)), t(v(5)), t(v(6))
            ));
        }
        if let Ok(file) = RobotFile::parse(&toml, Path::new("r.toml"))
            && let Ok(model) = file.to_model(Path::new("r.toml"))
        {
            prop_assert!(model.robot.validate().is_ok());
        }
    }
}

/// A `calibration.conf` with four lists of fields (some numbers, some not).
fn ur_conf() -> impl Strategy<Value = String> {
    (
        proptest::collection::vec(proptest::collection::vec(field(), 0..8), 4),
        proptest::sample::select(&["mounting", "other", " mounting "][..]),
        any::<bool>(),
    )
        .prop_map(|(lists, section, brackets)| {
            let mut text = format!("[{section}]\n");
            for (key, values) in ["delta_theta", "delta_a", "delta_d", "delta_alpha"]
                .iter()
                .zip(lists)
            {
                let list = values.join(", ");
                if brackets {
                    text.push_str(&format!("{key} = [{list}] # comment\n"));
                } else {
                    text.push_str(&format!("{key} = {list}\n"));
                }
            }
            text
        })
}

/// The JSON report of a calibration of the bundled simulated data, made once by `calib`.
fn report() -> &'static serde_json::Value {
    static REPORT: std::sync::OnceLock<serde_json::Value> = std::sync::OnceLock::new();
    REPORT.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.json");
        let manifest = env!("CARGO_MANIFEST_DIR");
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_calib"))
            .args([
                "calibrate",
                "--robot",
                &format!("{manifest}/robots/er10l-c10.toml"),
                "--data",
                &format!("{manifest}/data/er10l-c10-sim32.csv"),
                "--method",
                "lm",
                "--validate",
                "0.25",
                "--report",
                path.to_str().unwrap(),
                "--out",
                dir.path().join("x.toml").to_str().unwrap(),
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
    })
}

/// Every JSON pointer to a leaf of `value`.
fn leaves(value: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match value {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                leaves(
                    v,
                    format!("{at}/{}", k.replace('~', "~0").replace('/', "~1")),
                    out,
                );
            }
        }
        serde_json::Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                leaves(v, format!("{at}/{i}"), out);
            }
        }
        _ => out.push(at),
    }
}

/// A JSON value a report's field might be replaced by.
fn json_value() -> impl Strategy<Value = serde_json::Value> {
    use serde_json::json;
    prop_oneof![
        any::<f64>().prop_map(|v| json!(v)),
        proptest::sample::select(&[0.0, -5.0, 1e-300, 1e300, -1e308, 4e9][..])
            .prop_map(|v| json!(v)),
        any::<i64>().prop_map(|v| json!(v)),
        "\\PC{0,12}".prop_map(|v| json!(v)),
        Just(json!(null)),
        Just(json!([])),
        Just(json!({})),
        Just(json!([1e300, -1e300, 0])),
        Just(json!(true)),
    ]
}

proptest! {
    #[test]
    fn candidate_files_never_panic(text in csv_text(',')) {
        if let Ok(d) = TrackerData::parse_joints(&text, Path::new("c.csv"), &DataProfile::default()) {
            prop_assert!(d.records.iter().all(|r| r.q.iter().all(|v| v.is_finite())));
        }
    }

    #[test]
    fn ur_calibrations_never_panic(text in "\\PC{0,300}", conf in ur_conf()) {
        let _ = UrCalibration::parse(&text, Path::new("c.conf"));
        if let Ok(c) = UrCalibration::parse(&conf, Path::new("c.conf")) {
            for v in c.delta_theta.iter().chain(&c.delta_a).chain(&c.delta_d).chain(&c.delta_alpha) {
                prop_assert!(v.is_finite() && v.abs() <= 1e4);
            }
        }
    }
}

proptest! {
    // Each case renders a page with its plots: fewer cases.
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn reports_never_panic(
        picks in proptest::collection::vec((any::<proptest::sample::Index>(), json_value()), 1..12),
        text in "\\PC{0,200}",
    ) {
        let rendering = host_tools::report::html::Rendering::now();
        // A report reads through the typed report (what `calib report --from` does), which refuses
        // what it cannot read; whatever it reads renders.
        if let Ok(typed) = serde_json::from_str::<host_tools::calibration::Report>(&text) {
            let _ = host_tools::report::html::render(&typed, &rendering);
        }
        let unchanged = serde_json::from_value::<host_tools::calibration::Report>(report().clone());
        prop_assert!(unchanged.is_ok(), "{:?}", unchanged.err());
        let mut report = report().clone();
        let mut pointers = Vec::new();
        leaves(&report, String::new(), &mut pointers);
        for (index, value) in picks {
            let pointer = index.get(&pointers);
            if let Some(slot) = report.pointer_mut(pointer) {
                *slot = value;
            }
        }
        if let Ok(typed) = serde_json::from_value::<host_tools::calibration::Report>(report) {
            let _ = host_tools::report::html::render(&typed, &rendering);
        }
    }
}

proptest! {
    // Each case writes a file: fewer cases.
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// A socket file of arbitrary text or of near-valid lines: read or refused with a line,
    /// never a panic; what is read has the robot's joint count and finite readings only.
    #[test]
    fn socket_files_never_panic(
        text in prop_oneof!["\\PC{0,300}", "([-0-9.e,naif ]{0,40}\n){0,8}"],
        joints in 1usize..9,
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("hole_0.csv");
        std::fs::write(&path, &text).unwrap();
        match host_tools::io::sockets::read_socket(&path, joints) {
            Ok(socket) => {
                prop_assert!(!socket.readings.is_empty());
                for r in &socket.readings {
                    prop_assert_eq!(r.q_rad.len(), joints);
                    prop_assert!(r.q_rad.iter().all(|v| v.is_finite()));
                }
            }
            Err(e) => prop_assert!(e.to_string().contains("hole_0.csv")),
        }
    }
}
