//! The instruction counter: SysTick at the core clock, counting wraps in its interrupt. Under
//! `qemu-system-arm -icount shift=0` one instruction takes one nanosecond of virtual time, so one
//! tick of the 25 MHz SysTick is 40 instructions. Shared by the firmware's binaries.

use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::exception;

/// SysTick wraps (24-bit counter).
static WRAPS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// SysTick ticks since start (25 MHz on mps2-an386). Under `-icount shift=0` QEMU runs one
/// instruction per nanosecond of virtual time, so one tick is 40 instructions.
pub fn ticks() -> u64 {
    loop {
        let wraps = WRAPS.load(Ordering::SeqCst);
        let current = SYST::get_current();
        if WRAPS.load(Ordering::SeqCst) == wraps {
            return u64::from(wraps) * (1 << 24) + u64::from(0x00FF_FFFF - current);
        }
    }
}

/// Instructions per SysTick tick under `-icount shift=0`.
const INSTRUCTIONS_PER_TICK: u64 = 40;

/// Instructions in `ticks` SysTick ticks.
pub fn instructions(ticks: u64) -> u64 {
    ticks * INSTRUCTIONS_PER_TICK
}

/// Starts SysTick at the core clock with the longest reload and its wrap interrupt.
pub fn start() {
    if let Some(mut peripherals) = cortex_m::Peripherals::take() {
        peripherals.SYST.set_clock_source(SystClkSource::Core);
        peripherals.SYST.set_reload(0x00FF_FFFF);
        peripherals.SYST.clear_current();
        peripherals.SYST.enable_interrupt();
        peripherals.SYST.enable_counter();
    }
}
