"""Seconds and peak memory to read and plan a part program of N short blocks (the look-ahead is linear).

    python bench/feed_plan_speed.py [N ...]      # default 1000 10000 100000

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


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--one":
        print(measure(int(sys.argv[2])), flush=True)
        raise SystemExit(0)
    for n in [int(a) for a in sys.argv[1:]] or [1000, 10000, 100000]:
        subprocess.run([sys.executable, __file__, "--one", str(n)], check=True)
