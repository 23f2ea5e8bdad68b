"""The paper's controllers compared on the same seeded episodes: the documentation's tables and
figures.

Usage: ``python examples/compare_baselines.py [--episodes 200] [--fig6-episodes 20]
[--out compare_out] [--docs docs/images] [--version 1]``. Runs, with
:func:`khepera_gym.analysis.compare.compare`, on the envs of behaviour ``--version`` (default: the
latest; 0 is the paper's V-REP-like dynamics):

1. the paper's Fig. 6 scene (``config="paper_fig6"``): Braitenberg vs VFH (and position control
   alone), and how much each turns (total heading change, turn-direction reversals: the paper
   says VFH zigzags);
2. the paper's Fig. 7 scene (``config="paper_fig7"``): four LeaderFollower followers in a cross;
3. the paper's three tasks (Nav, Avoid and Formation) with every baseline that fits and a
   random policy;
4. from v1 on, the Fig. 6 scene and Avoid as K-Team's own Braitenberg demo drives the real robot:
   its speed profile (Acc_Inc 10 per 10 ms: ``wheel_accel_limit = 0.678`` m/s^2) and its cruise
   speed (200 units, 0.136 m/s: the ``*_slow`` policies);
5. from v1 on, KheperaIV-Track on each built-in reference (circle, lemniscate, square, spline)
   with Kanayama, PositionChase and random (``khepera-gym compare --task track --set
   reference=square``).

It prints each table, writes CSV, JSON and trajectory plots into ``--out``, and with ``--docs``
saves the Fig. 6 (Braitenberg vs VFH) and Fig. 7 figures the README shows (``_v<version>`` in
their names) and the Track figure (reference vs robot on the square, ``track_square_v1.png``).
The same runs from the shell: ``khepera-gym compare --task avoid --config paper_fig6 --policy
braitenberg vfh``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from khepera_gym.analysis import compare
from khepera_gym.analysis.plots import panel_title, plot_rollouts

#: Resolution of the figures saved for the documentation (keeps them well under 200 KB).
DOCS_DPI = 100


def env_id(task: str, version: int | None) -> str:
    """The registered id of ``task`` in behaviour ``version`` (None: the latest)."""
    latest = compare.TASK_IDS[task]
    return latest if version is None else f"{latest.rsplit('-v', 1)[0]}-v{version}"


def fig6(episodes: int, out: Path, docs: Path | None, version: int | None) -> None:
    """Braitenberg vs VFH on the paper's Fig. 6 scene, with how much each turns."""
    avoid = env_id("avoid", version)
    result = compare.compare(
        avoid,
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
            rollouts, titles, suptitle=f'Paper Fig. 6 scene: {avoid}, config="paper_fig6"'
        )
        _save(figure, docs / f"paper_fig6_braitenberg_vs_vfh_{avoid.rsplit('-', 1)[1]}.png")


def fig7(episodes: int, out: Path, docs: Path | None, version: int | None) -> None:
    """The cross formation of four LeaderFollower followers on the paper's Fig. 7 scene."""
    formation = env_id("formation", version)
    result = compare.compare(formation, ["leader_follower"], episodes=episodes, config="paper_fig7")
    compare.report(result, out)
    if docs is not None:
        rollout = result.rollouts["leader_follower"][0]
        title = panel_title("LeaderFollower followers, scripted leader", rollout)
        figure = plot_rollouts(
            [rollout],
            [title],
            suptitle=f'Paper Fig. 7 scene: {formation}, config="paper_fig7"',
        )
        _save(figure, docs / f"paper_fig7_leader_follower_{formation.rsplit('-', 1)[1]}.png")


#: K-Team's braitenbergAvoidance demo (kh4test): Acc_Inc 10 speed units (0.678 mm/s) per 10 ms.
KTEAM_DEMO_PROFILE = {"wheel_accel_limit": 0.678}
#: The baselines at the demo's cruise speed.
SLOW_POLICIES = ["position_control_slow", "braitenberg_slow", "vfh_slow"]


def kteam_demo(episodes: int, fig6_episodes: int, out: Path, version: int | None) -> None:
    """Fig. 6 and Avoid with K-Team's demo motor profile and cruise speed."""
    avoid = env_id("avoid", version)
    for config, n in (("paper_fig6", fig6_episodes), (None, episodes)):
        print(f"\n== {avoid}, config={config!r}, K-Team demo profile {KTEAM_DEMO_PROFILE}\n")
        result = compare.compare(
            avoid, SLOW_POLICIES, episodes=n, config=config, overrides=KTEAM_DEMO_PROFILE
        )
        compare.report(result, out / "kteam_demo", plot=False)


#: Track's built-in references compared (``waypoints`` needs a scenario's own points).
TRACK_REFERENCES = ("circle", "lemniscate", "square", "spline")


def track(episodes: int, out: Path, docs: Path | None) -> None:
    """Kanayama, PositionChase and random on each built-in Track reference."""
    for reference in TRACK_REFERENCES:
        print(f"\n== {compare.TASK_IDS['track']}, reference={reference!r}\n")
        result = compare.compare(
            compare.TASK_IDS["track"],
            list(compare.DEFAULT_POLICIES["track"]),
            episodes=episodes,
            record_worlds=3,
            overrides={"reference": reference},
        )
        compare.report(result, out)
        if docs is not None and reference == "square":
            # The two controllers (random is lost within 4 s in every episode).
            figure = compare.plot_reference_paths(
                {name: result.rollouts[name] for name in ("kanayama", "position_chase")},
                suptitle=f'{result.env_id}, reference="square": where smooth controllers fail',
            )
            _save(figure, docs / "track_square_v1.png")


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
    parser.add_argument(
        "--version", type=int, default=None, help="behaviour version of the envs (the latest)"
    )
    args = parser.parse_args()

    print("== The paper's Fig. 6 scene\n")
    fig6(args.fig6_episodes, args.out, args.docs, args.version)
    print("\n== The paper's Fig. 7 scene\n")
    fig7(args.fig6_episodes, args.out, args.docs, args.version)
    for task in ("nav", "avoid", "formation"):
        print(f"\n== {env_id(task, args.version)}\n")
        result = compare.compare(
            env_id(task, args.version),
            list(compare.DEFAULT_POLICIES[task]),
            episodes=args.episodes,
            record_worlds=2,
        )
        compare.report(result, args.out)
    if args.version is None or args.version >= 1:
        kteam_demo(args.episodes, args.fig6_episodes, args.out, args.version)
        track(args.episodes, args.out, args.docs)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
