"""Tuned rows kept as they finish (``benchmark --checkpoints DIR``), so that a benchmark stopped part way
(a closed laptop, a killed job, a cluster's time limit) goes on where it stopped.

Each tuned combination is one file in the folder, ``<key>.row``, in the part format
(:mod:`contouring_ros.parts`: gzip JSON with a checksum, nothing in it can run code). Its key is the SHA-256
of everything the tuning is a function of: the package's source (:func:`~contouring_ros.executors.source_digest`),
the scenario's experiment, the combination's sections and tuned keys, the machine, the noise limit, the
scoring window, the protocol and the robustness floor. A row is taken from the folder only when all of those
are the same, so a changed file, option or line of code tunes the row again instead of reporting a stale
result; a folder may be shared by runs of different scenarios or methods.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from .errors import ConfigError
from .executors import source_digest
from .parts import load as read_part, save as write_part

__all__ = ["SUFFIX", "row_key", "Checkpoints"]

SUFFIX = ".row"


def row_key(*inputs) -> str:
    """SHA-256 (hex) of the package's source and ``inputs`` (a tuning job's arguments: plain data and
    dataclasses, written out by their JSON text or their repr)."""
    text = json.dumps([source_digest(), *inputs], default=repr, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


class Checkpoints:
    """The rows kept in ``folder`` (None: none kept): :meth:`get` a finished row, :meth:`put` one as it
    finishes. ``kind`` is the class a row must be (the tuning's Tuned)."""

    def __init__(self, folder, kind: type, option: str = "--checkpoints"):
        self.folder = Path(folder) if folder is not None else None
        self.kind, self.option = kind, option
        self.taken = 0              # rows taken from the folder in this run
        if self.folder is not None:
            self.folder.mkdir(parents=True, exist_ok=True)

    def path(self, key: str) -> Path:
        return self.folder / f"{key}{SUFFIX}"

    def get(self, key: str):
        """The row kept under ``key``, or None. ConfigError naming the file when one is there but is not a
        row (a damaged file is not tuned over silently)."""
        if self.folder is None or not self.path(key).is_file():
            return None
        row = read_part(self.path(key), f"{self.option} {self.path(key)}")
        if not isinstance(row, self.kind):
            raise ConfigError(f"{self.option} {self.path(key)}: holds a {type(row).__name__}, not a tuned row; "
                              "remove it to tune that row again")
        self.taken += 1
        return row

    def put(self, key: str, row) -> None:
        """Keep ``row`` under ``key`` (written beside and moved into place: a run killed while writing leaves
        no half file)."""
        if self.folder is not None:
            write_part(row, self.path(key))
