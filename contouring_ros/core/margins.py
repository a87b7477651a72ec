"""Gain margin, phase margin and peak sensitivity Ms of the linear axis feedback loops.

Controllers are fairly compared at equal robustness, and the usual single measure of robustness is the
peak of the sensitivity function,

    Ms = max_w |S(e^{jwTs})| = max_w 1 / |1 + L(e^{jwTs})|,

the inverse of the shortest distance from the Nyquist curve of the loop transfer function L to the
critical point -1 (Åström & Hägglund, Advanced PID Control, ISA, 2006: the maximum sensitivity, with
reasonable values from about 1.2 to 2). Ms bounds the classical margins: GM >= Ms / (Ms - 1) and
PM >= 2 arcsin(1 / (2 Ms)).

Every loop here is the discrete-time loop the code runs at the sample time Ts, broken at the plant input
(the actuator command): L(z) = C(z) P(z), where P(z) is the zero-order-hold discretisation of the axis
from the command to what the servo reads (position, and velocity where the law feeds it back) and C(z)
is the servo law's difference equations (:mod:`contouring_ros.core.servo`, :class:`~.pid.DiscretePID`).
The timing is the one of :func:`contouring_ros.core.simulation.simulate`: the state measured at step k
gives the command at k, applied over [t_k, t_k+1), so P(z) is strictly proper; a plant's
``command_delay`` of d samples adds z^-d. The loops are the small-signal linear part: actuator and
output limits, Coulomb friction, encoder quantisation and measurement noise are left out, and so is the
reference feedforward, which does not act on the loop.

Linear time-invariant feedback laws: ``pid`` (:class:`~.servo.PIDServo`), ``pid_feedforward``
(:class:`~.servo.PIDFeedforwardServo`), ``zpetc`` (:class:`~.servo.ZPETCServo`: its PID; the feedforward filter
makes the loop's reference and does not act on the loop) and ``cascade`` (:class:`~.servo.CascadeServo`). Not linear
time-invariant feedback, so without a loop transfer function here (None): integral sliding mode
(:class:`~.servo.IntegralSlidingModeServo`, its switching term and disturbance observer),
ESO sliding mode (:class:`~.servo.ESOSlidingModeServo`) and ``direct``
(:class:`~.servo.DirectServo`: the whole command comes from a contour controller, task-frame PD or TVT,
whose frame moves with the reference).
"""
from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass

import control
import numpy as np
from scipy.optimize import brentq, minimize_scalar

from .contouring import NoCoupling, UnitVectorCCC, VariableGainCCC
from .plants import FirstOrderVelocityAxis, MassDamperAxis
from .polynomials import ZERO, cancel, polymul, rational_product, rational_sum, trim
from .servo import CascadeServo, PIDFeedforwardServo, PIDServo, ZPETCServo

__all__ = ["LoopMargins", "plant_transfer", "axis_loop", "coupled_loop", "margins", "quick_robustness"]

#: points of each of the two frequency grids (logarithmic and linear, up to Nyquist) the margins are sought on
GRID_POINTS = 20001
#: lowest frequency of the logarithmic grid, as a fraction of the Nyquist frequency
GRID_LOW = 1e-7


@dataclass(frozen=True)
class LoopMargins:
    """Robustness of one discrete-time loop L(z), broken at the plant input.

    Attributes
    ----------
    gain_margin : float
        Factor by which the loop gain may change before the closed loop becomes unstable: 1 / |L| at the
        phase crossover (arg L = -180 deg, the Nyquist frequency included) whose margin is closest to 1;
        a ratio, not dB; inf if the phase never crosses -180 deg.
    phase_margin_deg : float
        180 deg + arg L at the gain crossover (|L| = 1) of the smallest |margin|; inf if |L| never crosses 1.
    ms : float
        Peak sensitivity max over 0 < w <= pi / Ts of 1 / |1 + L(e^{jwTs})| (Åström & Hägglund, Advanced
        PID Control, 2006).
    crossover_hz : float
        Gain crossover frequency [Hz] of ``phase_margin_deg``; nan if none.
    stable : bool
        Whether every closed-loop pole, root of den(z) + num(z), lies inside the unit circle. The margins
        describe the distance to instability only for a stable closed loop.
    """

    gain_margin: float
    phase_margin_deg: float
    ms: float
    crossover_hz: float
    stable: bool


# --- the controllers ----------------------------------------------------------------------------------------

def _pid(kp: float, ki: float, kd: float, ts: float) -> tuple:
    """C(z) = kp + ki Ts z / (z - 1) + kd (z - 1) / (Ts z): :class:`~.pid.DiscretePID` on an error it
    differentiates itself (backward rectangle integral I_k = I_{k-1} + Ts e_k, used at k; derivative
    (e_k - e_{k-1}) / Ts). Terms with a zero gain leave their pole out."""
    c = (np.array([float(kp)]), np.ones(1))
    if ki:
        c = rational_sum(c, (np.array([ki * ts, 0.0]), np.array([1.0, -1.0])))
    if kd:
        c = rational_sum(c, (np.array([kd / ts, -kd / ts]), np.array([1.0, 0.0])))
    return c


def _check_sample_time(owner, ts: float, what: str):
    own = getattr(owner, "sample_time", None)
    if own is not None and not math.isclose(float(own), ts, rel_tol=1e-9):
        raise ValueError(f"the {what} was built for Ts = {own} s, not {ts} s")


# --- the plant ----------------------------------------------------------------------------------------------

def _plant_polynomials(plant, ts: float):
    """(Np, Nv, D): command -> position reading Np / D and command -> velocity reading Nv / D (a common
    denominator, z^d of the command delay included), or None for a plant without a linear model here.

    Both models are x+ = Phi x + Gamma u with x = (position, velocity), Phi = [[1, pv], [0, alpha]],
    Gamma = (pu, vu), exactly as :mod:`contouring_ros.core.plants` discretises them, so
    P_v = vu / (z - alpha) and P_p = (pu (z - alpha) + pv vu) / ((z - 1)(z - alpha)).
    """
    if isinstance(plant, FirstOrderVelocityAxis):
        k, tau = float(plant.gain), float(plant.time_constant)
        alpha = math.exp(-ts / tau)
        pv, vu = tau * (1.0 - alpha), k * (1.0 - alpha)
        pu = k * (ts - pv)
    elif isinstance(plant, MassDamperAxis):
        a, scale = float(plant.damping) / float(plant.mass), float(plant.gain) / float(plant.mass)
        if a * ts < 1e-9:           # the undamped limit plants.py uses
            alpha, pv, vw, pw = 1.0, ts, ts, 0.5 * ts * ts
        else:
            one_minus_e = -math.expm1(-a * ts)
            alpha, pv, vw = 1.0 - one_minus_e, one_minus_e / a, one_minus_e / a
            pw = (ts - one_minus_e / a) / a
        pu, vu = scale * pw, scale * vw
    else:
        return None
    _check_sample_time(plant, ts, "plant")
    num_p = np.array([pu, pv * vu - pu * alpha])
    num_v = np.array([vu, -vu])                       # vu (z - 1) over the common (z - 1)(z - alpha)
    den = polymul([1.0, -1.0], [1.0, -alpha])
    if getattr(plant, "velocity_measurement", "model") == "encoder":
        # the velocity read is the backward difference of the position readings: (z - 1) / (Ts z) P_p
        num_v = polymul([1.0, -1.0], num_p)
        num_p = polymul([ts, 0.0], num_p)
        den = polymul([ts, 0.0], den)
    delay = getattr(plant, "command_delay", 0)
    if int(delay) != delay or delay < 0:
        raise ValueError(f"command_delay must be a non-negative integer number of samples, got {delay!r}")
    den = polymul(den, np.r_[1.0, np.zeros(int(delay))])
    return num_p, num_v, den


def _transfer(num, den, ts: float) -> control.TransferFunction:
    num, den = trim(num), trim(den)
    return control.tf(num / den[0], den / den[0], ts)


def plant_transfer(plant, sample_time: float) -> tuple | None:
    """The axis as the servo sees it: (command -> position, command -> velocity reading).

    Parameters
    ----------
    plant : FirstOrderVelocityAxis or MassDamperAxis
        k / (s (tau s + 1)), or K / (M s^2 + B s), from command to position; discretised by zero-order
        hold from the plant's own parameters (the same exact discretisation as the plant's ``step``). A
        ``command_delay`` attribute of d samples multiplies both by z^-d; ``velocity_measurement``
        "encoder" makes the velocity reading the backward difference of the position readings.
    sample_time : float
        Ts [s]; must be the plant's.

    Returns
    -------
    tuple of control.TransferFunction, or None
        (P_p(z), P_v(z)) with time step Ts; None for a plant type without a linear model here.
    """
    ts = float(sample_time)
    polynomials = _plant_polynomials(plant, ts)
    if polynomials is None:
        return None
    num_p, num_v, den = polynomials
    return (_transfer(*cancel(num_p, den), ts), _transfer(*cancel(num_v, den), ts))


# --- the loops ----------------------------------------------------------------------------------------------

def _servo_filters(servo, ts: float, ccc: tuple = ZERO):
    """(F_p, F_v): the servo's command is -(F_p position + F_v velocity) + (terms in the reference), with a
    linear contour correction ccc(z) acting on the position error normal to the path. None if the law is
    not linear time-invariant feedback."""
    if isinstance(servo, (PIDServo, PIDFeedforwardServo, ZPETCServo)):
        # T = kp e + ki I(e) + kd (R' - V) [+ feedforward] + correction: the derivative is the velocity error
        # (the ZPETC's: kp e + ki I(e) - kd V on the error from its filtered reference, the same loop)
        pid = servo.pid
        _check_sample_time(pid, ts, "servo")
        return rational_sum(_pid(pid.kp, pid.ki, 0.0, ts), ccc), (np.array([pid.kd]), np.ones(1))
    if isinstance(servo, CascadeServo):
        # V* = R' + kp_position (R - P) + correction, T = PI(V* - V) [+ friction feedforward]
        loop = servo.velocity_loop
        _check_sample_time(loop, ts, "servo")
        velocity_pi = _pid(loop.kp, loop.ki, 0.0, ts)       # stepped with an error rate of 0: no derivative
        return rational_product(velocity_pi, rational_sum((np.array([servo.kp_position]), np.ones(1)), ccc)), velocity_pi
    return None


def _loop(plant, filters, ts: float) -> control.TransferFunction | None:
    polynomials = _plant_polynomials(plant, ts)
    if polynomials is None or filters is None:
        return None
    num_p, num_v, den = polynomials
    (fp_num, fp_den), (fv_num, fv_den) = filters
    num = np.polyadd(polymul(polymul(fp_num, num_p), fv_den), polymul(polymul(fv_num, num_v), fp_den))
    return _transfer(*cancel(num, polymul(polymul(fp_den, fv_den), den)), ts)


def axis_loop(plant, servo, sample_time: float) -> control.TransferFunction | None:
    """The loop transfer function L(z) = C(z) P(z) of one axis' feedback, broken at the plant input.

    C(z) follows the servo's difference equations exactly: ``pid``, ``pid_feedforward`` and ``zpetc`` are
    kp + ki Ts z / (z - 1) on the position and kd on the velocity reading (the derivative term is the
    velocity error R' - V, not a difference of the position error); ``cascade`` is
    (kp_v + ki_v Ts z / (z - 1)) (kp_position P_p + P_v). Feedforward terms do not act on the loop.

    Parameters
    ----------
    plant : FirstOrderVelocityAxis or MassDamperAxis
        See :func:`plant_transfer` (its ``command_delay`` and ``velocity_measurement`` are included).
    servo : PIDServo, PIDFeedforwardServo, ZPETCServo or CascadeServo
        Any other law gives None: integral sliding mode (switching term and disturbance observer), ESO
        sliding mode and ``direct`` are not linear time-invariant feedback on the axis alone.
    sample_time : float
        Ts [s]; must be the plant's and the servo's.

    Returns
    -------
    control.TransferFunction or None
        L(z) with time step Ts (command in, minus the command the feedback makes of it out), or None.
    """
    ts = float(sample_time)
    return _loop(plant, _servo_filters(servo, ts), ts)


def _contour_pid(controller, ts: float):
    """The linear contour controller's C_ccc(z), (0, 1) for no coupling, None if not linear."""
    if isinstance(controller, NoCoupling):
        return ZERO
    if isinstance(controller, (VariableGainCCC, UnitVectorCCC)):
        pid = controller.pid
        _check_sample_time(pid, ts, "contour controller")
        if isinstance(controller, VariableGainCCC) and controller.curve.dimension != 2 and (pid.ki or pid.kd):
            # in 3-D the variable-gain CCC filters |E| and multiplies by the direction E / |E|: not linear
            return None
        return _pid(pid.kp, pid.ki, pid.kd, ts)
    return None


def coupled_loop(plant, servo, controller, sample_time: float) -> control.TransferFunction | None:
    """The axis loop with a linear cross-coupled contour controller closed around it, broken at the plant
    input, for the error component normal to a straight line.

    Assumptions: every axis is identical to this one (its plant and servo); the contour is a straight
    line (e.g. at 45 degrees to a pair of axes); the contour error estimate is exact (the tangent-line
    estimate on a line, a converged Newton estimate), E = n n^T (R - P) for the unit normal n. The
    variable-gain CCC's coefficients C = E / epsilon are then the constant normal n (Koren & Lo's
    coefficients of a line), and the unit-vector CCC's per-axis PIDs act on the components of E, so both
    give the correction n C_ccc(z) n^T (R - P), with C_ccc(z) = kp + ki Ts z / (z - 1) + kd (z - 1) / (Ts z)
    (:class:`~.pid.DiscretePID` differencing the contour error itself). The loop of the axes then splits,
    for any direction of the line, into the tangential loop (:func:`axis_loop`) and the normal loop
    returned here: L = (C_servo + C_ccc) P for the PID laws, C_ccc adding to the position gain,
    L = C_v ((kp_position + C_ccc) P_p + P_v) for the cascade law, whose correction adds to the velocity
    command. For axes that are not identical this is the loop as if the others were like this one.

    Parameters
    ----------
    plant, servo :
        As for :func:`axis_loop`.
    controller : VariableGainCCC, UnitVectorCCC or NoCoupling
        NoCoupling gives the axis loop itself. Any other controller gives None (task-frame PD, TVT and
        the adaptive TNB controller are not linear time-invariant), and so does a variable-gain CCC with
        integral or derivative action on a 3-D contour (it filters |E|).
    sample_time : float
        Ts [s].

    Returns
    -------
    control.TransferFunction or None
    """
    ts = float(sample_time)
    ccc = _contour_pid(controller, ts)
    if ccc is None:
        return None
    return _loop(plant, _servo_filters(servo, ts, ccc), ts)


# --- the margins --------------------------------------------------------------------------------------------

def _response(num: np.ndarray, den: np.ndarray, theta):
    z = np.exp(1j * np.asarray(theta, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.polyval(num, z) / np.polyval(den, z)


def _grid_roots(function, theta: np.ndarray, values: np.ndarray) -> list:
    """The roots of ``function`` between neighbouring grid points where ``values`` changes sign."""
    finite = np.isfinite(values)
    change = np.flatnonzero(finite[:-1] & finite[1:] & (np.sign(values[:-1]) * np.sign(values[1:]) < 0))
    return [brentq(function, theta[i], theta[i + 1], xtol=1e-15, rtol=4 * np.finfo(float).eps) for i in change]


def _merged(found: list, candidates, residual, accept: float) -> list:
    """``found`` plus each candidate not already there whose ``residual`` is within ``accept``."""
    out = list(found)
    for theta in candidates:
        if 0.0 < theta <= math.pi and all(abs(theta - t) > 1e-7 * max(t, 1e-300) for t in out) \
                and abs(residual(theta)) <= accept:
            out.append(float(theta))
    return sorted(out)


class _LoopResponse:
    """L(e^{j theta}) of a loop num(z) / den(z), and the functions of theta = w Ts whose roots are its
    crossings (:meth:`log_gain`: |L| = 1; :meth:`phase_sine`: L real) and whose minimum is 1 / Ms
    (:meth:`distance`)."""

    def __init__(self, num: np.ndarray, den: np.ndarray):
        self.num, self.den = num, den

    def __call__(self, theta):
        return _response(self.num, self.den, theta)

    def log_gain(self, t) -> float:
        return float(np.log(np.abs(self(t))))

    def phase_sine(self, t) -> float:
        value = self(t)
        return float(value.imag / abs(value))

    def distance(self, t) -> float:
        """|1 + L| at ``t`` (inf where it is not finite)."""
        value = abs(1.0 + complex(self(t)))
        return value if math.isfinite(value) else math.inf


def _sample_time(loop: control.TransferFunction, sample_time: float) -> float:
    """Ts [s] as a float, checked positive and against the loop's own time step."""
    ts = float(sample_time)
    if not ts > 0.0:
        raise ValueError(f"sample_time must be positive, got {sample_time!r}")
    dt = loop.dt
    if dt is not None and not isinstance(dt, bool) and dt == 0:
        raise ValueError("a continuous-time loop: the margins here are of a discrete-time L(z)")
    if dt is not None and not isinstance(dt, bool) and not math.isclose(float(dt), ts, rel_tol=1e-9):
        raise ValueError(f"the loop has time step {dt}, not the sample time {ts}")
    return ts


def _grid() -> np.ndarray:
    """theta = w Ts [rad] of the margins' grid: logarithmic from :data:`GRID_LOW` Nyquist and linear, up to
    Nyquist, :data:`GRID_POINTS` each."""
    return np.unique(np.concatenate([np.geomspace(GRID_LOW * math.pi, math.pi, GRID_POINTS),
                                     np.linspace(0.0, math.pi, GRID_POINTS)[1:]]))


def _control_crossings(loop: control.TransferFunction, ts: float) -> tuple:
    """theta of python-control's phase crossovers, gain crossovers and stability-margin points (polynomial
    method, every crossing); none where it cannot give them (e.g. an improper L: the grid alone)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _, _, _, w_phase, w_gain, w_stab = control.stability_margins(loop, returnall=True, method="poly")
        return np.asarray(w_phase) * ts, np.asarray(w_gain) * ts, np.asarray(w_stab) * ts
    except (ValueError, np.linalg.LinAlgError):
        return np.zeros(0), np.zeros(0), np.zeros(0)


def _crossings(response: _LoopResponse, theta: np.ndarray, values: np.ndarray, theta_phase: np.ndarray,
               theta_gain: np.ndarray) -> tuple:
    """(gain crossovers, phase crossovers) in theta: the grid's sign changes of log|L| and Im L / |L| (L at
    ``theta`` is ``values``), refined, merged with python-control's, the phase crossovers those where L < 0
    and the Nyquist frequency where L(-1) < 0."""
    magnitude = np.abs(values)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain_crossings = _merged(_grid_roots(response.log_gain, theta, np.log(magnitude)), theta_gain,
                                 response.log_gain, 1e-9)
        sine = values.imag / magnitude
        near_nyquist = theta < math.pi * (1.0 - 1e-9)
        phase_crossings = _merged(_grid_roots(response.phase_sine, theta[near_nyquist], sine[near_nyquist]),
                                  theta_phase[theta_phase < math.pi * (1.0 - 1e-9)], response.phase_sine, 1e-9)
    phase_crossings = [t for t in phase_crossings if response(t).real < 0.0]
    at_nyquist = complex(response(math.pi))
    if np.isfinite(at_nyquist) and at_nyquist.real < 0.0:
        phase_crossings.append(math.pi)
    return gain_crossings, phase_crossings


def _gain_margin(response: _LoopResponse, phase_crossings: list) -> float:
    """1 / |L| at the phase crossover whose margin is closest to 1 (inf without one)."""
    if not phase_crossings:
        return math.inf
    with np.errstate(divide="ignore"):
        candidates = 1.0 / np.abs(response(np.array(phase_crossings)))
    finite = candidates[np.isfinite(candidates) & (candidates > 0.0)]
    return float(finite[np.argmin(np.abs(np.log(finite)))]) if finite.size else math.inf


def _phase_margin(response: _LoopResponse, gain_crossings: list, ts: float) -> tuple:
    """(phase margin [deg], its crossover [Hz]) at the gain crossover of the smallest |margin| (inf, nan
    without one)."""
    if not gain_crossings:
        return math.inf, math.nan
    angles = np.angle(response(np.array(gain_crossings)), deg=True)
    pms = np.remainder(angles, 360.0) - 180.0
    best = int(np.argmin(np.abs(pms)))
    return float(pms[best]), gain_crossings[best] / (2.0 * math.pi * ts)


def _peak_sensitivity(response: _LoopResponse, theta: np.ndarray, values: np.ndarray,
                      theta_stab: np.ndarray) -> float:
    """Ms: 1 / the smallest |1 + L| on the grid (L at ``theta`` is ``values``), refined around it, and at
    python-control's stability-margin points."""
    with np.errstate(divide="ignore", invalid="ignore"):
        distance = np.abs(1.0 + values)
    distance = np.where(np.isfinite(distance), distance, np.inf)
    i = int(np.argmin(distance))
    smallest = float(distance[i])
    lo, hi = theta[max(i - 1, 0)], theta[min(i + 1, len(theta) - 1)]
    if hi > lo:
        refined = minimize_scalar(response.distance, bounds=(lo, hi), method="bounded", options={"xatol": 1e-13})
        smallest = min(smallest, float(refined.fun))
    for t in np.remainder(theta_stab, 2.0 * math.pi):     # python-control's optimum (mirrored above Nyquist)
        smallest = min(smallest, response.distance(min(t, 2.0 * math.pi - t)))
    return 1.0 / smallest if smallest > 0.0 else math.inf


def margins(loop: control.TransferFunction, sample_time: float) -> LoopMargins:
    """Gain margin, phase margin, peak sensitivity Ms and crossover of a discrete-time loop.

    The crossings are the union of python-control's (:func:`control.stability_margins`, polynomial method,
    every crossing) and of the sign changes of log|L| and of Im L / |L| on a dense grid of
    0 < w <= pi / Ts (logarithmic and linear), each refined to machine precision; the Nyquist frequency,
    where L is real and which python-control leaves out, is a phase crossover when L(-1) < 0. Ms is the
    maximum of 1 / |1 + L| over the same grid, refined around its peak (Åström & Hägglund, Advanced PID
    Control, 2006).

    Parameters
    ----------
    loop : control.TransferFunction
        SISO L(z), e.g. from :func:`axis_loop` or :func:`coupled_loop`, broken at the plant input.
    sample_time : float
        Ts [s]; the loop's own time step, if it has one, must agree.

    Returns
    -------
    LoopMargins
    """
    ts = _sample_time(loop, sample_time)
    num, den = trim(loop.num[0][0]), trim(loop.den[0][0])
    characteristic = np.polyadd(den, num)
    stable = bool(np.all(np.abs(np.roots(characteristic)) < 1.0)) if len(trim(characteristic)) > 1 else True
    response, theta = _LoopResponse(num, den), _grid()
    values = response(theta)
    theta_phase, theta_gain, theta_stab = _control_crossings(loop, ts)
    gain_crossings, phase_crossings = _crossings(response, theta, values, theta_phase, theta_gain)
    phase_margin, crossover_hz = _phase_margin(response, gain_crossings, ts)
    return LoopMargins(gain_margin=_gain_margin(response, phase_crossings), phase_margin_deg=phase_margin,
                       ms=_peak_sensitivity(response, theta, values, theta_stab), crossover_hz=crossover_hz,
                       stable=stable)


@functools.lru_cache(maxsize=8)
def _frequencies(points: int) -> np.ndarray:
    """theta = w Ts [rad] of a quick check: ``points`` spaced logarithmically from 1e-5 Nyquist to Nyquist
    (read-only, made once)."""
    theta = np.pi * np.logspace(-5.0, 0.0, points)
    theta.flags.writeable = False
    return theta


@functools.lru_cache(maxsize=1024)
def _unit_circle(points: int) -> np.ndarray:
    """z = e^(j theta) on :func:`_frequencies` (read-only, made once)."""
    z = np.exp(1j * _frequencies(points))
    z.flags.writeable = False
    return z


def _loop_response(loop: control.TransferFunction, theta) -> np.ndarray:
    """L(e^(j theta)) of a discrete-time loop (inf or nan where a pole lies on the grid)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return _response(trim(loop.num[0][0]), trim(loop.den[0][0]), theta)


def quick_robustness(loop: control.TransferFunction, points: int = 4096) -> tuple:
    """(Ms, stable) of a discrete-time loop in about a millisecond, for a search that asks it at every point:
    Ms = max 1 / |1 + L| on ``points`` frequencies spaced logarithmically up to Nyquist (without the
    refinement of :func:`margins`, so at most a few per cent low at a sharp peak), stable when every root of
    the characteristic polynomial den + num lies inside the unit circle."""
    num, den = trim(loop.num[0][0]), trim(loop.den[0][0])
    return _quick_robustness(tuple(num.tolist()), tuple(den.tolist()), points)


@functools.lru_cache(maxsize=4096)
def _quick_robustness(num: tuple, den: tuple, points: int) -> tuple:
    """:func:`quick_robustness` of the loop num / den (coefficients as tuples: a search asks again for the
    loops its points share, such as an axis' own loop beside every contour gain it tries)."""
    num, den = np.asarray(num), np.asarray(den)
    z = _unit_circle(points)
    with np.errstate(divide="ignore", invalid="ignore"):
        sensitivity = 1.0 / np.abs(1.0 + np.polyval(num, z) / np.polyval(den, z))
    ms = float(np.nanmax(sensitivity)) if np.isfinite(sensitivity).any() else math.inf
    characteristic = np.polyadd(den, num)
    stable = bool(np.all(np.abs(np.roots(characteristic)) < 1.0)) if len(characteristic) > 1 else True
    return ms, stable


class GainScaledLoops:
    """The loops of every axis as a PID's gains are scaled together: axis a's loop is
    L_a(k) = L_a(0) + k (s_p U_a^p + s_i U_a^i + s_d U_a^d), with U_a^g the loop's change for a unit gain g and
    s the gains' shape: a linear contour controller's (it enters the position filter additively,
    :func:`coupled_loop`; L_a(0) the servo's loop) or a servo's own PID (L_a(0) = 0). :meth:`largest_scale`
    is the largest k at which every axis' Ms = max 1 / |1 + L_a(k)| stays within its target, in closed form
    per frequency, so that a search can ask it at every point (a PID at a chosen Ms: Åström & Hägglund,
    Advanced PID Control, 2006, ch. 7, the MIGO design).

    Parameters
    ----------
    axes : list of (L0, units, allowed) or (L0, units, allowed, loop_of)
        Per axis: the loop without the PID (zero for a servo's own), {gain name: (the loop with that gain
        alone, that gain)} (control.TransferFunction; a gain of the servo's own size keeps the loop
        polynomials' rounding small), the Ms the axis may reach (:data:`MS_LIMIT`, or the axis' own where
        its servo alone exceeds it), and ``loop_of(gains)``: the loop with those gains ({name: value}), built
        exactly, whose stability decides a range of k above the lowest (:meth:`largest_scale`; a servo's own
        PID, and a contour controller whose search may take such a range).
    limit : float
        The Ms a linear loop may reach (the tuning's MS_LIMIT); a search's Ms coordinate is a share of it.
    points : int
        Frequencies, spaced logarithmically up to Nyquist, as :func:`quick_robustness`'s.
    """

    def __init__(self, axes: list, limit: float, points: int = 4096):
        theta = _frequencies(points)
        self.limit = float(limit)
        self.axes = []
        for loop, units, allowed, *loop_of in axes:
            base = _loop_response(loop, theta)
            self.axes.append((1.0 + base, {g: (_loop_response(u, theta) - base) / size for g, (u, size) in units.items()},
                              float(allowed), loop_of[0] if loop_of else None))

    def _direction(self, units: dict, shape: dict) -> np.ndarray:
        return sum(float(shape.get(g, 0.0)) * u for g, u in units.items())

    def peak(self, shape: dict, scale: float = 1.0) -> float:
        """The largest Ms / allowed over the axes with the gains ``scale`` x ``shape``."""
        worst = 0.0
        for one, units, allowed, _ in self.axes:
            with np.errstate(divide="ignore", invalid="ignore"):
                ms = float(np.nanmax(1.0 / np.abs(one + scale * self._direction(units, shape))))
            worst = max(worst, ms / allowed)
        return worst

    def ranges(self, shape: dict, share: float) -> list:
        """The ranges [low, high] of k >= 0 (high inf for the last) where every axis' Ms is at most ``share`` x
        its allowed Ms, lowest first: per frequency, |1 + L(k)|^2 is a quadratic in k, above the bound outside
        the interval between its roots (:func:`_allowed_ranges`), and the axes' ranges intersected. [] where
        k = 0 already exceeds the bound on an axis."""
        joint = [(0.0, math.inf)]
        for one, units, allowed, _ in self.axes:
            b = self._direction(units, shape)
            floor = 1.0 / (share * allowed)
            qa, qb, qc = np.abs(b) ** 2, 2.0 * np.real(one * np.conj(b)), np.abs(one) ** 2 - floor ** 2
            if np.nanmin(qc) < 0.0:
                return []
            joint = _intersected(joint, _allowed_ranges(qa, qb, qc))
        return joint

    def largest_scale(self, shape: dict, share: float, cap: float = math.inf, highest: bool | None = None) -> float:
        """The largest k >= 0, at most ``cap``, of a range of scales where every axis' Ms is at most ``share`` x
        its allowed Ms (:meth:`ranges`) and every loop is stable (0 where k = 0 already exceeds the bound or no
        range qualifies, ``cap`` where no k in a qualifying range exceeds it). Between two ranges no
        closed-loop pole can cross the unit circle without |1 + L| = 0 on the way, so each range is stable or
        unstable as a whole.

        The lowest range (``highest`` False, the default where an axis has no ``loop_of``: a contour controller
        around stable servo loops, stable from k = 0 on) gives its top, the k where the bound is first reached
        on the way from 0. The highest (``highest`` True, the default where every axis has ``loop_of``: a
        servo's own PID, whose loop can be unstable at small gains, as an integral on an integrating axis is,
        and can keep the bound again at higher ones) gives the top of the highest range below ``cap`` whose
        loops are stable, one loop of each axis in it deciding (:func:`quick_robustness`; an axis without
        ``loop_of`` is known stable only in the range from 0). On a loop whose Ms is not monotone in the scale
        (a contour controller around a PID + feedforward servo can keep the bound again at scales 10-30x the
        lowest range's top) the two differ. The frequency grid decides where the ranges lie, so a narrow peak
        between two of its frequencies can be missed: :func:`quick_robustness` on the loop itself still decides
        stability."""
        if highest is None:
            highest = all(loop_of is not None for *_, loop_of in self.axes)
        joint = self.ranges(shape, share)
        if not joint:
            return 0.0
        if not highest:
            return min(cap, joint[0][1] * (1.0 - 1e-6))     # inside: the boundary's rounding either way
        for low, high in reversed(joint):
            if low >= cap:
                continue
            top = min(high * (1.0 - 1e-6), cap)
            inside = {g: _inside(low, top) * float(shape.get(g, 0.0)) for g in self.axes[0][1]}
            if all(_stable(loop_of(inside)) if loop_of is not None else low == 0.0 for *_, loop_of in self.axes):
                return top
        return 0.0


def _stable(loop) -> bool:
    """Whether the closed loop of ``loop`` is stable (False where it could not be built: None)."""
    return loop is not None and quick_robustness(loop)[1]


def _intersected(first: list, second: list) -> list:
    """The ranges [low, high] lying in both lists of disjoint ranges ``first`` and ``second`` (lowest first)."""
    out = []
    for a_low, a_high in first:
        for b_low, b_high in second:
            low, high = max(a_low, b_low), min(a_high, b_high)
            if low < high:
                out.append((low, high))
    return sorted(out)


def _allowed_ranges(qa: np.ndarray, qb: np.ndarray, qc: np.ndarray) -> list:
    """The ranges [low, high] of k >= 0 (high inf for the last) where qa k^2 + qb k + qc >= 0 at every
    frequency, lowest first (qc >= 0: k = 0 is in the first): the complement of the union of the intervals
    between each frequency's two roots."""
    disc = qb * qb - 4.0 * qa * qc
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.sqrt(np.where(disc >= 0.0, disc, np.nan))
        first, second = (-qb - root) / (2.0 * qa), (-qb + root) / (2.0 * qa)
    keep = np.isfinite(first) & np.isfinite(second) & (second > 0.0)
    bad = sorted(zip(np.maximum(first[keep], 0.0), second[keep]))
    ranges, low = [], 0.0
    for start, end in bad:
        if start > low:
            ranges.append((low, float(start)))
        low = max(low, float(end))
    ranges.append((low, math.inf))
    return ranges


def _inside(low: float, high: float) -> float:
    """A scale inside the range [low, high]: its geometric middle (its middle from 0, twice its start or 1
    where it is open)."""
    if math.isinf(high):
        return 2.0 * low if low > 0.0 else 1.0
    return math.sqrt(low * high) if low > 0.0 else 0.5 * high
