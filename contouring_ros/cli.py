"""The contouring-ros command line: run, simulate, score, paper."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .errors import ContouringError

DEFAULT_EXPERIMENT = "config/paper000_b_ismc_h50_newton.yaml"


def _experiment_path(name: str) -> Path:
    """An experiment file as given, else the packaged scenario of that name (config/<name>[.yaml])."""
    path = Path(name)
    if path.exists():
        return path
    from .paper import CONFIG_DIR
    for candidate in (CONFIG_DIR / path.name, CONFIG_DIR / f"{path.name}.yaml"):
        if candidate.exists():
            return candidate
    return path


def _warn(run):
    for warning in run.warnings:
        print(f"warning: {warning}", file=sys.stderr)


def _run(args):
    from .errors import BagError, RunError
    from .runner import run_graph
    from .scoring import format_scores, score_bag
    config = _experiment_path(args.config)
    try:
        bag = run_graph(config, args.bag, progress=lambda m: print(m, flush=True))
    except RunError as error:
        print(f"error: {error}", file=sys.stderr)
        if error.bag is not None and Path(error.bag).is_file():
            try:
                scores, run = score_bag(error.bag)
            except BagError as bag_error:
                print(f"the partial bag {error.bag} cannot be scored: {bag_error}", file=sys.stderr)
            else:
                _warn(run)
                print(f"partial bag: {error.bag} ({run.complete_steps} complete steps)")
                print(format_scores([(config.stem, scores)], run.axes))
        raise SystemExit(1)
    scores, run = score_bag(bag)
    _warn(run)
    print(f"bag: {bag}")
    print(format_scores([(config.stem, scores)], run.axes))


def _simulate(args):
    from .config import build_loop, load_experiment
    from .core.simulation import simulate
    from .scoring import format_scores, score_run
    experiment = load_experiment(_experiment_path(args.config))
    loop = build_loop(experiment)
    print(format_scores([(experiment.name, score_run(loop.curve, simulate(loop)))], list(experiment.axes)))


def _score(args):
    from .scoring import format_scores, score_bag
    results = [(Path(bag).stem, *score_bag(bag)) for bag in args.bags]
    for _, _, run in results:
        _warn(run)
    if args.json:
        print(json.dumps({name: scores.as_dict() for name, scores, _ in results}, indent=2))
    else:
        print(format_scores([(name, scores) for name, scores, _ in results], results[0][2].axes))


def _paper(args):
    from .paper import paper_report
    print(paper_report(args.paper, graph=args.graph, progress=lambda m: print(m, file=sys.stderr, flush=True)))


def main(argv=None):
    parser = argparse.ArgumentParser(prog="contouring-ros", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("run", help="run an experiment through the node graph, record a bag, print its scores")
    p.add_argument("config", nargs="?", default=DEFAULT_EXPERIMENT, help=f"experiment YAML (default {DEFAULT_EXPERIMENT})")
    p.add_argument("--bag", help="bag to write (default bags/<experiment>_<time>.mcap)")
    p.set_defaults(func=_run)
    p = sub.add_parser("simulate", help="run an experiment in-process (no ROS) and print its scores")
    p.add_argument("config")
    p.set_defaults(func=_simulate)
    p = sub.add_parser("score", help="score bags from their contents alone")
    p.add_argument("bags", nargs="+")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=_score)
    p = sub.add_parser("paper", help="run a paper's scenarios and print our numbers beside the paper's")
    p.add_argument("paper", choices=["000"], help="paper number (see ../shared/seeds/README.md)")
    p.add_argument("--graph", action="store_true", help="run each scenario through the node graph too")
    p.set_defaults(func=_paper)
    args = parser.parse_args(argv)
    try:
        args.func(args)
    except ContouringError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
