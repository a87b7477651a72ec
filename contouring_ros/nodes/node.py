"""The class every node of the graph subclasses: its ground, its intake and both timing modes in one.

:class:`LockstepNode` is :class:`~contouring_ros.nodes.base.NodeBase` (parameters in, validated experiment,
inputs and outputs, the end of the run) with :class:`~contouring_ros.nodes.intake.InputIntake` (what it
admits of its inputs), :class:`~contouring_ros.nodes.lockstep.LockstepStepping` (``timing: lockstep``,
:meth:`~LockstepNode.spin`) and :class:`~contouring_ros.nodes.realtime.RealtimeStepping` (``timing:
realtime``, :meth:`~LockstepNode.spin_realtime`). :func:`contouring_ros.nodes.process.run_node` runs one in
its own process.
"""
from __future__ import annotations

from .base import NodeBase
from .intake import InputIntake
from .lockstep import LockstepStepping
from .realtime import RealtimeStepping

__all__ = ["LockstepNode"]


class LockstepNode(LockstepStepping, RealtimeStepping, InputIntake, NodeBase):
    """Base of the graph's nodes: parameters in, validated experiment, lockstep loop.

    Subclasses set ``role``, call :meth:`add_input` / :meth:`add_output` in ``setup`` and implement
    :meth:`start` (publish what needs no input) and :meth:`on_step` (handle one complete step).
    """
