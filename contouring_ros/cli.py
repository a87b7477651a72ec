"""The contouring-ros command line: run an experiment through the node graph or simulate it in-process;
score, compare, export, plot and replay its bags; sweep its keys; measure the papers' claims; benchmark
every estimator and controller on every paper scenario."""
from __future__ import annotations

import contextlib
import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

from .errors import BagError, ConfigError, ContouringError, Diverged, Interrupted, RunError
from .experiment.scenarios import DEFAULT_EXPERIMENT, experiment_path as _experiment_path


# the stated bounds of the numeric options, checked before any work
MAX_WORKERS = 256         # --workers: processes (a pool never starts more than it has tasks)
MAX_BATCH = 10_000        # sweep --batch: combinations per vectorised batch
MAX_BUDGET = 100_000      # benchmark --budget: evaluations per combination
MAX_DRAWS = 1_000         # benchmark --draws
MAX_SEARCHES = 100        # benchmark --searches
MAX_SECONDS = 1e9         # any time option (about 32 years)
MAX_WAIT_SUBSCRIBERS = 1_000


def _seconds(text: str) -> float:
    """A non-negative finite time in seconds, at most MAX_SECONDS (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not 0.0 <= value <= MAX_SECONDS:
        raise argparse.ArgumentTypeError(f"expected a number of seconds from 0 to {MAX_SECONDS:g}, got {text!r}")
    return value


def _whole(low: int, high: int, what: str):
    """An argparse type: a whole number of ``what`` from ``low`` to ``high``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not low <= value <= high:
            raise argparse.ArgumentTypeError(f"expected a whole number of {what} from {low} to {high}, got {text!r}")
        return value
    return parse


def _seconds_at_most(limit: float):
    """An argparse type: a number of seconds from 0 to ``limit``."""
    def parse(text: str) -> float:
        value = _seconds(text)
        if value > limit:
            raise argparse.ArgumentTypeError(f"expected a number of seconds from 0 to {limit:g}, got {text!r}")
        return value
    return parse


class _Parser(argparse.ArgumentParser):
    """argparse's parser with its errors on one line (the usage is one --help away)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def _magnification(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.0 < value <= 1e9:
        raise argparse.ArgumentTypeError(f"expected a positive magnification up to 1e9, got {text!r}")
    return value


def _rate(text: str) -> float:
    """A playback rate: 0 (as fast as possible) or a finite positive factor (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value == 0.0 or 1e-6 <= value <= 1e6):
        raise argparse.ArgumentTypeError("expected 0 (as fast as possible) or a positive factor from 1e-6 to 1e6, got "
                                         f"{text!r}")
    return value


def _domain_id(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 232:
        raise argparse.ArgumentTypeError(f"expected a ROS domain id from 0 to 232, got {text!r}")
    return value


def _warn(run):
    for warning in run.warnings:
        print(f"warning: {warning}", file=sys.stderr)


@contextlib.contextmanager
def _with_settings(config: Path, specs):
    """(file, Experiment) for the ``with`` block: the experiment file ``config`` with the ``--set KEY=VALUE``
    settings ``specs`` applied, written under the same name (the bag's default name) in a temporary folder,
    and its validated Experiment; ``config`` itself without any (and None: the caller reads it)."""
    if not specs:
        yield config, None
        return
    from .experiment.settings import written_settings
    with tempfile.TemporaryDirectory(prefix="contouring_ros_set_") as directory:
        yield written_settings(config, specs, directory)


def _run(args):
    from .records import outputs
    if args.bag:
        outputs.active().claim(args.bag, outputs.BAG, "--bag")
    else:
        outputs.active().claim_folder("bags", "run")
    with _with_settings(_experiment_path(args.config), args.set) as (config, experiment):
        _run_config(args, config, experiment)


def _run_config(args, config: Path, experiment=None):
    from .run.runner import run_graph
    from .records.scoring import format_scores, score_bag
    try:
        if sum(map(bool, (args.composed, args.group, args.process))) > 1:
            raise ConfigError("--process, --composed and --group are three layouts: give one")
        layout = "composed" if args.composed else "process" if args.process or args.group else None
        from .experiment.build import build_curve
        from .experiment.catalogue.curves import program_warnings
        from .experiment.files import load_experiment
        if experiment is None:
            experiment = load_experiment(config)       # the one parse of the file in this process
        for warning in program_warnings(build_curve(experiment)):
            print(f"warning: {warning}", file=sys.stderr)
        from .studies.learning import pass_bag, passes

        def run_one(path, bag, parsed):
            from .notices import progress_of
            with progress_of(parsed.n_steps, "run", waiting="no step recorded yet") as on_step:
                return run_graph(path, bag, progress=lambda m: print(m, flush=True),
                                 layout=layout, groups=args.group, experiment=parsed, on_step=on_step,
                                 namespace=args.namespace, domain_id=args.domain,
                                 shared_domain=args.domain is not None)
        if args.bag is not None:          # a user's file is never overwritten: refused before any node starts
            for target in ([pass_bag(Path(args.bag), j) for j in range(1, passes(experiment) + 1)]
                           if passes(experiment) > 1 else [args.bag]):
                _bag_target(str(target), experiment)
        if passes(experiment) > 1:
            _run_passes(config, experiment, args.bag, run_one, args.from_time)
            return
        bag = run_one(config, args.bag, experiment)
    except RunError as error:
        interrupted = isinstance(error, Interrupted)
        print(f"{'' if interrupted else 'error: '}{error}", file=sys.stderr)
        if error.bag is not None and Path(error.bag).is_file():
            try:
                scores, run = score_bag(error.bag, parsed=experiment)
            except BagError as bag_error:
                print(f"the partial bag {error.bag} cannot be scored: {bag_error}", file=sys.stderr)
            else:
                _warn(run)
                print(f"partial bag: {error.bag} ({run.complete_steps} complete steps)")
                print(format_scores([(experiment.name, scores)], run.axes))
        raise SystemExit(error.code if interrupted else 1)
    scores, run = score_bag(bag, parsed=experiment, from_time=args.from_time)   # the text just parsed: not again
    _warn(run)
    print(f"bag: {bag}")
    if args.from_time:
        print(f"scores of the samples at t >= {args.from_time:g} s")
    print(format_scores([(experiment.name, scores)], run.axes))
    from .records.scoring import curve_of, cutting_lines
    for line in cutting_lines(curve_of(run), run.result, run.require_experiment()):
        print(line)
    from .records.bag import node_reports
    from .records.scoring import format_realtime
    realtime = format_realtime(node_reports(bag))
    if realtime:
        print(realtime)
    _exit_on_breach(curve_of(run), run.result, run.require_experiment(), bag)


def _exit_on_breach(curve, result, experiment, bag=None):
    """A run that monitoring stopped ends in one line on stderr and exit status 1 (its bag, if any, whole)."""
    from .records.scoring import breach_message
    line = breach_message(curve, result, experiment)
    if line is not None:
        print(f"error: {line}" + (f" (bag {bag}, complete)" if bag is not None else ""), file=sys.stderr)
        raise SystemExit(1)


def _run_passes(config: Path, experiment, bag, run_one, from_time: float = 0.0):
    """Every pass of a learning experiment through the graph, each pass's scores as it ends, then all side by
    side (:mod:`contouring_ros.studies.learning`)."""
    from .records import outputs
    from .studies.learning import learned_path, pass_bag, passes, run_passes
    from .run.runner import default_bag_path
    from .records.scoring import curve_of, format_scores, score_run
    if bag:
        for j in range(1, passes(experiment) + 1):
            outputs.active().claim(pass_bag(Path(bag), j), outputs.BAG, "--bag")
            if j > 1:
                outputs.active().claim(learned_path(pass_bag(Path(bag), j)), outputs.LEARNED, "--bag")
    rows = []

    def report(j, path, recorded):
        scores = score_run(curve_of(recorded), recorded.result, from_time, experiment=recorded.experiment)
        rows.append((f"pass {j}", scores))
        print(f"pass {j}: bag {path}: MCE {scores.mce * 1e6:.4g} um, TACE {scores.tace * 1e6:.4g} um", flush=True)
    run_passes(config, experiment, Path(bag) if bag else default_bag_path(experiment), run_one, report)
    print(format_scores(rows, list(experiment.axes)))


_DEFAULT_BAG = "<default>"     # simulate --bag without a path
LONG_RUN_STEPS = 20_000       # simulate shows a progress bar beyond this many steps (about 20 s of run)


def _simulate(args):
    from .experiment.build import build_loop
    from .experiment.files import load_experiment
    from .notices import note_while_slow
    from .core.simulation import simulate
    from .records.scoring import cutting_lines, format_scores, score_run
    from .experiment.catalogue.curves import program_warnings
    with _with_settings(_experiment_path(args.config), args.set) as (config, experiment):
        if experiment is None:
            experiment = load_experiment(config)
    from .studies.learning import passes
    if passes(experiment) > 1:
        _simulate_passes(experiment, args.from_time, args.bag)
        return
    if args.bag is not None:
        _bag_target(args.bag, experiment)        # refused before the run, not after it
    loop = build_loop(experiment)
    for warning in program_warnings(loop.curve):
        print(f"warning: {warning}", file=sys.stderr)
    try:
        terminal = sys.stderr.isatty()             # a progress bar there; a note now and then off one
        with contextlib.nullcontext() if terminal else note_while_slow(f"simulating {loop.n_steps} steps"):
            result = simulate(loop, progress=loop.n_steps > LONG_RUN_STEPS and sys.stderr.isatty())
    except Diverged as error:
        print(f"error: {error}", file=sys.stderr)
        if len(error.result.time):
            print(f"scores of the {len(error.result.time)} steps before it:")
            print(format_scores([(experiment.name, score_run(loop.curve, error.result, experiment=experiment))],
                                list(experiment.axes)))
        raise SystemExit(1)
    scores = score_run(loop.curve, result, args.from_time, experiment)
    if args.bag is not None:
        print(f"bag: {_write_simulation_bag(args.bag, experiment, result)}")
    if args.from_time:
        print(f"scores of the samples at t >= {args.from_time:g} s")
    print(format_scores([(experiment.name, scores)], list(experiment.axes)))
    for line in cutting_lines(loop.curve, result, experiment):
        print(line)
    _exit_on_breach(loop.curve, result, experiment)


def _bag_target(given: str, experiment) -> Path:
    """Where ``simulate --bag`` writes: the path given (refused if something is there: a user's file is never
    overwritten), or bags/<experiment>_<time>.mcap for ``--bag`` alone, as ``run`` names its bags."""
    from .run.runner import default_bag_path
    path = default_bag_path(experiment) if given == _DEFAULT_BAG else Path(given)
    if path.exists() or path.is_symlink():
        raise ConfigError(f"--bag {path}: a file of that name exists (name another, or remove it)")
    if path.parent.exists() and not path.parent.is_dir():
        raise ConfigError(f"--bag {path}: {path.parent} is not a folder")
    return path


def _write_simulation_bag(given: str, experiment, result) -> Path:
    """The in-process run's bag, as the node graph's recorder would have written it (the same topics, types
    and payloads: :func:`contouring_ros.records.bag.write_simulation`)."""
    from .records.bag import write_simulation
    from .records.outputs import write_atomically
    path = _bag_target(given, experiment)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_atomically(path, lambda tmp: write_simulation(tmp, experiment, result))


def _simulate_passes(experiment, from_time: float = 0.0, bag: str | None = None):
    """Every pass of a learning experiment in-process, then their scores side by side (of the samples at
    t >= ``from_time``); with ``bag``, each pass's bag as ``run`` names them (``<bag>_pass<j>.mcap``)."""
    from .studies.learning import pass_bag, pass_experiment, passes as passes_of, simulate_passes
    from .records.scoring import format_scores, score_run
    rows = []
    base = _bag_target(bag, experiment) if bag is not None else None
    if base is not None:
        for j in range(1, passes_of(experiment) + 1):
            _bag_target(str(pass_bag(base, j)), experiment)

    def report(j, loop, result):
        rows.append((f"pass {j}", score_run(loop.curve, result, from_time, experiment)))
        if base is not None:
            print(f"pass {j}: bag {_write_simulation_bag(str(pass_bag(base, j)), pass_experiment(experiment, j), result)}")
    try:
        simulate_passes(experiment, report)
    except Diverged as error:
        print(f"error: pass {len(rows) + 1}: {error}", file=sys.stderr)
        if rows:
            print(format_scores(rows, list(experiment.axes)))
        raise SystemExit(1)
    print(format_scores(rows, list(experiment.axes)))


def _given(args) -> dict:
    """The reader's keywords for ``--experiment FILE`` (bags recorded without one): the file's text and its
    Experiment, parsed here once for every bag (see :func:`contouring_ros.records.scoring.read_run`); none without it."""
    if getattr(args, "experiment", None) is None:
        return {}
    from .experiment.files import load_experiment
    experiment = load_experiment(args.experiment)
    return {"experiment_text": experiment.text, "parsed": experiment}


def _scored(args):
    from .records.scoring import score_bag
    given = _given(args)
    start = getattr(args, "from_time", 0.0) or 0.0
    results = [(Path(bag).stem, *score_bag(bag, progress=sys.stderr.isatty(), from_time=start, **given))
               for bag in args.bags]
    for _, _, run in results:
        _warn(run)
    return results


def _json_scores(scores, axes) -> dict:
    """A run's scores for JSON: the Scores fields as they are (mce, tace, rms ... in metres), and the same
    per-axis values keyed by axis name, with the units spelled out."""
    out = scores.as_dict()
    out["axes"] = list(axes)
    for key in ("tracking_max", "tracking_rms", "effort_rms"):
        out[f"{key}_by_axis"] = dict(zip(axes, out[key]))
    out["units"] = {"mce": "m", "tace": "m", "rms": "m", "estimation_max": "m", "estimation_rms": "m",
                    "tracking_max": "m", "tracking_rms": "m", "effort_rms": "command units", "travel_time": "s",
                    "from_time": "s"}
    return out


def _score(args):
    from .records.scoring import format_scores
    results = _scored(args)
    if args.json:
        print(json.dumps({name: _json_scores(scores, run.axes) for name, scores, run in results}, indent=2))
    else:
        if args.from_time:
            print(f"scores of the samples at t >= {args.from_time:g} s")
        print(format_scores([(name, scores) for name, scores, _ in results], results[0][2].axes))


def _blocks(args):
    from dataclasses import replace

    from .records.blocks import block_results, format_blocks, write_blocks_csv
    from .experiment.build import build_schedule
    from .records.scoring import curve_of, cutting_lines, motion_steps, read_run
    from .records import outputs
    if args.csv:
        outputs.active().claim_folder(args.csv, "--csv")
        for bag in args.bags:
            outputs.active().claim(Path(args.csv) / f"{Path(bag).stem}_blocks.csv", outputs.BLOCKS_CSV, "--csv")
    given = _given(args)
    for bag in args.bags:
        run = read_run(bag, progress=sys.stderr.isatty(), **given)
        _warn(run)
        curve = curve_of(run)
        if not hasattr(curve, "blocks"):
            raise ConfigError(f"{bag}: not a tool path run (curve type gcode or toolpath): it has no blocks")
        experiment = replace(run.require_experiment(), path=str(bag))      # named after the bag in messages
        rows = block_results(curve, run.result, build_schedule(experiment, curve),
                             experiment.schedule.get("contour_tolerance") or 0.0,
                             end=motion_steps(curve, run.result, experiment))
        print(f"{bag}:")
        for line in cutting_lines(curve, run.result, experiment):
            print(line)
        print(format_blocks(rows, run.axes, curve, experiment.sample_time))
        if args.csv:
            print(write_blocks_csv(rows, run.axes, Path(args.csv) / f"{Path(bag).stem}_blocks.csv", curve,
                                   experiment.sample_time))


def _compare(args):
    from .records.analysis import compare_table, experiment_differences, format_differences, run_names
    if args.baseline:
        args.bags = [args.baseline] + [bag for bag in args.bags if bag != args.baseline]
    results = _scored(args)
    runs = [(label, run) for label, _, run in results]
    names = run_names(runs)       # the experiment's name (with what --set changed), the bag's time where needed
    print(compare_table([(name, scores) for name, (_, scores, _) in zip(names, results)], 0, results[0][2].axes))
    differ = format_differences(names, experiment_differences(runs))
    if differ:
        print()
        print(differ)


def _replay(args):
    if args.play:
        from .run.playback import play_bag
        topics = [t.strip() for t in args.topics.split(",")] if args.topics is not None else None
        try:
            play_bag(args.bag, rate=args.rate, progress=sys.stderr.isatty(), loop=args.loop, start=args.start,
                     topics=topics, wait_subscribers=args.wait_subscribers, wait_timeout=args.wait_timeout)
        except KeyboardInterrupt:      # the player has said where it stopped
            raise SystemExit(130)
        return
    from .records.analysis import parse_estimator_spec, replay_estimators
    from .records.scoring import read_run
    if not args.estimator:
        raise SystemExit("error: replay needs --estimator NAME[:key=value,...] (or --play)")
    run = read_run(args.bag, progress=sys.stderr.isatty(), **_given(args))
    _warn(run)
    exact, replays = replay_estimators(run, [parse_estimator_spec(spec) for spec in args.estimator],
                                       progress=sys.stderr.isatty())
    width = max(len(r.name) for r in replays)
    print(f"{'estimator'.ljust(width)}  deviation from exact: max [um]  RMS [um]")
    for replay in replays:
        print(f"{replay.name.ljust(width)}  {replay.deviation_max * 1e6:>28.4g}  {replay.deviation_rms * 1e6:>8.4g}")


def _plot(args):
    import numpy as np

    from .records.analysis import figures, html_report, write_figures
    from .records.scoring import curve_of, read_run, score_run
    from .records import outputs
    if args.baseline:
        args.bags = [args.baseline] + [bag for bag in args.bags if bag != args.baseline]
    out = outputs.active().claim_folder(args.out or Path(args.bags[0]).with_suffix(""), "--out")
    if args.html:
        outputs.active().claim(out / "report.html", outputs.HTML, "--html")
    given = _given(args)
    runs, scores = [], []
    for bag in args.bags:        # a run that cannot be scored (diverged, no steps) is still drawn
        run = read_run(bag, progress=sys.stderr.isatty(), **given)
        _warn(run)
        try:
            with np.errstate(all="ignore"):
                scores.append(score_run(curve_of(run), run.result, experiment=run.experiment))
        except (ContouringError, ValueError, ArithmeticError) as error:
            print(f"warning: {bag}: not scored ({error})", file=sys.stderr)
            scores.append(None)
        runs.append((Path(bag).stem, run))
    drawn = figures(runs, args.magnification)
    for path in write_figures(runs, out, drawn=drawn):
        print(path)
    if args.html:
        print(html_report(runs, scores, out / "report.html", drawn=drawn))


def _export(args):
    from .records.export import export_bag
    from .records import outputs
    if args.csv is None and args.parquet is None:
        raise ConfigError("export needs --csv DIR and/or --parquet DIR")
    for option, folder, suffix, kind in (("--csv", args.csv, ".csv", outputs.EXPORT_CSV),
                                         ("--parquet", args.parquet, ".parquet", outputs.PARQUET)):
        if folder is not None:
            outputs.active().claim_folder(folder, option)
            for bag in args.bags:
                outputs.active().claim(Path(folder) / f"{Path(bag).stem}{suffix}", kind, option)
    given = _given(args)
    for bag in args.bags:
        written, warnings = export_bag(bag, args.csv, args.parquet, **given)
        for warning in warnings:
            print(f"warning: {warning}", file=sys.stderr)
        for path in written:
            print(path)


def _sweep(args):
    from datetime import datetime
    from .experiment.files import load_experiment
    import time

    from .studies.sweep import BATCH, format_sweep, run_sweep, sweep_summary, write_sweep_csv
    from .experiment.settings import parse_grid
    from .records import outputs
    experiment = load_experiment(_experiment_path(args.config))
    if args.batch is not None and args.batch < 1:
        raise ConfigError(f"--batch {args.batch}: expected a positive number of combinations")
    out = Path(args.out or f"bags/{experiment.name}_sweep_{datetime.now():%Y%m%d_%H%M%S}.csv")
    outputs.active().claim(out, outputs.SWEEP_CSV, "--out")
    started = time.monotonic()
    rows = run_sweep(experiment.text, parse_grid(args.grid), args.workers, progress=None,
                     batch=args.batch or BATCH, from_time=args.from_time, scheduler=args.scheduler)
    if args.from_time:
        print(f"scores of the samples at t >= {args.from_time:g} s (steady state)")
    print(format_sweep(rows))
    workers = args.workers or os.cpu_count() or 1
    print(sweep_summary(rows, time.monotonic() - started, workers) if not args.scheduler else
          sweep_summary(rows, time.monotonic() - started, workers).replace(
              f"on {workers} process{'es' if workers != 1 else ''}", f"on the cluster at {args.scheduler}"))
    write_sweep_csv(rows, out, experiment.axes)
    print(f"ranked results: {out}")


def _paper(args):
    from .studies.paper import available_papers, paper_report, write_report
    papers = available_papers()
    if args.paper != "all" and args.paper not in papers:
        raise ConfigError(f"paper {args.paper!r}: no scenario files config/paper{args.paper}_*.yaml "
                          f"(papers with scenarios: {', '.join(papers)}, or all)")
    from .records import outputs
    out = outputs.active().claim_folder(args.out, "--out")
    outputs.active().claim(out / ("papers.md" if args.paper == "all" else f"paper{args.paper}.md"), outputs.REPORT,
                           "--out")
    outputs.active().claim(out / ("claims.md" if args.paper == "all" else f"claims_paper{args.paper}.md"),
                           outputs.REPORT, "--out")
    say = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    chosen = papers if args.paper == "all" else [args.paper]
    if args.readings:
        from .studies.readings import analyse, readings_files, readings_report
        with_readings = {path.stem[5:] for path in readings_files()}
        if args.paper != "all" and args.paper not in with_readings:
            raise ConfigError(f"paper {args.paper}: no config/readings/paper{args.paper}.yaml (papers with "
                              f"readings: {', '.join(sorted(with_readings))})")
    sections = []
    for p in chosen:
        sections.append(paper_report(p, graph=args.graph, progress=say))
        if args.readings and p in with_readings:
            say(f"paper {p}: measuring its open readings")
            sections.append(readings_report(analyse(p, workers=args.workers)))
    text = "\n\n".join(sections)
    print(text)
    print(f"wrote {write_report(text, args.paper, args.out, args.readings)}", file=sys.stderr)
    if args.readings:
        return
    from .studies.claims_file import claim_files
    from .studies.claims_report import claims_report, write_claims_report
    with_claims = [p for p in chosen if any(path.stem == f"paper{p}" for path in claim_files())]
    if with_claims:
        report = claims_report(with_claims, args.out, maps=not args.no_maps, workers=args.workers, progress=say,
                               command=args.paper, scheduler=args.scheduler)
        name = "claims.md" if args.paper == "all" else f"claims_paper{args.paper}.md"
        print(f"wrote {write_claims_report(report, args.out, name)}", file=sys.stderr)


# the options that name what a command writes; every other path on its command line is an input
_OUTPUT_OPTIONS = {"run": ("bag",), "export": ("csv", "parquet"), "blocks": ("csv",), "sweep": ("out",),
                   "plot": ("out",), "paper": ("out",), "benchmark": ("out", "save_part")}


def _inputs(args) -> list:
    """The files a command reads, as named on its command line (its experiment file by scenario name too):
    never replaced by its outputs (:mod:`contouring_ros.records.outputs`)."""
    found = []
    for key, value in vars(args).items():
        if key in _OUTPUT_OPTIONS.get(args.command, ()) or key == "func":
            continue
        for item in value if isinstance(value, list) else [value]:
            if not isinstance(item, str) or not item or "\0" in item:
                continue
            try:
                path = _experiment_path(item) if key == "config" else Path(item)
                if path.is_file():
                    found.append(path)
            except (OSError, ContouringError, ValueError):
                continue
    return found


def _force_option(parser) -> None:
    parser.add_argument("--force", action="store_true",
                        help="replace an existing file that is not this command's own kind of output (never one "
                             "of its inputs)")


def _scheduler_option(parser) -> None:
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run on the Dask distributed cluster whose scheduler is at ADDRESS (e.g. "
                             "tcp://10.0.0.5:8786) instead of local processes; same results (--workers is then "
                             "the cluster's thread count)")


def _benchmark(args):
    from .studies.benchmark_report import main_benchmark
    from .studies.tuning import Protocol
    if args.budget < 2:
        raise ConfigError(f"--budget {args.budget}: expected at least 2 evaluations per combination")
    if args.draws < 1:
        raise ConfigError(f"--draws {args.draws}: expected at least 1 draw per combination")
    if args.searches < 1:
        raise ConfigError(f"--searches {args.searches}: expected at least 1 search per combination")
    max_searches = args.max_searches if args.max_searches is not None else max(Protocol.max_searches, args.searches)
    if max_searches < args.searches:
        raise ConfigError(f"--max-searches {max_searches}: expected at least --searches ({args.searches})")
    protocol = Protocol(evaluations=args.budget, draws=args.draws, searches=args.searches, max_searches=max_searches)
    command = "contouring-ros benchmark" + (f" --scenarios {' '.join(args.scenarios)}" if args.scenarios else "") \
        + (f" --budget {args.budget}" if args.budget != Protocol.evaluations else "") \
        + (f" --draws {args.draws}" if args.draws != Protocol.draws else "") \
        + (f" --searches {args.searches}" if args.searches != Protocol.searches else "") \
        + (f" --max-searches {max_searches}" if max_searches != Protocol.max_searches else "") \
        + (f" --methods {' '.join(args.methods)}" if args.methods else "")
    from .records import outputs
    out = outputs.active().claim_folder(args.out, "--out")
    for name, kind in (("benchmark.md", outputs.REPORT), ("benchmark.csv", outputs.BENCHMARK_CSV),
                       ("benchmark_heatmap.png", outputs.PNG)):
        outputs.active().claim(out / name, kind, "--out")
    if args.save_part:
        outputs.active().claim(args.save_part, outputs.PART, "--save-part")
    if args.checkpoints:
        outputs.active().claim_folder(args.checkpoints, "--checkpoints")
    if args.from_parts:
        from .studies.benchmark_parts import load_parts
        from .studies.benchmark_report import write_outputs
        if args.methods or args.scenarios or args.save_part or args.checkpoints:
            raise ConfigError("--from-parts runs nothing: --methods, --scenarios, --save-part and --checkpoints belong "
                              "to the runs that wrote the parts")
        md, table, png = write_outputs(load_parts(args.from_parts), args.out)
        print(f"wrote {md}, {table} and {png} from {len(args.from_parts)} parts")
        return
    say = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    md, table, png, seconds = main_benchmark(args.scenarios, protocol, args.out, args.workers,
                                             progress=sys.stderr.isatty(), say=say, command=command,
                                             scheduler=args.scheduler, save_part_to=args.save_part,
                                             host=args.host or "", methods=args.methods or (),
                                             checkpoints=args.checkpoints)
    print(f"wrote {md}, {table} and {png} in {seconds / 60:.1f} min" + (f"; the part in {args.save_part}"
                                                                         if args.save_part else ""))


def main(argv=None):
    parser = _Parser(prog="contouring-ros", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("run", help="run an experiment through the node graph, record a bag, print its scores")
    p.add_argument("config", nargs="?", default=DEFAULT_EXPERIMENT, help=f"experiment YAML (default {DEFAULT_EXPERIMENT})")
    p.add_argument("--bag", help="bag to write (default bags/<experiment>_<time>.mcap)")
    p.add_argument("--composed", action="store_true", help="run every node in one process under one executor "
                   "(default: the experiment's layout key, else a process per node)")
    p.add_argument("--process", action="store_true", help="run every node in its own process, whatever the "
                   "experiment's layout key says")
    p.add_argument("--group", action="append", metavar="NODE,NODE,...",
                   help="grouped layout: run these nodes (e.g. x/plant,x/servo) in one process on the composed "
                        "loop; repeat for more groups; every node in no group runs in its own process")
    p.add_argument("--namespace", default="/", metavar="NS",
                   help="run every node and topic under /NS (e.g. m1: /m1/x/plant publishes /m1/x/state)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="change one key of the experiment for this run, with the sweep's key syntax (x/servo.kp=10, "
                        "ccc.kp=2, curve.h=80); repeatable")
    p.add_argument("--from", dest="from_time", type=_seconds, default=0.0, metavar="T",
                   help="print the scores of the samples at t >= T s (steady state), as score --from T; the bag "
                        "holds the whole run")
    p.add_argument("--domain", type=_domain_id, metavar="ID",
                   help="run on this ROS domain, shared with ROS tools and other runs there (give each graph its "
                        "own --namespace) instead of a private one")
    _force_option(p)
    p.set_defaults(func=_run)
    p = sub.add_parser("simulate", help="run an experiment in-process (no ROS) and print its scores")
    p.add_argument("config")
    p.add_argument("--bag", nargs="?", const=_DEFAULT_BAG, metavar="PATH",
                   help="also write the run's bag, the MCAP the node graph would record (the same payloads), to "
                        "PATH (never over an existing file); --bag alone: bags/<experiment>_<time>.mcap")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="change one key of the experiment for this run, as `run --set` does; repeatable")
    p.add_argument("--from", dest="from_time", type=_seconds, default=0.0, metavar="T",
                   help="score only the samples at t >= T seconds (steady state), as `score --from` does")
    p.set_defaults(func=_simulate)
    experiment_help = "experiment YAML, for bags recorded without one (e.g. by ros2 bag record)"
    p = sub.add_parser("score", help="score bags from their contents alone")
    p.add_argument("bags", nargs="+")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--from", dest="from_time", type=_seconds, default=0.0, metavar="T",
                   help="score only the samples at t >= T seconds (steady state; same keys)")
    p.add_argument("--experiment", help=experiment_help)
    p.set_defaults(func=_score)
    p = sub.add_parser("blocks", help="results per block of tool path runs, and the scores of their cutting moves")
    p.add_argument("bags", nargs="+")
    p.add_argument("--csv", metavar="DIR", help="also write <bag>_blocks.csv per bag into DIR")
    p.add_argument("--experiment", help=experiment_help)
    _force_option(p)
    p.set_defaults(func=_blocks)
    p = sub.add_parser("compare", help="score runs side by side, with ratios to a baseline")
    p.add_argument("bags", nargs="+")
    p.add_argument("--baseline", help="the bag the ratios refer to (default: the first)")
    p.add_argument("--experiment", help=experiment_help)
    p.set_defaults(func=_compare)
    p = sub.add_parser("replay", help="run other estimators over a recorded run, or republish a bag")
    p.add_argument("bag")
    p.add_argument("--estimator", action="append", help="NAME[:key=value,...], repeatable (e.g. newton:k_prime=800)")
    p.add_argument("--play", action="store_true", help="republish the bag on ROS topics with /clock")
    p.add_argument("--rate", type=_rate, default=1.0, help="with --play: speed factor, 0 = as fast as possible")
    p.add_argument("--loop", action="store_true",
                   help="with --play: play again and again until Ctrl-C (/clock restarts with the bag each pass)")
    p.add_argument("--start", type=_seconds, default=0.0, metavar="T",
                   help="with --play: skip the messages before T seconds after the bag's first")
    p.add_argument("--topics", metavar="/A,/B", help="with --play: play only these topics (/clock is still published)")
    p.add_argument("--wait-subscribers", type=_whole(0, MAX_WAIT_SUBSCRIBERS, "subscribers"), default=1, metavar="N",
                   help="with --play: wait until N nodes subscribe to the bag's topics before publishing "
                        "(default 1; 0: start at once)")
    p.add_argument("--wait-timeout", type=_seconds_at_most(86400.0), default=10.0, metavar="S",
                   help="with --play: publish anyway after S seconds without them (default 10)")
    p.add_argument("--experiment", help=experiment_help)
    p.set_defaults(func=_replay)
    p = sub.add_parser("plot", help="PNG figures of one run or a comparison, and an HTML report")
    p.add_argument("bags", nargs="+")
    p.add_argument("--out", help="directory for the figures (default: next to the first bag)")
    p.add_argument("--html", action="store_true", help="also write a self-contained report.html")
    p.add_argument("--magnification", type=_magnification, help="contour error magnification in the path plot")
    p.add_argument("--baseline", help="with --html: the bag the ratios refer to (default: the first)")
    p.add_argument("--experiment", help=experiment_help)
    _force_option(p)
    p.set_defaults(func=_plot)
    p = sub.add_parser("export", help="every signal of every step of bags, with the exact contour error, as tables")
    p.add_argument("bags", nargs="+")
    p.add_argument("--csv", metavar="DIR", help="write DIR/<bag>.csv (column names carry units and axis names)")
    p.add_argument("--parquet", metavar="DIR", help="write DIR/<bag>.parquet (needs pyarrow)")
    p.add_argument("--experiment", help=experiment_help)
    _force_option(p)
    p.set_defaults(func=_export)
    p = sub.add_parser("sweep", help="in-process runs over a parameter grid, ranked by MCE and TACE")
    p.add_argument("config")
    p.add_argument("--grid", action="append", required=True,
                   help="KEY=V1,V2,... (repeatable), e.g. ccc.kp=0.5,1,2 or curve.h=50,100")
    p.add_argument("--workers", type=_whole(1, MAX_WORKERS, "processes"),
                   help=f"processes, 1 to {MAX_WORKERS} (default: one per core; never more than there are tasks)")
    p.add_argument("--batch", type=_whole(1, MAX_BATCH, "combinations"), default=None,
                   help=f"at most this many combinations per vectorised batch, 1 to {MAX_BATCH} (default 250; 1: each "
                        "alone)")
    p.add_argument("--from", dest="from_time", type=_seconds, default=0.0, metavar="T",
                   help="score only the samples at t >= T seconds (steady state)")
    p.add_argument("--out", help="CSV of the ranked results (default bags/<experiment>_sweep_<time>.csv)")
    _scheduler_option(p)
    _force_option(p)
    p.set_defaults(func=_sweep)
    p = sub.add_parser("paper", help="run a paper's scenarios and print our numbers beside the paper's")
    p.add_argument("paper", help="paper number with scenario files in config/ (e.g. 000, 003) or 'all'")
    p.add_argument("--out", default="reports", help="folder for the Markdown report (default: reports/)")
    p.add_argument("--graph", action="store_true", help="run each scenario through the node graph too")
    p.add_argument("--no-maps", action="store_true", help="write the claims report without computing the regime maps")
    p.add_argument("--readings", action="store_true",
                   help="instead of the claims: each open reading's effect on every figure, the single reading "
                        "closest to the paper's figures and what explains the rest of each gap "
                        "(config/readings/paper<N>.yaml)")
    p.add_argument("--workers", type=_whole(1, MAX_WORKERS, "processes"),
                   help=f"processes for the claims and maps, 1 to {MAX_WORKERS} (default: one per core)")
    _scheduler_option(p)
    _force_option(p)
    p.set_defaults(func=_paper)
    from .studies.tuning import Protocol
    p = sub.add_parser("benchmark", help="every estimator x controller (x servo) on every paper scenario, each gain "
                                         "tuned under equal constraints on a realistic machine, with intervals")
    p.add_argument("--scenarios", nargs="+", metavar="NAME",
                   help="scenarios (or scenario files) by name or glob, e.g. 'paper000_*' (default: the papers' own "
                        "experiments; the claims' mechanism scenarios with e.g. '*_mech_*')")
    p.add_argument("--budget", type=_whole(2, MAX_BUDGET, "evaluations"), default=Protocol.evaluations,
                   help=f"evaluations of each search at most, 2 to {MAX_BUDGET} (default {Protocol.evaluations})")
    p.add_argument("--draws", type=_whole(1, MAX_DRAWS, "draws"), default=Protocol.draws,
                   help=f"noise-seed and model-mismatch draws per tuned combination, 1 to {MAX_DRAWS} (default "
                        f"{Protocol.draws})")
    p.add_argument("--searches", type=_whole(1, MAX_SEARCHES, "searches"), default=Protocol.searches,
                   help="independent searches per combination (seeds 1, 2, ...; the first from the file's gains), "
                        "each of at most --budget evaluations; a row is converged when "
                        f"{Protocol.agree} of them end within {100 * Protocol.agreement:g}%% of the best nominal TACE; "
                        "the robust result with the lowest nominal TACE is kept, the same for every method "
                        f"(1 to {MAX_SEARCHES}, default {Protocol.searches})")
    p.add_argument("--max-searches", type=_whole(1, MAX_SEARCHES, "searches"),
                   help="while a row's searches do not agree, as many more as the agreement lacks run side by side, up to "
                        f"this many, the same cap for every method (at least --searches, at most {MAX_SEARCHES}; default "
                        f"{Protocol.max_searches})")
    p.add_argument("--out", default="reports", help="folder for benchmark.md, .csv and the figures (default: reports/)")
    p.add_argument("--workers", type=_whole(1, MAX_WORKERS, "processes"),
                   help=f"processes, 1 to {MAX_WORKERS} (default: one per core; never more than there are tasks)")
    p.add_argument("--save-part", metavar="FILE", help="also keep this run's rows in FILE, to report them with other "
                                                       "parts (e.g. each paper run on another machine)")
    p.add_argument("--methods", nargs="+", metavar="GLOB",
                   help="only the combinations whose estimator, controller or servo set matches, e.g. 'ilc' "
                        "'mpcc' (and each scenario's proposed combination); with --save-part, a later "
                        "--from-parts puts their rows in place of an earlier full run's")
    p.add_argument("--checkpoints", metavar="DIR",
                   help="keep each tuned row in DIR (made if missing) as it finishes, and take the rows kept there by an earlier run of "
                        "the same scenario, settings and code instead of tuning them again: a run stopped part way "
                        "goes on where it stopped")
    p.add_argument("--host", help="the machine's name or description a saved part records (default: none)")
    p.add_argument("--from-parts", nargs="+", metavar="FILE", help="run nothing: write the report, CSV and figures "
                                                                   "from parts saved by --save-part")
    _scheduler_option(p)
    _force_option(p)
    p.set_defaults(func=_benchmark)
    args = parser.parse_args(argv)
    try:
        from .records.outputs import Outputs
        if getattr(args, "scheduler", None):     # before any work: one line within 30 s if it is not one
            from .studies.executors import probe_scheduler
            probe_scheduler(args.scheduler)
        with Outputs(_inputs(args), force=getattr(args, "force", False)):
            args.func(args)
    except ContouringError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:        # output piped into head and the like
        sys.stdout = open(os.devnull, "w")
        return 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
