"""Part programs as CAM systems write them, measured in-process (about 2 min on 2 cores).

    python bench/part_programs.py

1. A circle of 720 chords of 0.087 mm (radius 10 mm) at F1200 on config/gcode_example_part.yaml's axes and
   bounds: the planned travel time against the ideal (length / feed) under exact stop and under G64 P at
   1 um to 1 mm (the curve's blend_tolerance), and the MCE of the cutting moves of each run.
2. A 50 mm square at F3000 then an arc on the axes of paper 000 (b) (ISMC) and of the example part (PID +
   feedforward): the MCE of the cutting moves with the in-position check off (in_position 0) and on (10 um),
   the largest contour error after each corner, the waits at the four exact stops and the time the reference
   reaches the program's end; on the ISMC axes also without paper 000's disturbance estimate (eq. 24-26),
   whose filtered velocity derivative reads the plan's jerk as a load, and with jerk 0.5 m/s^3.
"""
from __future__ import annotations

import math
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contouring_ros.records.blocks import block_results, cutting_scores  # noqa: E402
from contouring_ros.experiment.build import build_loop  # noqa: E402
from contouring_ros.experiment.files import load_experiment  # noqa: E402
from contouring_ros.core.simulation import simulate  # noqa: E402

CONFIG = ROOT / "config"


def experiment(directory: Path, base: str, program: str, curve_keys: str = "", shared: str = "",
               jerk: float = 10.0, observer: bool | str = True) -> Path:
    """The experiment ``base`` (a scenario of config/) with the part program ``program`` as its reference,
    planned with the example part's bounds (acceleration 1 m/s^2, ``jerk`` [m/s^3], default 10);
    ``curve_keys`` and ``shared`` are added to the curve and /**; ``observer`` False takes the disturbance
    estimate (paper 000 eq. 24-26) off ISMC servos, "paper" keeps it as the paper gives it (without the plan
    correction a tool path gets by default: observer_plan_correction false)."""
    name = f"{base}_{abs(hash((program, curve_keys, shared, jerk, observer)))}"
    (directory / f"{name}.ngc").write_text(program)
    text = (CONFIG / f"{base}.yaml").read_text()
    three = '"z"' in text
    start = ", start: [0.0, 0.0, 1.0e-9]" if three else ""          # a planar program on three axes
    text = re.sub(r"curve: \{[^}]*\}", f"curve: {{type: gcode, file: {name}.ngc{start}{curve_keys}}}", text)
    text = re.sub(r"schedule: \{[^}]*\}", f"schedule: {{type: feedrate, acceleration: 1.0, jerk: {jerk}, "
                                          "rapid_feedrate: 0.05}", text)
    if observer == "paper":
        text = text.replace("observer: true", "observer: true\n    observer_plan_correction: false")
    elif not observer:
        text = text.replace("observer: true", "observer: false")
    text = re.sub(r"    duration: [0-9.]+\n", "", text)
    text = text.replace("    sample_time:", f"{shared}    sample_time:", 1)
    path = directory / f"{name}.yaml"
    path.write_text(text)
    return path


def end_time(result, loop) -> float:
    """When the reference reaches the end of the program."""
    return float(result.time[np.argmax(result.theta >= loop.curve.domain[1] - 1e-9)])


def chord_circle(directory: Path):
    rows = ["G21 G90 G17", "G1 X10 Y0 F1200"] + [f"X{10 * math.cos(a):.6f} Y{10 * math.sin(a):.6f}"
                                                 for a in 2 * math.pi * np.arange(1, 721) / 720]
    program = "\n".join(rows) + "\nM30\n"
    print("720 chords of 0.087 mm at F1200 (config/gcode_example_part.yaml's axes, acceleration 1, jerk 10):")
    for blend in (0.0, 1e-6, 1e-5, 1e-4, 1e-3):
        loop = build_loop(load_experiment(experiment(directory, "gcode_example_part", program,
                                                     f", blend_tolerance: {blend}", "    in_position: [0.0]\n")))
        ideal = loop.curve.domain[1] / 0.02
        line = (f"  blend_tolerance {blend * 1e6:6g} um: planned {loop.schedule.duration:7.3f} s, ideal "
                f"{ideal:.3f} s, ratio {loop.schedule.duration / ideal:.3f}")
        if blend:
            result = simulate(loop)
            line += f"; cutting-move MCE {cutting_scores(loop.curve, result).mce * 1e6:.2f} um"
        print(line, flush=True)


def square(directory: Path):
    program = "G21 G90 G17\nG1 X50 Y0 F3000\nY50\nX0\nY0\nG2 X20 Y0 R10\nM30\n"
    print("a 50 mm square at F3000 then an arc (acceleration 1, jerk 10 unless said), exact stop at the corners "
          "(corners: the largest contour error of the blocks after the corners at (50, 0), (50, 50), (0, 50)):")
    ismc, pidff = "ISMC, paper 000 (b)", "PID + feedforward, the example part"
    paper = ismc + " with the paper's estimate (observer_plan_correction: false)"
    runs = [("paper000_b_ismc_h50_newton", paper, 0.0, 10.0, "paper"),
            ("paper000_b_ismc_h50_newton", paper, 1e-5, 10.0, "paper"),
            ("paper000_b_ismc_h50_newton", ismc + " without the disturbance estimate (eq. 24-26)", 1e-5, 10.0,
             False),
            ("paper000_b_ismc_h50_newton", ismc + " (the estimate with the plan correction: the default on a "
             "tool path)", 1e-5, 10.0, True),
            ("paper000_b_ismc_h50_newton", paper + ", jerk 0.5", 1e-5, 0.5, "paper"),
            ("gcode_example_part", pidff, 0.0, 10.0, True),
            ("gcode_example_part", pidff, 1e-5, 10.0, True)]
    for base, axes, window, jerk, observer in runs:
        loop = build_loop(load_experiment(experiment(directory, base, program, "",
                                                     f"    in_position: [{window}]\n", jerk, observer)))
        result = simulate(loop)
        scores = cutting_scores(loop.curve, result)
        corners = [row.max_contour_error * 1e6 for row in block_results(loop.curve, result, loop.schedule)[1:4]]
        waits = [steps for _, steps in loop.clock.waits] if loop.clock is not None else []
        print(f"  {axes}, in_position {window * 1e6:g} um: cutting-move MCE {scores.mce * 1e6:.1f} um, TACE "
              f"{scores.tace * 1e6:.2f} um; corners {'/'.join(f'{c:.1f}' for c in corners)} um; waits {waits} "
              f"steps; the program ends at {end_time(result, loop):.3f} s (planned {loop.schedule.duration:.3f} s)",
              flush=True)


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as name:
        chord_circle(Path(name))
        square(Path(name))
