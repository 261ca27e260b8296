//! `calib report`: a calibration's JSON report (`calibrate --report`) rendered again, as the
//! self-contained HTML page of `calibrate --html` ([`host_tools::report::html`]), and printed to a PDF
//! ([`host_tools::report::pdf`]).

use host_tools::io::outputs::Outputs;
use std::path::PathBuf;

/// Options of `calib report`.
#[derive(Clone, Debug, clap::Args)]
pub struct ReportOptions {
    /// The JSON report of a calibration (calib calibrate --report).
    #[arg(long, value_name = "FILE")]
    pub from: PathBuf,
    /// The HTML page to write.
    #[arg(long, value_name = "FILE", required_unless_present = "pdf")]
    pub html: Option<PathBuf>,
    /// The page printed to a PDF on A4 (needs a headless Chromium: chromium, chromium-browser or
    /// google-chrome).
    #[arg(long, value_name = "FILE")]
    pub pdf: Option<PathBuf>,
}

/// Runs `calib report`: writes the HTML page and/or the PDF asked for, all or nothing.
pub fn report(options: &ReportOptions) -> anyhow::Result<()> {
    let report = host_tools::calibration::Report::read(&options.from)?;
    let page =
        host_tools::report::html::render(&report, &host_tools::report::html::Rendering::now())?;
    let pdf = match &options.pdf {
        Some(_) => Some(host_tools::report::pdf::print(&page)?),
        None => None,
    };
    let mut outputs = Outputs::new(&[("--from", &options.from)]);
    if let Some(path) = &options.html {
        outputs.stage("--html", path, page.as_bytes())?;
    }
    if let (Some(path), Some(bytes)) = (&options.pdf, &pdf) {
        outputs.stage("--pdf", path, bytes)?;
    }
    outputs.commit()?;
    Ok(())
}
