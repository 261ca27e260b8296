/* checks.c: checks of the calib C API with the UR10 blocks of calib_data.h (see checks.h). */
#include "checks.h"

#include <stddef.h>
#include <stdint.h>

#include "calib.h"
#include "calib_data.h"

static int failures;

static void fail(const char *what) {
    platform_print("FAIL ");
    platform_print(what);
    platform_print("\n");
    failures++;
}

static void expect(int ok, const char *what) {
    if (!ok) {
        fail(what);
    }
}

static void expect_status(CalibStatus got, CalibStatus want, const char *what) {
    if (got != want) {
        fail(what);
#ifdef COMPENSATION_ONLY
        print_value("  got status", (uint32_t)got); /* no message table in this build */
#else
        platform_print("  got: ");
        platform_print(calib_status_message((int32_t)got));
        platform_print("\n");
#endif
    }
}

void print_value(const char *label, uint32_t value) {
    char digits[12];
    int n = 0;
    do {
        digits[n++] = (char)('0' + value % 10u);
        value /= 10u;
    } while (value != 0u && n < 11);
    char text[12];
    for (int i = 0; i < n; i++) {
        text[i] = digits[n - 1 - i];
    }
    text[n] = '\0';
    platform_print(label);
    platform_print(" ");
    platform_print(text);
    platform_print("\n");
}

static uint32_t bits_of(float value) {
    union {
        float f;
        uint32_t u;
    } v;
    v.f = value;
    return v.u;
}

static float float_of(uint32_t bits) {
    union {
        float f;
        uint32_t u;
    } v;
    v.u = bits;
    return v.f;
}

static void joints_of(const uint32_t bits[CALIB_JOINTS], float q[CALIB_JOINTS]) {
    for (int j = 0; j < CALIB_JOINTS; j++) {
        q[j] = float_of(bits[j]);
    }
}

#ifndef COMPENSATION_ONLY
static float distance_squared_mm2(const CalibPoseF32 *a, const CalibPoseF32 *b) {
    float sum = 0.0f;
    for (int i = 0; i < 3; i++) {
        float d = a->position_mm[i] - b->position_mm[i];
        sum += d * d;
    }
    return sum; /* squared: no libm needed */
}
#endif

/* The controller's caller-owned memory (no heap in the library). */
static CalibRobotF32 nominal;
static CalibModelF32 model;
static uint8_t slot_a[CALIB_BLOCK_MAX_BYTES_F32];
static uint8_t slot_b[CALIB_BLOCK_MAX_BYTES_F32];
#ifndef COMPENSATION_ONLY
static uint8_t scratch[CALIB_BLOCK_MAX_BYTES_F32];
#endif

static void copy(uint8_t *to, const uint8_t *from, size_t len, size_t room) {
    for (size_t i = 0; i < room; i++) {
        to[i] = i < len ? from[i] : 0xFFu;
    }
}

static CalibPoseF32 pose_of(const uint32_t bits[POSE_VALUES]) {
    CalibPoseF32 pose;
    for (int i = 0; i < 3; i++) {
        pose.position_mm[i] = float_of(bits[i]);
    }
    for (int i = 0; i < 9; i++) {
        pose.rotation[i] = float_of(bits[3 + i]);
    }
    return pose;
}

/* Compensates every target (the host's poses) with the loaded model; compares with `expected`
 * bit for bit (the host checked that those joints put the model on the target). The full build
 * also checks the model's pose at the result here (the compensation-only build leaves forward
 * kinematics out, as a controller that only compensates would). */
static void compensate_targets(const uint32_t expected[TARGETS][CALIB_JOINTS], const char *what,
                               checks_cost *cost, uint32_t *forward_instructions) {
    uint32_t total = 0, slowest = 0;
    for (int t = 0; t < TARGETS; t++) {
        float q[CALIB_JOINTS];
        joints_of(TARGET_JOINTS[t], q);
        CalibPoseF32 target = pose_of(TARGET_POSES[t]);
        CalibCompensatedF32 result;
        uint32_t start = platform_instructions();
        CalibStatus status = calib_compensate_joints_f32(&nominal, &model, &target, q, NULL, &result);
        uint32_t spent = platform_instructions() - start;
        total += spent;
        slowest = spent > slowest ? spent : slowest;
        expect_status(status, CALIB_STATUS_OK, what);
        for (int j = 0; j < CALIB_JOINTS; j++) {
            expect(bits_of(result.q[j]) == expected[t][j], what);
        }
#ifndef COMPENSATION_ONLY
        /* The whole model at the result is on the target: 1e-2 mm (f32 tolerance). */
        CalibPoseF32 reached;
        start = platform_instructions();
        expect_status(calib_model_forward_f32(&model, result.q, &reached), CALIB_STATUS_OK,
                      "model forward kinematics");
        if (forward_instructions != NULL) {
            *forward_instructions = platform_instructions() - start;
        }
        expect(distance_squared_mm2(&reached, &target) <= 1e-4f, "compensated pose within 1e-2 mm");
#else
        (void)forward_instructions;
#endif
    }
    if (cost != NULL) {
        cost->mean = total / TARGETS;
        cost->slowest = slowest;
    }
}

int check_decode(checks_measured *measured) {
    failures = 0;
    expect(calib_api_version() >> 16 == CALIB_API_VERSION_MAJOR, "API major version");
    expect_status(calib_robot_decode_f32(&nominal, NOMINAL_F32, sizeof NOMINAL_F32),
                  CALIB_STATUS_OK, "decode the nominal robot");
    /* Slot A: a geometric calibration (sequence 1); slot B: erased flash. */
    copy(slot_a, GEOMETRIC_F32, sizeof GEOMETRIC_F32, sizeof slot_a);
    copy(slot_b, GEOMETRIC_F32, 0, sizeof slot_b);
    CalibSource source;
    uint32_t start = platform_instructions();
    CalibStatus status = calib_model_load_f32(&model, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                              &nominal, &source);
    measured->decode_instructions = platform_instructions() - start;
    expect_status(status, CALIB_STATUS_OK, "load the geometric model");
    expect(source.slot == CALIB_SLOT_A && !source.fallback && source.sequence == 1,
           "the geometric model is loaded from slot A, sequence 1");
    return failures;
}

int check_geometric(checks_measured *measured) {
    failures = 0;
    compensate_targets(EXPECTED_GEOMETRIC, "compensation with the geometric model (bits)",
                       &measured->geometric, NULL);
    return failures;
}

int check_load(checks_measured *measured) {
    failures = 0;
    /* Slot A: the maps model (sequence 1); slot B: maps and compliance (sequence 2). */
    copy(slot_a, MAPS_F32, sizeof MAPS_F32, sizeof slot_a);
    copy(slot_b, COMPLIANCE_F32, sizeof COMPLIANCE_F32, sizeof slot_b);
    CalibSource source;
    uint32_t start = platform_instructions();
    CalibStatus status = calib_model_load_f32(&model, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                              &nominal, &source);
    measured->load_instructions = platform_instructions() - start;
    expect_status(status, CALIB_STATUS_OK, "load two valid slots");
    expect(source.slot == CALIB_SLOT_B && !source.fallback && source.sequence == 2,
           "the newest slot (B, sequence 2) is loaded");
    return failures;
}

int check_compliance(checks_measured *measured) {
    failures = 0;
    compensate_targets(EXPECTED_COMPLIANCE, "compensation with maps and compliance (bits)",
                       &measured->compliance, &measured->forward_instructions);
    return failures;
}

#ifndef COMPENSATION_ONLY
/* A flash driver writing into slot_a / slot_b; with a budget it stops early and fails. */
static long write_budget = -1;

static int32_t flash_write(void *context, CalibSlot slot, const uint8_t *data, size_t len) {
    int *writes = (int *)context;
    (*writes)++;
    uint8_t *to = slot == CALIB_SLOT_A ? slot_a : slot_b;
    size_t n = len;
    if (write_budget >= 0 && (size_t)write_budget < len) {
        n = (size_t)write_budget;
    }
    copy(to, data, n, CALIB_BLOCK_MAX_BYTES_F32);
    return n == len ? 0 : -1;
}

static void check_storage(void) {
    CalibSource source;
    /* B damaged (a bit flipped in its geometry): fall back to A, and say so. */
    slot_b[40] ^= 0x01u;
    expect_status(calib_model_load_f32(&model, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                       &nominal, &source),
                  CALIB_STATUS_OK, "load with slot B damaged");
    expect(source.slot == CALIB_SLOT_A && source.fallback && source.sequence == 1,
           "fallback to slot A, sequence 1");
    compensate_targets(EXPECTED_MAPS, "compensation with maps after the fallback (bits)", NULL,
                       NULL);

    /* A block received from the host is decoded, then stored: it goes to the older slot B. */
    CalibModelF32 received;
    uint32_t sequence = 0;
    expect_status(calib_model_decode_f32(&received, COMPLIANCE_F32, sizeof COMPLIANCE_F32,
                                         &sequence),
                  CALIB_STATUS_OK, "decode a received block");
    expect(sequence == 2, "received block's sequence number");
    int writes = 0;
    CalibSource written;
    expect_status(calib_model_store_f32(&received, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                        scratch, sizeof scratch, flash_write, &writes, &written),
                  CALIB_STATUS_OK, "store a model");
    expect(writes == 1 && written.slot == CALIB_SLOT_B && written.sequence == 2,
           "stored to slot B with sequence 2");
    expect_status(calib_model_load_f32(&model, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                       &nominal, &source),
                  CALIB_STATUS_OK, "load after storing");
    expect(source.slot == CALIB_SLOT_B && !source.fallback && source.sequence == 2,
           "the stored block is the newest");
    compensate_targets(EXPECTED_COMPLIANCE, "compensation with the stored block (bits)", NULL,
                       NULL);

    /* A write to A (older) cut after 100 bytes: the previous block (B) still loads. */
    write_budget = 100;
    expect_status(calib_model_store_f32(&received, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                        scratch, sizeof scratch, flash_write, &writes, &written),
                  CALIB_STATUS_FLASH_WRITE, "an interrupted write is reported");
    write_budget = -1;
    expect_status(calib_model_load_f32(&model, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                       &nominal, &source),
                  CALIB_STATUS_OK, "load after an interrupted write");
    expect(source.slot == CALIB_SLOT_B && source.fallback && source.sequence == 2,
           "an interrupted write keeps the previous block");

    /* Both damaged: the nominal robot without maps. */
    slot_b[40] ^= 0x01u;
    expect_status(calib_model_load_f32(&model, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                       &nominal, &source),
                  CALIB_STATUS_OK, "load with both slots damaged");
    expect(source.slot == CALIB_SLOT_NOMINAL && source.sequence == 0, "nominal fallback");
    /* ... with which a target of the nominal robot needs no correction. */
    float q[CALIB_JOINTS];
    joints_of(TARGET_JOINTS[0], q);
    CalibPoseF32 target;
    calib_robot_forward_f32(&nominal, q, &target);
    CalibCompensatedF32 result;
    expect_status(calib_compensate_joints_f32(&nominal, &model, &target, q, NULL, &result),
                  CALIB_STATUS_OK, "compensation with the nominal model");
    expect(result.iterations == 0, "the nominal model's target needs no iteration");
}

static void check_kinematics(void) {
    CalibSource source;
    copy(slot_a, COMPLIANCE_F32, sizeof COMPLIANCE_F32, sizeof slot_a);
    expect_status(calib_model_load_f32(&model, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                       &nominal, &source),
                  CALIB_STATUS_OK, "load for kinematics");
    /* Forward kinematics of the nominal robot: the host's target poses, bit for bit. */
    for (int t = 0; t < TARGETS; t++) {
        float joints[CALIB_JOINTS];
        joints_of(TARGET_JOINTS[t], joints);
        CalibPoseF32 pose;
        expect_status(calib_robot_forward_f32(&nominal, joints, &pose), CALIB_STATUS_OK,
                      "nominal forward kinematics");
        CalibPoseF32 host = pose_of(TARGET_POSES[t]);
        for (int i = 0; i < 3; i++) {
            expect(bits_of(pose.position_mm[i]) == bits_of(host.position_mm[i]),
                   "nominal forward kinematics: the host's position (bits)");
        }
        for (int i = 0; i < 9; i++) {
            expect(bits_of(pose.rotation[i]) == bits_of(host.rotation[i]),
                   "nominal forward kinematics: the host's rotation (bits)");
        }
    }
    float q[CALIB_JOINTS];
    joints_of(TARGET_JOINTS[1], q);
    CalibPoseF32 target;
    calib_robot_forward_f32(&nominal, q, &target);
    /* Closed-form inverse kinematics (UR offset wrist) recovers the joints. */
    float solved[CALIB_JOINTS];
    uint32_t branch = 99;
    expect_status(calib_inverse_kinematics_f32(&nominal, &target, q, solved, &branch),
                  CALIB_STATUS_OK, "inverse kinematics");
    for (int j = 0; j < CALIB_JOINTS; j++) {
        float d = solved[j] - q[j];
        expect(d < 1e-3f && d > -1e-3f, "inverse kinematics recovers the joints to 1e-3 rad");
    }
    expect(branch < 8, "inverse kinematics names its branch");
    /* Pre-distortion: the nominal joints of the command put the model on the target. */
    CalibPoseF32 command;
    CalibCompensatedF32 result;
    expect_status(calib_predistort_f32(&nominal, &model, &target, q, NULL, &command, &result),
                  CALIB_STATUS_OK, "pre-distortion");
    CalibPoseF32 reached;
    calib_model_forward_f32(&model, result.q, &reached);
    expect(distance_squared_mm2(&reached, &target) <= 4e-4f, "pre-distorted pose within 2e-2 mm");
    expect(distance_squared_mm2(&command, &target) > 0.01f, "the command differs from the target");
}

static void check_f64(void) {
    static CalibRobotF64 nominal64;
    static CalibModelF64 model64;
    expect_status(calib_robot_decode_f64(&nominal64, NOMINAL_F64, sizeof NOMINAL_F64),
                  CALIB_STATUS_OK, "decode an f64 robot");
    expect_status(calib_model_decode_f64(&model64, COMPLIANCE_F64, sizeof COMPLIANCE_F64, NULL),
                  CALIB_STATUS_OK, "decode an f64 model");
    double q[CALIB_JOINTS];
    for (int j = 0; j < CALIB_JOINTS; j++) {
        q[j] = (double)float_of(TARGET_JOINTS[2][j]);
    }
    CalibPoseF64 target, reached;
    calib_robot_forward_f64(&nominal64, q, &target);
    CalibCompensatedF64 result;
    expect_status(calib_compensate_joints_f64(&nominal64, &model64, &target, q, NULL, &result),
                  CALIB_STATUS_OK, "f64 compensation");
    calib_model_forward_f64(&model64, result.q, &reached);
    double sum = 0.0;
    for (int i = 0; i < 3; i++) {
        double d = reached.position_mm[i] - target.position_mm[i];
        sum += d * d;
    }
    expect(sum <= 1e-6, "f64 compensated pose within 1e-3 mm");
    CalibSettingsF64 settings;
    calib_settings_default_f64(&settings);
    expect(settings.position_tolerance_mm == 1e-3, "f64 default tolerance 1e-3 mm");
}

static void check_refusals(void) {
    float q[CALIB_JOINTS];
    joints_of(TARGET_JOINTS[0], q);
    CalibPoseF32 target;
    calib_robot_forward_f32(&nominal, q, &target);
    CalibCompensatedF32 result;
    expect_status(calib_compensate_joints_f32(&nominal, &model, NULL, q, NULL, &result),
                  CALIB_STATUS_NULL_POINTER, "NULL target");
    expect_status(calib_compensate_joints_f32(&nominal, &model, &target, q, NULL, NULL),
                  CALIB_STATUS_NULL_POINTER, "NULL result");
    static uint32_t raw[32];
    CalibPoseF32 *misaligned = (CalibPoseF32 *)((uint8_t *)raw + 2);
    expect_status(calib_compensate_joints_f32(&nominal, &model, misaligned, q, NULL, &result),
                  CALIB_STATUS_MISALIGNED, "misaligned target");
    static CalibModelF32 empty; /* zero: never filled */
    expect_status(calib_compensate_joints_f32(&nominal, &empty, &target, q, NULL, &result),
                  CALIB_STATUS_NOT_INITIALISED, "a model that was never loaded");
    expect_status(calib_compensate_joints_f32((const CalibRobotF32 *)&model, &model, &target, q,
                                              NULL, &result),
                  CALIB_STATUS_NOT_INITIALISED, "a model passed as the nominal robot");
    CalibPoseF32 skewed = target;
    skewed.rotation[1] += 0.01f;
    expect_status(calib_compensate_joints_f32(&nominal, &model, &skewed, q, NULL, &result),
                  CALIB_STATUS_NOT_A_ROTATION, "a matrix that is no rotation");
    float bad[CALIB_JOINTS];
    joints_of(TARGET_JOINTS[0], bad);
    bad[3] = float_of(0x7fc00000u); /* NaN */
    expect_status(calib_compensate_joints_f32(&nominal, &model, &target, bad, NULL, &result),
                  CALIB_STATUS_NON_FINITE, "a NaN start joint");
    /* A target 50 mm away: more than the 5 mm correction bound. */
    CalibPoseF32 far = target;
    far.position_mm[0] += 50.0f;
    CalibStatus far_status = calib_compensate_joints_f32(&nominal, &model, &far, q, NULL, &result);
    expect(far_status == CALIB_STATUS_CORRECTION_TOO_LARGE, "a 50 mm correction is refused");
    CalibModelF32 decoded;
    expect_status(calib_model_decode_f32(&decoded, NOMINAL_F64, sizeof NOMINAL_F64, NULL),
                  CALIB_STATUS_WRONG_SCALAR, "an f64 block read as f32");
    expect_status(calib_model_decode_f32(&decoded, COMPLIANCE_F32, 100, NULL),
                  CALIB_STATUS_BUFFER_TOO_SMALL, "a truncated block");
    uint8_t erased[64];
    for (size_t i = 0; i < sizeof erased; i++) {
        erased[i] = 0xFFu;
    }
    expect_status(calib_model_decode_f32(&decoded, erased, sizeof erased, NULL),
                  CALIB_STATUS_BAD_MAGIC, "erased flash");
    expect_status(calib_robot_decode_f32(&nominal, MAPS_F32, sizeof MAPS_F32),
                  CALIB_STATUS_UNSUPPORTED_VERSION, "a version 2 block as the nominal robot");
    expect_status(calib_robot_forward_f32(&nominal, q, &target), CALIB_STATUS_NOT_INITIALISED,
                  "a robot whose decode failed is not used");
    expect_status(calib_robot_decode_f32(&nominal, NOMINAL_F32, sizeof NOMINAL_F32),
                  CALIB_STATUS_OK, "decode the nominal robot again");
    expect_status(calib_model_store_f32(&model, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                        scratch, sizeof scratch, NULL, NULL, NULL),
                  CALIB_STATUS_NULL_POINTER, "store without a flash driver");
    expect_status(calib_model_store_f32(&model, slot_a, sizeof slot_a, slot_b, sizeof slot_b,
                                        scratch, 64, flash_write, &(int){0}, NULL),
                  CALIB_STATUS_BUFFER_TOO_SMALL, "store with a small scratch buffer");
    const char *unknown = calib_status_message(12345);
    expect(unknown != NULL && unknown[0] == 'u', "message of an unknown status");
    expect(calib_status_message(CALIB_STATUS_BAD_CHECKSUM)[0] == 't', "message of a status");
}

int check_api(void) {
    failures = 0;
    check_storage();
    check_kinematics();
    check_f64();
    check_refusals();
    return failures;
}
#endif /* COMPENSATION_ONLY */
