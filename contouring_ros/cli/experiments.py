"""An experiment as ``run`` and ``simulate`` take it: the file with its ``--set`` settings, where its bag goes
(never over a user's file), and the end of a run that monitoring stopped."""
from __future__ import annotations

import contextlib
import sys
import tempfile
from pathlib import Path

from ..errors import ConfigError

__all__ = ["DEFAULT_BAG", "with_settings", "bag_target", "exit_on_breach"]

DEFAULT_BAG = "<default>"     # simulate --bag without a path


@contextlib.contextmanager
def with_settings(config: Path, specs):
    """(file, Experiment) for the ``with`` block: the experiment file ``config`` with the ``--set KEY=VALUE``
    settings ``specs`` applied, written under the same name (the bag's default name) in a temporary folder,
    and its validated Experiment; ``config`` itself without any (and None: the caller reads it)."""
    if not specs:
        yield config, None
        return
    from ..experiment.settings import written_settings
    with tempfile.TemporaryDirectory(prefix="contouring_ros_set_") as directory:
        yield written_settings(config, specs, directory)


def bag_target(given: str, experiment) -> Path:
    """Where ``simulate --bag`` writes: the path given (refused if something is there: a user's file is never
    overwritten), or bags/<experiment>_<time>.mcap for ``--bag`` alone, as ``run`` names its bags."""
    from ..run.runner import default_bag_path
    path = default_bag_path(experiment) if given == DEFAULT_BAG else Path(given)
    if path.exists() or path.is_symlink():
        raise ConfigError(f"--bag {path}: a file of that name exists (name another, or remove it)")
    if path.parent.exists() and not path.parent.is_dir():
        raise ConfigError(f"--bag {path}: {path.parent} is not a folder")
    return path


def exit_on_breach(curve, result, experiment, bag=None) -> None:
    """A run that monitoring stopped ends in one line on stderr and exit status 1 (its bag, if any, whole)."""
    from ..records.scoring import breach_message
    line = breach_message(curve, result, experiment)
    if line is not None:
        print(f"error: {line}" + (f" (bag {bag}, complete)" if bag is not None else ""), file=sys.stderr)
        raise SystemExit(1)
