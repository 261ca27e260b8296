//! The settings of a calibration, with the paper's values as defaults.

use crate::measurement::frames::Frames;

use calib_core::identify::halton::Scrambling;
use calib_core::identify::ipso;
use calib_core::identify::lm::Loss;
use serde::Serialize;

/// The swarm sizes `--swarm` accepts (particles; the swarm's memory is allocated for the size
/// asked, about 24 bytes per particle and identified parameter).
pub const SWARM_SIZES: std::ops::RangeInclusive<usize> = 1..=1000;

/// Identification method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, serde::Deserialize)]
pub enum Method {
    /// The paper's improved particle swarm (Halton start, constriction factor).
    #[serde(rename = "ipso")]
    Ipso,
    /// Levenberg-Marquardt least squares from the nominal model.
    #[serde(rename = "lm")]
    Lm,
    /// The swarm for a global start, then least squares to the noise floor.
    #[value(name = "ipso+lm")]
    #[serde(rename = "ipso+lm")]
    IpsoLm,
}

impl Method {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ipso => "ipso",
            Self::Lm => "lm",
            Self::IpsoLm => "ipso+lm",
        }
    }

    /// `true` when the swarm runs.
    pub fn swarm(self) -> bool {
        self != Self::Lm
    }

    /// `true` when least squares runs.
    pub fn least_squares(self) -> bool {
        self != Self::Ipso
    }
}

/// Loss of the least-squares stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LossChoice {
    /// Plain least squares.
    L2,
    /// Huber: quadratic up to the scale, linear beyond.
    Huber,
    /// Cauchy: weight 1 / (1 + (r / scale)^2).
    Cauchy,
}

impl LossChoice {
    /// The core's loss with the given scale (mm).
    pub(crate) fn with_scale(self, scale: f64) -> Loss<f64> {
        match self {
            Self::L2 => Loss::L2,
            Self::Huber => Loss::Huber(scale),
            Self::Cauchy => Loss::Cauchy(scale),
        }
    }
}

/// Halton digit scrambling.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScramblingChoice {
    /// Plain Halton, as in the paper.
    None,
    /// Reverse Halton (Vandewoestyne and Cools 2006).
    Reverse,
}

impl From<ScramblingChoice> for Scrambling {
    fn from(choice: ScramblingChoice) -> Self {
        match choice {
            ScramblingChoice::None => Scrambling::None,
            ScramblingChoice::Reverse => Scrambling::Reverse,
        }
    }
}

/// The swarm's settings (the paper's section 2.2).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct SwarmConfig {
    /// Particles: within [`SWARM_SIZES`] (paper: 20).
    pub particles: usize,
    /// Maximum number of generations (paper: 2000).
    pub generations: u32,
    /// Cognitive acceleration coefficient c1 (paper: 2.05; c1 + c2 > 4).
    pub c1: f64,
    /// Social acceleration coefficient c2 (paper: 2.05).
    pub c2: f64,
    /// Seed of the random numbers r1, r2.
    pub seed: u64,
    /// Initial half range of angle errors, rad (paper: 0.01).
    pub init_angle_rad: f64,
    /// Initial half range of length errors, mm (paper: 0.5).
    pub init_length_mm: f64,
    /// Search bounds as a multiple of the initial half range (absorbing walls).
    pub bound_factor: f64,
    /// Stop after this many generations without improvement (0: never).
    pub stall_generations: u32,
    /// Stop as soon as the objective reaches this value.
    #[serde(deserialize_with = "target_or_none")]
    pub target: f64,
    /// Halton index of the first particle (the paper's k; 0 is the all-zero point).
    pub halton_start: u64,
    /// Halton digit scrambling.
    pub scrambling: ScramblingChoice,
}

/// Reads the swarm's target objective back from a report: JSON has no infinity, so the default
/// (no target, minus infinity) is written as `null`.
fn target_or_none<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(<Option<f64> as serde::Deserialize>::deserialize(d)?.unwrap_or(f64::NEG_INFINITY))
}

impl Default for SwarmConfig {
    fn default() -> Self {
        Self {
            particles: 20,
            generations: 2000,
            c1: 2.05,
            c2: 2.05,
            seed: 0,
            init_angle_rad: ipso::PAPER_ANGLE_RANGE,
            init_length_mm: ipso::PAPER_LENGTH_RANGE,
            bound_factor: ipso::DEFAULT_BOUND_FACTOR,
            stall_generations: 0,
            target: f64::NEG_INFINITY,
            halton_start: 1,
            scrambling: ScramblingChoice::None,
        }
    }
}

/// The settings of the paper's improved particle swarm (`--method ipso` and `ipso+lm`). Each is
/// optional: unset, the default of [`SwarmConfig::default`] (the paper's) applies; set with
/// `--method lm`, which runs no swarm, the calibration is refused naming it.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct SwarmOptions {
    /// Swarm size, particles (1 to 1000; default 20, the paper's). Swarm only: refused with
    /// --method lm, as are all the swarm's settings below.
    #[arg(long, value_name = "N")]
    pub swarm: Option<usize>,
    /// Maximum number of generations of the swarm (default 2000).
    #[arg(long, value_name = "N")]
    pub generations: Option<u32>,
    /// Cognitive acceleration coefficient c1 (default 2.05; c1 + c2 > 4).
    #[arg(long)]
    pub c1: Option<f64>,
    /// Social acceleration coefficient c2 (default 2.05).
    #[arg(long)]
    pub c2: Option<f64>,
    /// Seed of the swarm's random numbers r1, r2 (default 0).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Initial half range of angle errors, rad (default 0.01, the paper's).
    #[arg(long)]
    pub init_angle_rad: Option<f64>,
    /// Initial half range of length errors, mm (default 0.5, the paper's).
    #[arg(long)]
    pub init_length_mm: Option<f64>,
    /// Search bounds as a multiple of the initial half range (absorbing walls; default 10).
    #[arg(long)]
    pub bound_factor: Option<f64>,
    /// Stop after this many generations without improvement (default 0: never).
    #[arg(long)]
    pub stall_generations: Option<u32>,
    /// Stop as soon as the objective reaches this value (default: never).
    #[arg(long, allow_hyphen_values = true)]
    pub target: Option<f64>,
    /// Halton index of the first particle (the paper's k; 0 is the all-zero point; default 1).
    #[arg(long)]
    pub halton_start: Option<u64>,
    /// Halton digit scrambling (default none).
    #[arg(long, value_enum)]
    pub scrambling: Option<ScramblingChoice>,
}

impl SwarmOptions {
    /// The swarm configuration: each option given, else the default.
    pub fn config(&self) -> SwarmConfig {
        let d = SwarmConfig::default();
        SwarmConfig {
            particles: self.swarm.unwrap_or(d.particles),
            generations: self.generations.unwrap_or(d.generations),
            c1: self.c1.unwrap_or(d.c1),
            c2: self.c2.unwrap_or(d.c2),
            seed: self.seed.unwrap_or(d.seed),
            init_angle_rad: self.init_angle_rad.unwrap_or(d.init_angle_rad),
            init_length_mm: self.init_length_mm.unwrap_or(d.init_length_mm),
            bound_factor: self.bound_factor.unwrap_or(d.bound_factor),
            stall_generations: self.stall_generations.unwrap_or(d.stall_generations),
            target: self.target.unwrap_or(d.target),
            halton_start: self.halton_start.unwrap_or(d.halton_start),
            scrambling: self.scrambling.unwrap_or(d.scrambling),
        }
    }

    /// The options given, by their flags.
    pub fn given(&self) -> Vec<&'static str> {
        [
            ("--swarm", self.swarm.is_some()),
            ("--generations", self.generations.is_some()),
            ("--c1", self.c1.is_some()),
            ("--c2", self.c2.is_some()),
            ("--seed", self.seed.is_some()),
            ("--init-angle-rad", self.init_angle_rad.is_some()),
            ("--init-length-mm", self.init_length_mm.is_some()),
            ("--bound-factor", self.bound_factor.is_some()),
            ("--stall-generations", self.stall_generations.is_some()),
            ("--target", self.target.is_some()),
            ("--halton-start", self.halton_start.is_some()),
            ("--scrambling", self.scrambling.is_some()),
        ]
        .into_iter()
        .filter_map(|(flag, given)| given.then_some(flag))
        .collect()
    }
}

impl SwarmConfig {
    /// The settings that differ from [`SwarmConfig::default`], by their command-line flags.
    pub fn changed(&self) -> Vec<&'static str> {
        let d = Self::default();
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits();
        [
            ("--swarm", self.particles == d.particles),
            ("--generations", self.generations == d.generations),
            ("--c1", same(self.c1, d.c1)),
            ("--c2", same(self.c2, d.c2)),
            ("--seed", self.seed == d.seed),
            (
                "--init-angle-rad",
                same(self.init_angle_rad, d.init_angle_rad),
            ),
            (
                "--init-length-mm",
                same(self.init_length_mm, d.init_length_mm),
            ),
            ("--bound-factor", same(self.bound_factor, d.bound_factor)),
            (
                "--stall-generations",
                self.stall_generations == d.stall_generations,
            ),
            ("--target", same(self.target, d.target)),
            ("--halton-start", self.halton_start == d.halton_start),
            ("--scrambling", self.scrambling == d.scrambling),
        ]
        .into_iter()
        .filter(|(_, same)| !same)
        .map(|(flag, _)| flag)
        .collect()
    }
}

/// The refusal of the swarm's settings `flags` with `--method lm`, which runs no swarm.
pub fn swarm_without_swarm(flags: &[&str]) -> crate::Error {
    crate::Error::conflict(
        &[flags, &["--method"]].concat(),
        format!(
            "{} set the swarm, and --method lm runs none: drop {}, or use --method ipso or ipso+lm",
            flags.join(", "),
            if flags.len() == 1 { "it" } else { "them" }
        ),
    )
}

/// What a calibration identifies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, serde::Deserialize)]
pub enum Identify {
    /// The geometry (the robot file's identify lists, or the default rule) and the frames.
    #[value(name = "geometry")]
    #[serde(rename = "geometry")]
    Geometry,
    /// Only the frames of the measurement setup (tracker position, reflector or probe); the
    /// geometry of the robot file is kept: re-registration of an identified robot measured again.
    #[value(name = "frames")]
    #[serde(rename = "frames")]
    Frames,
}

/// The error model identified.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, serde::Deserialize)]
pub enum ErrorModel {
    /// The geometry (and the frames of the measurement setup).
    #[value(name = "geometric")]
    #[serde(rename = "geometric")]
    Geometric,
    /// The geometry and each joint's angle-error map, identified jointly with an
    /// evidence-tuned prior ([`crate::model::joint_maps`]).
    #[value(name = "joint-maps")]
    #[serde(rename = "joint-maps")]
    JointMaps,
    /// The joint maps and gravity compliance (bearing tilts of every joint but the wrist's last
    /// two, torsion of the same but joint 1; [`crate::model::compliance::gains`]) from the robot
    /// file's `[dynamics]` masses.
    #[value(name = "joint-maps+compliance")]
    #[serde(rename = "joint-maps+compliance")]
    JointMapsCompliance,
}

impl ErrorModel {
    /// Whether the model has joint maps.
    pub fn maps(self) -> bool {
        self != Self::Geometric
    }
}

/// Everything a calibration needs besides the data. `Default` is the paper's method followed by
/// least squares (`ipso+lm`), `k = 1e6` mm^2/rad^2, the frames chosen from the data.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct CalibrationConfig {
    /// Identification method.
    pub method: Method,
    /// Frames identified with the geometry; `None`: base+tool, or none when the data are in the
    /// base frame.
    pub frames: Option<Frames>,
    /// What is identified: the geometry and the frames, or the frames alone.
    pub identify: Identify,
    /// The error model: geometric, or with joint maps.
    pub model: ErrorModel,
    /// Harmonics per joint of the joint maps (`--harmonics`, 1 to
    /// [`super::maps::evidence::MAX_HARMONICS`]); `None`: chosen by the evidence among 10, 20,
    /// ..., 60.
    pub harmonics: Option<usize>,
    /// Orientation weight k of eq. (7), mm^2/rad^2.
    pub k: f64,
    /// The swarm's settings.
    pub swarm: SwarmConfig,
    /// Iteration cap of the least-squares stage.
    pub lm_iterations: u32,
    /// Loss of the least-squares stage.
    pub loss: LossChoice,
    /// Scale of the robust loss, mm of pose residual; poses beyond it are outliers. `None`:
    /// estimated from the data (the median absolute deviation of the least-squares residuals).
    pub loss_scale_mm: Option<f64>,
    /// Drop what the data cannot determine instead of refusing.
    pub auto_mask: bool,
    /// Keep every parameter when the pose set is ill-conditioned (the default drops, one by one,
    /// the parameter with the largest share of the least determined direction).
    pub keep_ill_conditioned: bool,
    /// Return a result that fails the plausibility check ([`super::plausibility`]) instead of
    /// refusing it; its problems are listed in the result.
    pub accept_implausible: bool,
    /// Acceptance criteria judged on the held-out poses (`--accept`); empty: none stated.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub acceptance: Vec<crate::analysis::accuracy::Criterion>,
    /// The mass the flange carried while measured, kg (`--payload-kg`): stated on the
    /// certificate, not modelled. `None`: the robot file's `[dynamics] tool` mass, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub payload_kg: Option<f64>,
    /// Show a progress bar on a terminal.
    #[serde(skip)]
    pub progress: bool,
    /// Set from another thread to stop the calibration early (the Python package's Ctrl-C).
    #[serde(skip)]
    pub cancel: Cancel,
}

/// A flag another thread sets to stop a calibration: the swarm stops at its next generation and
/// the calibration is refused as cancelled. Clones share the flag; every flag compares equal (it
/// is not a setting).
#[derive(Clone, Debug, Default)]
pub struct Cancel(std::sync::Arc<std::sync::atomic::AtomicBool>);

impl Cancel {
    /// Asks the calibration holding a clone of this flag to stop.
    pub fn cancel(&self) {
        self.0.store(true, std::sync::atomic::Ordering::Relaxed);
    }

    /// `true` once [`Cancel::cancel`] was called.
    pub(crate) fn is_cancelled(&self) -> bool {
        self.0.load(std::sync::atomic::Ordering::Relaxed)
    }
}

impl PartialEq for Cancel {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Default for CalibrationConfig {
    fn default() -> Self {
        Self {
            method: Method::IpsoLm,
            frames: None,
            identify: Identify::Geometry,
            model: ErrorModel::Geometric,
            harmonics: None,
            k: calib_core::identify::objective::DEFAULT_K,
            swarm: SwarmConfig::default(),
            lm_iterations: 100,
            loss: LossChoice::L2,
            loss_scale_mm: None,
            auto_mask: false,
            keep_ill_conditioned: false,
            accept_implausible: false,
            acceptance: Vec::new(),
            payload_kg: None,
            progress: false,
            cancel: Cancel::default(),
        }
    }
}

impl CalibrationConfig {
    /// An error naming the first setting out of its range (by its command-line flag).
    pub fn check(&self) -> crate::Result<()> {
        if self.loss == LossChoice::L2 && self.loss_scale_mm.is_some() {
            return Err(crate::Error::conflict(
                &["--loss-scale-mm", "--loss"],
                "--loss-scale-mm scales a robust loss, and --loss l2 (the default) has none: give --loss huber or cauchy, or drop --loss-scale-mm",
            ));
        }
        let (c1, c2) = (self.swarm.c1, self.swarm.c2);
        if !(c1 > 0.0 && c2 > 0.0 && c1 + c2 > 4.0 && (c1 + c2).is_finite()) {
            return Err(crate::refused!(option "--c1";
                "--c1 {c1} and --c2 {c2}: the constriction factor needs both positive with c1 + c2 > 4 (the paper's: 2.05 each)"
            ));
        }
        if !SWARM_SIZES.contains(&self.swarm.particles) {
            return Err(crate::refused!(option "--swarm";
                "--swarm {} is out of range; choose {} to {} particles (paper: 20)",
                self.swarm.particles,
                SWARM_SIZES.start(),
                SWARM_SIZES.end()
            ));
        }
        for (name, v) in [
            ("--k", self.k),
            ("--init-angle-rad", self.swarm.init_angle_rad),
            ("--init-length-mm", self.swarm.init_length_mm),
            ("--bound-factor", self.swarm.bound_factor),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(crate::refused!(option name;
                    "{name} must be a finite number >= 0, got {v}"
                ));
            }
        }
        if let Some(scale) = self.loss_scale_mm
            && !(scale.is_finite() && scale > 0.0)
        {
            return Err(crate::refused!(option "--loss-scale-mm";
                "--loss-scale-mm must be a finite number > 0, got {scale}"
            ));
        }
        if let Some(harmonics) = self.harmonics {
            if !self.model.maps() {
                return Err(crate::Error::conflict(
                    &["--harmonics", "--model"],
                    "--harmonics sets the joint maps' harmonics: give --model joint-maps or joint-maps+compliance, or drop --harmonics",
                ));
            }
            let most = super::maps::evidence::MAX_HARMONICS;
            if !(1..=most).contains(&harmonics) {
                return Err(crate::refused!(option "--harmonics";
                    "--harmonics {harmonics} is out of range; choose 1 to {most} harmonics per joint (or leave it to the evidence)"
                ));
            }
        }
        if self.model.maps() && self.identify == Identify::Frames {
            return Err(crate::Error::conflict(
                &["--model", "--identify"],
                "--model joint-maps identifies maps with the geometry; --identify frames keeps the robot file's model \
                 (with its maps, when it has them): drop one of the two",
            ));
        }
        if self.loss != LossChoice::L2 && !self.method.least_squares() {
            return Err(crate::Error::conflict(
                &["--loss", "--method"],
                format!(
                    "--loss {:?} applies to the least-squares stage: use --method lm or ipso+lm",
                    self.loss
                ),
            ));
        }
        let changed = self.swarm.changed();
        if self.method == Method::Lm && !changed.is_empty() {
            return Err(swarm_without_swarm(&changed));
        }
        Ok(())
    }
}
