//! The calibration core on the reference controller board (QEMU mps2-an386, Cortex-M4F, f32).
//!
//! Runs the controller's calibration job (`calib-onboard`: the paper's 32-pose scenario with
//! tracker noise, the paper's swarm, least squares, Table 3, compensation of four targets), logs
//! progress and the statistics with defmt over semihosting, measures instructions between marks
//! with SysTick (exact under `qemu-system-arm -icount shift=0`, see `run.sh`), measures the
//! peak stack by painting, and exits through semihosting with status 0 only when its outcome
//! equals, bit for bit, the one the host test computed (`onboard/expected.bin`).
#![no_std]
#![no_main]

use calib_core::identify::objective::{DEFAULT_K, Objective};
use calib_core::{Kinematics, ParameterErrors, ParameterSet, Problem};
use calib_onboard::{D, Marks, Stage};
use core::hint::black_box;
use cortex_m_rt::entry;
use cortex_m_semihosting::debug;
#[cfg(feature = "log")]
use defmt_semihosting as _;
#[cfg(feature = "panic-never")]
use panic_never as _;
use timing::{instructions, ticks};

mod timing;

/// Pattern of the painted stack.
const PAINT: u32 = 0xCAFE_F00D;
/// Bytes of stack painted below the entry stack pointer.
const PAINTED: usize = 256 * 1024;

/// Paints the stack below the current stack pointer (minus a margin for this function).
fn paint_stack() -> usize {
    let sp = cortex_m::register::msp::read() as usize;
    let bottom = sp - PAINTED;
    let mut address = bottom;
    while address < sp - 256 {
        // SAFETY: the painted words are free stack below the live frames (mps2 has 4 MiB RAM).
        unsafe { core::ptr::write_volatile(address as *mut u32, PAINT) };
        address += 4;
    }
    bottom
}

/// Lowest painted word that was overwritten: the deepest the stack reached.
fn deepest(bottom: usize, top: usize) -> usize {
    let mut address = bottom;
    // SAFETY: reads words of the painted region.
    while address < top && unsafe { core::ptr::read_volatile(address as *const u32) } == PAINT {
        address += 4;
    }
    address
}

/// Instruction counts between the job's marks.
struct Counter {
    started: u64,
    swarm: u64,
    least_squares: u64,
    compensation: u64,
    slowest_compensation: u64,
    compensations: u32,
    maps_compensation: u64,
    slowest_maps_compensation: u64,
    maps_compensations: u32,
    first_generation: u64,
    last_generation: u64,
    generations: u32,
}

impl Marks for Counter {
    fn begin(&mut self, _: Stage) {
        self.started = ticks();
    }
    fn end(&mut self, stage: Stage) {
        let spent = ticks() - self.started;
        match stage {
            Stage::Swarm => {
                self.swarm = spent;
                defmt::info!("swarm done");
            }
            Stage::LeastSquares => self.least_squares = spent,
            Stage::Compensation => {
                self.compensation += spent;
                self.slowest_compensation = self.slowest_compensation.max(spent);
                self.compensations += 1;
            }
            Stage::MapsCompensation => {
                self.maps_compensation += spent;
                self.slowest_maps_compensation = self.slowest_maps_compensation.max(spent);
                self.maps_compensations += 1;
            }
        }
    }
    fn generation(&mut self, generation: u32, best_cost: f32) {
        let now = ticks();
        if generation == 1 {
            self.first_generation = now;
        }
        self.last_generation = now;
        self.generations = generation;
        if generation.is_multiple_of(500) {
            defmt::info!(
                "IPSO generation {=u32}: best objective {=f32}",
                generation,
                best_cost
            );
        }
    }
}

fn log_table(name: &str, t: &calib_onboard::Table) {
    let deg = 180.0 / core::f32::consts::PI;
    defmt::info!(
        "{=str}: position mean {=f32} std {=f32} max {=f32} mm; orientation x mean {=f32} max {=f32}, y mean {=f32} max {=f32}, z mean {=f32} max {=f32} deg",
        name,
        t[0],
        t[1],
        t[2],
        t[3] * deg,
        t[5] * deg,
        t[6] * deg,
        t[8] * deg,
        t[9] * deg,
        t[11] * deg
    );
}

/// Instructions of the single operations, averaged over repetitions. Not inlined, so that its
/// frame does not add to the job's.
#[inline(never)]
fn micro_benchmarks() {
    let robot = calib_onboard::robot();
    let Ok(measurements) = calib_onboard::measurements() else {
        return;
    };
    let Ok(set) = ParameterSet::<nalgebra::U6, nalgebra::Const<D>>::default_for(&robot) else {
        return;
    };
    let Ok(kinematics) = Kinematics::new(&robot, &calib_core::model::paper::table2::<f32>()) else {
        return;
    };
    // Calibrate the counter: a loop of 3 instructions per iteration.
    let t = ticks();
    for _ in 0..100_000u32 {
        cortex_m::asm::nop();
    }
    defmt::info!(
        "counter check: 100000 x (nop, subs, bne) counted as {=u64} instructions",
        instructions(ticks() - t)
    );
    let q = [0.3f32, -0.4, 0.5, 0.2, 0.9, -0.3];
    const FK: u64 = 1000;
    let t = ticks();
    for _ in 0..FK {
        let _ = black_box(kinematics.forward(black_box(&q)));
    }
    defmt::info!(
        "forward kinematics (6 joints, f32, with sin/cos of q): {=u64} instructions",
        instructions(ticks() - t) / FK
    );
    let Ok(problem) = Problem::new(
        &robot,
        &ParameterErrors::zero(),
        set,
        &measurements,
        DEFAULT_K as f32,
    ) else {
        return;
    };
    let objective = Objective::new(&problem);
    let x = set.pack(&calib_core::model::paper::table2::<f32>());
    let prepared = calib_core::PreparedRobot::new(&robot);
    let errors = calib_core::model::paper::table2::<f32>();
    let t = ticks();
    for _ in 0..100 {
        let _ = black_box(prepared.actual(black_box(&errors)));
    }
    defmt::info!(
        "candidate model (PreparedRobot::actual): {=u64} instructions",
        instructions(ticks() - t) / 100
    );
    let t = ticks();
    for _ in 0..100 {
        let mut e = ParameterErrors::zero();
        let _ = set.unpack_into(black_box(&x), &mut e);
        let _ = black_box(e);
    }
    defmt::info!(
        "unpack 24 errors: {=u64} instructions",
        instructions(ticks() - t) / 100
    );
    let m0 = measurements.first().map(|m| m.angles);
    if let Some(angles) = m0 {
        let t = ticks();
        for _ in 0..100 {
            let _ = black_box(kinematics.forward_angles(black_box(&angles)));
        }
        defmt::info!(
            "forward kinematics with precomputed sin/cos: {=u64} instructions",
            instructions(ticks() - t) / 100
        );
    }
    const OBJECTIVE: u64 = 100;
    let t = ticks();
    for _ in 0..OBJECTIVE {
        let _ = black_box(objective.value(black_box(&x)));
    }
    defmt::info!(
        "objective eq. (7), 32 poses: {=u64} instructions",
        instructions(ticks() - t) / OBJECTIVE
    );
}

/// The parameter region (`.calib_slots`, outside the program's text and rodata): the UR10's
/// nominal model (version 1 block), its model with joint maps (version 2) and its model with
/// joint maps and gravity compliance (version 2 with the compliance section), as a controller
/// keeps them in its parameter flash. The same bytes as `calib_onboard::maps`'s.
#[unsafe(link_section = ".calib_slots")]
static NOMINAL_SLOT: [u8; calib_onboard::maps::NOMINAL_BLOCK.len()] =
    *include_bytes!("../../onboard/data/ur10-nominal.calb");
#[unsafe(link_section = ".calib_slots")]
static MAPS_SLOT: [u8; calib_onboard::maps::MAPS_BLOCK.len()] =
    *include_bytes!("../../onboard/data/ur10-series-b-maps.calb");
#[unsafe(link_section = ".calib_slots")]
static COMPLIANCE_SLOT: [u8; calib_onboard::maps::COMPLIANCE_BLOCK.len()] =
    *include_bytes!("../../onboard/data/ur10-series-b-compliance.calb");

/// The compensation beyond geometry (`calib_onboard::maps`) with the model of `slot` (`what`:
/// "maps" or "compliance"): logs it and its instruction counts; `true` when its outcome equals
/// `expected`, the host's, bit for bit.
#[inline(never)]
fn compensate_with_model(counter: &mut Counter, slot: &[u8], expected: &[u8], what: &str) -> bool {
    (
        counter.maps_compensation,
        counter.slowest_maps_compensation,
        counter.maps_compensations,
    ) = (0, 0, 0);
    let slots = (black_box(&NOMINAL_SLOT[..]), black_box(slot));
    let outcome = match calib_onboard::maps::compensate_with_maps(slots.0, slots.1, counter) {
        Ok(o) => o,
        Err(e) => {
            defmt::error!("the {=str} job failed: {}", what, defmt::Debug2Format(&e));
            return false;
        }
    };
    defmt::info!(
        "model block with {=str}: {=usize} bytes, {=u32} harmonics per joint",
        what,
        slot.len(),
        outcome.harmonics
    );
    for (q, r) in outcome.compensated.iter().zip(&outcome.residual_mm) {
        defmt::info!(
            "compensated with {=str}: joints {=[?]} rad, residual {=f32} mm",
            what,
            q[..],
            r
        );
    }
    defmt::info!(
        "instructions: compensation with {=str} {=u64} (mean of {=u32}; slowest with {=str} {=u64})",
        what,
        instructions(counter.maps_compensation) / u64::from(counter.maps_compensations.max(1)),
        counter.maps_compensations,
        what,
        instructions(counter.slowest_maps_compensation)
    );
    let ok = outcome.matches(expected);
    if !ok {
        defmt::error!("the {=str} outcome differs from the host's", what);
    }
    ok
}

/// Instructions of loading the maps block and of the maps alone (all joints, the harmonics of the
/// block): the kinematic angles of six readings, and the readings of six angles (fixed point).
#[inline(never)]
fn maps_micro_benchmarks() {
    use calib_core::controller::storage::{ControllerModel, decode_model_into};
    use calib_onboard::maps::{CAPACITY, TARGET_JOINTS};
    let mut model =
        ControllerModel::<f32, nalgebra::U6, CAPACITY>::geometric(calib_onboard::robot());
    let t = ticks();
    let decoded = decode_model_into(black_box(&MAPS_SLOT[..]), &mut model);
    let spent = ticks() - t;
    if decoded.is_err() {
        return;
    }
    defmt::info!(
        "decode the maps block (CRC, checks, bounds): {=u64} instructions",
        instructions(spent)
    );
    let q = TARGET_JOINTS[0];
    let t = ticks();
    for _ in 0..100 {
        let _ = black_box(model.maps.apply(black_box(&q)));
    }
    defmt::info!(
        "joint maps, 6 joints: angles of readings {=u64} instructions",
        instructions(ticks() - t) / 100
    );
    let t = ticks();
    let mut iterations = 0;
    for _ in 0..100 {
        let (_, n) = black_box(model.maps.readings(black_box(&q), 1e-6));
        iterations = n;
    }
    defmt::info!(
        "joint maps, 6 joints: readings of angles {=u64} instructions ({=u32} fixed-point iterations)",
        instructions(ticks() - t) / 100,
        iterations
    );
}

#[entry]
fn main() -> ! {
    let bottom = paint_stack();
    let top = cortex_m::register::msp::read() as usize;
    timing::start();
    defmt::info!(
        "calib firmware: f32 calibration of the paper's 32-pose scenario with tracker noise"
    );
    micro_benchmarks();
    let mut counter = Counter {
        started: 0,
        swarm: 0,
        least_squares: 0,
        compensation: 0,
        slowest_compensation: 0,
        compensations: 0,
        maps_compensation: 0,
        slowest_maps_compensation: 0,
        maps_compensations: 0,
        first_generation: 0,
        last_generation: 0,
        generations: 0,
    };
    let outcome = match calib_onboard::run(&mut counter) {
        Ok(o) => o,
        Err(e) => {
            defmt::error!("the job failed: {}", defmt::Debug2Format(&e));
            debug::exit(debug::EXIT_FAILURE);
            loop {
                cortex_m::asm::wfi();
            }
        }
    };
    defmt::info!(
        "IPSO: {=u32} generations, objective {=f32}; least squares: {=u32} iterations, 0.5 |r|^2 {=f32}",
        outcome.generations,
        outcome.swarm_cost,
        outcome.lm_iterations,
        outcome.lm_cost
    );
    log_table("before calibration", &outcome.before);
    log_table("after calibration", &outcome.after);
    for (q, r) in outcome.compensated.iter().zip(&outcome.residual_mm) {
        defmt::info!(
            "compensated joints {=[?]} rad, residual {=f32} mm",
            q[..],
            r
        );
    }
    let per_generation = counter
        .last_generation
        .saturating_sub(counter.first_generation)
        / u64::from(counter.generations.saturating_sub(1).max(1));
    defmt::info!(
        "instructions: swarm generation {=u64}, whole swarm {=u64}, least squares {=u64} ({=u64} per iteration), whole calibration {=u64}, compensation {=u64} (mean of {=u32}; slowest {=u64})",
        instructions(per_generation),
        instructions(counter.swarm),
        instructions(counter.least_squares),
        instructions(counter.least_squares) / u64::from(outcome.lm_iterations.max(1)),
        instructions(counter.swarm + counter.least_squares),
        instructions(counter.compensation) / u64::from(counter.compensations.max(1)),
        counter.compensations,
        instructions(counter.slowest_compensation)
    );
    let maps_ok = compensate_with_model(
        &mut counter,
        &MAPS_SLOT,
        &calib_onboard::maps::MAPS_EXPECTED,
        "maps",
    );
    maps_micro_benchmarks();
    let compliance_ok = compensate_with_model(
        &mut counter,
        &COMPLIANCE_SLOT,
        &calib_onboard::maps::COMPLIANCE_EXPECTED,
        "compliance",
    );
    let peak = top - deepest(bottom, top);
    defmt::info!("peak stack {=usize} bytes", peak);
    if outcome.matches_expected() && maps_ok && compliance_ok {
        defmt::info!("outcome equals the host's bit for bit: PASS");
        debug::exit(debug::EXIT_SUCCESS);
    } else {
        defmt::error!("outcome differs from the host's expected.bin: FAIL");
        debug::exit(debug::EXIT_FAILURE);
    }
    loop {
        cortex_m::asm::wfi();
    }
}

#[cfg(not(feature = "panic-never"))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic");
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
