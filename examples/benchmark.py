"""Throughput of the Nav task: env-steps/s of the native vector env and one env; memory per world.

Usage: ``python examples/benchmark.py [--quick]`` (or ``khepera-gym bench``, ``make bench``).
The logic lives in :mod:`khepera_gym.analysis.throughput`.
"""

from khepera_gym.analysis.throughput import main

if __name__ == "__main__":
    raise SystemExit(main())
