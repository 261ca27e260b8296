//! `calib import-ur-calibration`: a UR controller's factory calibration (`calibration.conf`) as
//! our robot file ([`host_tools::formats::ur_calibration`]).

use host_tools::formats::ur_calibration::{Import, UrCalibration};
use host_tools::io::outputs::Outputs;
use host_tools::io::robot_file::{RobotFile, RobotModel};
use std::path::PathBuf;

/// Options of `calib import-ur-calibration`.
#[derive(Clone, Debug, clap::Args)]
pub struct ImportUrOptions {
    /// The robot's nominal file in classic DH (host-tools/robots/ur5.toml, ur10.toml,
    /// ur10e.toml).
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// The controller's calibration.conf (its `[mounting]` deltas, m and rad).
    #[arg(long, value_name = "FILE")]
    pub calibration: PathBuf,
    /// The robot file to write: nominal + the calibration as Hayati errors.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Write an import whose Hayati errors are beyond a robot's geometric errors (20 mm, 3 deg,
    /// or the robot file's max_length_error_mm, max_angle_error_deg) or that moves the flange by
    /// more than 20 mm, instead of refusing it.
    #[arg(long)]
    pub accept_implausible: bool,
}

/// The problems of an import, each naming the value and its bound; empty when it is plausible.
/// A factory calibration corrects a robot by millimetres and tenths of a degree; more means
/// wrong deltas or a nominal file of another robot than the one calibrated.
fn implausible(file: &RobotFile, import: &Import) -> Vec<String> {
    use host_tools::calibration::plausibility::{MAX_LENGTH_ERROR_MM, bound_of};
    let mut problems = Vec::new();
    for p in import.mask.iter() {
        let value = import.errors.get(p).unwrap_or(0.0);
        // The bounds a calibration of this robot is held to (its file's, or the general ones).
        let (bound, _) = bound_of(file, p);
        let (shown, unit) = if p.is_angle() {
            (value.to_degrees(), "deg")
        } else {
            (value, "mm")
        };
        if shown.abs() > bound || !shown.is_finite() {
            problems.push(format!(
                "{p} = {shown:.3} {unit} is beyond {bound} {unit}, a robot's geometric errors"
            ));
        }
    }
    if import.max_change_mm > MAX_LENGTH_ERROR_MM || !import.max_change_mm.is_finite() {
        problems.push(format!(
            "the calibration moves the flange by up to {:.1} mm (a factory calibration moves it by millimetres)",
            import.max_change_mm
        ));
    }
    problems
}

/// Runs `calib import-ur-calibration`; returns the import and the text to print.
pub fn import(options: &ImportUrOptions) -> anyhow::Result<(Import, String)> {
    let file = RobotFile::read(&options.robot)?;
    let model: RobotModel = file.to_model(&options.robot)?;
    let calibration = UrCalibration::read(&options.calibration)?;
    let import = host_tools::formats::ur_calibration::import(&model.robot, &calibration)?;
    let problems = implausible(&file, &import);
    if !problems.is_empty() && !options.accept_implausible {
        anyhow::bail!(
            "{} on {} is not a plausible calibration, nothing written:\n  {}\nLikely causes: a nominal \
             file of another robot than the one calibrated (ur5.toml, ur10.toml, ur10e.toml), or \
             wrong deltas. If the import is right, --accept-implausible writes it.",
            options.calibration.display(),
            options.robot.display(),
            problems.join("\n  ")
        );
    }
    let listed: Vec<_> = import.mask.iter().collect();
    let mut out = file.with_errors(
        &import.errors,
        listed.iter().copied(),
        &[],
        "import-ur-calibration",
        &options.robot.display().to_string(),
    );
    out.measurement = None;
    let toml = out.to_toml(&format!(
        "{} with the factory calibration {} (UR classic DH deltas) as Hayati errors, written by calib import-ur-calibration.\n\
         It reproduces the calibrated classic DH to {:.1e} mm and {:.1e} rad on {} random configurations.",
        file.name,
        options.calibration.display(),
        import.max_position_mm,
        import.max_rotation_rad,
        host_tools::formats::ur_calibration::CHECK_POSES
    ));
    let mut outputs = Outputs::new(&[
        ("--robot", &options.robot),
        ("--calibration", &options.calibration),
    ]);
    outputs.stage("--out", &options.out, toml.as_bytes())?;
    outputs.commit()?;
    let mut text = format!(
        "imported {}: the calibration moves the flange by up to {:.3} mm; the Hayati model reproduces it to {:.1e} mm and {:.1e} rad\n",
        options.calibration.display(),
        import.max_change_mm,
        import.max_position_mm,
        import.max_rotation_rad
    );
    for p in &listed {
        let value = import.errors.get(*p).unwrap_or(0.0);
        let shown = if p.is_angle() {
            format!("{:>12.6} deg", value.to_degrees())
        } else {
            format!("{value:>12.6} mm")
        };
        text.push_str(&format!("  {:<10} {shown}\n", p.to_string()));
    }
    for problem in &problems {
        text.push_str(&format!(
            "warning: implausible, written as asked: {problem}\n"
        ));
    }
    text.push_str(&format!("wrote {}\n", options.out.display()));
    Ok((import, text))
}
