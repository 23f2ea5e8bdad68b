/* policy.h: a trained policy network as plain C99.
 * The $source policy exported by khepera_gym $version
 * from $provenance. Generated: export again rather than edit.
 *
 * policy_forward(observation, action): the deterministic action for one observation as the
 * simulator gives it (observation.h builds it on the robot). No allocation, no state; libm for
 * tanhf/expf only. Returns 0, or -1 if an action value is not finite.
 */
#ifndef KHEPERA_GYM_POLICY_H
#define KHEPERA_GYM_POLICY_H

#define POLICY_OBS_DIM $obs_dim
#define POLICY_ACTION_DIM $action_dim

int policy_forward(const float observation[POLICY_OBS_DIM], float action[POLICY_ACTION_DIM]);

#endif /* KHEPERA_GYM_POLICY_H */
