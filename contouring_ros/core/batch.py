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

from .estimators import ContourEstimate
from .interpolation import Reference, ahead_times, reference, reference_rows
from .simulation import ControlLoop, SimulationResult, step_time
from .progress import EVERY, add as count_steps

__all__ = ["NotBatchable", "deep_equal", "stack", "batch_problem", "batchable", "batch_minimum", "structure", "frame",
           "part_classes", "loop_parts", "simulate_batch"]


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
    for part in loop_parts(loop):
        members = getattr(part, "batch_minimum", 2)
        if members > most:
            most, which = members, type(part).__name__
    return most, which


def part_classes(obj) -> tuple | str:
    """The class of one part of a loop and of the objects it holds, nested: parts with equal classes can be
    stacked when every class is batchable."""
    if not hasattr(obj, "__dict__"):
        return type(obj).__name__
    return (type(obj).__name__,) + tuple((name, part_classes(value)) for name, value in vars(obj).items()
                                         if hasattr(value, "__dict__") or value is None)


def structure(loop: ControlLoop) -> tuple:
    """The step count, sample time and classes a loop is built of, nested objects included: loops with
    equal structures can be stacked when every class is batchable."""
    return (loop.n_steps, loop.sample_time, loop.preview) + tuple(part_classes(part) for part in loop_parts(loop))


def frame(loop: ControlLoop) -> tuple:
    """What loops of different structures must share to run as one *mixed* batch (:func:`simulate_batch` with
    ``mixed``): step count, sample time, axes, reference preview, curve and schedule classes (the path every
    member's reference comes from) and whether an in-position clock sets its times."""
    return (loop.n_steps, loop.sample_time, len(loop.plants), loop.preview, part_classes(loop.curve),
            part_classes(loop.schedule), loop.clock is None)


def loop_parts(loop: ControlLoop) -> tuple:
    """The objects a loop is built of: curve, schedule, plants, servos, estimator, controller."""
    return (loop.curve, loop.schedule, *loop.plants, *loop.servos, loop.estimator, loop.controller)


def batch_problem(loops: list, mixed: bool = False) -> str | None:
    """Why ``loops`` cannot run as one batch (a class without a batch path, different structures, monitoring
    during the run), or None. ``mixed``: as one mixed batch (:func:`simulate_batch`)."""
    if any(getattr(loop, "feed_control", None) is not None for loop in loops):
        return "feed holds and monitoring (feed_events, contour_error_limit, following_error_limit) act on each run " \
            "on its own"
    try:
        _stacked(loops, mixed)
    except NotBatchable as problem:
        return str(problem)
    return None


def batchable(loops: list) -> bool:
    """Whether ``loops`` can run as one batch (same structure, every component with a batch path)."""
    return batch_problem(loops) is None


def _stacked(loops, mixed: bool = False, structures: list | None = None):
    """The loops' parts stacked (see :func:`simulate_batch`); ``structures``: each loop's :func:`structure`,
    where the caller has it (a mixed batch then takes each part's classes from it)."""
    first = loops[0]
    if any(loop.n_steps != first.n_steps or loop.sample_time != first.sample_time
           or len(loop.plants) != len(first.plants) or loop.preview != first.preview for loop in loops):
        raise NotBatchable("the batch mixes durations, sample times, axis counts or reference previews")
    n = len(first.plants)
    part = _mixed_part if mixed else (lambda kind, objects, axes, keys: stack(objects))
    if not mixed:
        for name in ("plants", "servos"):
            for i in range(n):
                if any(part_classes(getattr(loop, name)[i]) != part_classes(getattr(first, name)[i]) for loop in loops):
                    raise NotBatchable(f"the batch mixes {name[:-1]} classes on axis {i + 1}")
    # every axis of every member is a row of one object of the plants and one of the servos, member by member
    # (row j n + i: member j's axis i), each class's axes stacked apart where the axes' classes differ
    keys = None if structures is None else [structure[5:] for structure in structures]   # plants, servos, ...
    return (stack([loop.curve for loop in loops]), stack([loop.schedule for loop in loops]),
            _mixed_part(MixedPlants, [plant for loop in loops for plant in loop.plants], n,
                        None if keys is None else [key[i] for key in keys for i in range(n)]),
            _mixed_part(MixedServos, [servo for loop in loops for servo in loop.servos], n,
                        None if keys is None else [key[n + i] for key in keys for i in range(n)]),
            part(MixedEstimators, [loop.estimator for loop in loops], 0, None if keys is None else [k[-2] for k in keys]),
            part(MixedControllers, [loop.controller for loop in loops], 0,
                 None if keys is None else [k[-1] for k in keys]))


# ------------------------------------------------------------------------------------------ mixed batches
#
# A mixed batch advances loops of different structures along one path together (the rows of a benchmark
# scenario: the same curve, schedule and plants, other estimators, controllers and servos). Each part of the
# loop (an axis' plant, an axis' servo, the estimator, the controller) is stacked per class: the members whose
# part has one class make one stacked object, which steps on its members' rows of the batch's signals. A step
# then costs one call per class of each part, not one per structure, and every member computes exactly what it
# computes in a batch of its own structure: each class's batch path works row by row.


def _mixed_part(kind, objects: list, axes: int = 0, classes: list | None = None):
    """``objects`` (one part of every loop) stacked: one object where they share their classes, else a ``kind``
    (MixedPlants, ...) of one stacked object per class, each on its members' rows. ``axes``: the objects are
    every member's axes, member by member (row j axes + i: member j's axis i); the axes of a class whose
    ``batch_axes`` is set (its batch path computes with every number of its own elementwise, so that one
    axis' numbers can differ from another's) are stacked together, unless they differ in a setting that is
    not a number (say one axis' velocity from the encoder, another's from the model); any other class's
    axis by axis. ``classes``: each object's :func:`part_classes`, where the caller has them."""
    classes = classes or [part_classes(o) for o in objects]
    keys = [key if axes <= 1 or getattr(type(o), "batch_axes", False) else (key, j % axes)
            for j, (o, key) in enumerate(zip(objects, classes))]
    members = {}
    for j, key in enumerate(keys):
        members.setdefault(key, []).append(j)
    parts = []
    for group in members.values():
        try:
            parts.append((_rows_of(group), stack([objects[j] for j in group])))
        except NotBatchable:
            if axes <= 1:
                raise
            for i in range(axes):
                mine = [j for j in group if j % axes == i]
                if mine:
                    parts.append((_rows_of(mine), stack([objects[j] for j in mine])))
    if len(parts) == 1:
        return parts[0][1]
    return kind(sorted(parts, key=lambda part: _first_row(part[0])), len(objects))


def _first_row(rows) -> int:
    return rows.start if isinstance(rows, slice) else int(rows[0])


def _rows_of(group: list):
    """The batch rows of ``group`` (sorted member indices): a slice where they are contiguous (a view), else
    an index array."""
    if group[-1] - group[0] == len(group) - 1:
        return slice(group[0], group[-1] + 1)
    return np.asarray(group)


def _take(value, rows, size: int):
    """``value``'s rows ``rows`` where it has a batch axis of ``size``, else ``value`` (one value for all)."""
    if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == size:
        return value[rows]
    return value


def _count(rows, size: int) -> int:
    return len(range(*rows.indices(size))) if isinstance(rows, slice) else len(rows)


class _Scatter:
    """Arrays of a batch's size filled part by part: ``put(name, rows, value)`` writes a part's value (its rows,
    or one value for them all) into the array ``name``, made on its first value with the value's trailing shape."""

    def __init__(self, size: int):
        self.size, self.arrays = size, {}

    def put(self, name: str, rows, value, shape: tuple | None = None) -> None:
        value = np.asarray(value, dtype=float)
        array = self.arrays.get(name)
        if array is None:
            trailing = shape if shape is not None else (value.shape[1:] if value.ndim else ())
            array = self.arrays[name] = np.empty((self.size,) + tuple(trailing))
        array[rows] = np.broadcast_to(value, (_count(rows, self.size),) + array.shape[1:])


class _Mixed:
    """One part of a mixed batch: ``parts`` (rows, stacked object of one class) covering ``size`` members."""

    batchable = True

    def __init__(self, parts: list, size: int):
        self.parts, self.size = parts, size
        self.preview = max(int(getattr(part, "preview", 0) or 0) for _, part in parts)

    def _rows(self, value, rows):
        return _take(value, rows, self.size)


class MixedPlants(_Mixed):
    """An axis' plants of a mixed batch: each class's ``measure`` and ``step`` on its rows."""

    def measure(self) -> tuple:
        out = _Scatter(self.size)
        for rows, part in self.parts:
            position, velocity = part.measure()
            out.put("position", rows, position, (1,))
            out.put("velocity", rows, velocity, (1,))
        return out.arrays["position"], out.arrays["velocity"]

    def step(self, command, t: float) -> None:
        for rows, part in self.parts:
            part.step(self._rows(command, rows), t)


class MixedServos(_Mixed):
    """An axis' servos of a mixed batch: each class's ``step`` (and ``look_ahead`` where it previews) on its rows."""

    def look_ahead(self, positions) -> None:
        for rows, part in self.parts:
            count = int(getattr(part, "preview", 0) or 0)
            if count:
                part.look_ahead(tuple(self._rows(p, rows) for p in positions[:count]))

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction):
        out = _Scatter(self.size)
        for rows, part in self.parts:
            out.put("command", rows, part.step(*(self._rows(v, rows) for v in (
                ref_pos, ref_vel, ref_acc, position, velocity, correction))), (1,))
        return out.arrays["command"]


def _reference_rows(reference: Reference, rows, size: int) -> Reference:
    """The members ``rows`` of a batch's reference (its memo kept: the rows of a shared path's step are alike)."""
    return Reference(*(_take(v, rows, size) for v in (reference.theta, reference.theta_dot, reference.theta_ddot,
                                                       reference.position, reference.velocity,
                                                       reference.acceleration)), reference.memo)


def _estimate_rows(estimate: ContourEstimate, rows, size: int) -> ContourEstimate:
    return ContourEstimate(theta=_take(estimate.theta, rows, size), vector=_take(estimate.vector, rows, size),
                           signed=_take(estimate.signed, rows, size))


class MixedEstimators(_Mixed):
    """The contour estimators of a mixed batch: each class's ``step_batch`` on its rows."""

    def step_batch(self, reference, position) -> ContourEstimate:
        out, n = _Scatter(self.size), position.shape[-1]
        for rows, part in self.parts:
            estimate = part.step_batch(_reference_rows(reference, rows, self.size), position[rows])
            out.put("theta", rows, estimate.theta, (1,))
            out.put("vector", rows, estimate.vector, (n,))
            out.put("signed", rows, estimate.signed, ())
        return ContourEstimate(theta=out.arrays["theta"], vector=out.arrays["vector"], signed=out.arrays["signed"])


class MixedControllers(_Mixed):
    """The contour controllers of a mixed batch: each class's ``step`` (and ``look_ahead`` where it previews) on
    its rows."""

    def look_ahead(self, positions) -> None:
        for rows, part in self.parts:
            count = int(getattr(part, "preview", 0) or 0)
            if count:
                part.look_ahead(positions[rows, :count])

    def step(self, estimate, reference=None, position=None, velocity=None):
        out, n = _Scatter(self.size), position.shape[-1]
        for rows, part in self.parts:
            out.put("correction", rows, part.step(_estimate_rows(estimate, rows, self.size),
                                                  _reference_rows(reference, rows, self.size),
                                                  position[rows], velocity[rows]), (n,))
        return out.arrays["correction"]


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
    (``batch_shared``: profile tables, tool paths, splines) and its read-only arrays (a plant's noise table) as
    they are: they are only read, and copying them
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
            if name in shared or (value.__class__ is np.ndarray and not value.flags.writeable):
                memo[id(value)] = value         # shared or read-only: nothing writes to it
            elif hasattr(value, "__dict__") or isinstance(value, (list, tuple)):
                todo.append(value)
    return memo


def _axis_rows(values, rows: int) -> np.ndarray:
    """A batch's per-axis values (b, n) as the plants' and servos' rows (b n, 1), member by member."""
    return values.reshape(rows, 1) if values.flags.c_contiguous else np.ascontiguousarray(values).reshape(rows, 1)


def _by_axis(values, b: int, n: int):
    """The plants' or servos' rows (b n, 1) as a batch's per-axis values (b, n); one value for all as it is."""
    return values.reshape(b, n) if values.__class__ is np.ndarray and values.size == b * n else values


def simulate_batch(loops: list[ControlLoop], mixed: bool = False, structures: list | None = None) -> list[SimulationResult]:
    """Run every loop of ``loops`` (one structure, see :func:`batchable`) in one vectorised pass. ``mixed``:
    loops of different structures along one path (one :func:`frame`), each part stacked per class (see
    "mixed batches" above); every member's numbers are those of a batch of its own structure. ``structures``:
    each loop's :func:`structure`, where the caller has them.

    Each loop's objects are left untouched (the batch works on stacked copies).

    Raises
    ------
    NotBatchable
        When the loops cannot run as one batch.
    """
    loops = [copy.deepcopy(loop, _read_only(loop)) for loop in loops]
    curve, schedule, plants, servos, estimator, controller = _stacked(loops, mixed, structures)
    b, m, n, ts = len(loops), loops[0].n_steps, len(loops[0].plants), loops[0].sample_time
    clocks = [loop.clock for loop in loops]
    clocked = any(clock is not None for clock in clocks)
    # every member on one path, on the step time: the path's table holds each step's reference as this batch
    # would compute it for each member (the same for all), computed once for every batch along the path
    table = loops[0].reference_table
    if clocked or table is None or any(loop.reference_table is not table for loop in loops):
        table = None
    time = np.empty(m)
    est_theta, est_signed = np.empty((m, b)), np.empty((m, b))
    positions, velocities, est_vector, corrections, commands = (np.empty((m, b, n)) for _ in range(5))
    if table is not None:       # every step's reference for every member, (m, b, ...), read-only views of the
        stacked, memos = table.stacked_rows(m)                 # path's table: the same for every member
        path = [np.broadcast_to(values, (m, b) + values.shape[2:]) for values in stacked]
        theta, ref_pos, ref_vel, ref_acc = path[0][:, :, 0], path[3], path[4], path[5]
    else:
        theta = np.empty((m, b))
        ref_pos, ref_vel, ref_acc = (np.empty((m, b, n)) for _ in range(3))
    # (b, 1) columns of the per-step rows: a member's value, or one value for all, is written by broadcasting
    theta_rows, est_theta_rows = theta[:, :, None], est_theta[:, :, None]
    preview = loops[0].preview
    servo_preview = int(getattr(servos, "preview", 0) or 0)
    controller_preview = getattr(controller, "preview", 0)
    rows = b * n                # the plants' and servos' rows: member j's axis i is row j n + i
    for k in range(m):
        if k % EVERY == EVERY - 1:
            count_steps(EVERY * b)
        t = step_time(k, ts)
        measured_position, measured_velocity = plants.measure()
        positions[k], velocities[k] = _by_axis(measured_position, b, n), _by_axis(measured_velocity, b, n)
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
            if servo_preview:
                servos.look_ahead(tuple(ahead[:, j, :].reshape(rows, 1) for j in range(servo_preview)))
            if controller_preview:
                controller.look_ahead(ahead[:, :controller_preview])
        correction = np.broadcast_to(controller.step(estimate, ref, position, velocity), (b, n))
        command_row = commands[k]
        command_row[:] = _by_axis(servos.step(*(_axis_rows(v, rows) for v in (
            ref.position, ref.velocity, ref.acceleration, position, velocity, correction))), b, n)
        plants.step(command_row.reshape(rows, 1), t)
        time[k] = t
        if table is None:
            theta_rows[k] = ref.theta
            ref_pos[k], ref_vel[k], ref_acc[k] = ref.position, ref.velocity, ref.acceleration
        est_theta_rows[k] = estimate.theta
        est_signed[k] = estimate.signed
        est_vector[k], corrections[k] = estimate.vector, correction
    return [SimulationResult(time=time, theta=theta[:, j], reference_position=ref_pos[:, j],
                             reference_velocity=ref_vel[:, j], reference_acceleration=ref_acc[:, j],
                             position=positions[:, j], velocity=velocities[:, j], estimate_theta=est_theta[:, j],
                             estimate_vector=est_vector[:, j], estimate_signed=est_signed[:, j],
                             correction=corrections[:, j], command=commands[:, j]) for j in range(b)]
