//! `calib evaluate`: the paper's Table 3 statistics of any robot model on any data, the frames of
//! tracker data fitted first ([`host_tools::analysis::evaluation`]).

use host_tools::analysis::evaluation::Evaluation;
use host_tools::measurement::frames::Frames;

/// Options of `calib evaluate`.
#[derive(Clone, Debug, clap::Args)]
#[command(mut_arg("robot", |a| a.help("Robot model file (TOML): a nominal or an identified model")))]
pub struct EvaluateOptions {
    /// Robot, data and data profile files.
    #[command(flatten)]
    pub input: crate::cli::InputFiles,
    /// Frames of the measurement setup fitted before the statistics, the geometry kept (default
    /// base+tool unless the data say `# frame: base`; none: the data must be in the base frame).
    #[arg(long, value_enum)]
    pub fit_frames: Option<Frames>,
    /// Fit the frames on this many poses, chosen at random (--seed) as `calibrate --validate`
    /// chooses its calibration poses, and compute the statistics on the others only. Without it,
    /// all poses serve both (and the statistics flatter the model).
    #[arg(long, value_name = "POSES")]
    pub fit_poses: Option<usize>,
    /// Seed of the choice of --fit-poses (as --validate-seed of calibrate; default 0; refused
    /// without --fit-poses).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Use the registration stored with an identified model (its `[measurement]` section: the
    /// tracker's view of the base and the probe) instead of fitting frames: how well the model
    /// and its registration predict new data of the same set-up.
    #[arg(long, conflicts_with_all = ["fit_frames", "fit_poses"])]
    pub stored_registration: bool,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `calib evaluate`.
pub fn evaluate(options: &EvaluateOptions) -> anyhow::Result<Evaluation> {
    host_tools::model::counts::joint_count(options.input.joints()?)?;
    let (_, dataset) = options.input.load()?;
    evaluate_dataset(options, dataset)
}

/// [`evaluate`] on the data already read and checked against the robot (`dataset`): the options
/// as the library's request ([`host_tools::analysis::evaluation::evaluate_model`]).
pub fn evaluate_dataset(
    options: &EvaluateOptions,
    dataset: host_tools::measurement::dataset::Dataset,
) -> anyhow::Result<Evaluation> {
    use host_tools::analysis::evaluation::{FitPoses, Registration};
    if options.seed.is_some() && options.fit_poses.is_none() {
        anyhow::bail!(
            "--seed chooses the --fit-poses poses, and none are chosen: give --fit-poses N, or drop --seed"
        );
    }
    let registration = if options.stored_registration {
        Registration::Stored
    } else {
        Registration::Fit(options.fit_frames)
    };
    let fit_poses = options.fit_poses.map(|count| FitPoses {
        count,
        seed: options.seed.unwrap_or(0),
    });
    Ok(host_tools::analysis::evaluation::evaluate_model(
        &dataset,
        registration,
        fit_poses,
    )?)
}
