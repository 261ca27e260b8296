//! The improved particle swarm optimiser (IPSO) of the paper, section 2.2: particles start from
//! Halton points (eq. 8-9) and fly with the constriction-factor velocity update (eq. 10):
//!
//! `v <- K (v + c1 r1 (pbest - x) + c2 r2 (gbest - x))`, `x <- x + v` (time step 1),
//! `K = 2 / |2 - phi - sqrt(phi^2 - 4 phi)|`, `phi = c1 + c2 > 4`.
//!
//! The dimension `D` is a nalgebra dimension (`Const<24>` on a controller, `Dyn` on a host).
//! [`optimize`] takes the swarm size `P` as a const generic and
//! keeps the whole swarm on the stack (`3 P D + 2 P` scalars: 11.6 KiB for P = 20, D = 24 in
//! f64, half in f32); [`optimize_in`] runs the same algorithm in memory the caller lends
//! ([`SwarmMemory`]), for a swarm size chosen at run time. `r1, r2` are drawn per
//! particle and per dimension from `Xoshiro256Plus` (the xoshiro variant meant for floating-point
//! numbers; the top 53 or 24 bits are used) seeded by the caller ([`RandomStream`]), so the same
//! seed and data give bit-identical results on every target; [`optimize_drawing`] takes them
//! from the caller ([`RandomPairs`]), who may draw a generation's pairs ahead on another core.
//!
//! Initialisation: particle `i` (0-based) takes Halton point `start + i` for its position,
//! `center + (2h - 1) half_width`, and Halton point `start + P + i` (the continuation of the same
//! sequence) for its velocity, `(2h - 1) half_width`. Updates are synchronous: all particles move,
//! then personal and global bests are updated (paper steps 5-9).
//!
//! Bounds: a coordinate that leaves `[lower, upper]` is set onto the bound and its velocity
//! component to zero (an absorbing wall), so the swarm never evaluates outside the search box.

use crate::identify::halton::{self, MAX_DIMENSION, Scrambling};
use crate::model::JointCount;
use crate::scalar::Real;
use core::fmt;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OVector, U1};
use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256Plus;

/// Something to minimise: the cost of a packed parameter vector. Non-finite costs count as +inf.
pub trait CostFunction<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// The cost at `x`.
    fn cost(&mut self, x: &OVector<T, D>) -> T;

    /// The costs of several points (`out[i]` for `xs[i]`); the swarm calls this once per
    /// generation. The default evaluates one after the other; a host may evaluate in parallel.
    fn cost_batch(&mut self, xs: &[OVector<T, D>], out: &mut [T]) {
        for (x, c) in xs.iter().zip(out.iter_mut()) {
            *c = self.cost(x);
        }
    }

    /// Told by the swarm, during a generation's update, that particle `index` has its new
    /// position `x` (final for this generation; the particles come in order, from 0, and
    /// [`CostFunction::cost_batch`] then asks for all of them). A host evaluating on other
    /// threads starts on the first particles while the others are updated. The default does
    /// nothing.
    // A host's speed-up hook (host-tools' swarm team evaluates on helper threads); hidden from
    // the docs because a controller never needs it.
    #[doc(hidden)]
    fn position_ready(&mut self, index: usize, x: &OVector<T, D>) {
        let _ = (index, x);
    }
}

impl<T: Real, D: Dim, F: FnMut(&OVector<T, D>) -> T> CostFunction<T, D> for F
where
    DefaultAllocator: Allocator<D>,
{
    fn cost(&mut self, x: &OVector<T, D>) -> T {
        self(x)
    }
}

/// What an observer wants after a generation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Control {
    /// Go on.
    Continue,
    /// Stop now; the result says [`StopReason::Cancelled`].
    Cancel,
}

/// Called once per generation (0 = the initial swarm) with the best cost so far.
pub trait Observer<T> {
    /// Reports a finished generation.
    fn generation(&mut self, generation: u32, best_cost: T) -> Control;
}

impl<T, F: FnMut(u32, T) -> Control> Observer<T> for F {
    fn generation(&mut self, generation: u32, best_cost: T) -> Control {
        self(generation, best_cost)
    }
}

/// An observer that never cancels.
pub struct Silent;

impl<T> Observer<T> for Silent {
    fn generation(&mut self, _: u32, _: T) -> Control {
        Control::Continue
    }
}

/// Where the swarm starts and where it may search (per parameter, mm or rad).
#[derive(Clone, Debug, PartialEq)]
pub struct SearchSpace<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// Centre of the initial swarm (usually the current estimate, e.g. zero errors).
    pub center: OVector<T, D>,
    /// Half width of the initial positions and velocities (paper: 0.01 rad, 0.5 mm).
    pub half_width: OVector<T, D>,
    /// Lower search bound.
    pub lower: OVector<T, D>,
    /// Upper search bound.
    pub upper: OVector<T, D>,
}

/// `Copy` for a fixed dimension (`Const<D>`).
impl<T: Real, D: Dim> Copy for SearchSpace<T, D>
where
    DefaultAllocator: Allocator<D>,
    OVector<T, D>: Copy,
{
}

/// Paper's initial half range of angle errors, rad.
pub const PAPER_ANGLE_RANGE: f64 = 0.01;
/// Paper's initial half range of length errors, mm.
pub const PAPER_LENGTH_RANGE: f64 = 0.5;
/// Default search bounds as a multiple of the initial half range. With 2 the swarm stalled at a
/// wall in one of two seeds of the paper scenario; with 5, 10 and 100 it converged in all tried.
pub const DEFAULT_BOUND_FACTOR: f64 = 10.0;

impl<T: Real, D: Dim> SearchSpace<T, D>
where
    DefaultAllocator: Allocator<D>,
{
    /// The space of the parameters of `set` around zero errors: initial half range `angle` (rad)
    /// for angles and `length` (mm) for lengths, bounds `bound_factor` times that.
    pub fn for_parameters<N: JointCount>(
        set: &crate::model::parameters::ParameterSet<N, D>,
        angle: T,
        length: T,
        bound_factor: T,
    ) -> Self {
        let widths = OVector::<T, D>::from_iterator_generic(
            set.dim(),
            U1,
            set.parameters()
                .iter()
                .map(|p| if p.is_angle() { angle } else { length }),
        );
        Self::spanning(set.zeros(), widths, bound_factor)
    }

    /// [`SearchSpace::for_parameters`] with the paper's ranges (0.01 rad, 0.5 mm) and
    /// [`DEFAULT_BOUND_FACTOR`].
    pub fn paper<N: JointCount>(set: &crate::model::parameters::ParameterSet<N, D>) -> Self {
        Self::for_parameters(
            set,
            T::of(PAPER_ANGLE_RANGE),
            T::of(PAPER_LENGTH_RANGE),
            T::of(DEFAULT_BOUND_FACTOR),
        )
    }

    /// The box `center +- half_width` for the start and `center +- bound_factor * half_width` for
    /// the search; two vectors of different lengths (a run-time `Dyn` dimension holds any) are
    /// refused with [`IpsoError::InvalidSize`].
    pub fn around(
        center: OVector<T, D>,
        half_width: OVector<T, D>,
        bound_factor: T,
    ) -> Result<Self, IpsoError> {
        if center.len() != half_width.len() {
            return Err(IpsoError::InvalidSize);
        }
        Ok(Self::spanning(center, half_width, bound_factor))
    }

    /// [`Self::around`] of two vectors of one length.
    fn spanning(center: OVector<T, D>, half_width: OVector<T, D>, bound_factor: T) -> Self {
        let reach = &half_width * bound_factor;
        Self {
            lower: &center - &reach,
            upper: &center + &reach,
            center,
            half_width,
        }
    }

    /// Finite everywhere, non-negative half widths and `lower <= upper` in every dimension.
    pub fn is_valid(&self) -> bool {
        let finite = |v: &OVector<T, D>| v.iter().all(|x| x.finite());
        finite(&self.center)
            && finite(&self.half_width)
            && finite(&self.lower)
            && finite(&self.upper)
            && !self.half_width.iter().any(|w| *w < T::zero())
            && !self
                .lower
                .iter()
                .zip(self.upper.iter())
                .any(|(lo, hi)| lo > hi)
    }
}

/// Settings of a swarm run; [`IpsoSettings::paper`] gives the paper's values.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IpsoSettings<T> {
    /// Cognitive acceleration coefficient (paper: 2.05).
    pub c1: T,
    /// Social acceleration coefficient (paper: 2.05).
    pub c2: T,
    /// Maximum number of generations after the initial swarm (paper: 2000).
    pub max_generations: u32,
    /// Stop as soon as the best cost is at most this (default: -inf, i.e. never).
    pub target_cost: T,
    /// Stop after this many generations without improvement of the best cost (0: never).
    pub stall_generations: u32,
    /// Halton index of the first particle (the paper's k; default 1, skipping the zero point).
    pub halton_start: u64,
    /// Digit scrambling of the Halton points (default none, as in the paper).
    pub scrambling: Scrambling,
    /// Seed of the generator of `r1, r2`.
    pub seed: u64,
}

impl<T: Real> IpsoSettings<T> {
    /// The paper's settings: c1 = c2 = 2.05, 2000 generations, plain Halton from k = 1, seed 0.
    pub fn paper() -> Self {
        Self {
            c1: T::of(2.05),
            c2: T::of(2.05),
            max_generations: 2000,
            target_cost: T::of(f64::NEG_INFINITY),
            stall_generations: 0,
            halton_start: 1,
            scrambling: Scrambling::None,
            seed: 0,
        }
    }
}

/// Why the swarm stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StopReason {
    /// The maximum number of generations ran.
    MaxGenerations,
    /// The best cost reached the target.
    TargetReached,
    /// The best cost did not improve for the configured number of generations.
    Stalled,
    /// The observer cancelled the run.
    Cancelled,
}

/// Why a swarm run was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum IpsoError {
    /// `c1`, `c2` are not finite and positive with `c1 + c2 > 4` (eq. 10 needs phi > 4).
    InvalidCoefficients,
    /// A bound or width is not finite, a width is negative, or a lower bound exceeds its upper one.
    InvalidSearchSpace,
    /// `D` exceeds the number of Halton bases (64), the swarm is empty, or the slices of a
    /// [`SwarmMemory`] or the vectors of a search space differ in length.
    InvalidSize,
}

impl fmt::Display for IpsoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::InvalidCoefficients => "c1 and c2 must be positive with c1 + c2 > 4",
            Self::InvalidSearchSpace => {
                "search space: bounds and widths must be finite, widths >= 0, lower <= upper"
            }
            Self::InvalidSize => "swarm size must be at least 1 and dimension at most 64",
        })
    }
}

impl core::error::Error for IpsoError {}

/// The outcome of a swarm run.
#[derive(Clone, Debug, PartialEq)]
pub struct IpsoResult<T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// Best position found (mm, rad).
    pub best: OVector<T, D>,
    /// Its cost.
    pub best_cost: T,
    /// Cost of the best initial particle.
    pub initial_cost: T,
    /// Generations run after the initial swarm.
    pub generations: u32,
    /// Cost evaluations.
    pub evaluations: u64,
    /// Why it stopped.
    pub stop: StopReason,
}

/// `Copy` for a fixed dimension (`Const<D>`).
impl<T: Real, D: Dim> Copy for IpsoResult<T, D>
where
    DefaultAllocator: Allocator<D>,
    OVector<T, D>: Copy,
{
}

/// The constriction factor `K` of eq. (10) for `phi = c1 + c2 > 4`.
pub fn constriction<T: Real>(c1: T, c2: T) -> Result<T, IpsoError> {
    let phi = c1 + c2;
    if !(c1.finite() && c2.finite() && c1 > T::zero() && c2 > T::zero() && phi > T::of(4.0)) {
        return Err(IpsoError::InvalidCoefficients);
    }
    let two = T::of(2.0);
    Ok(two / (two - phi - (phi * phi - T::of(4.0) * phi).sqrt()).abs())
}

fn sanitize<T: Real>(cost: T) -> T {
    if cost.finite() {
        cost
    } else {
        T::of(f64::INFINITY)
    }
}

/// Runs the swarm of `P` particles in `D` dimensions on `cost`, its state on the stack
/// ([`optimize_in`] with arrays of `P`).
pub fn optimize<T, const P: usize, D: Dim>(
    cost: &mut impl CostFunction<T, D>,
    space: &SearchSpace<T, D>,
    settings: &IpsoSettings<T>,
    observer: &mut impl Observer<T>,
) -> Result<IpsoResult<T, D>, IpsoError>
where
    T: Real,
    DefaultAllocator: Allocator<D>,
{
    let zeros = || OVector::<T, D>::zeros_generic(space.center.shape_generic().0, U1);
    let mut positions: [OVector<T, D>; P] = core::array::from_fn(|_| zeros());
    let mut velocities: [OVector<T, D>; P] = core::array::from_fn(|_| zeros());
    let mut best_positions: [OVector<T, D>; P] = core::array::from_fn(|_| zeros());
    let mut costs = [T::zero(); P];
    let mut best_costs = [T::zero(); P];
    let memory = SwarmMemory::new(
        &mut positions,
        &mut velocities,
        &mut best_positions,
        &mut costs,
        &mut best_costs,
    )?;
    optimize_in(memory, cost, space, settings, observer)
}

/// The state of a swarm whose size is known at run time (a host choosing it from a setting):
/// one entry per particle in each slice, all of the same length (the swarm size).
pub struct SwarmMemory<'m, T: Real, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    positions: &'m mut [OVector<T, D>],
    velocities: &'m mut [OVector<T, D>],
    best_positions: &'m mut [OVector<T, D>],
    costs: &'m mut [T],
    best_costs: &'m mut [T],
}

impl<'m, T: Real, D: Dim> SwarmMemory<'m, T, D>
where
    DefaultAllocator: Allocator<D>,
{
    /// The swarm's memory; the slices' contents are overwritten by the run. Fails with
    /// [`IpsoError::InvalidSize`] unless all have the same non-zero length.
    pub fn new(
        positions: &'m mut [OVector<T, D>],
        velocities: &'m mut [OVector<T, D>],
        best_positions: &'m mut [OVector<T, D>],
        costs: &'m mut [T],
        best_costs: &'m mut [T],
    ) -> Result<Self, IpsoError> {
        let p = positions.len();
        if p == 0
            || velocities.len() != p
            || best_positions.len() != p
            || costs.len() != p
            || best_costs.len() != p
        {
            return Err(IpsoError::InvalidSize);
        }
        Ok(Self {
            positions,
            velocities,
            best_positions,
            costs,
            best_costs,
        })
    }

    /// The number of particles.
    pub fn particles(&self) -> usize {
        self.positions.len()
    }
}

/// Runs the swarm of `memory.particles()` particles in `D` dimensions on `cost`: the same
/// algorithm and, for the same swarm size, bit for bit the same result as [`optimize`].
pub fn optimize_in<T, D: Dim>(
    memory: SwarmMemory<'_, T, D>,
    cost: &mut impl CostFunction<T, D>,
    space: &SearchSpace<T, D>,
    settings: &IpsoSettings<T>,
    observer: &mut impl Observer<T>,
) -> Result<IpsoResult<T, D>, IpsoError>
where
    T: Real,
    DefaultAllocator: Allocator<D>,
{
    let mut random = RandomStream::new(settings.seed);
    optimize_drawing(memory, cost, &mut random, space, settings, observer)
}

/// Where a swarm's `r1, r2` come from: pairs of uniform numbers in `[0, 1)` taken in a fixed
/// order, generation by generation, particle by particle, dimension by dimension (`r1` then
/// `r2`). [`RandomStream`] draws them as they are taken; a host can draw a generation's pairs
/// ahead of time on another core ([`RandomStream::fill`] gives the same numbers) while the
/// particles are evaluated.
pub trait RandomPairs<T> {
    /// Called before each generation's update, which then takes exactly `pairs` pairs (the
    /// number of particles times `D`). The default does nothing.
    fn generation(&mut self, pairs: usize) {
        let _ = pairs;
    }

    /// The next pair `(r1, r2)`.
    fn pair(&mut self) -> (T, T);

    /// The next `r1.len()` pairs, one particle's: `(r1[j], r2[j])` is what [`RandomPairs::pair`]
    /// would give the `j`-th time (the default takes them so). A source that has the pairs
    /// already drawn lends them instead ([`RandomPairs::lend_particle`]), and a PC's update runs
    /// over the whole arrays (vectorised).
    fn particle(&mut self, r1: &mut [T], r2: &mut [T]) {
        for (a, b) in r1.iter_mut().zip(r2.iter_mut()) {
            (*a, *b) = self.pair();
        }
    }

    /// The next `count` pairs lent in place as `(r1, r2)`, when the source holds them drawn
    /// ahead (then taken, as [`RandomPairs::particle`] would take them); `None` (the default)
    /// when it does not, and nothing is taken. A PC's update then reads them without a copy.
    fn lend_particle(&mut self, count: usize) -> Option<(&[T], &[T])> {
        let _ = count;
        None
    }
}

/// The swarm's generator: `Xoshiro256Plus` seeded with [`IpsoSettings::seed`], from which
/// [`optimize`] and [`optimize_in`] draw. f64 takes the top 53 bits of one draw for `r1` and of
/// the next for `r2`; f32 takes both from one draw (its top 24 bits and the 24 after them).
#[derive(Clone, Debug)]
pub struct RandomStream {
    rng: Xoshiro256Plus,
}

impl RandomStream {
    /// The stream of the swarm run with this seed.
    pub fn new(seed: u64) -> Self {
        Self {
            rng: Xoshiro256Plus::seed_from_u64(seed),
        }
    }

    /// The next `out.len()` pairs, as [`RandomPairs::pair`] would give them one by one.
    pub fn fill<T: Real>(&mut self, out: &mut [(T, T)]) {
        for pair in out {
            *pair = RandomPairs::<T>::pair(self);
        }
    }
}

impl<T: Real> RandomPairs<T> for RandomStream {
    #[inline(always)]
    fn pair(&mut self) -> (T, T) {
        T::unit_pair(&mut || self.rng.next_u64())
    }
}

/// [`optimize_in`] with `r1, r2` taken from `random` instead of the stream of `settings.seed`
/// (which is then not used): bit for bit [`optimize_in`]'s result when `random` gives
/// [`RandomStream::new`]`(settings.seed)`'s pairs in order. Always inlined on a PC, so that a
/// caller compiled for wider vectors (AVX-512) gets the swarm's update in them.
#[cfg_attr(not(target_arch = "arm"), inline(always))]
pub fn optimize_drawing<T, D: Dim>(
    memory: SwarmMemory<'_, T, D>,
    cost: &mut impl CostFunction<T, D>,
    random: &mut impl RandomPairs<T>,
    space: &SearchSpace<T, D>,
    settings: &IpsoSettings<T>,
    observer: &mut impl Observer<T>,
) -> Result<IpsoResult<T, D>, IpsoError>
where
    T: Real,
    DefaultAllocator: Allocator<D>,
{
    let SwarmMemory {
        positions,
        velocities,
        best_positions,
        costs,
        best_costs,
    } = memory;
    let particles = positions.len() as u64;
    let dimension = space.center.shape_generic().0;
    let d = dimension.value();
    let sized = |x: &OVector<T, D>| x.len() == d;
    if particles == 0
        || d > MAX_DIMENSION
        || ![&space.half_width, &space.lower, &space.upper]
            .into_iter()
            .all(sized)
        || !positions.iter().chain(velocities.iter()).all(sized)
        || !best_positions.iter().all(sized)
    {
        return Err(IpsoError::InvalidSize);
    }
    let k = constriction(settings.c1, settings.c2)?;
    if !space.is_valid() {
        return Err(IpsoError::InvalidSearchSpace);
    }
    halton_start(space, settings, positions, velocities);

    cost.cost_batch(positions, costs);
    let mut evaluations = particles;
    for ((best_x, x), (best_c, c)) in best_positions
        .iter_mut()
        .zip(positions.iter())
        .zip(best_costs.iter_mut().zip(costs.iter()))
    {
        copy(best_x, x);
        *best_c = sanitize(*c);
    }
    // The first particle if all costs are infinite (never NaN: sanitised).
    let mut global = OVector::<T, D>::zeros_generic(dimension, U1);
    let mut global_cost = T::of(f64::INFINITY);
    if let Some((x, c)) = best_of(best_positions, best_costs) {
        copy(&mut global, x);
        global_cost = c;
    }
    let initial_cost = global_cost;

    let (c1, c2) = (settings.c1, settings.c2);
    // One particle's pairs (on a PC, see the update).
    #[cfg(not(target_arch = "arm"))]
    let (mut r1, mut r2) = (
        OVector::<T, D>::zeros_generic(dimension, U1),
        OVector::<T, D>::zeros_generic(dimension, U1),
    );
    let mut generations = 0;
    let mut stalled = 0u32;
    let mut stop = StopReason::MaxGenerations;
    if observer.generation(0, global_cost) == Control::Cancel {
        stop = StopReason::Cancelled;
    } else if global_cost <= settings.target_cost {
        stop = StopReason::TargetReached;
    } else {
        while generations < settings.max_generations {
            generations += 1;
            random.generation(positions.len() * d);
            for (index, ((x, v), pbest)) in positions
                .iter_mut()
                .zip(velocities.iter_mut())
                .zip(best_positions.iter())
                .enumerate()
            {
                // Eq. (10): constriction-factor velocity update, then x <- x + v.
                let step = |xj: &mut T, vj: &mut T, pj: T, gj: T, (r1, r2): (T, T)| {
                    *vj = k * (*vj + c1 * r1 * (pj - *xj) + c2 * r2 * (gj - *xj));
                    *xj += *vj;
                };
                // Plain slices: nalgebra's matrix iterators check for the end of a column at
                // every step (a third of the update's instructions on the controller).
                let coordinates = x
                    .as_mut_slice()
                    .iter_mut()
                    .zip(v.as_mut_slice().iter_mut())
                    .zip(pbest.as_slice().iter().zip(global.as_slice()));
                // On a PC the particle's pairs are taken at once and the loop vectorises; the
                // controller, without vectors, takes them one by one (the copy cost it 1.5% of
                // the swarm's instructions).
                #[cfg(not(target_arch = "arm"))]
                {
                    let (r1, r2) = match random.lend_particle(d) {
                        Some(lent) => lent,
                        None => {
                            random.particle(r1.as_mut_slice(), r2.as_mut_slice());
                            (r1.as_slice(), r2.as_slice())
                        }
                    };
                    for (((xj, vj), (pj, gj)), (r1, r2)) in coordinates.zip(r1.iter().zip(r2)) {
                        step(xj, vj, *pj, *gj, (*r1, *r2));
                    }
                }
                #[cfg(target_arch = "arm")]
                for ((xj, vj), (pj, gj)) in coordinates {
                    step(xj, vj, *pj, *gj, random.pair());
                }
                clamp(x, v, space);
                cost.position_ready(index, x);
            }
            cost.cost_batch(positions, costs);
            evaluations += particles;
            personal_bests(costs, positions, best_costs, best_positions);
            let improved = best_of(best_positions, best_costs).filter(|(_, c)| *c < global_cost);
            if let Some((candidate, candidate_cost)) = improved {
                copy(&mut global, candidate);
                global_cost = candidate_cost;
                stalled = 0;
            } else {
                stalled += 1;
            }
            if observer.generation(generations, global_cost) == Control::Cancel {
                stop = StopReason::Cancelled;
                break;
            }
            if global_cost <= settings.target_cost {
                stop = StopReason::TargetReached;
                break;
            }
            if settings.stall_generations > 0 && stalled >= settings.stall_generations {
                stop = StopReason::Stalled;
                break;
            }
        }
    }
    Ok(IpsoResult {
        best: global,
        best_cost: global_cost,
        initial_cost,
        generations,
        evaluations,
        stop,
    })
}

/// The swarm's start (section 2.2): particle `i` of `P` at Halton point `start + i` mapped onto
/// the initial box, its velocity from point `start + P + i` scaled by the half widths; both
/// clamped.
fn halton_start<T: Real, D: Dim>(
    space: &SearchSpace<T, D>,
    settings: &IpsoSettings<T>,
    positions: &mut [OVector<T, D>],
    velocities: &mut [OVector<T, D>],
) where
    DefaultAllocator: Allocator<D>,
{
    let particles = positions.len() as u64;
    let mut point = [0.0f64; MAX_DIMENSION];
    let unit = point.get_mut(..space.center.len()).unwrap_or_default();
    let two = T::of(2.0);
    let start = settings.halton_start;
    for (i, (x, v)) in positions.iter_mut().zip(velocities.iter_mut()).enumerate() {
        let i = i as u64;
        halton::halton_point(start.wrapping_add(i), settings.scrambling, unit);
        for (((xj, h), c), w) in x
            .iter_mut()
            .zip(unit.iter())
            .zip(space.center.iter())
            .zip(space.half_width.iter())
        {
            *xj = *c + (two * T::of(*h) - T::one()) * *w;
        }
        halton::halton_point(start.wrapping_add(particles + i), settings.scrambling, unit);
        for ((vj, h), w) in v.iter_mut().zip(unit.iter()).zip(space.half_width.iter()) {
            *vj = (two * T::of(*h) - T::one()) * *w;
        }
        clamp(x, v, space);
    }
}

/// Each particle's best: replaced where its new cost (non-finite counts as +infinity) is lower.
fn personal_bests<T: Real, D: Dim>(
    costs: &[T],
    positions: &[OVector<T, D>],
    best_costs: &mut [T],
    best_positions: &mut [OVector<T, D>],
) where
    DefaultAllocator: Allocator<D>,
{
    for ((c, best_c), (x, best_x)) in costs
        .iter()
        .zip(best_costs.iter_mut())
        .zip(positions.iter().zip(best_positions.iter_mut()))
    {
        let c = sanitize(*c);
        if c < *best_c {
            *best_c = c;
            copy(best_x, x);
        }
    }
}

/// Absorbing walls: a coordinate outside its bounds goes onto the bound and stops. On a PC with
/// selects, no branches: which coordinates hit a wall is random, and mispredicted branches were
/// a quarter of the update there (the loop vectorises instead).
#[cfg_attr(target_arch = "arm", inline(never))] // one copy for both call sites (controller flash)
fn clamp<T: Real, D: Dim>(x: &mut OVector<T, D>, v: &mut OVector<T, D>, space: &SearchSpace<T, D>)
where
    DefaultAllocator: Allocator<D>,
{
    for (((xj, vj), lo), hi) in x
        .as_mut_slice()
        .iter_mut()
        .zip(v.as_mut_slice().iter_mut())
        .zip(space.lower.as_slice())
        .zip(space.upper.as_slice())
    {
        // The controller (no vectors) keeps the branches: fewer instructions there.
        #[cfg(target_arch = "arm")]
        if *xj < *lo {
            *xj = *lo;
            *vj = T::zero();
        } else if *xj > *hi {
            *xj = *hi;
            *vj = T::zero();
        }
        #[cfg(not(target_arch = "arm"))]
        {
            // Selects between values already loaded (a select between the three addresses
            // became a gather for a dimension known only at run time).
            let (x, lo, hi) = (*xj, *lo, *hi);
            let (below, above) = (x < lo, x > hi);
            *vj = if below || above { T::zero() } else { *vj };
            let x = if below { lo } else { x };
            *xj = if above { hi } else { x };
        }
    }
}

/// `to = from` for two vectors of the swarm's dimension: one block copy (nalgebra's `copy_from`
/// goes entry by entry through its strides). The dimensions are checked at the start of a run.
#[inline(always)]
fn copy<T: Real, D: Dim>(to: &mut OVector<T, D>, from: &OVector<T, D>)
where
    DefaultAllocator: Allocator<D>,
{
    if let Some(to) = to.as_mut_slice().get_mut(..from.len()) {
        to.copy_from_slice(from.as_slice());
    }
}

/// The position with the lowest cost (the first one on ties; all costs are sanitised, never
/// NaN), borrowed: the caller copies it only when it improves (no allocation for `Dyn`).
#[inline(never)] // one copy for both call sites (controller flash)
fn best_of<'a, T: Real, D: Dim>(
    positions: &'a [OVector<T, D>],
    costs: &[T],
) -> Option<(&'a OVector<T, D>, T)>
where
    DefaultAllocator: Allocator<D>,
{
    let mut pairs = positions.iter().zip(costs);
    let (first, first_cost) = pairs.next()?;
    Some(pairs.fold((first, *first_cost), |best, (x, c)| {
        if *c < best.1 { (x, *c) } else { best }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{SVector, U24, U65};

    /// A convex quadratic in 24 dimensions with minimum 0 at `x*` (well inside the box).
    fn quadratic(x: &SVector<f64, 24>) -> f64 {
        x.iter()
            .enumerate()
            .map(|(i, v)| {
                let target = 0.003 * (i as f64 - 11.5);
                (1.0 + i as f64) * (v - target).powi(2)
            })
            .sum()
    }

    fn space() -> SearchSpace<f64, U24> {
        SearchSpace::around(SVector::zeros(), SVector::repeat(0.05), 2.0).unwrap()
    }

    #[test]
    fn constriction_factor_of_the_paper() {
        // phi = 4.1: K = 2 / |2 - 4.1 - sqrt(4.1^2 - 16.4)| = 0.729843788...
        let k: f64 = constriction(2.05, 2.05).unwrap();
        assert!((k - 0.729_843_788_128_357_8).abs() < 1e-15, "{k}");
        assert_eq!(constriction(2.0, 2.0), Err(IpsoError::InvalidCoefficients));
        assert_eq!(
            constriction(f64::NAN, 3.0),
            Err(IpsoError::InvalidCoefficients)
        );
    }

    #[test]
    fn reaches_1e_10_on_a_convex_quadratic_in_24_dimensions() {
        let mut settings = IpsoSettings::paper();
        settings.seed = 7;
        let result =
            optimize::<f64, 20, U24>(&mut quadratic, &space(), &settings, &mut Silent).unwrap();
        assert!(result.best_cost < 1e-10, "best {}", result.best_cost);
        assert!(result.initial_cost > 1e-3);
        assert_eq!(result.generations, 2000);
        assert_eq!(result.evaluations, 20 * 2001);
        assert_eq!(result.stop, StopReason::MaxGenerations);
    }

    #[test]
    fn same_seed_gives_bit_identical_results_and_another_seed_differs() {
        let mut settings = IpsoSettings::<f64>::paper();
        settings.max_generations = 300;
        settings.seed = 42;
        let a = optimize::<f64, 20, U24>(&mut quadratic, &space(), &settings, &mut Silent).unwrap();
        let b = optimize::<f64, 20, U24>(&mut quadratic, &space(), &settings, &mut Silent).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.best_cost.to_bits(), b.best_cost.to_bits());
        settings.seed = 43;
        let c = optimize::<f64, 20, U24>(&mut quadratic, &space(), &settings, &mut Silent).unwrap();
        assert_ne!(a.best, c.best);
    }

    #[test]
    fn lent_memory_gives_the_stack_swarm_bit_for_bit() {
        let mut settings = IpsoSettings::<f64>::paper();
        settings.max_generations = 300;
        settings.seed = 42;
        let on_stack =
            optimize::<f64, 20, U24>(&mut quadratic, &space(), &settings, &mut Silent).unwrap();
        // Memory larger than needed, lent in part: the swarm size is the slices' length.
        let mut positions = [SVector::<f64, 24>::repeat(7.0); 30];
        let mut velocities = [SVector::<f64, 24>::repeat(-7.0); 30];
        let mut best_positions = [SVector::<f64, 24>::zeros(); 30];
        let (mut costs, mut best_costs) = ([f64::NAN; 30], [0.0; 30]);
        let memory = SwarmMemory::new(
            &mut positions[..20],
            &mut velocities[..20],
            &mut best_positions[..20],
            &mut costs[..20],
            &mut best_costs[..20],
        )
        .unwrap();
        assert_eq!(memory.particles(), 20);
        let lent = optimize_in(memory, &mut quadratic, &space(), &settings, &mut Silent).unwrap();
        assert_eq!(lent, on_stack);
        assert_eq!(lent.best_cost.to_bits(), on_stack.best_cost.to_bits());
        assert_eq!(lent.evaluations, 20 * 301);

        let uneven = SwarmMemory::new(
            &mut positions[..20],
            &mut velocities[..20],
            &mut best_positions[..20],
            &mut costs[..19],
            &mut best_costs[..20],
        );
        assert_eq!(uneven.err(), Some(IpsoError::InvalidSize));
        let empty = SwarmMemory::<f64, U24>::new(&mut [], &mut [], &mut [], &mut [], &mut []);
        assert_eq!(empty.err(), Some(IpsoError::InvalidSize));
    }

    /// A generation's pairs drawn ahead into a buffer (as a host drawing on another core does).
    struct DrawnAhead {
        stream: RandomStream,
        buffer: [(f64, f64); 20 * 24],
        taken: usize,
        generations: u32,
    }

    impl RandomPairs<f64> for DrawnAhead {
        fn generation(&mut self, pairs: usize) {
            assert_eq!(pairs, self.buffer.len());
            self.stream.fill(&mut self.buffer);
            self.taken = 0;
            self.generations += 1;
        }

        fn pair(&mut self) -> (f64, f64) {
            self.taken += 1;
            self.buffer[self.taken - 1]
        }
    }

    #[test]
    fn pairs_drawn_ahead_give_the_stream_swarm_bit_for_bit() {
        // The stream is xoshiro256+ and the top 53 bits of each draw, r1 before r2.
        let mut rng = Xoshiro256Plus::seed_from_u64(42);
        let mut first = [(0.0, 0.0); 2];
        RandomStream::new(42).fill(&mut first);
        for (r1, r2) in first {
            assert_eq!(r1, (rng.next_u64() >> 11) as f64 / 9_007_199_254_740_992.0);
            assert_eq!(r2, (rng.next_u64() >> 11) as f64 / 9_007_199_254_740_992.0);
        }

        let mut settings = IpsoSettings::<f64>::paper();
        settings.max_generations = 300;
        settings.seed = 42;
        let drawn = optimize::<f64, 20, U24>(&mut quadratic, &space(), &settings, &mut Silent);
        let mut ahead = DrawnAhead {
            stream: RandomStream::new(42),
            buffer: [(0.0, 0.0); 20 * 24],
            taken: 0,
            generations: 0,
        };
        let (mut x, mut v, mut p) = (
            [SVector::zeros(); 20],
            [SVector::zeros(); 20],
            [SVector::zeros(); 20],
        );
        let (mut c, mut pc) = ([0.0; 20], [0.0; 20]);
        let memory = SwarmMemory::new(&mut x, &mut v, &mut p, &mut c, &mut pc).unwrap();
        // The seed in the settings is not used: the pairs come from `ahead`.
        settings.seed = 7;
        let result = optimize_drawing(
            memory,
            &mut quadratic,
            &mut ahead,
            &space(),
            &settings,
            &mut Silent,
        );
        assert_eq!(ahead.generations, 300);
        assert_eq!(result, drawn);
        let (result, drawn) = (result.unwrap(), drawn.unwrap());
        assert_eq!(result.best_cost.to_bits(), drawn.best_cost.to_bits());
        assert!(result.best_cost < 1e-3 * result.initial_cost);
    }

    /// A cost function is told each particle's new position during the update, in order, and
    /// they are the positions `cost_batch` then asks for (none before the initial swarm's).
    #[test]
    fn positions_are_announced_in_order_before_their_costs() {
        struct Announced {
            seen: [SVector<f64, 24>; 20],
            next: usize,
            batches: u32,
        }
        impl CostFunction<f64, U24> for Announced {
            fn cost(&mut self, x: &SVector<f64, 24>) -> f64 {
                quadratic(x)
            }
            fn position_ready(&mut self, index: usize, x: &SVector<f64, 24>) {
                assert_eq!(index, self.next);
                self.seen[index] = *x;
                self.next += 1;
            }
            fn cost_batch(&mut self, xs: &[SVector<f64, 24>], out: &mut [f64]) {
                let announced = if self.batches == 0 { 0 } else { xs.len() };
                assert_eq!(self.next, announced);
                assert_eq!(&self.seen[..announced], &xs[..announced]);
                self.next = 0;
                self.batches += 1;
                for (x, c) in xs.iter().zip(out) {
                    *c = quadratic(x);
                }
            }
        }
        let mut settings = IpsoSettings::<f64>::paper();
        settings.max_generations = 50;
        let mut announced = Announced {
            seen: [SVector::zeros(); 20],
            next: 0,
            batches: 0,
        };
        let told = optimize::<f64, 20, U24>(&mut announced, &space(), &settings, &mut Silent);
        let plain = optimize::<f64, 20, U24>(&mut quadratic, &space(), &settings, &mut Silent);
        assert_eq!(announced.batches, 51);
        assert_eq!(told, plain);
    }

    #[test]
    fn stops_on_target_stall_and_cancel() {
        let mut settings = IpsoSettings::<f64>::paper();
        settings.target_cost = 1e-4;
        let r = optimize::<f64, 20, U24>(&mut quadratic, &space(), &settings, &mut Silent).unwrap();
        assert_eq!(r.stop, StopReason::TargetReached);
        assert!(r.best_cost <= 1e-4 && r.generations < 2000);

        // A constant cost never improves.
        settings = IpsoSettings::paper();
        settings.stall_generations = 25;
        let r = optimize::<f64, 5, U24>(
            &mut |_: &SVector<f64, 24>| 1.0,
            &space(),
            &settings,
            &mut Silent,
        )
        .unwrap();
        assert_eq!((r.stop, r.generations), (StopReason::Stalled, 25));

        let mut seen = 0;
        let mut cancel_at_3 = |g: u32, _: f64| {
            seen += 1;
            if g == 3 {
                Control::Cancel
            } else {
                Control::Continue
            }
        };
        let r = optimize::<f64, 5, U24>(
            &mut quadratic,
            &space(),
            &IpsoSettings::paper(),
            &mut cancel_at_3,
        )
        .unwrap();
        assert_eq!((r.stop, r.generations, seen), (StopReason::Cancelled, 3, 4));
    }

    #[test]
    fn never_leaves_the_bounds_and_survives_nan_costs() {
        let s = space();
        let mut inside = true;
        let mut nan_sometimes = |x: &SVector<f64, 24>| {
            inside &= x
                .iter()
                .zip(s.lower.iter().zip(s.upper.iter()))
                .all(|(v, (lo, hi))| lo <= v && v <= hi);
            if x[0] > 0.02 { f64::NAN } else { quadratic(x) }
        };
        let mut settings = IpsoSettings::paper();
        settings.max_generations = 200;
        let r = optimize::<f64, 20, U24>(&mut nan_sometimes, &s, &settings, &mut Silent).unwrap();
        assert!(inside);
        assert!(r.best_cost.is_finite() && r.best[0] <= 0.02);
    }

    #[test]
    fn rejects_bad_spaces_and_sizes() {
        let mut bad = space();
        bad.lower[3] = 1.0;
        let settings = IpsoSettings::paper();
        assert_eq!(
            optimize::<f64, 20, U24>(&mut quadratic, &bad, &settings, &mut Silent),
            Err(IpsoError::InvalidSearchSpace)
        );
        let s0 =
            SearchSpace::around(SVector::<f64, 65>::zeros(), SVector::repeat(1.0), 1.0).unwrap();
        assert_eq!(
            optimize::<f64, 4, U65>(&mut |_: &SVector<f64, 65>| 0.0, &s0, &settings, &mut Silent),
            Err(IpsoError::InvalidSize)
        );
    }

    #[test]
    fn works_in_f32() {
        let mut settings = IpsoSettings::<f32>::paper();
        settings.seed = 7;
        let space =
            SearchSpace::around(SVector::<f32, 24>::zeros(), SVector::repeat(0.05), 2.0).unwrap();
        let mut f = |x: &SVector<f32, 24>| quadratic(&x.map(f64::from)) as f32;
        let r = optimize::<f32, 20, U24>(&mut f, &space, &settings, &mut Silent).unwrap();
        assert!(r.best_cost < 1e-9, "{}", r.best_cost);
    }
}
