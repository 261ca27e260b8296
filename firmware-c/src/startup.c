/* startup.c: reset, vector table, semihosting and the instruction counter of the C firmware on
 * QEMU's mps2-an386 (Cortex-M4F). No C library: the Rust library brings memcpy and memset. */
#include <stdint.h>

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
int main(void);

/* Semihosting call (the debugger's BKPT 0xAB; QEMU implements it). */
static int semihosting(int operation, const void *argument) {
    register int r0 __asm__("r0") = operation;
    register const void *r1 __asm__("r1") = argument;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void platform_print(const char *text) {
    semihosting(0x04, text); /* SYS_WRITE0 */
}

/* SYS_EXIT: QEMU exits with status 0 for ADP_Stopped_ApplicationExit, 1 otherwise. */
__attribute__((noreturn)) void platform_exit(int ok) {
    semihosting(0x18, (const void *)(uintptr_t)(ok ? 0x20026u : 0x20024u));
    for (;;) {
    }
}

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define CPACR (*(volatile uint32_t *)0xE000ED88u)

/* Instructions since start: SysTick runs at 25 MHz on mps2-an386 and QEMU's -icount shift=0
 * executes one instruction per virtual nanosecond, so one tick is 40 instructions. The 24-bit
 * down-counter is extended in software (no interrupt): each read adds the ticks since the
 * previous one, which is exact while reads are less than 2^24 ticks (671 million instructions)
 * apart. */
static uint32_t last_tick = 0x00FFFFFFu;
static uint32_t ticks;

uint32_t platform_instructions(void) {
    uint32_t now = SYST_CVR;
    ticks += (last_tick - now) & 0x00FFFFFFu;
    last_tick = now;
    return ticks * 40u;
}

void HardFault_Handler(void) {
    platform_print("hard fault\n");
    platform_exit(0);
}

__attribute__((noreturn)) void Reset_Handler(void) {
    uint32_t *from = &_sidata;
    for (uint32_t *to = &_sdata; to < &_edata;) {
        *to++ = *from++;
    }
    for (uint32_t *to = &_sbss; to < &_ebss;) {
        *to++ = 0;
    }
    CPACR |= 0xFu << 20; /* CP10 and CP11: the FPU the library's f32 code uses */
    __asm__ volatile("dsb\n isb" ::: "memory");
    SYST_RVR = 0x00FFFFFFu;
    SYST_CVR = 0; /* reloads 0x00FFFFFF */
    SYST_CSR = 0x5u; /* processor clock, enable, no interrupt */
    platform_exit(main() == 0);
}

static void default_handler(void) {
    platform_print("unexpected exception\n");
    platform_exit(0);
}

/* The vector table: the initial stack pointer, then the handlers. */
struct vector_table {
    uint32_t *initial_stack;
    void (*handlers[15])(void);
};

__attribute__((section(".vector_table"), used)) static const struct vector_table vectors = {
    &_estack,
    {
        Reset_Handler,
        default_handler,   /* NMI */
        HardFault_Handler, /* HardFault */
        default_handler,   /* MemManage */
        default_handler,   /* BusFault */
        default_handler,   /* UsageFault */
        0,
        0,
        0,
        0,
        default_handler, /* SVCall */
        default_handler, /* DebugMonitor */
        0,
        default_handler, /* PendSV */
        default_handler, /* SysTick (not enabled) */
    },
};
