//! `calib sockets`: calibration without an instrument, from a ball touched in sockets (joint
//! readings only), through the library's [`TouchSession`].

use host_tools::calibration::CalibrationConfig;
use host_tools::calibration::mixed::TrackerFigures;
use host_tools::calibration::touches::{
    DatumPlane, Gauge, PlacementFigures, TouchCalibrated, TouchReport, TouchSession,
};
use host_tools::io::outputs::Outputs;
use host_tools::io::robot_file::RobotFile;
use std::path::PathBuf;

/// Options of `calib sockets`.
#[derive(Clone, Debug, clap::Args)]
pub struct SocketsOptions {
    /// Robot model file (TOML): the nominal model; its identify lists (or the default rule)
    /// select the joints' parameters.
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// The touches: a folder in the MUKCa layout (PLACEMENT/hole_0.csv, hole_1.csv, ...:
    /// radians, no header) or our CSV file (placement,socket,q1_deg,...; see USAGE).
    #[arg(long, value_name = "PATH")]
    pub data: PathBuf,
    /// The ball's centre in the robot file's tool frame (its flange when the file gives no
    /// tool), nominal, mm (identified with the geometry).
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    pub ball_mm: Vec<f64>,
    /// The placements fitted, comma-separated (default: all); the others are held out and
    /// judged.
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    pub train: Vec<String>,
    /// The known distance between sockets.
    #[command(flatten)]
    pub gauge: GaugeOptions,
    /// Also judge each placement by a calibration of all the others (leave one placement
    /// out), printed and in the report; the identified file is the one of --train.
    #[arg(long, conflicts_with = "tracker")]
    pub leave_one_out: bool,
    /// A plane known in the robot's base frame, repeatable: plane N (plane_N.csv, or N in the
    /// column plane) of every placement lies where the ball's centre has NX x + NY y + NZ z =
    /// OFFSET mm (the normal is normalised, OFFSET is along it; the surface moved out by the
    /// ball's radius), such as 0:0,0,1,-10 for a table 10 mm below the base's origin less the
    /// radius. Its contacts are judged against it, not against their best plane.
    #[arg(long, value_name = "N:NX,NY,NZ,OFFSET", value_parser = parse_datum)]
    pub datum_plane: Vec<DatumPlane>,
    /// Positions of the same ball measured by a laser tracker, fitted with the touches: a CSV
    /// file with the header q1_deg,...,qN_deg,x_mm,y_mm,z_mm (or the joints in _rad), the
    /// ball's centre in the tracker's frame. At least three, spread: they place the robot in
    /// the tracker's frame and fix the scale, which touches alone cannot.
    #[arg(long, value_name = "FILE")]
    pub tracker: Option<PathBuf>,
    /// The tracker's standard uncertainty per coordinate, mm (its weight against the touches,
    /// whose scatter is estimated from the data).
    #[arg(long, value_name = "MM", default_value_t = 0.02, requires = "tracker")]
    pub tracker_sd: f64,
    /// Also fit the joints' torsion under gravity (joints 2 to N - 2, gains in urad per N m,
    /// not negative; the moments from the robot file's `[dynamics]` masses), kept only when it
    /// predicts left-out touches of the fitted placements better (five folds); the identified
    /// file then carries it as `[compliance]`.
    #[arg(long, conflicts_with = "tracker")]
    pub compliance: bool,
    /// Keep parameters the configurations barely determine (default: dropped while the scaled
    /// condition number exceeds 1000, as for tracker data).
    #[arg(long)]
    pub keep_ill_conditioned: bool,
    /// Write the identified robot file here (the joints' errors; base and tool as given).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Write the JSON report here.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Write the certificate here: one self-contained HTML page stating consistency and the
    /// known distance's error (never as absolute accuracy) and what the data could not
    /// determine (also from the JSON report: calib report --from).
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,
    /// The certificate printed to a PDF on A4 (needs a headless Chromium: chromium,
    /// chromium-browser or google-chrome).
    #[arg(long, value_name = "FILE")]
    pub pdf: Option<PathBuf>,
    /// The command line, for the report (set by the `calib` binary; empty otherwise).
    #[arg(skip)]
    pub command_line: Vec<String>,
}

/// The known distance between two sockets of every placement, as `calib sockets` and `calib
/// plan-sockets` take it.
#[derive(Clone, Debug, clap::Args)]
pub struct GaugeOptions {
    /// The known distance between two sockets of every placement, mm (MUKCa: 50): fixes the
    /// scale, which touches alone leave free.
    #[arg(long, value_name = "MM")]
    pub distance: Option<f64>,
    /// The standard uncertainty of that distance, mm.
    #[arg(long, value_name = "MM", default_value_t = 0.05, requires = "distance")]
    pub distance_sd: f64,
    /// The two sockets the distance is between.
    #[arg(long, value_name = "A,B", value_delimiter = ',', default_values_t = [0u16, 1], requires = "distance")]
    pub distance_between: Vec<u16>,
}

impl GaugeOptions {
    /// The gauge asked for, if any.
    pub fn gauge(&self) -> anyhow::Result<Option<Gauge>> {
        let [a, b] = self.distance_between[..] else {
            anyhow::bail!("--distance-between: give two socket numbers A,B, such as 0,1");
        };
        Ok(self.distance.map(|mm| Gauge {
            sockets: [a, b],
            mm,
            sd_mm: self.distance_sd,
        }))
    }
}

/// A datum plane as `--datum-plane` takes it: `N:NX,NY,NZ,OFFSET`, the normal normalised.
fn parse_datum(text: &str) -> Result<DatumPlane, String> {
    let usage = || {
        format!(
            "\"{text}\": give N:NX,NY,NZ,OFFSET, the plane's number, its normal in the base frame and the ball centre's offset along it in mm, such as 0:0,0,1,-10"
        )
    };
    let (plane, rest) = text.split_once(':').ok_or_else(usage)?;
    let plane: u16 = plane.trim().parse().map_err(|_| usage())?;
    let numbers: Vec<f64> = (rest.split(','))
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| usage())?;
    let [x, y, z, offset] = numbers[..] else {
        return Err(usage());
    };
    let length = (x * x + y * y + z * z).sqrt();
    if !(length.is_finite() && length > 0.0 && offset.is_finite()) {
        return Err(format!(
            "\"{text}\": the normal must be a finite non-zero vector and the offset a finite number of mm"
        ));
    }
    Ok(DatumPlane {
        plane,
        normal: [x / length, y / length, z / length],
        offset_mm: offset,
    })
}

/// Runs `calib sockets`: calibrates, writes the outputs asked for, returns the text to print.
pub fn sockets(options: &SocketsOptions) -> anyhow::Result<String> {
    let [x, y, z] = options.ball_mm[..] else {
        anyhow::bail!(
            "--ball-mm: give the ball's centre as three numbers X,Y,Z in mm, not {}",
            options.ball_mm.len()
        );
    };
    let robot = RobotFile::read(&options.robot)?;
    let joints = robot.joint.len();
    host_tools::model::counts::joint_count(joints)?;
    let placements = if options.data.is_dir() {
        host_tools::io::sockets::read_layout(&options.data, joints)?
    } else {
        host_tools::io::sockets::read_touches_csv(&options.data, joints)?
    };
    let session = TouchSession {
        robot,
        robot_path: options.robot.clone(),
        ball_mm: [x, y, z],
        placements,
        train: options.train.clone(),
        gauge: options.gauge.gauge()?,
        datums: options.datum_plane.clone(),
        config: CalibrationConfig {
            keep_ill_conditioned: options.keep_ill_conditioned,
            ..CalibrationConfig::default()
        },
        compliance: options.compliance,
    };
    let (calibrated, tracker) = match &options.tracker {
        Some(path) => {
            let mixed = host_tools::calibration::mixed::MixedSession {
                tracker: host_tools::io::sockets::read_tracker_csv(path, joints)?,
                tracker_sd_mm: options.tracker_sd,
                touches: session.clone(),
            }
            .run()?;
            (mixed.calibrated, Some(mixed.tracker))
        }
        None => (session.run()?, None),
    };
    let left_out = if options.leave_one_out {
        session.leave_one_out()?
    } else {
        Vec::new()
    };
    write_outputs(
        options,
        &session,
        (&calibrated, tracker.as_ref()),
        &left_out,
    )?;
    let mut text = host_tools::report::touches::touches_text(&calibrated);
    if let Some(tracker) = &tracker {
        text.push_str(&host_tools::report::touches::tracker_text(tracker));
    }
    if options.leave_one_out {
        text.push_str(&host_tools::report::touches::leave_one_out_text(&left_out));
    }
    Ok(text)
}

/// Writes the identified robot file, the report and the certificate, all or nothing.
fn write_outputs(
    options: &SocketsOptions,
    session: &TouchSession,
    (calibrated, tracker): (&TouchCalibrated, Option<&TrackerFigures>),
    left_out: &[PlacementFigures],
) -> anyhow::Result<()> {
    let mut inputs = vec![
        ("--robot", options.robot.as_path()),
        ("--data", &options.data),
    ];
    inputs.extend(options.tracker.as_deref().map(|t| ("--tracker", t)));
    let mut outputs = Outputs::new(&inputs);
    let contents = TouchReport {
        leave_one_out: left_out.to_vec(),
        command_line: options.command_line.clone(),
        inputs: input_files(options, session)?,
        tracker: tracker.cloned(),
        ..calibrated.report(session)
    };
    if let Some(out) = &options.out {
        let header = format!(
            "{} identified by calib sockets (least squares on touches in sockets) from {}.\nValues are nominal + identified errors; [calibration.errors] lists the joints' errors and [calibration.std_errors] their standard errors, in mm and rad. The ball and the sockets are the measurement setup, not written here.",
            session.robot.name,
            options.data.display()
        );
        outputs.stage("--out", out, calibrated.file.to_toml(&header).as_bytes())?;
    }
    if let Some(report) = &options.report {
        let json = serde_json::to_string_pretty(&contents)?;
        outputs.stage("--report", report, format!("{json}\n").as_bytes())?;
    }
    if options.html.is_some() || options.pdf.is_some() {
        let rendering = host_tools::report::html::Rendering::now();
        let page = host_tools::report::touch_certificate::render(&contents, &rendering)?;
        if let Some(pdf) = &options.pdf {
            outputs.stage("--pdf", pdf, &host_tools::report::pdf::print(&page)?)?;
        }
        if let Some(html) = &options.html {
            outputs.stage("--html", html, page.as_bytes())?;
        }
    }
    outputs.commit()?;
    Ok(())
}

/// The input files with their SHA-256: the robot file, then every file of touches read (a
/// folder's files one by one).
fn input_files(
    options: &SocketsOptions,
    session: &TouchSession,
) -> anyhow::Result<Vec<host_tools::io::provenance::InputFile>> {
    use host_tools::io::provenance::InputFile;
    let mut files = vec![InputFile::of("--robot", &options.robot)?];
    if options.data.is_dir() {
        for placement in &session.placements {
            for file in placement.sockets.iter().chain(&placement.planes) {
                files.push(InputFile::of("--data", &file.path)?);
            }
        }
    } else {
        files.push(InputFile::of("--data", &options.data)?);
    }
    if let Some(tracker) = &options.tracker {
        files.push(InputFile::of("--tracker", tracker)?);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `--datum-plane N:NX,NY,NZ,OFFSET`: the normal normalised, the offset kept; a zero normal,
    /// a missing number or no plane number refused with the form to give.
    #[test]
    fn a_datum_plane_as_the_command_line_gives_it() {
        let datum = parse_datum("2:0,0,-2,-12.5").unwrap();
        assert_eq!(datum.plane, 2);
        assert_eq!(datum.normal, [0.0, 0.0, -1.0]);
        assert_eq!(datum.offset_mm, -12.5);
        assert!(parse_datum("0:0,0,0,1").unwrap_err().contains("non-zero"));
        for bad in ["0,0,1,5", "0:0,0,1", "a:0,0,1,5", "0:0,0,1,x"] {
            assert!(
                parse_datum(bad).unwrap_err().contains("N:NX,NY,NZ,OFFSET"),
                "{bad}"
            );
        }
    }
}
