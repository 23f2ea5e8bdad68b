"""Learning: train agents on the envs and measure them against the baselines.

* the adapters: :mod:`~khepera_gym.learning.sb3` (an SB3 ``VecEnv`` over the Rust batch, saved
  policies), :mod:`~khepera_gym.learning.rllib`, :mod:`~khepera_gym.learning.torchrl` and
  :mod:`~khepera_gym.learning.torchrl.benchmarl`;
* ``khepera-gym train`` (:mod:`~khepera_gym.learning.train`) and the shipped recipes
  (:mod:`~khepera_gym.learning.recipes`, the tables of ``configs/hyperparams/``);
* ``khepera-gym benchmark`` (:mod:`~khepera_gym.learning.benchmark`);
* :mod:`~khepera_gym.learning.policies`: what a ``--policy`` argument names (a baseline, a saved
  model, a user's function), for every tool that plays policies.

Each adapter needs its extra (``sb3``, ``rllib``, ``torchrl``, ``benchmarl``); importing this
package imports none of them. Layer: above the env library and :mod:`khepera_gym.tooling`; it
imports no other tool family (``docs/architecture.md`` draws the edges).
"""
