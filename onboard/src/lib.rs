//! The controller's calibration job, in f32, exactly as the firmware runs it: the paper's
//! 32-pose scenario with tracker noise (embedded at build time), the paper's swarm (20 particles,
//! 24 parameters, 2000 generations, seed 0), least squares from the swarm's best, the Table 3
//! statistics before and after, and compensation of a few target poses; then ([`maps`]) the
//! UR10's model with joint maps loaded from a parameter block and compensation with it.
//!
//! The same code runs in the firmware (Cortex-M4F under QEMU) and in a host test; the host test
//! writes the encoded [`Outcome`] to `expected.bin`, which the firmware compares bit for bit.
#![no_std]
#![deny(missing_docs)]

use calib_core::Problem;
use calib_core::controller::compensate::{CompensationSettings, compensate_joints};
use calib_core::identify::ipso::{self, Control, IpsoSettings, SearchSpace};
use calib_core::identify::lm::{LeastSquares, LmSettings};
use calib_core::identify::objective::{DEFAULT_K, Measurement, Objective};
use calib_core::identify::statistics::PoseStatistics;
use calib_core::model::paper;
use calib_core::{Kinematics, ParameterErrors, ParameterSet, Robot};
use nalgebra::U6;
use nalgebra::{Const, Matrix3, SVector, Vector3};

pub mod maps;
pub mod seven_joints;

mod scenario {
    include!(concat!(env!("OUT_DIR"), "/scenario.rs"));
}
pub use scenario::POSES;

/// Identified parameters (the paper's 24).
pub const D: usize = 24;
/// Swarm size (the paper's 20).
pub const P: usize = 20;
/// Capacity of the measurement buffer: the RAM budget is for a 64-pose calibration.
pub const CAPACITY: usize = 64;
/// Target poses compensated.
pub const TARGETS: usize = 4;
/// Joint readings of the compensation targets, rad (the nominal robot's pose there is the
/// target).
pub const TARGET_JOINTS: [[f32; 6]; TARGETS] = [
    [0.3, -0.4, 0.5, 0.2, 0.9, -0.3],
    [-1.2, 0.2, -0.3, 1.0, -0.7, 0.4],
    [2.0, -0.8, 0.9, -1.5, 1.1, 2.5],
    [0.0, 0.5, -1.0, 0.0, 1.2, 0.0],
];

/// The paper's ER10L-C10 in f32.
pub fn robot() -> Robot<f32, U6> {
    paper::er10l_c10::<f32>()
}

/// The embedded measurements (32 poses), in a buffer sized for [`CAPACITY`].
pub fn measurements() -> Result<heapless::Vec<Measurement<f32, U6>, CAPACITY>, Error> {
    let mut out = heapless::Vec::new();
    for pose in &scenario::SCENARIO {
        let v = pose.map(f32::from_bits);
        let [
            q1,
            q2,
            q3,
            q4,
            q5,
            q6,
            x,
            y,
            z,
            r00,
            r01,
            r02,
            r10,
            r11,
            r12,
            r20,
            r21,
            r22,
        ] = v;
        let rotation = Matrix3::new(r00, r01, r02, r10, r11, r12, r20, r21, r22);
        let m = Measurement::new(
            &[q1, q2, q3, q4, q5, q6],
            Vector3::new(x, y, z),
            Some(rotation),
            1.0,
        )
        .map_err(|_| Error::Data)?;
        out.push(m).map_err(|_| Error::Data)?;
    }
    Ok(out)
}

/// A step of the job, for instruction counting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// The swarm (IPSO), whole.
    Swarm,
    /// Least squares from the swarm's best, whole.
    LeastSquares,
    /// One compensation.
    Compensation,
    /// One compensation with joint maps ([`maps`]).
    MapsCompensation,
}

/// Hooks called by [`run`]: the firmware reads its instruction counter in them and logs.
pub trait Marks {
    /// A stage begins.
    fn begin(&mut self, stage: Stage);
    /// A stage ends.
    fn end(&mut self, stage: Stage);
    /// The swarm finished a generation.
    fn generation(&mut self, generation: u32, best_cost: f32);
}

/// No hooks (the host test).
pub struct NoMarks;

impl Marks for NoMarks {
    fn begin(&mut self, _: Stage) {}
    fn end(&mut self, _: Stage) {}
    fn generation(&mut self, _: u32, _: f32) {}
}

/// Why the job failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// The embedded data could not be prepared.
    Data,
    /// The objective or least-squares problem was refused.
    Problem,
    /// The swarm failed.
    Swarm,
    /// Least squares failed.
    LeastSquares,
    /// An embedded parameter block could not be loaded.
    Block,
}

/// The little-endian bytes of `words`, in order (an outcome's encoding; the length fixes how
/// many words are taken).
pub(crate) fn encode_words<const L: usize>(words: impl Iterator<Item = u32>) -> [u8; L] {
    let mut out = [0u8; L];
    for (chunk, word) in out.chunks_exact_mut(4).zip(words) {
        chunk.copy_from_slice(&word.to_le_bytes());
    }
    out
}

/// Table 3 statistics in f32: position mean, std, max (mm), then per axis x, y, z: mean, std,
/// max (rad).
pub type Table = [f32; 12];

/// Everything the job computes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// Objective (eq. 7) of the swarm's best.
    pub swarm_cost: f32,
    /// Swarm generations run.
    pub generations: u32,
    /// `0.5 |r|^2` after least squares.
    pub lm_cost: f32,
    /// Least-squares iterations.
    pub lm_iterations: u32,
    /// Identified errors (canonical order of the default mask), mm and rad.
    pub errors: [f32; D],
    /// Table 3 with the nominal model.
    pub before: Table,
    /// Table 3 with the identified model.
    pub after: Table,
    /// Compensated joints per target, rad (NaN where compensation failed).
    pub compensated: [[f32; 6]; TARGETS],
    /// Remaining position error per target, mm (NaN where compensation failed).
    pub residual_mm: [f32; TARGETS],
}

/// Length of [`Outcome::encode`]'s output, bytes.
pub const ENCODED_LEN: usize = 4 * (4 + D + 12 + 12 + TARGETS * 6 + TARGETS);

/// The expected outcome, written by the host test `tests/tests/onboard.rs`. On the controller in
/// the job's data region (`.calib_data`, with the measurements): test data, not program.
#[cfg_attr(target_os = "none", unsafe(link_section = ".calib_data"))]
pub static EXPECTED: [u8; include_bytes!("../expected.bin").len()] =
    *include_bytes!("../expected.bin");

impl Outcome {
    /// Little-endian bytes of every field, in declaration order (integers as u32).
    pub fn encode(&self) -> [u8; ENCODED_LEN] {
        let words = [
            self.swarm_cost.to_bits(),
            self.generations,
            self.lm_cost.to_bits(),
            self.lm_iterations,
        ]
        .into_iter()
        .chain(self.errors.iter().map(|v| v.to_bits()))
        .chain(self.before.iter().map(|v| v.to_bits()))
        .chain(self.after.iter().map(|v| v.to_bits()))
        .chain(self.compensated.iter().flatten().map(|v| v.to_bits()))
        .chain(self.residual_mm.iter().map(|v| v.to_bits()));
        encode_words(words)
    }

    /// `true` when the encoded outcome equals [`EXPECTED`] bit for bit.
    pub fn matches_expected(&self) -> bool {
        self.encode().as_slice() == EXPECTED.as_slice()
    }
}

/// Table 3 statistics of `kinematics` on `measurements`.
pub fn table(kinematics: &Kinematics<f32, U6>, measurements: &[Measurement<f32, U6>]) -> Table {
    let mut stats = PoseStatistics::default();
    for m in measurements {
        stats.add(
            &m.error_of(&kinematics.forward_angles(&m.angles)),
            m.rotation.is_some(),
        );
    }
    let mut out = [0.0; 12];
    let summaries = core::iter::once(&stats.position).chain(stats.orientation.iter());
    for (slot, s) in out.chunks_exact_mut(3).zip(summaries) {
        slot.copy_from_slice(&[s.mean, s.std(), s.max]);
    }
    out
}

/// Runs the job.
pub fn run(marks: &mut impl Marks) -> Result<Outcome, Error> {
    let robot = robot();
    let measurements = measurements()?;
    let set = ParameterSet::<U6, Const<D>>::default_for(&robot).map_err(|_| Error::Problem)?;
    let zero = ParameterErrors::zero();
    let k = DEFAULT_K as f32;
    let problem = Problem::new(&robot, &zero, set, &measurements, k).map_err(|_| Error::Problem)?;
    let objective = Objective::new(&problem);

    marks.begin(Stage::Swarm);
    let mut observer = |generation: u32, best: f32| {
        marks.generation(generation, best);
        Control::Continue
    };
    let swarm = ipso::optimize::<f32, P, Const<D>>(
        &mut |x: &SVector<f32, D>| objective.value(x),
        &SearchSpace::paper(problem.set()),
        &IpsoSettings::paper(),
        &mut observer,
    )
    .map_err(|_| Error::Swarm)?;
    marks.end(Stage::Swarm);

    marks.begin(Stage::LeastSquares);
    let least_squares = LeastSquares::new(&problem);
    let lm = least_squares
        .solve(&swarm.best, &LmSettings::default())
        .map_err(|_| Error::LeastSquares)?;
    marks.end(Stage::LeastSquares);

    let mut identified = ParameterErrors::zero();
    (problem.set().unpack_into(&lm.x, &mut identified)).map_err(|_| Error::Problem)?;
    let nominal = Kinematics::nominal(&robot).map_err(|_| Error::Problem)?;
    let actual = Kinematics::new(&robot, &identified).map_err(|_| Error::Problem)?;
    let before = table(&nominal, &measurements);
    let after = table(&actual, &measurements);

    let mut compensated = [[f32::NAN; 6]; TARGETS];
    let mut residual_mm = [f32::NAN; TARGETS];
    // Table 2's errors move the ER10L-C10 by up to about 35 mm and 1.5 deg: above the default
    // bounds meant for a well-built robot.
    let settings = CompensationSettings {
        max_correction_mm: 50.0,
        max_correction_rad: 5f32.to_radians(),
        ..CompensationSettings::default()
    };
    for ((joints, out), residual) in TARGET_JOINTS
        .iter()
        .zip(compensated.iter_mut())
        .zip(residual_mm.iter_mut())
    {
        let Ok(target) = nominal.forward(joints) else {
            continue;
        };
        marks.begin(Stage::Compensation);
        let result =
            compensate_joints(&nominal, &actual, &robot.limits, &target, joints, &settings);
        marks.end(Stage::Compensation);
        if let Ok(c) = result {
            *out = c.q;
            *residual = c.residual_mm;
        }
    }
    let mut errors = [0.0; D];
    errors.copy_from_slice(lm.x.as_slice());
    Ok(Outcome {
        swarm_cost: swarm.best_cost,
        generations: swarm.generations,
        lm_cost: lm.cost,
        lm_iterations: lm.iterations,
        errors,
        before,
        after,
        compensated,
        residual_mm,
    })
}
