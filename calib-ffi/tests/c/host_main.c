/* host_main.c: the checks of firmware-c/src/checks.c on the host (gcc, the host's static
 * library), run by calib-ffi/tests/c_api.rs. Instructions are not counted here (0). */
#include <stdio.h>

#include "checks.h"

void platform_print(const char *text) {
    fputs(text, stdout);
}

uint32_t platform_instructions(void) {
    return 0;
}

int main(void) {
    platform_print("calib C API on the host\n");
    checks_measured measured = {0};
    int failed = check_decode(&measured);
    failed += check_geometric(&measured);
    failed += check_load(&measured);
    failed += check_compliance(&measured);
    failed += check_api();
    print_value("failed checks:", (uint32_t)failed);
    platform_print(failed == 0 ? "PASS\n" : "FAILED\n");
    return failed == 0 ? 0 : 1;
}
