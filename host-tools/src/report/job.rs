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
}
