"""Comparison of recorded runs: their names, their scores side by side and as ratios to a baseline run, and
how their experiment files differ.

Nothing here needs ROS: the runs are (label, :class:`contouring_ros.records.bag.RecordedRun`) pairs read from
bags.
"""
from __future__ import annotations

from collections import Counter

from .bag import RecordedRun
from .numbers import ratio
from ..experiment.ros_yaml import read_yaml
from ..errors import ContouringError
from .scoring import SCORE_ROWS, format_scores
from ..experiment.settings import differences

__all__ = ["run_names", "compare_table", "experiment_differences", "format_differences"]


def _stored_name(run: RecordedRun) -> str | None:
    experiment = run.experiment
    name = experiment and (experiment.info.get("experiment") or {}).get("name")
    return str(name) if name else None


def run_names(runs: list) -> list:
    """Legend names of (label, RecordedRun) pairs: the experiment name stored in each bag (the label where
    the bag has none); runs of one name are told apart by what their labels add to it (a bag's
    timestamp) where the labels differ, else numbered."""
    names = [_stored_name(run) or label for label, run in runs]
    labels = {name: [label for (label, _), other in zip(runs, names) if other == name] for name in names}
    out, seen = [], Counter()
    for (label, _), name in zip(runs, names):
        seen[name] += 1
        same = labels[name]
        if len(same) == 1:
            out.append(name)
        elif len(set(same)) == len(same):
            extra = label[len(name):].strip(" _-") if label.startswith(name) else label
            out.append(f"{name} ({extra})" if extra else name)
        else:
            out.append(f"{name} #{seen[name]}")
    counts, seen = Counter(out), Counter()
    for k, name in enumerate(out):          # labels that differ only in separators
        seen[name] += 1
        out[k] = f"{name} #{seen[name]}" if counts[name] > 1 else name
    return out


def compare_table(named: list, baseline: int = 0, axes=None) -> str:
    """Scores side by side, then each run's main metrics as a ratio to the baseline run."""
    table = format_scores(named, axes)
    base_name, base = named[baseline]
    lines = [table, "", f"ratio to {base_name}:"]
    width = max(len(label) for label, _ in SCORE_ROWS)
    columns = [max(12, len(name)) for name, _ in named]
    lines.append("  ".join([" " * width] + [name.rjust(w) for (name, _), w in zip(named, columns)]))
    for label, get in SCORE_ROWS:
        reference = get(base)
        cells = [ratio(get(scores), reference).rjust(w)
                 for (_, scores), w in zip(named, columns)]
        lines.append("  ".join([label.split(" [")[0].ljust(width)] + cells))
    return "\n".join(lines)


def experiment_differences(runs: list) -> dict:
    """Grid key (``ccc.kp``, ``curve.h``) -> each run's value, for every key of the experiment files stored in
    (label, RecordedRun) ``runs`` whose value is not the same in all
    (:func:`contouring_ros.experiment.settings.differences`; the experiment's name left out: the runs are named
    by it anyway). Empty for one run, or where a run's bag holds no experiment it can read."""
    if len(runs) < 2:
        return {}
    try:
        datas = [read_yaml(run.experiment_text, label) for label, run in runs]
    except ContouringError:
        return {}
    if not all(isinstance(data, dict) for data in datas):
        return {}
    return {key: values for key, values in differences(datas).items() if key != "experiment.name"}


def format_differences(names: list, changed: dict) -> str:
    """The lines of a text report saying how compared experiments differ (:func:`experiment_differences`)."""
    if not changed:
        return "the experiments differ in nothing but their names" if len(names) > 1 else ""
    width = max(len(key) for key in changed)
    lines = ["how the experiments differ:"]
    for key, values in changed.items():
        lines.append(f"  {key.ljust(width)}  " + "; ".join(f"{name}: {'-' if value is None else value}"
                                                         for name, value in zip(names, values)))
    return "\n".join(lines)

