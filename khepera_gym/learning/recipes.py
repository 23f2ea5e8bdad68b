"""The hyperparameter files of ``khepera-gym train``, shared by its backends (stable-baselines3 in
:mod:`khepera_gym.learning.train`, Ray RLlib in :mod:`khepera_gym.learning.rllib`).

A file is ``configs/hyperparams/<name>.toml`` (``ppo``, ``sac``, ``rllib_ppo``) with one table
per env id, as rl-zoo3's files; ``--hp KEY=VALUE`` overrides a key with a TOML value. Evaluation
episodes of every backend are seeded from :data:`EVAL_SEED`.

This module reads files only (no simulation, no threads).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from khepera_gym.config import parse_key_values
from khepera_gym.errors import ConfigError

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10: tomli, a dependency there
    import tomli as tomllib

#: Folder of the hyperparameter files in a source checkout (``configs/hyperparams``).
HYPERPARAMS_DIR = Path(__file__).resolve().parents[2] / "configs" / "hyperparams"
#: Seed of the first evaluation episode; evaluation episodes are seeded EVAL_SEED + i, away from
#: the training worlds' seeds (``--seed`` + i).
EVAL_SEED = 10_000


def load_hyperparams(algo: str, env_id: str, path: str | Path | None = None) -> dict[str, Any]:
    """The hyperparameter table of ``env_id`` in an algorithm's TOML file.

    Args:
        algo: "ppo", "sac" or "rllib_ppo"; names the default file
            ``configs/hyperparams/<algo>.toml``.
        env_id: The table's name (a registered id such as "KheperaIV-Nav-v3", or another
            table such as "formation_v3-followers"); a table named without the version
            ("KheperaIV-Nav") serves every version, one named with a version
            ("KheperaIV-Avoid-v2" → v2) that version and the later ones until a table of a later
            version.
        path: Another TOML file to read instead.

    Raises:
        ConfigError: The file is missing or unreadable, or has no table for ``env_id``.
    """
    file = Path(path) if path is not None else HYPERPARAMS_DIR / f"{algo}.toml"
    try:
        tables = tomllib.loads(file.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(
            f"{file}: hyperparameter file not found (installed from a wheel? pass "
            "--hyperparams FILE; the repository's configs/hyperparams/ has examples)"
        ) from None
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise ConfigError(f"{file}: cannot read hyperparameters: {error}") from None
    # A table named without the version ("KheperaIV-Nav", "formation-followers") serves every
    # version of the env; one named with a version ("KheperaIV-Avoid-v2") wins for that version
    # and the later ones, until a table of a later version.
    unversioned = re.sub(r"[-_]v\d+(?=$|-)", "", env_id)
    name = env_id if env_id in tables else unversioned
    match = re.search(r"[-_]v(\d+)(?=$|-)", env_id)
    if env_id not in tables and match is not None:
        version = int(match.group(1))
        for earlier in range(version - 1, -1, -1):
            candidate = env_id[: match.start(1)] + str(earlier) + env_id[match.end(1) :]
            if candidate in tables:
                name = candidate
                break
    if name not in tables:
        raise ConfigError(
            f"{file}: no table [{env_id!r}] or [{unversioned!r}]; tables: {sorted(tables)}"
        )
    table = tables[name]
    if not isinstance(table, dict):
        raise ConfigError(f"{file}: [{name!r}] must be a table")
    return dict(table)


def parse_override(text: str) -> tuple[str, Any]:
    """``"KEY=VALUE"`` with VALUE in TOML syntax (``n_steps=64``, ``learning_rate="lin_1e-3"``,
    ``policy_kwargs={net_arch=[32, 32]}``); a VALUE that is not TOML is taken as a string.

    Raises:
        ConfigError: No ``=`` or an empty key.
    """
    ((key, value),) = parse_key_values([text], "--hp").items()
    return key, value


__all__ = ["EVAL_SEED", "HYPERPARAMS_DIR", "load_hyperparams", "parse_override"]


def check_rollout_shape(
    env_id: str, worlds: int, hyperparams: Mapping[str, Any], table_worlds: Any = None
) -> None:
    """Refuses a PPO-style rollout (``n_envs`` x ``n_steps`` env steps) that the table's
    ``batch_size`` does not divide: SB3 would train on a truncated last minibatch and warn, and
    the recipe's shape (``--n-envs`` changed it) would not be what its table says.

    Raises:
        ConfigError: The rollout is not a multiple of ``batch_size``; the message names the
            settings that fit.
    """
    if "n_steps" not in hyperparams or "batch_size" not in hyperparams:
        return
    steps, batch = int(hyperparams["n_steps"]), int(hyperparams["batch_size"])
    rollout = worlds * steps
    if batch < 1 or rollout % batch == 0:
        return
    fitting_steps = -(-batch // worlds)
    while worlds * fitting_steps % batch:
        fitting_steps += 1
    hint = f"the table's {table_worlds} worlds (no --n-envs), " if table_worlds else ""
    raise ConfigError(
        f"{env_id}: {worlds} worlds x n_steps {steps} = {rollout} env steps a rollout, which "
        f"batch_size {batch} does not divide; train with {hint}or --hp n_steps={fitting_steps}, "
        f"or a batch_size that divides {rollout} (--hp batch_size=...)"
    )
