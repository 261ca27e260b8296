//! Text tables: the paper's Table 3 statistics before and after calibration, and the parameter
//! comparison against a known truth, in fixed-width columns.

use crate::analysis::truth::TruthRow;
use crate::measurement::statistics::{Stat, Table3};

/// The paper's Table 3 layout, before and after, as fixed-width text.
pub(crate) fn table3_text(title: &str, before: &Table3, after: &Table3) -> String {
    let mut out = format!(
        "{title} ({} poses)\n{:<30} {:^32}   {:^32}\n{:<30} {:>10} {:>10} {:>10}   {:>10} {:>10} {:>10}\n",
        before.poses,
        "",
        "before calibration",
        "after calibration",
        "",
        "mean",
        "std",
        "max",
        "mean",
        "std",
        "max"
    );
    let row = |name: &str, b: &Stat, a: &Stat| {
        format!(
            "{name:<30} {:>10} {:>10} {:>10}   {:>10} {:>10} {:>10}\n",
            number(b.mean),
            number(b.std),
            number(b.max),
            number(a.mean),
            number(a.std),
            number(a.max)
        )
    };
    out.push_str(&row(
        "absolute position error (mm)",
        &before.position_mm,
        &after.position_mm,
    ));
    if let (Some(b), Some(a)) = (&before.orientation_deg, &after.orientation_deg) {
        out.push_str(&row("orientation error x (deg)", &b.x, &a.x));
        out.push_str(&row("orientation error y (deg)", &b.y, &a.y));
        out.push_str(&row("orientation error z (deg)", &b.z, &a.z));
    } else {
        out.push_str("orientation error              (position-only data)\n");
    }
    out
}

/// Four decimals, or three significant digits in scientific notation below 1e-3 (so that a
/// sub-micrometre result does not print as 0.0000).
fn number(v: f64) -> String {
    if v != 0.0 && v.abs() < 1e-3 {
        format!("{v:.3e}")
    } else {
        format!("{v:.4}")
    }
}

/// Table 3 of one model as fixed-width text.
pub(crate) fn table3_single_text(title: &str, table: &Table3) -> String {
    let mut out = format!(
        "{title} ({} poses)\n{:<30} {:>10} {:>10} {:>10}\n",
        table.poses, "", "mean", "std", "max"
    );
    let row = |name: &str, s: &Stat| {
        format!(
            "{name:<30} {:>10} {:>10} {:>10}\n",
            number(s.mean),
            number(s.std),
            number(s.max)
        )
    };
    out.push_str(&row("absolute position error (mm)", &table.position_mm));
    match &table.orientation_deg {
        Some(o) => {
            out.push_str(&row("orientation error x (deg)", &o.x));
            out.push_str(&row("orientation error y (deg)", &o.y));
            out.push_str(&row("orientation error z (deg)", &o.z));
        }
        None => out.push_str("orientation error              (position-only data)\n"),
    }
    out
}

/// The comparison as fixed-width text.
pub(crate) fn truth_text(rows: &[TruthRow]) -> String {
    let mut out = format!(
        "{:<10} {:>4} {:>16} {:>16} {:>13}\n",
        "parameter", "unit", "identified", "true", "difference"
    );
    for r in rows {
        out.push_str(&format!(
            "{:<10} {:>4} {:>16.9} {:>16.9} {:>13.3e}\n",
            r.name, r.unit, r.identified, r.truth, r.difference
        ));
    }
    out
}
