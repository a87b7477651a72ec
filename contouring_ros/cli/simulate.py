"""``contouring-ros simulate``: an experiment run in-process (no ROS) and scored; with ``--bag``, the bag the
node graph would record; a learning experiment's passes one after another."""
from __future__ import annotations

import contextlib
import sys
from pathlib import Path

from .arguments import seconds
from .experiments import DEFAULT_BAG, bag_target, exit_on_breach, with_settings
from ..errors import Diverged
from ..experiment.scenarios import experiment_path

__all__ = ["HELP", "OUTPUTS", "LONG_RUN_STEPS", "add_arguments", "main"]

HELP = "run an experiment in-process (no ROS) and print its scores"
#: the options that name what the command writes (its bag is checked by :func:`.experiments.bag_target`)
OUTPUTS = ()
LONG_RUN_STEPS = 20_000       # simulate shows a progress bar beyond this many steps (about 20 s of run)


def add_arguments(parser) -> None:
    """The arguments of ``simulate``."""
    parser.add_argument("config")
    parser.add_argument("--bag", nargs="?", const=DEFAULT_BAG, metavar="PATH",
                        help="also write the run's bag, the MCAP the node graph would record (the same payloads), "
                             "to PATH (never over an existing file); --bag alone: bags/<experiment>_<time>.mcap")
    parser.add_argument("--set", action="append", metavar="KEY=VALUE",
                        help="change one key of the experiment for this run, as `run --set` does; repeatable")
    parser.add_argument("--from", dest="from_time", type=seconds, default=0.0, metavar="T",
                        help="score only the samples at t >= T seconds (steady state), as `score --from` does")


def main(args) -> None:
    """Simulate the experiment ``args.config`` (with its ``--set`` settings) and print its scores."""
    from ..experiment.build import build_loop
    from ..experiment.files import load_experiment
    from ..records.scoring import cutting_lines, score_run, scores_lines
    from ..experiment.catalogue.curves import program_warnings
    with with_settings(experiment_path(args.config), args.set) as (config, experiment):
        if experiment is None:
            experiment = load_experiment(config)
    from ..studies.learning import passes
    if passes(experiment) > 1:
        _simulate_passes(experiment, args.from_time, args.bag)
        return
    if args.bag is not None:
        bag_target(args.bag, experiment)        # refused before the run, not after it
    loop = build_loop(experiment)
    for warning in program_warnings(loop.curve):
        print(f"warning: {warning}", file=sys.stderr)
    result = _simulated(loop, experiment)
    scores = score_run(loop.curve, result, args.from_time, experiment)
    if args.bag is not None:
        print(f"bag: {_write_simulation_bag(args.bag, experiment, result)}")
    for line in scores_lines(experiment.name, scores, list(experiment.axes), args.from_time):
        print(line)
    for line in cutting_lines(loop.curve, result, experiment):
        print(line)
    exit_on_breach(loop.curve, result, experiment)


def _simulated(loop, experiment):
    """The result of the in-process run of ``loop``, with a progress bar on a terminal for a long run (a note
    now and then off one); a run that diverged ends the command: the error, the scores of the steps before
    it, exit status 1."""
    from ..core.simulation import simulate
    from ..notices import note_while_slow
    from ..records.scoring import format_scores, score_run
    try:
        terminal = sys.stderr.isatty()             # a progress bar there; a note now and then off one
        with contextlib.nullcontext() if terminal else note_while_slow(f"simulating {loop.n_steps} steps"):
            return simulate(loop, progress=loop.n_steps > LONG_RUN_STEPS and sys.stderr.isatty())
    except Diverged as error:
        print(f"error: {error}", file=sys.stderr)
        if len(error.result.time):
            print(f"scores of the {len(error.result.time)} steps before it:")
            print(format_scores([(experiment.name, score_run(loop.curve, error.result, experiment=experiment))],
                                list(experiment.axes)))
        raise SystemExit(1)


def _write_simulation_bag(given: str, experiment, result) -> Path:
    """The in-process run's bag, as the node graph's recorder would have written it (the same topics, types
    and payloads: :func:`contouring_ros.records.bag_writer.write_simulation`)."""
    from ..records.bag_writer import write_simulation
    from ..records.outputs import write_atomically
    path = bag_target(given, experiment)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_atomically(path, lambda tmp: write_simulation(tmp, experiment, result))


class _PassBags:
    """The passes of a learning experiment as they end: each pass's scores (of the samples at t >=
    ``from_time``) kept for the table, and its bag written where ``base`` names the first (``run``'s names,
    ``<bag>_pass<j>.mcap``)."""

    def __init__(self, experiment, from_time: float = 0.0, base: Path | None = None):
        self.experiment, self.from_time, self.base = experiment, from_time, base
        self.rows = []

    def report(self, j: int, loop, result) -> None:
        """Pass ``j`` ended with ``result`` of ``loop``."""
        from ..records.scoring import score_run
        from ..studies.learning import pass_bag, pass_experiment
        self.rows.append((f"pass {j}", score_run(loop.curve, result, self.from_time, self.experiment)))
        if self.base is not None:
            written = _write_simulation_bag(str(pass_bag(self.base, j)), pass_experiment(self.experiment, j), result)
            print(f"pass {j}: bag {written}")

    def table(self) -> str:
        """The passes' scores side by side."""
        from ..records.scoring import format_scores
        return format_scores(self.rows, list(self.experiment.axes))


def _simulate_passes(experiment, from_time: float = 0.0, bag: str | None = None) -> None:
    """Every pass of a learning experiment in-process, then their scores side by side (of the samples at
    t >= ``from_time``); with ``bag``, each pass's bag as ``run`` names them (``<bag>_pass<j>.mcap``)."""
    from ..studies.learning import pass_bag, passes as passes_of, simulate_passes
    base = bag_target(bag, experiment) if bag is not None else None
    if base is not None:
        for j in range(1, passes_of(experiment) + 1):
            bag_target(str(pass_bag(base, j)), experiment)
    passes = _PassBags(experiment, from_time, base)
    try:
        simulate_passes(experiment, passes.report)
    except Diverged as error:
        print(f"error: pass {len(passes.rows) + 1}: {error}", file=sys.stderr)
        if passes.rows:
            print(passes.table())
        raise SystemExit(1)
    print(passes.table())
