//! What a plan is asked for ([`PlanRequest`]): where the candidate configurations come from, how
//! many poses, what the tracker measures, the noise; and the policy of `calib plan` that turns it
//! into a [`Plan`] (the noise from a previous calibration's report, a core large enough to
//! determine the parameters alone). `calib plan` and Python's `plan` build the same request.

use super::{Measure, Plan, PlanModel, PlanSettings};
use crate::io::profile::DataProfile;
use crate::io::robot_file::RobotFile;
use crate::io::tracker_data::TrackerData;
use std::path::{Path, PathBuf};

/// Most candidates a plan takes (the greedy selection's time grows with their number).
pub const MAX_CANDIDATES: usize = 100_000;

/// Where the candidate configurations (poses the cell can reach) come from.
#[derive(Clone, Debug, PartialEq)]
pub enum Candidates {
    /// A file of joint configurations: a tracker CSV whose joint columns are read, or another
    /// export through a data profile. Each must lie within the robot file's joint limits.
    File {
        /// The candidates file (`--candidates`).
        path: PathBuf,
        /// The data profile of a file not in our CSV format (`--profile`).
        profile: Option<PathBuf>,
    },
    /// `count` configurations generated within the joint limits (+-180 deg where unlimited), a
    /// Halton sequence (`--generate`).
    Generate {
        /// How many, at most [`MAX_CANDIDATES`].
        count: usize,
        /// Keep only those whose nominal tool point lies in this box of the base frame,
        /// `[x_min, x_max, y_min, y_max, z_min, z_max]` mm (`--box-mm`).
        box_mm: Option<[f64; 6]>,
        /// Without a box: keep those with the tool below the base's mounting plane (z < 0 mm)
        /// too (`--below-base`); by default the tool stays above it.
        below_base: bool,
    },
}

/// The noise of the measurements the plan predicts with.
#[derive(Clone, Debug, PartialEq)]
pub enum Noise {
    /// Stated: per position coordinate, mm (`--noise-mm`), and per orientation axis, deg
    /// (`--noise-deg`; default: the position noise over `sqrt(k)`, the ratio the fit's weight
    /// assumes).
    Given {
        /// 1 sigma per position coordinate, mm.
        mm: f64,
        /// 1 sigma per orientation axis, deg.
        deg: Option<f64>,
    },
    /// The residuals of a previous calibration (`--noise-from`, from its JSON report: see
    /// `calibration::Report::residuals`).
    Residuals(Residuals),
}

/// The residuals of a previous calibration of the robot, for the noise of a plan: the RMS per
/// coordinate and per orientation axis of its calibration poses, corrected for the parameters
/// fitted (`sqrt(rows / (rows - parameters))`). They include the errors the geometric model does
/// not describe.
#[derive(Clone, Debug, PartialEq)]
pub struct Residuals {
    /// Where they come from (a report file), for messages.
    pub source: PathBuf,
    /// Residual rows of its least squares.
    pub rows: u32,
    /// Parameters it identified.
    pub parameters: usize,
    /// RMS position error of its calibration poses after the calibration, mm.
    pub position_rms_mm: f64,
    /// RMS orientation error per axis (x, y, z) after the calibration, deg; `None` for
    /// position-only data.
    pub orientation_rms_deg: Option<[f64; 3]>,
}

impl Residuals {
    /// The noise levels: per position coordinate (mm) and per orientation axis (deg; for
    /// position-only data, the position's weighted by the default k). Refused without residual
    /// degrees of freedom.
    fn levels(&self) -> crate::Result<(f64, f64)> {
        let (rows, parameters) = (f64::from(self.rows), self.parameters as f64);
        if rows.partial_cmp(&parameters) != Some(std::cmp::Ordering::Greater) {
            return Err(crate::refused!(input self.source.display();
                "{}: the calibration has no residual degrees of freedom",
                self.source.display()
            ));
        }
        let dof = (rows / (rows - parameters)).sqrt();
        let position = self.position_rms_mm / 3f64.sqrt() * dof;
        let orientation = match self.orientation_rms_deg {
            Some([x, y, z]) => ((x * x + y * y + z * z) / 3.0).sqrt() * dof,
            // Position-only calibration: the weighted equivalent.
            None => (position / calib_core::identify::objective::DEFAULT_K.sqrt()).to_degrees(),
        };
        Ok((position, orientation))
    }
}

/// A plan asked for: `calib plan`'s options without the outputs.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanRequest {
    /// The candidate configurations.
    pub candidates: Candidates,
    /// Poses to fit (core and fill poses); the verification poses come on top.
    pub poses: usize,
    /// D-optimal core poses among `poses`. `None`: [`super::DEFAULT_CORE`], or the fewest
    /// poses that give as many equations as parameters if that is more.
    pub core: Option<usize>,
    /// Verification poses, measured and kept out of the fit.
    pub verify: usize,
    /// No two plan poses closer than this in joint space (Euclidean over the joints), deg.
    pub min_distance_deg: f64,
    /// What the tracker measures.
    pub measure: Measure,
    /// The model the calibration will identify.
    pub model: PlanModel,
    /// The noise of the measurements.
    pub noise: Noise,
    /// Orientation weight k, mm^2/rad^2 (`--measure pose` only). `None`: eq. (7)'s default.
    pub k: Option<f64>,
    /// Seed of the random fill and verification poses.
    pub seed: u64,
}

impl PlanRequest {
    /// A request with `calib plan`'s defaults for what it does not name: 12 core poses (or
    /// more, see [`PlanRequest::core`]), [`super::DEFAULT_VERIFY`] verification poses,
    /// [`super::DEFAULT_MIN_DISTANCE_DEG`], the geometric model, the default k, seed 1.
    pub fn new(candidates: Candidates, poses: usize, measure: Measure, noise: Noise) -> Self {
        Self {
            candidates,
            poses,
            core: None,
            verify: super::DEFAULT_VERIFY,
            min_distance_deg: super::DEFAULT_MIN_DISTANCE_DEG,
            measure,
            model: PlanModel::Geometric,
            noise,
            k: None,
            seed: 1,
        }
    }

    /// The plan for the robot `file` (read from `robot`). Errors: the request contradicts itself
    /// ([`crate::Error::OptionConflict`], by flag), too many candidates, a candidate outside the
    /// joint limits, a report without residuals, or what the planning refuses.
    pub fn plan(&self, file: &RobotFile, robot: &Path) -> crate::Result<Plan> {
        let candidates = self.candidates(file, robot)?;
        let (noise_mm, noise_deg) = self.noise_levels()?;
        let settings = PlanSettings {
            poses: self.poses,
            // The default fits in the poses asked for; a core given is taken as given (more than
            // the poses is refused, not cut).
            core: self.core.unwrap_or(super::DEFAULT_CORE.min(self.poses)),
            verify: self.verify,
            min_distance_deg: self.min_distance_deg,
            measure: self.measure,
            model: self.model,
            noise_mm,
            noise_deg,
            k: self.k(),
            seed: self.seed,
        };
        let plan = super::plan(file, robot, &candidates, &settings)?;
        // Too few core poses to determine the parameters alone: make the core large enough.
        let needed = plan.parameters.len().div_ceil(self.measure.rows());
        if self.core.is_none() && settings.core < needed && needed <= self.poses {
            let settings = PlanSettings {
                core: needed,
                ..settings
            };
            return super::plan(file, robot, &candidates, &settings);
        }
        Ok(plan)
    }

    /// The orientation weight: `k`, else the default of eq. (7).
    fn k(&self) -> f64 {
        self.k.unwrap_or(calib_core::identify::objective::DEFAULT_K)
    }

    /// The noise levels (mm per position coordinate, deg per orientation axis).
    fn noise_levels(&self) -> crate::Result<(f64, f64)> {
        let position = self.measure == Measure::Position;
        if position && matches!(self.noise, Noise::Given { deg: Some(_), .. }) {
            return Err(crate::Error::conflict(
                &["--noise-deg", "--measure"],
                "--noise-deg is the noise of a measured orientation, and --measure position measures none: drop it, or --measure pose",
            ));
        }
        if position && self.k.is_some() {
            return Err(crate::Error::conflict(
                &["--k", "--measure"],
                "--k weighs measured orientations against positions, and --measure position measures none: drop it, or --measure pose",
            ));
        }
        match &self.noise {
            Noise::Given { mm, deg } => {
                let weighted = (mm / self.k().sqrt()).to_degrees();
                Ok((*mm, deg.unwrap_or(weighted)))
            }
            Noise::Residuals(residuals) => residuals.levels(),
        }
    }

    /// The candidates: read or generated, at most [`MAX_CANDIDATES`].
    fn candidates(&self, file: &RobotFile, robot: &Path) -> crate::Result<Vec<(String, Vec<f64>)>> {
        let candidates = match &self.candidates {
            Candidates::File { path, profile } => {
                read_candidates(path, profile.as_deref(), file, robot)?
            }
            Candidates::Generate {
                count,
                box_mm,
                below_base,
            } => {
                let kept = match (box_mm, below_base) {
                    (Some(_), true) => {
                        return Err(crate::Error::conflict(
                            &["--below-base", "--box-mm"],
                            "--box-mm states the workspace, below the base or not: drop --below-base",
                        ));
                    }
                    (Some([a, b, c, d, e, f]), false) => {
                        if !(a < b && c < d && e < f) {
                            return Err(crate::refused!(option "--box-mm";
                                "--box-mm: each minimum must be below its maximum"
                            ));
                        }
                        Some([*a, *b, *c, *d, *e, *f])
                    }
                    (None, true) => None,
                    // The half space above the mounting plane.
                    (None, false) => Some([
                        f64::NEG_INFINITY,
                        f64::INFINITY,
                        f64::NEG_INFINITY,
                        f64::INFINITY,
                        0.0,
                        f64::INFINITY,
                    ]),
                };
                if *count > MAX_CANDIDATES {
                    return Err(crate::refused!(option "--generate";
                        "--generate {count}: at most {MAX_CANDIDATES} candidates"
                    ));
                }
                super::generate(file, robot, *count, kept)?
            }
        };
        if candidates.len() > MAX_CANDIDATES {
            return Err(crate::refused!(input "the candidates";
                "{} candidates: at most {MAX_CANDIDATES} (thin them out)",
                candidates.len()
            ));
        }
        Ok(candidates)
    }
}

/// The candidates of the file `path` (through `profile`), each within the joint limits of the
/// robot `file`.
fn read_candidates(
    path: &Path,
    profile: Option<&Path>,
    file: &RobotFile,
    robot: &Path,
) -> crate::Result<Vec<(String, Vec<f64>)>> {
    let profile = DataProfile::load(profile)?;
    let records = TrackerData::read_joints(path, &profile)?.records;
    let model = file.to_model(robot)?;
    for r in &records {
        if let Some(outside) = model.outside_limits(&r.q) {
            return Err(crate::refused!(input path.display();
                "{}:{}: candidate {}: {outside}; remove it or correct the limits",
                path.display(),
                r.line,
                r.id
            ));
        }
    }
    Ok(records.into_iter().map(|r| (r.id, r.q)).collect())
}
