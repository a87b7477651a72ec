"""Parameter sweeps: the in-process simulation over every combination of a grid.

Combinations of one structure (the same curve, schedule, plant, servo, estimator and controller classes)
run vectorised, up to ``BATCH`` at a time along a batch axis (:mod:`contouring_ros.core.batch`), where
every class has a batch path; the others run one by one. Batches and single runs share a process pool.

A grid key names a place in the experiment file: ``<node section>.<key>[.<subkey>]`` for a node's
parameter (``ccc.kp``, ``x/servo.a``, ``contour_estimator.k_prime``) or ``<key>[.<subkey>]`` for a shared
one (``curve.h``, ``schedule.duration``). Every combination is validated like a file before it runs.
"""
from __future__ import annotations

import contextlib
import copy
import csv
import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..core import progress
from ..core.batch import NotBatchable, batch_minimum, batch_problem, frame, loop_parts, simulate_batch, structure
from ..core.simulation import first_divergence, simulate
from ..errors import ConfigError, Diverged, ScoreError
from ..experiment.build import build_loop
from ..experiment.ros_yaml import read_yaml
from ..experiment.settings import apply_settings
from ..experiment.validate import experiment_from_data
from ..notices import progress_of
from ..records.outputs import write_atomically
from ..records.scoring import score_run
from .executors import pool as executor
from .shared_batches import current_batches

__all__ = ["experiments_for", "combinations",
           "SweepRow", "score_one", "score_experiments", "simulate_experiments",
           "simulate_loops", "run_sweep", "sweep_summary", "format_sweep",
           "write_sweep_csv"]


def experiments_for(text: str, settings_list: list, where: str = "--grid") -> list:
    """(settings, validated experiment) for each settings mapping applied to the experiment ``text``.

    The file is read once; each combination is a copy of its data with the settings applied, validated
    like a file (an invalid one is refused naming its settings) without another YAML round trip.
    """
    base = read_yaml(text, "sweep")
    out = []
    for settings in settings_list:
        data = apply_settings(copy.deepcopy(base), settings)
        try:
            out.append((settings, experiment_from_data(data, "sweep combination")))
        except ConfigError as error:
            raise ConfigError(f"{where} {settings}: {error}") from None
    return out


MAX_COMBINATIONS = 50_000   # a sweep's combinations, at most: each validated experiment holds about 4.3 kB
#                             (paper000's file), so they stay within about 0.2 GB before their runs


def combinations(text: str, grid: dict) -> list:
    """(settings, validated experiment) for every combination of the grid's values. The count is checked
    against :data:`MAX_COMBINATIONS` from the lengths alone, before any combination is made (ConfigError)."""
    count = math.prod(len(values) for values in grid.values())
    if count > MAX_COMBINATIONS:
        sizes = " x ".join(str(len(values)) for values in grid.values())
        raise ConfigError(f"--grid: {sizes} = {count:.4g} combinations, over the {MAX_COMBINATIONS} a sweep runs "
                          "(fewer values, or several sweeps)")
    return experiments_for(text, (dict(zip(grid, values)) for values in itertools.product(*grid.values())))


BATCH = 250      # combinations per vectorised batch (memory: about 0.25 MB per combination and 1000 steps)
RUN_FAILURES = (ArithmeticError, ValueError)   # what a run that diverges raises (non-finite or huge states)


@dataclass(frozen=True)
class SweepRow:
    settings: dict
    scores: object             # Scores, or None when the run diverged
    alone: str = ""            # why it ran one by one ("" when it ran in a vectorised batch)
    failure: str = ""          # why it has no scores (the run diverged)

    @property
    def vectorised(self) -> bool:
        return not self.alone


def _finite(scores) -> bool:
    return all(math.isfinite(v) for v in (scores.mce, scores.tace, scores.rms))


def score_one(loop, result, from_time: float, experiment=None):
    """(scores, failure): a run's scores, or None and why when it diverged (``experiment``: the run's, for
    the in-position check that ends a tool path's motion, :func:`contouring_ros.records.scoring.score_run`)."""
    diverged = first_divergence(result.time, result.position, result.reference_position)
    if diverged:
        return None, diverged[1]
    try:
        scores = score_run(loop.curve, result, from_time, experiment)
    except (ScoreError, *RUN_FAILURES) as error:
        return None, f"cannot be scored: {error}"
    return (scores, "") if _finite(scores) else (None, "diverged: its contour error is not finite")


def _simulate_alone(loop):
    try:
        return simulate(loop), ""
    except Diverged as error:
        return None, str(error)
    except RUN_FAILURES as error:
        return None, f"diverged: {error}"


def _score_chunk(experiments: list, from_time: float = 0.0) -> tuple:
    """Scores of each experiment (None where the run diverged), why each ran alone ("" for those in a
    vectorised batch, one batch per structure) and why each has no scores ("" where it has)."""
    before = progress.added()
    with np.errstate(all="ignore"):         # a diverging run overflows; it is reported, not warned about
        out = _score_loops(experiments, from_time)
    # the steps a diverged run did not take: the progress bar counts every combination's steps once
    progress.add(sum(e.n_steps for e in experiments) - (progress.added() - before))
    return out


def _score_loops(experiments: list, from_time: float) -> tuple:
    loops, results, alone, failures = simulate_experiments(experiments)
    scores = [None] * len(loops)
    for i, (loop, result) in enumerate(zip(loops, results)):
        if result is not None:
            scores[i], failures[i] = score_one(loop, result, from_time, experiments[i])
    return scores, alone, failures


def simulate_experiments(experiments: list) -> tuple:
    """(loops, results, why each ran alone, why each has no result) for ``experiments``: the loops of one
    structure advance as one vectorised batch where every class has a batch path and the group is at least
    as large as its classes' :func:`~contouring_ros.core.batch.batch_minimum` (smaller groups cost less one
    by one), the others one by one; a result is None where the run diverged (and the failure says how)."""
    loops = [build_loop(e) for e in experiments]
    return (loops, *simulate_loops(loops))


def _simulate_round(loops: list) -> tuple:
    """A shared round's loops (:mod:`contouring_ros.studies.shared_batches`), run mixed."""
    return simulate_loops(loops, mixed=True)


def simulate_loops(loops: list, mixed: bool = False) -> tuple:
    """(results, why each ran alone, why each has no result) of built ``loops``, as
    :func:`simulate_experiments` runs them. ``mixed``: the groups of different structures along one path
    advance as one mixed batch (:func:`_simulate_mixed`); a run's numbers are those it has in a batch of its
    own structure.

    Where another thread shares its batches (:mod:`contouring_ros.studies.shared_batches`), the loops are
    handed to it and run with the other threads' loops of the same round, mixed."""
    shared = current_batches()
    if shared is not None:
        return shared.simulate(loops, _simulate_round)
    results, alone, groups = [None] * len(loops), [""] * len(loops), {}
    failures = [""] * len(loops)
    structures = [structure(loop) for loop in loops]
    for i, key in enumerate(structures):
        groups.setdefault(key, []).append(i)
    pending = list(groups.values())
    if mixed:
        pending = _simulate_mixed(loops, pending, results, structures)
    while pending:
        group = pending.pop()
        members = [loops[i] for i in group]
        why = batch_problem(members if len(members) > 1 else members * 2) \
            or ("" if len(members) > 1 else "no other combination of its kind to share a batch with")
        smallest, setter = batch_minimum(members[0])
        if not why and len(members) < smallest:
            why = (f"runs faster one by one: a batch with the {setter} pays off from {smallest} "
                   "combinations of one kind")
        batch = None
        if not why:
            try:
                batch = simulate_batch(members)
            except RUN_FAILURES:        # a member diverged: batch each half again, down to runs alone
                if len(group) >= 4:
                    pending += [group[:len(group) // 2], group[len(group) // 2:]]
                    continue
                why = "a member of its batch diverged"
        for j, i in enumerate(group):
            if batch:
                results[i] = batch[j]
            else:
                results[i], failures[i] = _simulate_alone(loops[i])
                alone[i] = why
    return results, alone, failures


#: member-steps of one mixed batch, at most: its signals take about 0.2 kB a member-step on two axes, so a
#: batch of 1000 members of 2000 steps holds about 0.45 GB while it is scored
MIXED_MEMBER_STEPS = 2_000_000


def _simulate_mixed(loops: list, groups: list, results: list, structures: list) -> list:
    """Run the structure ``groups`` (lists of indices into ``loops``, whose :func:`~contouring_ros.core.batch.structure`
    is ``structures``) that can share a mixed batch
    (:func:`contouring_ros.core.batch.simulate_batch` with ``mixed``: one :func:`~contouring_ros.core.batch.frame`,
    each structure batchable) together, their results into ``results``; returns the groups left to run as
    :func:`simulate_loops` runs them alone (a frame of one structure; a structure whose costly class, its
    :func:`~contouring_ros.core.batch.batch_minimum`, has fewer members in the frame than that minimum; a
    mixed batch in which a member failed). At most :data:`MIXED_MEMBER_STEPS` member-steps a batch."""
    left, frames = [], {}
    for group in groups:
        members = [loops[i] for i in group]
        if batch_problem(members if len(members) > 1 else members * 2):
            left.append(group)
        else:
            frames.setdefault(frame(members[0]), []).append(group)
    for together in frames.values():
        if len(together) == 1:
            left += together
            continue
        classes = [{type(part).__name__ for part in loop_parts(loops[g[0]])} for g in together]
        chosen = []
        for group, mine in zip(together, classes):
            smallest, setter = batch_minimum(loops[group[0]])
            sharing = sum(len(g) for g, theirs in zip(together, classes) if setter in theirs) if setter else len(group)
            (chosen if sharing >= smallest else left).append(group)
        for chunk in _member_chunks(chosen, loops[chosen[0][0]].n_steps if chosen else 1):
            indices = [i for group in chunk for i in group]
            try:
                batch = simulate_batch([loops[i] for i in indices], mixed=True,
                                       structures=[structures[i] for i in indices])
            except (NotBatchable, *RUN_FAILURES):
                left += chunk
                continue
            for j, i in enumerate(indices):
                results[i] = batch[j]
    return left


def _member_chunks(groups: list, steps: int) -> list:
    """``groups`` in chunks of at most :data:`MIXED_MEMBER_STEPS` member-steps (a group larger than that is cut)."""
    most = max(1, MIXED_MEMBER_STEPS // max(1, steps))
    chunks, chunk, size = [], [], 0
    for group in groups:
        for start in range(0, len(group), most):
            part = group[start:start + most]
            if size + len(part) > most and chunk:
                chunks.append(chunk)
                chunk, size = [], 0
            chunk.append(part)
            size += len(part)
    return chunks + ([chunk] if chunk else [])


def _shape(section):
    """A section's settings with every number blanked: experiments whose shapes are equal differ only in
    numbers, and so (almost always) build loops of one structure."""
    if isinstance(section, dict):
        return tuple((key, _shape(value)) for key, value in section.items())
    if isinstance(section, (list, tuple)):
        return tuple(_shape(value) for value in section)
    return None if isinstance(section, (int, float)) and not isinstance(section, bool) else section


def _chunks(experiments: list, workers: int, batch: int) -> list:
    """Indices of the experiments in chunks of one shape and step count each, at most ``batch`` long,
    spread so that every worker gets some. (Numbers can still change a loop's structure, say a branch
    check of 0 samples beside one of 256: the worker batches each structure of its chunk apart.)"""
    groups = {}
    for index, e in enumerate(experiments):
        key = (e.n_steps, e.sample_time, e.axes, _shape([e.curve, e.schedule, e.initial_state, e.plants, e.servos,
                                                          e.estimator, e.controller]))
        groups.setdefault(key, []).append(index)
    size = max(1, min(batch, math.ceil(len(experiments) / (2 * workers))))
    return [group[i:i + size] for group in groups.values() for i in range(0, len(group), size)]


def score_experiments(experiments: list, workers: int | None = None, progress_bar: bool | None = False,
                      batch: int = BATCH, from_time: float = 0.0, desc: str = "sweep",
                      scheduler: str | None = None) -> list:
    """(scores or None, why it ran alone, why it has no scores) for each experiment, in order: the
    in-process simulation on a process pool (or the Dask cluster at ``scheduler``,
    :func:`contouring_ros.studies.executors.pool`), vectorised where it can be. ``progress_bar``: a bar on stderr
    that moves with the simulated steps of every worker (False: none; None: a bar on a terminal, a line now
    and then otherwise, :class:`contouring_ros.notices.progress_of`)."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, wait

    out = [None] * len(experiments)
    steps = [e.n_steps for e in experiments]
    counted = None          # every worker's simulated steps (core/progress.py), where a bar shows them
    if progress_bar is not False and not scheduler:
        try:
            counted = multiprocessing.Value("q", 0)
        except OSError:     # no shared memory to be had (a full /dev/shm): the bar moves chunk by chunk
            counted = None
    shown = progress_of(len(experiments), desc, "combination", terminal=progress_bar) \
        if progress_bar is not False else contextlib.nullcontext(lambda done: None)
    with executor(workers, scheduler, progress.attach, (counted,), tasks=len(experiments)) as (pool, workers), \
            shown as show:
        chunks = _chunks(experiments, workers, batch)
        jobs = {pool.submit(_score_chunk, [experiments[i] for i in chunk], from_time): chunk for chunk in chunks}
        finished, pending = 0, set(jobs)
        while pending:
            done, pending = wait(pending, timeout=0.25, return_when=FIRST_COMPLETED)
            for job in done:
                chunk = jobs[job]
                for i, s, why, failure in zip(chunk, *job.result(), strict=True):
                    out[i] = (s, why, failure)
                finished += sum(steps[i] for i in chunk)
            # combinations done, in fractions as their steps go by (a cluster's workers count none: by chunk)
            counts = counted.value if counted is not None else 0
            show(round(len(experiments) * max(counts, finished) / max(1, sum(steps)), 2))
    return out


def _rank(row: SweepRow):
    return (0, row.scores.mce, row.scores.tace) if row.scores else (1, 0.0, 0.0)


def run_sweep(text: str, grid: dict, workers: int | None = None, progress: bool = False, batch: int = BATCH,
              from_time: float = 0.0, scheduler: str | None = None) -> list:
    """Score every combination (validated first), ranked by MCE then TACE, diverged runs last; at most
    ``batch`` combinations per vectorised batch (1: each alone); ``scheduler``: a Dask scheduler's address
    (:mod:`contouring_ros.studies.executors`); ``from_time`` as in
    :func:`contouring_ros.records.scoring.score_run`."""
    combos = combinations(text, grid)
    results = score_experiments([e for _, e in combos], workers, progress, batch, from_time, scheduler=scheduler)
    rows = [SweepRow(settings, *result) for (settings, _), result in zip(combos, results)]
    return sorted(rows, key=_rank)


def sweep_summary(rows: list, seconds: float, workers: int) -> str:
    """What a sweep did, in the user's terms: how many combinations in how long on how many processes, how
    many ran together in vectorised batches and how many one by one, and why (each reason once, with how
    many it held for), and how many diverged."""
    together = sum(row.vectorised for row in rows)
    reasons = {}
    for row in rows:
        if row.alone:
            reasons[row.alone] = reasons.get(row.alone, 0) + 1
    if not rows:
        return "no combinations"
    how = ("all run together in vectorised batches" if together == len(rows) else
           "all run one by one" if not together else
           f"{together} run together in vectorised batches, {len(rows) - together} one by one")
    why = "; ".join(f"{why} ({count})" if len(reasons) > 1 else why for why, count in reasons.items())
    line = (f"{len(rows)} combination{'s' if len(rows) != 1 else ''} in {seconds:.1f} s on {workers} "
            f"process{'es' if workers != 1 else ''}: {how}" + (f" ({why})" if why else ""))
    failed = sum(row.scores is None for row in rows)
    if failed:
        line += f"\n{failed} without scores (diverged), listed last with the reason"
    return line


def format_sweep(rows: list, limit: int = 20) -> str:
    keys = list(rows[0].settings) if rows else []
    head = ["rank"] + keys + ["MCE [um]", "TACE [um]", "RMS [um]"]
    lines = ["  ".join(f"{h:>12}" for h in head)]
    for rank, row in enumerate(rows[:limit], 1):
        cells = [str(rank)] + [str(row.settings[k]) for k in keys]
        if row.scores is None:
            cells += ["-", "-", "-"]
        else:
            cells += [f"{row.scores.mce * 1e6:.4g}", f"{row.scores.tace * 1e6:.4g}", f"{row.scores.rms * 1e6:.4g}"]
        lines.append("  ".join(f"{c:>12}" for c in cells) + (f"  {row.failure}" if row.failure else ""))
    if len(rows) > limit:
        lines.append(f"... {len(rows) - limit} more in the CSV")
    return "\n".join(lines)


def write_sweep_csv(rows: list, path, axes=None) -> None:
    """One row per combination: its settings, ``status`` (ok, or why it has no scores), the scores in SI units
    (lengths in metres, effort in command units, time in seconds; per axis where the score is), and the
    time the scores start from (``from_s``, 0: the whole run)."""
    keys = list(rows[0].settings) if rows else []
    n = len(next((row.scores.tracking_max for row in rows if row.scores), ()))
    axes = list(axes or [f"axis{i}" for i in range(n)])
    per_axis = [f"{name}_{axis}{unit}" for name, unit in (("tracking_max", "_m"), ("tracking_rms", "_m"),
                                                           ("effort_rms", "")) for axis in axes]
    def write(tmp):
        with open(tmp, "w", newline="") as stream:
            writer = csv.writer(stream)
            writer.writerow(["rank"] + keys + ["status", "mce_m", "tace_m", "rms_m", "estimation_max_m",
                                               "estimation_rms_m"] + per_axis + ["travel_time_s", "from_s"])
            for rank, row in enumerate(rows, 1):
                s = row.scores
                values = [""] * (7 + len(per_axis)) if s is None else \
                    [s.mce, s.tace, s.rms, s.estimation_max, s.estimation_rms, *s.tracking_max, *s.tracking_rms,
                     *s.effort_rms, s.travel_time, s.from_time]
                writer.writerow([rank] + [row.settings[k] for k in keys] + [row.failure or "ok"] + values)
    write_atomically(path, write)
