//! The swarm's cost evaluated in vector lanes: the measurements collected once in lane layout
//! ([`Objective::lanes`]) and, where the CPU has AVX-512 (detected at run time; the binary still
//! runs on baseline x86-64), the evaluation compiled for it (an AVX2 build exists too, for tests:
//! [`Vectors::preferred`] says why it is not used). Rust never fuses a multiplication and an
//! addition on its own, so the wider vectors compute the same operations with the same roundings:
//! the costs are bit for bit those of [`Objective::value`] (test
//! `swarm_team::tests::team_evaluates_bit_for_bit`).

use calib_core::identify::objective::{Objective, PoseLanes};
use nalgebra::{DVector, Dyn};

/// The instruction set an evaluation is compiled for, chosen at run time (ordered narrowest
/// first).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Vectors {
    /// The build's baseline (SSE2 on x86-64).
    Baseline,
    /// AVX2: 256-bit vectors, 16 registers.
    Avx2,
    /// AVX2 with AVX-512F/VL: the same 256-bit vectors, 32 registers (the lanes of a frame no
    /// longer spill: 0.53-0.56 us per paper objective against 1.10 with AVX2 alone and 0.80
    /// baseline, `cargo bench -p calib-core --bench calibration -- lanes`).
    Avx512,
}

impl Vectors {
    /// The widest this CPU has.
    pub(crate) fn detected() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("avx2")
            {
                return Self::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                return Self::Avx2;
            }
        }
        Self::Baseline
    }

    /// What an evaluation uses by default on this CPU: AVX-512 where it has it, otherwise the
    /// baseline. The AVX2 build measured slower than the baseline one (1.10 against 0.80 us per
    /// paper objective: with 16 registers the lanes of a frame spill), so it is only used when
    /// asked for ([`LaneObjective::with_vectors`]).
    pub fn preferred() -> Self {
        match Self::detected() {
            Self::Avx2 => Self::Baseline,
            widest => widest,
        }
    }

    /// The paths this CPU can run, narrowest first (for tests comparing them).
    #[cfg(test)]
    pub(crate) fn available() -> Vec<Self> {
        let widest = Self::detected();
        [Self::Baseline, Self::Avx2, Self::Avx512]
            .into_iter()
            .filter(|v| *v <= widest)
            .collect()
    }
}

/// Eq. (7) of an objective with its measurements collected once in lane layout.
pub struct LaneObjective<'o, 'p> {
    objective: &'o Objective<'p, f64, Dyn, Dyn>,
    lanes: Vec<PoseLanes<f64, Dyn>>,
    vectors: Vectors,
}

impl<'o, 'p> LaneObjective<'o, 'p> {
    /// Collects the measurements of `objective` in lanes; evaluates with
    /// [`Vectors::preferred`].
    pub fn new(objective: &'o Objective<'p, f64, Dyn, Dyn>) -> Self {
        Self::with_vectors(objective, Vectors::preferred())
    }

    /// The same with the given vectors, or the widest this CPU has if it lacks them.
    pub fn with_vectors(objective: &'o Objective<'p, f64, Dyn, Dyn>, vectors: Vectors) -> Self {
        let widest = Vectors::detected();
        Self {
            objective,
            lanes: objective.lanes().collect(),
            vectors: vectors.min(widest),
        }
    }

    /// The cost at `x`: bit for bit `objective.value(x)`.
    pub fn value(&self, x: &DVector<f64>) -> f64 {
        #[cfg(target_arch = "x86_64")]
        match self.vectors {
            // SAFETY: `with_vectors` keeps only what `Vectors::detected` found on this CPU.
            Vectors::Avx512 => return unsafe { value_avx512(self.objective, x, &self.lanes) },
            // SAFETY: as above.
            Vectors::Avx2 => return unsafe { value_avx2(self.objective, x, &self.lanes) },
            Vectors::Baseline => {}
        }
        self.objective.value_of_lanes(x, &self.lanes)
    }

    /// The instruction set the evaluation runs in.
    pub fn vectors(&self) -> Vectors {
        self.vectors
    }
}

/// [`Objective::value_of_lanes`] compiled for AVX2 (it is always inlined, so all of the
/// evaluation is).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn value_avx2(
    objective: &Objective<'_, f64, Dyn, Dyn>,
    x: &DVector<f64>,
    lanes: &[PoseLanes<f64, Dyn>],
) -> f64 {
    objective.value_of_lanes(x, lanes)
}

/// [`Objective::value_of_lanes`] compiled for AVX2 with AVX-512F/VL's 32 registers.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl")]
fn value_avx512(
    objective: &Objective<'_, f64, Dyn, Dyn>,
    x: &DVector<f64>,
    lanes: &[PoseLanes<f64, Dyn>],
) -> f64 {
    objective.value_of_lanes(x, lanes)
}
