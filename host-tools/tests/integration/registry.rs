//! The registry (issue 55, item 1): calibrations registered, listed, shown and exported from a
//! real calibration's files, each field checked against the files themselves; foreign, newer,
//! damaged and read-only files refused and left as they were; two processes registering at once;
//! a registration killed in the middle.

use crate::common;

use common::{ROBOT, calib, calib_in, ok, simulate, touches_calibration};
use sha2::Digest as _;
use std::path::{Path, PathBuf};

fn sha256_of(path: &Path) -> String {
    sha2::Sha256::digest(std::fs::read(path).unwrap())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// A tracker calibration of simulated ER10L-C10 data, its robot file stating the serial
/// `ER-0042`, with its report and identified file in `dir`.
fn tracker_calibration(dir: &Path) -> (PathBuf, PathBuf) {
    let robot = dir.join("er10l-serial.toml");
    let text = std::fs::read_to_string(ROBOT).unwrap();
    std::fs::write(&robot, format!("serial = \"ER-0042\"\n{text}")).unwrap();
    let (data, _) = simulate(dir, "sim", &["--poses", "60", "--seed", "3"]);
    let (report, identified) = (dir.join("tracker.json"), dir.join("er10l-identified.toml"));
    ok(&calib(&[
        "calibrate",
        "--robot",
        s(&robot),
        "--data",
        s(&data),
        "--method",
        "lm",
        "--validate",
        "0.75",
        "--report",
        s(&report),
        "--out",
        s(&identified),
    ]));
    (report, identified)
}

#[test]
fn calibrations_are_registered_listed_shown_and_exported() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("fleet.db");
    let (touches, panda_file, html) = touches_calibration(dir.path());
    let (tracker, er_file) = tracker_calibration(dir.path());
    // The touches' report states no serial.
    let refused = calib(&["registry", "add", s(&touches), "--db", s(&db)]);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--serial"));
    assert!(!db.exists(), "a refused registration creates no registry");
    let out = ok(&calib(&[
        "registry",
        "add",
        s(&touches),
        "--serial",
        "PANDA-3",
        "--identified",
        s(&panda_file),
        "--certificate",
        s(&html),
        "--db",
        s(&db),
    ]));
    assert!(out.contains("registered record 1"), "{out}");
    use std::os::unix::fs::PermissionsExt as _;
    assert_eq!(
        std::fs::metadata(&db).unwrap().permissions().mode() & 0o777,
        0o600
    );
    // The tracker report states its serial: a different --serial is refused, none is fine.
    let wrong = calib(&[
        "registry",
        "add",
        s(&tracker),
        "--serial",
        "X",
        "--db",
        s(&db),
    ]);
    assert!(String::from_utf8_lossy(&wrong.stderr).contains("ER-0042"));
    ok(&calib(&[
        "registry",
        "add",
        s(&tracker),
        "--identified",
        s(&er_file),
        "--db",
        s(&db),
    ]));
    // The same report again is refused, naming the record.
    let again = calib(&["registry", "add", s(&tracker), "--db", s(&db)]);
    assert!(
        String::from_utf8_lossy(&again.stderr)
            .contains("already registered for robot ER-0042 as record 2")
    );
    // The listing and the records against the files.
    let list: serde_json::Value =
        serde_json::from_str(&ok(&calib(&["registry", "list", "--json", "--db", s(&db)]))).unwrap();
    let list = list.as_array().unwrap();
    assert_eq!(list.len(), 2);
    let touches_json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&touches).unwrap()).unwrap();
    let held: Vec<f64> = (touches_json["held_out"].as_array().unwrap().iter())
        .map(|f| f["identified"]["authors_mean_mm"].as_f64().unwrap())
        .collect();
    let mean = held.iter().sum::<f64>() / held.len() as f64;
    let panda = list.iter().find(|r| r["serial"] == "PANDA-3").unwrap();
    assert_eq!(panda["kind"], "touches");
    assert_eq!(panda["held_out_mm"].as_f64().unwrap(), mean);
    let shown: serde_json::Value = serde_json::from_str(&ok(&calib(&[
        "registry",
        "show",
        "1",
        "--json",
        "--db",
        s(&db),
    ])))
    .unwrap();
    let record = &shown[0];
    assert_eq!(record["report_sha256"], sha256_of(&touches));
    assert_eq!(record["identified_sha256"], sha256_of(&panda_file));
    assert_eq!(record["certificate_sha256"], sha256_of(&html));
    assert_eq!(
        record["identified_toml"],
        std::fs::read_to_string(&panda_file).unwrap()
    );
    assert_eq!(record["report"], touches_json);
    assert_eq!(record["model"], "Franka Emika Panda");
    let tracker_json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&tracker).unwrap()).unwrap();
    let shown: serde_json::Value = serde_json::from_str(&ok(&calib(&[
        "registry",
        "show",
        "2",
        "--json",
        "--db",
        s(&db),
    ])))
    .unwrap();
    assert_eq!(shown[0]["covariance"], tracker_json["covariance"]);
    let mut kept = tracker_json.clone();
    for key in ["per_pose", "poses", "convergence"] {
        assert!(kept.as_object_mut().unwrap().shift_remove(key).is_some());
    }
    assert_eq!(
        shown[0]["report"], kept,
        "the report without its per-pose lists"
    );
    assert_eq!(shown[0]["held_out"], tracker_json["held_out"]);
    assert_eq!(
        shown[0]["held_out_mm"].as_f64().unwrap(),
        tracker_json["held_out"]["after"]["position"]["p50_mm"]
            .as_f64()
            .unwrap()
    );
    let text = ok(&calib(&[
        "registry",
        "list",
        "--serial",
        "ER-0042",
        "--db",
        s(&db),
    ]));
    assert!(
        text.contains("ER-0042") && !text.contains("PANDA-3"),
        "{text}"
    );
    let missing = calib(&["registry", "show", "7", "--db", s(&db)]);
    assert!(String::from_utf8_lossy(&missing.stderr).contains("no record 7"));
    // Exports: CSV and JSON.
    let csv_path = dir.path().join("fleet.csv");
    let export_csv = || {
        ok(&calib(&[
            "registry",
            "export",
            "--format",
            "csv",
            "--out",
            s(&csv_path),
            "--db",
            s(&db),
        ]))
    };
    export_csv();
    let mut reader = csv::Reader::from_path(&csv_path).unwrap();
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 2);
    assert_eq!(
        &rows[0][8],
        sha256_of(&tracker).as_str(),
        "by serial: ER-0042 first"
    );
    let first = std::fs::read(&csv_path).unwrap();
    export_csv();
    assert_eq!(
        std::fs::read(&csv_path).unwrap(),
        first,
        "replaced whole, the same records"
    );
    let into_db = calib(&[
        "registry",
        "export",
        "--format",
        "csv",
        "--out",
        s(&db),
        "--db",
        s(&db),
    ]);
    assert!(
        !into_db.status.success(),
        "the registry is never an export's target"
    );
    let json_path = dir.path().join("fleet.json");
    ok(&calib(&[
        "registry",
        "export",
        "--format",
        "json",
        "--out",
        s(&json_path),
        "--db",
        s(&db),
    ]));
    let all: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    assert_eq!(all.as_array().unwrap().len(), 2);
}

#[test]
fn foreign_newer_damaged_and_read_only_files_are_refused_and_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let (touches, _, _) = touches_calibration(dir.path());
    let add = |db: &Path| {
        calib(&[
            "registry",
            "add",
            s(&touches),
            "--serial",
            "P3",
            "--db",
            s(db),
        ])
    };
    let refused = |db: &Path, expected: &str| {
        let before = std::fs::read(db).unwrap();
        let out = add(db);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        println!("{stderr}");
        assert!(
            !out.status.success() && stderr.contains(expected),
            "{stderr}"
        );
        assert_eq!(
            std::fs::read(db).unwrap(),
            before,
            "{} changed",
            db.display()
        );
        let listed = calib(&["registry", "list", "--db", s(db)]);
        assert!(!listed.status.success());
    };
    // Not a database.
    let text = dir.path().join("notes.db");
    std::fs::write(&text, "a text file, not a database\n".repeat(200)).unwrap();
    refused(&text, "not a calib registry (not an SQLite database)");
    // Another program's SQLite database.
    let foreign = dir.path().join("foreign.db");
    {
        let c = rusqlite::Connection::open(&foreign).unwrap();
        c.execute_batch("CREATE TABLE orders (id INTEGER); INSERT INTO orders VALUES (1);")
            .unwrap();
    }
    refused(&foreign, "an SQLite database of another program");
    // A registry of a newer schema.
    let newer = dir.path().join("newer.db");
    ok(&add(&newer));
    {
        let c = rusqlite::Connection::open(&newer).unwrap();
        c.execute_batch("PRAGMA user_version = 99;").unwrap();
    }
    refused(&newer, "schema version 99, written by a newer calib");
    // A damaged registry: its pages overwritten past the header.
    let damaged = dir.path().join("damaged.db");
    ok(&add(&damaged));
    let mut bytes = std::fs::read(&damaged).unwrap();
    for b in bytes.iter_mut().skip(100) {
        *b = 0x5a;
    }
    std::fs::write(&damaged, &bytes).unwrap();
    refused(&damaged, "damaged.db");
    // A read-only registry: refused for writing, still listed.
    let read_only = dir.path().join("read-only.db");
    ok(&add(&read_only));
    use std::os::unix::fs::PermissionsExt as _;
    std::fs::set_permissions(&read_only, std::fs::Permissions::from_mode(0o400)).unwrap();
    let before = std::fs::read(&read_only).unwrap();
    let out = calib(&[
        "registry",
        "add",
        s(&touches),
        "--serial",
        "OTHER",
        "--db",
        s(&read_only),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("read-only"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(&read_only).unwrap(), before);
    assert!(ok(&calib(&["registry", "list", "--db", s(&read_only)])).contains("P3"));
    // No registry at all: listing says so, and creates nothing.
    let none = dir.path().join("none.db");
    let out = calib(&["registry", "list", "--db", s(&none)]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("no registry there"));
    assert!(!none.exists());
}

/// A full disk while registering (issue 55, must hold): the registration runs under a file-size
/// limit (`ulimit -f`, with SIGXFSZ ignored, so that a write past it fails as on a full disk) at
/// several sizes, failing while the journal is written or the database grows: each is refused
/// with what to do, the records read afterwards (read-only, through an interrupted write's
/// journal left beside the file) are those before, the file passes SQLite's integrity check, and
/// with room again the registration lands under the next number.
#[test]
fn a_full_disk_loses_no_record() {
    let dir = tempfile::tempdir().unwrap();
    let (touches, _, _) = touches_calibration(dir.path());
    let (tracker, _) = tracker_calibration(dir.path());
    let db = dir.path().join("full.db");
    for serial in ["P1", "P2", "P3", "P4"] {
        ok(&calib(&[
            "registry",
            "add",
            s(&touches),
            "--serial",
            serial,
            "--db",
            s(&db),
        ]));
    }
    let listed = || ok(&calib(&["registry", "list", "--json", "--db", s(&db)]));
    let before = listed();
    let size_kib = std::fs::metadata(&db).unwrap().len() / 1024;
    let journal = dir.path().join("full.db-journal");
    let mut journals_left = 0;
    for limit_kib in [1, size_kib / 2, size_kib] {
        let out = std::process::Command::new("bash")
            .args([
                "-c",
                &format!("trap '' XFSZ; ulimit -f {limit_kib}; exec \"$0\" registry add \"$1\" --db \"$2\""),
                env!("CARGO_BIN_EXE_calib"),
                s(&tracker),
                s(&db),
            ])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        println!("limit {limit_kib} KiB: {stderr}");
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("the disk refused a write") && stderr.contains("nothing was written"),
            "{stderr}"
        );
        journals_left += usize::from(journal.exists());
        assert_eq!(
            listed(),
            before,
            "the records after a failed write at {limit_kib} KiB"
        );
        assert!(
            !journal.exists(),
            "the interrupted write rolled back when read"
        );
    }
    assert!(journals_left > 0, "no limit interrupted a write midway");
    let c = rusqlite::Connection::open(&db).unwrap();
    let check: String = c
        .query_row("PRAGMA integrity_check", [], |r| r.get(0))
        .unwrap();
    assert_eq!(check, "ok");
    let out = ok(&calib(&["registry", "add", s(&tracker), "--db", s(&db)]));
    assert!(out.contains("record 5"), "{out}");
}

/// Two processes registering at once: every registration lands, numbered once each.
#[test]
fn two_processes_register_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let (touches, _, _) = touches_calibration(dir.path());
    let db = dir.path().join("shared.db");
    let writers: Vec<std::thread::JoinHandle<Vec<bool>>> = (0..2)
        .map(|w| {
            let (touches, db) = (touches.clone(), db.clone());
            std::thread::spawn(move || {
                (0..12)
                    .map(|i| {
                        let serial = format!("W{w}-{i}");
                        calib(&[
                            "registry",
                            "add",
                            s(&touches),
                            "--serial",
                            &serial,
                            "--db",
                            s(&db),
                        ])
                        .status
                        .success()
                    })
                    .collect()
            })
        })
        .collect();
    for writer in writers {
        assert!(writer.join().unwrap().iter().all(|ok| *ok));
    }
    let list: serde_json::Value =
        serde_json::from_str(&ok(&calib(&["registry", "list", "--json", "--db", s(&db)]))).unwrap();
    let mut ids: Vec<i64> = (list.as_array().unwrap().iter())
        .map(|r| r["id"].as_i64().unwrap())
        .collect();
    ids.sort_unstable();
    assert_eq!(ids, (1..=24).collect::<Vec<i64>>());
}

/// Registrations killed (SIGKILL) at random moments: the registry stays whole (SQLite's
/// integrity check), and every record in it is complete (its content there, its report the file's).
#[test]
fn a_registration_killed_midway_leaves_the_registry_whole() {
    use rand::{RngExt, SeedableRng};
    let dir = tempfile::tempdir().unwrap();
    let (touches, _, _) = touches_calibration(dir.path());
    let db = dir.path().join("killed.db");
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9);
    let mut finished = 0;
    for i in 0..30 {
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_calib"))
            .args([
                "registry",
                "add",
                s(&touches),
                "--serial",
                &format!("K{i}"),
                "--db",
                s(&db),
            ])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_micros(
            rng.random_range(0..15_000),
        ));
        let _ = child.kill();
        if child.wait().unwrap().success() {
            finished += 1;
        }
    }
    let c = rusqlite::Connection::open(&db).unwrap();
    let check: String = c
        .query_row("PRAGMA integrity_check", [], |r| r.get(0))
        .unwrap();
    assert_eq!(check, "ok");
    let mut statement = c
        .prepare(
            "SELECT t.report, c.report_sha256 FROM calibration AS c
             LEFT JOIN calibration_content AS t ON t.id = c.id",
        )
        .unwrap();
    let rows: Vec<(Option<String>, String)> = statement
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap()
        .map(Result::unwrap)
        .collect();
    let expected = sha256_of(&touches);
    println!(
        "{finished} of 30 registrations finished before their kill; {} records",
        rows.len()
    );
    assert!(rows.len() >= finished);
    let contents: i64 = c
        .query_row("SELECT count(*) FROM calibration_content", [], |r| r.get(0))
        .unwrap();
    assert_eq!(contents, rows.len() as i64, "no content without its record");
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&touches).unwrap()).unwrap();
    for (report, sha) in &rows {
        assert_eq!(sha, &expected);
        let report = report.as_deref().expect("no record without its content");
        assert_eq!(
            serde_json::from_str::<serde_json::Value>(report).unwrap(),
            written
        );
    }
    // And the registry still takes registrations.
    ok(&calib_in(
        dir.path(),
        &[
            "registry",
            "add",
            s(&touches),
            "--serial",
            "AFTER",
            "--db",
            s(&db),
        ],
    ));
}

/// The ER10L-C10 file stating serial `ER-7` (`er-7.toml` in `dir`), and the same robot changed
/// by `change` (`name` in `dir`, described by `comment`).
fn er7_files(
    dir: &Path,
    (name, comment): (&str, &str),
    change: impl FnOnce(&mut host_tools::io::robot_file::RobotFile),
) -> (PathBuf, PathBuf) {
    let mut file = host_tools::io::robot_file::RobotFile::read(Path::new(ROBOT)).unwrap();
    file.serial = Some("ER-7".to_string());
    let (er7, changed) = (dir.join("er-7.toml"), dir.join(name));
    std::fs::write(&er7, file.to_toml("ER-7")).unwrap();
    change(&mut file);
    std::fs::write(&changed, file.to_toml(comment)).unwrap();
    (er7, changed)
}

/// Simulated tracker data of `robot` (noise 0.02 mm, 2e-5 rad), calibrated against the
/// ER10L-C10 file stating serial `ER-7` in `dir` and registered in `db` with its identified file.
fn register_simulated(dir: &Path, db: &Path, robot: &Path, seed: u64) {
    let name = format!("s{seed}");
    let data = dir.join(format!("{name}.csv"));
    let (report, identified) = (
        dir.join(format!("{name}.json")),
        dir.join(format!("{name}-id.toml")),
    );
    let seed = seed.to_string();
    ok(&calib(&[
        "simulate",
        "--robot",
        s(robot),
        "--poses",
        "60",
        "--seed",
        &seed,
        "--position-sigma-mm",
        "0.02",
        "--orientation-sigma-rad",
        "0.00002",
        "--out",
        s(&data),
        "--truth-out",
        s(&dir.join(format!("{name}-truth.toml"))),
    ]));
    ok(&calib(&[
        "calibrate",
        "--robot",
        s(&dir.join("er-7.toml")),
        "--data",
        s(&data),
        "--method",
        "lm",
        "--validate",
        "0.25",
        "--report",
        s(&report),
        "--out",
        s(&identified),
    ]));
    ok(&calib(&[
        "registry",
        "add",
        s(&report),
        "--identified",
        s(&identified),
        "--db",
        s(db),
    ]));
}

fn compare_json(db: &Path, a: &str, b: &str, poses: &str) -> serde_json::Value {
    serde_json::from_str(&ok(&calib(&[
        "registry",
        "compare",
        a,
        b,
        "--poses",
        poses,
        "--json",
        "--db",
        s(db),
    ])))
    .unwrap()
}

/// Item 2: calibrations compared with their uncertainty. Twelve pairs of calibrations of one
/// unchanged robot (fresh noise each): their squared Mahalanobis distances follow the chi-square
/// distribution of 24 degrees of freedom, so their mean is 24 within 3 standard errors
/// (sqrt(2 x 24 / 12) = 2). The robot with joint 2's link length 0.3 mm longer: the change comes
/// back within 3 standard deviations and is judged significant alone and jointly, and the tool's
/// largest movement equals the reference kinematics' at the configuration named.
#[test]
fn compared_calibrations_are_judged_by_their_uncertainty() {
    use host_tools::analysis::reference;
    use host_tools::io::robot_file::RobotFile;
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("fleet.db");
    let (er7, longer) = er7_files(
        dir.path(),
        ("er-7-longer-a2.toml", "ER-7, a2 0.3 mm longer"),
        |file| file.joint[1].a_mm += 0.3,
    );
    for seed in 11..35 {
        register_simulated(dir.path(), &db, &er7, seed);
    }
    let distances: Vec<f64> = (1..=12)
        .map(|pair| {
            let (a, b) = ((2 * pair - 1).to_string(), (2 * pair).to_string());
            let test = &compare_json(&db, &a, &b, "50")["joint_test"];
            assert_eq!(test["degrees_of_freedom"], 24);
            test["mahalanobis_squared"].as_f64().unwrap()
        })
        .collect();
    let mean = distances.iter().sum::<f64>() / 12.0;
    println!("squared Mahalanobis distances, unchanged robot: {distances:.2?}, mean {mean:.2}");
    assert!((mean - 24.0).abs() < 3.0 * 2.0, "{mean}");

    register_simulated(dir.path(), &db, &longer, 35);
    let c = compare_json(&db, "1", "25", "1000");
    let da2 = (c["parameters"].as_array().unwrap().iter())
        .find(|p| p["parameter"] == "da2")
        .unwrap();
    let (change, sd) = (da2["change"].as_f64().unwrap(), da2["sd"].as_f64().unwrap());
    println!("da2 changed by {change:.4} +- {sd:.4} mm (truth 0.3)");
    assert!((change - 0.3).abs() < 3.0 * sd && da2["significant"] == true);
    assert_eq!(c["joint_test"]["significant"], true);
    assert_eq!(c["same_robot"], true);
    let m = &c["movement"];
    let q: Vec<f64> = (m["max_pose_deg"].as_array().unwrap().iter())
        .map(|v| v.as_f64().unwrap().to_radians())
        .collect();
    let model = |n: u64| {
        let path = dir.path().join(format!("s{n}-id.toml"));
        reference::model(&RobotFile::read(&path).unwrap(), &[], &[0.0; 6], &[0.0; 6])
    };
    let (pa, pb) = (model(11).forward(&q), model(35).forward(&q));
    let moved = ((0..3).map(|i| (pb[i][3] - pa[i][3]).powi(2)).sum::<f64>()).sqrt();
    let max = m["max_mm"].as_f64().unwrap();
    println!(
        "tool movement: mean {} mm, largest {max} mm (reference {moved})",
        m["mean_mm"]
    );
    assert!((moved - max).abs() < 1e-9, "{moved} {max}");
    // A record without its identified file cannot be compared: said, with the fix.
    let (touches, _, _) = touches_calibration(dir.path());
    ok(&calib(&[
        "registry",
        "add",
        s(&touches),
        "--serial",
        "P3",
        "--db",
        s(&db),
    ]));
    let refused = calib(&["registry", "compare", "1", "26", "--db", s(&db)]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success() && stderr.contains("--identified"),
        "{stderr}"
    );
}

/// Item 5: is the right calibration on the controller? Blocks exported from the registered
/// identified files (f32 with another sequence number, f64), the identified file itself, and the
/// nominal model, each checked against robot ER-7's two calibrations: the latest passes, the
/// older one is named with the newer (exit status 3), the nominal model matches none and the
/// values that differ are those of the files.
#[test]
fn the_controllers_calibration_is_verified() {
    use host_tools::io::robot_file::RobotFile;
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("fleet.db");
    let (er7, longer) = er7_files(
        dir.path(),
        ("er-7-longer-a2.toml", "ER-7, a2 0.3 mm longer"),
        |file| file.joint[1].a_mm += 0.3,
    );
    register_simulated(dir.path(), &db, &er7, 11);
    register_simulated(dir.path(), &db, &longer, 12);
    let block = |params: &Path, name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec![
            "export",
            "--params",
            s(params),
            "--format",
            "block",
            "--out",
            s(&out),
        ];
        args.extend_from_slice(extra);
        ok(&calib(&args));
        out
    };
    let verify = |flag: &str, path: &Path| {
        let out = calib(&[
            "registry",
            "verify",
            "--serial",
            "ER-7",
            flag,
            s(path),
            "--json",
            "--db",
            s(&db),
        ]);
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        (out.status.code(), json)
    };
    let (older, latest) = (
        dir.path().join("s11-id.toml"),
        dir.path().join("s12-id.toml"),
    );
    let (code, v) = verify(
        "--block",
        &block(&latest, "latest.block", &["--sequence", "9"]),
    );
    assert_eq!(
        (code, &v["matched"]["id"], &v["matched"]["how"]),
        (Some(0), &2.into(), &"same model".into())
    );
    let f64_block = block(&latest, "latest-f64.block", &["--scalar", "f64"]);
    assert_eq!(verify("--block", &f64_block).0, Some(0));
    let (code, v) = verify("--robot", &latest);
    assert_eq!(
        (code, &v["matched"]["how"]),
        (Some(0), &"identical file".into())
    );
    let (code, v) = verify("--block", &block(&older, "older.block", &[]));
    assert_eq!(
        (code, &v["matched"]["id"], &v["latest"]),
        (Some(3), &1.into(), &2.into())
    );
    let text = String::from_utf8(
        calib(&[
            "registry",
            "verify",
            "--serial",
            "ER-7",
            "--robot",
            s(&older),
            "--db",
            s(&db),
        ])
        .stdout,
    )
    .unwrap();
    assert!(
        text.contains("NOT THE LATEST: it holds record 1") && text.contains("record 2"),
        "{text}"
    );
    // The nominal model: no match; the values that differ are the files'.
    let (code, v) = verify(
        "--block",
        &block(&er7, "nominal.block", &["--scalar", "f64"]),
    );
    assert_eq!((code, &v["matched"]), (Some(3), &serde_json::Value::Null));
    let nearest = &v["nearest"];
    let id = nearest["id"].as_i64().unwrap();
    let registered = RobotFile::read(if id == 1 { &older } else { &latest }).unwrap();
    let nominal = RobotFile::read(&er7).unwrap();
    let a2 = (nearest["differences"].as_array().unwrap().iter())
        .find(|d| d["value"] == "a2")
        .unwrap();
    assert_eq!(a2["given"].as_f64().unwrap(), nominal.joint[1].a_mm);
    assert_eq!(a2["registered"].as_f64().unwrap(), registered.joint[1].a_mm);
    println!("nominal model against the registry: {nearest}");
    let other = calib(&[
        "registry",
        "verify",
        "--serial",
        "ER-8",
        "--robot",
        s(&er7),
        "--db",
        s(&db),
    ]);
    assert!(String::from_utf8_lossy(&other.stderr).contains("no calibration of robot ER-8"));
}

/// Item 3: shift checks. A calibration in a tracker's frame (60 simulated poses, 0.02 mm
/// noise), then four checks of 10 poses each, a week apart: the same robot (passes), the base
/// moved 0.3 mm along the tracker's x, joint 3's zero moved 0.02 deg, the probe moved by
/// (0.2, 0, 0.1) mm on the flange. Each drift exits with status 3 and names its cause with the
/// change the simulation made (within 10 %); the drift rate equals the least-squares line
/// through the recorded means; the same data twice are refused and not recorded.
#[test]
fn shift_checks_name_the_cause_and_state_the_drift() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("cell.db");
    let (er7, zero) = er7_files(
        dir.path(),
        ("er-7-zero3.toml", "ER-7, joint 3's zero moved"),
        |file| file.joint[2].theta_offset_deg += 0.02,
    );
    let simulate = |robot: &Path, name: &str, poses: &str, seed: &str, extra: &[&str]| {
        let data = dir.path().join(format!("{name}.csv"));
        let truth = dir.path().join(format!("{name}-truth.toml"));
        let mut args = vec![
            "simulate",
            "--robot",
            s(robot),
            "--poses",
            poses,
            "--seed",
            seed,
            "--position-sigma-mm",
            "0.02",
            "--position-only",
            "--tracker-rpy-deg",
            "0,0,30",
            "--out",
            s(&data),
            "--truth-out",
            s(&truth),
        ];
        args.extend_from_slice(extra);
        if !extra.contains(&"--tracker-xyz-mm") {
            args.extend_from_slice(&["--tracker-xyz-mm", "2000,500,300"]);
        }
        ok(&calib(&args));
        data
    };
    let data = simulate(&er7, "calibration", "60", "3", &[]);
    let (report, identified) = (dir.path().join("cal.json"), dir.path().join("cal-id.toml"));
    ok(&calib(&[
        "calibrate",
        "--robot",
        s(&er7),
        "--data",
        s(&data),
        "--method",
        "lm",
        "--report",
        s(&report),
        "--out",
        s(&identified),
    ]));
    ok(&calib(&[
        "registry",
        "add",
        s(&report),
        "--identified",
        s(&identified),
        "--db",
        s(&db),
    ]));
    let check = |data: &Path, day: u32| {
        let out = calib(&[
            "check-shift",
            "--serial",
            "ER-7",
            "--data",
            s(data),
            "--json",
            "--db",
            s(&db),
            "--checked-at",
            &format!("2026-11-{day:02}T06:00:00Z"),
        ]);
        let json: serde_json::Value = serde_json::from_slice(&out.stdout)
            .unwrap_or_else(|_| panic!("{}", String::from_utf8_lossy(&out.stderr)));
        (out.status.code(), json)
    };
    let same = simulate(&er7, "same", "10", "50", &[]);
    let (code, same_check) = check(&same, 1);
    assert_eq!(
        (code, &same_check["result"]["drifted"]),
        (Some(0), &false.into())
    );
    type Case<'a> = (&'a Path, &'a [&'a str], &'a str, &'a [(&'a str, f64)]);
    let cases: [Case<'_>; 3] = [
        (
            &er7,
            &["--tracker-xyz-mm", "2000.3,500,300"],
            "the base moved",
            &[("base_tx", 0.3)],
        ),
        (&zero, &[], "joint 3's zero", &[("dtheta3", 0.02)]),
        (
            &er7,
            &["--tool-xyz-mm", "0.2,0,0.1"],
            "the tool or probe moved",
            &[("tool_tx", 0.2), ("tool_tz", 0.1)],
        ),
    ];
    let mut means = vec![same_check["result"]["mean_mm"].as_f64().unwrap()];
    for (i, (robot, extra, cause, changes)) in cases.iter().enumerate() {
        let data = simulate(
            robot,
            &format!("check{i}"),
            "10",
            &(51 + i).to_string(),
            extra,
        );
        let (code, json) = check(&data, 8 + 7 * i as u32);
        let result = &json["result"];
        println!("{cause}: {}", result["cause"]);
        assert_eq!(code, Some(3));
        assert!(
            result["cause"]["name"].as_str().unwrap().starts_with(cause),
            "{result}"
        );
        for (name, expected) in *changes {
            let fitted = (result["cause"]["change"].as_array().unwrap().iter())
                .find(|c| c[0] == *name)
                .unwrap()[1]
                .as_f64()
                .unwrap();
            assert!(
                (fitted - expected).abs() < 0.1 * expected,
                "{name} {fitted}"
            );
        }
        means.push(result["mean_mm"].as_f64().unwrap());
    }
    // The drift rate: the least-squares line through the four means, days 1, 8, 15, 22.
    let days = [1.0, 8.0, 15.0, 22.0];
    let (mt, my) = (
        days.iter().sum::<f64>() / 4.0,
        means.iter().sum::<f64>() / 4.0,
    );
    let slope = (days.iter().zip(&means))
        .map(|(t, y)| (t - mt) * (y - my))
        .sum::<f64>()
        / days.iter().map(|t| (t - mt).powi(2)).sum::<f64>();
    let (_, last) = check(&simulate(&er7, "later", "10", "60", &[]), 29);
    assert_eq!(last["drift_rate"]["checks"], 5);
    let days = [1.0, 8.0, 15.0, 22.0, 29.0];
    means.push(last["result"]["mean_mm"].as_f64().unwrap());
    let (mt, my) = (
        days.iter().sum::<f64>() / 5.0,
        means.iter().sum::<f64>() / 5.0,
    );
    let slope5 = (days.iter().zip(&means))
        .map(|(t, y)| (t - mt) * (y - my))
        .sum::<f64>()
        / days.iter().map(|t| (t - mt).powi(2)).sum::<f64>();
    let rate = last["drift_rate"]["mm_per_30_days"].as_f64().unwrap();
    println!(
        "drift rate {rate} mm per 30 days (four checks: {})",
        slope * 30.0
    );
    assert!((rate - slope5 * 30.0).abs() < 1e-9);
    // The same data again: refused, nothing recorded.
    let again = calib(&[
        "check-shift",
        "--serial",
        "ER-7",
        "--data",
        s(&same),
        "--db",
        s(&db),
    ]);
    assert!(
        String::from_utf8_lossy(&again.stderr)
            .contains("already checked against record 1 with these settings as shift check 1")
    );
    let listed = ok(&calib(&[
        "registry",
        "checks",
        "--serial",
        "ER-7",
        "--json",
        "--db",
        s(&db),
    ]));
    let listed: serde_json::Value = serde_json::from_str(&listed).unwrap();
    assert_eq!(listed["checks"].as_array().unwrap().len(), 5);
    // The trend: the calibration (no held-out poses: not drawn, and said), the five checks (two
    // red and two green markers besides the legend's), the drift line labelled with its rate.
    let svg = dir.path().join("trend.svg");
    ok(&calib(&[
        "registry",
        "trend",
        "--serial",
        "ER-7",
        "--out",
        s(&svg),
        "--db",
        s(&db),
    ]));
    let svg = std::fs::read_to_string(&svg).unwrap();
    assert_eq!(
        svg.matches("<polygon").count(),
        5 + 1,
        "five checks and the legend's marker"
    );
    assert!(svg.contains("1 without a date or held-out figure, not drawn"));
    assert!(
        svg.contains(&format!("drift: {rate:+.4} mm per 30 days")),
        "{rate}"
    );
}

/// A shift check on real data: the UR10 calibrated on 50 poses of Series B, then checked with
/// Series D (632 poses of a later session, the tracker placed elsewhere). Without re-registering
/// the tracker, the base "moved" by metres; re-registered, the errors equal `calib evaluate
/// --fit-frames base` (mean and largest to 1e-9 mm) and lie beyond the calibration's prediction:
/// a drift, exit status 3.
#[test]
fn a_later_session_of_the_real_ur10_is_checked() {
    let manifest = env!("CARGO_MANIFEST_DIR");
    let (robot, profile) = (
        format!("{manifest}/robots/ur10.toml"),
        format!("{manifest}/profiles/ipa-ur10-lasertracker.toml"),
    );
    let data = |series: &str| format!("{manifest}/data/ipa-ur10-lasertracker/{series}.csv");
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("ur10.db");
    let (report, identified) = (dir.path().join("b.json"), dir.path().join("b-id.toml"));
    ok(&calib(&[
        "calibrate",
        "--robot",
        &robot,
        "--data",
        &data("series-b-joint-configurations"),
        "--profile",
        &profile,
        "--validate",
        "0.9666",
        "--report",
        s(&report),
        "--out",
        s(&identified),
    ]));
    ok(&calib(&[
        "registry",
        "add",
        s(&report),
        "--identified",
        s(&identified),
        "--serial",
        "UR10-IPA",
        "--db",
        s(&db),
    ]));
    let data_d = data("series-d-iso-cubes");
    let check = |extra: &[&str]| {
        let mut args = vec![
            "check-shift",
            "--serial",
            "UR10-IPA",
            "--data",
            &data_d,
            "--profile",
            &profile,
            "--json",
            "--db",
            s(&db),
        ];
        args.extend_from_slice(extra);
        let out = calib(&args);
        let json: serde_json::Value = serde_json::from_slice(&out.stdout)
            .unwrap_or_else(|_| panic!("{}", String::from_utf8_lossy(&out.stderr)));
        (out.status.code(), json["result"].clone())
    };
    let (code, moved) = check(&["--checked-at", "2021-08-01T08:00:00Z"]);
    assert_eq!(code, Some(3));
    assert!(
        moved["cause"]["name"]
            .as_str()
            .unwrap()
            .starts_with("the base moved")
    );
    assert!(moved["mean_mm"].as_f64().unwrap() > 1000.0);
    let (code, registered) = check(&["--register-tracker", "--checked-at", "2021-08-02T08:00:00Z"]);
    let evaluation: serde_json::Value = serde_json::from_str(&ok(&calib(&[
        "evaluate",
        "--robot",
        s(&identified),
        "--data",
        &data_d,
        "--profile",
        &profile,
        "--fit-frames",
        "base",
        "--json",
    ])))
    .unwrap();
    let (mean, max) = (
        registered["mean_mm"].as_f64().unwrap(),
        registered["max_mm"].as_f64().unwrap(),
    );
    println!(
        "Series D against Series B's calibration, tracker re-registered: mean {mean} mm, largest {max} mm, {} of 632 beyond (chance allows {}), cause {}",
        registered["beyond"], registered["beyond_allowed"], registered["cause"]
    );
    assert!((mean - evaluation["position_mm"]["mean"].as_f64().unwrap()).abs() < 1e-9);
    assert!((max - evaluation["position_mm"]["max"].as_f64().unwrap()).abs() < 1e-9);
    assert_eq!((code, &registered["drifted"]), (Some(3), &true.into()));
}

/// `calib calibrate --registry`: the calibration registered as `calib registry add` would with its
/// report, identified file and certificate (each SHA-256 the file's); refused before anything is
/// calibrated without `--report`, for a robot file stating no serial, or with the registry named
/// as one of the outputs.
#[test]
fn calibrate_registers_its_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("cell.db");
    let robot = dir.path().join("er10l-serial.toml");
    let text = std::fs::read_to_string(ROBOT).unwrap();
    std::fs::write(&robot, format!("serial = \"ER-0042\"\n{text}")).unwrap();
    let (data, _) = simulate(dir.path(), "sim", &["--poses", "40", "--seed", "3"]);
    let (report, identified, html) = (
        dir.path().join("r.json"),
        dir.path().join("id.toml"),
        dir.path().join("r.html"),
    );
    let calibrate = |robot: &Path, extra: &[&str]| {
        let mut args = vec![
            "calibrate",
            "--robot",
            s(robot),
            "--data",
            s(&data),
            "--method",
            "lm",
        ];
        args.extend_from_slice(extra);
        calib(&args)
    };
    let refused = calibrate(&robot, &["--registry", s(&db), "--out", s(&identified)]);
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--registry needs --report"));
    let refused = calibrate(
        Path::new(ROBOT),
        &["--registry", s(&db), "--report", s(&report)],
    );
    assert!(String::from_utf8_lossy(&refused.stderr).contains("states no serial"));
    let refused = calibrate(&robot, &["--registry", s(&report), "--report", s(&report)]);
    assert!(String::from_utf8_lossy(&refused.stderr).contains("is also --report"));
    assert!(
        !db.exists() && !report.exists() && !identified.exists(),
        "nothing written"
    );
    let out = ok(&calibrate(
        &robot,
        &[
            "--registry",
            s(&db),
            "--report",
            s(&report),
            "--out",
            s(&identified),
            "--html",
            s(&html),
        ],
    ));
    assert!(out.contains("registered record 1: robot ER-0042"), "{out}");
    let shown: serde_json::Value = serde_json::from_str(&ok(&calib(&[
        "registry",
        "show",
        "1",
        "--json",
        "--db",
        s(&db),
    ])))
    .unwrap();
    assert_eq!(shown[0]["report_sha256"], sha256_of(&report));
    assert_eq!(shown[0]["identified_sha256"], sha256_of(&identified));
    assert_eq!(shown[0]["certificate_sha256"], sha256_of(&html));
}

/// The fleet page (item 7): two calibrations of ER-7 with a shift check and a pose test, a
/// calibration from touches of a Panda: one row per robot with its count, last calibration,
/// due date (a year after it; overdue when judged a century later), last check and pose test as
/// recorded; the page loads in a headless Chromium with its rows.
#[test]
fn the_fleet_page_shows_every_robot() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("fleet.db");
    er7_files(dir.path(), ("er-7-copy.toml", "ER-7"), |_| {});
    register_simulated(dir.path(), &db, Path::new(ROBOT), 1);
    register_simulated(dir.path(), &db, Path::new(ROBOT), 2);
    let (touches, _, _) = touches_calibration(dir.path());
    ok(&calib(&[
        "registry",
        "add",
        s(&touches),
        "--serial",
        "PANDA-3",
        "--db",
        s(&db),
    ]));
    ok(&calib(&[
        "check-shift",
        "--serial",
        "ER-7",
        "--data",
        s(&dir.path().join("s2.csv")),
        "--checked-at",
        "2026-11-29T06:00:00Z",
        "--db",
        s(&db),
    ]));
    let (targets, run) = common::drifting_run(dir.path());
    ok(&calib(&[
        "iso9283",
        "evaluate",
        "--targets",
        s(&targets),
        "--data",
        s(&run),
        "--robot",
        ROBOT,
        "--registry",
        s(&db),
        "--serial",
        "ER-7",
        "--tested-at",
        "2026-11-29T07:00:00Z",
    ]));
    let listed: serde_json::Value =
        serde_json::from_str(&ok(&calib(&["registry", "list", "--json", "--db", s(&db)]))).unwrap();
    let tests: serde_json::Value = serde_json::from_str(&ok(&calib(&[
        "registry",
        "pose-tests",
        "--serial",
        "ER-7",
        "--json",
        "--db",
        s(&db),
    ])))
    .unwrap();
    let page_of = |today: &str| {
        let out = dir.path().join(format!("fleet-{today}.html"));
        let said = ok(&calib(&[
            "registry",
            "fleet",
            "--out",
            s(&out),
            "--today",
            today,
            "--db",
            s(&db),
        ]));
        (std::fs::read_to_string(&out).unwrap(), said, out)
    };
    let (page, said, out) = page_of("2026-11-30");
    assert!(said.contains("2 robots, 0 overdue"), "{said}");
    let rows: Vec<&str> = page.lines().filter(|l| l.starts_with("<tr><td>")).collect();
    assert_eq!(rows.len(), 2);
    let er7 = rows
        .iter()
        .find(|r| r.starts_with("<tr><td>ER-7</td>"))
        .unwrap();
    let last = listed
        .as_array()
        .unwrap()
        .iter()
        .rfind(|r| r["serial"] == "ER-7")
        .unwrap();
    let calibrated = last["calibrated_at"].as_str().unwrap();
    let due = humantime::format_rfc3339_seconds(
        humantime::parse_rfc3339(calibrated).unwrap()
            + std::time::Duration::from_secs(365 * 86_400),
    )
    .to_string();
    assert!(
        er7.contains(&format!(
            "<td>2</td><td>{calibrated} (#{}, tracker)</td>",
            last["id"]
        )),
        "{er7}"
    );
    assert!(er7.contains(&format!("<td>{}</td>", &due[..10])), "{er7}");
    assert!(
        er7.contains("<td>2026-11-29T06:00:00Z</td>")
            && er7.contains("<span class=\"ok\">ok</span>"),
        "{er7}"
    );
    let ap = tests[0]["ap_max_mm"].as_f64().unwrap();
    assert!(
        er7.contains(&format!("<td>2026-11-29T07:00:00Z</td><td>{ap:.4}</td>")),
        "{er7}"
    );
    assert!(rows.iter().any(|r| r.starts_with("<tr><td>PANDA-3</td>")
        && r.contains("touches")
        && r.contains("<td>none</td>")));
    let (later, said, _) = page_of("2126-01-01");
    assert!(said.contains("2 robots, 2 overdue"), "{said}");
    assert_eq!(later.matches("OVERDUE").count(), 2);
    // A bad day and a registry that is not there are refused, nothing written.
    let bad = calib(&[
        "registry",
        "fleet",
        "--out",
        s(&dir.path().join("x.html")),
        "--today",
        "2026-02-30",
        "--db",
        s(&db),
    ]);
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("--today"));
    assert!(!dir.path().join("x.html").exists());
    // In a real browser: the page loads and its table has the two robots.
    let Some(browser) = host_tools::report::pdf::browser() else {
        assert!(
            std::env::var("CALIB_REQUIRE_CHROMIUM").as_deref() != Ok("1"),
            "no chromium"
        );
        return;
    };
    let profile = tempfile::tempdir().unwrap();
    let dom = std::process::Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", out.display()))
        .output()
        .unwrap();
    let dom = String::from_utf8_lossy(&dom.stdout);
    assert_eq!(dom.matches("<tr><td>").count(), 2, "{dom}");
    assert!(dom.contains("<h1>Fleet</h1>"));
}

/// The JSON report at `path` without what differs between two runs of one calibration: when
/// and how long it ran, the command line and the run's file names.
fn report_without_run(path: &Path) -> serde_json::Value {
    let mut report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    for key in [
        "calibrated_at",
        "seconds",
        "command_line",
        "inputs",
        "robot",
        "data",
    ] {
        report.as_object_mut().unwrap().remove(key);
    }
    report
}

/// Batch calibration (item 7): three robots from one manifest, two calibrated and registered,
/// one refused (two poses) with its reason and nothing written for it; each calibrated robot's
/// report equals `calib calibrate` run alone with the same options, the summary states its
/// figures, the registry its files' hashes. A manifest error refuses the batch before anything is
/// calibrated; an acceptance criterion failed on one robot gives exit status 3.
#[test]
fn a_batch_calibrates_each_robot_of_its_manifest() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = std::fs::read_to_string(ROBOT).unwrap();
    for serial in ["ER-A", "ER-B", "ER-C"] {
        std::fs::write(
            d.join(format!("{serial}.toml")),
            format!("serial = \"{serial}\"\n{text}"),
        )
        .unwrap();
    }
    let noise = ["--position-sigma-mm", "0.02"];
    simulate(
        d,
        "a",
        &[&["--poses", "60", "--seed", "1"][..], &noise].concat(),
    );
    simulate(
        d,
        "b",
        &[&["--poses", "60", "--seed", "2"][..], &noise].concat(),
    );
    simulate(d, "c", &["--poses", "2", "--seed", "3"]);
    let manifest = |robots: &str| {
        let path = d.join("cell.toml");
        std::fs::write(
            &path,
            format!("[calibrate]\nmethod = \"lm\"\nvalidate = 0.25\naccept = [\"95% <= 0.5 mm\"]\n{robots}"),
        )
        .unwrap();
        path
    };
    let robot = |serial: &str, data: &str, extra: &str| {
        format!("\n[[robot]]\nrobot = \"{serial}.toml\"\ndata = \"{data}.csv\"\n{extra}")
    };
    let three = [
        robot("ER-A", "a", ""),
        robot("ER-B", "b", "validate_seed = 3"),
        robot("ER-C", "c", ""),
    ]
    .concat();
    let (out_dir, db) = (d.join("results"), d.join("cell.db"));
    let batch = |manifest: &Path, out_dir: &Path| {
        calib(&[
            "batch",
            s(manifest),
            "--out-dir",
            s(out_dir),
            "--registry",
            s(&db),
            "--quiet",
        ])
    };
    // Refused before anything is calibrated: a key calibrate does not know, an output key,
    // two robots of one serial.
    let refusals = [
        (
            robot("ER-A", "a", "modle = \"lm\""),
            "unexpected argument '--modle'",
        ),
        (
            robot("ER-A", "a", "report = \"r.json\""),
            "report: set by calib batch itself",
        ),
        (
            [robot("ER-A", "a", ""), robot("ER-A", "b", "")].concat(),
            "robots 1 and 2 are both serial ER-A",
        ),
        (robot("ER-A", "missing", ""), "--data"),
    ];
    for (robots, expected) in refusals {
        let out = batch(&manifest(&robots), &out_dir);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && stderr.contains(expected),
            "{expected}: {stderr}"
        );
        assert!(
            !out_dir.exists() && !db.exists(),
            "nothing written: {stderr}"
        );
    }
    let out = batch(&manifest(&three), &out_dir);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    println!("{stdout}{stderr}");
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("1 of 3 robots were refused"), "{stderr}");
    assert!(
        stdout.contains("refused: 1 poses give 6 equations"),
        "{stdout}"
    );
    assert!(
        !out_dir.join("ER-C").exists(),
        "nothing written for the refused robot"
    );
    let summary: Vec<std::collections::HashMap<String, String>> =
        csv::Reader::from_path(out_dir.join("summary.csv"))
            .unwrap()
            .deserialize()
            .map(Result::unwrap)
            .collect();
    let status: Vec<&str> = summary.iter().map(|r| r["status"].as_str()).collect();
    assert_eq!(status, ["PASS", "PASS", "refused"]);
    for (i, (serial, data, seed)) in [("ER-A", "a", "0"), ("ER-B", "b", "3")]
        .into_iter()
        .enumerate()
    {
        // The same calibration alone.
        let alone = d.join(format!("{serial}-alone.json"));
        ok(&calib_in(
            d,
            &[
                "calibrate",
                "--robot",
                &format!("{serial}.toml"),
                "--data",
                &format!("{data}.csv"),
                "--method",
                "lm",
                "--validate",
                "0.25",
                "--validate-seed",
                seed,
                "--accept",
                "95% <= 0.5 mm",
                "--report",
                s(&alone),
                "--quiet",
            ],
        ));
        let report = out_dir.join(serial).join("report.json");
        assert_eq!(
            report_without_run(&report),
            report_without_run(&alone),
            "{serial}"
        );
        let expected = report_without_run(&alone);
        let held = &expected["held_out"]["after"];
        let number = |key: &str| summary[i][key].parse::<f64>().unwrap();
        assert_eq!(
            number("held_out_p95_mm"),
            held["position"]["p95_mm"].as_f64().unwrap()
        );
        assert_eq!(
            number("held_out_max_mm"),
            held["position"]["max_mm"].as_f64().unwrap()
        );
        assert_eq!(
            number("expanded_uncertainty_mm"),
            expected["budget"]["expanded_mm"].as_f64().unwrap()
        );
        let shown: serde_json::Value = serde_json::from_str(&ok(&calib(&[
            "registry",
            "show",
            &(i + 1).to_string(),
            "--json",
            "--db",
            s(&db),
        ])))
        .unwrap();
        assert_eq!(shown[0]["serial"], serial);
        assert_eq!(shown[0]["report_sha256"], sha256_of(&report));
        assert_eq!(
            shown[0]["certificate_sha256"],
            sha256_of(&out_dir.join(serial).join("certificate.html"))
        );
        assert_eq!(
            shown[0]["identified_sha256"],
            sha256_of(&out_dir.join(serial).join("identified.toml"))
        );
    }
    // An acceptance criterion failed on one robot, none refused: status 3, every file written.
    let strict = [
        robot("ER-A", "a", ""),
        robot("ER-B", "b", "accept = [\"95% <= 0.001 mm\"]"),
    ]
    .concat();
    let out = calib(&[
        "batch",
        s(&manifest(&strict)),
        "--out-dir",
        s(&d.join("strict")),
        "--quiet",
    ]);
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary = std::fs::read_to_string(d.join("strict/summary.csv")).unwrap();
    assert!(
        summary.contains("\nER-A,PASS,") && summary.contains("\nER-B,FAIL,"),
        "{summary}"
    );
}
