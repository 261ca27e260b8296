//! The self-contained HTML report (issue 16): structure checked with an HTML parser, every
//! number it shows against the JSON report, no external reference; rendered in headless
//! Chromium where it is installed (required with `CALIB_REQUIRE_CHROMIUM=1`, as `.ci/run` sets).

use crate::common;

use common::{FULL_POSE, POSITION, SERIES_B, UR10, calib_in, ok};
use scraper::{Html, Selector};
use std::path::Path;

fn select(page: &Html, css: &str) -> Vec<String> {
    page.select(&Selector::parse(css).unwrap())
        .map(|e| e.text().collect::<String>())
        .collect()
}

/// Issue 53 (item 3): the page is rendered from the typed report, and the typed report reads
/// back what `calib calibrate --report` wrote: written again, the same bytes (every field, every
/// number to the last bit).
fn reads_back_as_written(path: &Path) {
    let written = std::fs::read_to_string(path).unwrap();
    let report: host_tools::calibration::Report = serde_json::from_str(&written).unwrap();
    let again = serde_json::to_string_pretty(&report).unwrap();
    let differ = (again.lines().zip(written.lines()).enumerate()).find(|(_, (a, w))| a != w);
    assert_eq!(differ, None, "{}", path.display());
    assert_eq!(again, written, "{}", path.display());
}

/// The README's real-data example (50 random poses of Series B, 6-DoF, the others held out)
/// with `--html`: every section, the paper's Table 3 for calibration and held-out poses with the
/// JSON report's numbers, every identified parameter, the five plots inline, no script and no
/// reference outside the file; `calib report --from` the JSON renders the same page.
#[test]
fn the_html_report_holds_everything_and_nothing_external() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(&calib_in(
        d,
        &[
            "calibrate",
            "--robot",
            UR10,
            "--data",
            SERIES_B,
            "--profile",
            FULL_POSE,
            "--validate",
            "0.9666",
            "--report",
            "r.json",
            "--html",
            "r.html",
        ],
    ));
    let html = std::fs::read_to_string(d.join("r.html")).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("r.json")).unwrap()).unwrap();
    reads_back_as_written(&d.join("r.json"));
    let page = Html::parse_document(&html);
    assert!(page.errors.is_empty(), "{:?}", page.errors);
    let sections: Vec<String> = page
        .select(&Selector::parse("h2[id]").unwrap())
        .map(|e| e.value().attr("id").unwrap().to_string())
        .collect();
    assert_eq!(sections, host_tools::report::html::SECTIONS);
    // Table 3: calibration and validation, nominal and identified, position and 3 axes.
    let cells = select(&page, "td");
    for stage in ["calibration", "validation"] {
        for model in ["before", "after"] {
            let mean = json[stage][model]["position_mm"]["mean"].as_f64().unwrap();
            let shown = format!("{mean:.4}");
            assert!(cells.contains(&shown), "{stage} {model}: {shown}");
        }
    }
    assert_eq!(
        select(&page, "h3").len(),
        2,
        "calibration and validation tables"
    );
    // Issue 41: the held-out accuracy (percentiles, per axis, the largest poses by line) with the
    // JSON report's numbers.
    let held = &json["held_out"];
    for model in ["before", "after"] {
        for key in ["p50_mm", "p95_mm", "p99_mm", "max_mm"] {
            let v = held[model]["position"][key].as_f64().unwrap();
            assert!(cells.contains(&format!("{v:.4}")), "{model} {key}");
        }
        let x = &held[model]["axes"][0];
        let shown = format!(
            "{:.4} \u{b1} {:.4}",
            x["mean_mm"].as_f64().unwrap(),
            x["std_mm"].as_f64().unwrap()
        );
        assert!(cells.contains(&shown), "{model} x: {shown}");
    }
    let largest = &held["largest"][0];
    assert!(cells.contains(&largest["line"].to_string()));
    assert!(cells.contains(&format!("{:.4}", largest["error_mm"].as_f64().unwrap())));
    assert!(
        select(&page, "caption")
            .iter()
            .any(|c| c.starts_with("Flagged held-out poses"))
    );
    // The measurement conditions: the payload of the robot file's [dynamics] tool, the air
    // temperature range of the data's temperature column, what is not stated said so.
    let t = &json["conditions"]["temperature"];
    assert!(cells.contains(&format!(
        "{:.2} to {:.2}\u{a0}\u{b0}C over 1495 poses",
        t["min_c"].as_f64().unwrap(),
        t["max_c"].as_f64().unwrap()
    )));
    // Issue 52: a figure only assumed (the bundled file's) is stated as assumed.
    assert!(cells.contains(
        &"assumed 1.500\u{a0}kg (the robot file's [dynamics] tool, not given for this measurement: --payload-kg states it)"
            .to_string()
    ));
    assert!(
        cells
            .iter()
            .any(|c| c.starts_with("not stated (") && c.contains("[instrument]"))
    );
    // The caveats (here the held-out poses beyond the calibration poses' joint ranges) and the
    // worst regions of the workspace, with the JSON report's numbers.
    let caveat = select(&page, "ul.caveats li");
    assert_eq!(caveat.len(), json["caveats"].as_array().unwrap().len());
    assert!(
        caveat[0].contains("held-out poses have a joint outside the range"),
        "{caveat:?}"
    );
    let worst = &held["workspace"]["worst"][0];
    assert!(cells.contains(&format!("{:.4}", worst["mean_mm"].as_f64().unwrap())));
    assert!(cells.contains(&format!(
        "{:.4}",
        worst["predicted_rms_mm"].as_f64().unwrap()
    )));
    // No plan: the plan check is not made; the cross-validation, better than nominal, is stated.
    let paragraphs = select(&page, "p");
    assert!(
        paragraphs
            .iter()
            .any(|p| p.starts_with("Plan check: not made"))
    );
    let cv = &json["cross_validation"];
    assert!(paragraphs.iter().any(|p| p.contains(&format!(
        "{:.4}\u{a0}mm mean error predicted by the calibration, {:.4}\u{a0}mm by the nominal model: better than nominal",
        cv["calibrated_mean_mm"].as_f64().unwrap(),
        cv["nominal_mean_mm"].as_f64().unwrap()
    ))), "{paragraphs:?}");
    // The frames the data chose are shown as identified (not "-").
    assert!(cells.contains(&"base+tool (chosen from the data)".to_string()));
    // Every parameter, with its value in the unit shown.
    let parameters = json["parameters"].as_object().unwrap();
    assert!(parameters.len() > 20);
    for (name, p) in parameters {
        assert!(cells.contains(name), "{name}");
        let v = p["value"].as_f64().unwrap();
        let shown = if p["unit"] == "rad" {
            format!("{:.5}", v.to_degrees())
        } else {
            format!("{v:.4}")
        };
        assert!(cells.contains(&shown), "{name}: {shown}");
    }
    // Every calibration pose, its file line and errors.
    assert_eq!(
        page.select(&Selector::parse("table.poses tr").unwrap())
            .count(),
        51
    );
    // The plots, inline.
    let figures: Vec<String> = page
        .select(&Selector::parse("figure[id] > svg").unwrap())
        .map(|e| e.value().attr("width").unwrap_or("").to_string())
        .collect();
    assert_eq!(figures.len(), 5, "{figures:?}");
    for id in [
        "plot-position-error",
        "plot-orientation-error",
        "plot-convergence",
        "plot-validation-histogram",
        "plot-workspace-error",
    ] {
        assert_eq!(select(&page, &format!("figure#{id} svg")).len(), 1, "{id}");
    }
    // Nothing outside the file: no script, stylesheet link, image or frame, no URL attribute.
    for css in ["script", "link", "img", "iframe", "object", "embed"] {
        assert!(select(&page, css).is_empty(), "{css}");
    }
    for element in page
        .root_element()
        .descendants()
        .filter_map(|n| n.value().as_element())
    {
        // (`xmlns` names the SVG namespace; nothing is fetched from it.)
        for (name, value) in element.attrs().filter(|(n, _)| !n.starts_with("xmlns")) {
            assert!(
                !matches!(name, "src" | "href" | "xlink:href") && !value.contains("://"),
                "{name}={value}"
            );
        }
    }
    assert!(html.contains("@media print"));
    assert!(html.contains(&format!("calib {}", env!("CARGO_PKG_VERSION"))));
    // Rendered again from the JSON: the same page but for the time of rendering; both state the
    // calibration's date, which the JSON keeps (issue 40: a re-rendered report showed the
    // render time as the date).
    let calibrated = json["calibrated_at"].as_str().unwrap();
    let when = humantime::parse_rfc3339(calibrated).unwrap();
    let age = std::time::SystemTime::now().duration_since(when).unwrap();
    assert!(age.as_secs() < 600, "{calibrated}");
    assert!(
        html.contains(&format!(
            "<td>calibrated</td><td colspan=\"3\">{calibrated}</td>"
        )),
        "{calibrated}"
    );
    std::thread::sleep(std::time::Duration::from_millis(1100));
    ok(&calib_in(
        d,
        &["report", "--from", "r.json", "--html", "again.html"],
    ));
    let undated =
        |text: &str| -> String { text.lines().filter(|l| !l.contains("rendered")).collect() };
    let again = std::fs::read_to_string(d.join("again.html")).unwrap();
    assert_eq!(undated(&again), undated(&html));
    // Issue 39 N7: convergence values a log axis cannot show (zero, negative, 1e-300, 1e300,
    // a huge generation) and per-pose errors of 1e308 and more: rendered, in bounded time.
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("r.json")).unwrap()).unwrap();
    json["convergence"] = serde_json::json!([
        [0, 0.0],
        [1, -5.0],
        [2, 1e-300],
        [3, 1e300],
        [4000000000u64, 1.0]
    ]);
    if let Some(before) = json["per_pose"]["before"].as_array_mut() {
        for (i, e) in before.iter_mut().enumerate() {
            *e = serde_json::json!(if i % 2 == 0 { 1e308 } else { -1.0 });
        }
    }
    std::fs::write(d.join("extreme.json"), json.to_string()).unwrap();
    let started = std::time::Instant::now();
    ok(&calib_in(
        d,
        &["report", "--from", "extreme.json", "--html", "extreme.html"],
    ));
    println!(
        "report of extreme values rendered in {:.2} s",
        started.elapsed().as_secs_f64()
    );
    assert!(d.join("extreme.html").exists());
    // Issue 41: the certificate as a PDF (headless Chromium): A4 pages; without a browser on the
    // PATH the PDF is refused and nothing (not even the HTML asked beside it) is written.
    pdf(d);
    // Not a report: said, nothing written.
    std::fs::write(d.join("other.json"), "{\"a\": 1}").unwrap();
    let out = calib_in(d, &["report", "--from", "other.json", "--html", "x.html"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("not a JSON report"), "{stderr}");
    assert!(!d.join("x.html").exists());
    // Parameters dropped (position-only data, --auto-mask): named, and why.
    ok(&calib_in(
        d,
        &[
            "calibrate",
            "--robot",
            UR10,
            "--data",
            SERIES_B,
            "--profile",
            POSITION,
            "--validate",
            "0.9666",
            "--auto-mask",
            "--method",
            "lm",
            "--report",
            "p.json",
            "--html",
            "p.html",
        ],
    ));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("p.json")).unwrap()).unwrap();
    reads_back_as_written(&d.join("p.json"));
    let dropped: Vec<&str> = json["dropped"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    let page = Html::parse_document(&std::fs::read_to_string(d.join("p.html")).unwrap());
    let shown = if dropped.is_empty() {
        "none".to_string()
    } else {
        dropped.join(", ")
    };
    assert!(select(&page, "td").contains(&shown), "{dropped:?}");
    assert_eq!(
        select(&page, "p")
            .iter()
            .any(|p| p.starts_with("Why dropped")),
        !dropped.is_empty()
    );
    // The T-Mac point is 1.1 mm from joint 6's axis: the page says what that leaves out.
    let left_out: Vec<&str> = json["identifiability"]["reflector_on_last_axis"]["not_identified"]
        .as_array()
        .unwrap()
        .iter()
        .map(|u| u["name"].as_str().unwrap())
        .collect();
    assert_eq!(left_out, ["dtheta5", "dalpha5"]);
    // The undetermined parameters by name and status (the page showed their JSON until issue 53).
    let undetermined: Vec<String> = json["identifiability"]["undetermined"]
        .as_array()
        .unwrap()
        .iter()
        .map(|u| {
            format!(
                "{} ({})",
                u["name"].as_str().unwrap(),
                u["status"].as_str().unwrap()
            )
        })
        .collect();
    let shown = if undetermined.is_empty() {
        "none".to_string()
    } else {
        undetermined.join(", ")
    };
    assert!(select(&page, "td").contains(&shown), "{shown}");
    assert!(
        select(&page, "p").iter().any(|p| p
            .starts_with("Reflector 1.1 mm from the last joint's axis")
            && p.contains(
                "Not identified (kept nominal): dtheta5 (acts like da5), dalpha5 (acts like dd5)."
            )),
        "{:?}",
        select(&page, "p")
    );
    // No orientation data: no orientation plot.
    assert!(select(&page, "figure#plot-orientation-error").is_empty());
    // In a real browser: headless Chromium renders it to a PNG with content.
    screenshot(&d.join("r.html"), &d.join("r.png"));
}

/// `calib report --pdf` of `dir/r.json`: a PDF of A4 pages (595 x 842 pt) where Chromium is
/// installed; refused, writing nothing, where none is on the PATH.
fn pdf(dir: &Path) {
    let calib = env!("CARGO_BIN_EXE_calib");
    let empty = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(calib)
        .current_dir(dir)
        .env("PATH", empty.path())
        .args([
            "report", "--from", "r.json", "--html", "n.html", "--pdf", "n.pdf",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("writing a PDF needs a headless Chromium"),
        "{stderr}"
    );
    assert!(!dir.join("n.html").exists() && !dir.join("n.pdf").exists());
    if host_tools::report::pdf::browser().is_none() {
        assert!(
            std::env::var("CALIB_REQUIRE_CHROMIUM").as_deref() != Ok("1"),
            "CALIB_REQUIRE_CHROMIUM=1 but no chromium found"
        );
        eprintln!("skipped: no chromium to print the PDF (apt-get install chromium)");
        return;
    }
    ok(&calib_in(
        dir,
        &["report", "--from", "r.json", "--pdf", "r.pdf"],
    ));
    let bytes = std::fs::read(dir.join("r.pdf")).unwrap();
    assert!(bytes.starts_with(b"%PDF-"));
    let text = String::from_utf8_lossy(&bytes);
    let boxes: Vec<&str> = text
        .match_indices("/MediaBox [")
        .map(|(i, _)| &text[i + 11..])
        .collect();
    println!("PDF: {} bytes, {} pages", bytes.len(), boxes.len());
    assert!(boxes.len() >= 2, "{} pages", boxes.len());
    for b in boxes {
        let numbers: Vec<f64> = b
            .split(']')
            .next()
            .unwrap()
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect();
        assert!(
            (numbers[2] - 595.3).abs() < 2.0 && (numbers[3] - 841.9).abs() < 2.0,
            "{numbers:?}"
        );
    }
}

/// Renders `page` with headless Chromium into `png` and checks the picture: its size and that
/// it is not blank. Skips (with a message) where Chromium is missing, unless
/// `CALIB_REQUIRE_CHROMIUM=1`.
fn screenshot(page: &Path, png: &Path) {
    let chromium = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|c| {
            std::process::Command::new(c)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        });
    let Some(chromium) = chromium else {
        assert!(
            std::env::var("CALIB_REQUIRE_CHROMIUM").as_deref() != Ok("1"),
            "CALIB_REQUIRE_CHROMIUM=1 but no chromium found"
        );
        eprintln!("skipped: no chromium to render the HTML report (apt-get install chromium)");
        return;
    };
    let profile = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
            "--window-size=1000,2400",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg(format!("--screenshot={}", png.display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .unwrap();
    assert!(
        png.exists(),
        "chromium wrote no screenshot: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let decoder = png::Decoder::new(std::fs::File::open(png).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut pixels).unwrap();
    assert_eq!((info.width, info.height), (1000, 2400));
    let bytes = &pixels[..info.buffer_size()];
    let white = bytes.iter().filter(|b| **b == 255).count();
    let dark = bytes.iter().filter(|b| **b < 100).count();
    println!(
        "screenshot {}x{}: {:.1} % white bytes, {:.2} % dark",
        info.width,
        info.height,
        100.0 * white as f64 / bytes.len() as f64,
        100.0 * dark as f64 / bytes.len() as f64
    );
    // Text and plot lines on a white page: mostly white, not all of it.
    assert!(dark as f64 > 0.002 * bytes.len() as f64, "blank page");
    assert!(white as f64 > 0.5 * bytes.len() as f64, "not the page");
    if let Ok(dir) = std::env::var("CALIB_SCREENSHOT_DIR") {
        std::fs::copy(png, Path::new(&dir).join("html-report.png")).unwrap();
    }
}
