"""A bag decoded into a run: the per-step signals of a recorded graph run, checked against its experiment.

Reading, in two steps around the experiment's validation, which is not this module's (the caller parses the
experiment once: :func:`contouring_ros.records.scoring.read_run`): :func:`read_contents` streams a bag's records
(:func:`contouring_ros.records.bag_reader.iter_records`) and returns the experiment text it stores with the
columns of its topics, then :func:`decode_run` turns those into per-step arrays, checked against the parsed
experiment (sample time, namespace, joint names, steps), as a :class:`RecordedRun` that carries it.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path

from array import array

import numpy as np

from .bag_reader import Damage, iter_records
from .bag_writer import EXPERIMENT_METADATA
from ..wire import cdr, graph
from ..core.simulation import SimulationResult, first_divergence, step_time
from ..errors import BagError, ContouringError
from ..experiment.catalogue import GLOBALS
from ..experiment.model import Experiment
from ..experiment.schema import MAX_FILE_BYTES
from ..experiment.validate import is_axis_name

__all__ = ["RecordedRun", "BagContents", "reading", "read_contents", "decode_run"]

_MAX_TOPICS = 4096                 # JointState and JointTrajectory topics read at most (a graph of 8 axes has 19)


@dataclass
class RecordedRun:
    """A run as read back from a bag.

    Attributes
    ----------
    experiment_text : str
        The experiment YAML stored in the bag (or the one given for it), verbatim.
    axes : list of str
    result : SimulationResult
        The per-step signals of every step for which each topic was recorded.
    payloads : dict
        topic -> list of raw CDR payloads (only when asked for).
    warnings : list of str
        What the reader had to make do with (a bag cut off before its summary).
    experiment : Experiment or None
        ``experiment_text`` parsed (once, by the reader's caller); None where it does not validate here
        (e.g. a part program it names is not on this machine).
    experiment_error : Exception or None
        Why ``experiment`` is None: the error its validation raised.
    """

    experiment_text: str
    axes: list
    result: SimulationResult
    payloads: dict
    warnings: list
    experiment: Experiment | None = None
    experiment_error: Exception | None = None

    @property
    def complete_steps(self) -> int:
        return len(self.result.time)

    def require_experiment(self) -> Experiment:
        """The run's Experiment; where its text did not validate here, the error it failed with is raised."""
        if self.experiment is None:
            raise self.experiment_error or BagError("the run's experiment was not parsed")
        return self.experiment


class _TopicColumns:
    """The float arrays of one topic's messages, kept flat in typed arrays (8 bytes a value).

    A topic's messages share their layout (same names, same array lengths): the first message's array
    offsets (:func:`cdr.array_layout`) give one precompiled struct for all of them, checked by the message
    length; a message of another length gets its layout worked out again.
    """

    def __init__(self, topic: str, type_name: str):
        self.topic, self.type_name = topic, type_name
        self.size = self.width = None
        self.stamps, self.values = array("q"), array("d")
        self.problem = None       # why this topic's messages stopped being read (a message that cannot be)
        self.first = self.counts = None   # the first message read; its arrays' lengths

    def add(self, data: bytes):
        """Keep one message's numbers; a message that cannot be read (another layout, not CDR of the type)
        sets ``problem`` and ends the topic's reading: decode_run refuses the bag for it only when scoring needs
        the topic, and otherwise warns (a stray topic never makes a bag unreadable)."""
        if self.problem is not None:
            return
        try:
            if len(data) != self.size:
                layout = cdr.array_layout(self.type_name, data)
                counts = [count for _, count in layout]
                if self.width is not None and counts != self.counts:
                    self.problem = f"a message with arrays of {counts} values after messages with {self.counts}"
                    return
                self.size, self.width, self.counts = len(data), sum(counts), counts
                self.struct = cdr.values_struct(layout)
            values = self.struct.unpack_from(data, 0)
            stamp = cdr.stamp_ns(data)
        except Exception as error:    # not a CDR message of its type
            self.problem = f"a message that is not a {self.type_name} ({type(error).__name__})"
            return
        if self.first is None:
            self.first = bytes(data)
        self.stamps.append(stamp)
        self.values.extend(values)

    def array(self, index: int, rows: np.ndarray) -> np.ndarray:
        """Field ``index`` (the index-th float array of the message) at the message rows ``rows``."""
        table = np.frombuffer(self.values, dtype=float).reshape(-1, self.width)
        start = sum(self.counts[:index])
        return table[rows, start:start + self.counts[index]]


_KEPT_TYPES = {"sensor_msgs/msg/JointState", "trajectory_msgs/msg/JointTrajectory"}


@dataclass
class BagContents:
    """What a bag's records hold, read without the experiment being validated (:func:`read_contents`); the
    caller parses ``experiment_text`` and gives the result to :func:`decode_run`."""

    path: Path
    experiment_text: str          # the experiment YAML stored in the bag, or the one given for it
    given: bool                   # the text was given (a bag recorded without one, or another one's)
    stored_sample_time: str | None
    kept: dict                    # topic -> _TopicColumns of the JointState and JointTrajectory topics
    payloads: dict                # topic -> raw CDR payloads (only when asked for)
    warnings: list
    damaged: list                 # Damage of each part of the file that could not be read


@contextlib.contextmanager
def reading(path):
    """Whatever reading the bag at ``path`` meets becomes one BagError line naming the bag (KeyboardInterrupt
    passes): the reader's own refusals as they are, a ContouringError prefixed with the path, anything else
    (crafted contents no check foresaw) as 'cannot read the bag', never a traceback."""
    try:
        yield
    except (BagError, KeyboardInterrupt):
        raise
    except ContouringError as error:
        raise BagError(f"{path}: {error}") from None
    except Exception as error:
        raise BagError(f"{path}: cannot read the bag ({type(error).__name__}: {error})") from None


def read_contents(path, keep_payloads: bool = False, experiment_text: str | None = None,
                  progress: bool = False) -> BagContents:
    """Stream a bag's records and keep what a run is made of: the columns of its JointState and
    JointTrajectory topics, the experiment text it stores (``experiment_text`` instead when given: a bag
    recorded without one) and its stored sample time. Nothing here validates the experiment.

    Works on bags of the recorder, on rosbag2 MCAP bags with the same topics and types, and on bags whose
    writer died (see :func:`iter_records`); what the reader had to make do with is in the ``warnings``.
    Whatever the file holds, what cannot be read is a BagError (one line naming the bag and the problem).
    """
    path = Path(path)
    with reading(path):
        return _read_contents(path, keep_payloads, experiment_text, progress)


def decode_run(contents: BagContents, experiment=None, divergence_bound: float | None = None,
               experiment_error: Exception | None = None) -> RecordedRun:
    """The run a bag's contents hold: per-step arrays of the steps for which every topic was recorded.

    ``experiment`` is the Experiment of ``contents.experiment_text``, parsed by the caller (None where it
    does not validate here, ``experiment_error`` saying why): the bag is checked against it (sample time,
    axes, steps) and the run carries it. ``divergence_bound`` is the bound of its whole path (None: the
    recorded reference's own size). Every problem is a BagError (one line) or a warning.
    """
    with reading(contents.path):
        return _decode_run(contents, experiment, divergence_bound, experiment_error)


def _checked_sample_time(path, stored, experiment, warnings: list) -> float:
    """The sample time of a bag: the experiment's, and the metadata's (``stored``, a string or None) only as
    long as it is a sample time the validator would take and agrees with the experiment's."""
    low, high = GLOBALS["sample_time"].bounds
    value = None
    if stored is not None:
        try:
            value = float(stored)
        except ValueError:
            value = float("nan")
        if not low <= value <= high:
            what = f"the bag's {EXPERIMENT_METADATA} sample_time {stored!r} is not a sample time ({low:g} to {high:g} s)"
            if experiment is None:
                raise BagError(f"{path}: {what}, and the experiment gives none")
            warnings.append(f"{path}: {what}; the experiment's ({experiment.sample_time:g} s) is used")
            value = None
    if experiment is not None:
        if value is not None and value != experiment.sample_time:
            warnings.append(f"{path}: the bag's {EXPERIMENT_METADATA} sample_time {value:g} s differs from its "
                            f"experiment's ({experiment.sample_time:g} s); the experiment's is used")
        return experiment.sample_time
    if value is None:
        raise BagError(f"{path}: no sample time (neither the {EXPERIMENT_METADATA} metadata nor a valid experiment "
                       "gives one)")
    return value


def _graph_namespace(path, kept: dict, warnings: list) -> str:
    """The namespace of the graph a bag recorded: the one whose /reference has the most messages; another
    topic ending in /reference is named in a warning and left out (a stray publisher never makes a bag
    unreadable)."""
    prefixes = {}
    for name, columns in kept.items():
        if name.endswith(graph.REFERENCE) and columns.type_name == "trajectory_msgs/msg/JointTrajectory":
            prefixes[name[:-len(graph.REFERENCE)] or "/"] = len(columns.stamps)
    if not prefixes:
        return "/"
    chosen = max(sorted(prefixes), key=lambda prefix: prefixes[prefix])
    others = [prefix for prefix in sorted(prefixes) if prefix != chosen]
    if others:
        where = lambda prefix: (prefix.rstrip("/") + graph.REFERENCE)  # noqa: E731
        warnings.append(f"{path}: {', '.join(f'{where(p)} ({prefixes[p]} messages)' for p in others)} left out: "
                        f"the graph read is the one of {where(chosen)} ({prefixes[chosen]} messages)")
    return chosen


def _check_joint_names(path, joint_names, experiment, given: bool = False) -> list:
    """The axes a bag's /reference names (its joint names but the last, which must be theta): refused in one
    line when they are none, repeat one, are not axis names, or are not the experiment's axes."""
    names = list(joint_names)
    axes = names[:-1]
    shown = ", ".join(repr(name) for name in names[:10]) + (", ..." if len(names) > 10 else "")
    if not names or names[-1] != graph.THETA_NAME or not axes:
        raise BagError(f"{path}: its {graph.REFERENCE} names the joints [{shown}]: expected one or more axes, then "
                       f"'{graph.THETA_NAME}'")
    if len(set(axes)) != len(axes):
        twice = next(axis for axis in axes if axes.count(axis) > 1)
        raise BagError(f"{path}: its {graph.REFERENCE} names the axis {twice!r} twice ([{shown}])")
    for axis in axes:
        if not is_axis_name(axis):
            raise BagError(f"{path}: its {graph.REFERENCE} names {axis!r}, not an axis name ([{shown}])")
    if experiment is not None and list(experiment.axes) != axes:
        source = f"--experiment {experiment.name}" if given else "its experiment"
        raise BagError(f"{path}: {source} has axes {', '.join(experiment.axes)}; the bag has {', '.join(axes)} (the "
                       f"joints its {graph.REFERENCE} names)")
    return axes


def _on_grid(path, stamps: np.ndarray, sample_time: float, n_steps: int | None, warnings: list) -> np.ndarray:
    """The complete steps' stamps that are steps of the experiment: t_k = k Ts with 0 <= k < n_steps (the
    nodes refuse any other stamp, so no run records one); the others are left out, with a warning."""
    ts_ns = int(round(sample_time * 1e9))
    k = stamps // ts_ns
    good = (stamps >= 0) & (stamps % ts_ns == 0)
    if n_steps is not None:
        good &= k < n_steps
    if good.all():
        return stamps
    bad = stamps[~good]
    end = f" (the experiment ends at t = {(n_steps - 1) * sample_time:g} s)" if n_steps is not None else ""
    warnings.append(f"{path}: {len(bad)} step{'s' if len(bad) > 1 else ''} stamped off the experiment's steps "
                    f"(t = {', '.join(f'{t * 1e-9:.6g}' for t in bad[:3])}{' ...' if len(bad) > 3 else ''} s; "
                    f"steps are k x {sample_time:g} s){end}: left out")
    return stamps[good]


def _graph_named(topic: str) -> bool:
    """Whether ``topic`` ends as one of the graph's recorded JointState / JointTrajectory topics does
    (/reference, /contour_error, /ccc/correction, /<axis>/state, /<axis>/command), under any namespace."""
    return topic.rsplit("/", 1)[-1] in _GRAPH_TOPIC_NAMES


_GRAPH_TOPIC_NAMES = {topic.name.rsplit("/", 1)[-1] for topic in graph.recorded_topics(["axis"], True, True)
                      if topic.type in _KEPT_TYPES}


def _read_contents(path: Path, keep_payloads: bool, experiment_text: str | None, progress: bool) -> BagContents:
    from mcap.records import Channel, Metadata, Schema
    if not path.is_file():
        raise BagError(f"{path}: no such bag")
    given = experiment_text is not None
    kept: dict = {}
    payloads: dict = {}
    warnings: list = []
    damaged: list = []            # Damage of each part of the file that could not be read
    schemas, keepers = {}, {}     # channel id -> _TopicColumns of the topics scoring needs
    stored_sample_time = None
    counts, full = {False: 0, True: 0}, {False: False, True: False}   # topics kept, by _graph_named
    for record in iter_records(path, warnings, progress, damaged):
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            type_name = schemas[record.schema_id].name if record.schema_id in schemas else None
            if type_name in _KEPT_TYPES and not record.topic.endswith(graph.DIAGNOSTICS):
                # graph-named topics and the others are counted apart: strays listed first cannot crowd out
                # the run's own topics
                group = _graph_named(record.topic)
                if record.topic not in kept and counts[group] >= _MAX_TOPICS:
                    if not full[group]:
                        warnings.append(f"{path}: more than {_MAX_TOPICS} JointState and JointTrajectory topics"
                                        f"{' named as the graph names its own' if group else ''}; from "
                                        f"{record.topic} on, the others are left out")
                        full[group] = True
                    continue
                counts[group] += record.topic not in kept
                columns = kept.setdefault(record.topic, _TopicColumns(record.topic, type_name))
                if columns.type_name == type_name:    # a second channel of the topic with another type: not read
                    keepers[record.id] = columns
        elif isinstance(record, Metadata):
            if record.name == EXPERIMENT_METADATA:
                experiment_text = experiment_text or record.metadata.get("yaml")
                stored_sample_time = record.metadata.get("sample_time")
        else:
            columns = keepers.get(record.channel_id)
            if columns is None:
                continue
            columns.add(record.data)
            if keep_payloads:
                payloads.setdefault(columns.topic, []).append(bytes(record.data))
    if damaged and not experiment_text:
        raise BagError(f"{path}: the bag is damaged ({damaged[0].reason} at byte {damaged[0].offset}) and holds no "
                       f"experiment ('{EXPERIMENT_METADATA}' metadata); give the experiment file that produced it")
    if not experiment_text:
        raise BagError(f"{path}: the bag holds no experiment ('{EXPERIMENT_METADATA}' metadata); give the "
                       "experiment file that produced it")
    if len(experiment_text) > MAX_FILE_BYTES:
        raise BagError(f"{path}: its experiment ('{EXPERIMENT_METADATA}' metadata) is {len(experiment_text)} "
                       f"characters; an experiment file has at most {MAX_FILE_BYTES}")
    return BagContents(path, experiment_text, given, stored_sample_time, kept, payloads, warnings, damaged)


def _decode_run(contents: BagContents, experiment, divergence_bound: float | None,
                experiment_error: Exception | None) -> RecordedRun:
    """The steps of :func:`decode_run`, in order: each check raises its BagError or adds its warning."""
    path = contents.path
    warnings = list(contents.warnings)
    sample_time = _checked_sample_time(path, contents.stored_sample_time, experiment, warnings)
    namespace, kept, payloads = _in_namespace(path, contents.kept, contents.payloads, warnings)
    axes = _reference_axes(path, kept, namespace, experiment, contents.given)
    needed = [graph.REFERENCE, graph.CONTOUR_ERROR, graph.CORRECTION] + \
        [graph.state_topic(a) for a in axes] + [graph.command_topic(a) for a in axes]
    _check_topics(path, kept, needed, namespace, warnings)
    _check_arrays(path, kept, needed, axes, namespace)
    stamps = _complete_steps(path, kept, needed, sample_time, experiment.n_steps if experiment is not None else None,
                             warnings)
    rows = _rows(kept, needed, stamps)
    if contents.damaged:
        warnings[:0] = _damage_warnings(path, contents.damaged, kept, needed, stamps, sample_time)
    result = _signals(kept, rows, axes, stamps, sample_time)
    result = _up_to_divergence(path, result, divergence_bound, warnings)
    return RecordedRun(experiment_text=contents.experiment_text, axes=axes, result=result, payloads=payloads,
                       warnings=warnings, experiment=experiment, experiment_error=experiment_error)


def _in_namespace(path, kept: dict, payloads: dict, warnings: list) -> tuple:
    """(namespace, kept, payloads): a graph run under a namespace (/m1/reference ...) has its topics by the
    graph's own names, those of other namespaces left out (:func:`_graph_namespace`)."""
    namespace = _graph_namespace(path, kept, warnings)
    if namespace != "/":
        kept = {name[len(namespace):]: columns for name, columns in kept.items() if name.startswith(namespace + "/")}
        payloads = {name[len(namespace):]: data for name, data in payloads.items() if name.startswith(namespace + "/")}
    return namespace, kept, payloads


def _reference_axes(path, kept: dict, namespace: str, experiment, given: bool) -> list:
    """The axes the graph's reference names (:func:`_check_joint_names`); a BagError where there is no
    reference topic, or its first message cannot be read."""
    reference = kept.get(graph.REFERENCE)
    if reference is None or reference.type_name != "trajectory_msgs/msg/JointTrajectory" or \
            (not len(reference.stamps) and reference.problem is None):
        raise BagError(f"{path}: the bag has no {graph.REFERENCE} messages")
    if reference.problem is not None and not len(reference.stamps):
        raise BagError(f"{path}: {namespace.rstrip('/')}{graph.REFERENCE}: {reference.problem}")
    return _check_joint_names(path, cdr.decode_joint_trajectory(reference.first).joint_names, experiment, given)


def _check_topics(path, kept: dict, needed: list, namespace: str, warnings: list) -> None:
    """Every topic of the graph's steps (``needed``) is there, of its type, and read to its end; another topic
    whose messages stopped being read is left out with a warning."""
    for topic in needed:
        if topic not in kept:
            raise BagError(f"{path}: the bag has no {topic} messages")
        expected = "trajectory_msgs/msg/JointTrajectory" if topic == graph.REFERENCE else "sensor_msgs/msg/JointState"
        if kept[topic].type_name != expected:
            raise BagError(f"{path}: {namespace.rstrip('/')}{topic} is a {kept[topic].type_name}, not a {expected}")
        if kept[topic].problem is not None:
            raise BagError(f"{path}: {namespace.rstrip('/')}{topic}: {kept[topic].problem}")
    for topic, columns in kept.items():
        if columns.problem is not None and topic not in needed:
            warnings.append(f"{path}: {columns.topic} left out (not a topic of the graph's steps): {columns.problem}")


def _check_arrays(path, kept: dict, needed: list, axes: list, namespace: str) -> None:
    """Each topic's messages have the arrays the graph's have for ``axes`` (index -> values at least)."""
    n = len(axes)
    shapes = {graph.REFERENCE: {0: n + 1, 1: n + 1, 2: n + 1}, graph.CONTOUR_ERROR: {0: n + 2}, graph.CORRECTION: {2: n}}
    for topic in needed:
        columns = kept[topic]
        shape = shapes.get(topic, {0: 1, 1: 1} if topic.endswith("/state") else {2: 1})
        if columns.counts is not None and any(len(columns.counts) <= i or columns.counts[i] < count
                                              for i, count in shape.items()):
            raise BagError(f"{path}: {namespace.rstrip('/')}{topic}: messages with arrays of {columns.counts} values; "
                           f"the graph's for axes {', '.join(axes)} have at least {shape} (array: values)")


def _complete_steps(path, kept: dict, needed: list, sample_time: float, n_steps: int | None,
                    warnings: list) -> np.ndarray:
    """The stamps of the complete steps: those with a message on every topic of ``needed`` that are steps
    of the experiment (:func:`_on_grid`); a BagError where there is none."""
    silent = [topic for topic in needed if not len(kept[topic].stamps)]
    if silent:
        raise BagError(f"{path}: no complete step: {', '.join(silent)} recorded no messages")
    stamps = np.asarray(kept[needed[0]].stamps)
    for topic in needed[1:]:
        stamps = np.intersect1d(stamps, np.asarray(kept[topic].stamps))
    stamps = _on_grid(path, stamps, sample_time, n_steps, warnings)
    if not len(stamps):
        raise BagError(f"{path}: no complete step (no stamp has a message on every one of {', '.join(needed)})")
    return stamps


def _rows(kept: dict, needed: list, stamps: np.ndarray) -> dict:
    """topic -> the row of each step's message (the last one where a stamp repeats)."""
    rows = {}
    for topic in needed:
        own = np.asarray(kept[topic].stamps)
        order = np.argsort(own, kind="stable")
        rows[topic] = order[np.searchsorted(own[order], stamps, side="right") - 1]
    return rows


def _damage_warnings(path, damaged: list, kept: dict, needed: list, stamps: np.ndarray, sample_time: float) -> list:
    """One warning per damaged part of the bag, naming the steps it lost."""
    last_ns = max(int(kept[topic].stamps[-1]) for topic in needed)
    return [damage.warning(path, sample_time, _lost_steps(damage, stamps, sample_time, last_ns)) for damage in damaged]


def _signals(kept: dict, rows: dict, axes: list, stamps: np.ndarray, sample_time: float) -> SimulationResult:
    """The per-step signals of the complete steps, from the rows ``rows`` of each topic's messages."""
    n = len(axes)

    def column(topic, index, count=None):
        return kept[topic].array(index, rows[topic])[:, :count]

    def per_axis(topic_of, index):
        return np.hstack([column(topic_of(a), index, 1) for a in axes])

    reference_pos, reference_vel, reference_acc = (column(graph.REFERENCE, i) for i in (0, 1, 2))
    estimate = column(graph.CONTOUR_ERROR, 0)
    return SimulationResult(
        time=_step_times(stamps.tolist(), sample_time), theta=reference_pos[:, n],
        reference_position=reference_pos[:, :n], reference_velocity=reference_vel[:, :n],
        reference_acceleration=reference_acc[:, :n],
        position=per_axis(graph.state_topic, 0), velocity=per_axis(graph.state_topic, 1),
        estimate_theta=estimate[:, n + 1], estimate_vector=estimate[:, :n], estimate_signed=estimate[:, n],
        correction=column(graph.CORRECTION, 2), command=per_axis(graph.command_topic, 2))


def _step_times(stamps_ns, sample_time) -> np.ndarray:
    """Times of the recorded steps, computed as the simulation computes them (k Ts) when Ts is known."""
    if sample_time is None or not np.isfinite(sample_time):
        return np.array(stamps_ns, dtype=float) * 1e-9
    ts_ns = int(round(sample_time * 1e9))
    return np.array([step_time(stamp // ts_ns, sample_time) for stamp in stamps_ns])


def _up_to_divergence(path, result: SimulationResult, divergence_bound: float | None,
                      warnings: list) -> SimulationResult:
    """``result`` up to the step before the run diverged (with a warning); a BagError where it diverged
    before any complete step."""
    diverged = first_divergence(result.time, result.position, result.reference_position, divergence_bound)
    if not diverged:
        return result
    k, diverged = diverged
    if k == 0:
        raise BagError(f"{path}: the run {diverged}, before any complete step")
    warnings.append(f"the run {diverged}; read up to the step before it ({k} steps)")
    return SimulationResult(**{name: value[:k] for name, value in vars(result).items()})


def _lost_steps(damage: Damage, complete_ns: np.ndarray, sample_time: float, last_ns: int) -> np.ndarray:
    """The steps k within the damaged part's time range (to the last recorded step when it runs to the end)
    that have no complete step in the bag."""
    ts_ns = int(round(sample_time * 1e9))
    start = 0 if damage.start_ns is None else -(-damage.start_ns // ts_ns)
    stop = (last_ns if damage.end_ns is None else damage.end_ns) // ts_ns
    steps = np.arange(start, max(stop, start - 1) + 1, dtype=np.int64)
    return steps[~np.isin(steps * ts_ns, complete_ns)]
