"""``contouring-ros replay``: other estimators run over a recorded run (their deviation from the exact contour
error), or a bag republished on its ROS topics with /clock."""
from __future__ import annotations

import sys

from .arguments import MAX_WAIT_SUBSCRIBERS, experiment_option, rate, seconds, seconds_at_most, whole
from .reading import given, warn

__all__ = ["HELP", "OUTPUTS", "add_arguments", "main"]

HELP = "run other estimators over a recorded run, or republish a bag"
#: the options that name what the command writes
OUTPUTS = ()


def add_arguments(parser) -> None:
    """The arguments of ``replay``."""
    parser.add_argument("bag")
    parser.add_argument("--estimator", action="append",
                        help="NAME[:key=value,...], repeatable (e.g. newton:k_prime=800)")
    parser.add_argument("--play", action="store_true", help="republish the bag on ROS topics with /clock")
    parser.add_argument("--rate", type=rate, default=1.0, help="with --play: speed factor, 0 = as fast as possible")
    parser.add_argument("--loop", action="store_true",
                        help="with --play: play again and again until Ctrl-C (/clock restarts with the bag each "
                             "pass)")
    parser.add_argument("--start", type=seconds, default=0.0, metavar="T",
                        help="with --play: skip the messages before T seconds after the bag's first")
    parser.add_argument("--topics", metavar="/A,/B",
                        help="with --play: play only these topics (/clock is still published)")
    parser.add_argument("--wait-subscribers", type=whole(0, MAX_WAIT_SUBSCRIBERS, "subscribers"), default=1,
                        metavar="N", help="with --play: wait until N nodes subscribe to the bag's topics before "
                                          "publishing (default 1; 0: start at once)")
    parser.add_argument("--wait-timeout", type=seconds_at_most(86400.0), default=10.0, metavar="S",
                        help="with --play: publish anyway after S seconds without them (default 10)")
    experiment_option(parser)


def main(args) -> None:
    """Republish the bag (``--play``), or print each ``--estimator``'s deviation from the exact contour error
    over the recorded run."""
    if args.play:
        _play(args)
        return
    from ..records.replay import parse_estimator_spec, replay_estimators
    from ..records.scoring import read_run
    if not args.estimator:
        raise SystemExit("error: replay needs --estimator NAME[:key=value,...] (or --play)")
    run = read_run(args.bag, progress=sys.stderr.isatty(), **given(args))
    warn(run)
    exact, replays = replay_estimators(run, [parse_estimator_spec(spec) for spec in args.estimator],
                                       progress=sys.stderr.isatty())
    width = max(len(r.name) for r in replays)
    print(f"{'estimator'.ljust(width)}  deviation from exact: max [um]  RMS [um]")
    for replay in replays:
        print(f"{replay.name.ljust(width)}  {replay.deviation_max * 1e6:>28.4g}  {replay.deviation_rms * 1e6:>8.4g}")


def _play(args) -> None:
    """Republish the bag on its ROS topics (:func:`contouring_ros.run.playback.play_bag`); Ctrl-C ends the
    command with exit status 130."""
    from ..run.playback import play_bag
    topics = [t.strip() for t in args.topics.split(",")] if args.topics is not None else None
    try:
        play_bag(args.bag, rate=args.rate, progress=sys.stderr.isatty(), loop=args.loop, start=args.start,
                 topics=topics, wait_subscribers=args.wait_subscribers, wait_timeout=args.wait_timeout)
    except KeyboardInterrupt:      # the player has said where it stopped
        raise SystemExit(130)
