//! `calib plan-sockets`: which configurations to record in each socket of a placement, and what
//! a calibration from them will give, through the library's
//! [`host_tools::calibration::touch_plan`].

use host_tools::calibration::touch_plan::{TouchPlanRequest, plan_touches};
use host_tools::io::outputs::Outputs;
use host_tools::io::robot_file::RobotFile;
use std::path::PathBuf;

/// Options of `calib plan-sockets`.
#[derive(Clone, Debug, clap::Args)]
pub struct PlanSocketsOptions {
    /// Robot model file (TOML): the nominal model and its joint limits.
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// The ball's centre in the robot file's tool frame (its flange when the file gives no
    /// tool), mm.
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    pub ball_mm: Vec<f64>,
    /// A socket's centre in the robot's base frame, mm; once per socket, numbered in order.
    #[arg(
        long = "socket",
        value_name = "X,Y,Z",
        allow_hyphen_values = true,
        required = true
    )]
    pub sockets: Vec<String>,
    /// Configurations to record per socket.
    #[arg(long, value_name = "N", default_value_t = 25)]
    pub per_socket: usize,
    /// Starting configurations tried per socket (Halton over the joint limits); the candidates
    /// are those that reach it.
    #[arg(long, value_name = "N", default_value_t = 400)]
    pub starts: usize,
    /// The touches' expected scatter per coordinate, mm (a printed MUKCa tool on a Panda: 0.1).
    #[arg(long, value_name = "MM", default_value_t = 0.1)]
    pub touch_sd: f64,
    /// The known distance between sockets.
    #[command(flatten)]
    pub gauge: super::sockets::GaugeOptions,
    /// A candidate place for the next placement: where its first socket would go (the others
    /// keep their offsets), base frame, mm; once per candidate. Each is planned the same way and
    /// ranked by what it adds.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub next: Vec<String>,
    /// Write the planned configurations here (our touch CSV, joints in degrees).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// Runs `calib plan-sockets`: plans, writes the file asked for, returns the text to print.
pub fn plan_sockets(options: &PlanSocketsOptions) -> anyhow::Result<String> {
    let three = |text: &str, what: &str| -> anyhow::Result<[f64; 3]> {
        let values: Vec<f64> = (text.split(','))
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| anyhow::anyhow!("{what} {text}: give three numbers X,Y,Z in mm"))?;
        <[f64; 3]>::try_from(values)
            .map_err(|_| anyhow::anyhow!("{what} {text}: give three numbers X,Y,Z in mm"))
    };
    let [x, y, z] = options.ball_mm[..] else {
        anyhow::bail!("--ball-mm: give the ball's centre as three numbers X,Y,Z in mm");
    };
    let sockets_mm = (options.sockets.iter())
        .map(|s| three(s, "--socket"))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let robot = RobotFile::read(&options.robot)?;
    let request = TouchPlanRequest {
        robot,
        robot_path: options.robot.clone(),
        ball_mm: [x, y, z],
        sockets_mm,
        per_socket: options.per_socket,
        starts: options.starts,
        touch_sd_mm: options.touch_sd,
        gauge: options.gauge.gauge()?,
        next: (options.next.iter())
            .map(|s| three(s, "--next"))
            .collect::<anyhow::Result<Vec<_>>>()?,
    };
    let plan = plan_touches(&request)?;
    if let Some(out) = &options.out {
        let mut outputs = Outputs::new(&[("--robot", &options.robot)]);
        outputs.stage("--out", out, plan.csv().as_bytes())?;
        outputs.commit()?;
    }
    Ok(plan.text())
}

/// Runs `calib plan-sockets` and prints its text and what it wrote.
pub fn run(options: &PlanSocketsOptions) -> anyhow::Result<()> {
    let text = plan_sockets(options)?;
    super::print_text(format_args!("{text}"))?;
    if let Some(path) = &options.out {
        super::print_line(format_args!("wrote {}", path.display()))?;
    }
    Ok(())
}
