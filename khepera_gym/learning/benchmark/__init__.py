"""The learning benchmark: a learned result for every task, beside its classical baselines.

``khepera-gym benchmark`` (:mod:`khepera_gym.learning.benchmark.command`) trains each task's
learners (:mod:`~khepera_gym.learning.benchmark.learners`: stable-baselines3's PPO and SAC on the
Gymnasium envs, a PPO shared by the agents of a multi-agent task, BenchMARL's MAPPO and IPPO) over
several seeds, with the recipes of ``configs/hyperparams/``, and evaluates every run on held-out
episodes beside the baselines the suite names (:mod:`~khepera_gym.learning.benchmark.runner`). Each
task has a criterion, written in ``configs/benchmark.toml``
(:mod:`~khepera_gym.learning.benchmark.suite`), that says when it is solved: success, an error or a
share held to a number or to a baseline's mean on the same episodes. The tables
(:mod:`~khepera_gym.learning.benchmark.tables`) report, per task and learner, the held-out means
over seeds with 95 % intervals, the seeds that met the criterion and the training time and steps to
meet it. With ``--ray`` the runs are Ray tasks on a cluster, their results written to the same
folder (:mod:`~khepera_gym.learning.benchmark.cluster`).

Needs the ``sb3`` extra (stable-baselines3, torch); ``mappo`` and ``ippo`` the ``benchmarl``
extra. Training runs are benchmarks, not tests: the tests run the wiring on tiny budgets.
"""

from khepera_gym.learning.benchmark.learners import LEARNERS, learner
from khepera_gym.learning.benchmark.suite import Condition, TaskEntry, load_suite

__all__ = ["LEARNERS", "Condition", "TaskEntry", "learner", "load_suite"]
