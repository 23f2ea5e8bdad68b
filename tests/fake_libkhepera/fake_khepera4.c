/* fake_khepera4.c: a simulated Khepera IV behind libkhepera's calls, for khepera_gym's tests of
 * the generated robot programs. Its time passes only when fake_khepera_advance() is called:
 * fake_clock.c, linked in place of the programs' khepera_clock.c, does so when a program
 * sleeps, so that a run of minutes takes a fraction of a second. Linked with the programs' own
 * clock instead (`make robot` against libkhepera.a of this file), the robot stands still.
 *
 * The calls keep K-Team's conventions (khepera/khepera.h says which): 0 on success, the positive
 * KB_ERROR_KH4KBNOTINIT (58) for a NULL device, the buffers' byte layouts, the 16 bits of a speed
 * that reach the motor controller, the 6 bits of an LED level, ultrasonic sensors left out of
 * kh4_activate_us's mask reading KH4_US_DISABLED_SENSOR.
 *
 * Its "own settings" are the FAKE_* macros below (the tests pass -D to change them):
 *   the wheels: radius, axle, a first-order lag behind the motor controller's order, which
 *     follows kh4_SetSpeedProfile's profile in whole speed units every 10 ms (the firmware's
 *     staircase) or, in speed mode, FAKE_SPEED_ACCEL; measured speeds with Gaussian noise;
 *   the gyroscope: 10 samples at 100 Hz, each the yaw rate plus a bias and Gaussian noise, in
 *     counts of 0.066 deg/s; the accelerometer likewise (mg, raw << 4);
 *   the infrared ring: K-Team's curve (docs/robot.md §3) scaled by FAKE_IR_GAIN in value and
 *     FAKE_IR_SCALE in distance, sampled at the curve's 16 distances and interpolated linearly,
 *     falling to FAKE_IR_FLOOR at 0.25 m, with Gaussian noise;
 *   the ultrasonic sensors: every 100 ms the distance plus FAKE_US_OFFSET and Gaussian noise, in
 *     cm, for a surface within 22.5 degrees of facing the beam (codes 0, 1000);
 *   the scene: a straight wall across x = FAKE_WALL_X (m) in the start frame (x forward).
 * Environment variables:
 *   FAKE_TRACE=path      every kh4_get_position call also appends the true time (s), x, y (m),
 *                        heading (rad) and the gap to the wall (m) to that file, so that a test
 *                        can measure the final gap the user would measure;
 *   FAKE_FAIL=call:code[:n]  the libkhepera call named (e.g. kh4_measure_us) fails from its n-th
 *                        call on (1 if absent), returning code (e.g. 58, 55, -1) and leaving
 *                        junk in its outputs, as a failing bus does; knet_open then returns
 *                        NULL (its code is not used);
 *   FAKE_EXIT_STATE=path at the program's exit, the motor controller's state is written there:
 *                        "mode M target L R leds l0 .. l8 calls N" (N: libkhepera calls made).
 * Units: SI inside; K-Team's units at the calls.
 */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <khepera/khepera.h>

#include "fake_khepera4.h"

#ifndef FAKE_WHEEL_RADIUS
#define FAKE_WHEEL_RADIUS 0.0213
#endif
#ifndef FAKE_AXLE
#define FAKE_AXLE 0.1047
#endif
#ifndef FAKE_TAU
#define FAKE_TAU 0.03
#endif
#ifndef FAKE_SPEED_ACCEL
#define FAKE_SPEED_ACCEL 2.0
#endif
#ifndef FAKE_SPEED_NOISE
#define FAKE_SPEED_NOISE 2.0
#endif
#ifndef FAKE_GYRO_BIAS
#define FAKE_GYRO_BIAS 1.2
#endif
#ifndef FAKE_GYRO_NOISE
#define FAKE_GYRO_NOISE 0.3
#endif
#ifndef FAKE_IR_GAIN
#define FAKE_IR_GAIN 0.9
#endif
#ifndef FAKE_IR_SCALE
#define FAKE_IR_SCALE 1.05
#endif
#ifndef FAKE_IR_FLOOR
#define FAKE_IR_FLOOR 95.0
#endif
#ifndef FAKE_IR_NOISE
#define FAKE_IR_NOISE 8.0
#endif
#ifndef FAKE_US_OFFSET
#define FAKE_US_OFFSET 0.015
#endif
#ifndef FAKE_US_NOISE
#define FAKE_US_NOISE 0.008
#endif
#ifndef FAKE_WALL_X
#define FAKE_WALL_X 0.5704
#endif
#ifndef FAKE_SEED
#define FAKE_SEED 12345u
#endif

#define PI 3.14159265358979323846
#define PULSES_PER_TURN 19456.0
#define PERIOD 0.01       /* the firmware's period, s */
#define SUBSTEP 0.001     /* the physics' step, s */
#define BODY_RADIUS 0.0704
#define DEG_S_PER_COUNT 0.066

static const double CURVE_MM[16] = {0, 10, 20, 30, 35, 40, 45, 50, 60, 70, 80, 90, 100, 120,
                                    150, 200};
static const double CURVE_RAW[16] = {1018, 1012, 1002, 979, 889, 764, 597, 492, 380, 319, 254,
                                     228, 199, 163, 133, 111};
static const double IR_BEARINGS_DEG[8] = {135, 90, 45, 0, -45, -90, -135, 180};
static const double US_BEARINGS_DEG[5] = {90, 45, 0, -45, -90};

/* The dsPIC's handle knet_open gives. */
static knet_dev_t device = {NULL, 0, 0, 0, "Khepera4:dsPic", 1, NULL, NULL};
static struct {
    long time_ms;         /* the simulated time, in whole ms (no rounding drift) */
    int mode;
    int us_mask;          /* kh4_activate_us's: bit i on, sensor i pings */
    int leds[9];          /* kh4_SetRGBLeds' levels, 6 bits each */
    long calls;           /* libkhepera calls made */
    int acc_inc, acc_div, min_acc;
    int periods;          /* firmware ticks since the last profile increment */
    int target[2];        /* the set point (units) */
    double order[2];      /* the profile's order (units) */
    double wheel[2];      /* the wheels' speeds (units: pulses per 10 ms) */
    double pulses[2];
    double offset[2];     /* encoder value at the last reset */
    double x, y, heading;
    int16_t gyro[30];     /* newest first per axis */
    int16_t acc[30];
    double last_v;
    int us[5];
    uint64_t rng;
    double curve[16];
} robot;

static double uniform(void)
{
    robot.rng ^= robot.rng << 13;
    robot.rng ^= robot.rng >> 7;
    robot.rng ^= robot.rng << 17;
    return ((double)(robot.rng >> 11) + 0.5) / 9007199254740992.0;
}

static double gaussian(void)
{
    return sqrt(-2.0 * log(uniform())) * cos(2.0 * PI * uniform());
}

static double interpolate(const double *xs, const double *ys, int n, double x)
{
    int i;
    if (x <= xs[0]) {
        return ys[0];
    }
    for (i = 1; i < n; ++i) {
        if (x <= xs[i]) {
            return ys[i - 1] + (x - xs[i - 1]) / (xs[i] - xs[i - 1]) * (ys[i] - ys[i - 1]);
        }
    }
    /* beyond the table: the last segment's slope */
    return ys[n - 1] + (x - xs[n - 1]) / (xs[n - 1] - xs[n - 2]) * (ys[n - 1] - ys[n - 2]);
}

/* FAKE_EXIT_STATE: the motor controller's state when the program ends. */
static void write_exit_state(void)
{
    const char *path = getenv("FAKE_EXIT_STATE");
    FILE *file;
    int i;
    if (path == NULL || (file = fopen(path, "w")) == NULL) {
        return;
    }
    fprintf(file, "mode %d target %d %d leds", robot.mode, robot.target[0], robot.target[1]);
    for (i = 0; i < 9; ++i) {
        fprintf(file, " %d", robot.leds[i]);
    }
    fprintf(file, " calls %ld\n", robot.calls);
    fclose(file);
}

static void start(void)
{
    int i;
    if (robot.rng != 0) {
        return;
    }
    robot.rng = 0x9E3779B97F4A7C15ull ^ (uint64_t)FAKE_SEED;
    robot.us_mask = 31; /* the firmware starts with every ultrasonic sensor on */
    atexit(write_exit_state);
    robot.acc_inc = 3;
    robot.min_acc = 20;
    for (i = 0; i < 16; ++i) {
        double value = FAKE_IR_GAIN * interpolate(CURVE_MM, CURVE_RAW, 16, CURVE_MM[i] / FAKE_IR_SCALE);
        robot.curve[i] = value > 1023.0 ? 1023.0 : value;
    }
    for (i = 0; i < 5; ++i) {
        robot.us[i] = 1000;
    }
}

/* The distance (m) along a ray from the rim at `bearing` to the wall, or -1. */
static double ray_to_wall(double bearing)
{
    const double angle = robot.heading + bearing;
    const double c = cos(angle);
    const double ox = robot.x + BODY_RADIUS * c;
    double d;
    if (c <= 1e-9) {
        return -1.0;
    }
    d = (FAKE_WALL_X - ox) / c;
    return d >= 0.0 ? d : 0.0;
}

/* One firmware period: the profile's order moves toward the set point. */
static void firmware_period(void)
{
    int k;
    double rate = 0.0;
    for (k = 0; k < 2; ++k) {
        double order = robot.order[k];
        const double target = (double)robot.target[k];
        if (robot.mode == kh4RegSpeedProfile) {
            double goal = target;
            if (goal != 0.0 && fabs(goal) < robot.min_acc) {
                goal = goal > 0 ? robot.min_acc : -robot.min_acc;
            }
            if (robot.periods >= robot.acc_div) {
                double step = goal - order;
                if (step > robot.acc_inc) {
                    step = robot.acc_inc;
                } else if (step < -robot.acc_inc) {
                    step = -robot.acc_inc;
                }
                order += step;
                if (order != 0.0 && fabs(order) < robot.min_acc) {
                    order = (goal == 0.0 || (goal > 0) != (order > 0))
                        ? 0.0 : (goal > 0 ? robot.min_acc : -robot.min_acc);
                }
            }
        } else if (robot.mode == kh4RegSpeed) {
            const double limit = FAKE_SPEED_ACCEL * PERIOD / (2.0 * PI * FAKE_WHEEL_RADIUS
                                                              / PULSES_PER_TURN / PERIOD);
            double step = target - order;
            step = step > limit ? limit : (step < -limit ? -limit : step);
            order += step;
        } else {
            order = 0.0;
        }
        robot.order[k] = order;
    }
    robot.periods = robot.periods >= robot.acc_div ? 0 : robot.periods + 1;
    /* the IMU's samples of this period, newest first */
    memmove(&robot.gyro[1], &robot.gyro[0], 29 * sizeof robot.gyro[0]);
    memmove(&robot.acc[1], &robot.acc[0], 29 * sizeof robot.acc[0]);
    {
        const double metres = 2.0 * PI * FAKE_WHEEL_RADIUS / PULSES_PER_TURN / PERIOD;
        const double v_left = robot.wheel[0] * metres;
        const double v_right = robot.wheel[1] * metres;
        const double v = 0.5 * (v_left + v_right);
        rate = (v_right - v_left) / FAKE_AXLE * 180.0 / PI;
        for (k = 0; k < 3; ++k) {
            const double value = (k == 2 ? rate + FAKE_GYRO_BIAS : 0.0) + FAKE_GYRO_NOISE * gaussian();
            robot.gyro[10 * k] = (int16_t)lround(value / DEG_S_PER_COUNT);
        }
        robot.acc[0] = (int16_t)(16 * lround((v - robot.last_v) / PERIOD / 9.80665 * 1000.0));
        robot.acc[10] = (int16_t)(16 * lround(v * rate * PI / 180.0 / 9.80665 * 1000.0));
        robot.acc[20] = (int16_t)(16 * -1000);
        robot.last_v = v;
    }
}

static void ultrasonic_sweep(void)
{
    int i;
    for (i = 0; i < 5; ++i) {
        const double bearing = US_BEARINGS_DEG[i] * PI / 180.0;
        const double d = ray_to_wall(bearing);
        const double incidence = fabs(remainder(robot.heading + bearing, 2.0 * PI));
        if ((robot.us_mask & (1 << i)) == 0) {
            robot.us[i] = KH4_US_DISABLED_SENSOR;
        } else if (d < 0.0 || incidence > 22.5 * PI / 180.0) {
            robot.us[i] = 1000;
        } else {
            const double cm = floor((d + FAKE_US_OFFSET + FAKE_US_NOISE * gaussian()) * 100.0 + 0.5);
            robot.us[i] = cm < 25.0 ? 0 : (cm > 200.0 ? 1000 : (int)cm);
        }
    }
}

/* Runs the robot 1 ms at a time until `until` (s): the firmware's period every 10 ms, the
 * ultrasonic sweep every 100 ms, starting with those due at the current time. */
void fake_khepera_advance(double until)
{
    const double metres = 2.0 * PI * FAKE_WHEEL_RADIUS / PULSES_PER_TURN / PERIOD;
    const double k = 1.0 - exp(-SUBSTEP / FAKE_TAU);
    const long until_ms = (long)floor(until * 1000.0 + 0.5);
    start();
    while (robot.time_ms < until_ms) {
        int i;
        double v;
        double w;
        if (robot.time_ms % 10 == 0) {
            firmware_period();
        }
        if (robot.time_ms % 100 == 0) {
            ultrasonic_sweep();
        }
        for (i = 0; i < 2; ++i) {
            robot.wheel[i] += k * (robot.order[i] - robot.wheel[i]);
            robot.pulses[i] += robot.wheel[i] * SUBSTEP / PERIOD;
        }
        v = 0.5 * (robot.wheel[0] + robot.wheel[1]) * metres;
        w = (robot.wheel[1] - robot.wheel[0]) * metres / FAKE_AXLE;
        robot.x += v * cos(robot.heading + 0.5 * w * SUBSTEP) * SUBSTEP;
        robot.y += v * sin(robot.heading + 0.5 * w * SUBSTEP) * SUBSTEP;
        robot.heading += w * SUBSTEP;
        robot.time_ms += 1;
    }
}

double fake_khepera_time(void)
{
    start();
    return (double)robot.time_ms / 1000.0;
}

static void put_u16(char *buffer, int index, int value)
{
    buffer[2 * index] = (char)(value & 0xff);
    buffer[2 * index + 1] = (char)((value >> 8) & 0xff);
}

/* What a failing bus leaves in a read's buffer. */
static void junk(char *buffer, int size)
{
    memset(buffer, 0xA5, (size_t)size);
}

/* FAKE_FAIL: whether this call of `call` fails, and with which code. Every libkhepera call of
 * the program passes here once (it also counts them). */
static int fails(const char *call, int *code)
{
    static long counts[32];
    static const char *names[32];
    const char *spec = getenv("FAKE_FAIL");
    const size_t length = strlen(call);
    long from = 1;
    long count = 0;
    int slot;
    char *end;
    start();
    robot.calls += 1;
    for (slot = 0; slot < 32 && names[slot] != NULL && strcmp(names[slot], call) != 0; ++slot) {
    }
    if (slot < 32) {
        names[slot] = call;
        count = ++counts[slot];
    }
    if (spec == NULL || strncmp(spec, call, length) != 0 || spec[length] != ':') {
        return 0;
    }
    *code = (int)strtol(spec + length + 1, &end, 10);
    if (*end == ':') {
        from = strtol(end + 1, NULL, 10);
    }
    return count >= from;
}

/* The return of a call on `d` that did not fail: K-Team's 58 for a NULL device, else 0. */
static int on_device(const knet_dev_t *d)
{
    return d == NULL ? KB_ERROR_KH4KBNOTINIT : 0;
}

int kh4_init(int argc, char *argv[])
{
    int code;
    (void)argc;
    (void)argv;
    return fails("kh4_init", &code) ? code : 0;
}

knet_dev_t *knet_open(const char *name, int bus, int argc, char *argv[])
{
    int code;
    (void)argc;
    (void)argv;
    if (fails("knet_open", &code) || strcmp(name, "Khepera4:dsPic") != 0 || bus != KNET_BUS_I2C) {
        return NULL;
    }
    return &device;
}

int kh4_revision(char *buffer, knet_dev_t *d)
{
    int code;
    if (fails("kh4_revision", &code)) {
        junk(buffer, 1);
        return code;
    }
    if (d != NULL) {
        buffer[0] = (char)0x23; /* version C, revision 3 */
    }
    return on_device(d);
}

int kh4_SetMode(int mode, knet_dev_t *d)
{
    int code;
    if (fails("kh4_SetMode", &code)) {
        return code;
    }
    if (d != NULL) {
        robot.mode = mode;
    }
    return on_device(d);
}

int kh4_SetSpeedProfile(char acc_inc, char acc_div, char min_speed_acc, char min_speed_dec,
                        int max_speed, knet_dev_t *d)
{
    int code;
    (void)min_speed_dec;
    (void)max_speed;
    if (fails("kh4_SetSpeedProfile", &code)) {
        return code;
    }
    if (d != NULL) {
        robot.acc_inc = (unsigned char)acc_inc;
        robot.acc_div = (unsigned char)acc_div;
        robot.min_acc = (unsigned char)min_speed_acc;
    }
    return on_device(d);
}

/* The set point the motor controller receives: the low 16 bits of a speed, signed. */
static int low16(int value)
{
    const unsigned int bits = (unsigned int)value & 0xffffu;
    return bits >= 0x8000u ? (int)bits - 0x10000 : (int)bits;
}

int kh4_set_speed(int left, int right, knet_dev_t *d)
{
    int code;
    if (fails("kh4_set_speed", &code)) {
        return code;
    }
    if (d != NULL) {
        robot.target[0] = low16(left);
        robot.target[1] = low16(right);
    }
    return on_device(d);
}

int kh4_get_speed(int *left, int *right, knet_dev_t *d)
{
    int code;
    if (fails("kh4_get_speed", &code)) {
        *left = *right = -23131; /* junk */
        return code;
    }
    if (d != NULL) {
        *left = (int)lround(robot.wheel[0] + FAKE_SPEED_NOISE * gaussian());
        *right = (int)lround(robot.wheel[1] + FAKE_SPEED_NOISE * gaussian());
    }
    return on_device(d);
}

int kh4_get_position(int *left, int *right, knet_dev_t *d)
{
    const char *trace = getenv("FAKE_TRACE");
    int code;
    if (fails("kh4_get_position", &code)) {
        *left = *right = -1515870811; /* junk: 0xA5A5A5A5 */
        return code;
    }
    if (d == NULL) {
        return KB_ERROR_KH4KBNOTINIT;
    }
    if (trace != NULL) {
        FILE *file = fopen(trace, "a");
        if (file != NULL) {
            fprintf(file, "%.3f %.9f %.9f %.9f %.9f\n", (double)robot.time_ms / 1000.0, robot.x,
                    robot.y, robot.heading, FAKE_WALL_X - robot.x - BODY_RADIUS);
            fclose(file);
        }
    }
    *left = (int)floor(robot.pulses[0] - robot.offset[0]);
    *right = (int)floor(robot.pulses[1] - robot.offset[1]);
    return 0;
}

int kh4_ResetEncoders(knet_dev_t *d)
{
    int code;
    if (fails("kh4_ResetEncoders", &code)) {
        return code;
    }
    if (d != NULL) {
        robot.offset[0] = robot.pulses[0];
        robot.offset[1] = robot.pulses[1];
    }
    return on_device(d);
}

int kh4_proximity_ir(char *buffer, knet_dev_t *d)
{
    int code;
    int i;
    if (fails("kh4_proximity_ir", &code)) {
        junk(buffer, 24);
        return code;
    }
    if (d == NULL) {
        return KB_ERROR_KH4KBNOTINIT;
    }
    for (i = 0; i < 8; ++i) {
        const double distance = ray_to_wall(IR_BEARINGS_DEG[i] * PI / 180.0);
        double mean = FAKE_IR_FLOOR;
        double raw;
        if (distance >= 0.0 && distance < 0.25) {
            const double mm = distance * 1000.0;
            mean = mm >= 200.0 ? robot.curve[15] + (mm - 200.0) / 50.0 * (FAKE_IR_FLOOR - robot.curve[15])
                               : interpolate(CURVE_MM, robot.curve, 16, mm);
        }
        raw = floor(mean + FAKE_IR_NOISE * gaussian() + 0.5);
        raw = raw < 0.0 ? 0.0 : (raw > 1023.0 ? 1023.0 : raw);
        put_u16(buffer, i, (int)raw);
    }
    for (i = 8; i < 12; ++i) {
        put_u16(buffer, i, 950);
    }
    return 0;
}

int kh4_measure_us(char *buffer, knet_dev_t *d)
{
    int code;
    int i;
    if (fails("kh4_measure_us", &code)) {
        junk(buffer, 10);
        return code;
    }
    if (d == NULL) {
        return KB_ERROR_KH4KBNOTINIT;
    }
    for (i = 0; i < 5; ++i) {
        put_u16(buffer, i, robot.us[i]);
    }
    return 0;
}

int kh4_activate_us(char mask, knet_dev_t *d)
{
    int code;
    if (fails("kh4_activate_us", &code)) {
        return code;
    }
    if (d != NULL) {
        int i;
        robot.us_mask = (unsigned char)mask & 31;
        for (i = 0; i < 5; ++i) { /* off at once; on from the next sweep */
            if ((robot.us_mask & (1 << i)) == 0) {
                robot.us[i] = KH4_US_DISABLED_SENSOR;
            }
        }
    }
    return on_device(d);
}

/* The 10 samples of x, then y, then z, of an IMU channel. */
static int imu_read(const char *call, const int16_t *samples, char *buffer, knet_dev_t *d)
{
    int code;
    int i;
    if (fails(call, &code)) {
        junk(buffer, 60);
        return code;
    }
    if (d == NULL) {
        return KB_ERROR_KH4KBNOTINIT;
    }
    for (i = 0; i < 30; ++i) {
        put_u16(buffer, i, samples[i]);
    }
    return 0;
}

int kh4_measure_acc(char *buffer, knet_dev_t *d)
{
    return imu_read("kh4_measure_acc", robot.acc, buffer, d);
}

int kh4_measure_gyro(char *buffer, knet_dev_t *d)
{
    return imu_read("kh4_measure_gyro", robot.gyro, buffer, d);
}

int kh4_SetRGBLeds(char left_red, char left_green, char left_blue, char right_red,
                   char right_green, char right_blue, char back_red, char back_green,
                   char back_blue, knet_dev_t *d)
{
    const char levels[9] = {left_red, left_green, left_blue, right_red, right_green, right_blue,
                            back_red, back_green, back_blue};
    int code;
    int i;
    if (fails("kh4_SetRGBLeds", &code)) {
        return code;
    }
    if (d != NULL) {
        for (i = 0; i < 9; ++i) {
            robot.leds[i] = (unsigned char)levels[i] & 0x3F;
        }
    }
    return on_device(d);
}
