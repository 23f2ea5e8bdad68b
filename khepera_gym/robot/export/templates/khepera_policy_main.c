/* khepera_policy_main.c: TEMPLATE of a program running the exported policy on a real Khepera IV.
 *
 * A starting point to read and adapt, not a tested driver: khepera_gym checks that it is valid
 * C99 against the libkhepera declarations it uses, but it has not been run on a robot by the
 * exporter. Cross-compile it with K-Team's toolchain and libkhepera (see README.md and the
 * Makefile next to it), copy it to the robot and run it there.
 *
 * Every control period (KHEPERA_CONTROL_PERIOD_S: the simulator's step) it
 *   1. reads the IR ring (kh4_proximity_ir) and the ultrasonic sensors (kh4_measure_us) when
 *      the observation has their blocks (observation.h), the wheel speeds (kh4_get_speed) and
 *      the encoders (kh4_get_position);
 *   2. integrates the encoders into a dead-reckoning pose in the frame of the robot at start
 *      (x forward, y left): the goal inputs of the observation come from it and from the goal
 *      given on the command line in that frame;
 *   3. builds the observation exactly as the simulator does (observation.c);
 *   4. runs the policy (policy.c) and sends the wheel speeds with kh4_set_speed in K-Team's units
 *      (the motor controller set at start as in training: the speed profile or the speed mode),
 *      clipped to the robot's limit (wheel_command.c); with KHEPERA_LED_ACTION (a policy trained
 *      with task.led_action) it also sets the three top LEDs with kh4_SetRGBLeds, 0..63 a colour.
 * It stops the motors on Ctrl-C, at the goal (estimated by odometry, which drifts), after
 * MAX_STEPS steps, or when the policy gives a non-finite action. A libkhepera call that fails
 * (any non-zero return: khepera_sensors.h) stops it too: it stops the motors, says which call
 * failed, notes it in the log and closes the log, and exits with status 1.
 *
 * Usage on the robot:  ./khepera_policy GOAL_X GOAL_Y [MAX_STEPS] [--log FILE]
 *   GOAL_X, GOAL_Y  goal in metres in the robot's frame at start (ignored if the observation has
 *                   no goal inputs); MAX_STEPS  0 or absent: no limit;
 *   --log FILE      also read every sensor each step and write them, the command, the
 *                   observation and the action to FILE, a robot log (khepera_log.h) that
 *                   `khepera-gym replay` and `khepera-gym calibrate` read.
 * It prints one line per step: step, pose (m, m, rad), action, wheel units (then LED levels).
 */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <khepera/khepera.h>

#include "khepera_clock.h"
#include "khepera_log.h"
#include "khepera_policy_config.h"
#include "khepera_sensors.h"
#include "observation.h"
#include "policy.h"
#include "wheel_command.h"

#if POLICY_OBS_DIM != OBSERVATION_DIM
#error "policy.h and observation.h come from different exports"
#endif

static volatile sig_atomic_t stop_requested = 0;

static void on_signal(int signal_number)
{
    (void)signal_number;
    stop_requested = 1;
}

/* Dead reckoning from the wheel encoders (pulses), midpoint integration, in the start frame. */
typedef struct {
    double x;       /* m */
    double y;       /* m */
    double heading; /* rad, counter-clockwise, wrapped to (-pi, pi] */
    int last_left;  /* encoder pulses at the previous update */
    int last_right;
} odometry;

static void odometry_update(odometry *pose, int left_pulses, int right_pulses)
{
    const double pi = 3.14159265358979323846;
    const double left = (double)(left_pulses - pose->last_left) * KHEPERA_METRES_PER_PULSE;
    const double right = (double)(right_pulses - pose->last_right) * KHEPERA_METRES_PER_PULSE;
    const double distance = 0.5 * (left + right);
    const double turn = (right - left) / KHEPERA_AXLE_LENGTH;
    const double middle = pose->heading + 0.5 * turn;
    pose->x += distance * cos(middle);
    pose->y += distance * sin(middle);
    pose->heading += turn;
    if (pose->heading > pi) {
        pose->heading -= 2.0 * pi;
    } else if (pose->heading <= -pi) {
        pose->heading += 2.0 * pi;
    }
    pose->last_left = left_pulses;
    pose->last_right = right_pulses;
}

/* Stops the wheels (and puts the policy's LEDs out); every call is tried. Returns 0, or -1 with
 * the failing call in `status`. */
static int stop_motors(knet_dev_t *ds_pic, khepera_status *status)
{
    int failed = khepera_stop_motors(ds_pic, status);
#if KHEPERA_LED_ACTION
    failed |= khepera_check(status, "kh4_SetRGBLeds",
                            kh4_SetRGBLeds(0, 0, 0, 0, 0, 0, 0, 0, 0, ds_pic));
#endif
    return failed;
}

/* The motor controller as the policy was trained (khepera_policy_config.h): K-Team's speed
 * profile, whose ramp the simulator follows exactly, or the speed mode. */
static int set_drive(knet_dev_t *ds_pic, khepera_status *status)
{
#if KHEPERA_MOTOR_PROFILE
    if (khepera_check(status, "kh4_SetSpeedProfile",
                      kh4_SetSpeedProfile(KHEPERA_ACC_INC, KHEPERA_ACC_DIV, KHEPERA_MIN_SPEED_ACC,
                                          KHEPERA_MIN_SPEED_DEC, KHEPERA_PROFILE_MAX_SPEED,
                                          ds_pic))
            != 0
        || khepera_check(status, "kh4_SetMode", kh4_SetMode(kh4RegSpeedProfile, ds_pic)) != 0) {
        return -1;
    }
    fprintf(stderr, "motors: speed profile, acc_inc %d, acc_div %d, min_speed_acc %d\n",
            KHEPERA_ACC_INC, KHEPERA_ACC_DIV, KHEPERA_MIN_SPEED_ACC);
#else
    if (khepera_check(status, "kh4_SetMode", kh4_SetMode(kh4RegSpeed, ds_pic)) != 0) {
        return -1;
    }
    fprintf(stderr, "motors: speed mode\n");
#endif
    return 0;
}

/* The end of a run stopped by a failing libkhepera call (`failure`): the motors stopped when
 * there is a device, the failure said and noted in the log, the log closed. Returns the exit
 * status, 1. */
static int stop_on_failure(knet_dev_t *ds_pic, const khepera_status *failure, khepera_log *log)
{
    char text[160];
    khepera_describe(failure, text, sizeof text);
    fprintf(stderr, "libkhepera: %s: stopping\n", text);
    khepera_log_note(log, "libkhepera_error", text);
    if (ds_pic != NULL) {
        khepera_status stop = {NULL, 0};
        if (stop_motors(ds_pic, &stop) != 0) {
            khepera_describe(&stop, text, sizeof text);
            fprintf(stderr, "libkhepera: %s while stopping the motors\n", text);
            khepera_log_note(log, "libkhepera_error", text);
        }
    }
    khepera_log_close(log);
    return 1;
}

int main(int argc, char *argv[])
{
    float goal[2] = {0.0f, 0.0f};
    long max_steps = 0;
    long step;
    odometry pose = {0.0, 0.0, 0.0, 0, 0};
    observation_inputs inputs;
    khepera_readings readings;
    float observation[OBSERVATION_DIM];
    float action[POLICY_ACTION_DIM];
    policy_state memory; /* a frame stack's observations, a recurrent policy's LSTM states */
#if KHEPERA_SAMPLE_ACTIONS
    policy_rng rng; /* the draws of sampled actions */
#endif
    int units[2];
#if KHEPERA_LED_ACTION
    int leds[3];
#endif
    const char *log_path = NULL;
    khepera_log log = {NULL, 0, 0, 0}; /* closed: notes and closing do nothing without --log */
    khepera_status status = {NULL, 0};
    char firmware[32] = "unknown";
    double start_time;
    double next_tick;
    knet_dev_t *ds_pic;

    /* --log FILE may come last; the other arguments are positional. */
    if (argc >= 5 && strcmp(argv[argc - 2], "--log") == 0) {
        log_path = argv[argc - 1];
        argc -= 2;
    }
    if (argc < 3 || argc > 4) {
        fprintf(stderr, "usage: %s GOAL_X GOAL_Y [MAX_STEPS] [--log FILE]   (metres, start frame)\n",
                argv[0]);
        return 2;
    }
    goal[0] = strtof(argv[1], NULL);
    goal[1] = strtof(argv[2], NULL);
    if (argc == 4) {
        max_steps = strtol(argv[3], NULL, 10);
    }
    memset(&readings, 0, sizeof readings);

    /* Open the link to the dsPIC that runs the motors and sensors (libkhepera), read its
     * firmware's revision, then open the log (also when one of these failed: it then records
     * which). */
    ds_pic = khepera_open(&status);
    if (ds_pic != NULL) {
        khepera_firmware(ds_pic, firmware, sizeof firmware, &status);
    }
    if (log_path != NULL) {
        khepera_log_header header;
        header.program = "policy";
        header.khepera_gym = KHEPERA_GYM_VERSION;
        header.env_id = KHEPERA_ENV_ID;
        header.firmware = firmware;
        header.control_period = KHEPERA_CONTROL_PERIOD_S;
        header.wheel_radius = KHEPERA_WHEEL_RADIUS;
        header.axle_length = KHEPERA_AXLE_LENGTH;
        header.motors = KHEPERA_MOTOR_PROFILE ? "profile" : "speed";
        header.acc_inc = KHEPERA_ACC_INC;
        header.acc_div = KHEPERA_ACC_DIV;
        header.min_speed_acc = KHEPERA_MIN_SPEED_ACC;
        header.min_speed_dec = KHEPERA_MIN_SPEED_DEC;
        header.gyro_samples = KHEPERA_IMU_SAMPLES;
        header.wall_distance = -1.0;
        if (khepera_log_open(&log, log_path, &header, OBSERVATION_DIM, POLICY_ACTION_DIM) != 0) {
            fprintf(stderr, "cannot write the log %s\n", log_path);
            if (ds_pic != NULL) {
                stop_motors(ds_pic, &status);
            }
            return 1;
        }
    }
    if (status.call != NULL) {
        return stop_on_failure(ds_pic, &status, &log);
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    /* Idle, the encoders at 0, the ultrasonic sensors the policy observes on (0: all off), the
     * drive, the start pose. */
    if (khepera_check(&status, "kh4_SetMode", kh4_SetMode(kh4RegIdle, ds_pic)) != 0
        || khepera_check(&status, "kh4_ResetEncoders", kh4_ResetEncoders(ds_pic)) != 0
        || khepera_check(&status, "kh4_activate_us", kh4_activate_us(KHEPERA_US_MASK, ds_pic)) != 0
        || set_drive(ds_pic, &status) != 0
        || khepera_check(&status, "kh4_get_position",
                         kh4_get_position(&pose.last_left, &pose.last_right, ds_pic))
            != 0) {
        return stop_on_failure(ds_pic, &status, &log);
    }

    policy_reset(&memory); /* the episode starts: nothing observed yet */
#if KHEPERA_SAMPLE_ACTIONS
    policy_rng_seed(&rng, KHEPERA_SAMPLE_SEED);
    fprintf(stderr, "actions: sampled from the policy's Gaussian, seed %llu\n",
            (unsigned long long)KHEPERA_SAMPLE_SEED);
#else
    fprintf(stderr, "actions: the policy's mean\n");
#endif
    start_time = khepera_clock_now();
    next_tick = start_time;
    for (step = 0; !stop_requested && (max_steps <= 0 || step < max_steps); ++step) {
        const double elapsed = khepera_clock_now() - start_time;

        /* 1. Sensors, in K-Team's units: those the observation needs, or all of them for the
         * log. */
        if (log_path != NULL) {
            khepera_read_all(ds_pic, &readings, KHEPERA_IMU_SAMPLES, &status);
        } else {
#if OBSERVATION_HAS_IR
            khepera_read_ir(ds_pic, &readings, &status);
#endif
#if OBSERVATION_HAS_US
            khepera_read_us(ds_pic, &readings, &status);
#endif
            khepera_read_motion(ds_pic, &readings, &status);
        }
        if (status.call != NULL) {
            return stop_on_failure(ds_pic, &status, &log);
        }
#if OBSERVATION_HAS_IR
        for (int i = 0; i < 8; ++i) {
            inputs.ir_raw[i] = (uint16_t)readings.ir[i];
        }
#endif
#if OBSERVATION_HAS_US
        for (int i = 0; i < 5; ++i) {
            inputs.us_cm[i] = (int16_t)readings.us[i];
        }
#endif
#if OBSERVATION_HAS_WHEEL_SPEEDS
        inputs.wheel_speeds[0] = wheel_units_to_speed(readings.speed[0]);
        inputs.wheel_speeds[1] = wheel_units_to_speed(readings.speed[1]);
#endif

        /* 2. Dead reckoning; the goal stays where it was given, in the start frame. */
        odometry_update(&pose, readings.encoder[0], readings.encoder[1]);
#if OBSERVATION_HAS_GOAL
        inputs.robot_pose[0] = (float)pose.x;
        inputs.robot_pose[1] = (float)pose.y;
        inputs.robot_pose[2] = (float)pose.heading;
        inputs.goal[0] = goal[0];
        inputs.goal[1] = goal[1];
        if (hypot(goal[0] - pose.x, goal[1] - pose.y) < KHEPERA_GOAL_RADIUS) {
            printf("goal reached (by odometry) after %ld steps\n", step);
            break;
        }
#else
        (void)goal; /* this task's observation has no goal */
#endif
#if OBSERVATION_EXTRA_INPUTS > 0
        /* TODO: this task's observation has inputs the robot cannot measure by itself (see
         * observation.h, e.g. the leader's offset in a formation): fill them here from your own
         * source (motion capture, radio). They are zero until you do. */
        observation_clear_extra_inputs(&inputs);
#endif

        /* 3. and 4. Observation, policy, wheel command. */
        observation_build(&inputs, observation);
#if KHEPERA_SAMPLE_ACTIONS
        if (policy_sample_step(&memory, &rng, observation, action) != 0) {
#else
        if (policy_step(&memory, observation, action) != 0) {
#endif
            fprintf(stderr, "non-finite action at step %ld: stopping\n", step);
            break;
        }
        wheel_command_units(action, units);
        if (khepera_check(&status, "kh4_set_speed", kh4_set_speed(units[0], units[1], ds_pic))
            != 0) {
            return stop_on_failure(ds_pic, &status, &log);
        }
        if (log_path != NULL) {
            khepera_log_row(&log, elapsed, "policy", units, &readings, observation, action);
        }
        printf("%ld %.4f %.4f %.4f %.4f %.4f %d %d", step, pose.x, pose.y, pose.heading,
               (double)action[0], (double)action[1], units[0], units[1]);
#if KHEPERA_LED_ACTION
        /* The three top LEDs (front left, front right, back) in the colour the policy asks. */
        led_command_levels(action + 2, leds);
        printf(" %d %d %d", leds[0], leds[1], leds[2]);
#endif
        printf("\n");
#if KHEPERA_LED_ACTION
        if (khepera_check(&status, "kh4_SetRGBLeds",
                          kh4_SetRGBLeds((char)leds[0], (char)leds[1], (char)leds[2],
                                         (char)leds[0], (char)leds[1], (char)leds[2],
                                         (char)leds[0], (char)leds[1], (char)leds[2], ds_pic))
            != 0) {
            return stop_on_failure(ds_pic, &status, &log);
        }
#endif

        next_tick += KHEPERA_CONTROL_PERIOD_S;
        khepera_clock_sleep_until(next_tick);
    }
    if (stop_motors(ds_pic, &status) != 0) {
        return stop_on_failure(ds_pic, &status, &log);
    }
    khepera_log_close(&log);
    return 0;
}
