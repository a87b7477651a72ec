"""Benchmark: the Fast DDS options that could make message delivery cheaper, against the package's defaults.

For each option (``default``: the package's profile and rmw_fastrtps' defaults; ``async``: asynchronous
publication, RMW_FASTRTPS_PUBLICATION_MODE=ASYNCHRONOUS, a Fast DDS thread sends each message;
``intra-off``: Fast DDS intra-process delivery off, so that nodes in one process exchange messages through
the transports; ``udp-only``: the shared-memory transport left out of the profile, so that processes exchange
messages over UDP on 127.0.0.1), prints the ping-pong floor between two processes (us per message hop) and
the graph's lockstep rate (steps/s, the default experiment) in the composed and the process layouts, each
the median of ``--runs`` runs taken in turns (option by option, run after run), and the ratio to the
default. (Data sharing is not among them: it needs bounded message types, and JointState and
JointTrajectory have unbounded sequences.)

Usage: python bench/dds_options.py [--runs 3] [--seconds 2] [--rounds 3000] [--options default,async,...]
Figures vary run to run on a shared machine: compare the ratios within one run.
"""
from __future__ import annotations

import argparse
import os
import math
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from contouring_ros.run import runner  # noqa: E402
from all import DEFAULT, floor_hop_us, with_globals  # noqa: E402
from graph_speed import lockstep_run  # noqa: E402
# (bench/ is this script's folder)

PUBLICATION_MODE = "RMW_FASTRTPS_PUBLICATION_MODE"
PROFILES_TAG = '<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">'
SHM_TRANSPORT = "        <transport_id>contouring_ros_shm</transport_id>\n"


def option_profiles(directory: Path) -> dict:
    """Option name -> (Fast DDS profile file, extra environment)."""
    base = runner.FASTDDS_PROFILE
    text = base.read_text()
    if PROFILES_TAG not in text or SHM_TRANSPORT not in text:
        raise SystemExit(f"{base}: the profile no longer has the parts this benchmark edits")
    intra_off, udp_only = directory / "intra_off.xml", directory / "udp_only.xml"
    intra_off.write_text(text.replace(PROFILES_TAG, PROFILES_TAG + "\n  <library_settings><intraprocess_delivery>OFF"
                                      "</intraprocess_delivery></library_settings>", 1))
    udp_only.write_text(text.replace(SHM_TRANSPORT, "", 1))
    return {"default": (base, {}), "async": (base, {PUBLICATION_MODE: "ASYNCHRONOUS"}),
            "intra-off": (intra_off, {}), "udp-only": (udp_only, {})}


def use_option(profile: Path, environment: dict):
    """Make the runs that follow (runner.private_environment) use ``profile`` and ``environment``."""
    runner.FASTDDS_PROFILE = profile
    os.environ.pop(PUBLICATION_MODE, None)
    os.environ.update(environment)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs per option and case (median)")
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated seconds per lockstep run")
    parser.add_argument("--rounds", type=int, default=3000, help="ping-pong round trips per run")
    parser.add_argument("--options", default="default,async,intra-off,udp-only")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as directory:
        tmp = Path(directory)
        profiles = option_profiles(tmp)
        names = [name for name in args.options.split(",") if name]
        unknown = [name for name in names if name not in profiles]
        if unknown or "default" not in names:
            raise SystemExit(f"--options: {unknown or 'default'} (known: {', '.join(profiles)}; default is needed)")
        config = tmp / "lockstep.yaml"
        config.write_text(with_globals(DEFAULT, duration=args.seconds))
        figures = {}
        for run in range(args.runs):
            for name in names:
                use_option(*profiles[name])
                try:
                    hop = floor_hop_us(args.rounds)[0]
                except (subprocess.TimeoutExpired, SystemExit) as error:
                    print(f"{name}: a ping-pong run failed ({error}); left out of the median", flush=True)
                    hop = math.nan
                figures.setdefault((name, "hop"), []).append(hop)
                for layout in ("composed", "process"):
                    rate = lockstep_run(config, tmp / f"{name}_{layout}_{run}.mcap", layout)[1]
                    figures.setdefault((name, layout), []).append(rate)
        use_option(*profiles["default"])
        median = {key: statistics.median([v for v in values if not math.isnan(v)] or [math.nan])
                  for key, values in figures.items()}
        print(f"Fast DDS options, median of {args.runs} runs each (ratio to the default in brackets):")
        for name in names:
            hop, composed, process = (median[name, case] for case in ("hop", "composed", "process"))
            print(f"{name:10s} ping-pong {hop:5.0f} us per hop ({hop / median['default', 'hop']:.2f}x); lockstep "
                  f"composed {composed:5.0f} steps/s ({composed / median['default', 'composed']:.2f}x), process "
                  f"{process:4.0f} steps/s ({process / median['default', 'process']:.2f}x)")


if __name__ == "__main__":
    main()
