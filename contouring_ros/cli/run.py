"""``contouring-ros run``: an experiment through the node graph (a process per node, one process, or groups of
nodes), its bag recorded and scored; a learning experiment's passes one after another; a run that stops
leaves its partial bag scored."""
from __future__ import annotations

import sys
from pathlib import Path

from .arguments import domain_id, force_option, seconds
from .experiments import bag_target, exit_on_breach, with_settings
from .reading import warn
from ..errors import BagError, ConfigError, Interrupted, RunError
from ..experiment.scenarios import DEFAULT_EXPERIMENT, experiment_path

__all__ = ["HELP", "OUTPUTS", "add_arguments", "main"]

HELP = "run an experiment through the node graph, record a bag, print its scores"
#: the options that name what the command writes
OUTPUTS = ("bag",)


def add_arguments(parser) -> None:
    """The arguments of ``run``."""
    parser.add_argument("config", nargs="?", default=DEFAULT_EXPERIMENT,
                        help=f"experiment YAML (default {DEFAULT_EXPERIMENT})")
    parser.add_argument("--bag", help="bag to write (default bags/<experiment>_<time>.mcap)")
    parser.add_argument("--composed", action="store_true", help="run every node in one process under one executor "
                        "(default: the experiment's layout key, else a process per node)")
    parser.add_argument("--process", action="store_true", help="run every node in its own process, whatever the "
                        "experiment's layout key says")
    parser.add_argument("--group", action="append", metavar="NODE,NODE,...",
                        help="grouped layout: run these nodes (e.g. x/plant,x/servo) in one process on the composed "
                             "loop; repeat for more groups; every node in no group runs in its own process")
    parser.add_argument("--namespace", default="/", metavar="NS",
                        help="run every node and topic under /NS (e.g. m1: /m1/x/plant publishes /m1/x/state)")
    parser.add_argument("--set", action="append", metavar="KEY=VALUE",
                        help="change one key of the experiment for this run, with the sweep's key syntax "
                             "(x/servo.kp=10, ccc.kp=2, curve.h=80); repeatable")
    parser.add_argument("--from", dest="from_time", type=seconds, default=0.0, metavar="T",
                        help="print the scores of the samples at t >= T s (steady state), as score --from T; the "
                             "bag holds the whole run")
    parser.add_argument("--domain", type=domain_id, metavar="ID",
                        help="run on this ROS domain, shared with ROS tools and other runs there (give each graph "
                             "its own --namespace) instead of a private one")
    force_option(parser)


def main(args) -> None:
    """Run the experiment ``args.config`` (with its ``--set`` settings) through the node graph and print its
    scores."""
    from ..records import outputs
    if args.bag:
        outputs.active().claim(args.bag, outputs.BAG, "--bag")
    else:
        outputs.active().claim_folder("bags", "run")
    with with_settings(experiment_path(args.config), args.set) as (config, experiment):
        _run_config(args, config, experiment)


def _run_config(args, config: Path, experiment=None) -> None:
    """Run the experiment file ``config`` (``experiment``: its Experiment, where it has been read already)
    through the node graph as ``args`` say; a run the graph stopped ends the command (:meth:`_GraphRun.stopped`)."""
    graph = _GraphRun(args, config, experiment)
    try:
        bag = graph.start()
    except RunError as error:
        graph.stopped(error)
    if bag is not None:
        graph.report(bag)


def _layout(args) -> str | None:
    """The layout the options ask for: "composed", "process" (--process or --group) or None (the experiment's)."""
    if sum(map(bool, (args.composed, args.group, args.process))) > 1:
        raise ConfigError("--process, --composed and --group are three layouts: give one")
    return "composed" if args.composed else "process" if args.process or args.group else None


class _GraphRun:
    """One ``run`` command: the experiment file ``config`` through the node graph in the layout and on the
    namespace and domain the options ``args`` give; ``experiment`` is its Experiment, read once."""

    def __init__(self, args, config: Path, experiment=None):
        self.args, self.config, self.experiment = args, config, experiment
        self.layout = None

    def start(self):
        """Run the experiment (every pass of a learning experiment, each scored as it ends: None), and return
        the bag of its one run; its bags are refused before any node starts if files are in their place."""
        self.layout = _layout(self.args)
        from ..experiment.build import build_curve
        from ..experiment.catalogue.curves import program_warnings
        from ..experiment.files import load_experiment
        if self.experiment is None:
            self.experiment = load_experiment(self.config)       # the one parse of the file in this process
        for warning in program_warnings(build_curve(self.experiment)):
            print(f"warning: {warning}", file=sys.stderr)
        from ..studies.learning import pass_bag, passes
        bag = self.args.bag
        if bag is not None:          # a user's file is never overwritten: refused before any node starts
            for target in ([pass_bag(Path(bag), j) for j in range(1, passes(self.experiment) + 1)]
                           if passes(self.experiment) > 1 else [bag]):
                bag_target(str(target), self.experiment)
        if passes(self.experiment) > 1:
            _run_passes(self.config, self.experiment, bag, self.run_one, self.args.from_time)
            return None
        return self.run_one(self.config, bag, self.experiment)

    def run_one(self, path, bag, parsed):
        """One run of the experiment file ``path`` (``parsed``: its Experiment) recording ``bag``, with its
        progress on stderr; the bag's path."""
        from ..notices import progress_of
        from ..run.runner import run_graph
        args = self.args
        with progress_of(parsed.n_steps, "run", waiting="no step recorded yet") as on_step:
            return run_graph(path, bag, progress=lambda m: print(m, flush=True),
                             layout=self.layout, groups=args.group, experiment=parsed, on_step=on_step,
                             namespace=args.namespace, domain_id=args.domain,
                             shared_domain=args.domain is not None)

    def stopped(self, error: RunError):
        """End the command on a run the graph stopped: the error, then the scores of its partial bag where
        there is one; exit status 1, or the signal's for an interrupted run."""
        from ..records.scoring import format_scores, score_bag
        interrupted = isinstance(error, Interrupted)
        print(f"{'' if interrupted else 'error: '}{error}", file=sys.stderr)
        if error.bag is not None and Path(error.bag).is_file():
            try:
                scores, run = score_bag(error.bag, parsed=self.experiment)
            except BagError as bag_error:
                print(f"the partial bag {error.bag} cannot be scored: {bag_error}", file=sys.stderr)
            else:
                warn(run)
                print(f"partial bag: {error.bag} ({run.complete_steps} complete steps)")
                print(format_scores([(self.experiment.name, scores)], run.axes))
        raise SystemExit(error.code if interrupted else 1)

    def report(self, bag) -> None:
        """Print what the run's ``bag`` tells (:func:`contouring_ros.records.scoring.recorded_lines`); a run that
        monitoring stopped ends the command with exit status 1."""
        from ..records.scoring import curve_of, recorded_lines, score_bag
        from_time = self.args.from_time
        scores, run = score_bag(bag, parsed=self.experiment, from_time=from_time)   # the text just parsed: not again
        warn(run)
        print(f"bag: {bag}")
        for line in recorded_lines(bag, self.experiment.name, scores, run, from_time):
            print(line)
        exit_on_breach(curve_of(run), run.result, run.require_experiment(), bag)


class _PassScores:
    """The scores of a learning experiment's passes through the graph (of the samples at t >= ``from_time``):
    each pass's line as it ends (:meth:`report`), then all side by side (:meth:`table`)."""

    def __init__(self, from_time: float = 0.0):
        self.from_time = from_time
        self.rows = []

    def report(self, j: int, path, recorded) -> None:
        """Score pass ``j``, recorded in the bag ``path`` and read as ``recorded``, and print its line."""
        from ..records.scoring import curve_of, score_run
        scores = score_run(curve_of(recorded), recorded.result, self.from_time, experiment=recorded.experiment)
        self.rows.append((f"pass {j}", scores))
        print(f"pass {j}: bag {path}: MCE {scores.mce * 1e6:.4g} um, TACE {scores.tace * 1e6:.4g} um", flush=True)

    def table(self, axes) -> str:
        """The passes' scores side by side."""
        from ..records.scoring import format_scores
        return format_scores(self.rows, list(axes))


def _run_passes(config: Path, experiment, bag, run_one, from_time: float = 0.0) -> None:
    """Every pass of a learning experiment through the graph (``run_one`` as :meth:`_GraphRun.run_one`), each
    pass's scores as it ends, then all side by side (:mod:`contouring_ros.studies.learning`)."""
    from ..records import outputs
    from ..studies.learning import learned_path, pass_bag, passes, run_passes
    from ..run.runner import default_bag_path
    if bag:
        for j in range(1, passes(experiment) + 1):
            outputs.active().claim(pass_bag(Path(bag), j), outputs.BAG, "--bag")
            if j > 1:
                outputs.active().claim(learned_path(pass_bag(Path(bag), j)), outputs.LEARNED, "--bag")
    scores = _PassScores(from_time)
    run_passes(config, experiment, Path(bag) if bag else default_bag_path(experiment), run_one, scores.report)
    print(scores.table(experiment.axes))
