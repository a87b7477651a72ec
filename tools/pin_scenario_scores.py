"""Pin what every scenario file of config/ simulates to: MCE and TACE of its first PINNED_SECONDS (or its
whole run, where shorter), in-process, written to tests/data/scenario_scores.json, which
tests/experiment/test_scenario_scores.py holds every scenario to.

Run it only when a change is meant to change results (a fixed formula, a new scenario), and say so in the
commit: a refactoring must leave the file as it is.

Usage: python tools/pin_scenario_scores.py [OUT]
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import contouring_ros.api as cr  # noqa: E402

PINNED_SECONDS = 1.0
OUT = ROOT / "tests" / "data" / "scenario_scores.json"


def scenario_scores(path: Path) -> dict:
    """{duration, mce, tace} [s, m, m] of the scenario file ``path`` simulated for its first PINNED_SECONDS."""
    experiment = cr.load_experiment(str(path))
    duration = min(experiment.duration, PINNED_SECONDS)
    scores = cr.simulate(experiment, {"duration": duration}).scores()
    return {"duration": duration, "mce": scores.mce, "tace": scores.tace}


def main(argv: list) -> int:
    out = Path(argv[0]) if argv else OUT
    pinned = {path.name: scenario_scores(path) for path in sorted((ROOT / "config").glob("*.yaml"))}
    out.write_text(json.dumps(pinned, indent=1) + "\n")
    print(f"{out}: {len(pinned)} scenarios")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
