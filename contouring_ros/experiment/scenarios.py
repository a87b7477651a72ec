"""Where the scenario files live and how a name finds one: the config/ directory (of the source tree or an
installed package), the papers' scenario names, an experiment given by file or scenario name, a part program
next to its experiment or in config/. Standard library only."""
from __future__ import annotations

import os
from pathlib import Path

from ..errors import ConfigError

__all__ = ["CONFIG_DIR", "DEFAULT_EXPERIMENT", "available_papers", "experiment_path", "resolve_part_program",
           "scenario_files"]

DEFAULT_EXPERIMENT = "config/paper000_b_ismc_h50_newton.yaml"


def _config_dir() -> Path:
    """config/ of the source tree, else share/contouring_ros/config of an installed (colcon) package."""
    source = Path(__file__).resolve().parent.parent.parent / "config"
    if source.is_dir():
        return source
    for prefix in filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        installed = Path(prefix) / "share" / "contouring_ros" / "config"
        if installed.is_dir():
            return installed
    return source


CONFIG_DIR = _config_dir()


def scenario_files(paper: str, config_dir=CONFIG_DIR) -> list:
    return sorted(Path(config_dir).glob(f"paper{paper}_*.yaml"))


def available_papers(config_dir=CONFIG_DIR) -> list:
    """The paper numbers that have scenario files, e.g. ['000', '003']."""
    return sorted({path.name[5:8] for path in Path(config_dir).glob("paper???_*.yaml")})


def experiment_path(name: str) -> Path:
    """An experiment file as given, else the packaged scenario of that name (config/<name>[.yaml])."""
    path = Path(name)
    if path.exists():
        return path
    for candidate in (CONFIG_DIR / path.name, CONFIG_DIR / f"{path.name}.yaml"):
        if candidate.exists():
            return candidate
    if not path.suffix and len(path.parts) == 1:      # meant as a scenario name
        raise ConfigError(f"{name}: no such file, nor a scenario of that name in {CONFIG_DIR} (names like "
                          f"{Path(DEFAULT_EXPERIMENT).stem}; the file names there without .yaml)")
    return path


def resolve_part_program(name: str, where: str):
    """The part program file ``name``: as given when absolute, else relative to the experiment file
    ``where``, the scenario directory (config/) or the working directory, the first that exists."""
    path = Path(name)
    if path.is_absolute():
        return path if path.exists() else None
    bases = [Path(where).parent] if where and Path(where).is_file() else []
    for base in bases + [CONFIG_DIR, Path.cwd()]:
        if (base / path).exists():
            return base / path
    return None
