//! Plots of a calibration (SVG and PNG): the convergence curve of the swarm (paper Fig. 2), the
//! absolute position error of every pose before and after calibration (paper Fig. 3 / Fig. 7),
//! the orientation error per axis (each pose a point at its data file line, never joined to
//! unrelated poses), a histogram of the validation errors and the held-out error over the
//! workspace (measured and predicted, top and side views).
//! Text is drawn with the bundled DejaVu Sans font, so PNGs need no system fonts.

use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

pub(crate) const FONT: &str = "sans-serif";
const SIZE: (u32, u32) = (900, 560);

pub(crate) fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bundled font is valid; if registering ever failed, text would be missing, not wrong.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
    });
}

/// The most decades a log-scale axis spans: a report's values beyond them (a hand-edited or
/// corrupted JSON's zero, 1e-300 or 1e300) are drawn at the axis' foot instead of making the
/// axis, and its labels, without end.
const LOG_DECADES: f64 = 12.0;

/// The range of a log-scale axis over the positive finite `values`: from the smallest to the
/// largest, one decade at least and at most [`LOG_DECADES`] below the largest; 1 to 10 when no
/// value is positive and finite.
fn log_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let positive: Vec<f64> = values.filter(|v| *v > 0.0 && v.is_finite()).collect();
    if positive.is_empty() {
        return (1.0, 10.0);
    }
    let lo = positive.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = positive
        .iter()
        .copied()
        .fold(0.0, f64::max)
        .min(1e300)
        .max(lo * 10.0);
    (lo.max(hi / 10f64.powf(LOG_DECADES)), hi)
}

/// The largest finite value of `values` for a linear axis from zero (at least 1e-9, at most
/// 1e300, so that the axis has a finite, non-empty range).
fn finite_max(values: impl Iterator<Item = f64>) -> f64 {
    values
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max)
        .clamp(1e-9, 1e300)
}

/// Draws the convergence curve: best objective (log scale) against generation.
fn convergence<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    history: &[(u32, f64)],
) -> crate::Result<()>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE).map_err(crate::Error::plot)?;
    let last = history.last().map_or(1, |h| h.0).max(1);
    let (lo, hi) = log_range(history.iter().map(|h| h.1));
    let mut chart = ChartBuilder::on(area)
        .caption("IPSO convergence (eq. 7)", (FONT, 24))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(0u32..last, (lo / 2.0..hi * 2.0).log_scale())
        .map_err(crate::Error::plot)?;
    chart
        .configure_mesh()
        .x_desc("generation")
        .y_desc("best objective f")
        .label_style((FONT, 14))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(crate::Error::plot)?;
    chart
        .draw_series(LineSeries::new(
            history
                .iter()
                .filter(|h| h.1 > 0.0 && h.1.is_finite())
                .map(|h| (h.0, h.1)),
            BLUE.stroke_width(2),
        ))
        .map_err(crate::Error::plot)?;
    area.present().map_err(crate::Error::plot)?;
    Ok(())
}

/// The x value of each of `n` poses: its data file line from `lines` when there is one per
/// pose, else its 1-based position; and the axis' name.
fn pose_positions(lines: &[u64], n: usize) -> (Vec<f64>, &'static str) {
    if lines.len() == n && n > 0 {
        (lines.iter().map(|l| *l as f64).collect(), "data file line")
    } else {
        ((1..=n).map(|i| i as f64).collect(), "pose")
    }
}

/// Poses labelled with their line in a per-pose plot: the largest values after calibration.
const LABELLED: usize = 3;

/// Draws values per pose as unconnected points at each pose's data file line (`lines`), before
/// (red) and after (blue), the [`LABELLED`] largest after-values labelled with their line.
fn per_pose<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (title, y_desc): (&str, &str),
    lines: &[u64],
    before: &[f64],
    after: &[f64],
) -> crate::Result<()>
where
    DB::ErrorType: 'static,
{
    let n = before.len().max(after.len());
    let (x, x_desc) = pose_positions(lines, n);
    let lo = x.iter().copied().fold(f64::INFINITY, f64::min).min(1.0);
    let x_hi = x.iter().copied().fold(1.0, f64::max);
    let pad = ((x_hi - lo) * 0.02).max(0.5);
    let hi = finite_max(before.iter().chain(after).copied()) * 1.15;
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(lo - pad..x_hi + pad, 0.0..hi)
        .map_err(crate::Error::plot)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&|v| format!("{v:.0}"))
        .label_style((FONT, 14))
        .draw()
        .map_err(crate::Error::plot)?;
    let series = [
        (before, RED, "before calibration"),
        (after, BLUE, "after calibration"),
    ];
    for (values, color, label) in series {
        let points: Vec<(f64, f64)> = x.iter().copied().zip(values.iter().copied()).collect();
        chart
            .draw_series(points.iter().map(|p| Circle::new(*p, 3, color.filled())))
            .map_err(crate::Error::plot)?
            .label(label)
            .legend(move |(x, y)| Circle::new((x + 10, y), 3, color.filled()));
    }
    if x_desc == "data file line" {
        let mut largest: Vec<(f64, f64)> = x.iter().copied().zip(after.iter().copied()).collect();
        largest.sort_by(|a, b| b.1.total_cmp(&a.1));
        largest.truncate(LABELLED);
        chart
            .draw_series(largest.iter().map(|(line, value)| {
                Text::new(
                    format!("line {line:.0}"),
                    (*line, *value + hi * 0.02),
                    (FONT, 13).into_font().color(&BLUE),
                )
            }))
            .map_err(crate::Error::plot)?;
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(crate::Error::plot)?;
    Ok(())
}

/// Draws the absolute position error per pose before and after.
fn position_errors<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    plots: &PlotData<'_>,
) -> crate::Result<()>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE).map_err(crate::Error::plot)?;
    per_pose(
        area,
        (plots.title, "absolute position error |dp| (mm)"),
        plots.lines,
        plots.before,
        plots.after,
    )?;
    area.present().map_err(crate::Error::plot)?;
    Ok(())
}

/// Draws the orientation error per axis (three panels) before and after.
fn orientation_errors<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    lines: &[u64],
    before: &[[f64; 3]],
    after: &[[f64; 3]],
) -> crate::Result<()>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE).map_err(crate::Error::plot)?;
    for (axis, panel) in area.split_evenly((3, 1)).iter().enumerate() {
        let pick = |v: &[[f64; 3]]| -> Vec<f64> { v.iter().map(|e| e[axis]).collect() };
        let name = ["x", "y", "z"][axis];
        per_pose(
            panel,
            (
                &format!("orientation error about {name} per calibration pose"),
                &format!("|dr_{name}| (deg)"),
            ),
            lines,
            &pick(before),
            &pick(after),
        )?;
    }
    area.present().map_err(crate::Error::plot)?;
    Ok(())
}

/// A colour from blue (0) to red (`t` = 1) for a value's share `t` of the largest.
fn heat(t: f64) -> HSLColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        1.0
    };
    HSLColor(0.66 * (1.0 - t), 0.9, 0.45)
}

/// Draws the held-out poses at their base-frame positions coloured by `values` (blue 0 to red
/// at the largest): a top view (x, y) and a side view (x, z) side by side in `area`.
fn workspace_views<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    what: &str,
    positions: &[[f64; 3]],
    values: &[f64],
) -> crate::Result<()>
where
    DB::ErrorType: 'static,
{
    let hi = finite_max(values.iter().copied());
    // The largest values drawn last, on top.
    let mut order: Vec<usize> = (0..positions.len().min(values.len())).collect();
    order.sort_by(|a, b| values[*a].total_cmp(&values[*b]));
    let range = |axis: usize| {
        let (lo, hi) = positions
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |r, p| {
                (r.0.min(p[axis]), r.1.max(p[axis]))
            });
        let pad = ((hi - lo) * 0.05).max(1.0);
        if lo.is_finite() && hi.is_finite() {
            lo - pad..hi + pad
        } else {
            -1.0..1.0
        }
    };
    for (panel, (vertical, view)) in area
        .split_evenly((1, 2))
        .iter()
        .zip([(1, "top view"), (2, "side view")])
    {
        let name = ["x", "y", "z"][vertical];
        let mut chart = ChartBuilder::on(panel)
            .caption(format!("{what}, {view}"), (FONT, 17))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(range(0), range(vertical))
            .map_err(crate::Error::plot)?;
        chart
            .configure_mesh()
            .x_desc("x, base frame (mm)")
            .y_desc(format!("{name}, base frame (mm)"))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .label_style((FONT, 13))
            .draw()
            .map_err(crate::Error::plot)?;
        chart
            .draw_series(order.iter().map(|i| {
                let p = positions[*i];
                Circle::new((p[0], p[vertical]), 3, heat(values[*i] / hi).filled())
            }))
            .map_err(crate::Error::plot)?;
    }
    Ok(())
}

/// Draws the held-out error over the workspace: the measured error after calibration and, when
/// known, the error the parameters' covariance predicts, each in a top and a side view.
fn workspace<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    plots: &PlotData<'_>,
) -> crate::Result<()>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE).map_err(crate::Error::plot)?;
    let scale = |values: &[f64]| {
        format!(
            "(blue 0 to red {:.3} mm)",
            finite_max(values.iter().copied())
        )
    };
    let measured = format!(
        "held-out |dp| after calibration {}",
        scale(plots.validation_after)
    );
    let predicted = format!("predicted RMS error {}", scale(plots.validation_predicted));
    if plots.validation_predicted.len() == plots.validation_positions.len() {
        let rows = area.split_evenly((2, 1));
        workspace_views(
            &rows[0],
            &measured,
            plots.validation_positions,
            plots.validation_after,
        )?;
        workspace_views(
            &rows[1],
            &predicted,
            plots.validation_positions,
            plots.validation_predicted,
        )?;
    } else {
        workspace_views(
            area,
            &measured,
            plots.validation_positions,
            plots.validation_after,
        )?;
    }
    area.present().map_err(crate::Error::plot)?;
    Ok(())
}

/// Draws a histogram of the validation position errors before and after.
fn histogram<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    before: &[f64],
    after: &[f64],
) -> crate::Result<()>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE).map_err(crate::Error::plot)?;
    const BINS: usize = 25;
    let panels = area.split_evenly((2, 1));
    for (panel, (values, color, label)) in panels.iter().zip([
        (after, BLUE, "after calibration"),
        (before, RED, "before calibration (nominal geometry)"),
    ]) {
        let hi = finite_max(values.iter().copied()) * 1.0001;
        let width = hi / BINS as f64;
        let mut counts = [0u32; BINS];
        for v in values {
            let bin = ((v / width) as usize).min(BINS - 1);
            if let Some(c) = counts.get_mut(bin) {
                *c += 1;
            }
        }
        let top = counts.iter().copied().max().unwrap_or(1).max(1);
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!(
                    "validation poses, {label}: |dp| histogram ({} poses)",
                    values.len()
                ),
                (FONT, 18),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..hi, 0u32..top + top / 10 + 1)
            .map_err(crate::Error::plot)?;
        chart
            .configure_mesh()
            .x_desc("absolute position error |dp| (mm)")
            .y_desc("poses")
            .label_style((FONT, 14))
            .draw()
            .map_err(crate::Error::plot)?;
        chart
            .draw_series(counts.iter().enumerate().map(|(i, c)| {
                let x0 = i as f64 * width;
                Rectangle::new([(x0, 0), (x0 + width, *c)], color.mix(0.7).filled())
            }))
            .map_err(crate::Error::plot)?;
    }
    area.present().map_err(crate::Error::plot)?;
    Ok(())
}

/// Draws each joint's identified angle-error map (posterior mean, mrad) over one turn with its
/// 95 % band (+-2 posterior standard deviations) and the calibration readings as ticks: outside
/// them the map is extrapolated (and the band widens to the prior).
fn joint_maps<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    curves: &[crate::calibration::maps::MapCurve],
) -> crate::Result<()>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE).map_err(crate::Error::plot)?;
    let panels = area.split_evenly((3, 2));
    for (panel, curve) in panels.iter().zip(curves) {
        let extent = curve
            .mean_mrad
            .iter()
            .zip(&curve.sd_mrad)
            .map(|(m, s)| m.abs() + 2.0 * s)
            .fold(0.0, f64::max)
            .max(0.05)
            * 1.1;
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!("joint {}: angle error (mean, 95 % band)", curve.joint),
                (FONT, 16),
            )
            .margin(8)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(-180.0..180.0, -extent..extent)
            .map_err(crate::Error::plot)?;
        chart
            .configure_mesh()
            .x_desc("joint reading (deg)")
            .y_desc("dq (mrad)")
            .max_light_lines(1)
            .label_style((FONT, 12))
            .draw()
            .map_err(crate::Error::plot)?;
        let band: Vec<(f64, f64)> = curve
            .q_deg
            .iter()
            .zip(curve.mean_mrad.iter().zip(&curve.sd_mrad))
            .map(|(q, (m, s))| (*q, m + 2.0 * s))
            .chain(
                curve
                    .q_deg
                    .iter()
                    .zip(curve.mean_mrad.iter().zip(&curve.sd_mrad))
                    .rev()
                    .map(|(q, (m, s))| (*q, m - 2.0 * s)),
            )
            .collect();
        chart
            .draw_series(std::iter::once(Polygon::new(band, BLUE.mix(0.2).filled())))
            .map_err(crate::Error::plot)?;
        chart
            .draw_series(LineSeries::new(
                curve
                    .q_deg
                    .iter()
                    .copied()
                    .zip(curve.mean_mrad.iter().copied()),
                BLUE.stroke_width(2),
            ))
            .map_err(crate::Error::plot)?;
        // The calibration readings, wrapped into one turn, as ticks at the bottom.
        let tick = extent * 0.08;
        chart
            .draw_series(curve.readings_deg.iter().map(|q| {
                let q = (q + 180.0).rem_euclid(360.0) - 180.0;
                PathElement::new(vec![(q, -extent), (q, -extent + tick)], RED)
            }))
            .map_err(crate::Error::plot)?;
    }
    area.present().map_err(crate::Error::plot)?;
    Ok(())
}

/// What to plot for one calibration.
pub(crate) struct PlotData<'a> {
    /// Swarm convergence `(generation, best objective)`; empty without the swarm.
    pub history: &'a [(u32, f64)],
    /// Title of the position error plot.
    pub title: &'a str,
    /// The data file's line of each calibration pose (empty: poses are numbered).
    pub lines: &'a [u64],
    /// The data file's line of each calibration pose with an orientation.
    pub orientation_lines: &'a [u64],
    /// `|dp|` per calibration pose before and after, mm.
    pub before: &'a [f64],
    /// After calibration.
    pub after: &'a [f64],
    /// `|dr_x|, |dr_y|, |dr_z|` per calibration pose before and after, deg (empty for
    /// position-only data).
    pub orientation_before: &'a [[f64; 3]],
    /// After calibration.
    pub orientation_after: &'a [[f64; 3]],
    /// `|dp|` per validation pose before and after, mm (empty without validation).
    pub validation_before: &'a [f64],
    /// After calibration.
    pub validation_after: &'a [f64],
    /// The base-frame position of each validation pose, mm (empty: no workspace map).
    pub validation_positions: &'a [[f64; 3]],
    /// The predicted RMS error at each validation pose, mm (empty without a covariance).
    pub validation_predicted: &'a [f64],
    /// The identified joint maps (empty for a geometric calibration).
    pub joint_maps: &'a [crate::calibration::maps::MapCurve],
}

impl<'a> PlotData<'a> {
    /// The plots of a calibration's per-pose errors `p`, with the swarm's convergence `history`
    /// (empty without the swarm) and the identified `joint_maps` (empty without maps).
    pub(crate) fn of_poses(
        p: &'a crate::calibration::PerPose,
        history: &'a [(u32, f64)],
        joint_maps: &'a [crate::calibration::maps::MapCurve],
    ) -> Self {
        Self {
            history,
            title: "absolute position error per calibration pose",
            lines: &p.lines,
            orientation_lines: &p.orientation_lines,
            before: &p.before,
            after: &p.after,
            orientation_before: &p.orientation_before,
            orientation_after: &p.orientation_after,
            validation_before: &p.validation_before,
            validation_after: &p.validation_after,
            validation_positions: &p.validation_position_mm,
            validation_predicted: &p.validation_predicted_rms_mm,
            joint_maps,
        }
    }

    /// `true` when the validation poses have positions to map.
    fn has_workspace(&self) -> bool {
        !self.validation_positions.is_empty()
            && self.validation_positions.len() == self.validation_after.len()
    }
}

/// Stages the plots of the calibration `calibrated` into `dir`, each as SVG and PNG: the swarm's
/// convergence, the position and orientation errors per pose, the held-out histogram and
/// workspace map, the joint maps (those the calibration has). The files are written when
/// `outputs` is committed: what `calib calibrate --plot DIR` writes.
pub fn stage_calibration(
    outputs: &mut crate::io::outputs::Outputs,
    dir: &Path,
    calibrated: &crate::calibration::Calibrated,
) -> crate::Result<()> {
    let result = &calibrated.result;
    let history = (result.swarm.as_ref()).map_or(&[][..], |s| s.history.as_slice());
    let joint_maps = (result.joint_maps.as_ref()).map_or(&[][..], |m| m.curves.as_slice());
    let plots = PlotData::of_poses(&result.per_pose, history, joint_maps);
    stage_plots(outputs, dir, &plots)
}

/// Stages into `dir` (see [`crate::io::outputs::Outputs`]), each as SVG and PNG: `convergence` (with
/// the swarm), `position-error`, `orientation-error` (with orientation data) and
/// `validation-histogram` and `workspace-error` (with validation poses) and `joint-maps` (with joint maps). Nothing is replaced until the outputs are
/// committed.
pub(crate) fn stage_plots(
    outputs: &mut crate::io::outputs::Outputs,
    dir: &Path,
    plots: &PlotData<'_>,
) -> crate::Result<()> {
    register_font();
    // Both drawn in memory and staged as bytes: every byte goes through the output's
    // exclusively created temporary (a drawing backend that opens a path of its own would follow
    // a link planted at that name).
    macro_rules! both {
        ($name:literal, $size:expr, |$area:ident| $draw:expr) => {{
            let mut svg = String::new();
            {
                let $area = SVGBackend::with_string(&mut svg, $size).into_drawing_area();
                $draw?;
                $area.present().map_err(crate::Error::plot)?;
            }
            outputs.stage("--plot", &dir.join(concat!($name, ".svg")), svg.as_bytes())?;
            let (width, height) = $size;
            let mut rgb = vec![0u8; width as usize * height as usize * 3];
            {
                let $area = BitMapBackend::with_buffer(&mut rgb, $size).into_drawing_area();
                $draw?;
                $area.present().map_err(crate::Error::plot)?;
            }
            let png = png_bytes(&rgb, $size)?;
            outputs.stage("--plot", &dir.join(concat!($name, ".png")), &png)?;
        }};
    }
    if !plots.history.is_empty() {
        both!("convergence", SIZE, |area| convergence(
            &area,
            plots.history
        ));
    }
    both!("position-error", SIZE, |area| position_errors(&area, plots));
    if !plots.orientation_after.is_empty() {
        both!("orientation-error", (SIZE.0, SIZE.1 * 2), |area| {
            orientation_errors(
                &area,
                plots.orientation_lines,
                plots.orientation_before,
                plots.orientation_after,
            )
        });
    }
    if !plots.joint_maps.is_empty() {
        both!("joint-maps", (SIZE.0, SIZE.1 * 2), |area| joint_maps(
            &area,
            plots.joint_maps
        ));
    }
    if !plots.validation_after.is_empty() {
        both!("validation-histogram", SIZE, |area| histogram(
            &area,
            plots.validation_before,
            plots.validation_after
        ));
    }
    if plots.has_workspace() {
        both!("workspace-error", (SIZE.0 + 300, SIZE.1 * 2), |area| {
            workspace(&area, plots)
        });
    }
    Ok(())
}

/// The plots of [`stage_plots`] as SVG text, for a self-contained page
/// ([`crate::report::html`]): `(name, caption, svg)` for each plot the data allow.
pub(crate) fn svg_plots(
    plots: &PlotData<'_>,
) -> crate::Result<Vec<(&'static str, &'static str, String)>> {
    register_font();
    let mut out = Vec::new();
    let mut draw = |name: &'static str,
                    caption: &'static str,
                    size: (u32, u32),
                    f: &dyn Fn(&DrawingArea<SVGBackend<'_>, Shift>) -> crate::Result<()>|
     -> crate::Result<()> {
        let mut svg = String::new();
        {
            let area = SVGBackend::with_string(&mut svg, size).into_drawing_area();
            f(&area)?;
            area.present().map_err(crate::Error::plot)?;
        }
        out.push((name, caption, svg));
        Ok(())
    };
    if !plots.before.is_empty() {
        draw(
            "position-error",
            "Absolute position error of every calibration pose, nominal and identified model.",
            SIZE,
            &|area| position_errors(area, plots),
        )?;
    }
    if !plots.orientation_after.is_empty() {
        draw(
            "orientation-error",
            "Orientation error per axis of every calibration pose.",
            (SIZE.0, SIZE.1 * 2),
            &|area| {
                orientation_errors(
                    area,
                    plots.orientation_lines,
                    plots.orientation_before,
                    plots.orientation_after,
                )
            },
        )?;
    }
    if !plots.history.is_empty() {
        draw(
            "convergence",
            "Convergence of the particle swarm: best objective per generation.",
            SIZE,
            &|area| convergence(area, plots.history),
        )?;
    }
    if !plots.validation_after.is_empty() {
        draw(
            "validation-histogram",
            "Position errors of the held-out validation poses, nominal and identified model.",
            SIZE,
            &|area| histogram(area, plots.validation_before, plots.validation_after),
        )?;
    }
    if plots.has_workspace() {
        draw(
            "workspace-error",
            "Held-out poses over the workspace, seen from above and from the side: the measured error after calibration and the error the parameters' covariance predicts.",
            (SIZE.0 + 300, SIZE.1 * 2),
            &|area| workspace(area, plots),
        )?;
    }
    Ok(out)
}

/// An RGB image of `size` (width, height, pixels) encoded as PNG, in memory.
fn png_bytes(rgb: &[u8], (width, height): (u32, u32)) -> crate::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder
        .write_header()
        .map_err(|e| crate::Error::plot(e.to_string()))?;
    writer
        .write_image_data(rgb)
        .map_err(|e| crate::Error::plot(e.to_string()))?;
    writer
        .finish()
        .map_err(|e| crate::Error::plot(e.to_string()))?;
    Ok(bytes)
}
