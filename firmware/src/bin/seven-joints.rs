//! Compensation for a 7-joint robot on the reference controller board: the KUKA LBR
//! iiwa 14 R820 in f32 (`calib_onboard::seven_joints`), four targets compensated with an actual
//! robot that differs by tenths of a millimetre and milliradian per joint. A binary of its own,
//! so its flash is measured alone (`run.sh --size --bin seven-joints`) and the 6-joint
//! firmware's budget is untouched. Logs the joints' bit patterns (the host compares them with its
//! own run of the same code), the residuals and the instruction counts; exits with status 0 only
//! when every target was compensated to the f32 tolerance (1e-2 mm).
#![no_std]
#![no_main]

use calib_onboard::seven_joints::{self, TARGETS};
use calib_onboard::{Marks, Stage};
use cortex_m_rt::entry;
use cortex_m_semihosting::debug;
#[cfg(feature = "log")]
use defmt_semihosting as _;
#[cfg(feature = "panic-never")]
use panic_never as _;
use timing::{instructions, ticks};

#[path = "../timing.rs"]
mod timing;

/// Instruction counts of the compensations.
#[derive(Default)]
struct Counter {
    started: u64,
    total: u64,
    slowest: u64,
    count: u32,
}

impl Marks for Counter {
    fn begin(&mut self, _: Stage) {
        self.started = ticks();
    }
    fn end(&mut self, _: Stage) {
        let spent = ticks() - self.started;
        self.total += spent;
        self.slowest = self.slowest.max(spent);
        self.count += 1;
    }
    fn generation(&mut self, _: u32, _: f32) {}
}

#[entry]
fn main() -> ! {
    timing::start();
    defmt::info!("calib firmware, 7 joints: compensation of the KUKA LBR iiwa 14 R820 in f32");
    let mut counter = Counter::default();
    let ok = match seven_joints::run(&mut counter) {
        Ok(outcome) => {
            for ((q, r), before) in outcome
                .compensated
                .iter()
                .zip(&outcome.residual_mm)
                .zip(&outcome.uncompensated_mm)
            {
                defmt::info!(
                    "7-joint target: uncompensated {=f32} mm, compensated joints {=[?]} rad, residual {=f32} mm",
                    before,
                    q[..],
                    r
                );
            }
            defmt::info!("7-joint joint bits {=[?]}", outcome.bits()[..]);
            defmt::info!(
                "instructions: 7-joint compensation {=u64} (mean of {=u32}; slowest 7-joint {=u64})",
                instructions(counter.total) / u64::from(counter.count.max(1)),
                counter.count,
                instructions(counter.slowest)
            );
            counter.count as usize == TARGETS && outcome.residual_mm.iter().all(|r| *r <= 1e-2)
        }
        Err(e) => {
            defmt::error!("the 7-joint job failed: {}", defmt::Debug2Format(&e));
            false
        }
    };
    if ok {
        defmt::info!("7-joint compensation within 1e-2 mm: PASS");
        debug::exit(debug::EXIT_SUCCESS);
    } else {
        defmt::error!("7-joint compensation: FAIL");
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
