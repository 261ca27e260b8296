//! The swarm's particles evaluated on all cores, with no thread woken per generation.
//!
//! A generation of the paper's swarm (20 particles, 32 poses) is about 10 us of work: waking
//! sleeping threads for it each generation (as a general-purpose pool does) cost more than the
//! work split saved. A [`SwarmTeam`] keeps its helper threads for one swarm run
//! ([`SwarmTeam::run`], scoped threads): each generation the calling thread publishes the
//! particles, every member (the caller too) takes blocks of particles until none is left, and the
//! caller then waits until every particle is evaluated (not for the helpers: one that did not
//! wake up in time took nothing and is not waited for). Waiting spins ([`SPINS`] checks, about a millisecond) and then
//! yields the core at every check, so a loaded machine still makes progress.
//!
//! Every particle's cost is computed alone by [`LaneObjective::value`]: the measurements in lane
//! layout collected once ([`Objective::lanes`]) and, where the CPU has AVX-512 (detected at run
//! time; the binary still runs on baseline x86-64), the evaluation compiled for it (an AVX2 build
//! exists too, for tests: it measured slower than the baseline, [`Vectors::preferred`]). Rust never
//! fuses a multiplication and an addition on its own, so the wider vectors compute the same
//! operations with the same roundings: the costs, and the swarm, are bit for bit those of
//! [`Objective::value`] on one thread (test `team_evaluates_bit_for_bit`).

use calib_core::identify::ipso::CostFunction;
use calib_core::identify::objective::{Objective, PoseLanes};
use nalgebra::SVector;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{PoisonError, RwLock};

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
    pub fn detected() -> Self {
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
    pub fn available() -> Vec<Self> {
        let widest = Self::detected();
        [Self::Baseline, Self::Avx2, Self::Avx512]
            .into_iter()
            .filter(|v| *v <= widest)
            .collect()
    }
}

/// Eq. (7) of an objective with its measurements collected once in lane layout.
pub struct LaneObjective<'o, 'p, const N: usize, const D: usize> {
    objective: &'o Objective<'p, f64, N, D>,
    lanes: Vec<PoseLanes<f64, N>>,
    vectors: Vectors,
}

impl<'o, 'p, const N: usize, const D: usize> LaneObjective<'o, 'p, N, D> {
    /// Collects the measurements of `objective` in lanes; evaluates with
    /// [`Vectors::preferred`].
    pub fn new(objective: &'o Objective<'p, f64, N, D>) -> Self {
        Self::with_vectors(objective, Vectors::preferred())
    }

    /// The same with the given vectors, or the widest this CPU has if it lacks them.
    pub fn with_vectors(objective: &'o Objective<'p, f64, N, D>, vectors: Vectors) -> Self {
        let widest = Vectors::detected();
        Self {
            objective,
            lanes: objective.lanes().collect(),
            vectors: vectors.min(widest),
        }
    }

    /// The cost at `x`: bit for bit `objective.value(x)`.
    pub fn value(&self, x: &SVector<f64, D>) -> f64 {
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
fn value_avx2<const N: usize, const D: usize>(
    objective: &Objective<'_, f64, N, D>,
    x: &SVector<f64, D>,
    lanes: &[PoseLanes<f64, N>],
) -> f64 {
    objective.value_of_lanes(x, lanes)
}

/// [`Objective::value_of_lanes`] compiled for AVX2 with AVX-512F/VL's 32 registers.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl")]
fn value_avx512<const N: usize, const D: usize>(
    objective: &Objective<'_, f64, N, D>,
    x: &SVector<f64, D>,
    lanes: &[PoseLanes<f64, N>],
) -> f64 {
    objective.value_of_lanes(x, lanes)
}

/// Checks a waiting thread makes by spinning before it yields the core at every check: a
/// generation of the paper's swarm is about 10 us, and a wake-up by the scheduler costs as much.
pub const SPINS: u32 = 1 << 16;

/// Waits until `ready()`: [`SPINS`] checks with a spin hint between, then a yield between checks.
fn wait_until(mut ready: impl FnMut() -> bool) {
    let mut checks = 0u32;
    while !ready() {
        if checks < SPINS {
            checks += 1;
            std::hint::spin_loop();
        } else {
            std::thread::yield_now();
        }
    }
}

/// An atomic on cache lines of its own (128 bytes: two lines, which some CPUs fetch in pairs), so
/// that one member writing it does not take from the others the line they spin on.
#[repr(align(128))]
#[derive(Default)]
struct Padded<A>(A);

impl<A> std::ops::Deref for Padded<A> {
    type Target = A;
    fn deref(&self) -> &A {
        &self.0
    }
}

/// What the caller and the helpers share during one swarm run.
struct Shared<const D: usize> {
    /// Bumped by the caller once the particles of a generation are published.
    generation: Padded<AtomicU64>,
    /// The next particle to take. Members take blocks of particles (`blocks` per generation),
    /// so a member slowed down, by the scheduler or by the caller's own work, takes fewer, and one
    /// that does not wake up in time takes none.
    next: Padded<AtomicUsize>,
    /// Blocks a generation's particles are taken in: one per thread asked for (the whole
    /// `calib calibrate --method ipso` process, `perf stat -r 40`, two threads: 21.3-21.8 ms
    /// with 2 blocks, 22.5-23.4 with 4, 23.9 with 8, 24.6 with 20; every claim is a cache-line
    /// transfer, and a generation is about 10 us of work).
    blocks: usize,
    /// Particles of the current generation evaluated: the caller waits for all of them, not for
    /// the helpers, so a helper that took nothing (descheduled) does not hold it up.
    evaluated: Padded<AtomicUsize>,
    /// Set when the run is over (also on an early return).
    stop: Padded<AtomicBool>,
    particles: RwLock<Vec<SVector<f64, D>>>,
    /// The costs' bits, one per particle, written by whoever evaluated it.
    costs: RwLock<Vec<AtomicU64>>,
}

/// Sets `stop` when the run ends, however it ends, so the helpers leave and the scope joins.
struct StopOnDrop<'s>(&'s AtomicBool);

impl Drop for StopOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// The particles' costs on several threads, the caller one of them; see the module docs.
pub struct SwarmTeam<'t, 'o, 'p, const N: usize, const D: usize> {
    objective: &'t LaneObjective<'o, 'p, N, D>,
    shared: &'t Shared<D>,
    members: usize,
}

impl<'o, 'p, const N: usize, const D: usize> SwarmTeam<'_, 'o, 'p, N, D> {
    /// Runs `swarm` with a team of `threads` (at least 1; the caller and `threads - 1` helpers,
    /// fewer if the system cannot start them) evaluating `objective`; the helpers end when
    /// `swarm` returns.
    pub fn run<R>(
        objective: &LaneObjective<'o, 'p, N, D>,
        threads: usize,
        swarm: impl FnOnce(&mut SwarmTeam<'_, 'o, 'p, N, D>) -> R,
    ) -> R {
        let wanted = threads.max(1);
        let shared = Shared {
            generation: Padded::default(),
            evaluated: Padded::default(),
            stop: Padded::default(),
            next: Padded::default(),
            blocks: wanted,
            particles: RwLock::new(Vec::new()),
            costs: RwLock::new(Vec::new()),
        };
        std::thread::scope(|scope| {
            let _stop = StopOnDrop(&shared.stop);
            // A helper the system cannot start is one member fewer (never a panic).
            let helpers = (1..wanted)
                .filter(|_| {
                    let shared = &shared;
                    std::thread::Builder::new()
                        .name("calib-swarm".into())
                        .spawn_scoped(scope, move || helper(objective, shared))
                        .is_ok()
                })
                .count();
            let members = 1 + helpers;
            swarm(&mut SwarmTeam {
                objective,
                shared: &shared,
                members,
            })
        })
    }

    /// The number of threads evaluating (the caller included).
    pub fn members(&self) -> usize {
        self.members
    }
}

fn helper<const N: usize, const D: usize>(
    objective: &LaneObjective<'_, '_, N, D>,
    shared: &Shared<D>,
) {
    let mut seen = 0;
    loop {
        wait_until(|| {
            shared.stop.load(Ordering::Acquire) || shared.generation.load(Ordering::Acquire) != seen
        });
        if shared.stop.load(Ordering::Acquire) {
            return;
        }
        seen = shared.generation.load(Ordering::Acquire);
        take_particles(objective, shared);
    }
}

/// Evaluates the published particles, a block at a time, until no block is left to take.
fn take_particles<const N: usize, const D: usize>(
    objective: &LaneObjective<'_, '_, N, D>,
    shared: &Shared<D>,
) {
    let particles = shared
        .particles
        .read()
        .unwrap_or_else(PoisonError::into_inner);
    let costs = shared.costs.read().unwrap_or_else(PoisonError::into_inner);
    let block = particles.len().div_ceil(shared.blocks).max(1);
    loop {
        let start = shared.next.fetch_add(block, Ordering::AcqRel);
        let end = (start + block).min(particles.len());
        let (Some(xs), Some(out)) = (particles.get(start..end), costs.get(start..end)) else {
            return;
        };
        for (x, cost) in xs.iter().zip(out) {
            cost.store(objective.value(x).to_bits(), Ordering::Relaxed);
        }
        // Release: the costs stored above are visible to whoever sees the count.
        shared.evaluated.fetch_add(xs.len(), Ordering::AcqRel);
    }
}

impl<const N: usize, const D: usize> CostFunction<f64, D> for SwarmTeam<'_, '_, '_, N, D> {
    fn cost(&mut self, x: &SVector<f64, D>) -> f64 {
        self.objective.value(x)
    }

    fn cost_batch(&mut self, xs: &[SVector<f64, D>], out: &mut [f64]) {
        if self.members == 1 || xs.len() < 2 {
            for (c, x) in out.iter_mut().zip(xs) {
                *c = self.objective.value(x);
            }
            return;
        }
        {
            // The helpers are all done with the previous generation: nobody reads these now.
            let mut particles = self
                .shared
                .particles
                .write()
                .unwrap_or_else(PoisonError::into_inner);
            particles.clear();
            particles.extend_from_slice(xs);
            let mut costs = self
                .shared
                .costs
                .write()
                .unwrap_or_else(PoisonError::into_inner);
            costs.resize_with(xs.len(), || AtomicU64::new(f64::NAN.to_bits()));
        }
        // The count first: a helper can claim particles as soon as `next` is reset.
        self.shared.evaluated.store(0, Ordering::Release);
        self.shared.next.store(0, Ordering::Release);
        self.shared.generation.fetch_add(1, Ordering::AcqRel);
        take_particles(self.objective, self.shared);
        wait_until(|| self.shared.evaluated.load(Ordering::Acquire) >= xs.len());
        let costs = self
            .shared
            .costs
            .read()
            .unwrap_or_else(PoisonError::into_inner);
        for (c, bits) in out.iter_mut().zip(costs.iter()) {
            *c = f64::from_bits(bits.load(Ordering::Relaxed));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::identify::ipso::{self, IpsoSettings, SearchSpace, Silent};
    use calib_core::identify::objective::{DEFAULT_K, Measurement};
    use calib_core::{ParameterErrors, ParameterSet, Problem};

    /// The bundled paper scenario (32 simulated poses of the ER10L-C10), as `calibrate` reads it.
    fn paper_measurements() -> Vec<Measurement<f64, 6>> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        crate::dataset::Dataset::<6>::load(
            &dir.join("robots/er10l-c10.toml"),
            &dir.join("data/er10l-c10-sim32.csv"),
        )
        .expect("bundled files")
        .measurements
    }

    /// Every vector path this CPU has, and every team size, gives the swarm of
    /// `Objective::value` on one thread bit for bit (300 generations of the paper's swarm).
    #[test]
    fn team_evaluates_bit_for_bit() {
        let robot = calib_core::model::paper::er10l_c10::<f64>();
        let set = ParameterSet::<6, 24>::default_for(&robot).expect("paper set");
        let measurements = paper_measurements();
        let problem = Problem::new(
            &robot,
            &ParameterErrors::zero(),
            set,
            &measurements,
            DEFAULT_K,
        )
        .expect("valid problem");
        let objective = Objective::new(&problem);
        let space = SearchSpace::paper(&set);
        let mut settings = IpsoSettings::paper();
        settings.max_generations = 300;
        let mut plain = |x: &SVector<f64, 24>| objective.value(x);
        let expected = ipso::optimize::<f64, 20, 24>(&mut plain, &space, &settings, &mut Silent)
            .expect("valid settings");
        assert!(expected.best_cost < 0.01 * expected.initial_cost);
        let available = Vectors::available();
        assert_eq!(available.first(), Some(&Vectors::Baseline));
        for vectors in available {
            let lanes = LaneObjective::with_vectors(&objective, vectors);
            assert_eq!(lanes.vectors(), vectors);
            for i in 0..8 {
                let x = SVector::<f64, 24>::from_fn(|j, _| {
                    2e-3 * (i as f64 - 3.5) * ((j % 5) as f64 - 2.0)
                });
                assert_eq!(lanes.value(&x).to_bits(), objective.value(&x).to_bits());
            }
            for threads in [1, 2, 3] {
                let team = SwarmTeam::run(&lanes, threads, |team| {
                    assert_eq!(team.members(), threads);
                    ipso::optimize::<f64, 20, 24>(team, &space, &settings, &mut Silent)
                })
                .expect("valid settings");
                assert_eq!(team, expected, "{vectors:?}, {threads} threads");
                assert_eq!(team.best_cost.to_bits(), expected.best_cost.to_bits());
            }
        }
    }
}
