"""The documentation's pictures: an animation of a baseline on every env page, and the overview
picture of the front page and the README (the paper's Fig. 6 and Fig. 7 scenes and a swarm).

``python -m khepera_gym.analysis.docgen.pictures [--docs docs] [--task nav ...]`` runs, for every
task with a page (:func:`khepera_gym.analysis.docgen.envs.env_pages`), its baselines on seeded
episodes of the latest id or PettingZoo module, picks the first (seed, baseline) whose episode
succeeds (the first baseline on seed 0 for a task without success), records that episode with trails
and writes ``docs/images/envs/<task>.gif`` and its entry in ``animations.json`` (id, policy, seed,
steps, the commit and date it was made at). Frames are small and sampled so that a GIF stays
within a few hundred kilobytes and about ten seconds. Nothing is listed by hand: a new task gets
its animation from its page and its baselines.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from PIL import Image

from khepera_gym import _core, registry
from khepera_gym.analysis.docgen.envs import ANIMATIONS, EnvPage, baselines, env_pages
from khepera_gym.baselines import BaselinePolicy
from khepera_gym.config import make_batch
from khepera_gym.learning.policies import BatchView, on_every_agent
from khepera_gym.tooling.provenance import commit, provenance

#: Side of an animation's frames (pixels).
FRAME_SIZE = 168
#: Frames an animation keeps at most (the episode is sampled to fit).
MAX_FRAMES = 72
#: Display time of a frame (ms).
FRAME_MS = 120
#: Seeds tried for a successful episode.
SEEDS = range(8)
#: Episodes longer than this are cut (steps).
MAX_STEPS = 1600

Frame = npt.NDArray[np.uint8]


def _version_of(page: EnvPage) -> int:
    return int(page.ids[-1].rsplit("-v", 1)[1]) if page.ids else page.modules[-1].version


def _label(page: EnvPage) -> str:
    return page.ids[-1] if page.ids else f"{page.modules[-1].name}.parallel_env()"


def _make_policy(
    cls: type[BaselinePolicy], batch: _core.Batch
) -> Callable[[npt.NDArray[np.float32]], npt.NDArray[np.float32]]:
    """The baseline as its ``for_env`` builds it for the batch's scenario (a LeaderFollower
    takes the formation's shape from it), on the joint observation when it reads all of it
    (Formation's followers), else on every agent's block (every agent of a default scenario has
    the first one's layout)."""
    return on_every_agent(cls.for_env(BatchView(batch)), batch)


def episode(
    page: EnvPage, cls: type[BaselinePolicy], seed: int, frames: bool
) -> tuple[bool, int, list[Frame]]:
    """One seeded episode of a baseline on the page's latest env: (success, steps, frames)."""
    batch = make_batch(
        page.task, 1, None, {"version": _version_of(page)}, num_threads=1, autoreset=False
    )
    act = _make_policy(cls, batch)
    if frames:
        batch.set_trail_length(400)
    observation = batch.reset(seed)
    recorded = [batch.render(0, FRAME_SIZE, FRAME_SIZE)] if frames else []
    steps = 0
    success = False
    while steps < MAX_STEPS:
        observation, _, terminated, truncated = batch.step(np.ascontiguousarray(act(observation)))
        steps += 1
        if frames:
            recorded.append(batch.render(0, FRAME_SIZE, FRAME_SIZE))
        if terminated[0] or truncated[0]:
            success = bool(batch.episode_stats()["success"][0])
            break
    return success, steps, recorded


def choose(page: EnvPage) -> tuple[type[BaselinePolicy], int, bool]:
    """The first (baseline, seed) whose episode succeeds, else the first baseline on seed 0."""
    classes = baselines(page.task)
    for seed in SEEDS:
        for cls in classes:
            if episode(page, cls, seed, frames=False)[0]:
                return cls, seed, True
    return classes[0], 0, False


def save_gif(frames: Sequence[Frame], path: Path) -> None:
    """Frames sampled to at most :data:`MAX_FRAMES` (the last kept), as a looping GIF."""
    stride = max(1, math.ceil(len(frames) / MAX_FRAMES))
    kept = list(frames[::stride])
    if len(frames) > 1 and (len(frames) - 1) % stride:
        kept.append(frames[-1])
    images = [
        Image.fromarray(frame).quantize(colors=32, method=Image.Quantize.MEDIANCUT)
        for frame in kept
    ]
    durations = [FRAME_MS] * (len(images) - 1) + [1500]
    path.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(
        path, save_all=True, append_images=images[1:], duration=durations, loop=0, optimize=True
    )


def make_animation(page: EnvPage, docs_dir: Path) -> dict[str, Any]:
    """Records the page's animation; returns its ``animations.json`` entry."""
    cls, seed, success = choose(page)
    _, steps, frames = episode(page, cls, seed, frames=True)
    name = f"{page.task}.gif"
    save_gif(frames, docs_dir / ANIMATIONS / name)
    seconds = steps * 0.05
    speed = max(1.0, seconds * 1000 / (min(len(frames), MAX_FRAMES) * FRAME_MS))
    outcome = "reaches its goal" if success else "one episode"
    made = commit()
    return {
        "file": name,
        "env": _label(page),
        "version": _version_of(page),
        "policy": cls.__name__,
        "seed": seed,
        "steps": steps,
        "caption": (
            f"`{cls.__name__}` on `{_label(page)}`, seed {seed}: {outcome} in {steps} steps "
            f"({seconds:.1f} s), shown at about {speed:.0f}× speed."
        ),
        "commit": made["id"] if made else None,
        "date": provenance()["date"][:10],
    }


def overview(docs_dir: Path) -> Path:
    """The front page's picture: the paper's Fig. 6 and Fig. 7 scenes (v0, the paper's
    dynamics) and the ``swarm`` scene, each at the end of a baseline's episode, side by side."""
    from khepera_gym.baselines import Braitenberg, LeaderFollower

    panels = []
    for task, config, policy_class, steps in (
        ("avoid", "paper_fig6", Braitenberg, 400),
        ("formation", "paper_fig7", LeaderFollower, 400),
        ("multinav", "swarm", Braitenberg, 60),
    ):
        version = 0 if config.startswith("paper") else registry.LATEST_VERSION
        batch = make_batch(task, 1, config, {"version": version}, num_threads=1, autoreset=False)
        batch.set_trail_length(min(steps, 400))
        act = _make_policy(policy_class, batch)
        observation = batch.reset(0)
        for _ in range(steps):
            observation, _, terminated, truncated = batch.step(act(observation))
            if terminated[0] or truncated[0]:
                break
        panels.append(batch.render(0, 360, 360))
    gap = np.full((360, 8, 3), 255, dtype=np.uint8)
    picture = np.concatenate([panels[0], gap, panels[1], gap, panels[2]], axis=1)
    path = docs_dir / "images" / "overview.png"
    Image.fromarray(picture).quantize(colors=128).save(path, optimize=True)
    return path


def main(argv: Sequence[str] | None = None) -> int:
    """Makes the animations (all, or ``--task``'s) and the overview picture."""
    parser = argparse.ArgumentParser(prog="python -m khepera_gym.analysis.docgen.pictures")
    parser.add_argument("--docs", type=Path, default=Path("docs"), help="the docs folder")
    parser.add_argument("--task", nargs="*", default=None, help="only these tasks' animations")
    parser.add_argument("--no-overview", action="store_true", help="skip the overview picture")
    args = parser.parse_args(argv)
    index_path = args.docs / ANIMATIONS / "animations.json"
    index = json.loads(index_path.read_text(encoding="utf-8")) if index_path.is_file() else {}
    for page in env_pages():
        if args.task and page.task not in args.task:
            continue
        index[page.task] = make_animation(page, args.docs)
        size = (args.docs / ANIMATIONS / index[page.task]["file"]).stat().st_size
        print(f"{page.task}: {index[page.task]['caption']} ({size / 1024:.0f} KiB)", flush=True)
    index_path.parent.mkdir(parents=True, exist_ok=True)
    index_path.write_text(json.dumps(index, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    if not args.no_overview:
        print(f"wrote {overview(args.docs)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
