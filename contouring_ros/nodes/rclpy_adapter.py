"""The one home of the rclpy internals the package uses, with a check at import that they are there.

The graph's lean loops (:mod:`contouring_ros.nodes.lockstep`, :mod:`contouring_ros.nodes.realtime`,
:mod:`contouring_ros.run.composed`, bench/pingpong.py) run without an executor: a node waits on one persistent
wait set holding its subscriptions, takes each message as serialised bytes straight from the subscription (no
callback, no rclpy message object: the cdr codec reads the wire format) and answers its parameter services
between steps. rclpy's public API offers none of this: its executors wait on a wait set rebuilt every turn and
hand each message to a Python callback through a task. Each step of the graph is a handful of messages, so
those per-message layers would be most of a step's cost. The internals used, all from rclpy's C extension
(``rclpy.impl.implementation_singleton.rclpy_implementation``):

- ``WaitSet(n_subscriptions, 0, 0, 0, 0, 0, context.handle)`` with ``clear_entities``, ``add_subscription``
  and ``wait``: one wait set per loop, made once and refilled each wait (as rcl requires), instead of one
  built per turn by an executor (:class:`SubscriptionWaitSet`);
- ``subscription.handle.take_message(msg_type, raw)``: takes the next message, serialised when ``raw``, with
  its message info (the publication sequence number that tells the topic's one publisher from a stranger),
  or None (:func:`taker`);
- ``service.handle.service_take_request(request_type)``: takes a waiting service request with its header,
  so that the lean loops answer ``ros2 param`` without an executor (:func:`take_request`; the answer goes
  back through the public ``Service.send_response``).

They are rclpy's internals for ROS 2 Jazzy (rclpy 7.1); another rclpy may lack or change them. Importing
this module checks that every one is there and otherwise raises one ImportError
(:class:`~contouring_ros.errors.IncompatibleRclpy`, a ContouringError too) naming the rclpy found and the one
this module was written for, rather than an AttributeError deep in a node's loop; a node's console script
prints it as one line (:mod:`contouring_ros.nodes.scripts`). An rclpy of another version that has them all
is used as it is. The functions here bind the internals once per subscription or loop: a message taken
costs one call of the bound C method, as it would inline.
"""
from __future__ import annotations

import functools

from rclpy.impl.implementation_singleton import rclpy_implementation as _implementation

from ..errors import IncompatibleRclpy

__all__ = ["WRITTEN_FOR", "RCLPY_DISTRIBUTIONS", "installed_version", "missing_internals", "check_internals",
           "taker", "take_request", "SubscriptionWaitSet"]

#: the rclpy this module was written for
WRITTEN_FOR = "rclpy 7.1 (ROS 2 Jazzy)"
#: the distributions that may provide rclpy, in the order their version is read: the PyPI wheels'
#: metapackage (``ros-jazzy-rclpy``) and package (``ros-rclpy``), then a ROS install's own ``rclpy``
RCLPY_DISTRIBUTIONS = ("ros-jazzy-rclpy", "ros-rclpy", "rclpy")
#: (class of the C extension, its attributes) this module uses
REQUIRED = (("WaitSet", ("clear_entities", "add_subscription", "wait", "is_ready")),
            ("Subscription", ("take_message",)),
            ("Service", ("service_take_request",)))


def installed_version() -> str:
    """The installed rclpy as 'DISTRIBUTION VERSION' from the package metadata, or 'rclpy of unknown
    version' when no distribution providing it has metadata (a source checkout on the path)."""
    from importlib import metadata
    for name in RCLPY_DISTRIBUTIONS:
        try:
            return f"{name} {metadata.version(name)}"
        except (metadata.PackageNotFoundError, ValueError):
            continue
    return "rclpy of unknown version"


def missing_internals(implementation=_implementation) -> list:
    """The internals of REQUIRED that ``implementation`` (rclpy's C extension) lacks, as dotted names."""
    missing = []
    for class_name, attributes in REQUIRED:
        cls = getattr(implementation, class_name, None)
        if cls is None:
            missing.append(class_name)
            continue
        missing += [f"{class_name}.{attribute}" for attribute in attributes if not hasattr(cls, attribute)]
    return missing


def check_internals(implementation=_implementation):
    """Raise IncompatibleRclpy (an ImportError), one line, when ``implementation`` lacks an internal this
    module uses."""
    missing = missing_internals(implementation)
    if missing:
        raise IncompatibleRclpy(f"contouring_ros needs rclpy internals that {installed_version()} lacks "
                          f"({', '.join(missing)}); it was written for {WRITTEN_FOR}")


check_internals()


def taker(subscription, msg_type, raw: bool = True):
    """The subscription's take, bound once: ``take()`` returns (the next message, its message info dict)
    or None when none is waiting; the message is its serialised bytes when ``raw``."""
    return functools.partial(subscription.handle.take_message, msg_type, raw)


def take_request(service):
    """(request, header) of the next request waiting at ``service``, or (None, None) when none is; answer it
    with ``service.send_response(response, header)``."""
    with service.handle:
        taken = service.handle.service_take_request(service.srv_type.Request)
    return taken if taken is not None else (None, None)


class SubscriptionWaitSet:
    """One persistent wait set over ``subscriptions`` (a loop's every input), made once: :meth:`wait` refills
    it and waits. False when it holds no subscription (a loop with no input then sleeps instead)."""

    def __init__(self, subscriptions, context):
        self._handles = [subscription.handle for subscription in subscriptions]
        self._wait_set = _implementation.WaitSet(max(len(self._handles), 1), 0, 0, 0, 0, 0, context.handle)

    def __len__(self) -> int:
        return len(self._handles)

    def wait(self, timeout_ns: int):
        """Wait up to ``timeout_ns`` until one of the subscriptions has a message."""
        wait_set = self._wait_set
        wait_set.clear_entities()
        for handle in self._handles:
            wait_set.add_subscription(handle)
        wait_set.wait(timeout_ns)

    def holding(self) -> list:
        """Whether each subscription holds a message not taken yet, in order (waits for nothing; takes nothing)."""
        self.wait(0)
        return [self._wait_set.is_ready("subscription", index) for index in range(len(self._handles))]
