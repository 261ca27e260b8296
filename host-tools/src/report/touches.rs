//! A calibration from touches as text: the fit in a few lines, what the touches leave free and
//! what the data could not determine, then per placement the consistency and distortion under
//! the nominal and the identified model, fitted and held out. Consistency is not accuracy: the
//! text says so where the figures start.

use crate::calibration::touches::{PlacementFigures, TouchCalibrated};

/// The text `calib sockets` prints.
pub fn touches_text(calibrated: &TouchCalibrated) -> String {
    let mut text = fit_text(calibrated);
    text.push_str("\nidentified errors (mm, rad) and standard errors:\n");
    for p in &calibrated.fit.parameters {
        let sd = p
            .std_error
            .map_or(String::new(), |s| format!(" +- {s:.3e}"));
        text.push_str(&format!(
            "  {:<10} {:+.6e}{sd}\n",
            p.parameter.to_string(),
            p.value
        ));
    }
    if let Some(torsion) = &calibrated.torsion {
        text.push_str(&torsion_text(torsion));
    }
    text.push_str(
        "\nconsistency (distance of each ball centre from its socket's mean; not absolute accuracy), mm:\n\
         placement                 nominal mean  identified mean    p95  authors' rule  distance error\n",
    );
    let rows = |title: &str, figures: &[PlacementFigures], text: &mut String| {
        if figures.is_empty() {
            return;
        }
        text.push_str(&format!("{title}:\n"));
        for f in figures {
            if f.identified.sockets.is_empty() {
                text.push_str(&format!(
                    "  {:<24} no sockets (planes below)\n",
                    f.placement
                ));
                continue;
            }
            let distortion = f
                .identified
                .distortion_mm
                .first()
                .map_or("-".into(), |(_, e)| format!("{e:+.4}"));
            text.push_str(&format!(
                "  {:<24} {:>12.4} {:>16.4} {:>6.4} {:>14.4} {:>15}\n",
                f.placement,
                f.nominal.mean_mm,
                f.identified.mean_mm,
                f.identified.p95_mm,
                f.identified.authors_mean_mm,
                distortion
            ));
        }
    };
    rows("fitted", &calibrated.fitted, &mut text);
    rows("held out", &calibrated.held_out, &mut text);
    text.push_str(&planes_text(calibrated));
    let predicted: Vec<(&str, _)> = (calibrated.held_out.iter())
        .filter_map(|f| Some((f.placement.as_str(), f.predicted?)))
        .collect();
    if !predicted.is_empty() {
        text.push_str(
            "predicted on the held-out placements from the fit's scatter and covariance (measured above: more means the model leaves something out), mm:\n\
             placement                    mean    p95  scatter alone\n",
        );
        for (name, p) in predicted {
            text.push_str(&format!(
                "  {name:<24} {:>8.4} {:>6.4} {:>14.4}\n",
                p.mean_mm, p.p95_mm, p.scatter_mean_mm
            ));
        }
    }
    if !calibrated.held_out.is_empty() {
        let n = calibrated.held_out.len() as f64;
        let mean =
            |f: fn(&PlacementFigures) -> f64| calibrated.held_out.iter().map(f).sum::<f64>() / n;
        text.push_str(&format!(
            "held-out mean: {:.4} mm every touch, {:.4} mm by the authors' rule\n",
            mean(|f| f.identified.mean_mm),
            mean(|f| f.identified.authors_mean_mm)
        ));
    }
    text
}

/// The fit, the ball and what was left free or dropped.
fn fit_text(calibrated: &TouchCalibrated) -> String {
    let fit = &calibrated.fit;
    let l = &fit.least_squares;
    let id = &calibrated.selection.identifiability;
    let mut text = format!(
        "calibration from touches: {} parameters by least squares ({} iterations, {}, {:.3} s), residual sd {:.4} mm per coordinate\n",
        fit.parameters.len(),
        l.iterations,
        l.stop,
        fit.seconds,
        fit.sigma_mm
    );
    if let (Some(w), Some(sd)) = (calibrated.gauge_weight, calibrated.touch_sd_mm) {
        text.push_str(&format!(
            "known distance weighed {w:.3} against a touch's coordinate: the touches scatter {sd:.4} mm per coordinate without it\n"
        ));
    }
    let [x, y, z] = calibrated.ball_mm;
    text.push_str(&format!(
        "ball centre in the robot file's tool frame (the flange without a [tool]): {x:.4}, {y:.4}, {z:.4} mm (measurement setup: not written into the controller's tool)\n"
    ));
    text.push_str("\nleft free by touches, whatever the configurations:\n");
    for f in &id.left_free {
        text.push_str(&format!("  {}: {}\n", f.parameter, f.why));
    }
    if !calibrated.selection.dropped.is_empty() {
        let dropped: Vec<String> = (calibrated.selection.dropped.iter())
            .map(ToString::to_string)
            .collect();
        text.push_str(&format!(
            "dropped, barely determined by these configurations: {} (scaled condition number {} -> {})\n",
            dropped.join(", "),
            id.condition_number.map_or("infinite".into(), |c| format!("{c:.3e}")),
            id.condition_number_after_drop.map_or("infinite".into(), |c| format!("{c:.3e}"))
        ));
    }
    text
}

/// Leave one placement out as text: each placement under a calibration of all the others, then
/// the mean and the worst.
pub fn leave_one_out_text(figures: &[PlacementFigures]) -> String {
    let mut text = String::from(
        "\nleave one placement out (each judged by a calibration of all the others; consistency, not accuracy), mm:\n\
         placement                 identified mean    p95  authors' rule  distance error  predicted mean\n",
    );
    for f in figures {
        let distortion =
            (f.identified.distortion_mm.first()).map_or("-".into(), |(_, e)| format!("{e:+.4}"));
        let predicted = f
            .predicted
            .map_or("-".into(), |p| format!("{:.4}", p.mean_mm));
        text.push_str(&format!(
            "  {:<24} {:>15.4} {:>6.4} {:>14.4} {:>15} {:>15}\n",
            f.placement,
            f.identified.mean_mm,
            f.identified.p95_mm,
            f.identified.authors_mean_mm,
            distortion,
            predicted
        ));
    }
    let n = figures.len().max(1) as f64;
    let (mean, authors) = (
        figures.iter().map(|f| f.identified.mean_mm).sum::<f64>() / n,
        figures
            .iter()
            .map(|f| f.identified.authors_mean_mm)
            .sum::<f64>()
            / n,
    );
    let worst = figures.iter().max_by(|a, b| {
        a.identified
            .authors_mean_mm
            .total_cmp(&b.identified.authors_mean_mm)
    });
    text.push_str(&format!(
        "mean: {mean:.4} mm every touch, {authors:.4} mm by the authors' rule"
    ));
    if let Some(w) = worst {
        text.push_str(&format!(
            "; worst: {} ({:.4} mm by the authors' rule)",
            w.placement, w.identified.authors_mean_mm
        ));
    }
    text.push('\n');
    text
}

/// The planes' flatness per placement, fitted and held out (nothing without plane contacts).
fn planes_text(calibrated: &TouchCalibrated) -> String {
    let every = || calibrated.fitted.iter().chain(&calibrated.held_out);
    let mut text = datums_text(calibrated);
    if every().all(|f| f.identified.planes.is_empty()) {
        return text;
    }
    text.push_str(
        "planes (distance of each ball centre from its plane's best fit; not absolute accuracy), mm:\n\
         placement                 plane  contacts  nominal mean  identified mean    p95\n",
    );
    let fitted = calibrated.fitted.len();
    for (i, f) in every().enumerate() {
        let role = if i < fitted { "fitted" } else { "held out" };
        for (nominal, identified) in f.nominal.planes.iter().zip(&f.identified.planes) {
            text.push_str(&format!(
                "  {:<24} {:>6} {:>9} {:>13.4} {:>16.4} {:>6.4}  {role}\n",
                f.placement,
                identified.plane,
                identified.contacts,
                nominal.mean_mm,
                identified.mean_mm,
                identified.p95_mm
            ));
        }
    }
    text
}

/// The contacts with datum planes (known in the base frame): each one's distance from its plane,
/// nominal and identified, per placement.
fn datums_text(calibrated: &TouchCalibrated) -> String {
    let every = || calibrated.fitted.iter().chain(&calibrated.held_out);
    if every().all(|f| f.identified.known_planes.is_empty()) {
        return String::new();
    }
    let mut text = String::from(
        "datum planes (distance of each ball centre from its known plane: the model's error along the normal), mm:\n\
         placement                 plane  contacts  nominal mean  identified mean    p95\n",
    );
    let fitted = calibrated.fitted.len();
    for (i, f) in every().enumerate() {
        let role = if i < fitted { "fitted" } else { "held out" };
        for (nominal, identified) in f
            .nominal
            .known_planes
            .iter()
            .zip(&f.identified.known_planes)
        {
            let plane = (calibrated.datums.get(usize::from(identified.plane)))
                .map_or(identified.plane, |d| d.plane);
            text.push_str(&format!(
                "  {:<24} {:>6} {:>9} {:>13.4} {:>16.4} {:>6.4}  {role}\n",
                f.placement,
                plane,
                identified.contacts,
                nominal.mean_mm,
                identified.mean_mm,
                identified.p95_mm
            ));
        }
    }
    text
}

/// What the tracker positions of a mixed calibration add: where the robot stands in the
/// tracker's frame (measurement setup) and how well the positions fit.
pub fn tracker_text(tracker: &crate::calibration::mixed::TrackerFigures) -> String {
    let [x, y, z] = tracker.registration_xyz_mm;
    let [roll, pitch, yaw] = tracker.registration_rpy_rad.map(f64::to_degrees);
    format!(
        "\ntracker positions of the ball: {} fitted with the touches (tracker sd {:.4} mm per coordinate; a touch's coordinate weighs {:.4} against one), residual RMS {:.4} mm, largest {:.4} mm\n\
         the robot's base in the tracker's frame (measurement setup, not written as the controller's base): {x:.4}, {y:.4}, {z:.4} mm, roll {roll:.5}, pitch {pitch:.5}, yaw {yaw:.5} deg\n\
         the tracker positions place the robot and fix the scale: the base and the lengths are determined, not left free\n",
        tracker.positions, tracker.sd_mm, tracker.touch_weight, tracker.rms_mm, tracker.max_mm
    )
}

/// The joints' torsion under gravity: whether it earned its place, the gains.
pub fn torsion_text(torsion: &crate::calibration::torsion::TorsionReport) -> String {
    let [geometry, with] = torsion.cross_validated_mm;
    let mut text = format!(
        "\njoints' torsion under gravity ({}): left-out touches of the fitted placements predicted to {geometry:.4} mm by the geometry alone, {with:.4} mm with the torsions fitted ({} folds): {}\n",
        if torsion.kept { "kept" } else { "not kept" },
        crate::calibration::torsion::FOLDS,
        if torsion.kept {
            "the identified model turns the joints by them"
        } else {
            "the geometry alone is the calibration; the gains below are not applied"
        }
    );
    for (((joint, gain), se), fitted) in (torsion.joints.iter())
        .zip(&torsion.gains_urad_per_nm)
        .zip(&torsion.std_errors_urad_per_nm)
        .zip(&torsion.fitted)
    {
        let what = match (fitted, se) {
            (true, Some(se)) => format!("{gain:.1} +- {se:.1} urad per N m"),
            (true, None) => format!("{gain:.1} urad per N m"),
            (false, _) => {
                "0 (did not predict left-out touches better, or came out negative)".to_string()
            }
        };
        text.push_str(&format!("  torsion of joint {joint}: {what}\n"));
    }
    text.push_str(&format!(
        "  largest turn of a joint over the fitted touches {:.3} mrad; the controller's first-order deflection differs from the fitted turns by at most {:.4} mm there\n",
        torsion.largest_turn_mrad, torsion.controller_difference_mm
    ));
    text
}
