/* checks.h: checks of the calib C API, shared by the firmware (QEMU, Cortex-M4F) and the host C
 * test (gcc). Each platform provides the functions below. */
#ifndef CALIB_CHECKS_H
#define CALIB_CHECKS_H

#include <stdint.h>

/* Writes a NUL-terminated string to the log. */
void platform_print(const char *text);
/* Instructions executed so far (0 where the platform cannot count them). */
uint32_t platform_instructions(void);

/* Instructions of one compensation over the targets (0 where not counted). */
typedef struct {
    uint32_t mean;
    uint32_t slowest;
} checks_cost;

/* What the checks measured (instructions; 0 where not counted). */
typedef struct {
    uint32_t decode_instructions;  /* calib_model_load_f32: a geometric block and erased flash */
    uint32_t load_instructions;    /* calib_model_load_f32 of two valid slots (maps, compliance) */
    checks_cost geometric;         /* calib_compensate_joints_f32, geometric model */
    checks_cost compliance;        /* the same with maps and gravity compliance */
    uint32_t forward_instructions; /* calib_model_forward_f32 with maps and compliance */
} checks_measured;

/* The controller's job in four steps (each returns its number of failed checks), run in this
 * order: decode the nominal robot and load a geometric model (slot B erased); compensate the targets with it,
 * comparing the joints with the host's bit for bit; load the newest valid block of two slots
 * (maps, and maps with compliance); compensate the targets with the loaded model, bit for bit. */
int check_decode(checks_measured *measured);
int check_geometric(checks_measured *measured);
int check_load(checks_measured *measured);
int check_compliance(checks_measured *measured);

/* Everything else of the API: fallback, storing, interrupted writes, inverse kinematics,
 * pre-distortion, f64, and the refusals of wrong arguments. Returns the number of failed checks. */
int check_api(void);

/* Prints "label value" and a newline. */
void print_value(const char *label, uint32_t value);

#endif
