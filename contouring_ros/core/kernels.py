"""Optional compiled kernels (numba) for the in-process simulation's innermost loop: the Newton estimate.

The filtered Newton flow of :class:`~contouring_ros.core.estimators.NewtonEstimator` iterates tens of times
per control step (39-57 on the papers' files), each iteration one evaluation of the curve and a handful of
float operations; alone, that is most of a Newton run's time in Python. Where numba is installed
(``pip install numba``) the flow runs compiled for every curve with a :attr:`~contouring_ros.core.curves.
Curve.formula` (the analytic curves; not the spline, the tool path or a plugin's curve), one member after
another for a batch.

The kernel is the pure path's code: a copy of the flow the pure path runs (:func:`~contouring_ros.core.
foot_point.foot_point_flow` and its planar form), compiled with the curve's own formula function in place of
the curve's columns, itself compiled with the math module's sin, cos and exp (the functions CPython's math
module calls, from the same C library). Every operation is an IEEE
double one in the pure path's order, with no contraction into fused multiply-adds (numba's default), so the
results are the pure path's bit for bit (tests/core/test_kernels.py, on every analytic curve, alone and in
batches). Without numba, or with the environment variable ``CONTOURING_ROS_NUMBA=0``, the pure Python and
numpy path runs. numba is imported, and a curve's kernel compiled (2-3 s), once a process has taken
:data:`COMPILE_AFTER` steps of the pure flow (a sweep's or a tuning's first runs; never a short run alone).
"""
from __future__ import annotations

import importlib.util
import math
import os
import types
import warnings
import weakref

import numpy as np

from .foot_point import foot_point_flow, foot_point_flow_planar

__all__ = ["ENABLED", "compiled_formula", "formula_of", "newton_flow", "newton_flow_batch"]

#: whether the compiled kernels are used: numba installed and not turned off
ENABLED = os.environ.get("CONTOURING_ROS_NUMBA", "1") != "0" and importlib.util.find_spec("numba") is not None
#: steps of the pure flow a process takes before it compiles (numba's import and a curve's compilation cost
#: 2-3 s, about what 50,000 pure steps cost): a short run alone never waits for it, a sweep or a tuning
#: compiles within its first runs; the numbers are the same either way, even within a run
COMPILE_AFTER = 50_000
_pure_steps = 0

# the batch flow below calls the flow of one position, the planar wrapper the planar flow; each compiled copy
# (:func:`_kernels`) has its own
_flow = _flow_planar = None


def _flow_batch(parameters, position, theta, filtered, decay, blend, gain, tolerance2, cap, lo, hi, closed, active,
                iterations, capped):
    """The flow of each active member j of a batch (every per-member value an array (B,), ``parameters``
    (B, P), ``position`` (B, n); ``theta``, ``filtered`` updated in place, ``iterations`` and ``capped``
    written); inactive members are left as they are with 0 updates. ``_flow`` is the flow of one position,
    compiled for the curve, with (parameters, position, ...)'s arguments."""
    for j in range(theta.shape[0]):
        if not active[j]:
            iterations[j] = 0
            capped[j] = False
            continue
        t, f, n, done = _flow(parameters[j], position[j], theta[j], filtered[j], decay[j], blend[j], gain[j],
                              tolerance2[j], cap[j], lo[j], hi[j], closed)
        theta[j], filtered[j], iterations[j], capped[j] = t, f, n, not done


def _planar(parameters, position, theta, filtered, decay, blend, gain, tolerance2, cap, lo, hi, closed):
    """The planar flow (:func:`~contouring_ros.core.foot_point.foot_point_flow_planar`) with the general one's
    arguments (:func:`~contouring_ros.core.foot_point.foot_point_flow`; ``closed`` is False)."""
    return _flow_planar(parameters, position[0], position[1], theta, filtered, decay, blend, gain, tolerance2, cap,
                        lo, hi)


_KERNELS = {}          # (formula, planar) -> (flow of one position, flow of a batch) compiled for it, or None


def _numba():
    """numba, imported on first use; None where it cannot be (installed but broken, e.g. built for another
    numpy): the pure path runs, with a warning."""
    try:
        import numba
    except Exception as error:          # noqa: BLE001 - any failure of the import means: no kernels
        _unavailable(f"numba cannot be imported ({type(error).__name__}: {error})")
        return None
    return numba


def _unavailable(why: str) -> None:
    warnings.warn(f"contouring_ros: {why}; the Newton estimate runs its pure Python path (the same numbers, "
                  "slower)", RuntimeWarning, stacklevel=3)


def _kernels(formula, planar: bool):
    """The flows compiled for one curve formula, the unrolled planar one (an open planar curve, as the pure
    path takes it) or the general one: copies of the pure path's flow functions (core/foot_point.py) whose
    ``_formula`` is the formula compiled with the math module's sin, cos and exp in place of curves.py's
    scalar-or-array ones, and the batch flow above around them; no fastmath. The flow of one position raises
    ZeroDivisionError where the pure path's floats do (error_model "python"); the batch's gives inf or nan as
    the pure path's numpy does (error_model "numpy"). None where numba cannot be imported. numba compiles each
    at its first call."""
    key = formula, planar
    if key not in _KERNELS:
        if _numba() is None:
            _KERNELS[key] = None
            return None

        def flow(error_model):
            curve = compiled_formula(formula, error_model)
            if planar:
                return _compiled(_planar, error_model,
                                 _flow_planar=_compiled(foot_point_flow_planar, error_model, _formula=curve))
            return _compiled(foot_point_flow, error_model, _formula=curve)
        _KERNELS[key] = flow("python"), _compiled(_flow_batch, "numpy", _flow=flow("numpy"))
    return _KERNELS[key]


def _compiled(function, error_model: str, **names):
    """``function`` compiled by numba (lazily, at its first call) as a copy whose globals ``names`` replace."""
    import numba
    scope = dict(function.__globals__, **names)
    copy = types.FunctionType(function.__code__, scope, function.__name__, function.__defaults__)
    return numba.njit(error_model=error_model)(copy)


def compiled_formula(formula, error_model: str = "python"):
    """A curve formula (:attr:`~contouring_ros.core.curves.Curve.formula`) compiled with the math module's
    sin, cos and exp in place of curves.py's scalar-or-array ones, as the kernels call it; None without
    numba."""
    if not ENABLED or _numba() is None:
        return None
    return _compiled(formula, error_model, _sin=math.sin, _cos=math.cos, _exp=math.exp)


def _is_planar(curve) -> bool:
    return curve.dimension == 2 and not curve.closed


def formula_of(curve):
    """The curve's :attr:`~contouring_ros.core.curves.Curve.formula` where the curve's own class gives it,
    else None (a subclass, a plugin's say, may compute its columns otherwise: it runs the pure path)."""
    return curve.formula if "formula" in vars(type(curve)) else None


_FLOWS = weakref.WeakKeyDictionary()      # curve -> its flow of one position (newton_flow), or None


def newton_flow(curve):
    """The compiled flow of one position for ``curve``: a function (position (n,), theta, filtered, decay,
    blend, gain, tolerance2, cap) -> (theta, filtered, updates, converged) taking floats (``cap`` an int),
    or None where it does not run compiled (numba not installed, broken or turned off; a curve without a
    formula). Made once for the curve (its parameters read then: a run writes to no curve) and kept for its
    lifetime, so that asking at every step costs a look-up."""
    if not ENABLED or formula_of(curve) is None or not _worth_compiling(1):
        return None
    if curve not in _FLOWS:
        _FLOWS[curve] = _flow_for(curve)
    return _FLOWS[curve]


def _worth_compiling(steps: int) -> bool:
    """Whether this process has taken :data:`COMPILE_AFTER` steps of the pure flow (counting ``steps`` more
    until it has)."""
    global _pure_steps
    if _pure_steps >= COMPILE_AFTER:
        return True
    _pure_steps += steps
    return False


def _flow_for(curve):
    kernels = _kernels(curve.formula, _is_planar(curve))
    if kernels is None:
        return None
    compiled = kernels[0]
    parameters = tuple(float(v) for v in curve.parameters)
    (lo, hi), closed = (float(v) for v in curve.domain), bool(curve.closed)

    def flow(position, theta, filtered, decay, blend, gain, tolerance2, cap):
        return compiled(parameters, np.asarray(position, dtype=float), theta, filtered, decay, blend, gain,
                        tolerance2, cap, lo, hi, closed)
    try:                        # compile now: a failure leaves the curve to the pure path
        flow(curve.point(lo), lo, 0.0, 0.5, 0.5, 0.0, 1.0, 0)
    except Exception as error:          # noqa: BLE001 - whatever numba raises, the pure path still runs
        _unavailable(f"the Newton kernel for {type(curve).__name__} failed ({type(error).__name__}: {error})")
        return None
    return flow


def newton_flow_batch(curve, position, theta, filtered, decay, blend, gain, tolerance2, cap, active,
                      constants: dict | None = None):
    """The compiled flow of a batch on ``curve`` (possibly a batch's stacked curve): positions (B, n), every
    other per-member value a float or an array of shape (B, 1). Returns (theta, filtered, iterations,
    capped), each (B, 1), as ``NewtonEstimator._iterate_batch`` leaves them, or None where it does not run
    compiled (then nothing has changed). ``constants``: where the caller keeps the columns of the values that
    do not change from step to step (the curve's parameters and domain, decay, blend, gain, tolerance, cap),
    made at its first step."""
    if not ENABLED or formula_of(curve) is None or position.shape[1] != curve.dimension \
            or not _worth_compiling(position.shape[0]):
        return None
    key = curve.formula, _is_planar(curve)
    kernels = _kernels(*key)
    if kernels is None:
        return None
    b = position.shape[0]

    def column(value, dtype=float):
        return np.ascontiguousarray(np.broadcast_to(value, (b, 1))[:, 0], dtype=dtype)
    fixed = None if constants is None else constants.get(b)
    if fixed is None:
        fixed = (np.ascontiguousarray(np.stack([column(v) for v in curve.parameters], axis=1)),
                 *(column(v) for v in curve.domain), column(decay), column(blend), column(gain), column(tolerance2),
                 column(cap, np.int64))
        if constants is not None:
            constants[b] = fixed
    parameters, lo, hi, decay, blend, gain, tolerance2, cap = fixed
    theta, filtered = column(theta).copy(), column(filtered).copy()
    iterations, capped = np.zeros(b, dtype=np.int64), np.zeros(b, dtype=np.bool_)
    active = np.ones(b, dtype=np.bool_) if active is None else column(active, np.bool_)
    try:
        kernels[1](parameters, np.ascontiguousarray(position, dtype=float), theta, filtered, decay, blend, gain,
                   tolerance2, cap, lo, hi, bool(curve.closed), active, iterations, capped)
    except Exception as error:          # noqa: BLE001 - a failure to compile: the pure path runs from the same state
        _KERNELS[key] = None
        _unavailable(f"the Newton batch kernel for {type(curve).__name__} failed ({type(error).__name__}: {error})")
        return None
    return theta[:, None], filtered[:, None], iterations[:, None].astype(int), capped[:, None]
