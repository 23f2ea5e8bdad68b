"""The vector-path results (benchmarks/simd_paths.py's file) as the results page shows them:
each path's median speed and its ratio to the first column, taken within each round."""

from __future__ import annotations

import json
from pathlib import Path

from khepera_gym.analysis.docgen.simd import simd_fragment, simd_section


def _document() -> dict:
    portable, avx2 = [1.0e6, 2.0e6, 1.5e6], [1.2e6, 2.1e6, 1.5e6]
    return {
        "simd_paths": 1,
        "meta": {
            "date": "2026-12-07T20:00:00",
            "commit": {"id": "a" * 40, "dirty": False},
            "machine": {"cpu": "Some CPU", "cpus": 2, "cpu_flags": {"avx2": True, "fma": True}},
            "command": "python -m benchmarks.simd_paths --out x.json",
        },
        "columns": ["portable", "avx2"],
        "reference": "portable",
        "settings": {"rounds": 3, "duration": 1.0, "num_envs": [1024], "threads": [2]},
        "rows": [
            {
                "configuration": "make_vec n=1024 t=2",
                "columns": {
                    "portable": {"rounds": portable, "median": 1.5e6, "min": 1e6, "max": 2e6},
                    "avx2": {"rounds": avx2, "median": 1.5e6, "min": 1.2e6, "max": 2.1e6},
                },
                "ratios": {
                    "avx2": {"rounds": [1.2, 1.05, 1.0], "median": 1.05, "min": 1.0, "max": 1.2}
                },
            }
        ],
    }


def test_a_path_shows_its_median_and_its_ratio_within_rounds() -> None:
    page = simd_section(_document())
    assert "| configuration | portable | × avx2 |" in page
    # The medians of the speeds are equal (1.50M) while the ratio taken round by round is not.
    assert "| make_vec n=1024 t=2 | 1.50M | 1.05 (1.00–1.20) |" in page
    assert "Vector extensions: AVX2, FMA." in page and "commit `aaaaaaaaaa`" in page


def test_the_folder_without_a_file_says_how_to_make_one(tmp_path: Path) -> None:
    assert "python -m benchmarks.simd_paths" in simd_fragment(tmp_path)
    (tmp_path / "simd_paths_2026-12-07.json").write_text(json.dumps(_document()))
    assert "1.05 (1.00–1.20)" in simd_fragment(tmp_path)
