//! With the joint and parameter counts known only at run time (`Dyn`, as `calib` has them), an
//! objective evaluation and a swarm generation still take nothing from the heap: the per-joint
//! tables are inline (`JointVec`) and the swarm's vectors are lent to it once. Counted by a
//! global allocator on the test's own thread.

use calib_core::identify::ipso::{self, IpsoSettings, SearchSpace, Silent};
use calib_core::identify::objective::{DEFAULT_K, Objective, PoseLanes};
use calib_core::{ParameterErrors, ParameterSet, Problem};
use nalgebra::{DVector, Dyn};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

// SAFETY: every call is passed to the system allocator unchanged; only a counter is added.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Heap allocations made by `f` on this thread.
fn allocations<R>(f: impl FnOnce() -> R) -> (usize, R) {
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    COUNTING.with(|c| c.set(true));
    let result = f();
    COUNTING.with(|c| c.set(false));
    (ALLOCATIONS.load(Ordering::Relaxed) - before, result)
}

#[test]
fn an_objective_evaluation_and_a_swarm_generation_allocate_nothing_with_run_time_counts() {
    let dataset = host_tools::measurement::dataset::Dataset::load(
        &calib_tests::repo("host-tools/robots/er10l-c10.toml"),
        &calib_tests::repo("host-tools/data/er10l-c10-sim32.csv"),
    )
    .unwrap();
    let robot = &dataset.robot.model.robot;
    let set = ParameterSet::<Dyn, Dyn>::default_for(robot).unwrap();
    let problem = Problem::new(
        robot,
        &ParameterErrors::zeros_for(robot.joint_count()),
        set,
        &dataset.readings,
        DEFAULT_K,
    )
    .unwrap();
    let objective = Objective::new(&problem);
    let lanes: Vec<PoseLanes<f64, Dyn, 4>> = objective.lanes().collect();
    let x = problem.set().zeros::<f64>();

    // The counter counts: a vector of 24 is one allocation.
    assert_eq!(allocations(|| DVector::<f64>::zeros(24)).0, 1);
    let (count, value) = allocations(|| objective.value(&x));
    assert_eq!(count, 0, "Objective::value");
    let (count, in_lanes) = allocations(|| objective.value_of_lanes(&x, &lanes));
    assert_eq!(count, 0, "Objective::value_of_lanes");
    assert_eq!(value.to_bits(), in_lanes.to_bits());
    assert!(value > 0.0 && value.is_finite(), "{value}");
    assert_eq!(
        allocations(|| problem.kinematics(&x)).0,
        0,
        "the actual model"
    );

    // The swarm: as many allocations for 101 generations as for 1 (its result's vector), so
    // none per generation.
    let space = SearchSpace::paper(problem.set());
    let swarm = |generations: u32| {
        let mut x: [DVector<f64>; 20] = std::array::from_fn(|_| DVector::zeros(24));
        let (mut v, mut best) = (x.clone(), x.clone());
        let (mut costs, mut best_costs) = ([0.0; 20], [0.0; 20]);
        let mut settings = IpsoSettings::paper();
        settings.max_generations = generations;
        let mut cost = |x: &DVector<f64>| objective.value_of_lanes(x, &lanes);
        allocations(|| {
            let memory =
                ipso::SwarmMemory::new(&mut x, &mut v, &mut best, &mut costs, &mut best_costs)
                    .unwrap();
            ipso::optimize_in(memory, &mut cost, &space, &settings, &mut Silent).unwrap()
        })
    };
    let (one, first) = swarm(1);
    let (many, later) = swarm(101);
    assert_eq!(later.generations, 101);
    assert!(later.best_cost < first.best_cost);
    assert_eq!(
        one, many,
        "allocations: 1 generation {one}, 101 generations {many}"
    );
}
