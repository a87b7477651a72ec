"""Paper reproduction reports: our numbers beside the papers' for every scenario file of a paper."""
from __future__ import annotations

import sys
from pathlib import Path

from .config import build_loop, load_experiment
from .core.simulation import simulate
from .scoring import score_run

__all__ = ["CONFIG_DIR", "scenario_files", "paper_rows", "paper_report"]

def _config_dir() -> Path:
    """config/ of the source tree, else share/contouring_ros/config of an installed (colcon) package."""
    source = Path(__file__).resolve().parent.parent / "config"
    if source.is_dir():
        return source
    import os
    for prefix in filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        installed = Path(prefix) / "share" / "contouring_ros" / "config"
        if installed.is_dir():
            return installed
    return source


CONFIG_DIR = _config_dir()


def scenario_files(paper: str, config_dir=CONFIG_DIR) -> list:
    return sorted(Path(config_dir).glob(f"paper{paper}_*.yaml"))


def paper_rows(paper: str, graph: bool = False, progress=None) -> list:
    """(scenario, description, paper MCE/TACE, our in-process MCE/TACE, graph MCE/TACE or None) per file."""
    say = progress or (lambda message: None)
    rows = []
    from tqdm import tqdm
    for path in tqdm(scenario_files(paper), desc=f"paper {paper}", disable=not sys.stderr.isatty(), leave=False):
        experiment = load_experiment(path)
        loop = build_loop(experiment)
        ours = score_run(loop.curve, simulate(loop))
        through_graph = None
        if graph:
            from .runner import run_graph
            from .scoring import score_bag
            say(f"{path.name}: running the node graph")
            through_graph = score_bag(run_graph(path))[0]
        rows.append((path.stem, experiment.info["experiment"].get("description", ""), experiment.info["paper"],
                     ours, through_graph))
    return rows


def paper_report(paper: str, graph: bool = False, progress=None) -> str:
    """A Markdown table of every scenario of ``paper``: the paper's MCE/TACE and ours, in micrometres."""
    rows = paper_rows(paper, graph, progress)
    head = "| scenario | paper MCE | ours MCE | paper TACE | ours TACE | MCE ratio |"
    lines = [head + (" graph MCE | graph TACE |" if graph else ""),
             "|---|---:|---:|---:|---:|---:|" + ("---:|---:|" if graph else "")]
    for stem, _, reference, ours, through_graph in rows:
        line = (f"| {stem} | {reference.get('mce_um', float('nan')):g} | {ours.mce * 1e6:.3g} | "
                f"{reference.get('tace_um', float('nan')):g} | {ours.tace * 1e6:.3g} | "
                f"{ours.mce * 1e6 / reference.get('mce_um', float('nan')):.2g} |")
        if graph:
            line += f" {through_graph.mce * 1e6:.3g} | {through_graph.tace * 1e6:.3g} |"
        lines.append(line)
    return "\n".join(lines)
