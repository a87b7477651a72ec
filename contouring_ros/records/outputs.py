"""What a command may write: its outputs never destroy what a user owns.

Every command that writes files (``run --bag``, ``export``, ``blocks --csv``, ``sweep --out``, ``plot
--out``, ``paper --out``, ``benchmark --out`` and ``--save-part``) runs inside one :class:`Outputs`. Before
any work it :meth:`~Outputs.claim` s each destination it can name, and every file written through
:func:`contouring_ros.errors.write_atomically` (beside the destination, then moved into place) is checked
again just before the move. Refused, as one :class:`~contouring_ros.errors.OutputError` line naming the
option and the path:

* a destination that is an input of the same command (the experiment file, a bag read, a part read), even
  with ``--force``: the command would destroy what it reads;
* a destination that two outputs of the command share (two bags of one name exported into one folder);
* a folder where a file goes, or a file where a folder goes;
* an existing file that is not the command's own kind of output (not a bag, PNG, Parquet file, or a
  table or report whose first line is this command's), unless ``--force``;
* a destination that cannot be written (a read-only file system, a file in the way of its folder): said
  before the work, not after it.

A file of the command's own kind (the bag or table of an earlier run of it) is replaced, as before.
"""
from __future__ import annotations

import contextvars
import os
import secrets
from pathlib import Path

from ..errors import OutputError

__all__ = ["Outputs", "BAG", "PNG", "PARQUET", "PART", "LEARNED", "HTML", "EXPORT_CSV", "BLOCKS_CSV", "SWEEP_CSV",
           "BENCHMARK_CSV", "REPORT", "active", "signature", "check_write", "write_atomically"]

# an output kind: (what it is, the prefixes a file of that kind starts with)
BAG = ("an MCAP bag", (b"\x89MCAP",))
PNG = ("a PNG figure", (b"\x89PNG",))
PARQUET = ("a Parquet table", (b"PAR1",))
PART = ("a benchmark part", (b'{"format": "contouring_ros benchmark part"',))     # its gzip'd first line
LEARNED = ("a learned correction (.npy)", (b"\x93NUMPY",))
HTML = ("an HTML report", (b"<!DOCTYPE html>",))
EXPORT_CSV = ("an exported table", (b"time_s,",))
BLOCKS_CSV = ("a blocks table", (b"line,",))
SWEEP_CSV = ("a sweep table", (b"rank,",))
BENCHMARK_CSV = ("a benchmark table", (b"paper,scenario,",))
REPORT = ("a Markdown report of this package", (b"# Paper reproductions", b"# Claims", b"# Contouring benchmark"))

_MAGIC = (b"\x89MCAP", b"\x89PNG", b"PAR1", b"\x93NUMPY")
_ACTIVE: contextvars.ContextVar = contextvars.ContextVar("contouring_ros_outputs", default=None)


def _head(path, size: int = 64) -> bytes:
    """The first ``size`` bytes of ``path``, of its decompressed contents where it is gzip data."""
    with open(path, "rb") as stream:
        head = stream.read(size)
    if head.startswith(b"\x1f\x8b"):
        import gzip
        try:
            with gzip.open(path, "rb") as stream:
                return b"gzip:" + stream.read(size)
        except (OSError, EOFError):
            return head
    return head


def signature(path) -> bytes:
    """What kind of file ``path`` is, by its first bytes (of its contents where it is gzip data): a binary
    format's magic, else its first line up to the first comma (at most 40 bytes): the header's first column
    of a table, a report's title, a part's format."""
    head = _head(path)
    for magic in _MAGIC:
        if head.startswith(magic):
            return magic
    return head.split(b"\n", 1)[0].split(b",", 1)[0][:40]


def _key(path) -> str:
    return os.path.realpath(path)


class Outputs:
    """The inputs and outputs of one command; ``with`` it, :func:`check_write` checks every atomic write.

    Parameters
    ----------
    inputs : iterable of path-like
        The files the command reads: never replaced.
    force : bool
        ``--force``: an existing file of another kind may be replaced (never an input).
    """

    def __init__(self, inputs=(), force: bool = False):
        self.inputs = {_key(p): str(p) for p in inputs}
        self.force = force
        self.claimed = {}          # realpath -> the option that claimed it
        self.written = set()
        self._token = None

    def __enter__(self):
        self._token = _ACTIVE.set(self)
        return self

    def __exit__(self, *exc):
        _ACTIVE.reset(self._token)
        return False

    def _refuse_input(self, path, option: str) -> None:
        if _key(path) in self.inputs:
            raise OutputError(f"{option} {path}: an input of this command ({self.inputs[_key(path)]}); writing there "
                              "would destroy it (name another path)")

    def claim(self, path, kind: tuple, option: str) -> Path:
        """Check, before any work, that the file ``path`` may be written as output ``kind`` (e.g.
        :data:`BAG`) of option ``option``; returns it. OutputError naming the option otherwise."""
        path = Path(path)
        what, prefixes = kind
        self._refuse_input(path, option)
        if _key(path) in self.claimed:
            raise OutputError(f"{option} {path}: two outputs of this command would share that path (the first: "
                              f"{self.claimed[_key(path)]}); name them apart")
        if path.is_dir():
            raise OutputError(f"{option} {path}: a folder; {what} is written as a file (name the file)")
        if path.exists() and not self.force and not _starts(path, prefixes):
            raise OutputError(f"{option} {path}: exists and is not {what}; refusing to replace it (name another "
                              "path, or give --force)")
        writable(path.parent, f"{option} {path}")
        self.claimed[_key(path)] = f"{option} {path}"
        return path

    def claim_folder(self, folder, option: str) -> Path:
        """Check that ``folder`` is, or can be made, a folder this command can write into."""
        folder = Path(folder)
        if folder.exists() and not folder.is_dir():
            raise OutputError(f"{option} {folder}: a file of that name exists; the outputs go into a folder "
                              "(name another)")
        writable(folder, f"{option} {folder}")
        return folder

    def check_write(self, path, tmp) -> None:
        """Before ``tmp`` is moved onto ``path``: not an input, not written already by this command, and an
        existing file only if ``tmp`` is of its kind (:func:`signature`) or ``--force``."""
        self._refuse_input(path, "output")
        if _key(path) in self.written:
            raise OutputError(f"{path}: written twice by this command; two of its outputs would share it")
        if Path(path).is_file() and not self.force:
            try:
                same = signature(path) == signature(tmp)
            except OSError:
                same = True        # unreadable: replaced as before, the rename itself says if it cannot
            if not same:
                raise OutputError(f"{path}: exists and is another kind of file than this command writes there; "
                                  "refusing to replace it (name another path, or give --force)")
        self.written.add(_key(path))


def _starts(path: Path, prefixes: tuple) -> bool:
    try:
        head = _head(path, max(len(p) for p in prefixes))
    except OSError:
        return False
    return any(head.removeprefix(b"gzip:").startswith(p) for p in prefixes)


def writable(folder, label: str) -> None:
    """OutputError unless a file can be created in ``folder`` (made where missing): a file in the way of a
    folder on the path, or a read-only file system, is said here, before any work."""
    folder = Path(folder)
    probe = folder
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise OutputError(f"{label}: cannot be written: {probe} is a file, not a folder")
    try:
        name = probe / f".contouring_ros_probe.{os.getpid()}.{secrets.token_hex(4)}"
        name.open("x").close()
        name.unlink()
    except OSError as error:
        raise OutputError(f"{label}: cannot be written in {probe} ({error.strerror or type(error).__name__})") \
            from None


def active() -> Outputs:
    """The Outputs of the command running now; outside a command (a command function called from Python), a
    fresh one without inputs, whose claims check the same things."""
    return _ACTIVE.get() or Outputs()


def check_write(path, tmp) -> None:
    """:meth:`Outputs.check_write` of the running command, if any."""
    outputs = _ACTIVE.get()
    if outputs is not None:
        outputs.check_write(path, tmp)


def write_atomically(path, write):
    """Call ``write(tmp)`` on a temporary file beside ``path`` (same folder, so the rename is atomic), then
    rename it to ``path``: a full disk or any failure leaves no truncated file under ``path`` (a file already
    there is kept as it was). An OSError becomes one :class:`OutputError` line naming ``path``. Inside a
    command, the move obeys that command's :class:`contouring_ros.records.outputs.Outputs` (no input, no file of
    another kind, no path written twice)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.part")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write(tmp)
        check_write(path, tmp)          # the running command's rules
        os.replace(tmp, path)
    except OSError as error:
        _remove(tmp)
        raise OutputError(f"{path}: cannot write it ({error.strerror or type(error).__name__}); nothing was "
                          "written there") from None
    except BaseException:
        _remove(tmp)
        raise
    return path


def _remove(path):
    try:
        path.unlink()
    except OSError:
        pass
