//! The calibration report as one self-contained HTML file: for the people who pay for
//! a calibration and archive it. Inline SVG plots and an inline stylesheet (with a print
//! layout); no script, no external reference of any kind.
//!
//! It is rendered from the JSON report (`calib calibrate --report`, [`crate::calibration::Report`])
//! as a [`serde_json::Value`], so `calib calibrate --html` and `calib report --from report.json
//! --html` give the same page. A section whose data the report lacks (no swarm, no validation,
//! position-only data) is left out, and the summary says so.

use serde_json::Value;
use std::fmt::Write as _;

/// What the report is about, beyond the JSON: when and by which software it was rendered.
#[derive(Clone, Debug)]
pub struct Rendering {
    /// The time of rendering, RFC 3339 (UTC).
    pub date: String,
    /// `calib` and its version.
    pub software: String,
}

impl Rendering {
    /// Now, by this build of `calib`.
    pub fn now() -> Self {
        Self {
            date: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
            software: format!(
                "calib {} (commit {})",
                env!("CARGO_PKG_VERSION"),
                env!("CALIB_COMMIT")
            ),
        }
    }
}

/// The section identifiers of the page, in order (each an `<h2 id>`); tests and readers rely on
/// them.
pub const SECTIONS: [&str; 12] = [
    "summary",
    "conditions",
    "accuracy",
    "table3",
    "parameters",
    "identifiability",
    "plots",
    "poses",
    "outliers",
    "frames",
    "settings",
    "software",
];

/// Text escaped for HTML.
fn esc(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A number of the report with `digits` decimals, or "-" when absent.
fn num(value: &Value, digits: usize) -> String {
    value
        .as_f64()
        .map_or_else(|| "-".to_string(), |v| format!("{v:.digits$}"))
}

/// A scalar of the report as text ("-" when absent).
fn text(value: &Value) -> String {
    match value {
        Value::Null => "-".to_string(),
        Value::String(s) => esc(s),
        Value::Array(a) if a.is_empty() => "none".to_string(),
        Value::Array(a) => a.iter().map(text).collect::<Vec<_>>().join(", "),
        other => esc(&other.to_string()),
    }
}

/// The numbers of an array of the report.
fn numbers(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default()
}

/// The page for `report` (the JSON report of a calibration).
pub fn render(report: &Value, rendering: &Rendering) -> crate::Result<String> {
    let mut page = String::new();
    let robot = text(&report["robot"]);
    let data = text(&report["data"]);
    writeln!(
        page,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>Calibration report: {robot}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>Robot calibration report</h1>"
    )?;
    summary(&mut page, report, &robot, &data)?;
    conditions(&mut page, &report["conditions"])?;
    accuracy(&mut page, report)?;
    table3(&mut page, report)?;
    parameters(&mut page, report)?;
    identifiability(&mut page, report)?;
    plots(&mut page, report)?;
    poses(&mut page, report)?;
    outliers(&mut page, report)?;
    frames(&mut page, report)?;
    settings(&mut page, report)?;
    writeln!(
        page,
        "<h2 id=\"software\">Software</h2>\n<p>Calibrated by {} with the command line <code>{}</code>; rendered by {} (robot geometric calibration toolkit) {}.</p>\n{}</body>\n</html>",
        text(&report["software"]),
        (report["command_line"].as_array())
            .filter(|a| !a.is_empty())
            .map_or_else(
                || "-".to_string(),
                |a| a
                    .iter()
                    .map(|w| esc(&shell_word(w.as_str().unwrap_or_default())))
                    .collect::<Vec<_>>()
                    .join(" ")
            ),
        esc(&rendering.software),
        esc(&rendering.date),
        inputs(&report["inputs"])
    )?;
    Ok(page)
}

/// One word of a command line as a POSIX shell reads it back: as it is when it holds only
/// characters no shell treats specially, else in single quotes (a quote inside as `'\''`), so
/// that the recorded command line can be pasted back (`--accept '95% <= 1 mm'`).
pub(crate) fn shell_word(word: &str) -> String {
    let plain = !word.is_empty()
        && word
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"@%+=:,./_-".contains(&b));
    if plain {
        word.to_string()
    } else {
        format!("'{}'", word.replace('\'', "'\\''"))
    }
}

/// The input files with their SHA-256 (`inputs`), as a table; nothing when the report has none.
fn inputs(inputs: &Value) -> String {
    let Some(files) = inputs.as_array().filter(|a| !a.is_empty()) else {
        return String::new();
    };
    let rows: String = files
        .iter()
        .map(|f| {
            format!(
                "<tr><td>{}</td><td>{}</td><td><code>{}</code></td></tr>\n",
                text(&f["flag"]),
                text(&f["path"]),
                text(&f["sha256"])
            )
        })
        .collect();
    format!(
        "<table>\n<caption>Input files</caption>\n<tr><th>flag</th><th>path</th><th>SHA-256</th></tr>\n{rows}</table>\n"
    )
}

/// When the report's calibration finished (its `calibrated_at`), or that a report written before
/// the date was recorded does not say.
fn calibration_date(report: &Value) -> String {
    match report["calibrated_at"].as_str() {
        Some(date) => esc(date),
        None => "not recorded in this report".to_string(),
    }
}

/// The stylesheet: readable on screen and on paper.
const STYLE: &str = "body{font-family:sans-serif;max-width:60em;margin:2em auto;padding:0 1em;color:#111}\
h1{border-bottom:2px solid #333}h2{margin-top:2em;border-bottom:1px solid #999}\
table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #bbb;padding:0.2em 0.6em;text-align:right}\
th{background:#eee}td:first-child,th:first-child,td[colspan]{text-align:left}\
.note{color:#555}.bad{color:#a00;font-weight:bold}.pass{color:#060;border:2px solid #060;padding:0.4em}.fail{color:#a00;border:2px solid #a00;padding:0.4em}figure{margin:1em 0}svg{max-width:100%;height:auto}\
@page{size:A4;margin:15mm}@media print{body{max-width:none;margin:0}h2{break-after:avoid}figure,table{break-inside:avoid}.poses{font-size:8pt}}";

fn summary(page: &mut String, report: &Value, robot: &str, data: &str) -> crate::Result<()> {
    let stage = |name: &str| -> String {
        let s = &report[name];
        if s.is_null() {
            return format!("<tr><td>{name} poses</td><td colspan=\"3\">none held out</td></tr>");
        }
        format!(
            "<tr><td>{name} poses</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            text(&s["poses"]),
            num(&s["before"]["position_mm"]["mean"], 4),
            num(&s["after"]["position_mm"]["mean"], 4)
        )
    };
    writeln!(
        page,
        "<h2 id=\"summary\">Summary</h2>\n<table>\n<tr><td>robot</td><td colspan=\"3\">{robot}</td></tr>\n\
         <tr><td>data</td><td colspan=\"3\">{data}</td></tr>\n<tr><td>calibrated</td><td colspan=\"3\">{}</td></tr>\n\
         <tr><td>method</td><td colspan=\"3\">{} ({}; stopped: {}; {} s)</td></tr>\n\
         <tr><th>mean position error</th><th>poses</th><th>nominal, mm</th><th>identified, mm</th></tr>\n{}\n{}\n</table>",
        calibration_date(report),
        text(&report["method"]),
        text(&report["settings"]["model"]),
        text(&report["stop"]),
        num(&report["seconds"], 3),
        stage("calibration"),
        stage("validation"),
    )?;
    let implausible = numbers_or_texts(&report["implausible"]);
    if !implausible.is_empty() {
        writeln!(
            page,
            "<p class=\"bad\">Not plausible (written only because it was accepted): {}</p>",
            implausible.join("; ")
        )?;
    }
    if report["validation"].is_null() {
        page.push_str("<p class=\"note\">No poses were held out: the errors on the calibration poses flatter the model.</p>\n");
    }
    Ok(())
}

/// The texts of an array of strings.
fn numbers_or_texts(value: &Value) -> Vec<String> {
    value
        .as_array()
        .map(|a| a.iter().map(text).collect())
        .unwrap_or_default()
}

/// The held-out poses against the band predicted from the parameters' covariance.
fn uncertainty(page: &mut String, u: &Value) -> crate::Result<()> {
    if u.is_null() {
        return Ok(());
    }
    // What the band is made of, in the text report's words (from the typed figures; a report of
    // an earlier version has none).
    let makeup = serde_json::from_value::<crate::analysis::uncertainty::Coverage>(u.clone())
        .map(|c| format!("; {}", esc(&c.makeup())))
        .unwrap_or_default();
    writeln!(
        page,
        "<p>Predicted uncertainty (the parameters' covariance, and {}&nbsp;mm of noise per coordinate {}): the held-out errors lie inside their predicted 95&nbsp;% band for <strong>{}&nbsp;%</strong> of {} poses; the parameters alone predict {}&nbsp;mm RMS on average, at most {}&nbsp;mm (line {}){makeup}.</p>",
        num(&u["noise_mm"], 4),
        text(&u["noise_source"]),
        num(&u["percent_inside_95"], 1),
        text(&u["poses"]),
        num(&u["mean_model_rms_mm"], 4),
        num(&u["max_model_rms_mm"], 4),
        text(&u["max_model_rms_line"])
    )?;
    Ok(())
}

/// The acceptance statement (`acceptance`), when criteria were given: PASS or FAIL (the words of
/// the text report) with each criterion's measured share.
fn acceptance_stamp(page: &mut String, acceptance: &Value) -> crate::Result<()> {
    if let Some(criteria) = acceptance["criteria"].as_array() {
        let pass = acceptance["pass"].as_bool() == Some(true);
        writeln!(
            page,
            "<p class=\"{}\"><strong>{}</strong>: {}</p>",
            if pass { "pass" } else { "fail" },
            if pass { "PASS" } else { "FAIL" },
            criteria
                .iter()
                .map(|c| format!(
                    "{}: measured {}&nbsp;% ({})",
                    text(&c["text"]),
                    num(&c["measured_percent"], 2),
                    if c["pass"].as_bool() == Some(true) {
                        "met"
                    } else {
                        "not met"
                    }
                ))
                .collect::<Vec<_>>()
                .join("; ")
        )?;
    }
    Ok(())
}

/// Table rows of named held-out poses (`largest`, `flagged`): line, id, `|dp|` and x, y, z.
fn named_rows(poses: &Value) -> String {
    poses
        .as_array()
        .map(|a| {
            a.iter()
                .map(|p| {
                    let xyz = numbers(&p["xyz_mm"]);
                    format!(
                        "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                        text(&p["line"]),
                        text(&p["id"]),
                        num(&p["error_mm"], 4),
                        xyz.iter()
                            .map(|v| format!("{v:.4}"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The conditions of the measurement (`conditions`): robot serial, payload, instrument, air
/// temperature; what the inputs do not state says so and how to state it.
fn conditions(page: &mut String, c: &Value) -> crate::Result<()> {
    page.push_str("<h2 id=\"conditions\">Measurement conditions</h2>\n");
    if c.is_null() {
        page.push_str("<p>Not recorded in this report.</p>\n");
        return Ok(());
    }
    let not_stated = |how: &str| format!("<span class=\"note\">not stated ({how})</span>");
    let serial = match c["robot_serial"].as_str() {
        Some(s) => esc(s),
        None => not_stated("<code>serial = \"...\"</code> in the robot file"),
    };
    let payload = &c["payload"];
    let payload = if payload.is_null() {
        not_stated("<code>--payload-kg</code>, or <code>[dynamics.tool]</code> in the robot file")
    } else {
        match payload["source"].as_str() {
            Some("option") => format!(
                "{}&nbsp;kg (given for this measurement, --payload-kg)",
                num(&payload["mass_kg"], 3)
            ),
            _ => format!(
                "assumed {}&nbsp;kg (the robot file's [dynamics] tool, not given for this measurement: --payload-kg states it)",
                num(&payload["mass_kg"], 3)
            ),
        }
    };
    let i = &c["instrument"];
    let instrument = if i.is_null() {
        not_stated("<code>[instrument]</code> in the data profile")
    } else {
        format!(
            "{}{}: maximum permissible error {}&nbsp;&micro;m + {}&nbsp;&micro;m/m",
            i["name"].as_str().map_or_else(|| "unnamed".to_owned(), esc),
            i["serial"]
                .as_str()
                .map_or(String::new(), |s| format!(", serial {}", esc(s))),
            num(&i["mpe_um"], 1),
            num(&i["mpe_um_per_m"], 1)
        )
    };
    let t = &c["temperature"];
    let temperature = if t.is_null() {
        not_stated("a <code>temperature_c</code> column in the data")
    } else {
        format!(
            "{} to {}&nbsp;&deg;C over {} poses",
            num(&t["min_c"], 2),
            num(&t["max_c"], 2),
            text(&t["poses"])
        )
    };
    writeln!(
        page,
        "<table>\n<tr><td>robot serial</td><td>{serial}</td></tr>\n<tr><td>payload while measured</td><td>{payload}</td></tr>\n\
         <tr><td>instrument</td><td>{instrument}</td></tr>\n<tr><td>air temperature</td><td>{temperature}</td></tr>\n</table>"
    )?;
    Ok(())
}

/// The plan check (`plan_check`) and the cross-validation (`cross_validation`) as the
/// certificate states them, passed or not.
fn checks(page: &mut String, report: &Value) -> crate::Result<()> {
    let check = &report["plan_check"];
    if check.is_null() {
        page.push_str("<p>Plan check: not made (the data are not a measured plan with verification poses).</p>\n");
    } else {
        let p = &check["predicted"];
        writeln!(
            page,
            "<p>Plan check: {} verification poses measured {}&nbsp;mm mean error; the plan predicted {}&nbsp;mm (95&nbsp;% range {} to {}&nbsp;mm): {}.</p>",
            text(&check["poses"]),
            num(&check["measured_mean_mm"], 4),
            num(&p["mean_mm"], 4),
            num(&p["low_mm"], 4),
            num(&p["high_mm"], 4),
            match (
                check["measured_mean_mm"].as_f64(),
                p["low_mm"].as_f64(),
                p["high_mm"].as_f64(),
            ) {
                (Some(m), Some(low), Some(high)) if m > high => format!(
                    "<strong>{}</strong>",
                    crate::planning::verdict(m, low, high)
                ),
                (Some(m), Some(low), Some(high)) =>
                    crate::planning::verdict(m, low, high).to_string(),
                _ => "-".to_string(),
            }
        )?;
    }
    let cv = &report["cross_validation"];
    if report["settings"]["config"]["identify"] == "frames" && !cv.is_null() {
        // A re-registration: the geometry is the robot file's either way, so the comparison is
        // the frames' fit against their prediction of new poses, not a model against another.
        writeln!(
            page,
            "<p>Cross-validation of the re-registration ({} folds): poses predicted by the frames fitted without them {}&nbsp;mm mean error, the frames fitted on every pose {}&nbsp;mm (the same geometry, the robot file's). A geometry's cross-validation and the joint ranges of its calibration poses do not apply: the geometry was identified from other data.</p>",
            text(&cv["folds"]),
            num(&cv["calibrated_mean_mm"], 4),
            num(&cv["nominal_mean_mm"], 4)
        )?;
    } else if !cv.is_null() {
        let worse = cv["calibrated_mean_mm"].as_f64() > cv["nominal_mean_mm"].as_f64();
        writeln!(
            page,
            "<p>Cross-validation ({} folds of the calibration poses): {}&nbsp;mm mean error predicted by the calibration, {}&nbsp;mm by the nominal model: {}.</p>",
            text(&cv["folds"]),
            num(&cv["calibrated_mean_mm"], 4),
            num(&cv["nominal_mean_mm"], 4),
            if worse {
                "<strong>worse than nominal</strong>"
            } else {
                "better than nominal"
            }
        )?;
    }
    Ok(())
}

/// The certificate's caveats (`caveats`), or that none was found.
fn caveats(page: &mut String, caveats: &Value) -> crate::Result<()> {
    let Some(list) = caveats.as_array().filter(|l| !l.is_empty()) else {
        page.push_str("<p>Caveats: none found (plan check, cross-validation, joint ranges of the held-out poses against the calibration poses', predicted band).</p>\n");
        return Ok(());
    };
    page.push_str("<p>Caveats:</p>\n<ul class=\"caveats\">\n");
    for c in list {
        let lines: Vec<String> = (c["lines"].as_array().into_iter().flatten())
            .map(text)
            .collect();
        let shown = lines
            .iter()
            .take(20)
            .cloned()
            .collect::<Vec<_>>()
            .join(", ");
        let more = lines.len().saturating_sub(20);
        let lines = match (lines.is_empty(), more) {
            (true, _) => String::new(),
            (false, 0) => format!(" (lines {shown})"),
            (false, more) => format!(" (lines {shown} and {more} more)"),
        };
        writeln!(page, "<li>{}{lines}</li>", text(&c["text"]))?;
    }
    page.push_str("</ul>\n");
    Ok(())
}

/// The worst regions of the workspace map (`held_out.workspace`), measured and predicted.
fn workspace_regions(page: &mut String, map: &Value) -> crate::Result<()> {
    if map.is_null() {
        return Ok(());
    }
    let range = |r: &Value| {
        let n = numbers(r);
        match n.as_slice() {
            [lo, hi] => format!("{lo:.0}&nbsp;..&nbsp;{hi:.0}"),
            _ => "-".to_owned(),
        }
    };
    let row = |r: &Value, what: &str| {
        format!(
            "<tr><td>{what}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{} (line {})</td><td>{}</td></tr>\n",
            range(&r["x_mm"]),
            range(&r["y_mm"]),
            range(&r["z_mm"]),
            text(&r["poses"]),
            num(&r["mean_mm"], 4),
            num(&r["max_mm"], 4),
            text(&r["max_line"]),
            num(&r["predicted_rms_mm"], 4)
        )
    };
    let mut rows: String = (map["worst"].as_array().into_iter().flatten())
        .map(|r| row(r, "worst measured"))
        .collect();
    if !map["worst_predicted"].is_null() {
        rows.push_str(&row(&map["worst_predicted"], "largest predicted"));
    }
    if rows.is_empty() {
        // No header over no rows: say why there is no region to name.
        writeln!(
            page,
            "<p>Where the held-out error remains: {} poses in {} regions (terciles of x, y and z in the robot's base frame), none holding the {} poses a worst one is named from.</p>",
            text(&map["poses"]),
            map["regions"].as_array().map_or(0, Vec::len),
            crate::analysis::workspace::MIN_POSES
        )?;
        return Ok(());
    }
    writeln!(
        page,
        "<table>\n<caption>Where the held-out error remains: {} poses in {} regions (terciles of x, y and z in the robot's base frame; the map is under Plots)</caption>\n\
         <tr><th>region</th><th>x, mm</th><th>y, mm</th><th>z, mm</th><th>poses</th><th>mean |dp|, mm</th><th>max |dp|, mm</th><th>predicted RMS, mm</th></tr>\n{rows}</table>",
        text(&map["poses"]),
        map["regions"].as_array().map_or(0, Vec::len)
    )?;
    Ok(())
}

/// The ISO 9283-style figures (`iso9283`): AP, and RP with the largest AP from poses repeated
/// often enough, or why they are not stated.
fn iso9283(page: &mut String, iso: &Value) -> crate::Result<()> {
    if iso.is_null() {
        page.push_str("<p>ISO 9283 pose accuracy and repeatability: not measured (no held-out pose repeats a commanded pose).</p>\n");
        return Ok(());
    }
    // The typed figures, so that the certificate's words are the text report's.
    let Ok(iso) = serde_json::from_value::<crate::analysis::accuracy::Iso9283>(iso.clone()) else {
        page.push_str("<p>ISO 9283-style figures: in a form this version does not read (a report of an earlier version); calibrate again to state them.</p>\n");
        return Ok(());
    };
    writeln!(
        page,
        "<p>ISO 9283-style, from {} held-out poses repeated in {} groups (at most {} times; ISO asks for 30 cycles): accuracy AP mean {:.4}&nbsp;mm; {}.</p>",
        iso.poses,
        iso.groups,
        iso.most_repeats,
        iso.ap_mean_mm,
        esc(&iso.repeatability_text())
    )?;
    Ok(())
}

/// The accuracy on the held-out poses (`held_out`): the acceptance statement, the percentiles
/// and the per-axis errors before and after, the largest and the flagged poses by line.
fn accuracy(page: &mut String, report: &Value) -> crate::Result<()> {
    page.push_str("<h2 id=\"accuracy\">Accuracy on the held-out poses</h2>\n");
    let held = &report["held_out"];
    if held.is_null() {
        page.push_str("<p>No poses were held out: the accuracy on poses the calibration did not see is not measured (calibrate with --validate or --holdout).</p>\n");
        return Ok(());
    }
    acceptance_stamp(page, &report["acceptance"])?;
    caveats(page, &report["caveats"])?;
    writeln!(
        page,
        "<table>\n<tr><th>model ({} poses)</th><th>50&nbsp;%</th><th>95&nbsp;%</th><th>99&nbsp;%</th><th>max</th><th>x mean &plusmn; std</th><th>y mean &plusmn; std</th><th>z mean &plusmn; std</th></tr>",
        text(&held["after"]["poses"])
    )?;
    for (model, label) in [("before", "nominal"), ("after", "identified")] {
        let m = &held[model];
        let p = &m["position"];
        let axis = |k: usize| {
            let a = &m["axes"][k];
            format!(
                "{} &plusmn; {}",
                num(&a["mean_mm"], 4),
                num(&a["std_mm"], 4)
            )
        };
        writeln!(
            page,
            "<tr><td>{label}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            num(&p["p50_mm"], 4),
            num(&p["p95_mm"], 4),
            num(&p["p99_mm"], 4),
            num(&p["max_mm"], 4),
            axis(0),
            axis(1),
            axis(2)
        )?;
    }
    page.push_str("</table>\n<p class=\"note\">|dp| percentiles in mm; the signed error (measured - predicted) along the robot's base axes, mm.</p>\n");
    writeln!(
        page,
        "<table>\n<caption>Largest held-out errors</caption>\n<tr><th>line</th><th>id</th><th>|dp|, mm</th><th>x, y, z, mm</th></tr>\n{}</table>",
        named_rows(&held["largest"])
    )?;
    uncertainty(page, &report["uncertainty"])?;
    iso9283(page, &held["iso9283"])?;
    workspace_regions(page, &held["workspace"])?;
    checks(page, report)?;
    let flagged = &held["flagged"];
    if flagged.as_array().is_none_or(Vec::is_empty) {
        writeln!(
            page,
            "<p>No held-out pose is flagged (none above {} mm, the median + 3 robust standard deviations).</p>",
            num(&held["flag_above_mm"], 4)
        )?;
    } else {
        writeln!(
            page,
            "<table>\n<caption>Flagged held-out poses (above {} mm, the median + 3 robust standard deviations)</caption>\n<tr><th>line</th><th>id</th><th>|dp|, mm</th><th>x, y, z, mm</th></tr>\n{}</table>",
            num(&held["flag_above_mm"], 4),
            named_rows(flagged)
        )?;
    }
    Ok(())
}

fn table3(page: &mut String, report: &Value) -> crate::Result<()> {
    page.push_str("<h2 id=\"table3\">Table 3: errors before and after calibration</h2>\n");
    for name in ["calibration", "validation"] {
        let s = &report[name];
        if s.is_null() {
            continue;
        }
        writeln!(
            page,
            "<h3>{name} poses ({})</h3>\n<table>\n<tr><th>quantity</th><th>model</th><th>mean</th><th>std</th><th>max</th><th>RMS</th></tr>",
            text(&s["poses"])
        )?;
        let mut quantities = vec![("position |dp|, mm", "/position_mm".to_string())];
        for axis in ["x", "y", "z"] {
            quantities.push((
                match axis {
                    "x" => "orientation |dr_x|, deg",
                    "y" => "orientation |dr_y|, deg",
                    _ => "orientation |dr_z|, deg",
                },
                format!("/orientation_deg/{axis}"),
            ));
        }
        for (label, pointer) in quantities {
            for model in ["before", "after"] {
                let row = &s[model].pointer(&pointer).cloned().unwrap_or(Value::Null);
                if row.is_null() {
                    continue;
                }
                writeln!(
                    page,
                    "<tr><td>{label}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    if model == "before" {
                        "nominal"
                    } else {
                        "identified"
                    },
                    num(&row["mean"], 4),
                    num(&row["std"], 4),
                    num(&row["max"], 4),
                    num(&row["rms"], 4)
                )?;
            }
        }
        page.push_str("</table>\n");
    }
    Ok(())
}

fn parameters(page: &mut String, report: &Value) -> crate::Result<()> {
    page.push_str("<h2 id=\"parameters\">Identified parameters</h2>\n<p class=\"note\">Errors added to the nominal model, with their standard errors from least squares (1 sigma).</p>\n<table>\n<tr><th>parameter</th><th>error</th><th>standard error</th><th>unit</th></tr>\n");
    if let Some(map) = report["parameters"].as_object() {
        for (name, p) in map {
            let angle = p["unit"].as_str() == Some("rad");
            let shown = |v: &Value| -> String {
                v.as_f64().map_or_else(
                    || "-".to_string(),
                    |v| {
                        if angle {
                            format!("{:.5}", v.to_degrees())
                        } else {
                            format!("{v:.4}")
                        }
                    },
                )
            };
            writeln!(
                page,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                esc(name),
                shown(&p["value"]),
                shown(&p["std_error"]),
                if angle { "deg" } else { "mm" }
            )?;
        }
    }
    page.push_str("</table>\n");
    significance(page, &report["significance"])
}

/// The parameters not shown to differ from zero and the strongly correlated pairs.
fn significance(page: &mut String, significance: &Value) -> crate::Result<()> {
    if let Some(names) = significance["not_significant"]
        .as_array()
        .filter(|a| !a.is_empty())
    {
        writeln!(
            page,
            "<p class=\"note\">Smaller than twice their standard error (the data do not show them to differ from zero): {}.</p>",
            text(&Value::Array(names.clone()))
        )?;
    }
    if let Some(pairs) = significance["correlated"]
        .as_array()
        .filter(|a| !a.is_empty())
    {
        let shown: Vec<String> = pairs
            .iter()
            .map(|p| format!("{}/{} {}", text(&p[0]), text(&p[1]), num(&p[2], 3)))
            .collect();
        writeln!(
            page,
            "<p class=\"note\">Strongly correlated pairs (|correlation| &gt; 0.9): {}.</p>",
            shown.join(", ")
        )?;
    }
    Ok(())
}

fn identifiability(page: &mut String, report: &Value) -> crate::Result<()> {
    let i = &report["identifiability"];
    let weakest = i["weakest_direction"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|e| format!("{} {}", num(&e[1], 2), text(&e[0])))
                .collect::<Vec<_>>()
                .join(", ")
        })
        .unwrap_or_default();
    writeln!(
        page,
        "<h2 id=\"identifiability\">Identifiability</h2>\n<table>\n\
         <tr><td>parameters asked for</td><td>{}</td></tr>\n<tr><td>rank</td><td>{}</td></tr>\n\
         <tr><td>scaled condition number</td><td>{}</td></tr>\n<tr><td>observability index O1</td><td>{}</td></tr>\n\
         <tr><td>ill-conditioned</td><td>{}</td></tr>\n<tr><td>undetermined</td><td>{}</td></tr>\n\
         <tr><td>least determined direction</td><td>{weakest}</td></tr>\n<tr><td>dropped (in order)</td><td>{}</td></tr>\n</table>",
        text(&i["parameters"]),
        text(&i["rank"]),
        num(&i["condition_number"], 1),
        num(&i["observability_index"], 5),
        text(&i["ill_conditioned"]),
        text(&i["undetermined"]),
        text(&report["dropped"]),
    )?;
    if let Some(reflector) = i["reflector_on_last_axis"].as_object() {
        let left_out: Vec<String> = reflector
            .get("not_identified")
            .and_then(Value::as_array)
            .map(|a| {
                a.iter()
                    .map(|u| {
                        let with: Vec<String> = u["with"]
                            .as_array()
                            .map(|w| w.iter().map(|p| text(&p[0])).collect())
                            .unwrap_or_default();
                        if with.is_empty() {
                            format!("{} (does not move it)", text(&u["name"]))
                        } else {
                            format!("{} (acts like {})", text(&u["name"]), with.join(", "))
                        }
                    })
                    .collect()
            })
            .unwrap_or_default();
        writeln!(
            page,
            "<p>Reflector {} mm from the last joint's axis: the last joint barely moves it, so position data \
             cannot tell apart what moves it alike. Not identified (kept nominal): {}.</p>",
            num(reflector.get("distance_mm").unwrap_or(&Value::Null), 1),
            left_out.join(", ")
        )?;
    }
    if report["dropped"].as_array().is_some_and(|d| !d.is_empty()) {
        page.push_str(
            "<p>Why dropped: first the parameters the data cannot determine (rank deficiency, \
             with --auto-mask), then, while the pose set is ill-conditioned (scaled condition number \
             above 1000), the parameter with the largest share of the least determined direction.</p>\n",
        );
    }
    Ok(())
}

fn plots(page: &mut String, report: &Value) -> crate::Result<()> {
    let per_pose = &report["per_pose"];
    // Reports written before the lines were recorded have none: their poses are numbered.
    let lines = |v: &Value| -> Vec<u64> {
        v.as_array()
            .map(|a| a.iter().filter_map(Value::as_u64).collect())
            .unwrap_or_default()
    };
    let axes = |v: &Value| -> Vec<[f64; 3]> {
        v.as_array()
            .map(|a| {
                a.iter()
                    .map(|e| {
                        let n = numbers(e);
                        [0, 1, 2].map(|i| n.get(i).copied().unwrap_or(0.0))
                    })
                    .collect()
            })
            .unwrap_or_default()
    };
    let history: Vec<(u32, f64)> = report["convergence"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|e| Some((u32::try_from(e[0].as_u64()?).ok()?, e[1].as_f64()?)))
                .collect()
        })
        .unwrap_or_default();
    let (before, after) = (numbers(&per_pose["before"]), numbers(&per_pose["after"]));
    let (orientation_before, orientation_after) = (
        axes(&per_pose["orientation_before"]),
        axes(&per_pose["orientation_after"]),
    );
    let (validation_before, validation_after) = (
        numbers(&per_pose["validation_before"]),
        numbers(&per_pose["validation_after"]),
    );
    let data = crate::report::plots::PlotData {
        history: &history,
        title: "absolute position error per calibration pose",
        lines: &lines(&per_pose["lines"]),
        orientation_lines: &lines(&per_pose["orientation_lines"]),
        before: &before,
        after: &after,
        orientation_before: &orientation_before,
        orientation_after: &orientation_after,
        validation_before: &validation_before,
        validation_after: &validation_after,
        validation_positions: &axes(&per_pose["validation_position_mm"]),
        validation_predicted: &numbers(&per_pose["validation_predicted_rms_mm"]),
        joint_maps: &[],
    };
    page.push_str("<h2 id=\"plots\">Plots</h2>\n");
    for (name, caption, svg) in crate::report::plots::svg_plots(&data)? {
        writeln!(
            page,
            "<figure id=\"plot-{name}\">\n{}\n<figcaption>{caption}</figcaption>\n</figure>",
            strip_xml_declaration(&svg)
        )?;
    }
    Ok(())
}

/// An SVG document as an element to inline (without its XML declaration).
fn strip_xml_declaration(svg: &str) -> &str {
    match svg.find("<svg") {
        Some(start) => &svg[start..],
        None => svg,
    }
}

fn poses(page: &mut String, report: &Value) -> crate::Result<()> {
    page.push_str("<h2 id=\"poses\">Calibration poses</h2>\n<table class=\"poses\">\n<tr><th>id</th><th>line</th><th>nominal |dp|, mm</th><th>identified |dp|, mm</th><th>robust weight</th></tr>\n");
    for p in report["poses"].as_array().map_or(&[][..], Vec::as_slice) {
        writeln!(
            page,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            text(&p["id"]),
            text(&p["line"]),
            num(&p["before_mm"], 4),
            num(&p["after_mm"], 4),
            num(&p["robust_weight"], 3)
        )?;
    }
    page.push_str("</table>\n");
    Ok(())
}

fn outliers(page: &mut String, report: &Value) -> crate::Result<()> {
    // "Flagged" is kept for held-out poses of unusual error; these are calibration poses the
    // robust loss weighed down.
    page.push_str("<h2 id=\"outliers\">Calibration poses down-weighted as outliers</h2>\n");
    let list = report["outliers"].as_array().map_or(&[][..], Vec::as_slice);
    if list.is_empty() {
        page.push_str(
            "<p>No calibration pose was down-weighted as an outlier (the robust loss kept every weight).</p>\n",
        );
        return Ok(());
    }
    page.push_str(
        "<table>\n<tr><th>id</th><th>line</th><th>residual, mm</th><th>weight</th></tr>\n",
    );
    for o in list {
        writeln!(
            page,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            text(&o["id"]),
            text(&o["line"]),
            num(&o["residual_mm"], 4),
            num(&o["weight"], 3)
        )?;
    }
    page.push_str("</table>\n");
    Ok(())
}

fn frames(page: &mut String, report: &Value) -> crate::Result<()> {
    let f = &report["frames"];
    writeln!(
        page,
        "<h2 id=\"frames\">Frames of the measurement setup</h2>\n<table>\n<tr><td>identified</td><td>{}</td></tr>\n\
         <tr><td>registration RMS / max, mm</td><td>{} / {}</td></tr>\n<tr><td>redundant with the frames (not identified)</td><td>{}</td></tr>",
        text(&f["identified"]),
        num(&f["registration_rms_mm"], 4),
        num(&f["registration_max_mm"], 4),
        text(&f["redundant_with_frames"]),
    )?;
    for name in ["base", "tool"] {
        let frame = &f[name];
        if frame.is_null() {
            continue;
        }
        let list = |v: &Value, digits: usize| {
            v.as_array()
                .map(|a| {
                    a.iter()
                        .map(|x| num(x, digits))
                        .collect::<Vec<_>>()
                        .join(", ")
                })
                .unwrap_or_default()
        };
        writeln!(
            page,
            "<tr><td>{name}: xyz mm; rpy deg</td><td>{}; {}</td></tr>",
            list(&frame["xyz_mm"], 3),
            list(&frame["rpy_deg"], 5)
        )?;
    }
    page.push_str("</table>\n");
    Ok(())
}

fn settings(page: &mut String, report: &Value) -> crate::Result<()> {
    page.push_str("<h2 id=\"settings\">Settings</h2>\n<table>\n");
    let mut rows = Vec::new();
    flatten("", &report["settings"], &mut rows);
    for (key, value) in rows {
        // The frames setting is the choice asked for; absent, the data chose: show what was
        // identified.
        let value = if key == "frames" && value == "-" {
            format!(
                "{} (chosen from the data)",
                text(&report["frames"]["identified"])
            )
        } else {
            value
        };
        writeln!(page, "<tr><td>{}</td><td>{value}</td></tr>", esc(&key))?;
    }
    page.push_str("</table>\n");
    Ok(())
}

/// `value` as `(dotted key, text)` rows.
fn flatten(prefix: &str, value: &Value, rows: &mut Vec<(String, String)>) {
    match value {
        Value::Object(map) => {
            for (key, v) in map {
                let key = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                flatten(&key, v, rows);
            }
        }
        other => rows.push((prefix.to_string(), text(other))),
    }
}

#[cfg(test)]
mod tests {
    /// A recorded command line pasted into a POSIX shell gives back the same words (issue 52:
    /// `--accept 95% <= 1 mm` was recorded without its quotes).
    #[test]
    fn shell_words_read_back_as_the_same_words() {
        let words = [
            "calib",
            "--accept",
            "95% <= 1 mm",
            "it's",
            "",
            "a\"b$c`d`\\e",
            "x,y:z/w.csv",
        ];
        let line = words.map(super::shell_word).join(" ");
        let out = std::process::Command::new("sh")
            .arg("-c")
            .arg(format!("printf '%s\\n' {line}"))
            .output()
            .unwrap();
        let text = String::from_utf8(out.stdout).unwrap();
        let back: Vec<&str> = text.strip_suffix('\n').unwrap().split('\n').collect();
        assert_eq!(back, words);
        assert_eq!(super::shell_word("--accept"), "--accept");
        assert_eq!(super::shell_word("95% <= 1 mm"), "'95% <= 1 mm'");
    }
}
