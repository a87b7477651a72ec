"""The validated experiment: :class:`Experiment`, every section a plain dict with its defaults filled in."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

@dataclass(frozen=True)
class Experiment:
    """A validated experiment. Sections are plain dicts with every default filled in."""

    path: str
    text: str
    sample_time: float
    duration: float
    axes: tuple
    curve: dict
    schedule: dict
    initial_state: str
    network: bool = False
    stall_timeout: float = 10.0
    graph_timeout: float = 300.0
    divergence_factor: float = 10.0
    on_invalid_input: str = "stop"
    timing: str = "lockstep"
    start_time: float = 0.0
    max_lag: float = 0.02
    on_overrun: str = "stop"
    layout: str = "process"
    groups: str = ""
    ccc_takes_state: bool = True
    in_position: tuple = (1e-5,)                   # m, one or one per axis (0: exact stops do not wait)
    namespaced_clock: bool = False
    contour_error_limit: float = 0.0               # m, 0: no contour monitoring
    following_error_limit: tuple = (0.0,)          # m, one or one per axis (0: not monitored)
    feed_events: tuple = ()                        # "hold T" / "resume T" strings (core/feed_control.py)
    reference_preview: int = 0                     # steps of reference ahead the interpolator publishes
    plants: dict = field(default_factory=dict)     # axis -> plant section
    servos: dict = field(default_factory=dict)     # axis -> servo section
    estimator: dict = field(default_factory=dict)
    controller: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)       # 'experiment' and 'paper' blocks, free-form

    @property
    def n_steps(self) -> int:
        """Steps k = 0 .. n_steps - 1 cover t = 0 .. duration inclusive."""
        return int(round(self.duration / self.sample_time)) + 1

    @property
    def name(self) -> str:
        return str(self.info.get("experiment", {}).get("name", Path(self.path).stem))
