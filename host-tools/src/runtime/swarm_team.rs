//! The swarm's particles evaluated on several cores, without a thread that burns a core waiting
//! and without a result that depends on which thread computed what.
//!
//! A generation of the paper's swarm (20 particles, 32 poses) is about 10 us of work, no more
//! than waking a sleeping thread costs. A [`SwarmTeam`] therefore keeps its helper threads for one
//! swarm run ([`SwarmTeam::run`], scoped threads of the standard library), and a helper with
//! nothing to do checks for work for at most [`SLEEP_AFTER`] and then sleeps until the caller
//! publishes the next generation: during a run the helpers wait microseconds between two
//! generations and never sleep; a helper that the system does not run, or a run that is over,
//! costs no core.
//!
//! Each generation the caller keeps the last block of particles for itself (evaluated from its
//! own memory), publishes the coordinates of the others as the swarm's update gives them
//! ([`CostFunction::position_ready`]) and the members claim them a block at a time. The caller
//! never depends on a helper: it evaluates any block nobody claimed, and a block a helper claimed
//! but has not finished after as long as the caller took for its own block (the helper was not
//! run by the system, or is slower) is evaluated by the caller too. Every word the threads share
//! carries the generation it belongs to, so a helper's late result is never taken for a later
//! generation's. A cost is the same bits whoever computes it ([`LaneObjective::value`]), so the
//! swarm is bit for bit the one that evaluates on one thread (test `team_evaluates_bit_for_bit`).
//!
//! The number of members is the cores this process may use
//! ([`std::thread::available_parallelism`], which follows `taskset` and a container's CPU quota)
//! but no more than gives each a block of [`MIN_BLOCK`] particles ([`team_size`]).

use super::lanes::{LaneObjective, Vectors};
use calib_core::identify::ipso::{
    self, CostFunction, IpsoError, IpsoResult, IpsoSettings, Observer, RandomStream, SearchSpace,
    SwarmMemory,
};
use nalgebra::{DVector, Dyn};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::Thread;
use std::time::{Duration, Instant};

/// How long a helper with nothing to do keeps checking for work before it sleeps: about five
/// generations of the paper's swarm, so that between two generations (microseconds) a helper
/// does not sleep, and after a run or while the caller does other work it soon does.
pub const SLEEP_AFTER: Duration = Duration::from_micros(50);

/// The fewest particles a member's block has: a claim and a block's results are cache-line
/// transfers between cores (a claim cost about 0.2 us a generation in the earlier team's
/// measurements) and a particle of the paper's swarm is 0.5 us of work, so a block of four is
/// mostly work. Chosen, not measured: this 2-core machine never forms blocks smaller than 10.
pub const MIN_BLOCK: usize = 4;

/// The most generations the caller evaluates alone after its helpers were late
/// ([`SwarmTeam`]'s back-off): 256 generations of the paper's swarm are about 2.5 ms.
pub const MAX_ALONE: u32 = 256;

/// The members (threads, the caller included) a team for a swarm of `particles` has on a machine
/// where this process may use `cores`: at most one per [`MIN_BLOCK`] particles, at least one.
pub fn team_size(cores: usize, particles: usize) -> usize {
    cores.min(particles / MIN_BLOCK).max(1)
}

/// A shared word that belongs to a generation: the generation in the high 32 bits, a count, a
/// block or a member in the low 32.
fn tagged(generation: u64, low: usize) -> u64 {
    (generation << 32) | (low as u64 & 0xFFFF_FFFF)
}

fn generation_of(word: u64) -> u64 {
    word >> 32
}

fn low_of(word: u64) -> usize {
    (word & 0xFFFF_FFFF) as usize
}

/// Checks `ready` until it holds, with a spin hint between checks, for at most `limit` counted
/// from `since` (set at the first check that fails, when not set yet); returns whether it held.
/// Every wait of the team is one of these: a helper then sleeps or gives its block up, the
/// caller evaluates a late block itself.
fn spin_until(
    since: &mut Option<Instant>,
    limit: Duration,
    mut ready: impl FnMut() -> bool,
) -> bool {
    while !ready() {
        if since.get_or_insert_with(Instant::now).elapsed() > limit {
            return false;
        }
        std::hint::spin_loop();
    }
    true
}

/// An atomic on cache lines of its own (128 bytes: two lines, which some CPUs fetch in pairs), so
/// that one member writing it does not take from the others the line they read.
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
struct Board {
    /// The next published block to claim, tagged with the generation.
    next: Padded<AtomicU64>,
    /// Particles of the generation whose coordinates are in the slots (the first ones, in
    /// order), tagged with the generation.
    ready: Padded<AtomicU64>,
    /// Set when the run is over (also on an early return).
    stop: Padded<AtomicBool>,
    /// Helper `m` is going to sleep, or asleep: the caller wakes it when it publishes.
    sleeping: Box<[Padded<AtomicBool>]>,
    /// The published particles and the members' results, sized by the first generation.
    slots: OnceLock<Slots>,
    /// How long a helper stalls after each claim (tests of a helper the system does not run).
    #[cfg(test)]
    stall: Duration,
}

/// Sixteen costs on a cache line pair of their own.
#[repr(align(128))]
#[derive(Default)]
struct CostLine([AtomicU64; 16]);

/// A generation's published particles, as the bits of their coordinates (`dimension` per
/// particle, written by the caller before it marks them ready), and each helper's results:
/// atomics, read and written without locks.
struct Slots {
    /// Coordinates per particle (the number of parameters).
    dimension: usize,
    /// Particles in the swarm.
    particles: usize,
    /// Particles per block; the caller's own block is the last `block` particles, not published.
    block: usize,
    /// The particles published (all but the caller's block) and the blocks they form.
    published: usize,
    blocks: usize,
    coordinates: Box<[AtomicU64]>,
    /// Per published block, the generation and helper of its last results.
    done: Box<[Padded<AtomicU64>]>,
    /// Per helper, the costs' bits of the particles it evaluated, by particle.
    costs: Box<[Box<[CostLine]>]>,
}

impl Slots {
    fn new(particles: usize, dimension: usize, members: usize) -> Self {
        let block = particles.div_ceil(members.max(1)).max(1);
        let published = particles.saturating_sub(block);
        let blocks = published.div_ceil(block);
        let lines = published.div_ceil(16);
        Self {
            dimension,
            particles,
            block,
            published,
            blocks,
            coordinates: (0..published * dimension)
                .map(|_| AtomicU64::new(0))
                .collect(),
            done: (0..blocks).map(|_| Padded::default()).collect(),
            costs: (1..members)
                .map(|_| (0..lines).map(|_| CostLine::default()).collect())
                .collect(),
        }
    }

    /// The particles of published block `b`.
    fn range(&self, b: usize) -> std::ops::Range<usize> {
        let start = (b * self.block).min(self.published);
        start..(start + self.block).min(self.published)
    }

    /// Helper `member`'s cost of particle `i`.
    fn cost(&self, member: usize, i: usize) -> Option<&AtomicU64> {
        self.costs.get(member)?.get(i / 16)?.0.get(i % 16)
    }
}

impl Board {
    fn new(helpers: usize) -> Self {
        Self {
            next: Padded(AtomicU64::new(tagged(0, usize::MAX))),
            ready: Padded::default(),
            stop: Padded::default(),
            sleeping: (0..helpers).map(|_| Padded::default()).collect(),
            slots: OnceLock::new(),
            #[cfg(test)]
            stall: Duration::ZERO,
        }
    }

    /// Whether a published block is left to claim, or the run is over.
    fn work_or_stop(&self, order: Ordering) -> bool {
        let blocks = self.slots.get().map_or(0, |s| s.blocks);
        low_of(self.next.load(order)) < blocks || self.stop.load(order)
    }

    /// Claims the next published block: its generation and number.
    fn claim(&self) -> Option<(&Slots, u64, usize)> {
        let slots = self.slots.get()?;
        if low_of(self.next.load(Ordering::Acquire)) >= slots.blocks {
            return None; // looked at first: a claim takes the line from the others
        }
        let word = self.next.fetch_add(1, Ordering::AcqRel);
        (low_of(word) < slots.blocks).then(|| (slots, generation_of(word), low_of(word)))
    }

    /// Helper `member` sleeps until woken ([`Board::wake`]), unless work came meanwhile.
    fn sleep(&self, member: usize) {
        let Some(flag) = self.sleeping.get(member) else {
            return;
        };
        // Sequentially consistent with the caller's publishing and `wake`: either this sees the
        // new work, or the caller sees the flag and wakes this thread.
        flag.store(true, Ordering::SeqCst);
        if !self.work_or_stop(Ordering::SeqCst) {
            std::thread::park();
        }
        flag.store(false, Ordering::SeqCst);
    }

    /// Wakes the helpers that sleep (a helper that does not costs a load).
    fn wake(&self, helpers: &[Thread]) {
        for (flag, thread) in self.sleeping.iter().zip(helpers) {
            if flag.load(Ordering::SeqCst) {
                thread.unpark();
            }
        }
    }
}

/// Ends the run however it ends: sets `stop` and wakes the helpers, so they leave and the scope
/// joins them.
struct StopOnDrop<'s> {
    board: &'s Board,
    helpers: Vec<Thread>,
}

impl Drop for StopOnDrop<'_> {
    fn drop(&mut self) {
        self.board.stop.store(true, Ordering::SeqCst);
        for thread in &self.helpers {
            thread.unpark();
        }
    }
}

/// A helper: claims published blocks and evaluates them while the run lasts, sleeping when it
/// has had nothing to do for [`SLEEP_AFTER`].
fn helper(objective: &LaneObjective<'_, '_>, board: &Board, member: usize) {
    // The particle evaluated, sized once (no allocation in a generation).
    let mut particle = DVector::zeros(0);
    while !board.stop.load(Ordering::Acquire) {
        if let Some((slots, generation, b)) = board.claim() {
            #[cfg(test)]
            std::thread::sleep(board.stall);
            evaluate_block(
                objective,
                board,
                slots,
                (generation, b),
                member,
                &mut particle,
            );
            continue;
        }
        if !spin_until(&mut None, SLEEP_AFTER, || {
            board.work_or_stop(Ordering::Acquire)
        }) {
            board.sleep(member);
        }
    }
}

/// Helper `member` evaluates block `b` of `generation` as its particles are published, and marks
/// it done; gives it up when the generation is over or its particles are not published within
/// [`SLEEP_AFTER`] (the caller then evaluates it).
fn evaluate_block(
    objective: &LaneObjective<'_, '_>,
    board: &Board,
    slots: &Slots,
    (generation, b): (u64, usize),
    member: usize,
    particle: &mut DVector<f64>,
) {
    let d = slots.dimension;
    if particle.len() != d {
        *particle = DVector::zeros(d);
    }
    for i in slots.range(b) {
        // Acquire: the coordinates stored before `ready` passed `i` are visible.
        let ready = || board.ready.load(Ordering::Acquire);
        let published = spin_until(&mut None, SLEEP_AFTER, || {
            let ready = ready();
            generation_of(ready) != generation || low_of(ready) > i
        });
        if !published || generation_of(ready()) != generation {
            return;
        }
        let Some(coordinates) = slots.coordinates.get(i * d..(i + 1) * d) else {
            return;
        };
        for (p, c) in particle.as_mut_slice().iter_mut().zip(coordinates) {
            *p = f64::from_bits(c.load(Ordering::Relaxed));
        }
        // A result of coordinates overwritten by a later generation meanwhile is tagged with
        // this one, and never read.
        if let Some(cost) = slots.cost(member, i) {
            cost.store(objective.value(particle).to_bits(), Ordering::Relaxed);
        }
    }
    if let Some(done) = slots.done.get(b) {
        // Release: with the costs above. The latest generation's tag stays.
        done.fetch_max(tagged(generation, member), Ordering::Release);
    }
}

/// The particles' costs on several threads, the caller one of them; see the module docs.
pub struct SwarmTeam<'t, 'o, 'p> {
    objective: &'t LaneObjective<'o, 'p>,
    board: &'t Board,
    helpers: &'t [Thread],
    /// The current generation (numbered from 1).
    generation: u64,
    /// The current generation was started by [`CostFunction::position_ready`], which has
    /// published this many particles.
    started: Option<usize>,
    /// The published blocks this caller claimed in the current generation (sized once).
    claimed: Vec<bool>,
    /// Generations the caller evaluates alone, the helpers having been late, and how many it
    /// did so last time ([`SwarmTeam::back_off`]).
    alone: u32,
    backoff: u32,
}

impl<'o, 'p> SwarmTeam<'_, 'o, 'p> {
    /// Runs `swarm` with a team of `threads` (at least 1; the caller and `threads - 1` helpers,
    /// fewer if the system cannot start them; [`team_size`] says how many are worth it)
    /// evaluating `objective`; the helpers end when `swarm` returns. `swarm` gets the team as the
    /// cost function (for [`SwarmTeam::optimize`] or the core's [`ipso`] functions).
    pub fn run<R>(
        objective: &LaneObjective<'o, 'p>,
        threads: usize,
        swarm: impl FnOnce(&mut SwarmTeam<'_, 'o, 'p>) -> R,
    ) -> R {
        Self::run_on(&Board::new(threads.max(1) - 1), objective, swarm)
    }

    fn run_on<R>(
        board: &Board,
        objective: &LaneObjective<'o, 'p>,
        swarm: impl FnOnce(&mut SwarmTeam<'_, 'o, 'p>) -> R,
    ) -> R {
        std::thread::scope(|scope| {
            // A helper the system cannot start is one member fewer (never a panic).
            let helpers = (0..board.sleeping.len())
                .filter_map(|member| {
                    std::thread::Builder::new()
                        .name("calib-swarm".into())
                        .spawn_scoped(scope, move || helper(objective, board, member))
                        .ok()
                        .map(|handle| handle.thread().clone())
                })
                .collect();
            let stop = StopOnDrop { board, helpers };
            swarm(&mut SwarmTeam {
                objective,
                board,
                helpers: &stop.helpers,
                generation: 0,
                started: None,
                claimed: Vec::new(),
                alone: 0,
                backoff: 0,
            })
        })
    }

    /// The number of threads evaluating (the caller included).
    #[cfg(test)]
    pub(crate) fn members(&self) -> usize {
        1 + self.helpers.len()
    }

    /// [`ipso::optimize_in`] with this team as the cost, compiled for AVX-512 when the objective
    /// evaluates with it ([`Vectors::Avx512`]; otherwise the baseline): the swarm's update
    /// between generations (velocities, positions, walls, the random pairs: on the caller) then
    /// vectorises too. Same operations, same roundings: the same swarm bit for bit (test
    /// `team_evaluates_bit_for_bit`).
    pub fn optimize(
        &mut self,
        memory: SwarmMemory<'_, f64, Dyn>,
        space: &SearchSpace<f64, Dyn>,
        settings: &IpsoSettings<f64>,
        observer: &mut impl Observer<f64>,
    ) -> Result<IpsoResult<f64, Dyn>, IpsoError> {
        #[cfg(target_arch = "x86_64")]
        if self.objective.vectors() == Vectors::Avx512 {
            // SAFETY: an objective keeps only vectors `Vectors::detected` found on this CPU.
            return unsafe { optimize_avx512(memory, self, space, settings, observer) };
        }
        ipso::optimize_in(memory, self, space, settings, observer)
    }

    /// Starts a generation: its number in the shared words, nothing published, every block
    /// free; a helper still in the previous one gives up (its results carry the old number).
    fn start_generation(&mut self) {
        self.generation += 1;
        let generation = self.generation;
        self.board
            .ready
            .store(tagged(generation, 0), Ordering::Release);
        self.board
            .next
            .store(tagged(generation, 0), Ordering::SeqCst);
        self.board.wake(self.helpers);
    }

    /// Copies the coordinates of particle `index` into the slots and marks the particles up to
    /// it ready.
    fn publish(&self, slots: &Slots, index: usize, x: &DVector<f64>) {
        let d = slots.dimension;
        if let Some(slot) = slots.coordinates.get(index * d..(index + 1) * d) {
            for (slot, c) in slot.iter().zip(x.as_slice()) {
                slot.store(c.to_bits(), Ordering::Relaxed);
            }
        }
        // Release: with the coordinates above.
        self.board
            .ready
            .store(tagged(self.generation, index + 1), Ordering::Release);
    }

    /// Evaluates `xs` here, into `out`.
    fn evaluate_here(&self, xs: &[DVector<f64>], out: &mut [f64]) {
        for (c, x) in out.iter_mut().zip(xs) {
            *c = self.objective.value(x);
        }
    }

    /// Claims and evaluates here the published blocks nobody has claimed.
    fn evaluate_unclaimed(&mut self, slots: &Slots, xs: &[DVector<f64>], out: &mut [f64]) {
        self.claimed.clear();
        self.claimed.resize(slots.blocks, false);
        while let Some((_, generation, b)) = self.board.claim() {
            let range = slots.range(b);
            if generation == self.generation
                && let (Some(xs), Some(out)) = (xs.get(range.clone()), out.get_mut(range))
            {
                self.evaluate_here(xs, out);
                if let Some(claimed) = self.claimed.get_mut(b) {
                    *claimed = true;
                }
            }
        }
    }

    /// Takes the helpers' results of the blocks they claimed; a block not done after
    /// `patience` (counted from the first look at it) is evaluated here. Returns whether one was.
    fn gather(
        &self,
        slots: &Slots,
        xs: &[DVector<f64>],
        out: &mut [f64],
        patience: Duration,
    ) -> bool {
        let mut since = None;
        let mut late = false;
        for (b, claimed) in self.claimed.iter().enumerate() {
            if *claimed {
                continue;
            }
            let range = slots.range(b);
            let (Some(xs), Some(out)) = (xs.get(range.clone()), out.get_mut(range.clone())) else {
                continue;
            };
            // Acquire: the costs stored before the tag are visible. Only this generation's
            // helper moves the tag on to it, and nothing moves it further before the next.
            let tag = || slots.done.get(b).map_or(0, |d| d.load(Ordering::Acquire));
            let done = spin_until(&mut since, patience, || {
                generation_of(tag()) == self.generation
            });
            match done.then(|| low_of(tag())) {
                Some(m) => {
                    for (c, i) in out.iter_mut().zip(range) {
                        let bits = slots.cost(m, i).map(|c| c.load(Ordering::Relaxed));
                        *c = bits.map_or(f64::NAN, f64::from_bits);
                    }
                }
                None => {
                    late = true;
                    self.evaluate_here(xs, out);
                }
            }
        }
        late
    }

    /// After a generation whose helpers were `late`: the next generations are evaluated by the
    /// caller alone, one after the first such generation, twice as many after each further one
    /// (at most [`MAX_ALONE`]), so that helpers the system does not run (other programs use the
    /// cores) sleep and leave the caller's core to it; a generation the helpers finish in time
    /// starts the count again.
    fn back_off(&mut self, late: bool) {
        self.backoff = if late {
            (self.backoff * 2).clamp(1, MAX_ALONE)
        } else {
            0
        };
        self.alone = self.backoff;
    }
}

/// [`ipso::optimize_in`] (inlined on a PC) compiled for AVX2 with AVX-512F/VL: the update of the
/// paper's swarm alone, its pairs ready, 0.97 ms per run against 1.37 in the baseline's SSE2 (a
/// scratch criterion bench).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl")]
fn optimize_avx512(
    memory: SwarmMemory<'_, f64, Dyn>,
    team: &mut SwarmTeam<'_, '_, '_>,
    space: &SearchSpace<f64, Dyn>,
    settings: &IpsoSettings<f64>,
    observer: &mut impl Observer<f64>,
) -> Result<IpsoResult<f64, Dyn>, IpsoError> {
    let mut random = RandomStream::new(settings.seed);
    ipso::optimize_drawing(memory, team, &mut random, space, settings, observer)
}

impl CostFunction<f64, Dyn> for SwarmTeam<'_, '_, '_> {
    fn cost(&mut self, x: &DVector<f64>) -> f64 {
        self.objective.value(x)
    }

    fn position_ready(&mut self, index: usize, x: &DVector<f64>) {
        if self.alone > 0 {
            return;
        }
        let Some(slots) = self.board.slots.get() else {
            return; // a team of one, or the first generation: published by `cost_batch`
        };
        if index == 0 {
            self.start_generation();
            self.started = Some(0);
        }
        if self.started == Some(index) && index < slots.published {
            self.publish(slots, index, x);
            self.started = Some(index + 1);
        }
    }

    fn cost_batch(&mut self, xs: &[DVector<f64>], out: &mut [f64]) {
        let dimension = xs.first().map_or(0, |x| x.len());
        let members = 1 + self.helpers.len();
        let board = self.board;
        let slots = (members > 1 && xs.len() > 1)
            .then(|| {
                board
                    .slots
                    .get_or_init(|| Slots::new(xs.len(), dimension, members))
            })
            .filter(|slots| slots.particles == xs.len() && slots.dimension == dimension);
        let Some(slots) = slots else {
            // A team of one, a swarm of one particle, or not the swarm the slots were made
            // for: evaluated here (a generation `position_ready` started is given up).
            self.started = None;
            return self.evaluate_here(xs, out);
        };
        if self.alone > 0 {
            self.alone -= 1;
            self.started = None;
            if self.alone < 2 {
                // Helpers asleep wake up now, to be checking for work when the team tries again.
                self.board.wake(self.helpers);
            }
            return self.evaluate_here(xs, out);
        }
        // The particles `position_ready` has not published (all of them in the first
        // generation).
        let done = match self.started.take() {
            Some(done) => done,
            None => {
                self.start_generation();
                0
            }
        };
        for (index, x) in xs.iter().enumerate().take(slots.published).skip(done) {
            self.publish(slots, index, x);
        }
        // The caller's own block, from its own memory, timed: a helper's block is waited for
        // as long again before it is evaluated here.
        let own = Instant::now();
        if let (Some(xs), Some(out)) = (xs.get(slots.published..), out.get_mut(slots.published..)) {
            self.evaluate_here(xs, out);
        }
        let patience = own.elapsed();
        self.evaluate_unclaimed(slots, xs, out);
        let late = self.gather(slots, xs, out, patience);
        self.back_off(late);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::identify::ipso::{self, IpsoSettings, SearchSpace, Silent};
    use calib_core::identify::objective::{DEFAULT_K, Measurement, Objective};
    use calib_core::{ParameterErrors, ParameterSet, Problem};
    use nalgebra::{SVector, U6, U24};

    /// The bundled paper scenario (32 simulated poses of the ER10L-C10), as `calibrate` reads it.
    fn paper_measurements() -> Vec<Measurement<f64, Dyn>> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        crate::measurement::dataset::Dataset::load(
            &dir.join("robots/er10l-c10.toml"),
            &dir.join("data/er10l-c10-sim32.csv"),
        )
        .expect("bundled files")
        .readings
    }

    /// `check` of the paper's objective (its 24 parameters) on the bundled measurements.
    /// The objective with the joint and parameter counts at run time (`Dyn`, as `calibrate` has
    /// them) and, as the controller compiles it, fixed (`U6`, `U24`).
    fn with_paper_objective(
        check: impl FnOnce(&Objective<'_, f64, Dyn, Dyn>, &Objective<'_, f64, U6, U24>),
    ) {
        let robot = calib_core::model::paper::er10l_c10::<f64>();
        let measurements = paper_measurements();
        let fixed_measurements: Vec<Measurement<f64, U6>> = measurements
            .iter()
            .map(|m| m.recount().expect("6 joints"))
            .collect();
        let dynamic_robot = robot.recount::<Dyn>().expect("6 joints");
        let dynamic = Problem::new(
            &dynamic_robot,
            &ParameterErrors::zeros_for(dynamic_robot.joint_count()),
            ParameterSet::<Dyn, Dyn>::default_for(&dynamic_robot).expect("paper set"),
            &measurements,
            DEFAULT_K,
        )
        .expect("valid problem");
        let fixed = Problem::new(
            &robot,
            &ParameterErrors::zero(),
            ParameterSet::<U6, U24>::default_for(&robot).expect("paper set"),
            &fixed_measurements,
            DEFAULT_K,
        )
        .expect("valid problem");
        check(&Objective::new(&dynamic), &Objective::new(&fixed));
    }

    /// `a` (run-time count) and `b` (compiled count) to the last bit.
    fn assert_same_swarm(
        a: &ipso::IpsoResult<f64, Dyn>,
        b: &ipso::IpsoResult<f64, U24>,
        what: &str,
    ) {
        let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(a.best.as_slice()), bits(b.best.as_slice()), "{what}");
        assert_eq!(a.best_cost.to_bits(), b.best_cost.to_bits(), "{what}");
        assert_eq!(a.initial_cost.to_bits(), b.initial_cost.to_bits(), "{what}");
        assert_eq!(
            (a.generations, a.evaluations, a.stop),
            (b.generations, b.evaluations, b.stop),
            "{what}"
        );
    }

    /// Every vector path this CPU has, and every team size, gives the swarm of
    /// `Objective::value` on one thread bit for bit (300 generations of the paper's swarm).
    #[test]
    fn team_evaluates_bit_for_bit() {
        with_paper_objective(team_evaluates_bit_for_bit_on);
    }

    fn team_evaluates_bit_for_bit_on(
        objective: &Objective<'_, f64, Dyn, Dyn>,
        fixed: &Objective<'_, f64, U6, U24>,
    ) {
        let space = SearchSpace::paper(objective.problem().set());
        let fixed_space = SearchSpace::paper(fixed.problem().set());
        let mut settings = IpsoSettings::paper();
        settings.max_generations = 300;
        let mut plain = |x: &SVector<f64, 24>| fixed.value(x);
        let expected =
            ipso::optimize::<f64, 20, U24>(&mut plain, &fixed_space, &settings, &mut Silent)
                .expect("valid settings");
        assert!(expected.best_cost < 0.01 * expected.initial_cost);
        let available = Vectors::available();
        assert_eq!(available.first(), Some(&Vectors::Baseline));
        for vectors in available {
            let lanes = LaneObjective::with_vectors(objective, vectors);
            assert_eq!(lanes.vectors(), vectors);
            for i in 0..8 {
                let x = DVector::<f64>::from_fn(24, |j, _| {
                    2e-3 * (i as f64 - 3.5) * ((j % 5) as f64 - 2.0)
                });
                assert_eq!(lanes.value(&x).to_bits(), objective.value(&x).to_bits());
                let x24 = SVector::<f64, 24>::from_column_slice(x.as_slice());
                assert_eq!(lanes.value(&x).to_bits(), fixed.value(&x24).to_bits());
            }
            for threads in [1, 2, 3] {
                let team = SwarmTeam::run(&lanes, threads, |team| {
                    assert_eq!(team.members(), threads);
                    swarm_of(20, team, &space, &settings)
                })
                .expect("valid settings");
                assert_same_swarm(&team, &expected, &format!("{vectors:?}, {threads} threads"));
            }
        }
        // A swarm of one particle: the team evaluates it on the caller and draws its pairs
        // there too.
        let mut memory = [SVector::<f64, 24>::zeros(); 3];
        let [x, v, best] = &mut memory;
        let (mut costs, mut best_costs) = ([0.0], [0.0]);
        let alone = ipso::optimize_in(
            ipso::SwarmMemory::new(
                std::slice::from_mut(x),
                std::slice::from_mut(v),
                std::slice::from_mut(best),
                &mut costs,
                &mut best_costs,
            )
            .expect("slices of one length"),
            &mut plain,
            &fixed_space,
            &settings,
            &mut Silent,
        )
        .expect("valid settings");
        let lanes = LaneObjective::new(objective);
        let team = SwarmTeam::run(&lanes, 2, |team| swarm_of(1, team, &space, &settings))
            .expect("valid settings");
        assert_same_swarm(&team, &alone, "one particle");
    }

    /// The state of a swarm of `particles`.
    struct Memory {
        x: Vec<DVector<f64>>,
        v: Vec<DVector<f64>>,
        best: Vec<DVector<f64>>,
        costs: Vec<f64>,
        best_costs: Vec<f64>,
    }

    fn swarm_memory(particles: usize) -> Memory {
        let zero = vec![DVector::zeros(24); particles];
        Memory {
            x: zero.clone(),
            v: zero.clone(),
            best: zero,
            costs: vec![0.0; particles],
            best_costs: vec![0.0; particles],
        }
    }

    impl Memory {
        fn lend(&mut self) -> ipso::SwarmMemory<'_, f64, Dyn> {
            ipso::SwarmMemory::new(
                &mut self.x,
                &mut self.v,
                &mut self.best,
                &mut self.costs,
                &mut self.best_costs,
            )
            .expect("slices of one length")
        }
    }

    /// The swarm of `particles` on a team, as `calibrate` runs it.
    fn swarm_of(
        particles: usize,
        team: &mut SwarmTeam<'_, '_, '_>,
        space: &SearchSpace<f64, Dyn>,
        settings: &IpsoSettings<f64>,
    ) -> Result<ipso::IpsoResult<f64, Dyn>, ipso::IpsoError> {
        let mut memory = swarm_memory(particles);
        team.optimize(memory.lend(), space, settings, &mut Silent)
    }

    /// A generation `position_ready` started and its swarm did not complete (a batch of another
    /// size came, or the next generation started) is given up: every batch's costs are the
    /// objective's, never a helper's result of the positions given up.
    #[test]
    fn a_generation_left_unfinished_is_given_up() {
        with_paper_objective(|objective, _| {
            let lanes = LaneObjective::new(objective);
            let xs: Vec<DVector<f64>> = (0..20)
                .map(|i| {
                    DVector::from_fn(24, |j, _| 1e-3 * (i as f64 - 9.5) * ((j % 3) as f64 - 1.0))
                })
                .collect();
            let expected: Vec<u64> = xs.iter().map(|x| objective.value(x).to_bits()).collect();
            // Positions announced and then given up: not the ones asked for afterwards.
            let other: Vec<DVector<f64>> = xs.iter().map(|x| x * 2.0).collect();
            let batches = SwarmTeam::run(&lanes, 2, |team| {
                let mut costs = vec![0.0; 20];
                team.cost_batch(&xs, &mut costs);
                let mut batches = vec![costs.clone()];
                // Three particles announced, then a batch of one particle.
                for (i, x) in other.iter().enumerate().take(3) {
                    team.position_ready(i, x);
                }
                let mut one = [0.0];
                team.cost_batch(&xs[5..6], &mut one);
                batches.push(one.to_vec());
                // Four announced, four again from the start, then the whole batch.
                for announced in [&other, &xs] {
                    for (i, x) in announced.iter().enumerate().take(4) {
                        team.position_ready(i, x);
                    }
                }
                team.cost_batch(&xs, &mut costs);
                batches.push(costs);
                batches
            });
            let bits = |costs: &[f64]| costs.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&batches[0]), expected);
            assert_eq!(bits(&batches[1]), [expected[5]]);
            assert_eq!(bits(&batches[2]), expected);
        });
    }

    /// Helpers that the system runs late (each stalls 2 ms after it claims a block, ten times a
    /// block's work): the caller evaluates their blocks itself and the swarm is still bit for
    /// bit the one on one thread, taking at most about one stall per generation.
    #[test]
    fn late_helpers_change_nothing() {
        with_paper_objective(|objective, fixed| {
            let space = SearchSpace::paper(objective.problem().set());
            let mut settings = IpsoSettings::paper();
            settings.max_generations = 40;
            let mut plain = |x: &SVector<f64, 24>| fixed.value(x);
            let fixed_space = SearchSpace::paper(fixed.problem().set());
            let expected =
                ipso::optimize::<f64, 20, U24>(&mut plain, &fixed_space, &settings, &mut Silent)
                    .expect("valid settings");
            let lanes = LaneObjective::new(objective);
            for helpers in [1, 3] {
                let board = Board {
                    stall: Duration::from_millis(2),
                    ..Board::new(helpers)
                };
                let started = Instant::now();
                let team =
                    SwarmTeam::run_on(&board, &lanes, |team| swarm_of(20, team, &space, &settings))
                        .expect("valid settings");
                assert_same_swarm(&team, &expected, &format!("{helpers} late helpers"));
                // 41 batches; a stall holds a helper, not the caller.
                assert!(started.elapsed() < Duration::from_millis(41 * 2 + 200));
            }
        });
    }

    /// Helpers with nothing to do sleep after `SLEEP_AFTER` (they burn no core while the caller
    /// does something else), and the next generation wakes them: they evaluate again.
    #[test]
    fn idle_helpers_sleep_and_wake() {
        with_paper_objective(|objective, _| {
            let lanes = LaneObjective::new(objective);
            let xs: Vec<DVector<f64>> = (0..20)
                .map(|i| DVector::from_fn(24, |j, _| 1e-3 * (i as f64 - 9.5) * ((j % 3) as f64)))
                .collect();
            let expected: Vec<u64> = xs.iter().map(|x| objective.value(x).to_bits()).collect();
            // One helper per other core (with more, one of them always waits for a core).
            let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
            let board = Board::new((cores - 1).max(1));
            let asleep = |board: &Board| board.sleeping.iter().all(|f| f.load(Ordering::SeqCst));
            SwarmTeam::run_on(&board, &lanes, |team| {
                let mut costs = vec![0.0; 20];
                for _ in 0..3 {
                    team.cost_batch(&xs, &mut costs);
                    let bits: Vec<u64> = costs.iter().map(|c| c.to_bits()).collect();
                    assert_eq!(bits, expected);
                    let waited = Instant::now();
                    while !asleep(&board) && waited.elapsed() < Duration::from_secs(5) {
                        std::thread::sleep(Duration::from_millis(1));
                    }
                    assert!(asleep(&board), "helpers still awake after 5 s");
                }
                // Woken by the next generation, the helpers take blocks again within a few
                // generations (a helper that wakes later than the caller's own block takes is
                // not waited for, and the caller evaluates alone for a while: the test allows
                // 5 s, for a machine busy with other tests).
                let trying = Instant::now();
                let mut helped = cores < 2;
                while !helped && trying.elapsed() < Duration::from_secs(5) {
                    team.cost_batch(&xs, &mut costs);
                    assert_eq!(
                        costs.iter().map(|c| c.to_bits()).collect::<Vec<_>>(),
                        expected
                    );
                    let generation = team.generation;
                    helped = board.slots.get().is_some_and(|slots| {
                        slots
                            .done
                            .iter()
                            .any(|d| generation_of(d.load(Ordering::Acquire)) == generation)
                    });
                }
                assert!(helped, "no sleeping helper ever woke up to evaluate");
            });
        });
    }
}
