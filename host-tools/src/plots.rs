//! Plots of a calibration (SVG and PNG): the convergence curve of the swarm (paper Fig. 2) and the
//! absolute position error of every pose before and after calibration (paper Fig. 3 / Fig. 7).
//! Text is drawn with the bundled DejaVu Sans font, so PNGs need no system fonts.

use anyhow::{Context, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Once;

const FONT: &str = "sans-serif";
const SIZE: (u32, u32) = (900, 560);

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bundled font is valid; if registering ever failed, text would be missing, not wrong.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
    });
}

/// Draws the convergence curve: best objective (log scale) against generation.
fn convergence<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    history: &[(u32, f64)],
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let last = history.last().map_or(1, |h| h.0).max(1);
    let positive: Vec<f64> = history
        .iter()
        .map(|h| h.1)
        .filter(|v| *v > 0.0 && v.is_finite())
        .collect();
    let lo = positive
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
        .max(1e-300);
    let hi = positive.iter().copied().fold(0.0, f64::max).max(lo * 10.0);
    let mut chart = ChartBuilder::on(area)
        .caption("IPSO convergence (eq. 7)", (FONT, 24))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(0u32..last, (lo / 2.0..hi * 2.0).log_scale())
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc("generation")
        .y_desc("best objective f")
        .label_style((FONT, 14))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .draw_series(LineSeries::new(
            history
                .iter()
                .filter(|h| h.1 > 0.0 && h.1.is_finite())
                .map(|h| (h.0, h.1)),
            BLUE.stroke_width(2),
        ))
        .map_err(|e| anyhow!("{e}"))?;
    area.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// Draws the absolute position error per pose before and after.
fn position_errors<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    before: &[f64],
    after: &[f64],
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    area.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let n = before.len().max(after.len()).max(1);
    let hi = before
        .iter()
        .chain(after)
        .copied()
        .fold(0.0, f64::max)
        .max(1e-9)
        * 1.1;
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 24))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(0.5f64..n as f64 + 0.5, 0.0..hi)
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc("pose")
        .y_desc("absolute position error |dp| (mm)")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .label_style((FONT, 14))
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    let series = [
        (before, RED, "before calibration"),
        (after, BLUE, "after calibration"),
    ];
    for (values, color, label) in series {
        let points: Vec<(f64, f64)> = values
            .iter()
            .enumerate()
            .map(|(i, v)| ((i + 1) as f64, *v))
            .collect();
        chart
            .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))
            .map_err(|e| anyhow!("{e}"))?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart
            .draw_series(points.iter().map(|p| Circle::new(*p, 3, color.filled())))
            .map_err(|e| anyhow!("{e}"))?;
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    area.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// Writes `convergence.svg/.png` and `position-error.svg/.png` into `dir`; returns the paths.
/// Each file is drawn into a temporary name and renamed, so no half-drawn plot is left behind.
pub fn write_plots(
    dir: &Path,
    history: &[(u32, f64)],
    title: &str,
    before: &[f64],
    after: &[f64],
) -> anyhow::Result<Vec<PathBuf>> {
    register_font();
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut written = Vec::new();
    let mut finish = |name: &str, temporary: PathBuf| -> anyhow::Result<()> {
        let path = dir.join(name);
        std::fs::rename(&temporary, &path)
            .with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
        Ok(())
    };
    // The bitmap backend picks its format from the extension, so it stays last.
    let tmp = |name: &str| dir.join(format!(".tmp-{}-{name}", std::process::id()));

    let t = tmp("convergence.svg");
    convergence(&SVGBackend::new(&t, SIZE).into_drawing_area(), history)?;
    finish("convergence.svg", t)?;
    let t = tmp("convergence.png");
    convergence(&BitMapBackend::new(&t, SIZE).into_drawing_area(), history)?;
    finish("convergence.png", t)?;
    let t = tmp("position-error.svg");
    position_errors(
        &SVGBackend::new(&t, SIZE).into_drawing_area(),
        title,
        before,
        after,
    )?;
    finish("position-error.svg", t)?;
    let t = tmp("position-error.png");
    position_errors(
        &BitMapBackend::new(&t, SIZE).into_drawing_area(),
        title,
        before,
        after,
    )?;
    finish("position-error.png", t)?;
    Ok(written)
}
