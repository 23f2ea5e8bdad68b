/* export_check.c: runs the exported C code on rows of numbers read from standard input, so that
 * it can be compared with the Python policy and the simulator (khepera_gym's tests do; you can
 * too, on a PC or on the robot, with rows recorded in the simulator).
 *
 *   export_check policy      rows of POLICY_OBS_DIM observation values  -> rows of actions
 *                            (each from a fresh policy state: policy_forward)
 *   export_check sequence    rows of 1 + POLICY_OBS_DIM values: a flag (1 when an episode starts
 *                            with this observation) and the observation -> rows of actions, one
 *                            policy_step each (the memory of a frame-stacked policy carries over)
 *   export_check sample SEED as sequence, but each action sampled from the policy's Gaussian
 *                            (policy_sample_step, the draws seeded with SEED): only for a policy
 *                            exported with its noise (POLICY_SAMPLES 1)
 *   export_check observation rows of OBSERVATION_INPUT_COUNT raw inputs -> rows of observations
 *                            (the fields of observation_inputs in order: observation.h)
 *   export_check wheels      rows of 2 action values -> rows of 2 kh4_set_speed units
 *   export_check leds        rows of 3 LED action values -> rows of 3 kh4_SetRGBLeds levels
 *
 * Numbers are whitespace-separated; outputs are printed with 9 significant digits (exact for
 * float32). Exit status: 0, or 1 on malformed input or a non-finite action.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "observation.h"
#include "policy.h"
#include "wheel_command.h"

/* Reads `count` floats; returns 1 on success, 0 at a clean end of input, -1 on a partial row. */
static int read_row(float *row, int count)
{
    int i;
    for (i = 0; i < count; ++i) {
        if (scanf("%f", &row[i]) != 1) {
            return i == 0 && feof(stdin) ? 0 : -1;
        }
    }
    return 1;
}

static void print_row(const float *row, int count)
{
    int i;
    for (i = 0; i < count; ++i) {
        printf(i + 1 < count ? "%.9g " : "%.9g\n", (double)row[i]);
    }
}

static int check_policy(void)
{
    float observation[POLICY_OBS_DIM];
    float action[POLICY_ACTION_DIM];
    int status = 0;
    int read;
    while ((read = read_row(observation, POLICY_OBS_DIM)) == 1) {
        if (policy_forward(observation, action) != 0) {
            status = 1;
        }
        print_row(action, POLICY_ACTION_DIM);
    }
    return read < 0 ? 1 : status;
}

#if POLICY_SAMPLES
/* The draws of `export_check sample SEED`; NULL for `sequence`. */
static policy_rng *sample_draws = NULL;
#endif

static int check_sequence(void)
{
    float row[1 + POLICY_OBS_DIM];
    float action[POLICY_ACTION_DIM];
    policy_state state;
    int status = 0;
    int read;
    policy_reset(&state);
    while ((read = read_row(row, 1 + POLICY_OBS_DIM)) == 1) {
        int failed;
        if (row[0] != 0.0f) {
            policy_reset(&state);
        }
#if POLICY_SAMPLES
        failed = sample_draws != NULL
                     ? policy_sample_step(&state, sample_draws, row + 1, action)
                     : policy_step(&state, row + 1, action);
#else
        failed = policy_step(&state, row + 1, action);
#endif
        if (failed != 0) {
            status = 1;
        }
        print_row(action, POLICY_ACTION_DIM);
    }
    return read < 0 ? 1 : status;
}

static int check_observation(void)
{
    float row[OBSERVATION_INPUT_COUNT];
    float observation[OBSERVATION_DIM];
    observation_inputs inputs;
    int read;
    while ((read = read_row(row, OBSERVATION_INPUT_COUNT)) == 1) {
        observation_inputs_from_row(row, &inputs);
        observation_build(&inputs, observation);
        print_row(observation, OBSERVATION_DIM);
    }
    return read < 0 ? 1 : 0;
}

static int check_wheels(void)
{
    float action[2];
    int units[2];
    int read;
    while ((read = read_row(action, 2)) == 1) {
        wheel_command_units(action, units);
        printf("%d %d\n", units[0], units[1]);
    }
    return read < 0 ? 1 : 0;
}

static int check_leds(void)
{
    float action[3];
    int levels[3];
    int read;
    while ((read = read_row(action, 3)) == 1) {
        led_command_levels(action, levels);
        printf("%d %d %d\n", levels[0], levels[1], levels[2]);
    }
    return read < 0 ? 1 : 0;
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "policy") == 0) {
        return check_policy();
    }
    if (argc == 2 && strcmp(argv[1], "sequence") == 0) {
        return check_sequence();
    }
    if (argc == 3 && strcmp(argv[1], "sample") == 0) {
#if POLICY_SAMPLES
        policy_rng draws;
        policy_rng_seed(&draws, (uint64_t)strtoull(argv[2], NULL, 10));
        sample_draws = &draws;
        return check_sequence();
#else
        fprintf(stderr, "this policy was exported without its action noise\n");
        return 2;
#endif
    }
    if (argc == 2 && strcmp(argv[1], "observation") == 0) {
        return check_observation();
    }
    if (argc == 2 && strcmp(argv[1], "wheels") == 0) {
        return check_wheels();
    }
    if (argc == 2 && strcmp(argv[1], "leds") == 0) {
        return check_leds();
    }
    fprintf(stderr, "usage: %s policy|sequence|sample SEED|observation|wheels|leds < rows.txt\n",
            argv[0]);
    return 2;
}
