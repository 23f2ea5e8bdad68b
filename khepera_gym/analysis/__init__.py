"""Analysis: run, measure and show what the envs and their policies do.

* ``khepera-gym compare`` and ``demo`` (:mod:`~khepera_gym.analysis.compare`): policies on the
  same seeded episodes, with tables, intervals and plots;
* ``khepera-gym bench`` (:mod:`~khepera_gym.analysis.throughput`, with the swarm rows of
  :mod:`~khepera_gym.analysis.swarm_throughput`): the simulator's speed and memory;
* :mod:`~khepera_gym.analysis.plots` (trajectories and reference plots) and ``khepera-gym
  render`` (:mod:`~khepera_gym.analysis.record`: a video of seeded episodes);
* :mod:`~khepera_gym.analysis.docgen`: the documentation's generated pages and results tables.

Layer: above the env library, :mod:`khepera_gym.tooling` and :mod:`khepera_gym.learning` (it
plays saved policies and shows the learning benchmark's results).
"""
