"""Batch simulation: many experiments of the same structure advanced together, one numpy array per signal.

A sweep varies numbers (gains, curve sizes, durations) and keeps the structure (which curve, estimator,
controller, servo and plant classes). :func:`stack` turns B core objects of one class into one object of
that class whose differing numbers are arrays of shape (B, 1); their ``step`` code then advances all B
experiments at once, because every class marked ``batchable`` computes with operations that work
elementwise on such arrays (the per-axis values of a batch are (B, 1), the vectors (B, n)). The maths stays
in one place: the same methods run a single experiment on floats and a batch on arrays.

:func:`simulate_batch` runs B control loops with the step semantics of
:func:`contouring_ros.core.simulation.simulate` and returns one :class:`SimulationResult` per loop, equal
to the loop's own simulation up to the rounding of vectorised sums.
"""
from __future__ import annotations

import copy
import dataclasses
import inspect
import numbers

import numpy as np

from .interpolation import Reference, ahead_times, reference, reference_rows
from .simulation import ControlLoop, SimulationResult, step_time
from .progress import EVERY, add as count_steps

__all__ = ["NotBatchable", "deep_equal", "stack", "batch_problem", "batchable", "batch_minimum", "structure", "simulate_batch"]


class NotBatchable(Exception):
    """The objects cannot advance as one batch (a class without a batch path, or different structure)."""


def _same(values) -> bool:
    first = values[0]
    for value in values[1:]:
        if value is first:
            continue
        if isinstance(first, np.ndarray) or isinstance(value, np.ndarray):
            if not (np.shape(first) == np.shape(value) and np.array_equal(first, value)):
                return False
        elif type(value) is not type(first) or value != first:
            return False
    return True


def deep_equal(a, b) -> bool:
    """Whether two values are equal all the way down (arrays by value, containers and plain objects by
    their contents): for the attributes a class shares across a batch."""
    if a is b:
        return True
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and np.array_equal(a, b)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(deep_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(deep_equal(a[k], b[k]) for k in a)
    if hasattr(a, "__dict__") and not inspect.isroutine(a):
        return deep_equal(vars(a), vars(b))
    if dataclasses.is_dataclass(a) and not isinstance(a, type):      # a dataclass with slots: field by field
        return all(deep_equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    return bool(a == b)


def _stack_value(name, values):
    if _same(values):
        return values[0]
    first = values[0]
    if isinstance(first, bool) or not all(isinstance(v, type(first)) for v in values):
        raise NotBatchable(f"{name} differs in kind across the batch")
    if isinstance(first, numbers.Real):
        return np.array(values, dtype=float).reshape(-1, 1)
    if isinstance(first, np.ndarray) and first.dtype.kind == "f" and all(v.shape == first.shape for v in values):
        return np.stack(values)
    if isinstance(first, (tuple, list)) and all(len(v) == len(first) for v in values):
        return type(first)(_stack_value(f"{name}[{i}]", [v[i] for v in values]) for i in range(len(first)))
    if hasattr(first, "__dict__"):
        return stack(values)
    raise NotBatchable(f"{name} differs across the batch and cannot be stacked")


def stack(objects: list):
    """One object of the objects' class whose attributes that differ are stacked along a batch axis.

    Numbers that differ become arrays of shape (B, 1); nested objects are stacked the same way; equal
    attributes are kept as they are (so a limit of 0 that no experiment sets stays a plain 0).

    A class whose step cannot run on stacked numbers (an optimisation per member, such as the MPCC's QP)
    gives a ``batch_of(objects)`` class method instead, which returns the batch's object.

    The same object given for every member, of a class that no run writes to (``batch_read_only``: curves and
    schedules, shared by the runs along a path), is the batch's object as it is.

    A class can name attributes that its batch path needs equal across the batch (``batch_shared``, e.g. a
    schedule's profile table, a tool path's segments; compared by value all the way down) and attributes
    computed from those alone (``batch_kept``, e.g. a feed plan's trajectories): both are taken from the
    first object as they are.

    Raises
    ------
    NotBatchable
        When the class has no batch path (``batchable`` is not set), the objects differ in structure or in
        a ``batch_shared`` attribute.
    """
    first = objects[0]
    cls = type(first)
    if not getattr(cls, "batchable", False):
        raise NotBatchable(f"{cls.__name__} has no batch path")
    if any(type(o) is not cls for o in objects):
        raise NotBatchable(f"the batch mixes {cls.__name__} with other classes")
    if all(o is first for o in objects[1:]) and getattr(cls, "batch_read_only", False):
        return first            # one read-only object (a shared path's curve or schedule) serves the batch as it is
    if hasattr(cls, "batch_of"):          # a class whose batch steps each member's own object
        return cls.batch_of(objects)
    shared = tuple(getattr(cls, "batch_shared", ()))
    for name in shared:
        if not all(deep_equal(vars(o).get(name), vars(first).get(name)) for o in objects[1:]):
            raise NotBatchable(f"{cls.__name__}.{name} must be the same across a batch")
    kept = shared + tuple(getattr(cls, "batch_kept", ()))
    out = copy.copy(first)
    for name in vars(first):
        if name not in kept:
            setattr(out, name, _stack_value(f"{cls.__name__}.{name}", [vars(o)[name] for o in objects]))
    return out


def batch_minimum(loop: ControlLoop) -> tuple:
    """(members, class): the fewest members from which a batch of ``loop``'s structure costs less CPU than
    its runs one by one, and the class that sets it (None where every class pays off from two). A class
    states it as ``batch_minimum`` (an attribute or a property; default 2) where its batch path pays a
    cost per step that does not shrink with the batch, such as an iteration that runs until the slowest
    member has converged (bench/batch_speed.py --batch N measures it)."""
    most, which = 2, None
    for part in _parts(loop):
        members = getattr(part, "batch_minimum", 2)
        if members > most:
            most, which = members, type(part).__name__
    return most, which


def structure(loop: ControlLoop) -> tuple:
    """The step count, sample time and classes a loop is built of, nested objects included: loops with
    equal structures can be stacked when every class is batchable."""
    def classes(obj):
        if not hasattr(obj, "__dict__"):
            return type(obj).__name__
        return (type(obj).__name__,) + tuple((name, classes(value)) for name, value in vars(obj).items()
                                              if hasattr(value, "__dict__") or value is None)
    return (loop.n_steps, loop.sample_time, loop.preview) + tuple(classes(part) for part in _parts(loop))


def _parts(loop: ControlLoop) -> tuple:
    """The objects a loop is built of: curve, schedule, plants, servos, estimator, controller."""
    return (loop.curve, loop.schedule, *loop.plants, *loop.servos, loop.estimator, loop.controller)


def batch_problem(loops: list) -> str | None:
    """Why ``loops`` cannot run as one batch (a class without a batch path, different structures, monitoring
    during the run), or None."""
    if any(getattr(loop, "feed_control", None) is not None for loop in loops):
        return "feed holds and monitoring (feed_events, contour_error_limit, following_error_limit) act on each run " \
            "on its own"
    try:
        _stacked(loops)
    except NotBatchable as problem:
        return str(problem)
    return None


def batchable(loops: list) -> bool:
    """Whether ``loops`` can run as one batch (same structure, every component with a batch path)."""
    return batch_problem(loops) is None


def _stacked(loops):
    first = loops[0]
    if any(loop.n_steps != first.n_steps or loop.sample_time != first.sample_time
           or len(loop.plants) != len(first.plants) or loop.preview != first.preview for loop in loops):
        raise NotBatchable("the batch mixes durations, sample times, axis counts or reference previews")
    n = len(first.plants)
    return (stack([loop.curve for loop in loops]), stack([loop.schedule for loop in loops]),
            [stack([loop.plants[i] for loop in loops]) for i in range(n)],
            [stack([loop.servos[i] for loop in loops]) for i in range(n)],
            stack([loop.estimator for loop in loops]), stack([loop.controller for loop in loops]))


def _times(clocks, k, t, positions, velocities) -> np.ndarray:
    """The schedule's time of each member at step k, (b, 1): the step time t, or where a member has an in-position
    clock (:class:`~contouring_ros.core.interpolation.InPositionClock`) its clock's time on its own axis
    states of step k - delay, as :func:`~contouring_ros.core.simulation.simulate` takes it. Each clock is stepped
    on its member's row with the scalar code: where the members wait at exact stops is theirs alone, and the
    times are the runs' own, bit for bit."""
    out = np.full((len(clocks), 1), t)
    for j, clock in enumerate(clocks):
        if clock is not None:
            seen = (positions[k - clock.delay, j].copy(), velocities[k - clock.delay, j].copy()) \
                if k >= clock.delay else (None, None)
            out[j, 0] = clock.time(k, *seen)
    return out


def _ahead_times(clocks, k, times, count, sample_time) -> np.ndarray:
    """Each member's reference preview times after step k, (b, count): as
    :func:`~contouring_ros.core.interpolation.ahead_times` gives them to the member's run alone."""
    out = np.empty((len(clocks), count))
    for j, clock in enumerate(clocks):
        out[j] = ahead_times(k, float(times[j, 0]), count, sample_time, clock)
    return out


def _read_only(loop) -> dict:
    """A deep-copy memo that keeps the tables a loop's classes declare equal across a batch
    (``batch_shared``: profile tables, tool paths, splines) as they are: they are only read, and copying them
    for every member was a good part of a batch's set-up. So are the curve and schedule of a loop on a shared
    path (one with a ``reference_table``: :func:`~contouring_ros.experiment.build.build_path`), which every
    run along the path reads and none writes."""
    memo, seen, todo = {}, set(), [loop]
    if loop.reference_table is not None:
        memo[id(loop.curve)], memo[id(loop.schedule)] = loop.curve, loop.schedule
    while todo:
        obj = todo.pop()
        if id(obj) in seen:
            continue
        seen.add(id(obj))
        if isinstance(obj, (list, tuple)):
            todo.extend(obj)
            continue
        if not hasattr(obj, "__dict__") or inspect.isroutine(obj) or isinstance(obj, type) \
                or hasattr(type(obj), "__deepcopy__"):        # copies itself as it must (a ReferenceTable: not)
            continue
        shared = getattr(type(obj), "batch_shared", ())
        for name, value in vars(obj).items():
            if name in shared:
                memo[id(value)] = value
            elif hasattr(value, "__dict__") or isinstance(value, (list, tuple)):
                todo.append(value)
    return memo


def simulate_batch(loops: list[ControlLoop]) -> list[SimulationResult]:
    """Run every loop of ``loops`` (one structure, see :func:`batchable`) in one vectorised pass.

    Each loop's objects are left untouched (the batch works on stacked copies).

    Raises
    ------
    NotBatchable
        When the loops cannot run as one batch.
    """
    loops = [copy.deepcopy(loop, _read_only(loop)) for loop in loops]
    curve, schedule, plants, servos, estimator, controller = _stacked(loops)
    b, m, n, ts = len(loops), loops[0].n_steps, len(plants), loops[0].sample_time
    clocks = [loop.clock for loop in loops]
    clocked = any(clock is not None for clock in clocks)
    # every member on one path, on the step time: the path's table holds each step's reference as this batch
    # would compute it for each member (the same for all), computed once for every batch along the path
    table = loops[0].reference_table
    if clocked or table is None or any(loop.reference_table is not table for loop in loops):
        table = None
    if table is not None:       # every step's reference for every member, (m, b, ...): a step takes views
        stacked, memos = table.stacked_rows(m)
        path = [np.repeat(values, b, axis=1) for values in stacked]
    time = np.empty(m)
    theta, est_theta, est_signed = np.empty((m, b)), np.empty((m, b)), np.empty((m, b))
    ref_pos, ref_vel, ref_acc, positions, velocities, est_vector, corrections, commands = (
        np.empty((m, b, n)) for _ in range(8))
    # (b, 1) columns of the per-step rows: a member's value, or one value for all, is written by broadcasting
    theta_rows, est_theta_rows = theta[:, :, None], est_theta[:, :, None]
    axes = [(slice(i, i + 1), plant, servo) for i, (plant, servo) in enumerate(zip(plants, servos))]
    preview = loops[0].preview
    previewing = [(i, servo) for i, servo in enumerate(servos) if getattr(servo, "preview", 0)]
    controller_preview = getattr(controller, "preview", 0)
    for k in range(m):
        if k % EVERY == EVERY - 1:
            count_steps(EVERY * b)
        t = step_time(k, ts)
        for column, plant, _ in axes:
            positions[k, :, column], velocities[k, :, column] = plant.measure()
        position, velocity = positions[k].copy(), velocities[k].copy()
        if table is not None:
            ref = Reference(*(values[k] for values in path), memos[k])
        else:
            times = _times(clocks, k, t, positions, velocities) if clocked else np.full((b, 1), t)
            ref = reference_rows(curve, schedule, times)
        estimate = estimator.step_batch(ref, position)
        if preview:         # as simulate() gives it: before the controller's and the servos' steps
            ahead = np.repeat(table.row_ahead(k, preview), b, axis=0) if table is not None else \
                reference(curve, schedule, _ahead_times(clocks, k, times, preview, ts)).position   # (b, P, n)
            for i, servo in previewing:
                servo.look_ahead(tuple(ahead[:, j, i:i + 1] for j in range(servo.preview)))
            if controller_preview:
                controller.look_ahead(ahead[:, :controller_preview])
        correction = np.broadcast_to(controller.step(estimate, ref, position, velocity), (b, n))
        rp, rv, ra, command_row = ref.position, ref.velocity, ref.acceleration, commands[k]
        for column, plant, servo in axes:
            command_row[:, column] = servo.step(rp[:, column], rv[:, column], ra[:, column], position[:, column],
                                                velocity[:, column], correction[:, column])
            plant.step(command_row[:, column], t)
        time[k] = t
        theta_rows[k] = ref.theta
        est_theta_rows[k] = estimate.theta
        est_signed[k] = estimate.signed
        ref_pos[k], ref_vel[k], ref_acc[k] = ref.position, ref.velocity, ref.acceleration
        est_vector[k], corrections[k] = estimate.vector, correction
    return [SimulationResult(time=time, theta=theta[:, j], reference_position=ref_pos[:, j],
                             reference_velocity=ref_vel[:, j], reference_acceleration=ref_acc[:, j],
                             position=positions[:, j], velocity=velocities[:, j], estimate_theta=est_theta[:, j],
                             estimate_vector=est_vector[:, j], estimate_signed=est_signed[:, j],
                             correction=corrections[:, j], command=commands[:, j]) for j in range(b)]
