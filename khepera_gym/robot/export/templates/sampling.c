
/* Sampled actions (policy.h): the Gaussian's σ around the action before its clip, as trained
 * (exp of the model's log_std). */
static const float POLICY_ACTION_STD[POLICY_ACTION_DIM] = {$action_std};

void policy_rng_seed(policy_rng *rng, uint64_t seed)
{
    rng->state = seed;
}

/* splitmix64 (Steele, Lea and Flood, "Fast splittable pseudorandom number generators", OOPSLA
 * 2014): a Weyl sequence through a 64-bit mixing function. */
static uint64_t next_bits(policy_rng *rng)
{
    uint64_t z = (rng->state += UINT64_C(0x9E3779B97F4A7C15));
    z = (z ^ (z >> 30)) * UINT64_C(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)) * UINT64_C(0x94D049BB133111EB);
    return z ^ (z >> 31);
}

/* A standard normal draw by the Box-Muller transform of two uniform draws of 53 bits. */
static double standard_normal(policy_rng *rng)
{
    const double u1 = (double)((next_bits(rng) >> 11) + 1) * 0x1.0p-53; /* (0, 1] */
    const double u2 = (double)(next_bits(rng) >> 11) * 0x1.0p-53;       /* [0, 1) */
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

int policy_sample_step(policy_state *state, policy_rng *rng,
                       const float observation[POLICY_OBS_DIM], float action[POLICY_ACTION_DIM])
{
    int i;
    policy_output(state, observation, action);
    for (i = 0; i < POLICY_ACTION_DIM; ++i) {
        action[i] = (float)((double)action[i] + (double)POLICY_ACTION_STD[i] * standard_normal(rng));
    }
    clip_action(action);
    return finite_action(action);
}
