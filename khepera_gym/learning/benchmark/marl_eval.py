"""The benchmark's runs in marl-eval's JSON format (Gorsane et al., NeurIPS 2022; the format
BenchMARL writes), so that the field's plotting tools read them: ``marl_eval.json`` beside the
``runs/`` folder, rewritten after every run.

The format (marl-eval's README, "Data Structure for Raw Experiment data"):
``{environment: {task: {algorithm: {run: {"step_<k>": {"step_count": int, metric: [values]},
..., "absolute_metrics": {metric: [values]}}}}}}``. Here the environment is ``khepera_gym``, a
task is ``<task>-v<version>``, an algorithm is a learner of the suite, a run is
``seed_<training seed>``; the steps are the run's evaluations during training (``history``: each
metric a one-element list, its mean over the evaluation episodes, as marl-eval allows for a
metric computed over several episodes) and ``absolute_metrics`` the held-out evaluation of the
final policy (each metric a one-element list: its mean over the held-out episodes). A metric
without a value at a step (no episode ended) is left out of that step.

marl-eval aggregates only data with the same number of runs and steps for every algorithm and
task; a suite whose learners ran different numbers of seeds is written as it ran.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

#: The file, in a benchmark's results folder.
MARL_EVAL_FILE = "marl_eval.json"
#: The environment's name in the file.
ENVIRONMENT = "khepera_gym"


def _metrics(values: Mapping[str, Any]) -> dict[str, list[float]]:
    found = {}
    for name, value in values.items():
        if isinstance(value, Mapping):  # a summary: {"value", "low", "high", "n"}
            value = value.get("value")
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if number and math.isfinite(value):
            found[name] = [float(value)]
    return found


def marl_eval_document(runs: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The marl-eval document of a benchmark's run records (``runs/*.json``)."""
    tasks: dict[str, Any] = {}
    ordered = sorted(runs, key=lambda r: (r["key"]["task"], r["key"]["learner"], r["key"]["seed"]))
    for run in ordered:
        key = run["key"]
        task = f"{key['task']}-v{key['version']}"
        record: dict[str, Any] = {}
        for index, point in enumerate(run.get("history") or [], start=1):
            record[f"step_{index}"] = {
                "step_count": int(point["steps"]),
                **_metrics(point["means"]),
            }
        record["absolute_metrics"] = _metrics(run.get("final") or {})
        algorithm = tasks.setdefault(task, {}).setdefault(key["learner"], {})
        algorithm[f"seed_{key['seed']}"] = record
    return {ENVIRONMENT: tasks}


def write_marl_eval(out: Path, runs: Sequence[Mapping[str, Any]]) -> Path:
    """Writes ``out/marl_eval.json`` from the folder's run records (``runs/*.json``)."""
    path = out / MARL_EVAL_FILE
    text = json.dumps(marl_eval_document(runs), indent=1, allow_nan=False) + "\n"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    return path


__all__ = ["ENVIRONMENT", "MARL_EVAL_FILE", "marl_eval_document", "write_marl_eval"]
