"""``python tests/hostile_campaign.py``: run a hostile-input campaign (see the package's
docstring).

    python tests/hostile_campaign.py --cases 100000 --json hostile-report.json
    python tests/hostile_campaign.py --replay 0:1234

Exits 1 if any case failed (an unexpected exception, a crash, a hang, a non-finite reward or
an observation outside its space), printing each failure's replay command.
"""

from __future__ import annotations

import argparse
import json
import sys

from khepera_gym.tooling.provenance import command_line, provenance

from .campaign import DEFAULT_MEMORY, DEFAULT_TIMEOUT, campaign, replay, worker


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python tests/hostile_campaign.py", description=__doc__)
    parser.add_argument("--cases", type=int, default=1000, help="cases to run (default 1000)")
    parser.add_argument("--seed", type=int, default=0, help="campaign seed (default 0)")
    parser.add_argument("--workers", type=int, default=None, help="worker processes (cores)")
    parser.add_argument(
        "--memory", type=int, default=DEFAULT_MEMORY, help="bytes a case may map (default 2 GiB)"
    )
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT, help="s per case")
    parser.add_argument("--json", help="write the report (counts, failures) to this file")
    parser.add_argument("--replay", help="SEED:INDEX: rerun one case here, with a traceback")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        worker(args.memory, args.timeout, sys.stdin, sys.stdout)
        return 0
    if args.replay:
        seed, index = (int(part) for part in args.replay.split(":"))
        return replay(seed, index)
    report = campaign(
        args.cases, args.seed, args.workers, args.memory, args.timeout, progress=sys.stderr
    )
    summary = report.summary()
    # The provenance every results file has (the docs' results importer reads it).
    arguments = sys.argv[1:] if argv is None else argv
    summary["meta"] = provenance(command_line(["tests/hostile_campaign.py", *arguments]))
    summary["limits"] = {"memory_limit_bytes": args.memory, "timeout_s": args.timeout}
    print(
        f"{summary['cases']} cases in {summary['seconds']} s: {summary['accepted']} accepted, "
        f"{summary['refused']} refused with a typed error, {summary['failures']} failures"
    )
    for kind, counts in summary["by_kind"].items():
        print(f"  {kind:11s} " + ", ".join(f"{k}: {v}" for k, v in sorted(counts.items())))
    for failure in report.failures[:50]:
        print(f"FAIL {failure['replay']} {failure['kind']}: {failure['outcome']}")
        print("     " + failure["detail"].replace("\n", "\n     ")[:600])
    if args.json:
        with open(args.json, "w", encoding="utf-8") as out:
            json.dump(summary, out, indent=1, default=repr)
            out.write("\n")
    return 1 if report.failures else 0


if __name__ == "__main__":
    sys.exit(main())
