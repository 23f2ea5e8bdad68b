/* policy.h: a trained policy network as plain C99.
 * The $source policy exported by khepera_gym $version
 * from $provenance. Generated: export again rather than edit.
 *
 * The policy acts on its last POLICY_FRAME_STACK observations (1: the current one only), each
 * normalised as it arrives, oldest first, as it was trained; a recurrent policy
 * (POLICY_LSTM_LAYERS > 0) also carries its LSTM layers' hidden and cell states from step to
 * step. Run it with a policy_state:
 *
 *   policy_state state;
 *   policy_reset(&state);                          once, before an episode's first observation
 *   policy_step(&state, observation, action);      every control period
 *
 * policy_forward(observation, action) is policy_step on a fresh state: the action of an
 * episode's first observation; for a policy without memory (POLICY_FRAME_STACK 1,
 * POLICY_LSTM_LAYERS 0), the action of any observation. Observations are as the simulator gives
 * them (observation.h builds them on the robot). No allocation; libm for tanhf/expf (and sqrt,
 * log, cos for sampled actions) only.
 * They return 0, or -1 if an action value is not finite.
 */
#ifndef KHEPERA_GYM_POLICY_H
#define KHEPERA_GYM_POLICY_H

#include <stdint.h>

#define POLICY_OBS_DIM $obs_dim
#define POLICY_FRAME_STACK $frame_stack
#define POLICY_ACTION_DIM $action_dim
/* A recurrent policy's LSTM layers and the width of their hidden and cell states (0: none). */
#define POLICY_LSTM_LAYERS $lstm_layers
#define POLICY_LSTM_HIDDEN $lstm_hidden

/* The policy's memory: its last POLICY_FRAME_STACK normalised observations, oldest first
 * (zeros before the episode's first one), and a recurrent policy's LSTM states. */
typedef struct {
    float frames[POLICY_FRAME_STACK * POLICY_OBS_DIM];
$lstm_state} policy_state;

void policy_reset(policy_state *state);
int policy_step(policy_state *state, const float observation[POLICY_OBS_DIM],
                float action[POLICY_ACTION_DIM]);
int policy_forward(const float observation[POLICY_OBS_DIM], float action[POLICY_ACTION_DIM]);

$sampling_api

#endif /* KHEPERA_GYM_POLICY_H */
