"""Seconds and peak memory to read and plan a part program of N short blocks (the look-ahead is linear).

    python bench/feed_plan_speed.py [N ...]      # default 1000 10000 100000
    python bench/feed_plan_speed.py --window      # the look-ahead window against the whole program's plan
    python bench/feed_plan_speed.py --merge       # G64 Q: blocks and G1 time of a 720-chord circle

Each N runs in a fresh process: a program of N chords of 5 um (circles of radius 10 mm at F1200, G64 P0.001,
in mm as CAM systems write them) is parsed (core/gcode.py), made a tool path (blend arcs at every corner)
and planned (core/feed_planning.py, the bounds of config/gcode_example_part.yaml); the line printed gives
the seconds of each stage, the seconds per block and the process's peak resident memory.
"""
from __future__ import annotations

import math
import resource
import subprocess
import sys
import time


def program(blocks: int) -> str:
    step = 0.005 / 10.0                                  # rad: 5 um chords on a 10 mm radius
    rows = ["%", "G21 G90 G17 G64 P0.001", "G1 X10 Y0 F1200"]
    rows += [f"X{10 * math.cos(step * i):.6f} Y{10 * math.sin(step * i):.6f}" for i in range(1, blocks + 1)]
    return "\n".join(rows + ["M30", "%"]) + "\n"


def measure(blocks: int) -> str:
    from contouring_ros.core.curves import ToolPath
    from contouring_ros.core.feed_planning import FeedPlan
    from contouring_ros.core.gcode import parse_program
    text = program(blocks)
    start = time.perf_counter()
    parsed = parse_program(text)
    parse = time.perf_counter()
    path = ToolPath.from_program(parsed)
    built = time.perf_counter()
    plan = FeedPlan(path, 1.0, 10.0)
    planned = time.perf_counter()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    total = planned - start
    return (f"{blocks:>8} blocks ({len(text) / 1e6:.1f} MB): parse {parse - start:.2f} s, tool path "
            f"{built - parse:.2f} s, plan {planned - built:.2f} s; {1e6 * total / blocks:.1f} us per block; "
            f"peak memory {peak:.0f} MiB; planned duration {plan.duration:.2f} s")


def circle(chords: int, radius_mm: float = 10.0, q: str = "") -> str:
    """A circle of ``chords`` G1 chords at F1200 under G64 P0.001 (and Q ``q``), reached by a G0 from the
    origin."""
    rows = [f"G21 G90 G0 X{radius_mm} Y0", "G64 P0.001" + (f" Q{q}" if q else "")]
    rows += [f"G1 X{radius_mm * math.cos(2 * math.pi * i / chords):.6f} "
             f"Y{radius_mm * math.sin(2 * math.pi * i / chords):.6f}" + (" F1200" if i == 1 else "")
             for i in range(1, chords + 1)]
    return "\n".join(rows) + "\n"


def windows() -> None:
    """The planned duration with a look-ahead of W blocks (schedule key lookahead_blocks) against the whole
    program's plan, on the example part, the 720-chord circle and a circle of 5 um chords (R10, F1200)."""
    from pathlib import Path

    from contouring_ros.config import build_curve, load_experiment
    from contouring_ros.core.curves import ToolPath
    from contouring_ros.core.feed_planning import FeedPlan
    from contouring_ros.core.gcode import parse_program
    root = Path(__file__).resolve().parent.parent
    cases = [("config/gcode_example_part.yaml", build_curve(load_experiment(root / "config/gcode_example_part.yaml"))),
             ("720-chord circle R10", ToolPath.from_program(parse_program(circle(720)))),
             ("5 um chords, circle R10", ToolPath.from_program(parse_program(circle(round(2 * math.pi * 10 / 0.005)))))]
    for name, path in cases:
        whole = FeedPlan(path, 1.0, 10.0, rapid_feedrate=0.05).duration
        cells = []
        for window in (1000, 200, 50, 10):
            duration = FeedPlan(path, 1.0, 10.0, rapid_feedrate=0.05, lookahead_blocks=window).duration
            cells.append(f"{window}: {duration:.3f} s (+{max(0.0, 100.0 * (duration / whole - 1.0)):.1f}%)")
        print(f"{name} ({len(path.blocks)} tool path blocks): whole program {whole:.3f} s; look-ahead "
              + ", ".join(cells), flush=True)


def merges() -> None:
    """G64 Q (core/gcode.merge_collinear) on a 720-chord circle of R5 at F1200: its blocks and the planned
    time of its G1 moves for Q = 0 (none), 0.001, 0.005 and 0.01 mm."""
    from contouring_ros.core.curves import ToolPath
    from contouring_ros.core.feed_planning import FeedPlan
    from contouring_ros.core.gcode import parse_program
    for q in ("", "0.001", "0.005", "0.01"):
        program = parse_program(circle(720, 5.0, q))
        plan = FeedPlan(ToolPath.from_program(program), 1.0, 10.0, rapid_feedrate=0.05)
        print(f"Q{q or ' none'}: {len(program.blocks) - 1} G1 blocks, G1 time "
              f"{plan.duration - plan.block_times[1]:.3f} s", flush=True)


if __name__ == "__main__":
    if sys.argv[1:] == ["--window"]:
        windows()
        raise SystemExit(0)
    if sys.argv[1:] == ["--merge"]:
        merges()
        raise SystemExit(0)
    if len(sys.argv) == 3 and sys.argv[1] == "--one":
        print(measure(int(sys.argv[2])), flush=True)
        raise SystemExit(0)
    for n in [int(a) for a in sys.argv[1:]] or [1000, 10000, 100000]:
        subprocess.run([sys.executable, __file__, "--one", str(n)], check=True)
