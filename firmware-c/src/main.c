/* main.c: the C firmware. Loads the newest valid parameter block of two flash-like slots,
 * compensates four targets and checks the joints against the host's, bit for bit; then (unless
 * built with COMPENSATION_ONLY) the rest of the API. Logs over semihosting and exits with status 0
 * only when every check passed. Instruction counts and the peak stack are printed for
 * firmware-c/run.sh and tests/tests/firmware_c_qemu.rs. */
#include <stdint.h>

#include "checks.h"

/* Paints the stack below the current stack pointer, so the deepest use can be found. */
#define PAINT 0xCAFEF00Du
#define PAINTED (64u * 1024u)

static uintptr_t stack_pointer(void) {
    uintptr_t sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    return sp;
}

static uintptr_t paint(void) {
    uintptr_t top = stack_pointer() - 64u;
    for (uintptr_t a = top - PAINTED; a < top; a += 4) {
        *(volatile uint32_t *)a = PAINT;
    }
    return top;
}

static uint32_t used_below(uintptr_t top) {
    uintptr_t a = top - PAINTED;
    while (a < top && *(volatile uint32_t *)a == PAINT) {
        a += 4;
    }
    return (uint32_t)(top - a);
}

/* A loop of a known instruction count checks the counter (2 instructions per iteration). */
static uint32_t counted_loop(void) {
    uint32_t start = platform_instructions();
    uint32_t n = 150000u;
    __asm__ volatile("1: subs %0, %0, #1\n bne 1b" : "+r"(n)::"cc");
    return platform_instructions() - start;
}

/* Runs one step with the stack painted; returns its failed checks, adds its peak stack. */
static int step(int (*check)(checks_measured *), checks_measured *measured, const char *label) {
    uintptr_t top = paint();
    int failed = check(measured);
    print_value(label, used_below(top));
    return failed;
}

int main(void) {
    platform_print("calib C firmware\n");
    print_value("counter check (300000 instructions):", counted_loop());

    checks_measured m = {0};
    int failed = step(check_decode, &m, "peak stack of decoding the robot and loading a model (bytes):");
    failed += step(check_geometric, &m, "peak stack of a geometric compensation (bytes):");
    failed += step(check_load, &m, "peak stack of loading two slots (bytes):");
    failed += step(check_compliance, &m, "peak stack of a compensation with maps and compliance (bytes):");
    print_value("load of one slot (geometric; other slot erased) instructions:",
                m.decode_instructions);
    print_value("load of two slots (maps, maps and compliance) instructions:", m.load_instructions);
    print_value("geometric compensation mean instructions:", m.geometric.mean);
    print_value("geometric compensation slowest instructions:", m.geometric.slowest);
    print_value("compensation with maps and compliance mean instructions:", m.compliance.mean);
    print_value("compensation with maps and compliance slowest instructions:", m.compliance.slowest);
#ifndef COMPENSATION_ONLY
    print_value("model forward kinematics (maps and compliance) instructions:",
                m.forward_instructions);
    uintptr_t top = paint();
    failed += check_api();
    print_value("peak stack of the whole API (bytes):", used_below(top));
#endif
    print_value("failed checks:", (uint32_t)failed);
    platform_print(failed == 0 ? "PASS\n" : "FAILED\n");
    return failed;
}
