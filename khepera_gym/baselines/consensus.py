"""The consensus baseline for the consensus task, every version (docs/task-design.md §8): the
consensus law on what the neighbours broadcast, with periodic or event-triggered messages (the
scenario's ``consensus.trigger``). Units: metres, seconds; robot frame x forward, y left."""

from __future__ import annotations

from typing import Any, ClassVar

from khepera_gym.baselines.base import BaselinePolicy


class ConsensusLaw(BaselinePolicy):
    r"""The consensus law on the last messages of the neighbours (Dimarogonas, Frazzoli &
    Johansson, IEEE TAC 57(5), 2012, eq. 3).

    With :math:`\hat x_j` neighbour j's last message, :math:`\hat x_i` the robot's own last
    broadcast and :math:`c` the formation offsets,
    :math:`u_i = -k \sum_{j \in N_i} \big((\hat x_i - c_i) - (\hat x_j - c_j)\big)`, that is
    :math:`k \sum_j (p_j - d)` in the observation's terms (``neighbours`` slots p_j with
    valid = 1, ``own_drift`` d). A point ``offset`` ahead of the axle follows u (v = u_x,
    ω = u_y / offset, |u| ≤ ``vmax``); below ``deadband`` the robot stops. With ``avoid``,
    Braitenberg avoidance on the IR ring is added, so robots crossing to their places steer
    round one another: keep it for formations, turn it off for a rendezvous (where the robots
    must come into contact).

    The two baselines of consensus are this law with ``consensus.trigger = "periodic"``
    (every ``period``) and with ``"event"`` (when the estimate moved ``threshold`` from the last
    broadcast): the trigger is the robots' radio firmware, set in the scenario.
    ``ConsensusLaw.for_env(env)`` reads any number of robots; without it the policy reads the
    default 4-robot observation.
    """

    CONTROLLER: ClassVar[str] = "consensus"
    #: consensus is PettingZoo-only: ``khepera-gym compare --task consensus`` runs this law.
    COMPARABLE: ClassVar[bool] = False

    @classmethod
    def for_env(cls, env: Any, **params: Any) -> BaselinePolicy:
        """The law reading one agent's observation of ``env`` (a ``consensus_v3`` parallel env
        or a :class:`khepera_gym.pettingzoo.arrays.MultiAgentArrayEnv` of task "consensus")."""
        layouts = getattr(getattr(env, "unwrapped", env), "agent_layouts", None)
        if layouts is None:
            return cls(layout=env, **params)
        return cls(layout=next(iter(layouts().values())), **params)
