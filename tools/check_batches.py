"""Check that every benchmark combination's runs give the same numbers in a batch as alone, bit for bit.

A tuning runs its points in batches of whatever size a round has (and runs a group smaller than its
classes' batch minimum one by one), so a tuned figure must not depend on which runs shared a batch. For each
combination of each scenario (as ``contouring-ros benchmark`` plans them, on the scenario's realistic
machine), ``--points`` points drawn in the middle of its tuning space are run alone
(:func:`contouring_ros.core.simulation.simulate`) and as one batch
(:func:`contouring_ros.core.batch.simulate_batch`), and every recorded signal is compared. Prints one line
per combination whose batch differs (the first signal, step and values) or fails, a line per combination that
cannot run as a batch, and a summary; exits 1 where any differs or fails. Only the recorded signals are
compared (not an estimator's counters), and only points of a tuning space: a batch of loops that differ in
their curves' own numbers (a sweep over curve.omega, a tool path's members on different segments) still
evaluates some curve terms with numpy's power, which may part from a run alone in the last bit.

    python tools/check_batches.py                         # every scenario (about 5 min of CPU)
    python tools/check_batches.py --scenarios 'paper004_*' --points 3
"""
from __future__ import annotations

import argparse
import dataclasses
import fnmatch
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from contouring_ros.core.batch import NotBatchable, simulate_batch  # noqa: E402
from contouring_ros.core.simulation import simulate  # noqa: E402
from contouring_ros.errors import ConfigError, Diverged  # noqa: E402
from contouring_ros.experiment.build import build_loop  # noqa: E402
from contouring_ros.studies.benchmark import fit_to_machine, plan, reference_job, scenario_families  # noqa: E402
from contouring_ros.studies.outcomes import experiment_for  # noqa: E402
from contouring_ros.studies.tuner import Tuning  # noqa: E402
from contouring_ros.studies.tuning import Protocol  # noqa: E402

def first_difference(alone, batched) -> str:
    """'' where every signal of the two results is equal bit for bit, else the first that is not."""
    for name in (f.name for f in dataclasses.fields(alone)):
        a, b = np.asarray(getattr(alone, name)), np.asarray(getattr(batched, name))
        if a.shape != b.shape:
            return f"{name}: shape {a.shape} alone, {b.shape} batched"
        differs = ~((a == b) | (np.isnan(a) & np.isnan(b))) if a.dtype.kind == "f" else a != b
        if differs.any():
            where = tuple(int(i) for i in np.argwhere(differs)[0])
            return f"{name}[{', '.join(map(str, where))}]: {a[where]!r} alone, {b[where]!r} batched " \
                   f"({int(differs.sum())} values differ)"
    return ""


def first_steps(result, steps: int):
    """``result`` (a SimulationResult) cut to its first ``steps`` steps."""
    return dataclasses.replace(result, **{f.name: getattr(result, f.name)[:steps] for f in dataclasses.fields(result)})


def experiments(family, reference, combo, points: int, seed: int) -> list:
    """``points`` experiments of the combination at points drawn uniformly in the middle half of its box (the
    first that build of at most 20 x ``points`` draws), its integer coordinates those of the first point (an
    MPCC's horizon: a batch shares one); ``reference``: the scenario's :func:`reference_job`."""
    protocol = Protocol()
    data = family.data[family.proposed]
    tuning = Tuning(data, fit_to_machine(data, combo.sections, reference.machine), combo.gain_keys,
                    reference.machine, math.inf, family.from_time, protocol, f"{family.name} {combo.label}", 0.0)
    rng = np.random.default_rng(seed)
    dimensions = tuning.space.dimensions
    first = rng.uniform(0.25, 0.75, len(dimensions))
    out = []
    for j in range(20 * points):         # draws until ``points`` build (a ZPETC refuses many)
        if len(out) == points:
            break
        unit = first if j == 0 else rng.uniform(0.25, 0.75, len(dimensions))
        unit = [first[i] if d.scale == "int" else u for i, (d, u) in enumerate(zip(dimensions, unit))]
        _, gains = tuning.space.decode(unit)
        try:
            out.append(experiment_for(tuning.data, tuning.with_gains(gains), tuning.machine, tuning.where))
        except ConfigError:
            continue
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenarios", nargs="*", default=["*"], help="scenario names or globs (default: all)")
    parser.add_argument("--points", type=int, default=3, help="points of each combination, run alone and batched")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    families = [f for f in scenario_families() if any(fnmatch.fnmatch(f.name, p) for p in args.scenarios)]
    if not families:
        parser.error(f"no scenario matches {' '.join(args.scenarios)}")
    checked = differing = skipped = 0
    started = time.process_time()
    for family in families:
        reference = reference_job(family.data[family.proposed], family.from_time, family.name, Protocol())
        for combo in plan(family)[0]:
            label = f"{family.name} {combo.label}"
            print(f"{label} ...", end="\r", flush=True)
            loops_of = experiments(family, reference, combo, args.points, args.seed)
            if len(loops_of) < 2:
                print(f"{label}: skipped (fewer than 2 points build)")
                skipped += 1
                continue
            try:
                batched = simulate_batch([build_loop(e) for e in loops_of])
            except NotBatchable as why:
                print(f"{label}: not batchable ({why})")
                skipped += 1
                continue
            except (ArithmeticError, ValueError, RuntimeError) as error:      # its runs alone may not: a defect
                print(f"{label}: the batch failed ({type(error).__name__}: {error})")
                differing += 1
                continue
            checked += 1
            for j, experiment in enumerate(loops_of):
                try:
                    alone, member = simulate(build_loop(experiment)), batched[j]
                except Diverged as diverged:      # alone it stops where it diverges; a batch goes on
                    if diverged.result is None:
                        continue
                    alone, member = diverged.result, first_steps(batched[j], diverged.step)
                why = first_difference(alone, member)
                if why:
                    differing += 1
                    print(f"{label}: member {j} differs from its run alone: {why}")
                    break
    print(f"{checked} combinations checked, {differing} differ or fail, {skipped} not run as batches; "
          f"{time.process_time() - started:.0f} s of CPU")
    return 1 if differing else 0


if __name__ == "__main__":
    sys.exit(main())
