"""A benchmark's runs kept as parts (``benchmark --save-part``, ``--from-parts``): saved, read back and checked
as benchmark parts, and merged into one set of rows to be reported together.

A cluster or a large machine can run the papers apart, each run saving its :class:`~.benchmark.Part`; a later
run with ``--methods`` reruns only some combinations of a scenario, whose rows then take the place of the
earlier part's (:func:`merged_rows`). The file format itself is :mod:`contouring_ros.studies.parts`'s.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .benchmark import Family, Part, Row, is_proposed_combination, matches_methods, proposed_row
from .parts import load as read_part, save as write_part
from .tuning import Tuned

__all__ = ["save_part", "load_parts", "merged_rows"]


def save_part(part: Part, path) -> Path:
    """Write ``part`` to ``path`` as a part file (:mod:`contouring_ros.studies.parts`: JSON with a format version and
    a checksum, read back by :func:`load_parts`; nothing in it can run code)."""
    return write_part(part, path)


def load_parts(paths: list) -> list:
    """The :class:`~contouring_ros.studies.benchmark.Part` of each file in ``paths``
    (:func:`contouring_ros.studies.parts.load`: checked before anything is built). ConfigError naming a file
    that is not one, whose rows do not hang together, or whose protocol differs from the first's (their rows
    would not compare)."""
    parts = []
    for path in paths:
        part = read_part(path, f"--from-parts {path}")
        if not isinstance(part, Part):
            raise ConfigError(f"--from-parts {path}: not a benchmark part (it holds a {type(part).__name__})")
        problem = next((what for ok, what in (
            (all(isinstance(f, Family) for f in part.families), "a scenario that is not a Family"),
            (all(isinstance(r, Row) for r in part.rows), "a row that is not a Row"),
            (all(any(r.family is f for f in part.families) for r in part.rows), "a row of no scenario of the part"),
            (all((r.combination is None) != (r.excluded is None) for r in part.rows),
             "a row with neither or both of a combination and an exclusion"),
            (all(r.tuned is None or isinstance(r.tuned, Tuned) for r in part.rows), "a row whose tuning is not Tuned"),
        ) if not ok), None)
        if problem:
            raise ConfigError(f"--from-parts {path}: odd contents for a benchmark part: {problem}")
        if parts and part.protocol != parts[0].protocol:
            raise ConfigError(f"--from-parts {path}: its tuning protocol differs from {paths[0]}'s")
        parts.append(part)
    return parts


def _same_tuning(before: Row, after: Row) -> bool:
    """Whether two runs of one combination gave the same figures (every draw's TACE and MCE, and the proposed
    method's with the paper's gains; a diverged draw's nan equal to nan)."""
    def figures(row):
        draws = row.tuned.draws if row.ok else []
        published = row.bound.published if row.bound is not None else None
        return np.array([[d.tace, d.mce] for d in draws] + ([[published.tace, published.mce]] if published else []),
                        dtype=float)
    mine, theirs = figures(before), figures(after)
    return before.ok == after.ok and mine.shape == theirs.shape and bool(np.allclose(mine, theirs, rtol=1e-9,
                                                                                     atol=0.0, equal_nan=True))


def merged_rows(parts: list) -> tuple:
    """(families, rows) of ``parts`` read in order: a later part's scenario replaces an earlier part's rows
    of it, all of them, or with ``methods`` those of its methods and the proposed combination (so that a
    method added or changed is rerun alone and reported with the rest). ConfigError where the proposed
    combination of a scenario did not tune to the same figures in both (the parts ran different code or
    settings: their ratios would not compare)."""
    families, rows = {}, {}
    for i, part in enumerate(parts):
        for family in part.families:
            new = [r for r in part.rows if r.family is family]
            kept = [] if not part.methods or family.name not in rows else [
                r for r in rows[family.name]
                if not matches_methods(r.combination or r.excluded, part.methods)
                and not (r.combination and is_proposed_combination(family, r.combination))]
            before = next((r for r in rows.get(family.name, []) if r.combination
                           and is_proposed_combination(family, r.combination)), None)
            after = next((r for r in new if r.combination and is_proposed_combination(family, r.combination)), None)
            if part.methods and before is not None and after is not None and not _same_tuning(before, after):
                raise ConfigError(f"--from-parts: part {i + 1} ({part.command}) tuned {family.name}'s proposed "
                                  "combination to other figures than the parts before it: they ran different "
                                  "code or settings, so its rows would not compare with theirs")
            for r in kept:
                r.family = family
                if after is not None:
                    r.bound = after.bound
            families[family.name] = family
            rows[family.name] = kept + new
    ordered = sorted(families.values(), key=lambda f: f.paper)
    out = []
    for family in ordered:
        mine = rows[family.name]
        proposed = proposed_row(family, [r for r in mine if r.combination])
        for r in mine:
            if r.combination:
                r.reference = proposed
        out += mine
    return ordered, out
