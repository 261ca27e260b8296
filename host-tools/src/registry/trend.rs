//! One robot over time (`calib registry trend`, issue 55 item 2): its calibrations' held-out
//! figures and its shift checks' mean errors against the date, with the drift rate's line
//! through the checks of the latest calibration checked, as one SVG (the values take the lower
//! part of the plot, the legend its top left).

use super::record::Summary;
use super::shift::{CheckSummary, DriftRate};
use crate::report::plots::{FONT, register_font};
use plotters::prelude::*;

const SIZE: (u32, u32) = (900, 520);

/// Days since the Unix epoch of an RFC 3339 time; `None` when it is not one.
fn day_of(time: &str) -> Option<f64> {
    let t = humantime::parse_rfc3339_weak(time).ok()?;
    Some(t.duration_since(std::time::UNIX_EPOCH).ok()?.as_secs_f64() / 86_400.0)
}

/// The SVG of robot `serial`'s `calibrations` and `checks` (each at its date; those without one
/// are left out, and said in the caption), with `rate` drawn through its checks. Refused: nothing
/// dated to draw.
pub fn svg(
    serial: &str,
    calibrations: &[Summary],
    checks: &[CheckSummary],
    rate: Option<&DriftRate>,
) -> crate::Result<String> {
    let calibrated: Vec<(f64, f64)> = (calibrations.iter())
        .filter_map(|c| Some((day_of(&c.calibrated_at)?, c.held_out_mm?)))
        .collect();
    let checked: Vec<(f64, f64, bool)> = (checks.iter())
        .filter_map(|c| Some((day_of(&c.checked_at)?, c.mean_mm, c.drifted)))
        .collect();
    let (first, last, top) = extent(&calibrated, &checked).ok_or_else(|| {
        crate::refused!(option "--serial";
            "robot {serial}: no dated calibration with a held-out figure and no shift check to plot")
    })?;
    let left_out = calibrations.len() + checks.len() - calibrated.len() - checked.len();
    let span = (last - first).max(1.0);
    let x = |day: f64| day - first;
    register_font();
    let mut text = String::new();
    {
        let area = SVGBackend::with_string(&mut text, SIZE).into_drawing_area();
        area.fill(&WHITE).map_err(crate::Error::plot)?;
        let mut chart = ChartBuilder::on(&area)
            .caption(caption(serial, left_out), (FONT, 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.05 * span..span * 1.05, 0.0..top)
            .map_err(crate::Error::plot)?;
        let since = humantime::format_rfc3339_seconds(
            std::time::UNIX_EPOCH + std::time::Duration::from_secs_f64(first.max(0.0) * 86_400.0),
        );
        chart
            .configure_mesh()
            .x_desc(format!("days since {since}"))
            .y_desc("mm")
            .label_style((FONT, 14))
            .draw()
            .map_err(crate::Error::plot)?;
        chart
            .draw_series(
                calibrated
                    .iter()
                    .map(|(d, v)| Circle::new((x(*d), *v), 6, BLUE.filled())),
            )
            .map_err(crate::Error::plot)?
            .label("calibration: held-out figure (median after; touches: consistency)")
            .legend(|(a, b)| Circle::new((a + 10, b), 5, BLUE.filled()));
        chart
            .draw_series(checked.iter().map(|(d, v, drifted)| {
                let colour = if *drifted { RED } else { GREEN };
                TriangleMarker::new((x(*d), *v), 6, colour.filled())
            }))
            .map_err(crate::Error::plot)?
            .label("shift check: mean error (red: drift)")
            .legend(|(a, b)| TriangleMarker::new((a + 10, b), 5, GREEN.filled()));
        if let Some(rate) = rate {
            let line = drift_line(checks, rate).map(|(d, v)| (x(d), v));
            chart
                .draw_series(LineSeries::new(line, RED.stroke_width(2)))
                .map_err(crate::Error::plot)?
                .label(format!("drift: {:+.4} mm per 30 days", rate.mm_per_30_days))
                .legend(|(a, b)| PathElement::new([(a, b), (a + 20, b)], RED.stroke_width(2)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FONT, 14))
            .draw()
            .map_err(crate::Error::plot)?;
        area.present().map_err(crate::Error::plot)?;
    }
    Ok(text)
}

/// The ends of the drift rate's line (day, mm) over the checks it was fitted to: through their
/// mean, at the rate's slope.
fn drift_line(checks: &[CheckSummary], rate: &DriftRate) -> [(f64, f64); 2] {
    let on_line: Vec<(f64, f64)> = (checks.iter())
        .filter(|c| c.calibration == rate.calibration)
        .filter_map(|c| Some((day_of(&c.checked_at)?, c.mean_mm)))
        .collect();
    let n = on_line.len().max(1) as f64;
    let (mt, my) = (
        on_line.iter().map(|p| p.0).sum::<f64>() / n,
        on_line.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let slope = rate.mm_per_30_days / 30.0;
    let (first, last) = (on_line.iter().map(|p| p.0))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), d| {
            (a.min(d), b.max(d))
        });
    [first, last].map(|d| (d, my + slope * (d - mt)))
}

/// The caption: the robot, and what was left out.
fn caption(serial: &str, left_out: usize) -> String {
    format!(
        "robot {serial}: calibrations and shift checks{}",
        if left_out > 0 {
            format!(" ({left_out} without a date or held-out figure, not drawn)")
        } else {
            String::new()
        }
    )
}

/// The first and last day and the top of the value axis (room above the values for the legend);
/// `None` with nothing to draw.
fn extent(calibrated: &[(f64, f64)], checked: &[(f64, f64, bool)]) -> Option<(f64, f64, f64)> {
    let days = (calibrated.iter().map(|p| p.0)).chain(checked.iter().map(|p| p.0));
    let (first, last) = days.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), d| {
        (a.min(d), b.max(d))
    });
    let top = (calibrated.iter().map(|p| p.1))
        .chain(checked.iter().map(|p| p.1))
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max)
        .clamp(1e-6, 1e6)
        * 1.6;
    first.is_finite().then_some((first, last, top))
}
