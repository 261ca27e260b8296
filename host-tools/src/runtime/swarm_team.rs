//! The swarm's particles evaluated on all cores, with no thread woken per generation.
//!
//! A generation of the paper's swarm (20 particles, 32 poses) is about 10 us of work: waking
//! sleeping threads for it each generation (as a general-purpose pool does) cost more than the
//! work split saved. A [`SwarmTeam`] keeps its helper threads for one swarm run
//! ([`SwarmTeam::run`], scoped threads): each generation the calling thread keeps the last
//! block of particles for itself and publishes the others (their coordinates copied into atomics,
//! no lock), every member takes blocks of particles until none is left, and the caller then waits
//! until every particle is evaluated (not for the helpers: one that did not wake up in time took
//! nothing and is not waited for). Waiting spins ([`SPINS`] checks, about a millisecond) and then
//! yields the core at every check, so a loaded machine still makes progress.
//!
//! The swarm's update between two generations runs on the caller alone, particle by particle;
//! each particle the members evaluate is published as soon as the update has given it its position
//! ([`CostFunction::position_ready`]), and a member evaluates it while the caller updates the
//! next ones (measured faster than publishing the whole generation after the update: docs/JOURNAL.md,
//! "Speed to the limit"). Its random pairs
//! `r1, r2` (960 draws from one sequential generator per generation of the paper's swarm) are
//! drawn ahead by a helper, which is idle while the caller updates: [`TeamPairs`] posts the next
//! generation's draws as an update starts and hands the swarm the pairs drawn during the previous
//! one, in the stream's order, so the swarm is bit for bit the one that draws them itself.
//!
//! Every particle's cost is computed alone by [`LaneObjective::value`]: the measurements in lane
//! layout collected once ([`Objective::lanes`]) and, where the CPU has AVX-512 (detected at run
//! time; the binary still runs on baseline x86-64), the evaluation compiled for it (an AVX2 build
//! exists too, for tests: [`Vectors::preferred`] says why it is not used). Rust never
//! fuses a multiplication and an addition on its own, so the wider vectors compute the same
//! operations with the same roundings: the costs, and the swarm, are bit for bit those of
//! [`Objective::value`] on one thread (test `team_evaluates_bit_for_bit`).

use calib_core::identify::ipso::{
    self, CostFunction, IpsoError, IpsoResult, IpsoSettings, Observer, RandomPairs, RandomStream,
    SearchSpace, SwarmMemory,
};
use calib_core::identify::objective::{Objective, PoseLanes};
use nalgebra::{DVector, Dyn};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock, PoisonError};

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
struct Shared {
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
    /// Particles of the current generation whose coordinates are in the slots (the first ones,
    /// in order): the caller publishes each as the update gives it its position
    /// ([`CostFunction::position_ready`]), and a member may take a block before all of it is
    /// published, evaluating each particle once it is.
    ready: Padded<AtomicUsize>,
    /// Set when the run is over (also on an early return).
    stop: Padded<AtomicBool>,
    /// The published particles and their costs, sized by the first generation.
    slots: OnceLock<Slots>,
    /// Draw jobs: as an update starts the caller posts one for the next update (`draw_pairs`
    /// pairs), which a helper, idle while the caller updates the particles, draws ahead from the
    /// swarm's stream; the caller draws a job itself only when nobody has claimed it by the time
    /// it needs the pairs. Numbered from 1: the last posted, claimed and drawn.
    posted: Padded<AtomicU64>,
    claimed: Padded<AtomicU64>,
    drawn: Padded<AtomicU64>,
    /// Pairs the posted job draws.
    draw_pairs: AtomicUsize,
    /// The swarm's stream and the pairs last drawn ahead from it.
    draws: Mutex<DrawnAhead>,
}

/// A generation's particles, as the bits of their coordinates (`D` per particle, written by
/// the caller before it publishes them), and their costs' bits (written by whoever evaluated
/// the particle): atomics, read and written without locks, so that publishing a generation
/// takes no lock the members would pass between their cores.
struct Slots {
    /// Coordinates per particle (the number of parameters).
    dimension: usize,
    coordinates: Box<[AtomicU64]>,
    costs: Box<[AtomicU64]>,
    /// The generation's split among the members ([`split`]), fixed with the slots: the block
    /// size, and the particles published (all but the caller's block).
    block: usize,
    published: usize,
}

impl Slots {
    fn new(particles: usize, dimension: usize, blocks: usize) -> Self {
        let bits = |n: usize| (0..n).map(|_| AtomicU64::new(f64::NAN.to_bits())).collect();
        let (block, published) = split(particles, blocks);
        Self {
            dimension,
            coordinates: bits(particles * dimension),
            costs: bits(particles),
            block,
            published,
        }
    }

    fn particles(&self) -> usize {
        self.costs.len()
    }
}

/// Pairs `r1, r2` in the stream's order as two arrays, the form a particle's update reads in
/// place ([`RandomPairs::lend_particle`]).
#[derive(Default)]
struct Pairs {
    r1: Vec<f64>,
    r2: Vec<f64>,
}

impl Pairs {
    fn len(&self) -> usize {
        self.r1.len().min(self.r2.len())
    }
}

/// The stream of `r1, r2` and the pairs a draw job took from it.
struct DrawnAhead {
    stream: RandomStream,
    pairs: Pairs,
}

impl DrawnAhead {
    /// The stream's next `count` pairs, replacing the previous ones.
    fn draw(&mut self, count: usize) {
        let Pairs { r1, r2 } = &mut self.pairs;
        r1.resize(count, 0.0);
        r2.resize(count, 0.0);
        RandomPairs::<f64>::particle(&mut self.stream, r1, r2);
    }
}

impl Shared {
    fn draws(&self) -> std::sync::MutexGuard<'_, DrawnAhead> {
        self.draws.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Draws the posted job's pairs if nobody has claimed it yet.
    fn draw_if_unclaimed(&self) {
        let job = self.posted.load(Ordering::Acquire);
        if job == 0
            || self
                .claimed
                .compare_exchange(job - 1, job, Ordering::AcqRel, Ordering::Relaxed)
                .is_err()
        {
            return;
        }
        self.draws().draw(self.draw_pairs.load(Ordering::Acquire));
        self.drawn.store(job, Ordering::Release);
    }
}

/// Sets `stop` when the run ends, however it ends, so the helpers leave and the scope joins.
struct StopOnDrop<'s>(&'s AtomicBool);

impl Drop for StopOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// The particles' costs on several threads, the caller one of them; see the module docs.
pub struct SwarmTeam<'t, 'o, 'p> {
    objective: &'t LaneObjective<'o, 'p>,
    shared: &'t Shared,
    members: usize,
    /// The current generation was started by [`CostFunction::position_ready`], which has
    /// published this many particles.
    started: Option<usize>,
    /// The particle the caller evaluates from the slots (sized once: no allocation in a
    /// generation).
    particle: DVector<f64>,
}

impl<'o, 'p> SwarmTeam<'_, 'o, 'p> {
    /// Runs `swarm` with a team of `threads` (at least 1; the caller and `threads - 1` helpers,
    /// fewer if the system cannot start them) evaluating `objective`, and the pairs `r1, r2` of
    /// the stream of `seed` ([`RandomStream`]) drawn ahead by a helper while the caller updates;
    /// the helpers end when `swarm` returns. `swarm` gets the team as the cost function and its
    /// pairs for [`ipso::optimize_drawing`] (or [`SwarmTeam::optimize`]).
    pub fn run<R>(
        objective: &LaneObjective<'o, 'p>,
        threads: usize,
        seed: u64,
        swarm: impl FnOnce(&mut SwarmTeam<'_, 'o, 'p>, &mut TeamPairs<'_>) -> R,
    ) -> R {
        let wanted = threads.max(1);
        let shared = Shared {
            generation: Padded::default(),
            evaluated: Padded::default(),
            ready: Padded::default(),
            stop: Padded::default(),
            next: Padded::default(),
            blocks: wanted,
            slots: OnceLock::new(),
            posted: Padded::default(),
            claimed: Padded::default(),
            drawn: Padded::default(),
            draw_pairs: AtomicUsize::new(0),
            draws: Mutex::new(DrawnAhead {
                stream: RandomStream::new(seed),
                pairs: Pairs::default(),
            }),
        };
        std::thread::scope(|scope| {
            let _stop = StopOnDrop(&shared.stop);
            // A helper the system cannot start is one member fewer (never a panic).
            let helpers = (1..wanted)
                .filter(|_| {
                    let shared = &shared;
                    super::helper_threads::spawn(scope, "calib-swarm", move || {
                        helper(objective, shared);
                    })
                    .is_some()
                })
                .count();
            let members = 1 + helpers;
            swarm(
                &mut SwarmTeam {
                    objective,
                    shared: &shared,
                    members,
                    started: None,
                    particle: DVector::zeros(0),
                },
                &mut TeamPairs {
                    shared: &shared,
                    taken: 0,
                    pairs: Pairs::default(),
                    next: 0,
                },
            )
        })
    }

    /// The number of threads evaluating (the caller included).
    #[cfg(test)]
    pub(crate) fn members(&self) -> usize {
        self.members
    }

    /// [`ipso::optimize_drawing`] with this team as the cost and `pairs`, compiled for AVX-512
    /// when the objective evaluates with it ([`Vectors::Avx512`]; otherwise the baseline): the
    /// swarm's update between generations (velocities, positions, walls: on the caller alone)
    /// then vectorises too. Same operations, same roundings: the same swarm bit for bit (test
    /// `team_evaluates_bit_for_bit`).
    pub fn optimize(
        &mut self,
        memory: SwarmMemory<'_, f64, Dyn>,
        pairs: &mut TeamPairs<'_>,
        space: &SearchSpace<f64, Dyn>,
        settings: &IpsoSettings<f64>,
        observer: &mut impl Observer<f64>,
    ) -> Result<IpsoResult<f64, Dyn>, IpsoError> {
        #[cfg(target_arch = "x86_64")]
        if self.objective.vectors() == Vectors::Avx512 {
            // SAFETY: an objective keeps only vectors `Vectors::detected` found on this CPU.
            return unsafe { optimize_avx512(memory, self, pairs, space, settings, observer) };
        }
        ipso::optimize_drawing(memory, self, pairs, space, settings, observer)
    }
}

/// [`ipso::optimize_drawing`] (inlined on a PC) compiled for AVX2 with AVX-512F/VL: the update
/// of the paper's swarm alone, its pairs ready, 0.97 ms per run against 1.37 in the baseline's
/// SSE2 (a scratch criterion bench; 1.52 before the pairs were taken a particle at a time).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl")]
fn optimize_avx512(
    memory: SwarmMemory<'_, f64, Dyn>,
    team: &mut SwarmTeam<'_, '_, '_>,
    pairs: &mut TeamPairs<'_>,
    space: &SearchSpace<f64, Dyn>,
    settings: &IpsoSettings<f64>,
    observer: &mut impl Observer<f64>,
) -> Result<IpsoResult<f64, Dyn>, IpsoError> {
    ipso::optimize_drawing(memory, team, pairs, space, settings, observer)
}

fn helper(objective: &LaneObjective<'_, '_>, shared: &Shared) {
    let mut seen = 0;
    // The particle evaluated, sized once (no allocation in a generation).
    let mut particle = DVector::zeros(0);
    loop {
        wait_until(|| {
            shared.stop.load(Ordering::Acquire)
                || shared.generation.load(Ordering::Acquire) != seen
                || shared.posted.load(Ordering::Acquire) != shared.claimed.load(Ordering::Acquire)
        });
        if shared.stop.load(Ordering::Acquire) {
            return;
        }
        let generation = shared.generation.load(Ordering::Acquire);
        if generation != seen {
            seen = generation;
            take_particles(objective, shared, &mut particle);
        }
        shared.draw_if_unclaimed();
    }
}

/// How a generation of `particles` is shared among `blocks` members: the caller's block is the
/// last `block` particles, which it evaluates from its own memory; the first `published` are
/// published and taken by the members in blocks of the same size. Returns `(block, published)`.
fn split(particles: usize, blocks: usize) -> (usize, usize) {
    let block = particles.div_ceil(blocks.max(1)).max(1);
    (block, particles.saturating_sub(block))
}

/// Evaluates published particles, a block at a time, until no block is left to take; waits for
/// each particle of a block taken until it is published.
fn take_particles(objective: &LaneObjective<'_, '_>, shared: &Shared, particle: &mut DVector<f64>) {
    let Some(slots) = shared.slots.get() else {
        return;
    };
    let d = slots.dimension;
    if particle.len() != d {
        *particle = DVector::zeros(d);
    }
    let (block, published) = (slots.block, slots.published);
    loop {
        // Acquire: `ready` was reset before `next` was.
        let start = shared.next.fetch_add(block, Ordering::AcqRel);
        let end = (start + block).min(published);
        if start >= end {
            return;
        }
        let (Some(coordinates), Some(costs)) = (
            slots.coordinates.get(start * d..end * d),
            slots.costs.get(start..end),
        ) else {
            return;
        };
        for (i, (x, cost)) in (start..).zip(coordinates.chunks_exact(d.max(1)).zip(costs)) {
            // Acquire: the coordinates stored before `ready` passed `i` are visible.
            wait_until(|| {
                shared.ready.load(Ordering::Acquire) > i || shared.stop.load(Ordering::Acquire)
            });
            if shared.ready.load(Ordering::Acquire) <= i {
                return; // the run is over
            }
            for (p, c) in particle.as_mut_slice().iter_mut().zip(x) {
                *p = f64::from_bits(c.load(Ordering::Relaxed));
            }
            cost.store(objective.value(particle).to_bits(), Ordering::Relaxed);
        }
        // Release: the costs stored above are visible to whoever sees the count.
        shared.evaluated.fetch_add(costs.len(), Ordering::AcqRel);
    }
}

impl SwarmTeam<'_, '_, '_> {
    /// Starts a generation: nothing published, nothing evaluated, every block free. The members
    /// are done with the previous generation (the caller waited for all of its particles); one
    /// that claims a block of the new generation before it sees the count waits for its
    /// particles like the others (`ready` is reset before `next`).
    fn start_generation(&self) {
        self.shared.ready.store(0, Ordering::Release);
        self.shared.evaluated.store(0, Ordering::Release);
        self.shared.next.store(0, Ordering::Release);
        // Only the caller writes the count: a plain store (no locked instruction).
        let generation = self.shared.generation.load(Ordering::Relaxed);
        self.shared
            .generation
            .store(generation + 1, Ordering::Release);
    }

    /// Copies the coordinates of particle `index` into the slots (not yet marked ready).
    fn store_coordinates(slots: &Slots, index: usize, x: &DVector<f64>) {
        let d = slots.dimension;
        if let Some(slot) = slots.coordinates.get(index * d..(index + 1) * d) {
            for (slot, c) in slot.iter().zip(x.as_slice()) {
                slot.store(c.to_bits(), Ordering::Relaxed);
            }
        }
    }

    /// Ends a generation [`CostFunction::position_ready`] started that no `cost_batch` of its
    /// swarm completed (another swarm's batch came, or a new generation): every particle marked
    /// ready (the members evaluate what the slots hold; those costs are not used), then waited
    /// for, so that no member is still in it when the next generation resets the counts.
    fn settle(&mut self) {
        if self.started.take().is_some()
            && let Some(slots) = self.shared.slots.get()
        {
            self.shared.ready.store(slots.published, Ordering::Release);
            self.finish_generation(slots.published);
        }
    }

    /// Waits until the members have evaluated the `published` particles, taking the blocks
    /// nobody has taken.
    fn finish_generation(&mut self, published: usize) {
        // Looked at first (a load): a claim (a locked write) would take the counter's line from
        // the helper that has it (about 0.2 us a generation, measured).
        if self.shared.next.load(Ordering::Acquire) < published {
            take_particles(self.objective, self.shared, &mut self.particle);
        }
        wait_until(|| self.shared.evaluated.load(Ordering::Acquire) >= published);
    }
}

impl CostFunction<f64, Dyn> for SwarmTeam<'_, '_, '_> {
    fn cost(&mut self, x: &DVector<f64>) -> f64 {
        self.objective.value(x)
    }

    fn position_ready(&mut self, index: usize, x: &DVector<f64>) {
        if self.members == 1 {
            return;
        }
        let Some(slots) = self.shared.slots.get() else {
            return; // the first generation: published by `cost_batch`
        };
        if index == 0 {
            self.settle();
            self.start_generation();
            self.started = Some(0);
        }
        if self.started == Some(index) && index < slots.published {
            Self::store_coordinates(slots, index, x);
            // Release: with the coordinates above.
            self.shared.ready.store(index + 1, Ordering::Release);
            self.started = Some(index + 1);
        }
    }

    fn cost_batch(&mut self, xs: &[DVector<f64>], out: &mut [f64]) {
        let dimension = xs.first().map_or(0, |x| x.len());
        let slots = (self.members > 1 && xs.len() > 1)
            .then(|| {
                self.shared
                    .slots
                    .get_or_init(|| Slots::new(xs.len(), dimension, self.shared.blocks))
            })
            .filter(|slots| slots.particles() == xs.len() && slots.dimension == dimension);
        let Some(slots) = slots else {
            // A team of one, a swarm of one particle, or not the swarm the slots were made
            // for: evaluated here.
            self.settle();
            for (c, x) in out.iter_mut().zip(xs) {
                *c = self.objective.value(x);
            }
            return;
        };
        let published = slots.published;
        // The particles `position_ready` has not published (all of them in the first
        // generation), then all marked ready at once.
        let done = match self.started.take() {
            Some(done) => done,
            None => {
                self.start_generation();
                0
            }
        };
        for (index, x) in xs.iter().enumerate().take(published).skip(done) {
            Self::store_coordinates(slots, index, x);
        }
        self.shared.ready.store(published, Ordering::Release);
        // The caller's own block, from its own memory (the lines a member reads have to move
        // between the cores: only the published particles are copied).
        for (x, c) in xs.iter().zip(out.iter_mut()).skip(published) {
            *c = self.objective.value(x);
        }
        self.finish_generation(published);
        for (c, bits) in out.iter_mut().zip(slots.costs.iter()).take(published) {
            *c = f64::from_bits(bits.load(Ordering::Relaxed));
        }
    }
}

/// The swarm's pairs `r1, r2` during a [`SwarmTeam::run`]: those a member drew ahead while the
/// particles were evaluated, in the order of the stream, drawn on the spot when there are none
/// (a team of one, a swarm of one particle).
pub struct TeamPairs<'t> {
    shared: &'t Shared,
    /// The last draw job taken.
    taken: u64,
    /// This generation's pairs and the next one to give.
    pairs: Pairs,
    next: usize,
}

impl TeamPairs<'_> {
    /// Appends pairs drawn from the stream after those this has (taking the vector when all
    /// of them are given).
    fn queue(&mut self, drawn: &mut Pairs) {
        if self.next >= self.pairs.len() {
            std::mem::swap(drawn, &mut self.pairs);
            self.next = 0;
        } else {
            self.pairs.r1.extend_from_slice(&drawn.r1);
            self.pairs.r2.extend_from_slice(&drawn.r2);
        }
    }

    /// Queues the pairs of the job last posted, drawing them here if nobody has claimed it.
    /// Afterwards no job is outstanding, and nobody else draws from the stream.
    fn take_job(&mut self) {
        let job = self.shared.posted.load(Ordering::Acquire);
        if job > self.taken {
            self.shared.draw_if_unclaimed();
            wait_until(|| self.shared.drawn.load(Ordering::Acquire) >= job);
            let mut draws = self.shared.draws();
            self.queue(&mut draws.pairs);
            self.taken = job;
        }
    }

    /// Queues `count` pairs drawn here (no job may be outstanding).
    fn draw_here(&mut self, count: usize) {
        let mut draws = self.shared.draws();
        draws.draw(count);
        self.queue(&mut draws.pairs);
    }
}

impl RandomPairs<f64> for TeamPairs<'_> {
    fn generation(&mut self, pairs: usize) {
        // Every draw from the stream, by a job or here, is queued in the order it was drawn:
        // only one job is ever outstanding, and it is taken before anything is drawn here.
        self.take_job();
        let left = self.pairs.len().saturating_sub(self.next);
        if pairs > left {
            self.draw_here(pairs - left);
        }
        // The next update's pairs, drawn by a helper while this one runs.
        self.shared.draw_pairs.store(pairs, Ordering::Release);
        let posted = self.shared.posted.load(Ordering::Relaxed);
        self.shared.posted.store(posted + 1, Ordering::Release);
    }

    fn pair(&mut self) -> (f64, f64) {
        if self.next >= self.pairs.len() {
            // More pairs than announced: those of the next job, then the stream's.
            self.take_job();
            if self.next >= self.pairs.len() {
                self.draw_here(1);
            }
        }
        let r1 = self.pairs.r1.get(self.next).copied().unwrap_or(0.0);
        let r2 = self.pairs.r2.get(self.next).copied().unwrap_or(0.0);
        self.next += 1;
        (r1, r2)
    }

    fn lend_particle(&mut self, count: usize) -> Option<(&[f64], &[f64])> {
        let queued = self.next..self.next + count;
        let (r1, r2) = (
            self.pairs.r1.get(queued.clone())?,
            self.pairs.r2.get(queued)?,
        );
        self.next += count;
        Some((r1, r2))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::identify::ipso::{self, IpsoSettings, SearchSpace, Silent};
    use calib_core::identify::objective::{DEFAULT_K, Measurement};
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
                let team = SwarmTeam::run(&lanes, threads, settings.seed, |team, pairs| {
                    assert_eq!(team.members(), threads);
                    swarm_of(20, team, pairs, &space, &settings)
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
        let team = SwarmTeam::run(&lanes, 2, settings.seed, |team, pairs| {
            swarm_of(1, team, pairs, &space, &settings)
        })
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
        pairs: &mut TeamPairs<'_>,
        space: &SearchSpace<f64, Dyn>,
        settings: &IpsoSettings<f64>,
    ) -> Result<ipso::IpsoResult<f64, Dyn>, ipso::IpsoError> {
        let mut memory = swarm_memory(particles);
        team.optimize(memory.lend(), pairs, space, settings, &mut Silent)
    }

    /// A generation `position_ready` started and its swarm did not complete (a batch of another
    /// size came, or the next generation started) is settled: no member is left waiting in it,
    /// and every batch's costs are the objective's.
    #[test]
    fn a_generation_left_unfinished_is_settled() {
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
            let batches = SwarmTeam::run(&lanes, 2, 1, |team, _| {
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

    /// The pairs come in the stream's order whatever the swarm announces: drawn ahead, drawn
    /// on the spot, and more than announced.
    #[test]
    fn team_pairs_follow_the_stream() {
        with_paper_objective(|objective, _| team_pairs_follow_the_stream_on(objective));
    }

    fn team_pairs_follow_the_stream_on(objective: &Objective<'_, f64, Dyn, Dyn>) {
        let lanes = LaneObjective::new(objective);
        let mut expected = vec![(0.0, 0.0); 4 * 24 + 7];
        RandomStream::new(5).fill(&mut expected);
        let xs = vec![DVector::<f64>::zeros(24); 2];
        let taken = SwarmTeam::run(&lanes, 2, 5, |team, pairs| {
            let mut taken = Vec::new();
            // Drawn on the spot: three announced, five taken.
            pairs.generation(3);
            taken.extend((0..5).map(|_| pairs.pair()));
            // Drawn ahead by a member while two particles are evaluated (48 pairs), of which
            // 40 are taken before the next announcement.
            let mut costs = [0.0; 2];
            team.cost_batch(&xs, &mut costs);
            assert_eq!(costs[0].to_bits(), objective.value(&xs[0]).to_bits());
            pairs.generation(48);
            taken.extend((0..40).map(|_| pairs.pair()));
            // Ten announced: the eight left and two more drawn here.
            pairs.generation(10);
            taken.extend((0..10).map(|_| pairs.pair()));
            // A particle's pairs at once: lent in place from those queued (24 announced),
            // then a particle's taken one by one past them (the next job's, drawn ahead or
            // here).
            pairs.generation(24);
            let (r1, r2) = pairs.lend_particle(24).expect("24 pairs queued");
            taken.extend(r1.iter().copied().zip(r2.iter().copied()));
            let (mut r1, mut r2) = ([0.0; 24], [0.0; 24]);
            pairs.particle(&mut r1, &mut r2);
            taken.extend(r1.into_iter().zip(r2));
            taken
        });
        assert_eq!(taken, expected);
    }
}
