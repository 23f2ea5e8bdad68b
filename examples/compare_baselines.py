"""The paper's controllers compared on the same seeded episodes: the README's tables and figures.

Usage: ``python examples/compare_baselines.py [--episodes 200] [--fig6-episodes 20]
[--out compare_out] [--docs docs]``. Runs, with :func:`khepera_gym.compare.compare`:

1. the paper's Fig. 6 scene (``config="paper_fig6"``): Braitenberg vs VFH (and position control
   alone), and how much each turns (total heading change, turn-direction reversals: the paper
   says VFH zigzags);
2. the paper's Fig. 7 scene (``config="paper_fig7"``): four LeaderFollower followers in a cross;
3. KheperaIV-Nav, KheperaIV-Avoid and KheperaIV-Formation with every baseline that fits and a
   random policy.

It prints each table, writes CSV, JSON and trajectory plots into ``--out``, and with ``--docs``
saves the Fig. 6 (Braitenberg vs VFH) and Fig. 7 figures the README shows. The same runs from
the shell: ``khepera-gym compare --task avoid --config paper_fig6 --policy braitenberg vfh``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from khepera_gym import compare
from khepera_gym.plot import panel_title, plot_rollouts

#: Resolution of the figures saved for the documentation (keeps them well under 200 KB).
DOCS_DPI = 100


def fig6(episodes: int, out: Path, docs: Path | None) -> None:
    """Braitenberg vs VFH on the paper's Fig. 6 scene, with how much each turns."""
    result = compare.compare(
        compare.TASK_IDS["avoid"],
        ["braitenberg", "vfh", "position_control"],
        episodes=episodes,
        config="paper_fig6",
        record_worlds=episodes,
    )
    compare.report(result, out)
    print("\nturning on paper_fig6 (mean over the episodes):")
    for name in ("braitenberg", "vfh"):
        turning = np.array([r.turning() for r in result.rollouts[name]])
        print(
            f"  {name:<12} total heading change {turning[:, 0].mean():5.1f} rad, "
            f"turn-direction reversals {turning[:, 1].mean():6.1f} per episode"
        )
    if docs is not None:
        rollouts = [result.rollouts["braitenberg"][0], result.rollouts["vfh"][0]]
        titles = [
            panel_title(name, r) for name, r in zip(("Braitenberg", "VFH"), rollouts, strict=True)
        ]
        figure = plot_rollouts(
            rollouts, titles, suptitle='Paper Fig. 6 scene: KheperaIV-Avoid, config="paper_fig6"'
        )
        _save(figure, docs / "paper_fig6_braitenberg_vs_vfh.png")


def fig7(episodes: int, out: Path, docs: Path | None) -> None:
    """The cross formation of four LeaderFollower followers on the paper's Fig. 7 scene."""
    result = compare.compare(
        compare.TASK_IDS["formation"], ["leader_follower"], episodes=episodes, config="paper_fig7"
    )
    compare.report(result, out)
    if docs is not None:
        rollout = result.rollouts["leader_follower"][0]
        title = panel_title("LeaderFollower followers, scripted leader", rollout)
        figure = plot_rollouts(
            [rollout],
            [title],
            suptitle='Paper Fig. 7 scene: KheperaIV-Formation, config="paper_fig7"',
        )
        _save(figure, docs / "paper_fig7_leader_follower.png")


def _save(figure, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=DOCS_DPI)
    print(f"saved {path} ({path.stat().st_size // 1024} KB)")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=200, help="per policy and task (200)")
    parser.add_argument("--fig6-episodes", type=int, default=20, help="on the paper scenes (20)")
    parser.add_argument("--out", type=Path, default=Path("compare_out"), help="(compare_out/)")
    parser.add_argument("--docs", type=Path, default=None, help="also save the README figures")
    args = parser.parse_args()

    print("== The paper's Fig. 6 scene\n")
    fig6(args.fig6_episodes, args.out, args.docs)
    print("\n== The paper's Fig. 7 scene\n")
    fig7(args.fig6_episodes, args.out, args.docs)
    for task in ("nav", "avoid", "formation"):
        print(f"\n== {compare.TASK_IDS[task]}\n")
        result = compare.compare(
            compare.TASK_IDS[task],
            list(compare.DEFAULT_POLICIES[task]),
            episodes=args.episodes,
            record_worlds=2,
        )
        compare.report(result, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
