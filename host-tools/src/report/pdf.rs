//! The report as a PDF: the HTML page printed on A4 by a headless Chromium, when one is installed
//! (`chromium`, `chromium-browser` or `google-chrome` on the `PATH`). No PDF library renders our
//! page (its tables and inline SVG plots) as a browser does, and every machine that shows the HTML
//! report has a browser; without one the command says so and writes nothing (the HTML prints to
//! PDF from any browser). The page's print style sets A4 and keeps tables and plots whole.

use std::path::Path;
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

/// The longest a browser may take to print the page, s: Chromium prints the certificate in about
/// a second; a browser that hangs (a locked profile, a dialog) is stopped, not waited for.
pub const PRINT_TIMEOUT_S: u64 = 120;

/// The PDF bytes of the HTML page `html`, printed by a headless Chromium. Refused when none is
/// installed, or when it writes no PDF (its error output quoted).
pub fn print(html: &str) -> crate::Result<Vec<u8>> {
    let Some(browser) = browser() else {
        return Err(crate::refused!(program "chromium";
            "writing a PDF needs a headless Chromium (chromium, chromium-browser or google-chrome on the PATH; \
             apt-get install chromium), and none was found; write --html and print it to PDF from any browser"
        ));
    };
    print_with(html, browser, PRINT_TIMEOUT_S)
}

/// [`print`] with the browser command `browser` and a time limit of `timeout_s`.
fn print_with(html: &str, browser: &str, timeout_s: u64) -> crate::Result<Vec<u8>> {
    // Private (0700) and removed on every exit, an interruption included: the page may be a
    // private report's copy.
    let scratch = crate::io::outputs::scratch_dir("calib-pdf")
        .map_err(|e| crate::refused!(program "chromium"; "cannot make a scratch directory: {e}"))?;
    let page = scratch.0.join("report.html");
    let pdf = scratch.0.join("report.pdf");
    std::fs::write(&page, html)
        .map_err(|e| crate::refused!(program "chromium"; "cannot write {}: {e}", page.display()))?;
    let stderr = run(browser, (&scratch.0, &page, &pdf), timeout_s)?;
    let bytes = std::fs::read(&pdf).unwrap_or_default();
    if !bytes.starts_with(b"%PDF-") {
        return Err(crate::refused!(program browser; "{browser} wrote no PDF: {}", stderr.trim()));
    }
    Ok(bytes)
}

/// Runs `browser` headless on `page`, printing it to `pdf` (its profile and error output in
/// `scratch`), for at most `timeout_s`; returns its error output.
fn run(
    browser: &str,
    (scratch, page, pdf): (&Path, &Path, &Path),
    timeout_s: u64,
) -> crate::Result<String> {
    let errors = scratch.join("browser.err");
    let stderr = std::fs::File::create(&errors)
        .map_err(|e| crate::refused!(program browser; "cannot write {}: {e}", errors.display()))?;
    let mut child = Command::new(browser)
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
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(stderr)
        .spawn()
        .map_err(|e| crate::refused!(program browser; "cannot run {browser}: {e}"))?;
    let start = std::time::Instant::now();
    loop {
        match child.try_wait() {
            Ok(Some(_)) => break,
            Ok(None) if start.elapsed().as_secs() < timeout_s => {
                std::thread::sleep(std::time::Duration::from_millis(50));
            }
            Ok(None) | Err(_) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(crate::refused!(program browser;
                    "{browser} did not print the page within {timeout_s} s and was stopped; write --html and print it from a browser"
                ));
            }
        }
    }
    Ok(std::fs::read_to_string(&errors).unwrap_or_default())
}

#[cfg(all(test, unix))]
mod tests {
    /// Issue 52 (V6): a browser that hangs is stopped after the time limit, and the scratch
    /// directory holding the page's copy was private (0700) and is gone afterwards. The "browser"
    /// is a script that notes its page's directory and mode, then sleeps.
    #[test]
    fn a_hanging_browser_is_stopped_and_the_private_copy_removed() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let (script, seen) = (dir.path().join("browser"), dir.path().join("seen"));
        std::fs::write(
            &script,
            format!(
                "#!/bin/sh\nfor a; do case \"$a\" in file://*) p=\"${{a#file://}}\";; esac; done\n\
                 d=$(dirname \"$p\"); echo \"$d $(stat -c %a \"$d\")\" > '{}'\nexec sleep 30\n",
                seen.display()
            ),
        )
        .unwrap();
        std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
        let start = std::time::Instant::now();
        // A script just written can be "busy" while another test's thread forks with it still
        // open (ETXTBSY until that child execs): run it again then.
        let mut error = String::new();
        for _ in 0..20 {
            error = super::print_with("<p>private</p>", script.to_str().unwrap(), 1)
                .unwrap_err()
                .to_string();
            if !error.contains("Text file busy") {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        assert!(
            error.contains("did not print the page within 1 s"),
            "{error}"
        );
        assert!(start.elapsed().as_secs() < 10);
        let seen = std::fs::read_to_string(&seen).unwrap();
        let (scratch, mode) = seen.trim().rsplit_once(' ').unwrap();
        assert_eq!(mode, "700");
        assert!(
            !std::path::Path::new(scratch).exists(),
            "{scratch} left behind"
        );
    }
}
