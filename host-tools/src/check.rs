//! Loading a robot and its measurements for the core, and `calib check`: the identifiability of
//! the identified parameters from a data set, without calibrating.

use crate::profile::DataProfile;
use crate::robot_file::{RobotFile, RobotModel};
use crate::tracker_data::TrackerData;
use anyhow::{Context, bail};
use calib_core::Problem;
use calib_core::identify::identifiability::{DEFAULT_RANK_TOLERANCE, Identifiability, Status};
use calib_core::identify::lm::LeastSquares;
use calib_core::identify::objective::Measurement;
use calib_core::{Parameter, ParameterErrors, ParameterMask, ParameterSet};
use nalgebra::{SVector, Vector3};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// A robot file, a data file and the measurements prepared for the core.
#[derive(Clone)]
pub struct Inputs {
    /// The robot file as read.
    pub file: RobotFile,
    /// The robot in core units, with its identification mask.
    pub model: RobotModel<6>,
    /// The data file as read.
    pub data: TrackerData,
    /// One core measurement per data row.
    pub measurements: Vec<Measurement<f64, 6>>,
}

/// The files a data command reads (`--robot`, `--data`, `--profile`), shared by `calibrate`,
/// `check`, `evaluate` and `verify`.
#[derive(Clone, Debug, clap::Args)]
pub struct InputFiles {
    /// Robot model file (TOML): the nominal model; its identify lists (or the default rule)
    /// select the parameters.
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// Tracker data file: our CSV, or another export read through --profile.
    #[arg(long, value_name = "FILE")]
    pub data: PathBuf,
    /// Data profile (TOML) for exports not in our CSV format: delimiter, decimal comma, column
    /// mapping with units, Euler convention (see host-tools/profiles/).
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
}

impl InputFiles {
    /// The data profile, then both files read and checked through it.
    pub fn load(&self) -> anyhow::Result<(DataProfile, Inputs)> {
        let profile = DataProfile::load(self.profile.as_deref())?;
        let inputs = Inputs::load_with(&self.robot, &self.data, &profile)?;
        Ok((profile, inputs))
    }
}

impl Inputs {
    /// Reads and checks both files (the data in our format).
    pub fn load(robot: &Path, data: &Path) -> anyhow::Result<Self> {
        Self::load_with(robot, data, &DataProfile::default())
    }

    /// Reads and checks both files, the data through a data profile.
    pub fn load_with(robot: &Path, data: &Path, profile: &DataProfile) -> anyhow::Result<Self> {
        let file = RobotFile::read(robot)?;
        let model: RobotModel<6> = file.to_model(robot)?;
        let data_file = TrackerData::read_with(data, profile)?;
        if data_file.joints != 6 {
            bail!(
                "{}:{}: has {} joint columns, the robot {} has 6 joints",
                data.display(),
                data_file.header_line,
                data_file.joints,
                model.name
            );
        }
        let mut measurements = Vec::with_capacity(data_file.records.len());
        for r in &data_file.records {
            let q: [f64; 6] = std::array::from_fn(|i| r.q[i]);
            for (i, (qi, limits)) in q.iter().zip(&model.robot.limits).enumerate() {
                if !limits.contains(*qi) {
                    bail!(
                        "{}:{}: column q{}: {:.4} deg is outside the joint limits [{}, {}] deg of {}",
                        data.display(),
                        r.line,
                        i + 1,
                        qi.to_degrees(),
                        limits.lower.to_degrees(),
                        limits.upper.to_degrees(),
                        robot.display()
                    );
                }
            }
            let m = Measurement::new(&q, Vector3::from(r.position), r.rotation, r.weight)
                .with_context(|| format!("{}:{}", data.display(), r.line))?;
            measurements.push(m);
        }
        Ok(Self {
            file,
            model,
            data: data_file,
            measurements,
        })
    }

    /// `(the others, the poses at indices)`: the data split in two, file order kept.
    pub fn partition(&self, indices: &[usize]) -> (Self, Self) {
        let mut kept = self.clone();
        let mut taken = self.clone();
        kept.data.records.clear();
        kept.measurements.clear();
        taken.data.records.clear();
        taken.measurements.clear();
        for (i, (record, m)) in self.data.records.iter().zip(&self.measurements).enumerate() {
            let side = if indices.contains(&i) {
                &mut taken
            } else {
                &mut kept
            };
            side.data.records.push(record.clone());
            side.measurements.push(*m);
        }
        (kept, taken)
    }

    /// Number of residual rows: 6 per full pose, 3 per position-only pose.
    pub fn rows(&self) -> usize {
        self.measurements
            .iter()
            .map(|m| if m.rotation.is_some() { 6 } else { 3 })
            .sum()
    }
}

/// Scaled condition number above which a pose set is reported as ill-conditioned: the weakest
/// parameter combination is then determined more than 1000 times worse than the best one, so
/// noise and unmodelled errors leak into it amplified.
pub const ILL_CONDITIONED: f64 = 1000.0;

/// A parameter the data do not determine.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Undetermined {
    /// Parameter name.
    pub name: String,
    /// `not identifiable` (changes no residual) or `redundant`.
    pub status: &'static str,
    /// For a redundant one: the determined parameters it is confounded with, and the coefficient
    /// in scaled units (its column equals the sum of coefficient times their columns).
    pub with: Vec<(String, f64)>,
}

/// The identifiability analysis in report form.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IdentifiabilityReport {
    /// Number of identified parameters analysed.
    pub parameters: usize,
    /// Numerical rank of the scaled Jacobian.
    pub rank: usize,
    /// Condition number of the scaled Jacobian (null when rank-deficient).
    pub condition_number: Option<f64>,
    /// Observability index O1 (Borm and Menq) of the pose set, scaled Jacobian.
    pub observability_index: f64,
    /// Singular values of the scaled Jacobian, largest first.
    pub singular_values: Vec<f64>,
    /// Parameters the data cannot determine, in pivot order.
    pub undetermined: Vec<Undetermined>,
    /// The least determined direction: the right singular vector of the smallest singular value
    /// of the scaled Jacobian, as (parameter, component) for components of magnitude >= 0.2,
    /// largest first. These are the parameters an ill-conditioned pose set leaves uncertain.
    pub weakest_direction: Vec<(String, f64)>,
    /// `true` when the condition number exceeds [`ILL_CONDITIONED`] (or the rank is deficient).
    pub ill_conditioned: bool,
    /// With `--auto-mask`: the condition number after dropping parameters.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub condition_number_after_drop: Option<f64>,
    /// The analysed parameter names, in order.
    #[serde(skip)]
    pub names: Vec<Parameter>,
}

impl IdentifiabilityReport {
    /// The parameters to drop so that the rest are determined.
    pub fn to_drop(&self) -> Vec<Parameter> {
        self.undetermined
            .iter()
            .filter_map(|u| self.names.iter().find(|p| p.to_string() == u.name).copied())
            .collect()
    }

    /// A sentence naming what the data cannot determine.
    pub fn problem(&self) -> String {
        self.undetermined
            .iter()
            .map(|u| {
                if u.with.is_empty() {
                    format!("{} ({})", u.name, u.status)
                } else {
                    let with: Vec<&str> = u.with.iter().map(|(n, _)| n.as_str()).collect();
                    format!("{} (redundant with {})", u.name, with.join(", "))
                }
            })
            .collect::<Vec<_>>()
            .join("; ")
    }

    /// The warning for an ill-conditioned pose set: the condition number and the parameters of
    /// the weakest direction.
    pub fn ill_conditioned_text(&self) -> String {
        let weakest: Vec<String> = self
            .weakest_direction
            .iter()
            .map(|(n, v)| format!("{v:+.2} {n}"))
            .collect();
        format!(
            "WARNING: the pose set is ill-conditioned (scaled condition number {}, above {ILL_CONDITIONED}): \
             the data barely determine the combination {}; its identified values follow the noise and unmodelled \
             errors. Add poses with other joint configurations (e.g. both wrist flips, both elbows), or drop those \
             parameters (identify = [...] in the robot file)\n",
            self.condition_number
                .map_or_else(|| "infinite".to_string(), |c| format!("{c:.3e}")),
            weakest.join(" ")
        )
    }

    /// Fixed-width text for people.
    pub fn text(&self) -> String {
        let mut out = format!(
            "identifiability of {} parameters: rank {}{}\n",
            self.parameters,
            self.rank,
            match self.condition_number {
                Some(c) => format!(", scaled condition number {c:.3}"),
                None => ", rank-deficient".to_string(),
            }
        );
        out.push_str(&format!(
            "observability index O1: {:.4e}\n",
            self.observability_index
        ));
        if self.ill_conditioned && self.rank == self.parameters {
            out.push_str(&self.ill_conditioned_text());
        }
        let values: Vec<String> = self
            .singular_values
            .iter()
            .map(|s| format!("{s:.3e}"))
            .collect();
        out.push_str(&format!("scaled singular values: {}\n", values.join(" ")));
        if self.undetermined.is_empty() {
            out.push_str("every parameter is determined by the data\n");
        }
        for u in &self.undetermined {
            if u.with.is_empty() {
                out.push_str(&format!(
                    "  {:<10} {}: it changes no residual\n",
                    u.name, u.status
                ));
            } else {
                let with: Vec<String> =
                    u.with.iter().map(|(n, c)| format!("{c:+.4} {n}")).collect();
                out.push_str(&format!(
                    "  {:<10} {}: acts like {} (scaled units); only their combination is determined\n",
                    u.name,
                    u.status,
                    with.join(" ")
                ));
            }
        }
        out
    }
}

/// The identifiability of the parameters selected by `mask` at the nominal model.
pub fn analyse<const D: usize>(
    inputs: &Inputs,
    mask: &ParameterMask<6>,
    k: f64,
) -> anyhow::Result<IdentifiabilityReport> {
    let set = ParameterSet::<6, D>::from_mask(mask)?;
    if inputs.rows() < D {
        bail!(
            "{} poses give {} equations, fewer than the {D} identified parameters",
            inputs.measurements.len(),
            inputs.rows()
        );
    }
    let problem = Problem::new(
        &inputs.model.robot,
        &ParameterErrors::zero(),
        set,
        &inputs.measurements,
        k,
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    let least_squares = LeastSquares::new(&problem);
    let r = least_squares.jacobian_factor(&SVector::zeros());
    let id = Identifiability::from_factor(&r, inputs.measurements.len(), DEFAULT_RANK_TOLERANCE);
    let names = set.parameters().to_vec();
    let mut undetermined = Vec::new();
    for index in id.pivots.iter().skip(id.rank) {
        let (Some(parameter), Some(status)) = (names.get(*index), id.status.get(*index)) else {
            continue;
        };
        let with = id
            .combination(*index, 1e-6)
            .map(|c| {
                c.iter()
                    .zip(&names)
                    .filter(|(v, _)| **v != 0.0)
                    .map(|(v, p)| (p.to_string(), *v))
                    .collect()
            })
            .unwrap_or_default();
        undetermined.push(Undetermined {
            name: parameter.to_string(),
            status: match status {
                Status::NotIdentifiable => "not identifiable",
                _ => "redundant",
            },
            with: if *status == Status::NotIdentifiable {
                Vec::new()
            } else {
                with
            },
        });
    }
    let weakest_direction = weakest_direction(&r, &names);
    let ill_conditioned =
        !(id.condition_number.is_finite() && id.condition_number <= ILL_CONDITIONED);
    Ok(IdentifiabilityReport {
        weakest_direction,
        ill_conditioned,
        condition_number_after_drop: None,
        parameters: D,
        rank: id.rank,
        condition_number: id
            .condition_number
            .is_finite()
            .then_some(id.condition_number),
        observability_index: id.observability,
        singular_values: id.singular_values.iter().copied().collect(),
        undetermined,
        names,
    })
}

/// The right singular vector of the smallest singular value of the column-scaled factor `r`.
fn weakest_direction<const D: usize>(
    r: &nalgebra::SMatrix<f64, D, D>,
    names: &[Parameter],
) -> Vec<(String, f64)> {
    let mut scaled = nalgebra::DMatrix::from_fn(D, D, |i, j| r[(i, j)]);
    for mut column in scaled.column_iter_mut() {
        let norm = column.norm();
        if norm > 0.0 {
            column /= norm;
        }
    }
    let svd = scaled.svd(false, true);
    let Some(v_t) = svd.v_t else {
        return Vec::new();
    };
    let smallest = svd.singular_values.argmin().0;
    let mut out: Vec<(String, f64)> = v_t
        .row(smallest)
        .iter()
        .zip(names)
        .filter(|(v, _)| v.abs() >= 0.2)
        .map(|(v, p)| (p.to_string(), *v))
        .collect();
    out.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    out
}

/// Options of `calib check`.
#[derive(Clone, Debug, clap::Args)]
pub struct CheckOptions {
    /// Robot, data and data profile files.
    #[command(flatten)]
    pub input: InputFiles,
    /// Frames identified with the geometry (as for calibrate; default base+tool unless the data
    /// say `# frame: base`).
    #[arg(long, value_enum)]
    pub frames: Option<crate::frames::Frames>,
    /// Orientation weight k, mm^2/rad^2 (as for calibrate).
    #[arg(long, default_value_t = calib_core::identify::objective::DEFAULT_K)]
    pub k: f64,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `calib check`: the identifiability analysis of a robot file's parameters on a data file.
pub fn check(options: &CheckOptions) -> anyhow::Result<IdentifiabilityReport> {
    let (_, mut inputs) = options.input.load()?;
    let frames = crate::frames::Frames::chosen(options.frames, &inputs.data);
    let (_, mask) = crate::frames::prepare(frames, &mut inputs, &mut [], options.k)?;
    crate::with_parameter_count!(mask.count(), analyse(&inputs, &mask, options.k))
}
