/* Sampled actions, as the policy acted while it trained: the network's action before its clip,
 * plus Gaussian noise of the trained σ (policy.c's POLICY_ACTION_STD), then the clip. The draws
 * come from a policy_rng of its own (splitmix64, Box-Muller): the same seed gives the same
 * actions.
 *
 *   policy_rng rng;
 *   policy_rng_seed(&rng, 0);                                 once
 *   policy_sample_step(&state, &rng, observation, action);   instead of policy_step
 */
#define POLICY_SAMPLES 1

typedef struct {
    uint64_t state;
} policy_rng;

void policy_rng_seed(policy_rng *rng, uint64_t seed);
int policy_sample_step(policy_state *state, policy_rng *rng,
                       const float observation[POLICY_OBS_DIM], float action[POLICY_ACTION_DIM]);