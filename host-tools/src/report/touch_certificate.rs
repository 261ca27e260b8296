//! The certificate of a calibration without an instrument (touches in sockets), as one
//! self-contained HTML page (printed to PDF by [`super::pdf`]): rendered from the typed JSON
//! report ([`TouchReport`]: what `calib sockets --report` writes and `calib report --from` reads
//! back), in the style of the tracker report ([`super::html`]).
//!
//! Touches measure how closely the ball returns to the same socket (consistency) and how well a
//! known distance is held (distortion); the sockets' positions are unknown. So the page states
//! those figures under their own names and never as absolute accuracy, says in words what the
//! data could not determine (where the robot stands, joint 1's turn and lift, what lies after the
//! last axis, the scale without a known distance, the parameters dropped), and gives the
//! parameters with their standard errors, the inputs' SHA-256 and the software.

use super::html::{Rendering, STYLE, command_line_html, esc, inputs, num, opt};
use crate::calibration::touches::{PlacementFigures, TouchReport};
use std::fmt::Write as _;

/// The section identifiers of the page, in order (each an `<h2 id>`).
pub const SECTIONS: [&str; 6] = [
    "summary",
    "consistency",
    "undetermined",
    "parameters",
    "identifiability",
    "software",
];

/// The page for `report` (the JSON report of a calibration from touches).
pub fn render(report: &TouchReport, rendering: &Rendering) -> crate::Result<String> {
    render_with(report, rendering, None)
}

/// The page for `report` with the job it certifies (`calib report --job`): the job under the
/// title, the certificate's number in the header of every printed page, and the
/// [`APPROVAL_SECTION`](super::job::APPROVAL_SECTION) with its signature lines before the
/// software.
pub fn render_with(
    report: &TouchReport,
    rendering: &Rendering,
    job: Option<&super::job::Job>,
) -> crate::Result<String> {
    let mut page = String::new();
    let robot = esc(&report.robot.display().to_string());
    let number = job.and_then(|j| j.certificate.as_deref());
    let header = format!(
        "{}Robot calibration (touches): {}",
        number.map_or(String::new(), |n| format!("Certificate {n} - ")),
        report.robot.display()
    );
    writeln!(
        page,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>Calibration certificate (touches): {robot}</title>\n<style>{STYLE}</style>\n{}</head>\n<body>\n<h1>Robot calibration certificate: touches in sockets, no instrument</h1>",
        super::job::page_header_style(&header)
    )?;
    if let Some(job) = job {
        page.push_str(&job.table_html());
    }
    summary(&mut page, report, &robot)?;
    consistency(&mut page, report)?;
    undetermined(&mut page, report)?;
    parameters(&mut page, report)?;
    torsion(&mut page, report)?;
    identifiability(&mut page, report)?;
    if let Some(job) = job {
        page.push_str(&job.approval_html());
    }
    let command_line = command_line_html(&report.command_line);
    let software = match report.software.as_str() {
        "" => "-".to_string(),
        s => esc(s),
    };
    writeln!(
        page,
        "<h2 id=\"software\">Software</h2>\n<p>Calibrated by {software} with the command line <code>{command_line}</code>; rendered by {} (robot geometric calibration toolkit) {}.</p>\n{}</body>\n</html>",
        esc(&rendering.software),
        esc(&rendering.date),
        inputs(&report.inputs)
    )?;
    Ok(page)
}

/// What was calibrated, from what, and what the figures are: the statement that they are not
/// absolute accuracy stands first.
fn summary(page: &mut String, report: &TouchReport, robot: &str) -> crate::Result<()> {
    let held: Vec<&str> = (report.held_out.iter())
        .map(|f| f.placement.as_str())
        .collect();
    let date = match report.calibrated_at.as_str() {
        "" => "not recorded in this report".to_string(),
        d => esc(d),
    };
    let [x, y, z] = report.ball_mm;
    writeln!(
        page,
        "<h2 id=\"summary\">Summary</h2>\n<p class=\"note\"><b>What this certifies.</b> A ball on the flange was touched in sockets from many arm configurations; only the joint readings were recorded. The figures below are <b>consistency</b> (how far each ball centre lies from its socket's mean under the identified model) and <b>distortion</b> (the known distance's error): they are <b>not absolute accuracy</b>. The sockets' positions are unknown, so where the robot stands in the cell and a displacement shared by every configuration are not measured (section <a href=\"#undetermined\">Not determined</a>).</p>\n<table>\n<tr><td>robot file</td><td>{robot}</td></tr>\n<tr><td>calibrated</td><td>{date}</td></tr>\n<tr><td>placements fitted</td><td>{}</td></tr>\n<tr><td>placements held out (judged)</td><td>{}</td></tr>\n<tr><td>ball centre in the robot file's tool frame (measurement setup, not the controller's tool)</td><td>{}, {}, {} mm</td></tr>\n<tr><td>known distance</td><td>{}</td></tr>\n<tr><td>touches' scatter per coordinate (fit without the distance)</td><td>{}</td></tr>\n<tr><td>parameters identified</td><td>{} by least squares ({} iterations, {:.3} s)</td></tr>\n</table>",
        super::html::list(&report.fitted_placements),
        super::html::list(&held),
        num(x, 4),
        num(y, 4),
        num(z, 4),
        gauge_text(report),
        report
            .touch_sd_mm
            .map_or("-".to_string(), |s| format!("{} mm", num(s, 4))),
        report.parameters.len(),
        report.least_squares.iterations,
        report.seconds,
    )?;
    if let Some(t) = &report.tracker {
        writeln!(
            page,
            "<p><b>Tracker positions of the ball</b>: {} fitted with the touches (the tracker's standard uncertainty {} mm per coordinate as given; a touch's coordinate weighs {} against one). Their residuals, RMS {} mm, largest {} mm, are of positions fitted, not held out: they show the fit, not the accuracy elsewhere.</p>",
            t.positions,
            num(t.sd_mm, 4),
            num(t.touch_weight, 4),
            num(t.rms_mm, 4),
            num(t.max_mm, 4)
        )?;
    }
    if let Some(mean) = held_out_mean(&report.held_out) {
        writeln!(
            page,
            "<p><b>Held-out consistency</b> (mean over the held-out placements of each one's mean distance from the socket): <b>{} mm</b> (nominal model: {} mm; the authors' rule, outliers beyond two interquartile ranges left out: {} mm).</p>",
            num(mean.0, 4),
            num(mean.1, 4),
            num(mean.2, 4)
        )?;
        if let Some((mean, worst, name)) = distance_errors(&report.held_out) {
            writeln!(
                page,
                "<p><b>Known distance on the held-out placements</b>: off by {} mm on average (absolute), at most {} mm ({}).</p>",
                num(mean, 4),
                num(worst, 4),
                esc(name)
            )?;
        }
    } else {
        writeln!(
            page,
            "<p class=\"bad\">No placement was held out: every figure below is of the data fitted, which flatters the model. Hold one out (--train) to judge it.</p>"
        )?;
    }
    Ok(())
}

/// The known distance and its standard uncertainty, or that the scale is not determined.
fn gauge_text(report: &TouchReport) -> String {
    match &report.gauge {
        Some(g) => format!(
            "{} mm +- {} mm (standard uncertainty) between sockets {} and {}; weighed {} against a touch's coordinate",
            num(g.mm, 3),
            num(g.sd_mm, 3),
            g.sockets[0],
            g.sockets[1],
            opt(report.gauge_weight, 3)
        ),
        None => "none: the scale is not determined".to_string(),
    }
}

/// Over the held-out placements: the means of the identified, the nominal and the authors'-rule
/// consistency, mm.
fn held_out_mean(held: &[PlacementFigures]) -> Option<(f64, f64, f64)> {
    if held.is_empty() {
        return None;
    }
    let n = held.len() as f64;
    let mean = |f: fn(&PlacementFigures) -> f64| held.iter().map(f).sum::<f64>() / n;
    Some((
        mean(|f| f.identified.mean_mm),
        mean(|f| f.nominal.mean_mm),
        mean(|f| f.identified.authors_mean_mm),
    ))
}

/// Over the held-out placements with the known distance: the mean absolute distortion, the
/// largest and its placement, mm.
fn distance_errors(held: &[PlacementFigures]) -> Option<(f64, f64, &str)> {
    let errors: Vec<(f64, &str)> = (held.iter())
        .filter_map(|f| {
            Some((
                f.identified.distortion_mm.first()?.1.abs(),
                f.placement.as_str(),
            ))
        })
        .collect();
    let worst = errors.iter().copied().max_by(|a, b| a.0.total_cmp(&b.0))?;
    let mean = errors.iter().map(|e| e.0).sum::<f64>() / errors.len() as f64;
    Some((mean, worst.0, worst.1))
}

/// Per placement: consistency and distortion, fitted, held out (with the prediction) and left
/// out one at a time.
fn consistency(page: &mut String, report: &TouchReport) -> crate::Result<()> {
    writeln!(
        page,
        "<h2 id=\"consistency\">Consistency and distortion per placement</h2>\n<p class=\"note\">Consistency: the distance of each ball centre from its socket's mean, mm (mean and 95th percentile over every touch; the authors' rule leaves out touches beyond two interquartile ranges). Distortion: the distance between the two sockets' centres minus the known one, mm. Predicted: what the fit's scatter and parameter covariance lead one to expect on a held-out placement; a measured figure well above it means the model leaves something out.</p>"
    )?;
    let groups: [(&str, &[PlacementFigures]); 3] = [
        ("fitted", &report.fitted),
        ("held out", &report.held_out),
        (
            "left out one at a time (each judged by a calibration of all the others)",
            &report.leave_one_out,
        ),
    ];
    for (title, figures) in groups {
        if figures.is_empty() {
            continue;
        }
        writeln!(
            page,
            "<table>\n<caption>{}</caption>\n<tr><th>placement</th><th>touches</th><th>nominal mean</th><th>mean</th><th>95 %</th><th>authors' rule</th><th>distortion</th><th>predicted mean</th></tr>",
            esc(title)
        )?;
        for f in figures {
            writeln!(page, "{}", placement_row(f))?;
        }
        writeln!(page, "</table>")?;
    }
    let planes: Vec<String> = (report.fitted.iter().chain(&report.held_out))
        .flat_map(|f| {
            (f.identified.planes.iter()).map(move |p| {
                format!(
                    "<tr><td>{} plane {}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    esc(&f.placement),
                    p.plane,
                    p.contacts,
                    num(p.mean_mm, 4),
                    num(p.p95_mm, 4)
                )
            })
        })
        .collect();
    let datums: Vec<String> = (report.fitted.iter().chain(&report.held_out))
        .flat_map(|f| {
            (f.identified.known_planes.iter()).map(move |p| {
                let plane = (report.datums.get(usize::from(p.plane))).map_or(p.plane, |d| d.plane);
                format!(
                    "<tr><td>{} plane {plane}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    esc(&f.placement),
                    p.contacts,
                    num(p.mean_mm, 4),
                    num(p.p95_mm, 4)
                )
            })
        })
        .collect();
    if !datums.is_empty() {
        writeln!(
            page,
            "<table>\n<caption>Contacts with the datum planes, known in the base frame (distance from the known plane, mm)</caption>\n<tr><th>plane</th><th>contacts</th><th>mean</th><th>95 %</th></tr>\n{}\n</table>",
            datums.join("\n")
        )?;
    }
    if !planes.is_empty() {
        writeln!(
            page,
            "<table>\n<caption>Flatness of the plane contacts (distance from the best plane, mm)</caption>\n<tr><th>plane</th><th>contacts</th><th>mean</th><th>95 %</th></tr>\n{}\n</table>",
            planes.join("\n")
        )?;
    }
    Ok(())
}

/// One placement's row.
fn placement_row(f: &PlacementFigures) -> String {
    let touches: usize = f.identified.sockets.iter().map(|s| s.touches).sum();
    let distortion = (f.identified.distortion_mm.first()).map_or("-".to_string(), |(_, e)| {
        format!("{}{}", if *e >= 0.0 { "+" } else { "" }, num(*e, 4))
    });
    format!(
        "<tr><td>{}</td><td>{touches}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{distortion}</td><td>{}</td></tr>",
        esc(&f.placement),
        num(f.nominal.mean_mm, 4),
        num(f.identified.mean_mm, 4),
        num(f.identified.p95_mm, 4),
        num(f.identified.authors_mean_mm, 4),
        opt(f.predicted.map(|p| p.mean_mm), 4)
    )
}

/// What the data could not determine, in words: the base and the scale, then the parameters the
/// touches leave free and those dropped as barely determined.
fn undetermined(page: &mut String, report: &TouchReport) -> crate::Result<()> {
    if let Some(t) = &report.tracker {
        let [x, y, z] = t.registration_xyz_mm;
        let [roll, pitch, yaw] = t.registration_rpy_rad.map(f64::to_degrees);
        writeln!(
            page,
            "<h2 id=\"undetermined\">Not determined by these data</h2>\n<ul>\n<li>Where the robot stands and the scale are determined by the {} tracker positions: the robot's base in the tracker's frame is {}, {}, {} mm, roll {}, pitch {}, yaw {} deg (measurement setup; the controller's base is kept as given).</li>",
            t.positions,
            num(x, 4),
            num(y, 4),
            num(z, 4),
            num(roll, 5),
            num(pitch, 5),
            num(yaw, 5)
        )?;
        return parameter_items(page, report);
    }
    let scale = match &report.gauge {
        Some(g) => format!(
            "The scale rests on the known distance alone ({} mm +- {} mm): a short distance against the arm's reach, so lengths are determined only as well as it is.",
            num(g.mm, 3),
            num(g.sd_mm, 3)
        ),
        None => "<b>The scale is not determined</b>: without a known distance, the touches are as consistent with the arm uniformly larger or smaller; lengths are not certified.".to_string(),
    };
    let standing = match report.datums.is_empty() {
        true => {
            "Where the robot stands in the cell (its base frame): the sockets' positions are unknown and move with it. The controller's base is kept as given."
        }
        false => {
            "The controller's base, kept as given: the datum planes are given in its frame, and they see where the arm stands along their normals (joint 1's turn and lift are then left to the analysis below)."
        }
    };
    writeln!(
        page,
        "<h2 id=\"undetermined\">Not determined by these data</h2>\n<ul>\n<li>{standing}</li>\n<li>{scale}</li>"
    )?;
    parameter_items(page, report)
}

/// The parameters left free (with why), dropped and undetermined, as list items, and the end
/// of the list.
fn parameter_items(page: &mut String, report: &TouchReport) -> crate::Result<()> {
    for free in &report.identifiability.left_free {
        writeln!(
            page,
            "<li><code>{}</code>: left free, {}.</li>",
            esc(&free.parameter.to_string()),
            esc(&free.why)
        )?;
    }
    if !report.dropped.is_empty() {
        writeln!(
            page,
            "<li>Dropped as barely determined by these configurations, kept at nominal: <code>{}</code> (scaled condition number {} before, {} after).</li>",
            esc(&report.dropped.join(", ")),
            opt(report.identifiability.condition_number, 1),
            opt(report.identifiability.condition_number_after_drop, 1)
        )?;
    }
    for u in &report.identifiability.undetermined {
        writeln!(
            page,
            "<li><code>{}</code>: {}.</li>",
            esc(&u.parameter.to_string()),
            esc(&u.status)
        )?;
    }
    writeln!(page, "</ul>")?;
    Ok(())
}

/// The identified parameters with their standard errors.
fn parameters(page: &mut String, report: &TouchReport) -> crate::Result<()> {
    writeln!(
        page,
        "<h2 id=\"parameters\">Identified parameters</h2>\n<p class=\"note\">Errors from the nominal model, with their standard errors from the fit's covariance (the touches' scatter as the noise). <code>tool_t*</code> is the ball's offset: measurement setup, not written into the controller's tool.</p>\n<table>\n<tr><th>parameter</th><th>error</th><th>unit</th><th>standard error</th></tr>"
    )?;
    for (name, entry) in &report.parameters {
        writeln!(
            page,
            "<tr><td>{}</td><td>{:+.6e}</td><td>{}</td><td>{}</td></tr>",
            esc(name),
            entry.value,
            esc(&entry.unit),
            entry
                .std_error
                .map_or("-".to_string(), |s| format!("{s:.3e}"))
        )?;
    }
    writeln!(page, "</table>")?;
    Ok(())
}

/// The joints' torsion under gravity, when tried: whether it earned its place and the gains.
fn torsion(page: &mut String, report: &TouchReport) -> crate::Result<()> {
    let Some(t) = &report.torsion else {
        return Ok(());
    };
    let [geometry, with] = t.cross_validated_mm;
    let verdict = if t.kept {
        "kept: the identified model (and the controller, from the identified file's <code>[compliance]</code>) turns each joint by its gain times the gravity moment about its axis"
    } else {
        "not kept: the calibration is the geometry's alone, the gains below are not applied"
    };
    writeln!(
        page,
        "<h2 id=\"torsion\">Joints' torsion under gravity</h2>\n<p>Tried with the geometry and {verdict}. Left-out touches of the fitted placements ({} folds) predicted to {geometry:.4} mm by the geometry alone, {with:.4} mm with the torsions fitted; a torsion stays only when it predicts them better, and none is negative. Largest turn over the fitted touches {:.3} mrad; the controller's first-order deflection differs from the fitted turns by at most {:.4} mm there.</p>\n<table>\n<tr><th>joint</th><th>gain (urad per N m)</th><th>standard error</th></tr>",
        crate::calibration::torsion::FOLDS,
        t.largest_turn_mrad,
        t.controller_difference_mm
    )?;
    for (((joint, gain), se), fitted) in (t.joints.iter())
        .zip(&t.gains_urad_per_nm)
        .zip(&t.std_errors_urad_per_nm)
        .zip(&t.fitted)
    {
        let (gain, se) = match fitted {
            true => (
                format!("{gain:.1}"),
                se.map_or("-".to_string(), |s| format!("{s:.1}")),
            ),
            false => ("0 (not fitted)".to_string(), "-".to_string()),
        };
        writeln!(
            page,
            "<tr><td>{joint}</td><td>{gain}</td><td>{se}</td></tr>"
        )?;
    }
    writeln!(page, "</table>")?;
    Ok(())
}

/// The condition of the fit: rank, condition number, the least determined direction.
fn identifiability(page: &mut String, report: &TouchReport) -> crate::Result<()> {
    let id = &report.identifiability;
    let weakest: Vec<String> = (id.weakest_direction.iter())
        .map(|(p, c)| format!("{p} {c:+.2}"))
        .collect();
    writeln!(
        page,
        "<h2 id=\"identifiability\">Identifiability</h2>\n<table>\n<tr><td>parameters analysed</td><td>{}</td></tr>\n<tr><td>rank of the scaled Jacobian</td><td>{}</td></tr>\n<tr><td>scaled condition number</td><td>{}</td></tr>\n<tr><td>after dropping</td><td>{}</td></tr>\n<tr><td>least determined direction (before dropping)</td><td>{}</td></tr>\n<tr><td>residual standard deviation per coordinate</td><td>{} mm</td></tr>\n</table>",
        id.parameters,
        id.rank,
        opt(id.condition_number, 1),
        opt(id.condition_number_after_drop, 1),
        super::html::list(&weakest),
        num(report.least_squares.sigma_mm, 4)
    )?;
    Ok(())
}
