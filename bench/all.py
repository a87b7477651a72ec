"""One command for the speed figures of the README's Speed section: everything measured in one run, with the ratios.

Prints, on this machine, now:
- the rclpy ping-pong floor: time per message hop between two processes on the graph's lean loop, and the
  same on rclpy's EventsExecutor and SingleThreadedExecutor (wall time per hop and CPU time per round);
- the graph's lockstep rate (control steps per wall second, measured by the recorder between the first and
  last message) for every layout (process: a process per node; composed: one process; grouped: a process
  per axis' plant and servo, one for the interpolator, estimator and CCC, the recorder alone; grouped-lean:
  every node but the recorder in one process, the recorder in another), with 2 axes (the default
  experiment) and 3 axes (config/line3d_newton_ismc.yaml), and each as a multiple of four floor hops (the
  lockstep critical path is plant -> estimator -> CCC -> servo -> plant); the best grouping;
- lockstep steps/s against axes (an N-axis line, ``--axes 2,3,5,8``) for every layout;
- the CPU time the whole graph spends per lockstep step (2 axes, every layout: a run and one three times
  as long, differenced) and the rate that caps on this machine's cores;
- realtime mode at 1 kHz for every layout (``on_overrun: skip``, so that a run the machine cannot keep up
  with completes; a skipped tick counts as a miss): deadline-miss rate over all nodes and the worst
  node's, skipped ticks, loop latency p50 / p99 and work time p50;
- the in-process simulation's rate (and real-time factor) and the sweep throughput: 1000 configurations of
  the default experiment (vectorised batches on a process pool), and the same sweep one configuration at a
  time on the pool (``--sweep-alone``, 100 configurations), with the ratio.

Usage: python bench/all.py [--seconds 2] [--realtime-seconds 10] [--axes 2,3,5,8] [--sweep 1000] [--sweep-alone 100]
Figures vary run to run on a shared machine: compare the ratios within one run.
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contouring_ros.records.bag_reader import node_reports  # noqa: E402
from contouring_ros.experiment.files import load_experiment  # noqa: E402
from contouring_ros.errors import RunError  # noqa: E402
from contouring_ros.run.runner import DomainLease, private_environment  # noqa: E402
from contouring_ros.records.scoring import miss_rate  # noqa: E402
from contouring_ros.studies.sweep import BATCH, run_sweep  # noqa: E402
from graph_speed import LAYOUTS, line_experiment, lockstep_run, run_layout, simulation_rate  # noqa: E402
# (bench/ is this script's folder)

DEFAULT = ROOT / "config" / "paper000_b_ismc_h50_newton.yaml"
THREE_AXES = ROOT / "config" / "line3d_newton_ismc.yaml"


def children_cpu_seconds() -> float:
    """User + system CPU time of every child process this one has waited for (the graph's nodes)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def cpu_per_step(path: Path, layout: str, seconds: float, tmp: Path) -> float:
    """CPU seconds the whole graph spends per lockstep step: the difference between a run of ``seconds`` and
    one three times as long, so start-up and shutdown cancel."""
    cpu, steps = [], []
    for duration in (seconds, 3 * seconds):
        config = tmp / f"cpu_{layout}_{duration:g}.yaml"
        config.write_text(with_globals(path, duration=duration))
        before = children_cpu_seconds()
        run_layout(config, tmp / f"cpu_{layout}_{duration:g}.mcap", layout)
        cpu.append(children_cpu_seconds() - before)
        steps.append(load_experiment(config).n_steps)
    return (cpu[1] - cpu[0]) / (steps[1] - steps[0])


def with_globals(path: Path, **keys) -> str:
    """The experiment text with extra shared keys (duration, timing) after sample_time."""
    extra = "".join(f"\n    {key}: {value}" for key, value in keys.items())
    return path.read_text().replace("    sample_time: 0.001", "    sample_time: 0.001" + extra, 1)


PINGPONG_TIMEOUT = 60.0   # s for one ping-pong run (a few seconds when it works; one run in about 30 hangs here)


def floor_hop_us(rounds: int, executor: str = "lean", timeout: float = PINGPONG_TIMEOUT,
                 tries: int = 1) -> tuple[float, float]:
    """The ping-pong between two processes on ``executor`` (lean: the graph's own loop; events: rclpy's
    EventsExecutor; single: its SingleThreadedExecutor): (wall us per hop, ping's CPU us per round).
    A run that takes longer than ``timeout`` seconds is abandoned and run again, up to ``tries`` runs in all;
    then subprocess.TimeoutExpired is raised."""
    for attempt in range(1, tries + 1):
        try:
            return _ping_pong(rounds, executor, timeout)
        except subprocess.TimeoutExpired:
            if attempt == tries:
                raise
            print(f"(a ping-pong run on {executor} hung for {timeout:g} s; running it again)", flush=True)


def _ping_pong(rounds: int, executor: str, timeout: float) -> tuple[float, float]:
    with DomainLease() as lease:
        env = private_environment(lease.domain_id)
        script = str(ROOT / "bench" / "pingpong.py")
        pong = subprocess.Popen([sys.executable, script, "pong", str(rounds), executor], env=env,
                                stdout=subprocess.DEVNULL)
        try:
            out = subprocess.run([sys.executable, script, "ping", str(rounds), executor], env=env,
                                 capture_output=True, text=True, timeout=timeout)
            pong.wait(timeout=30)
        finally:
            if pong.poll() is None:    # ping hung or failed: pong waits for a message that never comes
                pong.kill()
                pong.wait()
    figures = dict(line.split() for line in out.stdout.splitlines() if line.startswith(("hop_us", "cpu_us")))
    if "hop_us" not in figures:
        raise SystemExit(f"ping-pong failed: {out.stderr.strip().splitlines()[-1:]}")
    return float(figures["hop_us"]), float(figures["cpu_us_per_round"])


def lockstep_rate(path: Path, layout: str, seconds: float, tmp: Path, runs: int) -> float:
    config = tmp / f"lockstep_{path.stem}.yaml"
    config.write_text(with_globals(path, duration=seconds))
    return statistics.median(lockstep_run(config, tmp / f"{path.stem}_{layout}_{i}.mcap", layout)[1]
                             for i in range(runs))


def realtime(layout: str, seconds: float, tmp: Path) -> dict:
    """One realtime run's figures; {"error": ...} when the run failed (e.g. a graph that came up late)."""
    config = tmp / "realtime.yaml"
    config.write_text(with_globals(DEFAULT, duration=seconds, timing="realtime", on_overrun="skip"))
    try:
        bag = run_layout(config, tmp / f"realtime_{layout}.mcap", layout)
    except RunError as error:
        return {"error": str(error)}
    reports = {name: v for name, v in node_reports(bag).items() if "deadline misses" in v}
    skipped = {name: int(v.get("skipped ticks", 0)) for name, v in reports.items()}
    ticks = sum(int(v["ticks"]) + skipped[name] for name, v in reports.items())
    misses = sum(int(v["deadline misses"]) + skipped[name] for name, v in reports.items())
    return {"miss rate": 100.0 * misses / ticks, "worst node miss rate": max(map(miss_rate, reports.values())),
            "skipped": sum(skipped.values()),
            "p50": statistics.median(float(v["latency p50 [us]"]) for v in reports.values()),
            "p99": max(float(v["latency p99 [us]"]) for v in reports.values()),
            "work": {name: float(v["work p50 [us]"]) for name, v in reports.items() if "work p50 [us]" in v}}


def axes_rate(n_axes: int, layout: str, seconds: float, tmp: Path) -> float:
    config = tmp / f"line{n_axes}d.yaml"
    config.write_text(line_experiment(n_axes, seconds))
    return lockstep_run(config, tmp / f"line{n_axes}d_{layout}.mcap", layout)[1]


def sweep_rate(configs: int, batch: int | None = None) -> float:
    """Configurations per second of a sweep over ccc.kp on the default experiment (``batch``: at most
    that many per vectorised batch; 1 runs every configuration alone)."""
    text = DEFAULT.read_text()
    grid = {"ccc.kp": [0.5 + 2.0 * i / configs for i in range(configs)]}
    start = time.perf_counter()
    run_sweep(text, grid, batch=batch or BATCH)
    return configs / (time.perf_counter() - start)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated seconds per lockstep run")
    parser.add_argument("--runs", type=int, default=3, help="lockstep runs per case (median)")
    parser.add_argument("--realtime-seconds", type=float, default=10.0)
    parser.add_argument("--axes", default="2,3,5,8", help="axis counts of the lockstep sweep over axes")
    parser.add_argument("--rounds", type=int, default=5000, help="ping-pong round trips")
    parser.add_argument("--sweep", type=int, default=1000, help="sweep configurations (vectorised)")
    parser.add_argument("--sweep-alone", type=int, default=100, help="sweep configurations run one by one")
    args = parser.parse_args()
    say = lambda *a: print(*a, flush=True)  # noqa: E731
    with tempfile.TemporaryDirectory() as directory:
        tmp = Path(directory)
        hop, cpu = floor_hop_us(args.rounds, tries=3)
        floor_rate = 1e6 / (4 * hop)
        say(f"ping-pong floor: {hop:.0f} us per hop ({cpu:.0f} us of CPU a round); four hops (one lockstep "
            f"step's critical path) {4 * hop:.0f} us = at most {floor_rate:.0f} steps/s")
        for executor, name in (("events", "EventsExecutor"), ("single", "SingleThreadedExecutor")):
            other, other_cpu = floor_hop_us(args.rounds, executor, tries=3)
            say(f"ping-pong on rclpy's {name}: {other:.0f} us per hop ({other / hop:.1f}x the lean loop), "
                f"{other_cpu:.0f} us of CPU a round ({other_cpu / cpu:.1f}x)")
        rates = {}
        for label, path in (("2 axes", DEFAULT), ("3 axes", THREE_AXES)):
            for layout in LAYOUTS:
                rates[label, layout] = rate = lockstep_rate(path, layout, args.seconds, tmp, args.runs)
                say(f"lockstep {layout:12s} {label}: {rate:5.0f} steps/s ({1e6 / rate:.0f} us/step = "
                    f"{1e6 / rate / (4 * hop):.1f} x four floor hops; real-time factor {rate / 1000:.2f})")
        for label in ("2 axes", "3 axes"):
            say(f"{label}, as a multiple of the process layout: " + ", ".join(
                f"{layout} {rates[label, layout] / rates[label, 'process']:.1f}x" for layout in LAYOUTS[1:]))
        groupings = [layout for layout in LAYOUTS if layout.startswith("grouped")]
        best = max(groupings, key=lambda layout: rates["2 axes", layout])
        say(f"best grouping in lockstep (2 axes): {best}, {rates['2 axes', best]:.0f} steps/s")
        axes = [int(n) for n in args.axes.split(",") if n]
        for layout in LAYOUTS:
            figures = [(n, axes_rate(n, layout, args.seconds, tmp)) for n in axes]
            say(f"lockstep {layout:12s} against axes: " + ", ".join(f"{n} axes {r:.0f}" for n, r in figures)
                + " steps/s" + (f"; {1e6 / figures[-1][1] - 1e6 / figures[0][1]:.0f} us more per step from "
                                f"{figures[0][0]} to {figures[-1][0]} axes" if len(figures) > 1 else ""))
        for layout in LAYOUTS:
            cores = 1 if layout == "composed" else os.cpu_count() or 1
            cpu = cpu_per_step(DEFAULT, layout, args.seconds, tmp)
            if cpu <= 0.0:   # the longer run took less CPU than the shorter: this machine's noise
                say(f"CPU per lockstep step, {layout:12s} 2 axes: not measurable in this run (the run three times "
                    f"as long took {-cpu * 1e6:.0f} us a step less CPU, not more)")
                continue
            say(f"CPU per lockstep step, {layout:12s} 2 axes: {cpu * 1e6:.0f} us over all nodes = at most "
                f"{cores / cpu:.0f} steps/s on {cores} {'core (one thread)' if cores == 1 else 'cores'} if nothing "
                "else ran")
        for layout in LAYOUTS:
            r = realtime(layout, args.realtime_seconds, tmp)
            if "error" in r:
                say(f"realtime {layout:12s} 1 kHz, {args.realtime_seconds:g} s: failed: {r['error']}")
                continue
            work = ", ".join(f"{name} {us:.0f}" for name, us in sorted(r["work"].items()))
            say(f"realtime {layout:12s} 1 kHz, {args.realtime_seconds:g} s: deadline misses {r['miss rate']:.1f}% of "
                f"all node ticks (worst node {r['worst node miss rate']:.1f}%; {r['skipped']} ticks skipped), "
                f"latency p50 {r['p50']:.0f} us, p99 {r['p99']:.0f} us; work p50 per node [us]: {work}")
        sim, factor = simulation_rate(DEFAULT)
        say(f"in-process simulation (median of 5): {sim:.0f} steps/s = {factor:.1f}x real time; "
            f"{sim / rates['2 axes', 'process']:.0f}x the process graph, {sim / rates['2 axes', 'composed']:.0f}x "
            "the composed graph")
        configs = sweep_rate(args.sweep)
        alone = sweep_rate(args.sweep_alone, batch=1)
        say(f"sweep: {configs:.1f} configurations/s vectorised ({args.sweep} of the default experiment in "
            f"{args.sweep / configs:.1f} s); one by one {alone:.1f}/s ({args.sweep_alone} configurations; 1000 "
            f"would take {1000 / alone:.0f} s); vectorised / one by one: {configs / alone:.1f}x")


if __name__ == "__main__":
    main()
