//! `calib report`: a calibration's JSON report (`calibrate --report`) rendered again, as the
//! self-contained HTML page of `calibrate --html` ([`host_tools::report::html`]), and printed to a PDF
//! ([`host_tools::report::pdf`]); a calibration from touches (`sockets --report`) as its
//! certificate ([`host_tools::report::touch_certificate`]).

use host_tools::io::outputs::Outputs;
use std::path::PathBuf;

/// Options of `calib report`.
#[derive(Clone, Debug, clap::Args)]
pub struct ReportOptions {
    /// The JSON report of a calibration (calib calibrate --report or calib sockets --report).
    #[arg(long, value_name = "FILE")]
    pub from: PathBuf,
    /// The HTML page to write.
    #[arg(long, value_name = "FILE", required_unless_present = "pdf")]
    pub html: Option<PathBuf>,
    /// The page printed to a PDF on A4 (needs a headless Chromium: chromium, chromium-browser or
    /// google-chrome).
    #[arg(long, value_name = "FILE")]
    pub pdf: Option<PathBuf>,
    /// An ISO 9283 pose test of the calibrated robot (calib iso9283 evaluate --report), shown
    /// after the held-out accuracy (tracker calibrations).
    #[arg(long, value_name = "FILE")]
    pub pose_test: Option<PathBuf>,
    /// The job (TOML: certificate, customer, site, cell, operator, measured_on, approver): under
    /// the title, in every printed page's header, and the approval's signature lines (tracker
    /// calibrations and calibrations from touches).
    #[arg(long, value_name = "FILE")]
    pub job: Option<PathBuf>,
}

/// Runs `calib report`: writes the HTML page and/or the PDF asked for, all or nothing.
pub fn report(options: &ReportOptions) -> anyhow::Result<()> {
    let pose_test = match &options.pose_test {
        Some(path) => Some(pose_test_of(path)?),
        None => None,
    };
    let job = match &options.job {
        Some(path) => Some(host_tools::report::job::Job::read(path)?),
        None => None,
    };
    let additions = host_tools::report::html::Additions {
        pose_test: pose_test.as_ref(),
        job: job.as_ref(),
    };
    let page = page(&options.from, additions)?;
    let pdf = match &options.pdf {
        Some(_) => Some(host_tools::report::pdf::print(&page)?),
        None => None,
    };
    let mut inputs = vec![("--from", options.from.as_path())];
    if let Some(path) = &options.pose_test {
        inputs.push(("--pose-test", path.as_path()));
    }
    if let Some(path) = &options.job {
        inputs.push(("--job", path.as_path()));
    }
    let mut outputs = Outputs::new(&inputs);
    if let Some(path) = &options.html {
        outputs.stage("--html", path, page.as_bytes())?;
    }
    if let (Some(path), Some(bytes)) = (&options.pdf, &pdf) {
        outputs.stage("--pdf", path, bytes)?;
    }
    outputs.commit()?;
    Ok(())
}

/// The page of the report at `from`: a tracker calibration's report, or a calibration from
/// touches' certificate (a report naming `fitted_placements`, refused with that kind's message).
fn page(
    from: &std::path::Path,
    additions: host_tools::report::html::Additions<'_>,
) -> anyhow::Result<String> {
    use host_tools::report::{html, touch_certificate};
    let rendering = html::Rendering::now();
    match host_tools::calibration::Report::read(from) {
        Ok(report) => Ok(html::render_with(&report, &rendering, additions)?),
        Err(tracker) => {
            let bytes = host_tools::io::input::read(from, host_tools::io::input::Input::Data)?;
            if !String::from_utf8_lossy(&bytes).contains("\"fitted_placements\"") {
                return Err(tracker.into());
            }
            if additions.pose_test.is_some() {
                anyhow::bail!(
                    "--pose-test: {} is a calibration from touches, whose certificate states consistency, not the accuracy a pose test measures; render the pose test with the tracker calibration it belongs to, or drop --pose-test",
                    from.display()
                );
            }
            let report = host_tools::calibration::touches::TouchReport::read(from)?;
            Ok(touch_certificate::render_with(
                &report,
                &rendering,
                additions.job,
            )?)
        }
    }
}

/// The pose test saved at `path` (calib iso9283 evaluate --report).
fn pose_test_of(path: &std::path::Path) -> anyhow::Result<host_tools::pose_test::PoseTest> {
    let bytes = host_tools::io::input::read(path, host_tools::io::input::Input::Data)
        .map_err(|e| anyhow::anyhow!("--pose-test {}: {e}", path.display()))?;
    serde_json::from_slice(&bytes).map_err(|e| {
        anyhow::anyhow!(
            "--pose-test {}: not the JSON of calib iso9283 evaluate --report ({e})",
            path.display()
        )
    })
}
