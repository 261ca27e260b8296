//! Who and where a certificate is for (`calib report --job FILE`, issue 55 item 6): the
//! certificate's number, the customer, the site and cell, the operator who measured, the day of
//! the measurement and who approves. None of it is in the measured data, so it comes from a small
//! TOML file the integrator keeps per job:
//!
//! ```toml
//! certificate = "CAL-2026-0142"
//! customer = "ACME Automotive"
//! site = "Plant 2, Wolfsburg"
//! cell = "Cell 14, spot welding"
//! operator = "J. Doe"
//! measured_on = "2026-11-27"
//! approver = "M. Muster"
//! ```
//!
//! Every field is optional: one not stated is left as a line to fill in by hand on the printed
//! certificate, never guessed.

use super::markup::{css_string, esc};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The longest field accepted, characters (a field is one line of the certificate).
const MAX_FIELD_CHARS: usize = 200;

/// The certificate's job.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Job {
    /// The certificate's number.
    pub certificate: Option<String>,
    /// The customer.
    pub customer: Option<String>,
    /// The site (plant, address).
    pub site: Option<String>,
    /// The cell the robot works in.
    pub cell: Option<String>,
    /// The operator who measured.
    pub operator: Option<String>,
    /// The day of the measurement, `YYYY-MM-DD`.
    pub measured_on: Option<String>,
    /// Who approves the certificate.
    pub approver: Option<String>,
}

impl Job {
    /// The job file at `path`. Refused, with the field named: a file that is not TOML or has
    /// another key, a field of several lines or over 200 characters, a `measured_on` that is
    /// not a date.
    pub fn read(path: &Path) -> crate::Result<Self> {
        let bytes = crate::io::input::read(path, crate::io::input::Input::Document)
            .map_err(|e| crate::refused!(input path.display(); "--job {}: {e}", path.display()))?;
        let text = String::from_utf8(bytes).map_err(|_| {
            crate::refused!(input path.display(); "--job {}: not UTF-8 text; save it as UTF-8", path.display())
        })?;
        let job: Self = toml::from_str(&text).map_err(|e| {
            crate::refused!(input path.display();
                "--job {}: {}; the keys are certificate, customer, site, cell, operator, measured_on, approver",
                path.display(), e.message())
        })?;
        let fields = [
            ("certificate", &job.certificate),
            ("customer", &job.customer),
            ("site", &job.site),
            ("cell", &job.cell),
            ("operator", &job.operator),
            ("measured_on", &job.measured_on),
            ("approver", &job.approver),
        ];
        for (key, value) in fields {
            let Some(value) = value else { continue };
            if value.contains(['\n', '\r'])
                || value.chars().count() > MAX_FIELD_CHARS
                || value.trim().is_empty()
            {
                return Err(crate::refused!(input path.display();
                    "--job {}: {key} must be one line of 1 to {MAX_FIELD_CHARS} characters", path.display()));
            }
        }
        if let Some(day) = &job.measured_on {
            crate::io::dates::date(day).map_err(|e| {
                crate::refused!(input path.display(); "--job {}: measured_on = {day:?}: {e}", path.display())
            })?;
        }
        Ok(job)
    }
    /// The job under a certificate's title: certificate, customer, site, cell, operator, day of
    /// measurement; a field not stated is a line to fill in by hand.
    pub(crate) fn table_html(&self) -> String {
        format!(
            "<table>\n<tr><td>certificate</td><td>{}</td></tr>\n<tr><td>customer</td><td>{}</td></tr>\n<tr><td>site</td><td>{}</td></tr>\n\
             <tr><td>cell</td><td>{}</td></tr>\n<tr><td>operator</td><td>{}</td></tr>\n<tr><td>measured on</td><td>{}</td></tr>\n</table>\n",
            field(self.certificate.as_ref()),
            field(self.customer.as_ref()),
            field(self.site.as_ref()),
            field(self.cell.as_ref()),
            field(self.operator.as_ref()),
            field(self.measured_on.as_ref())
        )
    }

    /// The signature lines ([`APPROVAL_SECTION`]): measured by, approved by, accepted for the
    /// customer.
    pub(crate) fn approval_html(&self) -> String {
        let name = |v: Option<&String>| v.map_or(String::new(), |v| esc(v));
        format!(
            "<h2 id=\"{APPROVAL_SECTION}\">Approval</h2>\n<table class=\"sign\">\n<tr><th>role</th><th>name</th><th>date</th><th>signature</th></tr>\n\
             <tr><td>measured by</td><td>{}</td><td>{}</td><td></td></tr>\n<tr><td>approved by</td><td>{}</td><td></td><td></td></tr>\n\
             <tr><td>accepted for {}</td><td></td><td></td><td></td></tr>\n</table>\n",
            name(self.operator.as_ref()),
            name(self.measured_on.as_ref()),
            name(self.approver.as_ref()),
            self.customer
                .as_deref()
                .map_or_else(|| "the customer".to_string(), esc)
        )
    }
}

/// The section of a certificate's signature lines, before its `software` when it has a job.
pub const APPROVAL_SECTION: &str = "approval";

/// A job's field, or a line to fill in by hand.
fn field(value: Option<&String>) -> String {
    value.map_or_else(
        || "<span class=\"note\">not stated</span>".to_string(),
        |v| esc(v),
    )
}

/// The style that prints `header` at the top left of every page of a certificate (the page
/// number is in the certificate's own style, bottom right).
pub(crate) fn page_header_style(header: &str) -> String {
    format!(
        "<style>@page{{@top-left{{content:\"{}\";font-family:sans-serif;font-size:8pt;color:#555}}}}</style>\n",
        css_string(header)
    )
}
