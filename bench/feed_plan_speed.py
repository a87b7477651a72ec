"""Blocks per second, first-motion latency and peak memory of planning part programs of N short blocks.

    python bench/feed_plan_speed.py [N ...]        # default 10000 100000 1000000 10000000: the streaming plan
    python bench/feed_plan_speed.py --whole [N ...]   # the whole-program plan (default 1000 10000 100000)
    python bench/feed_plan_speed.py --window       # the look-ahead window against the whole program's plan
    python bench/feed_plan_speed.py --merge        # G64 Q: blocks and G1 time of a 720-chord circle
    python bench/feed_plan_speed.py --stages [N]   # where a streamed block's time goes (default 20000)
    python bench/feed_plan_speed.py --rounded [N]  # a CAM program's rounded chords, with and without G64 Q

Each N runs in a fresh process on a program of N chords of 5 um (round and round a circle of radius 10 mm at
F1200, G64 P0.001, in mm as CAM systems write them), with the bounds of config/gcode_example_part.yaml.

Streaming (core/feed_stream.py): the program's lines are generated one at a time as the planner reads them
(no program text is held), read, made tool-path stretches and planned over the default look-ahead
(feed_planning.LOOKAHEAD_BLOCKS stretches, the schedule key lookahead_blocks' default), and the reference
sampled every millisecond to the end; the line printed gives the blocks per second over the whole run, the
first-motion latency (seconds from the start until the first reference sample is out) and the process's
peak resident memory.

Whole (--whole): the program's text is parsed (core/gcode.py), made a tool path (blend arcs at every corner)
and planned (core/feed_planning.py); the seconds of each stage, per block, and the peak memory.
"""
from __future__ import annotations

import math
import resource
import subprocess
import sys
import time

STEP = 0.005 / 10.0                                  # rad: 5 um chords on a 10 mm radius


def lines(blocks: int):
    """The program's lines, one at a time."""
    yield "%"
    yield "G21 G90 G17 G64 P0.001"
    yield "G1 X10 Y0 F1200"
    for i in range(1, blocks + 1):
        yield f"X{10 * math.cos(STEP * i):.6f} Y{10 * math.sin(STEP * i):.6f}"
    yield "M30"
    yield "%"


def program(blocks: int) -> str:
    return "\n".join(lines(blocks)) + "\n"


def peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def streamed(blocks: int) -> str:
    from contouring_ros.core.feed_planning import LOOKAHEAD_BLOCKS
    from contouring_ros.core.feed_stream import stream_program
    start, cpu = time.perf_counter(), time.process_time()
    plan = stream_program(lines(blocks), 2, acceleration=1.0, jerk=10.0, lookahead_blocks=LOOKAHEAD_BLOCKS)
    samples = plan.samples(1e-3)
    last = next(samples)
    latency = time.perf_counter() - start
    count = 1
    for last in samples:
        count += 1
    total, cpu = time.perf_counter() - start, time.process_time() - cpu
    return (f"{blocks:>9} blocks streamed: {blocks / total:,.0f} blocks/s ({1e6 * total / blocks:.1f} us per block, "
            f"{total:.1f} s; {blocks / cpu:,.0f} blocks per CPU second), first motion after {latency:.3f} s, "
            f"peak memory {peak_mib():.0f} MiB; "
            f"{count} reference samples to t = {last[0]:.3f} s (look-ahead {LOOKAHEAD_BLOCKS} stretches)")


def stages(blocks: int) -> None:
    """Where a streamed block's time goes: the pipeline run on ``blocks`` chords up to each stage in turn
    (the least process CPU time of 5: the machine may be shared), each stage's microseconds per chord the
    difference from the one before."""
    from contouring_ros.core.curves import ToolPath, _blend, _program_items
    from contouring_ros.core.feed_planning import LOOKAHEAD_BLOCKS
    from contouring_ros.core.feed_stream import RUN_BLOCKS, stream_program
    from contouring_ros.core.gcode import ProgramReader, merge_collinear

    def reader():          # runs of plain G1 lines as stream_program reads them (gcode.LineRun)
        return merge_collinear(ProgramReader().blocks(lines(blocks), runs=min(RUN_BLOCKS, LOOKAHEAD_BLOCKS // 4)))
    pipeline = [("generate the lines", lambda: lines(blocks)),
                ("read them into blocks and runs of G1 lines (gcode.ProgramReader, merge_collinear)", reader),
                ("each block's or run's segments (curves._program_items)", lambda: _program_items(reader(), 2, 0.0)),
                ("each corner's blend arc (curves._blend)", lambda: _blend(_program_items(reader(), 2, 0.0))),
                ("each stretch's tangents and curvature (ToolPath.stream; a run's: line_runs.StretchChunk)",
                 lambda: ToolPath.stream(reader(), 2)),
                ("limits, junctions, spans, profiles (StreamingPlan.spans)",
                 lambda: stream_program(lines(blocks), 2, acceleration=1.0, jerk=10.0).spans()),
                ("the reference every ms (StreamingPlan.samples)",
                 lambda: stream_program(lines(blocks), 2, acceleration=1.0, jerk=10.0).samples(1e-3))]
    before = 0.0
    for name, make in pipeline:
        best = math.inf
        for _ in range(5):
            start = time.process_time()
            for _ in make():
                pass
            best = min(best, time.process_time() - start)
        cost = 1e6 * best / blocks
        print(f"{cost - before:7.1f} us per block  {name}  ({cost:.1f} us per block so far)", flush=True)
        before = cost


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
    total = planned - start
    return (f"{blocks:>8} blocks ({len(text) / 1e6:.1f} MB): parse {parse - start:.2f} s, tool path "
            f"{built - parse:.2f} s, plan {planned - built:.2f} s; {1e6 * total / blocks:.1f} us per block; "
            f"peak memory {peak_mib():.0f} MiB; planned duration {plan.duration:.2f} s")


def circle(chords: int, radius_mm: float = 10.0, q: str = "") -> str:
    """A circle of ``chords`` G1 chords at F1200 under G64 P0.001 (and Q ``q``), reached by a G0 from the
    origin."""
    rows = [f"G21 G90 G0 X{radius_mm} Y0", "G64 P0.001" + (f" Q{q}" if q else "")]
    rows += [f"G1 X{radius_mm * math.cos(2 * math.pi * i / chords):.6f} "
             f"Y{radius_mm * math.sin(2 * math.pi * i / chords):.6f}" + (" F1200" if i == 1 else "")
             for i in range(1, chords + 1)]
    return "\n".join(rows) + "\n"


def spiral(chords: int, q: str = "") -> str:
    """A spiral of ``chords`` G1 chords of 5 um from R10 at F1200 under G64 P0.001 (and Q ``q``), its
    coordinates rounded to 0.1 um as a CAM system writes them (4 decimals in mm): the rounding turns each
    chord by up to tens of milliradians, so every chord meets the next at a corner of its own."""
    rows, radius, angle = ["G21 G90 G17 G64 P0.001" + (f" Q{q}" if q else ""), "G1 X10 Y0 F1200"], 10.0, 0.0
    for _ in range(chords):
        angle, radius = angle + 0.005 / radius, radius + 1e-6
        rows.append(f"X{radius * math.cos(angle):.4f} Y{radius * math.sin(angle):.4f}")
    return "\n".join(rows) + "\n"


def rounded(chords: int) -> None:
    """The streaming plan of :func:`spiral` under G64 P0.001 alone and with Q0.001 (LinuxCNC's merge of
    nearly collinear short G1 blocks), at the default look-ahead and at 200: blocks per second, spans and the
    planned duration."""
    from contouring_ros.core.feed_planning import LOOKAHEAD_BLOCKS
    from contouring_ros.core.feed_stream import stream_program
    for q in ("", "0.001"):
        for window in (LOOKAHEAD_BLOCKS, 200):
            start = time.perf_counter()
            plan = stream_program(iter(spiral(chords, q).splitlines()), 2, acceleration=1.0, jerk=10.0,
                                  lookahead_blocks=window)
            count = 0
            for span in plan.spans():
                count += 1
            total = time.perf_counter() - start
            print(f"{chords} rounded chords, G64 P0.001{' Q' + q if q else ''}, look-ahead {window}: "
                  f"{chords / total:,.0f} blocks/s ({total:.1f} s), {count} spans, planned duration "
                  f"{span.end_time + plan.end_hold:.3f} s", flush=True)


def windows() -> None:
    """The planned duration of the streaming plan with a look-ahead of W tool-path stretches (schedule key
    lookahead_blocks) against the whole program's plan, on the example part (config/gcode_example_part.yaml's
    program and bounds), the 720-chord circle and a circle of 5 um chords (R10, F1200)."""
    from pathlib import Path

    from contouring_ros.core.curves import ToolPath
    from contouring_ros.core.feed_planning import FeedPlan
    from contouring_ros.core.feed_stream import stream_program
    from contouring_ros.core.gcode import parse_program
    root = Path(__file__).resolve().parent.parent
    cases = [("config/gcode_example_part.yaml", (root / "config/parts/example_part.ngc").read_text(), 3),
             ("720-chord circle R10", circle(720), 2),
             ("5 um chords, circle R10", circle(round(2 * math.pi * 10 / 0.005)), 2)]
    for name, text, dimension in cases:
        path = ToolPath.from_program(parse_program(text))
        whole = FeedPlan(path, 1.0, 10.0, rapid_feedrate=0.05).duration
        cells = []
        for window in (1000, 200, 50, 10, 2):
            plan = stream_program(iter(text.splitlines()), dimension, acceleration=1.0, jerk=10.0,
                                  rapid_feedrate=0.05, lookahead_blocks=window)
            for span in plan.spans():
                pass
            duration = span.end_time + plan.end_hold
            cells.append(f"{window}: {duration:.3f} s (+{max(0.0, 100.0 * (duration / whole - 1.0)):.2f}%)")
        print(f"{name} ({len(path.blocks)} tool path stretches): whole program {whole:.3f} s; streamed with a "
              "look-ahead of " + ", ".join(cells), flush=True)


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
    if sys.argv[1:2] == ["--rounded"]:
        rounded(int(float(sys.argv[2])) if len(sys.argv) > 2 else 10000)
        raise SystemExit(0)
    if sys.argv[1:2] == ["--stages"]:
        stages(int(float(sys.argv[2])) if len(sys.argv) > 2 else 20000)
        raise SystemExit(0)
    if len(sys.argv) == 4 and sys.argv[1] == "--one":
        print((measure if sys.argv[2] == "whole" else streamed)(int(sys.argv[3])), flush=True)
        raise SystemExit(0)
    whole = sys.argv[1:2] == ["--whole"]
    counts = [int(float(a)) for a in sys.argv[1 + whole:]] or ([1000, 10000, 100000] if whole else
                                                             [10000, 100000, 1000000, 10000000])
    for n in counts:
        subprocess.run([sys.executable, __file__, "--one", "whole" if whole else "stream", str(n)], check=True)
