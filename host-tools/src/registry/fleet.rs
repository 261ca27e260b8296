//! The fleet page (`calib registry fleet`, issue 55 item 7): one static HTML page of every robot
//! in the registry: its last calibration and accuracy, when it falls due again, its last shift
//! check and drift state, its last ISO 9283 pose test. Three queries (calibrations, shift checks,
//! pose tests, each ordered by robot) and one pass, so 100,000 calibrations render in well under
//! a second.

use super::Registry;
use super::pose_tests::PoseTestSummary;
use super::record::Summary;
use super::shift::CheckSummary;
use crate::report::markup::esc;
use std::fmt::Write as _;
use std::time::{Duration, SystemTime};

/// Days from a calibration to the next, unless stated.
pub const DEFAULT_INTERVAL_DAYS: u32 = 365;

/// One robot on the page.
#[derive(Clone, Debug, PartialEq)]
pub struct FleetRow {
    /// Its last calibration.
    pub last: Summary,
    /// Its calibrations.
    pub calibrations: usize,
    /// When it falls due again (`YYYY-MM-DD`), and whether that day has passed.
    pub due: (String, bool),
    /// Its last shift check.
    pub last_check: Option<CheckSummary>,
    /// Its last pose test.
    pub last_pose_test: Option<PoseTestSummary>,
}

/// The start (midnight, UTC) of `day`, `YYYY-MM-DD`: the "today" a page is judged on, when given.
pub fn day_start(day: &str) -> Result<SystemTime, String> {
    crate::io::dates::date(day)?;
    humantime::parse_rfc3339(&format!("{day}T00:00:00Z")).map_err(|e| e.to_string())
}

/// The page of `registry` (named `source` on it), due `interval_days` after each last
/// calibration, judged on `today` (`YYYY-MM-DD`; now when `None`), generated now; with its rows.
/// Refused: a `today` that is not a date.
pub fn page(
    registry: &Registry,
    source: &str,
    interval_days: u32,
    today: Option<&str>,
) -> crate::Result<(String, Vec<FleetRow>)> {
    let now = SystemTime::now();
    let today = match today {
        Some(day) => {
            day_start(day).map_err(|e| crate::refused!(option "--today"; "--today {day}: {e}"))?
        }
        None => now,
    };
    let rows = rows(registry, interval_days, today)?;
    let generated = humantime::format_rfc3339_seconds(now).to_string();
    Ok((html(&rows, &generated, source, interval_days), rows))
}

/// Every robot of `registry`, by serial: due `interval_days` after its last calibration, judged
/// on `today`.
pub fn rows(
    registry: &Registry,
    interval_days: u32,
    today: SystemTime,
) -> crate::Result<Vec<FleetRow>> {
    let calibrations = registry.list(None)?;
    let checks = registry.all_checks()?;
    let tests = registry.all_pose_tests()?;
    let mut rows: Vec<FleetRow> = Vec::new();
    for c in calibrations {
        match rows.last_mut() {
            Some(row) if row.last.serial == c.serial => {
                row.calibrations += 1;
                row.last = c;
            }
            _ => rows.push(FleetRow {
                last: c,
                calibrations: 1,
                due: (String::new(), false),
                last_check: None,
                last_pose_test: None,
            }),
        }
    }
    // Each list is ordered by serial, then time: the last of a serial is its latest.
    let index = |serial: &str| rows.binary_search_by(|r| r.last.serial.as_str().cmp(serial));
    let mut latest_check = vec![None; rows.len()];
    for check in checks {
        if let Ok(i) = index(&check.serial) {
            latest_check[i] = Some(check);
        }
    }
    let mut latest_test = vec![None; rows.len()];
    for test in tests {
        if let Ok(i) = index(&test.serial) {
            latest_test[i] = Some(test);
        }
    }
    let interval = Duration::from_secs(u64::from(interval_days) * 86_400);
    for ((row, check), test) in rows.iter_mut().zip(latest_check).zip(latest_test) {
        row.last_check = check;
        row.last_pose_test = test;
        row.due = match humantime::parse_rfc3339_weak(&row.last.calibrated_at) {
            Ok(at) => {
                let due = at + interval;
                let day = humantime::format_rfc3339_seconds(due).to_string();
                (day[..10].to_string(), due < today)
            }
            Err(_) => ("unknown".to_string(), false),
        };
    }
    Ok(rows)
}

/// The page of `rows` (generated at `generated`, RFC 3339, from the registry named `source`).
pub fn html(rows: &[FleetRow], generated: &str, source: &str, interval_days: u32) -> String {
    let overdue = rows.iter().filter(|r| r.due.1).count();
    let drifted = (rows.iter())
        .filter(|r| r.last_check.as_ref().is_some_and(|c| c.drifted))
        .count();
    let calibrations: usize = rows.iter().map(|r| r.calibrations).sum();
    let mut page = format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>Fleet: {} robots</title>\n<style>{STYLE}</style>\n</head>\n<body>\n\
         <h1>Fleet</h1>\n<p>{} robots, {calibrations} calibrations in <code>{}</code>; recalibration due {interval_days} days after the last; \
         <span class=\"{}\">{overdue} overdue</span>, <span class=\"{}\">{drifted} drifted at their last shift check</span>. Generated {}.</p>\n\
         <table>\n<tr><th>serial</th><th>model</th><th>calibrations</th><th>last calibrated</th><th>held out, mm</th><th>due</th>\
         <th>last shift check</th><th>mean, mm</th><th>drift</th><th>last pose test</th><th>AP max, mm</th><th>RP max, mm</th></tr>\n",
        rows.len(),
        rows.len(),
        esc(source),
        if overdue > 0 { "bad" } else { "ok" },
        if drifted > 0 { "bad" } else { "ok" },
        esc(generated)
    );
    for r in rows {
        let mm = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4}"));
        let (check_at, check_mean, drift) = match &r.last_check {
            None => ("none".to_string(), "-".to_string(), "-".to_string()),
            Some(c) => (
                esc(&c.checked_at),
                format!("{:.4}", c.mean_mm),
                match (c.drifted, &c.cause) {
                    (false, _) => "<span class=\"ok\">ok</span>".to_string(),
                    (true, cause) => format!(
                        "<span class=\"bad\">DRIFT{}</span>",
                        cause
                            .as_ref()
                            .map_or(String::new(), |c| format!(": {}", esc(c)))
                    ),
                },
            ),
        };
        let (test_at, ap, rp) = match &r.last_pose_test {
            None => ("none".to_string(), "-".to_string(), "-".to_string()),
            Some(t) => (
                esc(&t.tested_at),
                mm(Some(t.ap_max_mm)),
                mm(Some(t.rp_max_mm)),
            ),
        };
        let due = match r.due.1 {
            true => format!("<span class=\"bad\">{} OVERDUE</span>", esc(&r.due.0)),
            false => esc(&r.due.0),
        };
        let _ = writeln!(
            page,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{} (#{}, {})</td><td>{}</td><td>{due}</td><td>{check_at}</td><td>{check_mean}</td><td>{drift}</td><td>{test_at}</td><td>{ap}</td><td>{rp}</td></tr>",
            esc(&r.last.serial),
            esc(&r.last.model),
            r.calibrations,
            esc(&r.last.calibrated_at),
            r.last.id,
            r.last.kind.name(),
            mm(r.last.held_out_mm)
        );
    }
    page.push_str("</table>\n<p class=\"note\">Held out: a tracker calibration's held-out position error (median after calibration); touches' held-out consistency, not accuracy.</p>\n</body>\n</html>\n");
    page
}

/// The page's style: compact rows, red for what needs a technician.
const STYLE: &str = "body{font-family:sans-serif;margin:1em;color:#111}table{border-collapse:collapse}\
td,th{border:1px solid #bbb;padding:0.15em 0.5em;text-align:right;font-size:10pt}th{background:#eee}\
td:first-child,td:nth-child(2){text-align:left}.bad{color:#b00;font-weight:bold}.ok{color:#070}.note{color:#555}";
