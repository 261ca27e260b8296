//! The report as a PDF: the HTML page printed on A4 by a headless Chromium, when one is installed
//! (`chromium`, `chromium-browser` or `google-chrome` on the `PATH`). No PDF library renders our
//! page (its tables and inline SVG plots) as a browser does, and every machine that shows the HTML
//! report has a browser; without one the command says so and writes nothing (the HTML prints to
//! PDF from any browser). The page's print style sets A4 and keeps tables and plots whole.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The browsers tried, in order.
const BROWSERS: [&str; 3] = ["chromium", "chromium-browser", "google-chrome"];

/// The first of chromium, chromium-browser and google-chrome that runs, if any.
pub fn browser() -> Option<&'static str> {
    BROWSERS.into_iter().find(|b| {
        Command::new(b)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// A private scratch directory, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new() -> std::io::Result<Self> {
        let base = std::env::temp_dir();
        for n in 0..1000u32 {
            let dir = base.join(format!("calib-pdf-{}-{n}", std::process::id()));
            match std::fs::create_dir(&dir) {
                Ok(()) => return Ok(Self(dir)),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
                Err(e) => return Err(e),
            }
        }
        Err(std::io::Error::other("no free scratch directory name"))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The PDF bytes of the HTML page `html`, printed by a headless Chromium. Refused when none is
/// installed, or when it writes no PDF (its error output quoted).
pub fn print(html: &str) -> crate::Result<Vec<u8>> {
    let Some(browser) = browser() else {
        return Err(crate::refused!(
            "writing a PDF needs a headless Chromium (chromium, chromium-browser or google-chrome on the PATH; \
             apt-get install chromium), and none was found; write --html and print it to PDF from any browser"
        ));
    };
    let scratch =
        Scratch::new().map_err(|e| crate::refused!("cannot make a scratch directory: {e}"))?;
    let page = scratch.0.join("report.html");
    let pdf = scratch.0.join("report.pdf");
    std::fs::write(&page, html)
        .map_err(|e| crate::refused!("cannot write {}: {e}", page.display()))?;
    let out = run(browser, &scratch.0, &page, &pdf)?;
    let bytes = std::fs::read(&pdf).unwrap_or_default();
    if !bytes.starts_with(b"%PDF-") {
        return Err(crate::refused!(
            "{browser} wrote no PDF: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    Ok(bytes)
}

/// Runs `browser` headless on `page`, printing it to `pdf` (its profile in `scratch`).
fn run(
    browser: &str,
    scratch: &Path,
    page: &Path,
    pdf: &Path,
) -> crate::Result<std::process::Output> {
    Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-pdf-header-footer",
        ])
        .arg(format!(
            "--user-data-dir={}",
            scratch.join("profile").display()
        ))
        .arg(format!("--print-to-pdf={}", pdf.display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .map_err(|e| crate::refused!("cannot run {browser}: {e}"))
}
