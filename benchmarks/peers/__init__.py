"""khepera_gym beside its peers (issue 54): the same Khepera IV scene as a VMAS scenario
(:mod:`benchmarks.peers.vmas_khepera`) and as a hand-vectorised NumPy env
(:mod:`benchmarks.peers.numpy_khepera`), and the interleaved throughput run that compares them
with khepera_gym's native vector env (:mod:`benchmarks.peers.compare_peers`). See README.md."""
