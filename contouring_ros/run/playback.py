"""Republish a bag onto ROS topics, at its recorded rate (or a multiple) or as fast as possible.

Every playable channel of the bag is published raw (the recorded CDR bytes go out unchanged), in the order
of the file, and /clock follows the messages' log times, so use_sim_time nodes and tools see the recorded
time: the bag's own /clock when it is played, otherwise one Clock per distinct log time of the played
messages.

Delivery
--------
Publishers are reliable, volatile, keep-all, with the package's Fast DDS profile (reliable
heartbeats every 20 ms) unless a profile is set in the environment. Before the first message the player
waits, at most ``wait_timeout`` s, until ``wait_subscribers`` nodes subscribe to the played topics and
each of their subscriptions (but transient-local ones, which never match a volatile publisher) has matched
a publisher, unchanged for :data:`SETTLE` s; when it gives up it says so in one line and publishes anyway.
While publishing, no publisher has more than :data:`WINDOW` messages unacknowledged: past that the player
waits for its readers' acknowledgements (``wait_for_all_acked``; readers acknowledge at the heartbeats), at
any rate, and at a positive rate it spends the time before each message is due waiting for them. At the
end it waits for the last acknowledgements before it leaves. So a reliable keep-all subscriber receives
every message at any rate, ``--rate 0`` included, and a reliable keep-last subscriber of depth D every
message it takes before D more of the same topic arrive (at ``--rate 0`` the player outruns most Python
subscribers: give them keep-all, or a depth above the bag's messages per topic); a best-effort subscriber
may lose some. A topic whose subscribers do not acknowledge within :data:`ACK_TIMEOUT` s is named in a
warning, and from then on waited for only briefly.

Ctrl-C stops between two messages (the count said is exact), gives the messages under way up to
:data:`CTRL_C_DRAIN` s to be acknowledged, and re-raises KeyboardInterrupt (the CLI exits with 130).

Options
-------
``loop``: play the bag again and again until Ctrl-C; /clock and the pacing restart with the bag at each
pass (time jumps back: the messages go out unchanged, so their header stamps and /clock agree). ``start``: skip the
messages before ``start`` seconds after the bag's first message (a start past the bag's last message is
refused). ``topics``: play only these topics (/clock is still synthesised from their log times); a topic the
bag does not have is refused, and so is a topic name ROS refuses (over 247 characters, odd characters), in
one line before ROS starts. At a positive rate a gap to the next message of more than :data:`MAX_WAIT` s of
wall time (a bag whose last messages are logged years later) is refused, saying so, instead of waited for.

Message types
-------------
A channel's type is taken only from the ROS message packages installed (:func:`installed_message_class`):
its schema name must be ``pkg/msg/Type`` with ``pkg`` registered in an ament index (``rosidl_interfaces``)
of this environment or of ``AMENT_PREFIX_PATH`` and listing ``msg/Type``, and the Python package must live
under that prefix. Anything else is refused with one warning line naming the topic and the type, and
nothing is imported: a bag cannot make the player run code.
"""
from __future__ import annotations

import contextlib
import importlib
import importlib.util
import os
import re
import signal
import site
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..wire import cdr, graph
from ..records.bag_reader import iter_records, summary_chunks
from ..errors import BagError

__all__ = ["play_bag", "installed_message_class", "UnplayableType", "WINDOW", "SETTLE", "ACK_TIMEOUT",
           "CTRL_C_DRAIN"]

WINDOW = 1000       # messages a publisher may have unacknowledged before the player waits for its readers
SETTLE = 0.25       # s the matched subscriptions must stay the same before the first message
ACK_TIMEOUT = 10.0  # s the player waits for acknowledgements before it goes on without them (and says so)
CTRL_C_DRAIN = 2.0  # s at most for the acknowledgements of the messages under way at a Ctrl-C
MAX_WAIT = 3600.0   # s of wall time the player waits for one message at a positive rate; a longer gap is refused
_TYPE_NAME = re.compile(r"^([a-z][a-z0-9_]*)/msg/([A-Za-z][A-Za-z0-9]*)$")
_CLOCK_TYPE = "rosgraph_msgs/msg/Clock"


def _player_qos():
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                      history=HistoryPolicy.KEEP_ALL, depth=0)


class UnplayableType(ValueError):
    """A channel's type that is not an installed ROS message (the reason is the message)."""


def _prefixes() -> list[Path]:
    """Install prefixes to look for ament indexes in: AMENT_PREFIX_PATH (a sourced ROS install or
    workspace), this Python environment (the PyPI message wheels), the user's site base."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes += [sys.prefix, site.getuserbase()]
    out = []
    for prefix in prefixes:
        path = Path(os.path.abspath(prefix))
        if path not in out:
            out.append(path)
    return out


def _interface_prefix(package: str, name: str) -> Path | None:
    """The prefix whose ament index registers ``package`` as a ROS interface package listing ``msg/name``."""
    for prefix in _prefixes():
        resource = prefix / "share" / "ament_index" / "resource_index" / "rosidl_interfaces" / package
        try:
            entries = resource.read_text().split()
        except OSError:
            continue
        if f"msg/{name}.msg" in entries or f"msg/{name}.idl" in entries:
            return prefix
    return None


def installed_message_class(type_name: str):
    """The Python class of ``type_name`` if it names a message of an installed ROS interface package.

    Raises :class:`UnplayableType` (and imports nothing) unless ``type_name`` is ``pkg/msg/Type`` with
    ``pkg`` an interface package of an ament index (see the module docstring) that lists ``msg/Type``,
    and the Python package ``pkg`` found on sys.path lies under that index's prefix.
    """
    match = _TYPE_NAME.match(type_name or "")
    if match is None:
        raise UnplayableType("not a pkg/msg/Type name")
    package, name = match.groups()
    prefix = _interface_prefix(package, name)
    if prefix is None:
        raise UnplayableType("not a message of an installed ROS interface package")
    if package not in sys.modules:
        spec = importlib.util.find_spec(package)   # finds without importing (a top-level name)
        origin = getattr(spec, "origin", None) if spec is not None else None
        if origin is None or not os.path.abspath(origin).startswith(str(prefix) + os.sep):
            raise UnplayableType(f"the Python package {package} is not the one installed under {prefix}")
    try:
        cls = getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError) as error:
        raise UnplayableType(f"cannot load it ({type(error).__name__}: {error})") from None
    if not hasattr(type(cls), "__import_type_support__"):
        raise UnplayableType("not a ROS message class")
    return cls


@dataclass
class _Index:
    """What the player needs to know before it publishes: schemas, channels, first log time."""
    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    first_log: int | None = None
    last_log: int | None = None


def _index(path: Path, warnings: list) -> _Index:
    """Schemas, channels and first log time from the bag's summary (read with the bag reader's bounds: a
    summary section past its size cap, or one that does not check, is not used), or from one pass over a
    bag without."""
    from mcap.records import Channel, Schema
    index = _Index()
    with open(path, "rb") as stream:
        _, chunks, records = summary_chunks(stream, path.stat().st_size, path, [])
    if chunks and records:
        for record in records:
            (index.schemas if isinstance(record, Schema) else index.channels)[record.id] = record
        starts = [start for _, _, start, end in chunks if end > 0]     # a chunk without messages has 0, 0
        index.first_log = min(starts) if starts else None
        index.last_log = max((end for _, _, _, end in chunks if end > 0), default=None)
        if any(isinstance(record, Channel) for record in records):
            return index
        index = _Index()
    for record in iter_records(path, warnings):
        if isinstance(record, Schema):
            index.schemas[record.id] = record
        elif isinstance(record, Channel):
            index.channels[record.id] = record
        elif hasattr(record, "log_time"):
            if index.first_log is None or record.log_time < index.first_log:
                index.first_log = record.log_time
            if index.last_log is None or record.log_time > index.last_log:
                index.last_log = record.log_time
    return index


def _check_topic_name(path: Path, topic: str) -> None:
    """BagError in one line where ROS refuses ``topic`` as a topic name (too long, odd characters ...)."""
    from rclpy.exceptions import InvalidTopicNameException
    from rclpy.validate_full_topic_name import validate_full_topic_name
    try:
        validate_full_topic_name(topic)
    except InvalidTopicNameException as error:
        why = str(error).splitlines()[0].removeprefix("Invalid topic name: ")
        shown = topic if len(topic) <= 60 else f"{topic[:57]}... ({len(topic)} characters)"
        raise BagError(f"{path}: topic {shown}: ROS refuses the name ({why}); play the others with --topics") \
            from None


def _channel_type(index: _Index, channel) -> str:
    schema = index.schemas.get(channel.schema_id)
    if schema is None:
        raise UnplayableType("no schema")
    if schema.encoding not in ("ros2msg", "ros2idl") or channel.message_encoding != "cdr":
        raise UnplayableType(f"not a ROS 2 CDR channel ({schema.encoding}/{channel.message_encoding})")
    return schema.name


def _wait_for_subscribers(node, publishers: dict, count: int, timeout: float, say) -> None:
    """Wait until ``count`` nodes subscribe to the topics of ``publishers`` and every subscription seen on
    them (but transient-local ones) has matched, unchanged for SETTLE s; at most ``timeout`` s."""
    from rclpy.qos import DurabilityPolicy
    say(f"waiting up to {timeout:g} s for {count} subscriber{'s' if count != 1 else ''} on the bag's topics "
        "(--wait-subscribers 0 starts at once)")
    deadline, steady_since, last = time.monotonic() + timeout, None, None
    while True:
        nodes, unmatched, matched = set(), [], []
        for topic, publisher in publishers.items():
            # a transient-local subscription never matches a volatile publisher (rclpy's qos_check_compatible
            # reads the discovered profiles' infinite deadline and lease as finite ones, so it is not used)
            infos = [info for info in node.get_subscriptions_info_by_topic(topic)
                     if info.qos_profile.durability != DurabilityPolicy.TRANSIENT_LOCAL]
            nodes.update((info.node_namespace, info.node_name) for info in infos)
            have = publisher.get_subscription_count()
            matched.append(have)
            if have < len(infos):
                unmatched.append(topic)
        state = (len(nodes), tuple(matched))
        now = time.monotonic()
        if len(nodes) >= count and not unmatched:
            if state != last:
                steady_since = now
            elif now - steady_since >= SETTLE:
                return
        last = state
        if now >= deadline:
            detail = f"; not matched on {', '.join(unmatched)} (incompatible QoS?)" if unmatched else ""
            say(f"warning: {len(nodes)} of {count} subscriber{'s' if count != 1 else ''} after {timeout:g} s"
                f"{detail}; publishing anyway (early messages may be lost)")
            return
        time.sleep(0.01)


class _Acks:
    """Keeps each publisher's unacknowledged messages under WINDOW.

    Readers acknowledge at the writer's heartbeats (every 20 ms with the package's profile), so a wait is
    up to one heartbeat period. Messages count as pending from their publication until a wait finds all of
    the publisher's messages acknowledged. When the player has time to spare (``idle``: at a positive rate,
    until the next message is due) it spends it waiting for the acknowledgements of the publishers with
    SOFT or more pending; a publisher that reaches WINDOW pending is waited for at once (at ``--rate 0``
    this is what paces the player).
    """

    SOFT = 32

    def __init__(self, say):
        self.pending = {}
        self.say = say
        self.warned = set()

    def sent(self, publisher, count: int = 1):
        n = self.pending.get(publisher, 0) + count
        self.pending[publisher] = n
        if n >= WINDOW:
            self.wait(publisher, ACK_TIMEOUT)

    def idle(self, until: float):
        """Until the monotonic time ``until``: wait for acknowledgements, then sleep the rest."""
        from rclpy.duration import Duration
        for publisher, n in self.pending.items():
            left = until - time.monotonic()
            if left <= 0:
                return
            if n >= self.SOFT and publisher.wait_for_all_acked(Duration(nanoseconds=int(min(left, 0.05) * 1e9))):
                self.pending[publisher] = 0
        left = until - time.monotonic()
        if left > 0:
            time.sleep(left)

    def wait(self, publisher, timeout: float, quiet: bool = False):
        from rclpy.duration import Duration
        if publisher.topic_name in self.warned:
            timeout = 0.0
        deadline = time.monotonic() + timeout
        while not publisher.wait_for_all_acked(Duration(nanoseconds=50_000_000)):   # short: Ctrl-C gets in
            if time.monotonic() >= deadline:
                if not quiet and publisher.topic_name not in self.warned:
                    self.warned.add(publisher.topic_name)
                    self.say(f"warning: a subscriber of {publisher.topic_name} has not acknowledged for "
                             f"{timeout:g} s; going on without it (it may lose messages)")
                break
        self.pending[publisher] = 0

    def drain(self, timeout: float, quiet: bool = False):
        """Wait for every publisher's pending messages, ``timeout`` s at most in all."""
        deadline = time.monotonic() + timeout
        for publisher, n in list(self.pending.items()):
            if n:
                self.wait(publisher, max(deadline - time.monotonic(), 0.0), quiet)


class _Interrupts:
    """SIGINT handling that can hold a Ctrl-C back through a short critical section (``deferred``) and
    raise its KeyboardInterrupt right after; elsewhere a Ctrl-C raises at once. Only in the main thread
    (elsewhere Python's handler stays, and a Ctrl-C may land inside a section)."""

    def __init__(self):
        self.inside = self.held = False
        self.previous = None

    def _handler(self, signum, frame):
        if self.inside:
            self.held = True
        else:
            raise KeyboardInterrupt

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self.previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)

    @contextlib.contextmanager
    def deferred(self):
        self.inside = True
        try:
            yield
        finally:
            self.inside = False
        if self.held:
            self.held = False
            raise KeyboardInterrupt


class _Player:
    """Publishes the played records of the bag at ``path`` in the order of the file, paced by ``rate`` (0: as
    fast as the acknowledgements allow), from ``start_ns`` (a log time) on, with /clock following their log
    times unless the bag's own is played (``bag_clock``). ``sent`` counts the messages published (exact at a
    Ctrl-C: ``interrupts`` holds it back while one goes out), ``passes`` the passes over the bag."""

    def __init__(self, path: Path, rate: float, publishers: dict, clock, bag_clock: bool, start_ns: int,
                 interrupts: _Interrupts, say):
        self.path, self.rate, self.publishers, self.clock, self.bag_clock = path, rate, publishers, clock, bag_clock
        self.start_ns, self.interrupts, self.say = start_ns, interrupts, say
        self.acks = _Acks(say)
        self.sent = self.passes = 0

    def play(self, warnings: list, loop: bool, progress: bool) -> None:
        """Play the bag once (``loop``: again and again until Ctrl-C); say the reader's ``warnings`` of the
        first pass once it ends."""
        while True:
            played = self._play_pass(warnings if self.passes == 0 else [], progress)
            self.passes += 1
            if self.passes == 1:
                for warning in warnings:
                    self.say(f"warning: {warning}")
            if not loop or not played:
                break
            if progress:
                self.say(f"pass {self.passes} done ({self.sent} messages so far); again (Ctrl-C stops)")

    def _play_pass(self, warnings: list, progress: bool) -> bool:
        """One pass over the bag; False where it had no message to play."""
        path, rate, publishers, clock, bag_clock = self.path, self.rate, self.publishers, self.clock, self.bag_clock
        acks, interrupts, start_ns = self.acks, self.interrupts, self.start_ns
        first_log = wall_start = last_clock = None
        for record in iter_records(path, warnings, progress):
            if not hasattr(record, "log_time") or record.channel_id not in publishers:
                continue
            if record.log_time < start_ns:
                continue
            if wall_start is None:
                first_log, wall_start = record.log_time, time.monotonic()
            if rate > 0:
                due = wall_start + (record.log_time - first_log) * 1e-9 / rate
                if due - time.monotonic() > MAX_WAIT:
                    raise BagError(f"{path}: the next message is {(due - time.monotonic()) * rate:.3g} s of "
                                   f"the bag's time ahead, {due - time.monotonic():.3g} s at --rate {rate:g}: "
                                   f"over the {MAX_WAIT:g} s the player waits for one (published {self.sent} "
                                   "messages; --rate 0 plays without waiting)")
                if due > time.monotonic():
                    acks.idle(due)
            with interrupts.deferred():       # a Ctrl-C lands between messages: the count is exact
                if not bag_clock and record.log_time != last_clock:
                    clock.publish(cdr.encode_clock(*divmod(record.log_time, 1_000_000_000)))
                    last_clock = record.log_time
                    acks.pending[clock] = acks.pending.get(clock, 0) + 1
                publisher = publishers[record.channel_id]
                publisher.publish(bytes(record.data))
                self.sent += 1
            acks.sent(publisher)
            if not bag_clock:
                acks.sent(clock, 0)
        return wall_start is not None


def _check_request(path: Path, rate: float, start: float) -> None:
    """BagError in one line for a bag that is not a file, a negative rate, a start out of range."""
    if not path.is_file():
        raise BagError(f"{path}: no such bag")
    if rate < 0:
        raise BagError(f"--rate {rate:g}: must be 0 (as fast as possible) or positive")
    if not 0 <= start < 1e12:
        raise BagError(f"--start {start:g}: must be 0 or positive (and within the bag)")


def _selected_topics(path: Path, index: _Index, start: float, topics) -> tuple:
    """(the topics to play, ``topics`` as names from the root or None): ``topics`` (each of them the bag's)
    or every topic of the bag; BagError for a topic the bag does not have or a ``start`` past its last
    message."""
    if start and index.first_log is not None and index.last_log is not None \
            and start > (index.last_log - index.first_log) * 1e-9:
        raise BagError(f"--start {start:g}: beyond the bag, whose last message is at "
                       f"{(index.last_log - index.first_log) * 1e-9:g} s after its first")
    bag_topics = {channel.topic for channel in index.channels.values()}
    if topics is None:
        return bag_topics, None
    topics = [topic if topic.startswith("/") else "/" + topic for topic in topics if topic]
    for topic in topics:
        if topic not in bag_topics:
            raise BagError(f"{path}: no topic {topic} in the bag (it has {', '.join(sorted(bag_topics))})")
    return set(topics), topics


def _message_classes(path: Path, index: _Index, selected: set, say) -> tuple:
    """({channel id: message class}, {topic: type name}) of the ``selected`` topics' channels, resolved
    before ROS starts: a topic name ROS refuses is a BagError; a refused type is said in a warning line and
    never imported."""
    types, chosen = {}, {}
    for channel in sorted(index.channels.values(), key=lambda c: c.id):
        if channel.topic not in selected:
            continue
        _check_topic_name(path, channel.topic)
        try:
            type_name = _channel_type(index, channel)
            if channel.topic == graph.CLOCK and type_name != _CLOCK_TYPE:
                raise UnplayableType(f"/clock must be {_CLOCK_TYPE}")
            if chosen.get(channel.topic, type_name) != type_name:
                raise UnplayableType(f"the topic is already played as {chosen[channel.topic]}")
            types[channel.id] = installed_message_class(type_name)
            chosen[channel.topic] = type_name
        except UnplayableType as why:
            schema = index.schemas.get(channel.schema_id)
            say(f"warning: refusing {channel.topic}: type {getattr(schema, 'name', '?')!r}: {why}")
    return types, chosen


def _create_publishers(node, index: _Index, types: dict, clock_type, qos) -> tuple:
    """({topic: publisher}, {channel id: its topic's publisher}): one publisher per played topic and one for
    /clock."""
    by_topic = {graph.CLOCK: node.create_publisher(clock_type, graph.CLOCK, qos)}
    publishers = {}
    for channel_id, cls in types.items():
        topic = index.channels[channel_id].topic
        if topic not in by_topic:
            by_topic[topic] = node.create_publisher(cls, topic, qos)
        publishers[channel_id] = by_topic[topic]
    return by_topic, publishers


def play_bag(path, rate: float = 1.0, progress: bool = False, say=print, *, loop: bool = False,
             start: float = 0.0, topics=None, wait_subscribers: int = 1, wait_timeout: float = 10.0) -> int:
    """Publish the messages of the bag at ``path``; ``rate`` 1 is real time, 0 as fast as possible.

    ``loop`` repeats until Ctrl-C (KeyboardInterrupt, re-raised once the player has cleaned up);
    ``start`` skips the messages before that many seconds after the bag's first; ``topics`` (names)
    plays only those; ``wait_subscribers`` / ``wait_timeout``: see the module docstring.
    Returns the number of messages published (/clock messages the player makes up not counted).
    """
    path = Path(path)
    _check_request(path, rate, start)
    warnings = []
    index = _index(path, [])              # what the reader makes do with is said once, by the playing pass
    selected, topics = _selected_topics(path, index, start, topics)
    types, chosen = _message_classes(path, index, selected, say)
    if not types:
        raise BagError(f"{path}: nothing to play" + (f" on {', '.join(sorted(selected))}" if topics else ""))

    if "FASTDDS_DEFAULT_PROFILES_FILE" not in os.environ:   # the package's profile (heartbeats), as runner.py
        os.environ.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(Path(__file__).resolve().parent
                                                                    / "fastdds_profile.xml"))
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions
    from rosgraph_msgs.msg import Clock

    qos = _player_qos()
    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)   # Ctrl-C: KeyboardInterrupt
    node = player = None
    start_ns = (index.first_log or 0) + round(start * 1e9)
    interrupts = _Interrupts()
    try:
        interrupts.__enter__()
        node = rclpy.create_node("bag_player", context=context)
        by_topic, publishers = _create_publishers(node, index, types, Clock, qos)
        if wait_subscribers > 0:
            _wait_for_subscribers(node, by_topic, wait_subscribers, wait_timeout, say)
        player = _Player(path, rate, publishers, by_topic[graph.CLOCK], graph.CLOCK in chosen, start_ns,
                         interrupts, say)
        player.play(warnings, loop, progress)
        player.acks.drain(ACK_TIMEOUT)           # let reliable subscribers take the tail
    except KeyboardInterrupt:
        if player is not None:
            player.acks.drain(CTRL_C_DRAIN, quiet=True)   # the messages under way, briefly (a second Ctrl-C cuts it)
        say(f"stopped (Ctrl-C): published {player.sent if player is not None else 0} messages from {path}")
        raise
    finally:
        interrupts.__exit__(None, None, None)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=context)
    sent, passes = player.sent, player.passes
    if sent == 0:
        say(f"warning: no message at t >= {start:g} s" if start else "warning: no message to play")
    say(f"published {sent} messages from {path}" + (f" ({passes} pass{'es' if passes != 1 else ''})" if loop else ""))
    return sent
