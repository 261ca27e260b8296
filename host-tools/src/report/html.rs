//! The calibration report as one self-contained HTML file: for the people who pay for
//! a calibration and archive it. Inline SVG plots and an inline stylesheet (with a print
//! layout); no script, no external reference of any kind.
//!
//! It is rendered from the typed JSON report ([`crate::calibration::Report`]: what `calib
//! calibrate --report` writes and `calib report --from` reads back), so `calib calibrate --html`
//! and `calib report --from report.json --html` give the same page, and a field renamed in the
//! report is renamed here or the build fails. A section whose data the report lacks (no swarm, no
//! validation, position-only data) is left out, and the summary says so.

use crate::analysis::accuracy::{Acceptance, HeldOutAccuracy, Iso9283, NamedPose};
use crate::analysis::caveats::Caveat;
use crate::analysis::identifiability::Undetermined;
use crate::analysis::uncertainty::{Coverage, Significance};
use crate::analysis::workspace::{Region, WorkspaceMap};
use crate::calibration::{Identify, Report, Stage};
use crate::io::provenance::InputFile;
use crate::measurement::conditions::{MeasurementConditions, PayloadSource};
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
/// them. A page with a pose test has [`POSE_TEST_SECTION`] after `accuracy`.
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

pub(crate) use super::markup::{esc, list, num, opt};

/// The name a setting of the report is written with (its serde name), such as `joint-maps`.
fn serde_name<T: serde::Serialize>(value: &T) -> String {
    match serde_json::to_value(value) {
        Ok(Value::String(s)) => esc(&s),
        _ => "-".to_string(),
    }
}

/// The page for `report` (the JSON report of a calibration).
pub fn render(report: &Report, rendering: &Rendering) -> crate::Result<String> {
    render_with(report, rendering, Additions::default())
}

/// The section of an ISO 9283 pose test, after `accuracy` when the page has one
/// ([`render_with`]).
pub const POSE_TEST_SECTION: &str = "pose-test";

/// What a certificate shows beyond its calibration's report (`calib report --pose-test --job`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Additions<'a> {
    /// An ISO 9283 pose test of the calibrated robot ([`POSE_TEST_SECTION`], after the held-out
    /// accuracy).
    pub pose_test: Option<&'a crate::pose_test::PoseTest>,
    /// The job: the certificate's number, customer, site, cell, operator, day of measurement and
    /// approver (a table under the title, the header of every printed page, and the
    /// [`APPROVAL_SECTION`] with its signature lines).
    pub job: Option<&'a super::job::Job>,
}

pub use super::job::APPROVAL_SECTION;

/// The page for `report` with `additions`.
pub fn render_with(
    report: &Report,
    rendering: &Rendering,
    additions: Additions<'_>,
) -> crate::Result<String> {
    let mut page = String::new();
    let robot = esc(&report.robot);
    let data = esc(&report.data);
    writeln!(
        page,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>Calibration report: {robot}</title>\n<style>{STYLE}</style>\n{}</head>\n<body>\n<h1>Robot calibration report</h1>",
        super::job::page_header_style(&page_header(report, additions.job))
    )?;
    if let Some(job) = additions.job {
        page.push_str(&job.table_html());
    }
    summary(&mut page, report, &robot, &data)?;
    let measured_on = additions.job.and_then(|j| j.measured_on.as_deref());
    conditions(&mut page, report.conditions.as_ref(), measured_on)?;
    accuracy(&mut page, report)?;
    if let Some(test) = additions.pose_test {
        page.push_str(&super::pose_test::section(test)?);
    }
    table3(&mut page, report)?;
    parameters(&mut page, report)?;
    identifiability(&mut page, report)?;
    plots(&mut page, report)?;
    poses(&mut page, report)?;
    outliers(&mut page, report)?;
    frames(&mut page, report)?;
    settings(&mut page, report)?;
    if let Some(job) = additions.job {
        page.push_str(&job.approval_html());
    }
    let command_line = command_line_html(&report.command_line);
    writeln!(
        page,
        "<h2 id=\"software\">Software</h2>\n<p>Calibrated by {} with the command line <code>{command_line}</code>; rendered by {} (robot geometric calibration toolkit) {}.</p>\n{}</body>\n</html>",
        esc(&report.software),
        esc(&rendering.software),
        esc(&rendering.date),
        inputs(&report.inputs)
    )?;
    Ok(page)
}

/// A recorded command line as HTML, each word as a shell reads it back ([`shell_word`]), or
/// "-" when none was recorded (a library call).
pub(crate) fn command_line_html(words: &[String]) -> String {
    match words.is_empty() {
        true => "-".to_string(),
        false => (words.iter())
            .map(|w| esc(&shell_word(w)))
            .collect::<Vec<_>>()
            .join(" "),
    }
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
pub(crate) fn inputs(files: &[InputFile]) -> String {
    if files.is_empty() {
        return String::new();
    }
    let rows: String = files
        .iter()
        .map(|f| {
            format!(
                "<tr><td>{}</td><td>{}</td><td><code>{}</code></td></tr>\n",
                esc(&f.flag),
                esc(&f.path),
                esc(&f.sha256)
            )
        })
        .collect();
    format!(
        "<table>\n<caption>Input files</caption>\n<tr><th>flag</th><th>path</th><th>SHA-256</th></tr>\n{rows}</table>\n"
    )
}

/// When the report's calibration finished (its `calibrated_at`), or that a report written before
/// the date was recorded does not say.
fn calibration_date(report: &Report) -> String {
    match report.calibrated_at.as_str() {
        "" => "not recorded in this report".to_string(),
        date => esc(date),
    }
}

/// The stylesheet: readable on screen and on paper.
pub(crate) const STYLE: &str = "body{font-family:sans-serif;max-width:60em;margin:2em auto;padding:0 1em;color:#111}\
h1{border-bottom:2px solid #333}h2{margin-top:2em;border-bottom:1px solid #999}\
table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #bbb;padding:0.2em 0.6em;text-align:right}\
th{background:#eee}td:first-child,th:first-child,td[colspan]{text-align:left}\
.note{color:#555}.bad{color:#a00;font-weight:bold}.pass{color:#060;border:2px solid #060;padding:0.4em}.fail{color:#a00;border:2px solid #a00;padding:0.4em}figure{margin:1em 0}svg{max-width:100%;height:auto}\
@page{size:A4;margin:18mm 15mm;@bottom-right{content:\"page \" counter(page) \" of \" counter(pages);font-family:sans-serif;font-size:8pt;color:#555}}.sign td{height:12mm;min-width:9em}@media print{body{max-width:none;margin:0}h2{break-after:avoid}figure,table{break-inside:avoid}.poses{font-size:8pt}}";

fn summary(page: &mut String, report: &Report, robot: &str, data: &str) -> crate::Result<()> {
    let stage = |name: &str, stage: Option<&Stage>| -> String {
        let Some(s) = stage else {
            return format!("<tr><td>{name} poses</td><td colspan=\"3\">none held out</td></tr>");
        };
        format!(
            "<tr><td>{name} poses</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            s.poses,
            num(s.before.position_mm.mean, 4),
            num(s.after.position_mm.mean, 4)
        )
    };
    writeln!(
        page,
        "<h2 id=\"summary\">Summary</h2>\n<table>\n<tr><td>robot</td><td colspan=\"3\">{robot}</td></tr>\n\
         <tr><td>data</td><td colspan=\"3\">{data}</td></tr>\n<tr><td>calibrated</td><td colspan=\"3\">{}</td></tr>\n\
         <tr><td>method</td><td colspan=\"3\">{} ({}; stopped: {}; {} s)</td></tr>\n\
         <tr><th>mean position error</th><th>poses</th><th>nominal, mm</th><th>identified, mm</th></tr>\n{}\n{}\n</table>",
        calibration_date(report),
        esc(&report.method),
        serde_name(&report.settings.config.model),
        esc(&report.stop),
        num(report.seconds, 3),
        stage("calibration", Some(&report.calibration)),
        stage("validation", report.validation.as_ref()),
    )?;
    if !report.implausible.is_empty() {
        writeln!(
            page,
            "<p class=\"bad\">Not plausible (written only because it was accepted): {}</p>",
            (report.implausible.iter().map(|t| esc(t)))
                .collect::<Vec<_>>()
                .join("; ")
        )?;
    }
    if report.validation.is_none() {
        page.push_str("<p class=\"note\">No poses were held out: the errors on the calibration poses flatter the model.</p>\n");
    }
    Ok(())
}

/// The header of every printed page: the certificate's number when the job states it, the robot
/// and its serial.
fn page_header(report: &Report, job: Option<&super::job::Job>) -> String {
    let number = job.and_then(|j| j.certificate.as_deref());
    let serial = (report.conditions.as_ref()).and_then(|c| c.robot_serial.as_deref());
    format!(
        "{}Robot calibration: {}{}",
        number.map_or(String::new(), |n| format!("Certificate {n} - ")),
        report.robot,
        serial.map_or(String::new(), |s| format!(", serial {s}"))
    )
}

/// The instrument's own calibration: its certificate and due date, said to be overdue when it
/// was due before the measurement.
fn instrument_calibration(i: &crate::io::profile::Instrument, measured_on: Option<&str>) -> String {
    let certificate = i.certificate.as_deref().map_or_else(
        || "calibration certificate not stated (<code>certificate</code> in <code>[instrument]</code>)".to_string(),
        |c| format!("calibration certificate {}", esc(c)),
    );
    let due = match (
        &i.calibration_due,
        measured_on.and_then(|d| i.overdue_on(d)),
    ) {
        (None, _) => "due date not stated (<code>calibration_due</code>)".to_string(),
        (Some(d), Some(true)) => format!(
            "<span class=\"bad\">due {}: OVERDUE on the day of measurement</span>",
            esc(d)
        ),
        (Some(d), _) => format!("due {}", esc(d)),
    };
    format!("{certificate}, {due}")
}

/// The held-out poses against the band predicted from the parameters' covariance.
fn uncertainty(page: &mut String, coverage: Option<&Coverage>) -> crate::Result<()> {
    let Some(u) = coverage else {
        return Ok(());
    };
    writeln!(
        page,
        "<p>Predicted uncertainty (the parameters' covariance, and {}&nbsp;mm of noise per coordinate {}): the held-out errors lie inside their predicted 95&nbsp;% band for <strong>{}&nbsp;%</strong> of {} poses; the parameters alone predict {}&nbsp;mm RMS on average, at most {}&nbsp;mm (line {}); {}.</p>",
        num(u.noise_mm, 4),
        esc(&u.noise_source),
        num(u.percent_inside_95, 1),
        u.poses,
        num(u.mean_model_rms_mm, 4),
        num(u.max_model_rms_mm, 4),
        u.max_model_rms_line,
        esc(&u.makeup())
    )?;
    Ok(())
}

/// The uncertainty budget (GUM): each component with its evaluation type, source and standard
/// uncertainty, the combined and the expanded uncertainty (k = 2), the held-out check.
fn budget(
    page: &mut String,
    budget: Option<&crate::analysis::budget::UncertaintyBudget>,
) -> crate::Result<()> {
    let Some(b) = budget else {
        return Ok(());
    };
    page.push_str("<table>\n<caption>Uncertainty budget (GUM), per coordinate of the position error after calibration</caption>\n<tr><th>component</th><th>type</th><th>source</th><th>u, mm</th></tr>\n");
    for c in &b.components {
        writeln!(
            page,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&c.name),
            esc(&c.evaluation),
            esc(&c.source),
            num(c.standard_uncertainty_mm, 4)
        )?;
    }
    writeln!(
        page,
        "<tr><td>combined standard uncertainty u<sub>c</sub></td><td></td><td></td><td>{}</td></tr>\n<tr><th>expanded uncertainty U (k = {})</th><th></th><th>held out: {}&nbsp;% of {} coordinates within &plusmn;U</th><th>{}</th></tr>\n</table>",
        num(b.combined_mm, 4),
        b.k,
        num(b.held_out_within_percent, 1),
        b.held_out_coordinates,
        num(b.expanded_mm, 4)
    )?;
    for n in &b.not_evaluated {
        writeln!(page, "<p class=\"note\">Not evaluated: {}.</p>", esc(n))?;
    }
    Ok(())
}

/// The acceptance statement (`acceptance`), when criteria were given: PASS or FAIL (the words of
/// the text report) with each criterion's measured share.
fn acceptance_stamp(page: &mut String, acceptance: Option<&Acceptance>) -> crate::Result<()> {
    let Some(acceptance) = acceptance else {
        return Ok(());
    };
    writeln!(
        page,
        "<p class=\"{}\"><strong>{}</strong>: {}</p>",
        if acceptance.pass { "pass" } else { "fail" },
        if acceptance.pass { "PASS" } else { "FAIL" },
        (acceptance.criteria.iter())
            .map(|c| format!(
                "{}: measured {}&nbsp;% ({})",
                esc(&c.text),
                num(c.measured_percent, 2),
                if c.pass { "met" } else { "not met" }
            ))
            .collect::<Vec<_>>()
            .join("; ")
    )?;
    Ok(())
}

/// Table rows of named held-out poses (`largest`, `flagged`): line, id, `|dp|` and x, y, z.
fn named_rows(poses: &[NamedPose]) -> String {
    (poses.iter())
        .map(|p| {
            format!(
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                p.line,
                esc(&p.id),
                num(p.error_mm, 4),
                (p.xyz_mm.iter())
                    .map(|v| format!("{v:.4}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })
        .collect()
}

/// The conditions of the measurement (`conditions`): robot serial, payload, instrument, air
/// temperature; what the inputs do not state says so and how to state it.
fn conditions(
    page: &mut String,
    conditions: Option<&MeasurementConditions>,
    measured_on: Option<&str>,
) -> crate::Result<()> {
    page.push_str("<h2 id=\"conditions\">Measurement conditions</h2>\n");
    let Some(c) = conditions else {
        page.push_str("<p>Not recorded in this report.</p>\n");
        return Ok(());
    };
    let not_stated = |how: &str| format!("<span class=\"note\">not stated ({how})</span>");
    let serial = match &c.robot_serial {
        Some(s) => esc(s),
        None => not_stated("<code>serial = \"...\"</code> in the robot file"),
    };
    let payload = match &c.payload {
        None => not_stated(
            "<code>--payload-kg</code>, or <code>[dynamics.tool]</code> in the robot file",
        ),
        Some(p) if p.source == PayloadSource::Option => format!(
            "{}&nbsp;kg (given for this measurement, --payload-kg)",
            num(p.mass_kg, 3)
        ),
        Some(p) => format!(
            "assumed {}&nbsp;kg (the robot file's [dynamics] tool, not given for this measurement: --payload-kg states it)",
            num(p.mass_kg, 3)
        ),
    };
    let instrument = match &c.instrument {
        None => not_stated("<code>[instrument]</code> in the data profile"),
        Some(i) => format!(
            "{}{}: maximum permissible error {}&nbsp;&micro;m + {}&nbsp;&micro;m/m; {}",
            i.name.as_deref().map_or_else(|| "unnamed".to_owned(), esc),
            (i.serial.as_deref()).map_or(String::new(), |s| format!(", serial {}", esc(s))),
            num(i.mpe_um, 1),
            num(i.mpe_um_per_m, 1),
            instrument_calibration(i, measured_on)
        ),
    };
    let temperature = match &c.temperature {
        None => not_stated("a <code>temperature_c</code> column in the data"),
        Some(t) => format!(
            "{} to {}&nbsp;&deg;C over {} poses",
            num(t.min_c, 2),
            num(t.max_c, 2),
            t.poses
        ),
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
fn checks(page: &mut String, report: &Report) -> crate::Result<()> {
    match &report.plan_check {
        None => page.push_str("<p>Plan check: not made (the data are not a measured plan with verification poses).</p>\n"),
        Some(check) => {
            let (m, p) = (check.measured_mean_mm, &check.predicted);
            let verdict = crate::planning::verdict(m, p.low_mm, p.high_mm);
            writeln!(
                page,
                "<p>Plan check: {} verification poses measured {}&nbsp;mm mean error; the plan predicted {}&nbsp;mm (95&nbsp;% range {} to {}&nbsp;mm): {}.</p>",
                check.poses,
                num(m, 4),
                num(p.mean_mm, 4),
                num(p.low_mm, 4),
                num(p.high_mm, 4),
                if m > p.high_mm {
                    format!("<strong>{verdict}</strong>")
                } else {
                    verdict.to_string()
                }
            )?;
        }
    }
    let Some(cv) = &report.cross_validation else {
        return Ok(());
    };
    if report.settings.config.identify == Identify::Frames {
        // A re-registration: the geometry is the robot file's either way, so the comparison is
        // the frames' fit against their prediction of new poses, not a model against another.
        writeln!(
            page,
            "<p>Cross-validation of the re-registration ({} folds): poses predicted by the frames fitted without them {}&nbsp;mm mean error, the frames fitted on every pose {}&nbsp;mm (the same geometry, the robot file's). A geometry's cross-validation and the joint ranges of its calibration poses do not apply: the geometry was identified from other data.</p>",
            cv.folds,
            num(cv.calibrated_mean_mm, 4),
            num(cv.nominal_mean_mm, 4)
        )?;
    } else {
        writeln!(
            page,
            "<p>Cross-validation ({} folds of the calibration poses): {}&nbsp;mm mean error predicted by the calibration, {}&nbsp;mm by the nominal model: {}.</p>",
            cv.folds,
            num(cv.calibrated_mean_mm, 4),
            num(cv.nominal_mean_mm, 4),
            if cv.calibrated_mean_mm > cv.nominal_mean_mm {
                "<strong>worse than nominal</strong>"
            } else {
                "better than nominal"
            }
        )?;
    }
    Ok(())
}

/// The certificate's caveats (`caveats`), or that none was found.
fn caveats(page: &mut String, caveats: &[Caveat]) -> crate::Result<()> {
    if caveats.is_empty() {
        page.push_str("<p>Caveats: none found (plan check, cross-validation, joint ranges of the held-out poses against the calibration poses', predicted band).</p>\n");
        return Ok(());
    }
    page.push_str("<p>Caveats:</p>\n<ul class=\"caveats\">\n");
    for c in caveats {
        let shown = (c.lines.iter().take(20))
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join(", ");
        let lines = match (c.lines.is_empty(), c.lines.len().saturating_sub(20)) {
            (true, _) => String::new(),
            (false, 0) => format!(" (lines {shown})"),
            (false, more) => format!(" (lines {shown} and {more} more)"),
        };
        writeln!(page, "<li>{}{lines}</li>", esc(&c.text))?;
    }
    page.push_str("</ul>\n");
    Ok(())
}

/// The worst regions of the workspace map (`held_out.workspace`), measured and predicted.
fn workspace_regions(page: &mut String, map: Option<&WorkspaceMap>) -> crate::Result<()> {
    let Some(map) = map else {
        return Ok(());
    };
    let range = |[lo, hi]: [f64; 2]| format!("{lo:.0}&nbsp;..&nbsp;{hi:.0}");
    let row = |r: &Region, what: &str| {
        format!(
            "<tr><td>{what}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{} (line {})</td><td>{}</td></tr>\n",
            range(r.x_mm),
            range(r.y_mm),
            range(r.z_mm),
            r.poses,
            num(r.mean_mm, 4),
            num(r.max_mm, 4),
            r.max_line,
            opt(r.predicted_rms_mm, 4)
        )
    };
    let mut rows: String = (map.worst.iter())
        .map(|r| row(r, "worst measured"))
        .collect();
    if let Some(r) = &map.worst_predicted {
        rows.push_str(&row(r, "largest predicted"));
    }
    if rows.is_empty() {
        // No header over no rows: say why there is no region to name.
        writeln!(
            page,
            "<p>Where the held-out error remains: {} poses in {} regions (terciles of x, y and z in the robot's base frame), none holding the {} poses a worst one is named from.</p>",
            map.poses,
            map.regions.len(),
            crate::analysis::workspace::MIN_POSES
        )?;
        return Ok(());
    }
    writeln!(
        page,
        "<table>\n<caption>Where the held-out error remains: {} poses in {} regions (terciles of x, y and z in the robot's base frame; the map is under Plots)</caption>\n\
         <tr><th>region</th><th>x, mm</th><th>y, mm</th><th>z, mm</th><th>poses</th><th>mean |dp|, mm</th><th>max |dp|, mm</th><th>predicted RMS, mm</th></tr>\n{rows}</table>",
        map.poses,
        map.regions.len()
    )?;
    Ok(())
}

/// The ISO 9283-style figures (`iso9283`): AP, and RP with the largest AP from poses repeated
/// often enough, or why they are not stated (the text report's words).
fn iso9283(page: &mut String, iso: Option<&Iso9283>) -> crate::Result<()> {
    let Some(iso) = iso else {
        page.push_str("<p>ISO 9283 pose accuracy and repeatability: not measured (no held-out pose repeats a commanded pose).</p>\n");
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
fn accuracy(page: &mut String, report: &Report) -> crate::Result<()> {
    page.push_str("<h2 id=\"accuracy\">Accuracy on the held-out poses</h2>\n");
    let Some(held) = &report.held_out else {
        page.push_str("<p>No poses were held out: the accuracy on poses the calibration did not see is not measured (calibrate with --validate or --holdout).</p>\n");
        return Ok(());
    };
    acceptance_stamp(page, report.acceptance.as_ref())?;
    caveats(page, &report.caveats)?;
    accuracy_table(page, held)?;
    writeln!(
        page,
        "<table>\n<caption>Largest held-out errors</caption>\n<tr><th>line</th><th>id</th><th>|dp|, mm</th><th>x, y, z, mm</th></tr>\n{}</table>",
        named_rows(&held.largest)
    )?;
    uncertainty(page, report.uncertainty.as_ref())?;
    budget(page, report.budget.as_ref())?;
    iso9283(page, held.iso9283.as_ref())?;
    workspace_regions(page, held.workspace.as_ref())?;
    checks(page, report)?;
    if held.flagged.is_empty() {
        writeln!(
            page,
            "<p>No held-out pose is flagged (none above {} mm, the median + 3 robust standard deviations).</p>",
            num(held.flag_above_mm, 4)
        )?;
    } else {
        writeln!(
            page,
            "<table>\n<caption>Flagged held-out poses (above {} mm, the median + 3 robust standard deviations)</caption>\n<tr><th>line</th><th>id</th><th>|dp|, mm</th><th>x, y, z, mm</th></tr>\n{}</table>",
            num(held.flag_above_mm, 4),
            named_rows(&held.flagged)
        )?;
    }
    Ok(())
}

/// The held-out `|dp|` percentiles and the signed error per base axis, nominal and identified.
fn accuracy_table(page: &mut String, held: &HeldOutAccuracy) -> crate::Result<()> {
    writeln!(
        page,
        "<table>\n<tr><th>model ({} poses)</th><th>50&nbsp;%</th><th>95&nbsp;%</th><th>99&nbsp;%</th><th>max</th><th>x mean &plusmn; std</th><th>y mean &plusmn; std</th><th>z mean &plusmn; std</th></tr>",
        held.after.poses
    )?;
    for (m, label) in [(&held.before, "nominal"), (&held.after, "identified")] {
        let p = &m.position;
        let axis = |k: usize| {
            let a = &m.axes[k];
            format!("{} &plusmn; {}", num(a.mean_mm, 4), num(a.std_mm, 4))
        };
        writeln!(
            page,
            "<tr><td>{label}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            num(p.p50_mm, 4),
            num(p.p95_mm, 4),
            num(p.p99_mm, 4),
            num(p.max_mm, 4),
            axis(0),
            axis(1),
            axis(2)
        )?;
    }
    page.push_str("</table>\n<p class=\"note\">|dp| percentiles in mm; the signed error (measured - predicted) along the robot's base axes, mm.</p>\n");
    Ok(())
}

fn table3(page: &mut String, report: &Report) -> crate::Result<()> {
    page.push_str("<h2 id=\"table3\">Table 3: errors before and after calibration</h2>\n");
    let stages = [
        ("calibration", Some(&report.calibration)),
        ("validation", report.validation.as_ref()),
    ];
    for (name, stage) in stages {
        let Some(s) = stage else {
            continue;
        };
        writeln!(
            page,
            "<h3>{name} poses ({})</h3>\n<table>\n<tr><th>quantity</th><th>model</th><th>mean</th><th>std</th><th>max</th><th>RMS</th></tr>",
            s.poses
        )?;
        let mut rows = vec![(
            "position |dp|, mm",
            [Some(s.before.position_mm), Some(s.after.position_mm)],
        )];
        let orientation = [s.before.orientation_deg, s.after.orientation_deg];
        for (label, axis) in [
            ("orientation |dr_x|, deg", 0),
            ("orientation |dr_y|, deg", 1),
            ("orientation |dr_z|, deg", 2),
        ] {
            rows.push((label, orientation.map(|o| o.map(|o| [o.x, o.y, o.z][axis]))));
        }
        for (label, models) in rows {
            for (stat, model) in models.iter().zip(["nominal", "identified"]) {
                let Some(stat) = stat else {
                    continue;
                };
                writeln!(
                    page,
                    "<tr><td>{label}</td><td>{model}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    num(stat.mean, 4),
                    num(stat.std, 4),
                    num(stat.max, 4),
                    num(stat.rms, 4)
                )?;
            }
        }
        page.push_str("</table>\n");
    }
    Ok(())
}

fn parameters(page: &mut String, report: &Report) -> crate::Result<()> {
    page.push_str("<h2 id=\"parameters\">Identified parameters</h2>\n<p class=\"note\">Errors added to the nominal model, with their standard errors from least squares (1 sigma).</p>\n<table>\n<tr><th>parameter</th><th>error</th><th>standard error</th><th>unit</th></tr>\n");
    for (name, p) in &report.parameters {
        let angle = p.is_angle();
        let shown = |v: Option<f64>| -> String {
            match v {
                Some(v) if angle => num(v.to_degrees(), 5),
                v => opt(v, 4),
            }
        };
        writeln!(
            page,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(name),
            shown(Some(p.value)),
            shown(p.std_error),
            if angle { "deg" } else { "mm" }
        )?;
    }
    page.push_str("</table>\n");
    significance(page, report.significance.as_ref())
}

/// The parameters not shown to differ from zero and the strongly correlated pairs.
fn significance(page: &mut String, significance: Option<&Significance>) -> crate::Result<()> {
    let Some(significance) = significance else {
        return Ok(());
    };
    if !significance.not_significant.is_empty() {
        writeln!(
            page,
            "<p class=\"note\">Smaller than twice their standard error (the data do not show them to differ from zero): {}.</p>",
            list(&significance.not_significant)
        )?;
    }
    if !significance.correlated.is_empty() {
        let shown: Vec<String> = (significance.correlated.iter())
            .map(|(a, b, r)| format!("{}/{} {}", esc(a), esc(b), num(*r, 3)))
            .collect();
        writeln!(
            page,
            "<p class=\"note\">Strongly correlated pairs (|correlation| &gt; 0.9): {}.</p>",
            shown.join(", ")
        )?;
    }
    Ok(())
}

/// Undetermined parameters as `name (status)`, with what a redundant one acts like.
fn undetermined(parameters: &[Undetermined]) -> String {
    let named: Vec<String> = (parameters.iter())
        .map(|u| format!("{} ({})", u.parameter, u.status))
        .collect();
    list(&named)
}

fn identifiability(page: &mut String, report: &Report) -> crate::Result<()> {
    let i = &report.identifiability;
    let weakest = (i.weakest_direction.iter())
        .map(|(p, v)| format!("{} {p}", num(*v, 2)))
        .collect::<Vec<_>>()
        .join(", ");
    writeln!(
        page,
        "<h2 id=\"identifiability\">Identifiability</h2>\n<table>\n\
         <tr><td>parameters asked for</td><td>{}</td></tr>\n<tr><td>rank</td><td>{}</td></tr>\n\
         <tr><td>scaled condition number</td><td>{}</td></tr>\n<tr><td>observability index O1</td><td>{}</td></tr>\n\
         <tr><td>ill-conditioned</td><td>{}</td></tr>\n<tr><td>undetermined</td><td>{}</td></tr>\n\
         <tr><td>least determined direction</td><td>{weakest}</td></tr>\n<tr><td>dropped (in order)</td><td>{}</td></tr>\n</table>",
        i.parameters,
        i.rank,
        opt(i.condition_number, 1),
        num(i.observability_index, 5),
        i.ill_conditioned,
        undetermined(&i.undetermined),
        list(&report.dropped),
    )?;
    if let Some(reflector) = &i.reflector_on_last_axis {
        let left_out = reflector.left_out();
        writeln!(
            page,
            "<p>Reflector {} mm from the last joint's axis: the last joint barely moves it, so position data \
             cannot tell apart what moves it alike. Not identified (kept nominal): {}.</p>",
            num(reflector.distance_mm, 1),
            left_out.join(", ")
        )?;
    }
    if !report.dropped.is_empty() {
        page.push_str(
            "<p>Why dropped: first the parameters the data cannot determine (rank deficiency, \
             with --auto-mask), then, while the pose set is ill-conditioned (scaled condition number \
             above 1000), the parameter with the largest share of the least determined direction.</p>\n",
        );
    }
    Ok(())
}

fn plots(page: &mut String, report: &Report) -> crate::Result<()> {
    let data = crate::report::plots::PlotData::of_poses(&report.per_pose, &report.convergence, &[]);
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

fn poses(page: &mut String, report: &Report) -> crate::Result<()> {
    page.push_str("<h2 id=\"poses\">Calibration poses</h2>\n<table class=\"poses\">\n<tr><th>id</th><th>line</th><th>nominal |dp|, mm</th><th>identified |dp|, mm</th><th>robust weight</th></tr>\n");
    for p in &report.poses {
        writeln!(
            page,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&p.id),
            p.line,
            num(p.before_mm, 4),
            num(p.after_mm, 4),
            num(p.robust_weight, 3)
        )?;
    }
    page.push_str("</table>\n");
    Ok(())
}

fn outliers(page: &mut String, report: &Report) -> crate::Result<()> {
    // "Flagged" is kept for held-out poses of unusual error; these are calibration poses the
    // robust loss weighed down.
    page.push_str("<h2 id=\"outliers\">Calibration poses down-weighted as outliers</h2>\n");
    if report.outliers.is_empty() {
        page.push_str(
            "<p>No calibration pose was down-weighted as an outlier (the robust loss kept every weight).</p>\n",
        );
        return Ok(());
    }
    page.push_str(
        "<table>\n<tr><th>id</th><th>line</th><th>residual, mm</th><th>weight</th></tr>\n",
    );
    for o in &report.outliers {
        writeln!(
            page,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&o.id),
            o.line,
            num(o.residual_mm, 4),
            num(o.weight, 3)
        )?;
    }
    page.push_str("</table>\n");
    Ok(())
}

fn frames(page: &mut String, report: &Report) -> crate::Result<()> {
    let f = &report.frames;
    writeln!(
        page,
        "<h2 id=\"frames\">Frames of the measurement setup</h2>\n<table>\n<tr><td>identified</td><td>{}</td></tr>\n\
         <tr><td>registration RMS / max, mm</td><td>{} / {}</td></tr>\n<tr><td>redundant with the frames (not identified)</td><td>{}</td></tr>",
        esc(f.identified.name()),
        num(f.registration_rms_mm, 4),
        num(f.registration_max_mm, 4),
        list(&f.redundant_with_frames),
    )?;
    for (name, frame) in [("base", &f.base), ("tool", &f.tool)] {
        let Some(frame) = frame else {
            continue;
        };
        let numbers = |v: &[f64; 3], digits: usize| {
            (v.iter().map(|x| num(*x, digits)))
                .collect::<Vec<_>>()
                .join(", ")
        };
        writeln!(
            page,
            "<tr><td>{name}: xyz mm; rpy deg</td><td>{}; {}</td></tr>",
            numbers(&frame.xyz_mm, 3),
            numbers(&frame.rpy_deg, 5)
        )?;
    }
    page.push_str("</table>\n");
    Ok(())
}

/// The settings, every one the report states (`settings`, flattened to dotted keys).
fn settings(page: &mut String, report: &Report) -> crate::Result<()> {
    page.push_str("<h2 id=\"settings\">Settings</h2>\n<table>\n");
    let mut rows = Vec::new();
    flatten("", &serde_json::to_value(&report.settings)?, &mut rows);
    for (key, value) in rows {
        // The frames setting is the choice asked for; absent, the data chose: show what was
        // identified.
        let value = if key == "frames" && value == "-" {
            format!(
                "{} (chosen from the data)",
                esc(report.frames.identified.name())
            )
        } else {
            value
        };
        writeln!(page, "<tr><td>{}</td><td>{value}</td></tr>", esc(&key))?;
    }
    page.push_str("</table>\n");
    Ok(())
}

/// A setting's value as text ("-" when absent).
fn text(value: &Value) -> String {
    match value {
        Value::Null => "-".to_string(),
        Value::String(s) => esc(s),
        Value::Array(a) if a.is_empty() => "none".to_string(),
        Value::Array(a) => a.iter().map(text).collect::<Vec<_>>().join(", "),
        other => esc(&other.to_string()),
    }
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
