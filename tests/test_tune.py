"""``khepera-gym tune`` (issue 52, item 4): its search space, its checks before any work, its
score's direction, and a tiny search on a Ray of its own that writes every trial and the best
table, scored on the training's evaluation seeds."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from khepera_gym import cli
from khepera_gym.errors import ConfigError
from khepera_gym.learning.benchmark import tune
from khepera_gym.learning.benchmark.aggregate import TaskMetric
from khepera_gym.learning.recipes import EVAL_SEED

pytest.importorskip("ray", reason="needs the rllib extra (Ray Tune)")
pytest.importorskip("stable_baselines3", reason="needs the sb3 extra")


def test_the_space_takes_ranges_logs_integers_and_choices() -> None:
    space = tune.parse_space(["learning_rate=1e-4:1e-3:log", "n_epochs=2:6:int", "gamma=0.9:0.99",
                              "batch_size=64,128"])  # fmt: skip
    assert space["learning_rate"].lower == 1e-4 and space["learning_rate"].upper == 1e-3
    assert space["n_epochs"].lower == 2 and space["n_epochs"].upper == 7  # HIGH included
    assert space["batch_size"].categories == [64, 128]
    for bad, message in [
        (["lr"], "KEY=LOW"),
        (["lr=1:0"], "LOW < HIGH"),
        (["lr=0:1:log"], "0 < LOW"),
        (["lr=1:2:cube"], "KEY=LOW:HIGH"),
        (["a=1:2", "a=3:4"], "twice"),
        ([], "at least one"),
    ]:
        with pytest.raises(ConfigError, match=message):
            tune.parse_space(bad)


def test_a_key_the_recipe_does_not_have_is_refused_with_the_nearest() -> None:
    with pytest.raises(ConfigError, match="did you mean 'n_steps'"):
        tune.tune_recipe("nav", "ppo", ["n_step=64,128"], 2, 2048)
    with pytest.raises(ConfigError, match="unknown learner 'ppoo'"):
        tune.tune_recipe("nav", "ppoo", ["n_steps=64,128"], 2, 2048)
    with pytest.raises(ConfigError, match="unknown task"):
        tune.tune_recipe("navv", "ppo", ["n_steps=64,128"], 2, 2048)


def test_the_score_is_higher_for_the_better_policy() -> None:
    success = TaskMetric("nav", "success", True)
    error = TaskMetric("track", "track_error_rms", False)
    assert tune.score(success, {"success": 0.9}) > tune.score(success, {"success": 0.5})
    assert tune.score(error, {"track_error_rms": 0.01}) > tune.score(
        error, {"track_error_rms": 0.1}
    )
    assert tune.score(error, {"track_error_rms": math.nan}) == -math.inf


def test_a_tiny_search_writes_every_trial_and_the_best_table(tmp_path: Path) -> None:
    # Trials are scored on the training's own evaluation episodes, which start above the
    # held-out seeds 0-199.
    assert EVAL_SEED >= 200
    out = tmp_path / "tune_nav.json"
    argv = ["tune", "--task", "nav", "--learner", "ppo", "--space", "n_epochs=1,2"]
    argv += ["--trials", "2", "--timesteps", "2048", "--hp", "n_envs=8", "--hp", "n_steps=128"]
    argv += ["--eval-episodes", "4", "--out", str(out)]
    assert cli.main(argv) == 0
    document = json.loads(out.read_text())
    assert len(document["trials"]) == 2 and all(not t["error"] for t in document["trials"])
    assert all(t["evaluations"] for t in document["trials"])
    assert document["best"]["config"] in [t["config"] for t in document["trials"]]
    best = document["best_table"]
    assert best["n_envs"] == 8 and best["n_steps"] == 128
    assert best["n_epochs"] == document["best"]["config"]["n_epochs"]
    assert document["meta"]["commit"] is not None and "10000" in document["evaluation_seeds"]
    # The results page shows the search, its best configuration and the shipped one.
    from khepera_gym.analysis.docgen.benchmark_reliable import tune_fragment

    page = tune_fragment(tmp_path)
    assert "**nav-v3, ppo**" in page.replace(f"v{document['version']}", "v3")
    assert f'best `{{"n_epochs": {document["best"]["config"]["n_epochs"]}}}`' in page
    assert "| n_epochs | evaluations | last score | mean score |" in page
    assert str(tmp_path) not in page
