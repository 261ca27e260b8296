//! `calib evaluate`: the paper's Table 3 statistics of any robot model on any data, and the
//! held-out split used for validation.

use crate::check::Inputs;
use crate::report::Table3;
use calib_core::Kinematics;
use calib_core::identify::statistics::PoseStatistics;
use rand_core::{Rng, SeedableRng};

/// Table 3 statistics of `kinematics` on `inputs`, and `|dp|` per pose (mm).
pub fn table3(kinematics: &Kinematics<f64, 6>, inputs: &Inputs) -> (Table3, Vec<f64>) {
    let mut stats = PoseStatistics::default();
    let mut per_pose = Vec::with_capacity(inputs.measurements.len());
    for m in &inputs.measurements {
        let error = m.error_of(&kinematics.forward_angles(&m.angles));
        stats.add(&error, m.rotation.is_some());
        per_pose.push(error.position.norm());
    }
    (Table3::from_statistics(&stats), per_pose)
}

/// `|dr_x|, |dr_y|, |dr_z|` (deg) of `kinematics` for every pose of `inputs` that has an
/// orientation, in file order.
pub fn orientation_per_pose(kinematics: &Kinematics<f64, 6>, inputs: &Inputs) -> Vec<[f64; 3]> {
    inputs
        .measurements
        .iter()
        .filter(|m| m.rotation.is_some())
        .map(|m| {
            let e = m.error_of(&kinematics.forward_angles(&m.angles));
            [0, 1, 2].map(|i| e.rotation[i].abs().to_degrees())
        })
        .collect()
}

/// Options of `calib evaluate`.
#[derive(Clone, Debug, clap::Args)]
#[command(mut_arg("robot", |a| a.help("Robot model file (TOML): a nominal or an identified model")))]
pub struct EvaluateOptions {
    /// Robot, data and data profile files.
    #[command(flatten)]
    pub input: crate::check::InputFiles,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `calib evaluate`.
pub fn evaluate(options: &EvaluateOptions) -> anyhow::Result<Table3> {
    let (_, inputs) = options.input.load()?;
    let kinematics =
        Kinematics::nominal(&inputs.model.robot).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(table3(&kinematics, &inputs).0)
}

/// Splits `inputs` into calibration and validation poses: `fraction` of the poses, chosen at
/// random with `seed` (deterministic), are held out.
pub fn split(inputs: &Inputs, fraction: f64, seed: u64) -> anyhow::Result<(Inputs, Inputs)> {
    if !(fraction > 0.0 && fraction < 1.0) {
        anyhow::bail!("--validate must be a fraction between 0 and 1, got {fraction}");
    }
    let n = inputs.measurements.len();
    let held = ((n as f64) * fraction).round() as usize;
    if held == 0 || held >= n {
        anyhow::bail!("--validate {fraction} of {n} poses leaves no pose on one side");
    }
    // Fisher-Yates with a seeded generator.
    let mut order: Vec<usize> = (0..n).collect();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    for i in (1..n).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        order.swap(i, j);
    }
    let mut validation: Vec<usize> = order[..held].to_vec();
    validation.sort_unstable();
    Ok(inputs.partition(&validation))
}
