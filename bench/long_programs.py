"""`simulate` on part programs of N short chords: where the time goes and how memory grows with the program.

    python bench/long_programs.py [N ...]            # default 1000 10000 90000
    python bench/long_programs.py --rounded [N ...]  # the chords' coordinates rounded to 4 decimals (mm)

Each N runs in a fresh process: a circle of N chords of 5 um (radius 10 mm) at F1200 under G64 P0.001 (with
--rounded a spiral from R10 whose coordinates are rounded as a CAM system writes them, bench/feed_plan_speed.py's
spiral), on the x and y axes of config/gcode_example_part.yaml (PID + feedforward, a tangent-line estimate
and a unit-vector CCC), with the schedule's default look-ahead. The line printed gives the seconds to load the
experiment (read the program, check it, plan the feed), to build the loop, to run it (and its steps per second)
and to score it, the process's peak resident memory and its memory per chord beyond the short program's.
The whole tool path and its plan are held, as rows of arrays (core/path_tables.py); a program may have up to
experiment/schema.py's MAX_PROGRAM_LINES lines.
"""
from __future__ import annotations

import math
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

EXPERIMENT = """/**:
  ros__parameters:
    experiment: {{name: chords_{n}}}
    sample_time: 0.001
    axes: ["x", "y"]
    curve: {{type: gcode, file: {file}}}
    schedule: {{type: feedrate, acceleration: 1.0, jerk: 10.0, rapid_feedrate: 0.05}}
    initial_state: on_reference
/x/plant:
  ros__parameters: {{model: first_order_velocity, gain: 10.3, time_constant: 0.040}}
/y/plant:
  ros__parameters: {{model: first_order_velocity, gain: 10.0, time_constant: 0.045}}
/x/servo:
  ros__parameters: {{law: pid_feedforward, kp: 8.08, ki: 93.2, kd: 0.24, gain: 10.3, time_constant: 0.040}}
/y/servo:
  ros__parameters: {{law: pid_feedforward, kp: 9.36, ki: 108.0, kd: 0.3, gain: 10.0, time_constant: 0.045}}
/contour_estimator:
  ros__parameters: {{type: tangent_line}}
/ccc:
  ros__parameters: {{type: unit_vector, kp: 1.0, ki: 10.0, kd: 0.1}}
"""


def circle(chords: int) -> str:
    """A circle of ``chords`` chords of 5 um from (10, 0) mm at F1200 under G64 P0.001, 6 decimals."""
    step = 0.005 / 10.0
    rows = ["%", "G21 G90 G17 G64 P0.001", "G1 X10 Y0 F1200"]
    rows += [f"X{10 * math.cos(step * i):.6f} Y{10 * math.sin(step * i):.6f}" for i in range(1, chords + 1)]
    return "\n".join(rows + ["M30", "%"]) + "\n"


def one(chords: int, rounded: bool) -> str:
    from contouring_ros.core.simulation import simulate
    from contouring_ros.experiment.build import build_loop
    from contouring_ros.experiment.files import load_experiment
    from contouring_ros.records.scoring import cutting_lines, score_run
    from feed_plan_speed import spiral
    with tempfile.TemporaryDirectory() as folder:
        program = Path(folder) / "chords.ngc"
        program.write_text(spiral(chords) if rounded else circle(chords))
        config = Path(folder) / "chords.yaml"
        config.write_text(EXPERIMENT.format(n=chords, file=program))
        start = time.perf_counter()
        experiment = load_experiment(str(config))
        loaded = time.perf_counter()
        loop = build_loop(experiment)
        built = time.perf_counter()
        result = simulate(loop)
        ran = time.perf_counter()
        score_run(loop.curve, result, 0.0, experiment)
        lines = cutting_lines(loop.curve, result, experiment)
        scored = time.perf_counter()
    steps = len(result.time)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return (f"{chords:>7} chords{' (rounded)' if rounded else ''}: load {loaded - start:.1f} s, build "
            f"{built - loaded:.1f} s, run {ran - built:.1f} s ({steps} steps, {steps / (ran - built):,.0f} steps/s), "
            f"score {scored - ran:.1f} s; peak memory {peak:.0f} MiB; {lines[-1] if lines else ''}")


def main(argv: list) -> None:
    rounded = "--rounded" in argv
    counts = [int(float(a)) for a in argv if a != "--rounded"] or [1000, 10000, 90000]
    peaks = []
    for n in counts:
        line = subprocess.run([sys.executable, __file__, "--one", str(n)] + (["--rounded"] if rounded else []),
                              check=True, capture_output=True, text=True).stdout.strip()
        peaks.append((n, float(line.split("peak memory ")[1].split(" MiB")[0])))
        print(line, flush=True)
    if len(peaks) > 1:
        (n0, m0), (n1, m1) = peaks[0], peaks[-1]
        print(f"memory per chord beyond the {n0}-chord program's: {(m1 - m0) * 1024 * 1024 / (n1 - n0) / 1e3:.1f} kB")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--one"]:
        print(one(int(sys.argv[2]), "--rounded" in sys.argv[3:]), flush=True)
    else:
        main(sys.argv[1:])
