"""Benchmark-only code of the repository, outside the wheel (pyproject.toml's [tool.maturin]
ships only ``khepera_gym/``): run from the checkout's root, e.g.
``python -m benchmarks.peers.compare_peers``."""
