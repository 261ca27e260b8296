//! The ISO 9283 pose test ([`crate::pose_test::PoseTest`]) as a section of the certificate
//! (`calib report --pose-test`): per point `AP` (with its components) and `RP`, the distance
//! characteristics, the drift, and what the run was and how it was measured.

use super::markup::{esc, num};
use crate::pose_test::PoseTest;
use std::fmt::Write as _;

/// The section `<h2 id="pose-test">`.
pub fn section(test: &PoseTest) -> crate::Result<String> {
    let c = &test.characteristics;
    let mut page = String::new();
    writeln!(
        page,
        "<h2 id=\"pose-test\">ISO 9283 pose test</h2>\n<p>Run <code>{}</code> (SHA-256 <code>{}</code>) against the commanded poses <code>{}</code> (SHA-256 <code>{}</code>); {}; {}.</p>",
        esc(&test.data),
        esc(&test.data_sha256),
        esc(&test.targets),
        esc(&test.targets_sha256),
        esc(&test.setup),
        esc(&test.instrument_text())
    )?;
    page.push_str("<table>\n<caption>Pose accuracy and repeatability per point (ISO 9283:1998, 7.2.1 and 7.2.2)</caption>\n<tr><th>point</th><th>cycles</th><th>AP, mm</th><th>APx, mm</th><th>APy, mm</th><th>APz, mm</th><th>RP, mm</th><th>AP a, b, c, deg</th><th>RP a, b, c, &plusmn;deg</th></tr>\n");
    for p in &c.points {
        let angles = |v: Option<[f64; 3]>| match v {
            Some(v) => v.map(|x| format!("{x:.4}")).join(", "),
            None => "-".to_string(),
        };
        writeln!(
            page,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&p.point),
            p.cycles,
            num(p.ap_mm, 4),
            num(p.ap_xyz_mm[0], 4),
            num(p.ap_xyz_mm[1], 4),
            num(p.ap_xyz_mm[2], 4),
            num(p.rp_mm, 4),
            angles(p.ap_abc_deg),
            angles(p.rp_abc_deg)
        )?;
    }
    page.push_str("</table>\n<p class=\"note\">AP = |barycentre - commanded|; RP = mean(l) + 3 S<sub>l</sub>, l the distance of each cycle's position from the barycentre; orientation columns only when the run measured orientation.</p>\n");
    match &c.distance {
        Some(d) => writeln!(
            page,
            "<p>Distance accuracy and repeatability between {} and {} ({} cycles, 7.6): commanded {}&nbsp;mm, AD {}&nbsp;mm, RD &plusmn;{}&nbsp;mm.</p>",
            esc(&d.points[0]),
            esc(&d.points[1]),
            d.cycles,
            num(d.commanded_mm, 4),
            num(d.ad_mm, 4),
            num(d.rd_mm, 4)
        )?,
        None => page.push_str(
            "<p>Distance accuracy: not measured (P2 and P4 in fewer than 2 common cycles).</p>\n",
        ),
    }
    match &c.drift {
        Some(d) => writeln!(
            page,
            "<p>Drift of pose characteristics at {} (7.7; the first and the last {} cycles{}): AP {} &rarr; {}&nbsp;mm, dAP {}&nbsp;mm; RP {} &rarr; {}&nbsp;mm, dRP {}&nbsp;mm.</p>",
            esc(&d.point),
            d.block_cycles,
            d.span_s
                .map_or(String::new(), |s| format!(", {s:.0}&nbsp;s apart")),
            num(d.ap_mm[0], 4),
            num(d.ap_mm[1], 4),
            num(d.dap_mm, 4),
            num(d.rp_mm[0], 4),
            num(d.rp_mm[1], 4),
            num(d.drp_mm, 4)
        )?,
        None => page.push_str("<p>Drift: not measured (P1 in fewer than 6 cycles).</p>\n"),
    }
    for note in &c.notes {
        writeln!(page, "<p class=\"note\">{}</p>", esc(note))?;
    }
    Ok(page)
}
