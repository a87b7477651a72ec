"""The keys every node shares (the file's ``/**`` section), and the optional nodes' own keys."""
from __future__ import annotations

from ...wire import catalogue as nodes
from ..schema import MAX_DURATION, Param
from .curves import CURVES
from .schedules import SCHEDULES

__all__ = ["GLOBALS", "OPTIONAL_NODES", "TIMINGS", "INVALID_INPUT_POLICIES", "OVERRUN_POLICIES", "LAYOUTS",
           "INITIAL_STATES"]

TIMINGS = ("lockstep", "realtime")
INVALID_INPUT_POLICIES = ("stop", "hold")
OVERRUN_POLICIES = ("stop", "skip")
LAYOUTS = ("process", "composed", "grouped")    # where `contouring-ros run` puts the nodes (README, "Commands")
INITIAL_STATES = ("on_reference", "at_rest")
_S = "[s]"

GLOBALS = {
    "experiment": Param("dict", {}),
    "paper": Param("dict", {}),
    "sample_time": Param("float", check="positive", help=f"control period Ts {_S}", bounds=(1e-5, 1.0)),
    "duration": Param("float", 0.0, "nonnegative", help=f"simulated time of the run, 0: the schedule's own {_S}",
                      bounds=(0.0, MAX_DURATION)),
    # s run past the schedule's end (duration left to it)
    "settle_time": Param("float", 0.0, "nonnegative", help=f"simulated time run past the schedule's end {_S}",
                         bounds=(0.0, MAX_DURATION)),
    "axes": Param("strings", help="axis names, in order"),
    "curve": Param("dict", choices=CURVES),
    "schedule": Param("dict", choices=SCHEDULES),
    "initial_state": Param("str", "on_reference", choices=INITIAL_STATES, help="where the axes start"),
    "network": Param("bool", False, help="discover nodes beyond localhost"),
    "stall_timeout": Param("float", 10.0, "positive", help=f"wall time without a complete step before a node gives "
                           f"up {_S}", bounds=(1e-3, 3600.0)),
    # hand-started nodes in separate terminals need time
    "graph_timeout": Param("float", 300.0, "positive", help=f"wall time a node waits at start for the rest of the "
                           f"graph {_S}", bounds=(1e-3, 86400.0)),
    "divergence_factor": Param("float", 10.0, "nonnegative", help="the run stops once an axis is this many path sizes "
                               "from its reference (0: never)", bounds=(0.0, 1e6)),
    "on_invalid_input": Param("str", "stop", choices=INVALID_INPUT_POLICIES,
                              help="what a node does with a non-finite or malformed input"),
    "timing": Param("str", "lockstep", choices=TIMINGS,   # docs/ARCHITECTURE.md, "One control step"
                    help="lockstep (as fast as the graph goes) or realtime (one step a period of wall time)"),
    "start_time": Param("float", 0.0, "nonnegative", help="realtime: Unix time of tick 0 [s since 1970]",
                        bounds=(0.0, 1e10)),     # the runner sets it
    "max_lag": Param("float", 0.02, "positive", help=f"realtime: how far a node (or a group's loop) may fall behind "
                     f"its ticks before on_overrun acts {_S}", bounds=(1e-6, 3600.0)),
    # like a drive's following-error trip
    "on_overrun": Param("str", "stop", choices=OVERRUN_POLICIES,
                        help="realtime, past max_lag: stop the run, or skip to the tick now due and count the "
                             "skipped ones"),
    # --composed/--group/--process win
    "layout": Param("str", "process", choices=LAYOUTS, help="where contouring-ros run puts the nodes: a process "
                    "each, all in one, or the processes of groups"),
    "groups": Param("str", "", help="grouped layout: the nodes of each process, e.g. "
                                    "'x/plant,x/servo; y/plant,y/servo'"),
    # contouring-ros run sets false where the controller does not use them (3 fewer deliveries a step with 2
    # axes); true is always safe
    "ccc_takes_state": Param("bool", True, help="the CCC node subscribes to the reference and the axis states"),
    # contouring-ros run sets it to what the servos read (a ZPETC law: its command_delay + 3); a node started
    # by hand needs it given
    "reference_preview": Param("int", 0, "nonnegative", help="steps of reference after each step's that the "
                               "interpolator publishes with it, for servos that read ahead", bounds=(0, 64)),
    # on a tool path an exact stop waits until every axis' following error is within it
    "in_position": Param("floats", [1e-5], help="drives' in-position window, one or one per axis: exact stops wait "
                         "for it, 0: no wait [m]", bounds=(0.0, 1e-2)),
    # monitoring during the run (core/monitoring.py): a breach stops the reference on the path and fails the run
    "contour_error_limit": Param("float", 0.0, "nonnegative", help="contour monitoring: the run stops on the path "
                                 "once the estimated contour error passes it, 0: off [m]", bounds=(0.0, 1.0)),
    "following_error_limit": Param("floats", [0.0], help="following-error monitoring, one or one per axis: the run "
                                   "stops on the path once an axis' |reference - position| passes it, 0: off [m]",
                                   bounds=(0.0, 1.0)),
    # feed hold, resume and override at given times (core/feed_control.py), e.g. ["hold 1.2", "resume 1.8",
    # "override 50% 2.5"]
    "feed_events": Param("strings", [], help="feed holds, resumes and overrides of the run: 'hold T', 'resume T' "
                         "and 'override P% T' (T [s] rising, P 0 to 200 percent); holds and resumes alternate, "
                         "a hold first"),
    # false: what use_sim_time nodes and diagnostic aggregators listen to; true: several graphs sharing a
    # domain, each its clock
    "namespaced_clock": Param("bool", False, help="under a namespace, /clock and /diagnostics take it too (else they "
                                                  "stay global)"),
}

_OPTIONAL_KEYS = {"recorder": {"bag": Param("str", "", help="the MCAP file to write"),
                               "experiment_file": Param("str", "", help="experiment file stored in the bag")}}
#: nodes whose section may be left out (contouring_ros/wire/catalogue.py), with the keys they take
OPTIONAL_NODES = {node.name: _OPTIONAL_KEYS.get(node.name, {}) for node in nodes.NODES if node.optional}
