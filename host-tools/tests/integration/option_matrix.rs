//! No option is ever taken without a word (issue 52, V10, as a class): every option of every
//! command, as its `--help` lists it, is added to each of the command's base runs (the modes
//! that matter to it: least squares, swarm, position-only data, pose data, ...). The run must
//! either refuse, naming the option (or a file it names, or an input it made fail), and write
//! nothing, or change what the command writes: its result files and standard output, without
//! the provenance that records the command line and the time. An option that does neither was
//! taken and ignored.
//!
//! The table of each command must list every option its `--help` shows, so a new option is
//! tested here the day it is added. The few options that may rightly change nothing on these
//! data (a limit the inputs stay within, a permission the result does not need) say why.

use crate::common;

use common::ROBOT;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Output;
use std::sync::OnceLock;

/// What adding an option to a base run does.
#[derive(Clone, Copy)]
enum Variation {
    /// A flag: added as it is.
    Flag,
    /// An option with this value (`{F}` is the fixture folder, `{R}` the ER10L-C10 robot file);
    /// when the base run has the option already, the value replaces the base run's: the first
    /// of the `|`-separated values that differs from the base run's.
    Value(&'static str),
    /// Per base run: `Some(variation)`, or `None` where the option is not varied (a permission
    /// the base run does not need: the reason is the string).
    PerBase(&'static [Option<Variation>], &'static str),
    /// Not varied, with the reason it may change nothing here.
    Exempt(&'static str),
}
use Variation::{Exempt, Flag, PerBase, Value};

/// An input every run of the command reads.
const REQUIRED: Variation = Exempt("required: every run reads it");

/// The global option every command takes.
const INPUT_LIMIT: (&str, Variation) = (
    "--max-input-mb",
    Exempt("a limit: inputs below it read the same (tested in input_guards.rs)"),
);

/// The inputs every base run reads, written once per test process into the target folder's
/// scratch space (a static is never dropped, so a temporary folder would be left behind):
/// simulated ER10L-C10 data (pose and position-only), their identified models, a plan, its
/// measurement and data profiles.
fn fixture() -> &'static Path {
    static FIXTURE: OnceLock<std::path::PathBuf> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("option-matrix");
        if dir.exists() {
            std::fs::remove_dir_all(&dir).unwrap();
        }
        std::fs::create_dir_all(&dir).unwrap();
        make_fixture(&dir);
        dir
    })
}

fn make_fixture(f: &Path) {
    let run = |args: &[&str]| {
        common::ok(&common::calib_in(f, args));
    };
    let noise = [
        "--position-sigma-mm",
        "0.02",
        "--orientation-sigma-rad",
        "2e-5",
    ];
    // Errors a compensation corrects within its default bounds (5 mm, 0.5 deg).
    let errors = [
        "--errors",
        "random",
        "--random-length-mm",
        "0.3",
        "--random-angle-rad",
        "0.002",
    ];
    let mut pose = vec!["simulate", "--robot", ROBOT, "--poses", "40", "--seed", "1"];
    pose.extend(errors);
    pose.extend(noise);
    pose.extend(["--out", "pose.csv", "--truth-out", "truth.toml"]);
    run(&pose);
    let mut held_out = vec!["simulate", "--robot", ROBOT, "--poses", "15", "--seed", "3"];
    held_out.extend(errors);
    held_out.extend(noise);
    held_out.extend(["--out", "pose2.csv", "--truth-out", "truth2.toml"]);
    run(&held_out);
    run(&[
        "simulate",
        "--robot",
        ROBOT,
        "--poses",
        "40",
        "--seed",
        "2",
        "--position-only",
        "--position-sigma-mm",
        "0.02",
        "--tracker-xyz-mm",
        "2000,100,50",
        "--tracker-rpy-deg",
        "1,2,3",
        "--tool-xyz-mm",
        "0,0,100",
        "--out",
        "pos.csv",
        "--truth-out",
        "truth-pos.toml",
    ]);
    run(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        "pose.csv",
        "--method",
        "lm",
        "--out",
        "params.toml",
        "--quiet",
    ]);
    run(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        "pos.csv",
        "--frames",
        "base+tool",
        "--method",
        "lm",
        "--out",
        "params-pos.toml",
        "--report",
        "pos.json",
        "--quiet",
    ]);
    run(&[
        "plan",
        "--robot",
        ROBOT,
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
        "--joint-targets",
        "targets.csv",
    ]);
    // The plan measured (the tracker's export, with the plan's ids in its order).
    run(&[
        "simulate",
        "--robot",
        ROBOT,
        "--joints-from",
        "plan.csv",
        "--position-only",
        "--position-sigma-mm",
        "0.02",
        "--seed",
        "4",
        "--out",
        "measured.csv",
        "--truth-out",
        "truth-plan.toml",
    ]);
    timed_export_and_log(f);
    // Target poses without joints (the configuration then comes from an option).
    let poses = std::fs::read_to_string(f.join("pose.csv")).unwrap();
    let bare: Vec<String> = poses
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let fields: Vec<&str> = l.split(',').collect();
            [&fields[..1], &fields[7..]].concat().join(",")
        })
        .collect();
    std::fs::write(f.join("poses.csv"), bare.join("\n") + "\n").unwrap();
    std::fs::write(
        f.join("profile.toml"),
        "description = \"our CSV, measured by a laser tracker\"\ndelimiter = \",\"\n\n\
         [instrument]\nname = \"a laser tracker\"\nmpe_um = 15.0\nmpe_um_per_m = 6.0\n",
    )
    .unwrap();
    // An ISO 9283 run of 6 cycles in the base frame (iso/targets.csv, iso/run.csv).
    std::fs::create_dir(f.join("iso")).unwrap();
    common::drifting_run(&f.join("iso"));
    std::fs::write(
        f.join("log-profile-s.toml"),
        "description = \"the robot log, times read as s\"\ndelimiter = \",\"\n\n[columns]\n\
         id = \"pose\"\ntime_s = \"t\"\n",
    )
    .unwrap();
    std::fs::write(
        f.join("log-profile.toml"),
        "description = \"the robot log, times in ms\"\ndelimiter = \",\"\n\n[columns]\n\
         id = \"pose\"\ntime_ms = \"t\"\n",
    )
    .unwrap();
}

/// The measured plan as a tracker streams it (a `time_s` column, one point every 5 s, the
/// plan's ids dropped) and the robot's log of when it stood at each pose (`pose, t` in ms,
/// read through `log-profile.toml`).
fn timed_export_and_log(f: &Path) {
    let measured = std::fs::read_to_string(f.join("measured.csv")).unwrap();
    let mut rows = measured.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    let keep: Vec<usize> = (0..header.len()).filter(|&i| header[i] != "id").collect();
    let pick = |fields: &[&str]| {
        keep.iter()
            .map(|&i| fields[i])
            .collect::<Vec<_>>()
            .join(",")
    };
    let mut export = format!("time_s,{}\n", pick(&header));
    let mut log = String::from("pose,t\n");
    let mut late = log.clone();
    for (i, row) in rows.enumerate() {
        let fields: Vec<&str> = row.split(',').collect();
        export += &format!("{},{}\n", 100.0 + 5.0 * i as f64, pick(&fields));
        log += &format!("{},{}\n", fields[0], 100_000.0 + 5000.0 * i as f64 + 200.0);
        late += &format!("{},{}\n", fields[0], 100_000.0 + 5000.0 * i as f64 + 5200.0);
    }
    std::fs::write(f.join("measured-timed.csv"), export).unwrap();
    std::fs::write(f.join("log.csv"), log).unwrap();
    std::fs::write(f.join("log-late.csv"), late).unwrap();
}

/// One command's base runs and the table of its options.
struct Matrix {
    command: &'static str,
    bases: &'static [&'static [&'static str]],
    options: &'static [(&'static str, Variation)],
}

/// Replaces `{F}` and `{R}` in an argument.
fn expand(arg: &str) -> String {
    arg.replace("{F}", fixture().to_str().unwrap())
        .replace("{R}", ROBOT)
}

/// The base run with `option` added (its value replacing the base's when the base has it);
/// `None` when the base has the flag already, or the option is not varied on this base.
fn with_option(base: &[&str], option: &str, variation: Variation) -> Option<Vec<String>> {
    let mut args: Vec<String> = base.iter().map(|a| expand(a)).collect();
    let at = args.iter().position(|a| a == option);
    let value = |values: &str| {
        let current = at.map(|i| args[i + 1].clone());
        let mut choices = values.split('|').map(expand);
        let first = choices.clone().next().unwrap();
        choices
            .find(|v| Some(v) != current.as_ref())
            .unwrap_or(first)
    };
    match (variation, at) {
        (Flag, Some(_)) | (Exempt(_) | PerBase(..), _) => return None,
        (Flag, None) => args.push(option.into()),
        (Value(v), Some(i)) => args[i + 1] = value(v),
        (Value(v), None) => args.extend([option.into(), value(v)]),
    }
    Some(args)
}

/// The variation of an option on the base run numbered `base`.
fn on_base(variation: Variation, base: usize) -> Variation {
    match variation {
        PerBase(values, why) => values.get(base).copied().flatten().unwrap_or(Exempt(why)),
        other => other,
    }
}

/// What a run wrote, without what records the run rather than its result: standard output,
/// and every file in its folder (JSON without the command line, the time, the software and the
/// echo of the settings; text with durations and timestamps masked; HTML and images by name).
#[derive(Debug, PartialEq)]
struct Written {
    stdout: String,
    files: BTreeMap<String, String>,
}

fn run(dir: &Path, command: &str, args: &[String]) -> Output {
    let all: Vec<&str> = (command.split(' '))
        .chain(args.iter().map(String::as_str))
        .collect();
    common::calib_in(dir, &all)
}

fn written(dir: &Path, out: &Output) -> Written {
    let mask = |text: &str| mask_run(&text.replace(dir.to_str().unwrap(), "<run>"));
    let mut files = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            let name = path
                .strip_prefix(dir)
                .unwrap()
                .to_string_lossy()
                .into_owned();
            let bytes = std::fs::read(&path).unwrap();
            let content = if name.ends_with(".html") || name.ends_with(".png") {
                String::new()
            } else if name.ends_with(".json") {
                let mut value: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
                strip_provenance(&mut value);
                mask(&value.to_string())
            } else {
                mask(&String::from_utf8_lossy(&bytes))
            };
            files.insert(name, content);
        }
    }
    Written {
        stdout: mask(&String::from_utf8_lossy(&out.stdout)),
        files,
    }
}

/// Removes the keys that record the run (command line, time, software, settings echo).
fn strip_provenance(value: &mut serde_json::Value) {
    match value {
        serde_json::Value::Object(map) => {
            for key in [
                "command_line",
                "seconds",
                "calibrated_at",
                "software",
                "settings",
                "inputs",
            ] {
                map.remove(key);
            }
            map.values_mut().for_each(strip_provenance);
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(strip_provenance),
        _ => {}
    }
}

/// Masks durations (`0.012 s`) and ISO 8601 times, which differ between identical runs.
fn mask_run(text: &str) -> String {
    let words: Vec<&str> = text.split(' ').collect();
    let mut out = Vec::with_capacity(words.len());
    for (i, word) in words.iter().enumerate() {
        let next = words.get(i + 1).copied().unwrap_or("");
        let duration =
            word.parse::<f64>().is_ok() && next.trim_end_matches([',', ')', '\n']) == "s";
        let bare = word
            .trim_matches(|c: char| !c.is_ascii_alphanumeric())
            .as_bytes();
        let time = bare.len() >= 20 && bare[4] == b'-' && bare[7] == b'-' && bare[10] == b'T';
        out.push(if duration || time { "<t>" } else { word });
    }
    out.join(" ")
}

/// Runs every option of `matrix` against every base run; returns the defects found.
fn check(matrix: &Matrix) -> Vec<String> {
    let mut defects = Vec::new();
    let listed = help_options(matrix.command);
    let table: Vec<&str> = matrix.options.iter().map(|(o, _)| *o).collect();
    for option in &listed {
        if !table.contains(&option.as_str()) {
            defects.push(format!("{}: {option} is not in the table", matrix.command));
        }
    }
    for option in &table {
        if !listed.iter().any(|l| l == option) {
            defects.push(format!("{}: {option} is not an option", matrix.command));
        }
    }
    let mut tried: BTreeMap<&str, usize> = BTreeMap::new();
    for (number, base) in matrix.bases.iter().enumerate() {
        let dir = tempfile::tempdir().unwrap();
        let base_args: Vec<String> = base.iter().map(|a| expand(a)).collect();
        let out = run(dir.path(), matrix.command, &base_args);
        assert!(
            out.status.success(),
            "{} {base:?} must run:\n{}",
            matrix.command,
            String::from_utf8_lossy(&out.stderr)
        );
        let reference = written(dir.path(), &out);
        for &(option, variation) in matrix.options {
            let variation = on_base(variation, number);
            let Some(args) = with_option(base, option, variation) else {
                continue;
            };
            *tried.entry(option).or_default() += 1;
            if let Some(defect) =
                verdict(matrix.command, base, option, variation, &args, &reference)
            {
                defects.push(defect);
            }
        }
    }
    println!(
        "{}: {} options, {} varied in {} runs over {} base runs",
        matrix.command,
        listed.len(),
        tried.len(),
        tried.values().sum::<usize>(),
        matrix.bases.len()
    );
    for &(option, variation) in matrix.options {
        if !matches!(variation, Exempt(_) | PerBase(..)) && !tried.contains_key(option) {
            defects.push(format!(
                "{}: {option} is in every base run: add a base without it",
                matrix.command
            ));
        }
    }
    defects
}

/// `None` when the run with the option refused naming it and wrote nothing, or wrote something
/// else than the base run; else the defect.
fn verdict(
    command: &str,
    base: &[&str],
    option: &str,
    variation: Variation,
    args: &[String],
    reference: &Written,
) -> Option<String> {
    let dir = tempfile::tempdir().unwrap();
    let out = run(dir.path(), command, args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        // The option, its value, or an input its effect made fail.
        let value = args.iter().skip_while(|a| *a != option).nth(1);
        let input = args
            .iter()
            .any(|a| a.starts_with(fixture().to_str().unwrap()) && stderr.contains(a.as_str()));
        let named =
            stderr.contains(option) || value.is_some_and(|v| stderr.contains(v.as_str())) || input;
        let nothing = std::fs::read_dir(dir.path()).unwrap().next().is_none();
        return (!named || !nothing).then(|| {
            format!(
                "{command} {base:?} + {option}: refused without naming it or wrote something \
                 ({} written): {stderr}",
                !nothing
            )
        });
    }
    let now = written(dir.path(), &out);
    if std::env::var_os("OPTION_MATRIX_DEBUG").is_some() && now != *reference {
        for (name, text) in &now.files {
            if reference.files.get(name) != Some(text) {
                let old = reference.files.get(name).cloned().unwrap_or_default();
                let line = text.lines().zip(old.lines()).find(|(a, b)| a != b);
                eprintln!("DEBUG {command} {option}: {name} differs: {line:?}");
            }
        }
        if now.stdout != reference.stdout {
            eprintln!(
                "DEBUG {command} {option}: stdout differs:\n{}\n---\n{}",
                now.stdout, reference.stdout
            );
        }
    }
    (now == *reference).then(|| {
        format!("{command} {base:?} + {option} {variation:?}: taken and ignored (the same output)")
    })
}

impl std::fmt::Debug for Variation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Flag => Ok(()),
            Value(v) => write!(f, "{v}"),
            PerBase(values, _) => write!(f, "{values:?}"),
            Exempt(why) => write!(f, "(exempt: {why})"),
        }
    }
}

/// The long options `calib COMMAND --help` lists (without `--help`).
fn help_options(command: &str) -> Vec<String> {
    let mut words: Vec<&str> = command.split(' ').collect();
    words.push("--help");
    let out = common::calib(&words);
    let text = common::ok(&out);
    text.lines()
        .filter_map(|line| {
            let line = line.trim_start();
            let long = line.strip_prefix("-h, ").unwrap_or(line);
            long.starts_with("--")
                .then(|| long.split([' ', '=', '\t']).next().unwrap().to_string())
        })
        .filter(|o| o != "--help")
        .collect()
}

fn assert_no_defects(matrices: &[Matrix]) {
    let defects: Vec<String> = matrices.iter().flat_map(check).collect();
    assert!(defects.is_empty(), "{}", defects.join("\n"));
}

/// Options of the swarm (`--method ipso` and `ipso+lm`), and what varies them.
macro_rules! swarm_options {
    () => {
        [
            ("--swarm", Value("9")),
            ("--generations", Value("25")),
            ("--c1", Value("2.2")),
            ("--c2", Value("2.2")),
            ("--seed", Value("7")),
            ("--init-angle-rad", Value("0.02")),
            ("--init-length-mm", Value("1")),
            ("--bound-factor", Value("2")),
            ("--stall-generations", Value("3")),
            ("--target", Value("1e3")),
            ("--halton-start", Value("11")),
            ("--scrambling", Value("reverse")),
        ]
    };
}

#[test]
fn calibrate() {
    const SWARM: [(&str, Variation); 12] = swarm_options!();
    const OTHER: &[(&str, Variation)] = &[
        ("--robot", REQUIRED),
        ("--data", REQUIRED),
        ("--profile", Value("{F}/profile.toml")),
        ("--frames", Value("base")),
        ("--identify", Value("frames")),
        ("--model", Value("joint-maps")),
        (
            "--harmonics",
            Exempt(
                "refused without --model joint-maps; the maps it gives are tested in joint_maps.rs",
            ),
        ),
        ("--method", Value("ipso+lm|lm")),
        ("--lm-iterations", Value("2")),
        ("--loss", Value("cauchy")),
        ("--loss-scale-mm", Value("0.01")),
        (
            "--auto-mask",
            Exempt(
                "acts only on parameters the data leave undetermined (least_squares.rs, real_data.rs)",
            ),
        ),
        (
            "--keep-ill-conditioned",
            Exempt("acts only on an ill-conditioned pose set (real_data.rs)"),
        ),
        (
            "--accept-implausible",
            Exempt("a permission: a plausible result is written without it"),
        ),
        ("--accept", Value("95% <= 0.001 mm")),
        ("--payload-kg", Value("2.5")),
        ("--validate", Value("0.25")),
        ("--validate-seed", Value("3")),
        ("--holdout", Value("{F}/pose2.csv")),
        ("--k", Value("1e4")),
        ("--truth", Value("{F}/truth.toml")),
        ("--out", Value("other.toml")),
        ("--report", Value("other.json")),
        ("--html", Value("other.html")),
        ("--plot", Value("plots")),
        ("--quiet", Exempt("progress bars, shown on a terminal only")),
        (
            "--registry",
            Exempt(
                "adds a record to the named registry; the files written are unchanged (registry.rs: calibrate_registers_its_calibration)",
            ),
        ),
        INPUT_LIMIT,
    ];
    let options: Vec<_> = OTHER.iter().copied().chain(SWARM).collect();
    let options: &'static [(&str, Variation)] = options.leak();
    assert_no_defects(&[Matrix {
        command: "calibrate",
        bases: &[
            &[
                "--robot",
                "{R}",
                "--data",
                "{F}/pose.csv",
                "--method",
                "lm",
                "--out",
                "x.toml",
                "--report",
                "x.json",
                "--quiet",
            ],
            &[
                "--robot",
                "{R}",
                "--data",
                "{F}/pose.csv",
                "--method",
                "ipso",
                "--swarm",
                "8",
                "--generations",
                "30",
                "--accept-implausible",
                "--out",
                "x.toml",
                "--report",
                "x.json",
                "--quiet",
            ],
            &[
                "--robot",
                "{R}",
                "--data",
                "{F}/pos.csv",
                "--frames",
                "base+tool",
                "--method",
                "ipso+lm",
                "--swarm",
                "8",
                "--generations",
                "20",
                "--loss",
                "huber",
                "--out",
                "x.toml",
                "--report",
                "x.json",
                "--quiet",
            ],
        ],
        options,
    }]);
}

#[test]
fn simulate() {
    assert_no_defects(&[Matrix {
        command: "simulate",
        bases: &[
            &[
                "--robot",
                "{R}",
                "--poses",
                "20",
                "--seed",
                "1",
                "--out",
                "d.csv",
                "--truth-out",
                "t.toml",
            ],
            &[
                "--robot",
                "{R}",
                "--errors",
                "random",
                "--seed",
                "1",
                "--joints-from",
                "{F}/targets.csv",
                "--position-only",
                "--position-sigma-mm",
                "0.01",
                "--out",
                "d.csv",
                "--truth-out",
                "t.toml",
            ],
        ],
        options: &[
            (
                "--robot",
                Value(concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml")),
            ),
            ("--errors", Value("random|table2")),
            ("--random-length-mm", Value("0.2")),
            ("--random-angle-rad", Value("0.004")),
            ("--poses", Value("25")),
            ("--joints-from", Value("{F}/targets.csv|{F}/pose.csv")),
            ("--within-limits", Flag),
            ("--joint-noise-rad", Value("0.001")),
            ("--position-sigma-mm", Value("0.05")),
            ("--orientation-sigma-rad", Value("1e-4")),
            ("--position-only", Flag),
            ("--tracker-xyz-mm", Value("1000,0,0")),
            ("--tracker-rpy-deg", Value("0,0,30")),
            ("--tool-xyz-mm", Value("0,0,50")),
            ("--seed", Value("9")),
            ("--out", Value("e.csv")),
            ("--truth-out", Value("u.toml")),
            INPUT_LIMIT,
        ],
    }]);
}

#[test]
fn plan() {
    assert_no_defects(&[Matrix {
        command: "plan",
        bases: &[
            &[
                "--robot",
                "{R}",
                "--generate",
                "300",
                "--poses",
                "30",
                "--measure",
                "position",
                "--noise-mm",
                "0.02",
                "--out",
                "p.csv",
                "--report",
                "p.json",
            ],
            &[
                "--robot",
                "{R}",
                "--candidates",
                "{F}/targets.csv",
                "--poses",
                "20",
                "--verify",
                "5",
                "--measure",
                "pose",
                "--noise-mm",
                "0.02",
                "--noise-deg",
                "0.002",
                "--out",
                "p.csv",
                "--urscript",
                "p.script",
            ],
        ],
        options: &[
            ("--robot", REQUIRED),
            ("--candidates", Value("{F}/plan.csv")),
            (
                "--profile",
                PerBase(
                    &[Some(Value("{F}/profile.toml")), None],
                    "reads the candidates the same (the reading through profiles: inputs.rs)",
                ),
            ),
            ("--generate", Value("200")),
            ("--box-mm", Value("0,1500,-1500,1500,0,1500")),
            ("--poses", Value("25")),
            ("--core", Value("14")),
            ("--verify", Value("8")),
            ("--min-distance-deg", Value("10")),
            ("--measure", Value("pose|position")),
            ("--model", Value("joint-maps")),
            ("--noise-mm", Value("0.05")),
            ("--noise-deg", Value("0.01")),
            ("--noise-from", Value("{F}/pos.json")),
            ("--k", Value("1e4")),
            ("--seed", Value("3")),
            ("--out", Value("q.csv")),
            ("--report", Value("q.json")),
            ("--urscript", Value("q.script")),
            ("--joint-targets", Value("q-joints.csv")),
            ("--below-base", Flag),
            ("--settle-s", Value("1")),
            ("--speed-rad-s", Value("0.25")),
            ("--acceleration-rad-s2", Value("0.25")),
            INPUT_LIMIT,
        ],
    }]);
}

#[test]
fn check_evaluate_and_verify() {
    let data_options =
        |extra: &'static [(&'static str, Variation)]| -> &'static [(&'static str, Variation)] {
            let mut all = vec![
                ("--robot", REQUIRED),
                ("--data", REQUIRED),
                (
                    "--profile",
                    Exempt("reads our CSV the same (the reading through profiles: inputs.rs)"),
                ),
                ("--json", Flag),
                INPUT_LIMIT,
            ];
            all.extend_from_slice(extra);
            all.leak()
        };
    assert_no_defects(&[
        Matrix {
            command: "check",
            bases: &[
                &["--robot", "{R}", "--data", "{F}/pose.csv"],
                &[
                    "--robot",
                    "{R}",
                    "--data",
                    "{F}/pos.csv",
                    "--frames",
                    "base+tool",
                ],
            ],
            options: data_options(&[("--frames", Value("base")), ("--k", Value("1e4"))]),
        },
        Matrix {
            command: "evaluate",
            bases: &[
                &["--robot", "{F}/params.toml", "--data", "{F}/pose.csv"],
                &[
                    "--robot",
                    "{F}/params-pos.toml",
                    "--data",
                    "{F}/pos.csv",
                    "--stored-registration",
                ],
                &[
                    "--robot",
                    "{R}",
                    "--data",
                    "{F}/pos.csv",
                    "--fit-frames",
                    "base+tool",
                ],
            ],
            options: data_options(&[
                ("--fit-frames", Value("base")),
                ("--fit-poses", Value("10")),
                ("--seed", Value("4")),
                ("--stored-registration", Flag),
            ]),
        },
        Matrix {
            command: "verify",
            bases: &[
                &["--robot", "{R}", "--data", "{F}/pose.csv"],
                &[
                    "--robot",
                    "{R}",
                    "--data",
                    "{F}/pos.csv",
                    "--frames",
                    "base+tool",
                ],
            ],
            options: data_options(&[
                ("--frames", Value("base")),
                ("--validate", Value("0.25")),
                ("--validate-seed", Value("3")),
                ("--k", Value("1e4")),
            ]),
        },
    ]);
}

#[test]
fn compensate() {
    assert_no_defects(&[Matrix {
        command: "compensate",
        bases: &[
            &[
                "--robot",
                "{R}",
                "--params",
                "{F}/params.toml",
                "--joint-targets",
                "--targets",
                "{F}/targets.csv",
                "--out",
                "c.csv",
            ],
            &[
                "--robot",
                "{R}",
                "--params",
                "{F}/params.toml",
                "--targets",
                "{F}/pose.csv",
                "--out",
                "c.csv",
            ],
            &[
                "--robot",
                "{R}",
                "--params",
                "{F}/params.toml",
                "--targets",
                "{F}/poses.csv",
                "--branch",
                "0",
                "--out",
                "c.csv",
            ],
        ],
        options: &[
            ("--robot", REQUIRED),
            ("--params", REQUIRED),
            ("--targets", REQUIRED),
            ("--targets-frame", Value("ur-base")),
            ("--joint-targets", Flag),
            ("--out", Value("d.csv")),
            ("--urscript", Value("d.script")),
            ("--speed-rad-s", Value("0.25")),
            ("--acceleration-rad-s2", Value("0.25")),
            ("--max-correction-mm", Value("0.001")),
            ("--max-correction-deg", Value("0.00001")),
            ("--max-joint-correction-deg", Value("0.00001")),
            ("--near-deg", Value("0,-30,-120,0,60,0")),
            ("--branch", Value("3")),
            (
                "--allow-extrapolation",
                Exempt("a permission: targets inside the calibrated range need none"),
            ),
            ("--max-arm-angle-deg", Value("5")),
            ("--near-within-deg", Value("30")),
            INPUT_LIMIT,
        ],
    }]);
}

#[test]
fn export() {
    assert_no_defects(&[Matrix {
        command: "export",
        bases: &[
            &[
                "--params",
                "{F}/params.toml",
                "--format",
                "urdf",
                "--out",
                "r.urdf",
            ],
            &[
                "--params",
                "{F}/params.toml",
                "--format",
                "block",
                "--out",
                "p.bin",
            ],
            &[
                "--params",
                "{F}/params.toml",
                "--format",
                "toml",
                "--out",
                "r.toml",
            ],
        ],
        options: &[
            ("--params", REQUIRED),
            ("--format", Value("ur-kinematics-yaml")),
            ("--out", Value("other")),
            ("--scalar", Value("f64")),
            ("--sequence", Value("5")),
            ("--link-names", Value("a,b,c,d,e,f,g")),
            ("--joint-names", Value("j1,j2,j3,j4,j5,j6")),
            ("--base-link", Value("root")),
            ("--flange-link", Value("flange0")),
            ("--tool-link", Value("tcp0")),
            ("--joints-only", Flag),
            (
                "--geometry-only",
                PerBase(
                    &[None, Some(Flag), Some(Flag)],
                    "a permission: a model without joint maps exports whole without it",
                ),
            ),
            INPUT_LIMIT,
        ],
    }]);
}

#[test]
fn merge() {
    assert_no_defects(&[Matrix {
        command: "merge",
        bases: &[
            &[
                "--plan",
                "{F}/plan.csv",
                "--measured",
                "{F}/measured.csv",
                "--by",
                "id",
                "--out",
                "m.csv",
            ],
            &[
                "--plan",
                "{F}/plan.csv",
                "--measured",
                "{F}/measured.csv",
                "--by",
                "order",
                "--out",
                "m.csv",
            ],
            &[
                "--plan",
                "{F}/plan.csv",
                "--measured",
                "{F}/measured-timed.csv",
                "--by",
                "time",
                "--robot-log",
                "{F}/log.csv",
                "--log-profile",
                "{F}/log-profile.toml",
                "--out",
                "m.csv",
            ],
        ],
        options: &[
            ("--plan", REQUIRED),
            ("--measured", REQUIRED),
            (
                "--profile",
                Exempt("reads our CSV the same (the reading through profiles: inputs.rs)"),
            ),
            ("--by", Value("order|id")),
            ("--robot-log", Value("{F}/log.csv|{F}/log-late.csv")),
            (
                "--log-profile",
                Value("{F}/log-profile.toml|{F}/log-profile-s.toml"),
            ),
            ("--time-tolerance-s", Value("0.1")),
            (
                "--tolerance-deg",
                Exempt("a bound: the export's joints are the plan's, within any bound"),
            ),
            ("--out", Value("n.csv")),
            INPUT_LIMIT,
        ],
    }]);
}

#[test]
fn the_small_commands() {
    assert_no_defects(&[
        Matrix {
            command: "fk",
            bases: &[&["--robot", "{R}", "--joints-deg", "0,-30,-120,0,60,0"]],
            options: &[
                ("--robot", REQUIRED),
                ("--joints-deg", Value("0,-30,-120,0,60,10")),
                ("--json", Flag),
                INPUT_LIMIT,
            ],
        },
        Matrix {
            command: "report",
            bases: &[&["--from", "{F}/pos.json", "--html", "r.html"]],
            options: &[
                ("--from", REQUIRED),
                ("--html", Value("s.html")),
                ("--pdf", Exempt("needs Chromium: html_report.rs tests it")),
                (
                    "--job",
                    Exempt(
                        "adds the job and signature lines to the page, which this matrix compares by name only (certificate.rs)",
                    ),
                ),
                (
                    "--pose-test",
                    Exempt(
                        "adds a section to the page, which this matrix compares by name only (pose_test.rs: the_certificate_shows_the_pose_test)",
                    ),
                ),
                INPUT_LIMIT,
            ],
        },
        Matrix {
            command: "import-ur-calibration",
            bases: &[&[
                "--robot",
                concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml"),
                "--calibration",
                concat!(
                    env!("CARGO_MANIFEST_DIR"),
                    "/data/ur-factory-calibration/ur10-test-set-1.conf"
                ),
                "--out",
                "u.toml",
            ]],
            options: &[
                ("--robot", REQUIRED),
                ("--calibration", REQUIRED),
                ("--out", Value("v.toml")),
                (
                    "--accept-implausible",
                    Exempt("a permission: a plausible import is written without it"),
                ),
                INPUT_LIMIT,
            ],
        },
        Matrix {
            command: "uncertainty",
            bases: &[&[
                "--params",
                "{F}/params.toml",
                "--joints",
                "{F}/targets.csv",
                "--out",
                "u.csv",
            ]],
            options: &[
                ("--params", REQUIRED),
                ("--joints", REQUIRED),
                ("--profile", Value("{F}/profile.toml")),
                ("--out", Value("v.csv")),
                INPUT_LIMIT,
            ],
        },
        Matrix {
            command: "demo",
            bases: &[],
            options: &[
                (
                    "--out",
                    Exempt("the output folder: cli_demo_verify.rs runs the demo"),
                ),
                ("--quiet", Exempt("progress bars, shown on a terminal only")),
                INPUT_LIMIT,
            ],
        },
    ]);
}

#[test]
fn the_iso9283_pose_test() {
    assert_no_defects(&[
        Matrix {
            command: "iso9283 plan",
            bases: &[&[
                "--robot",
                "{R}",
                "--centre-mm",
                "1200,0,800",
                "--edge-mm",
                "400",
                "--near-deg",
                "0,-30,30,0,60,0",
                "--cycles",
                "3",
                "--targets",
                "t.csv",
                "--out",
                "run.csv",
                "--urscript",
                "p.script",
            ]],
            options: &[
                ("--robot", REQUIRED),
                ("--centre-mm", Value("1200,0,700")),
                ("--edge-mm", Value("300")),
                ("--rpy-deg", Value("180,-20,0")),
                ("--near-deg", Value("0,-20,30,0,60,0")),
                ("--branch", Value("0")),
                ("--cycles", Value("4")),
                ("--targets", Value("t2.csv")),
                ("--out", Value("run2.csv")),
                ("--joint-targets", Value("jt.csv")),
                ("--urscript", Value("q.script")),
                ("--settle-s", Value("1")),
                ("--speed-rad-s", Value("0.25")),
                ("--acceleration-rad-s2", Value("0.25")),
                INPUT_LIMIT,
            ],
        },
        Matrix {
            command: "iso9283 evaluate",
            bases: &[
                &[
                    "--targets",
                    "{F}/iso/targets.csv",
                    "--data",
                    "{F}/iso/run.csv",
                    "--robot",
                    "{R}",
                    "--report",
                    "t.json",
                ],
                &[
                    "--targets",
                    "{F}/iso/targets.csv",
                    "--data",
                    "{F}/iso/run.csv",
                    "--robot",
                    "{R}",
                    "--registry",
                    "r.db",
                    "--serial",
                    "ER-1",
                ],
            ],
            options: &[
                ("--targets", REQUIRED),
                ("--data", REQUIRED),
                ("--robot", REQUIRED),
                ("--profile", Value("{F}/profile.toml")),
                ("--report", Value("u.json")),
                ("--json", Flag),
                (
                    "--registry",
                    PerBase(
                        &[None, Some(Value("s.db"))],
                        "records under a serial, which the first base's robot file does not state",
                    ),
                ),
                (
                    "--serial",
                    PerBase(&[None, Some(Value("ER-2"))], "needs --registry"),
                ),
                (
                    "--tested-at",
                    PerBase(
                        &[None, Some(Value("2026-01-01T00:00:00Z"))],
                        "needs --registry",
                    ),
                ),
                INPUT_LIMIT,
            ],
        },
    ]);
}
