"""Tuned rows kept as they finish (``benchmark --checkpoints DIR``), so that a benchmark stopped part way
(a closed laptop, a killed job, a cluster's time limit) goes on where it stopped.

Each tuned combination is one file in the folder, ``<key>.row``, in the part format
(:mod:`contouring_ros.studies.parts`: gzip JSON with a checksum, nothing in it can run code). Its key is the SHA-256
of everything the tuning is a function of: the package's source (:func:`~contouring_ros.studies.executors.source_digest`),
the scenario's experiment, the combination's sections and tuned keys, the machine, the noise limit, the
scoring window, the protocol and the robustness floor. A row is taken from the folder only when all of those
are the same, so a changed file, option or line of code tunes the row again instead of reporting a stale
result; a folder may be shared by runs of different scenarios or methods.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

from ..errors import ConfigError
from .executors import source_digest
from .parts import load as read_part, register, save as write_part

__all__ = ["SUFFIX", "row_key", "KeptRow", "Checkpoints"]

SUFFIX = ".row"


def row_key(*inputs, source: str | None = None) -> str:
    """SHA-256 (hex) of the package's source (its digest ``source``, default the package's now) and ``inputs``
    (a tuning job's arguments: plain data and dataclasses, written out by their JSON text or their repr)."""
    text = json.dumps([source or source_digest(), *inputs], default=repr, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass
class KeptRow:
    """One kept row: its key (checked against the file's name as it is read: a file copied or renamed onto
    another row's name is not taken for that row), what it is (scenario and combination) and its tuning."""

    key: str
    where: str
    tuned: object


register(KeptRow)


class Checkpoints:
    """The rows kept in ``folder`` (None: none kept): :meth:`get` a finished row, :meth:`put` one as it
    finishes. ``kind`` is the class a row must be (the tuning's Tuned)."""

    def __init__(self, folder, kind: type, option: str = "--checkpoints"):
        self.folder = Path(folder) if folder is not None else None
        self.kind, self.option = kind, option
        self.taken = 0              # rows taken from the folder in this run
        self.source = None          # the package's source digest as the run starts: every row's key has it
        if self.folder is not None:
            self.folder.mkdir(parents=True, exist_ok=True)
            self.source = source_digest()

    def key(self, *inputs) -> str:
        """The key of a row of ``inputs`` (:func:`row_key`; "" where no rows are kept)."""
        return row_key(*inputs, source=self.source) if self.folder is not None else ""

    def path(self, key: str) -> Path:
        return self.folder / f"{key}{SUFFIX}"

    def get(self, key: str):
        """The row kept under ``key``, or None. ConfigError naming the file when one is there but is not the
        row of that key (damaged, another file, another row's copied onto its name): it is not tuned over
        silently."""
        if self.folder is None or not self.path(key).is_file():
            return None
        path = self.path(key)
        where = f"{self.option} {path}"
        try:
            kept = read_part(path, where)
        except ConfigError as error:
            said = str(error).replace("a benchmark part (written by benchmark --save-part)", "a row kept by "
                                      "--checkpoints").replace("benchmark part", "kept row")
            raise ConfigError(f"{said} (remove it to tune that row again)") from None
        if not isinstance(kept, KeptRow) or not isinstance(kept.tuned, self.kind):
            raise ConfigError(f"{where}: holds a {type(kept).__name__}, not a row kept by --checkpoints (remove it "
                              "to tune that row again)")
        if kept.key != key:
            raise ConfigError(f"{where}: holds the row of another key ({kept.where}), copied or renamed onto "
                              "this name (remove it to tune that row again)")
        self.taken += 1
        return kept.tuned

    def put(self, key: str, row, where: str = "") -> None:
        """Keep ``row`` (of the combination ``where``) under ``key`` (written beside and moved into place: a
        run killed while writing leaves no half file)."""
        if self.folder is not None:
            write_part(KeptRow(key, where, row), self.path(key))
