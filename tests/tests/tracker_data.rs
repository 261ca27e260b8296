//! Tracker CSV: units, orientation forms, comments, and errors with file, line and column.

use host_tools::io::profile::DataProfile;
use host_tools::io::tracker_data::{OrientationColumns, TrackerData};
use std::path::Path;

fn parse(text: &str) -> Result<TrackerData, String> {
    TrackerData::parse(text, Path::new("cell/data.csv")).map_err(|e| e.to_string())
}

const HEADER: &str = "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm";

#[test]
fn units_comments_and_orientation_forms() {
    let text = "# frame: base\n# a comment\nid,q1_rad,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_m,y_m,z_m,rx_deg,ry_deg,rz_deg,weight\n\
                A,0.5,90,0,0,0,0,1.5,-0.25,0.001,90,0,0,2\n";
    let d = parse(text).unwrap();
    assert!(d.base_frame);
    assert_eq!(d.orientation, OrientationColumns::FixedAngles);
    let r = &d.records[0];
    assert_eq!((r.id.as_str(), r.line, r.weight), ("A", 4, 2.0));
    assert_eq!(r.q[0], 0.5);
    assert!((r.q[1] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    assert_eq!(r.position, [1500.0, -250.0, 1.0]);
    // rx = 90 deg: y axis goes to z.
    let m = r.rotation.unwrap();
    assert!((m[(2, 1)] - 1.0).abs() < 1e-15);

    let q = parse(&format!(
        "{HEADER},qw,qx,qy,qz\n0,0,0,0,0,0,1,2,3,0,0,0,1\n"
    ))
    .unwrap();
    assert!(!q.base_frame);
    assert_eq!(q.orientation, OrientationColumns::Quaternion);
    // qz = 1: 180 deg about z.
    assert!((q.records[0].rotation.unwrap()[(0, 0)] + 1.0).abs() < 1e-15);
    assert_eq!(q.records[0].id, "2");

    let p = parse(&format!("{HEADER}\n0,0,0,0,0,0,1,2,3\n")).unwrap();
    assert_eq!(p.orientation, OrientationColumns::None);
    assert!(p.records[0].rotation.is_none());
}

#[test]
fn errors_name_file_line_and_column() {
    let e = parse(&format!("{HEADER},temperature\n")).unwrap_err();
    assert!(
        e.starts_with("cell/data.csv:1: column 10 (\"temperature\"): unknown column"),
        "{e}"
    );

    let e = parse("q1_deg,q2_deg,x_mm,y_mm\n0,0,1,2\n").unwrap_err();
    assert!(
        e.contains("cell/data.csv:1: missing position column z_mm"),
        "{e}"
    );

    let e = parse(&format!(
        "# c\n{HEADER}\n0,0,0,0,0,0,1,2,3\n0,0,0,abc,0,0,1,2,3\n"
    ))
    .unwrap_err();
    assert_eq!(
        e,
        "cell/data.csv:4: column 4 (\"q4_deg\"): \"abc\" is not a number"
    );

    let e = parse(&format!("{HEADER}\n0,0,0,0,0,0,1,inf,3\n")).unwrap_err();
    assert!(
        e.contains(":2: column 8 (\"y_mm\"): inf is not a finite number"),
        "{e}"
    );

    let e = parse(&format!(
        "{HEADER},qw,qx,qy,qz\n0,0,0,0,0,0,1,2,3,0.9,0,0,0\n"
    ))
    .unwrap_err();
    assert!(
        e.contains(":2: column qw..qz: quaternion norm 0.900000 is not 1"),
        "{e}"
    );

    let e = parse(&format!(
        "id,{HEADER}\nP1,0,0,0,0,0,0,1,2,3\nP1,0,0,0,0,0,0,1,2,3\n"
    ))
    .unwrap_err();
    assert!(
        e.contains(":3: column id: id \"P1\" already used on line 2"),
        "{e}"
    );

    let e = parse(&format!("{HEADER},qw,qx\n")).unwrap_err();
    assert!(e.contains("not a mix"), "{e}");

    let e = parse(&format!("{HEADER}\n0,0,0,0,0,0,1,2\n")).unwrap_err();
    assert!(e.contains(":2: has 8 fields, the header has 9"), "{e}");

    let e = parse(&format!("{HEADER}\n")).unwrap_err();
    assert!(e.contains("no data rows"), "{e}");

    let e = parse("q1_deg,q1_rad,x_mm,y_mm,z_mm\n").unwrap_err();
    assert!(e.contains("q1 appears twice"), "{e}");

    let e = parse("q1_rad,q2_rad,x_mm,y_mm,z_mm\n0.5,90,1,2,3\n").unwrap_err();
    assert!(e.contains(":2: column 2 (\"q2_rad\"): 90 is beyond one turn for a radian column; are these degrees (q2_deg)?"), "{e}");
}

#[test]
fn line_numbers_are_physical_lines_with_crlf_endings() {
    // The csv crate counts one line short after a CRLF header; errors and ids must not.
    let text = format!("{HEADER}\r\n0,0,0,0,0,0,1,2,3\r\n0,0,0,0,0,0,1,2,x\r\n");
    let err = parse(&text).unwrap_err();
    assert!(
        err.starts_with("cell/data.csv:3: column 9 (\"z_mm\")"),
        "{err}"
    );
    let ok = parse(&format!("# c\r\n{HEADER}\r\n0,0,0,0,0,0,1,2,3\r\n")).unwrap();
    assert_eq!((ok.records[0].line, ok.records[0].id.as_str()), (3, "3"));
}

const PROFILE: &str = r#"
delimiter = ";"
decimal = ","
frame = "tracker"
[columns]
q1_rad = "j1"
q2_rad = "j2"
q3_rad = "j3"
q4_rad = "j4"
q5_rad = "j5"
q6_rad = "j6"
x_mm = "mx"
y_mm = "my"
z_m = "mz"
rx_deg = "a"
ry_deg = "b"
rz_deg = "c"
[orientation]
euler = "intrinsic"
order = "xyz"
"#;

fn profiled(text: &str) -> Result<TrackerData, String> {
    let profile = DataProfile::parse(PROFILE, Path::new("cell/p.toml")).unwrap();
    TrackerData::parse_profiled(text, Path::new("cell/export.csv"), &profile)
        .map_err(|e| e.to_string())
}

#[test]
fn a_profile_reads_semicolons_decimal_commas_mapped_columns_and_intrinsic_angles() {
    let header = "time;j1;j2;j3;j4;j5;j6;temp;mx;my;mz;a;b;c";
    let d = profiled(&format!(
        "{header}\r\n2,02E+13;0,5;-1;0;0;0;0;21,5;1,25;-2;0,5;30;-20;45\r\n"
    ))
    .unwrap();
    assert!(!d.base_frame);
    let r = &d.records[0];
    assert_eq!((r.line, r.q[0], r.q[1]), (2, 0.5, -1.0));
    assert_eq!(r.position, [1.25, -2.0, 500.0]);
    // Intrinsic xyz: R = Rx(a) Ry(b) Rz(c), checked against the closed form of its last row:
    // R[2] = [-cos(a) sin(b) cos(c) + sin(a) sin(c), cos(a) sin(b) sin(c) + sin(a) cos(c), cos(a) cos(b)].
    let (a, b, c) = (
        30f64.to_radians(),
        (-20f64).to_radians(),
        45f64.to_radians(),
    );
    let m = r.rotation.unwrap();
    let expected = [
        -a.cos() * b.sin() * c.cos() + a.sin() * c.sin(),
        a.cos() * b.sin() * c.sin() + a.sin() * c.cos(),
        a.cos() * b.cos(),
    ];
    for (j, e) in expected.iter().enumerate() {
        assert!((m[(2, j)] - e).abs() < 1e-15, "{j}: {} vs {e}", m[(2, j)]);
    }
    // R[0][2] = sin(b) for intrinsic xyz.
    assert!((m[(0, 2)] - b.sin()).abs() < 1e-15);

    // Errors name the file, the line and the source column.
    let e = profiled(&format!("{header}\n0;0;0;0;0;0;0;0;1,2.3;0;0;0;0;0\n")).unwrap_err();
    assert!(
        e.starts_with("cell/export.csv:2: column 9 (\"mx\"): \"1,2.3\" is not a number"),
        "{e}"
    );
    let e = profiled("time;j1;j2;j3;j4;j5;j6;mx;my;a;b;c\n").unwrap_err();
    assert!(e.contains("cell/export.csv:1: missing column \"mz\", which the data profile maps to z_m (data profile cell/p.toml)"), "{e}");
    let e = profiled(&format!("{header}\n0;0;0;0;0;0;7;0;0;0;0;0;0;0\n")).unwrap_err();
    assert!(
        e.contains(":2: column 7 (\"j6\"): 7 is beyond one turn"),
        "{e}"
    );
}

/// Derived columns (issue 15): a profile can compute one of our columns as the sum or the
/// difference of two source columns, as for data that give the commanded target and the
/// deviation of the reached position (the Barrett WAM set). Values in the unit of our column;
/// decimal commas as everywhere; errors name the source columns.
#[test]
fn a_profile_derives_a_column_from_two_source_columns() {
    let profile = r#"
delimiter = ";"
decimal = ","
[columns]
q1_deg = "j1"
q2_deg = "j2"
q3_deg = "j3"
q4_deg = "j4"
q5_deg = "j5"
q6_deg = "j6"
x_m = { sum = ["target_x", "dx"] }
y_mm = { difference = ["target_y", "minus_dy"] }
z_mm = "z"
"#;
    let profile = DataProfile::parse(profile, Path::new("wam/p.toml")).unwrap();
    let read = |text: &str| {
        TrackerData::parse_profiled(text, Path::new("wam/data.csv"), &profile)
            .map_err(|e| e.to_string())
    };
    let header = "j1;j2;j3;j4;j5;j6;target_x;dx;target_y;minus_dy;z";
    let d = read(&format!(
        "{header}\n10;20;30;40;50;60;0,5;0,0125;-250,5;-0,75;1000\n"
    ))
    .unwrap();
    let r = &d.records[0];
    // x = (0.5 + 0.0125) m, y = -250.5 - (-0.75) mm.
    assert_eq!(r.position, [(0.5 + 0.0125) * 1000.0, -250.5 + 0.75, 1000.0]);
    assert!((r.q[5] - 60f64.to_radians()).abs() < 1e-15);
    // A missing source column, a broken value: said with the names.
    let missing =
        read("j1;j2;j3;j4;j5;j6;target_x;target_y;minus_dy;z\n0;0;0;0;0;0;1;2;3;4\n").unwrap_err();
    assert!(
        missing.contains("missing column \"dx\"") && missing.contains("x_m = target_x + dx"),
        "{missing}"
    );
    let broken = read(&format!("{header}\n0;0;0;0;0;0;0,5;abc;1;2;3\n")).unwrap_err();
    assert!(
        broken.contains("\"dx\", part of x_m") && broken.contains("\"abc\" is not a number"),
        "{broken}"
    );
    // Malformed combinations in the profile.
    for bad in [
        "x_mm = { sum = [\"a\"] }",
        "x_mm = { product = [\"a\", \"b\"] }",
        "x_mm = { sum = [\"a\", \"b\"], difference = [\"a\", \"b\"] }",
    ] {
        let e = DataProfile::parse(&format!("[columns]\n{bad}\n"), Path::new("p.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("two source columns"), "{bad}: {e}");
    }
}
