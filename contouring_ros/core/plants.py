"""Axis dynamics, discretised exactly under a zero-order-hold input.

Each plant holds its state (position, velocity), applies a command over one sample period
[t_k, t_k+1) and returns the state at k+1. Between the controller and the dynamics sit the imperfections of
a real feed drive (:class:`Axis`): encoder resolution, measurement noise, velocity from the differentiated
encoder, computation delay and the actuator limit; all off by default.
"""
from __future__ import annotations

import math

import numpy as np

from .disturbances import NoDisturbance

__all__ = ["Axis", "FirstOrderVelocityAxis", "MassDamperAxis", "NOISE_TABLE_LENGTH", "noise_table", "VELOCITY_MEASUREMENTS",
           "MAX_COMMAND_DELAY", "coulomb_friction", "quantize", "has_limit", "symmetric_clip"]


def quantize(value: float, resolution: float) -> float:
    """``value`` rounded to the nearest multiple of ``resolution`` (0: unchanged), as an encoder reads it."""
    if isinstance(resolution, np.ndarray):             # a batch's resolutions, some of them 0 maybe
        if not resolution.any():
            return value
        kept = resolution > 0.0
        safe = np.where(kept, resolution, 1.0)
        return np.where(kept, np.round(value / safe) * safe, value)
    if not resolution:
        return value
    if isinstance(value, float) and resolution.__class__ is float:     # one run's step (numpy's float64 is a
        return round(value / resolution) * resolution                  # float): the common case first
    if np.ndim(value):                                 # a batch (both round half to even)
        return np.round(value / resolution) * resolution
    return round(value / resolution) * resolution


#: samples of the measurement-noise table a plant draws at construction and reads cyclically (8.192 s at 1 kHz)
NOISE_TABLE_LENGTH = 8192
#: what the velocity reading is: the drive's own (exact) velocity, or the differentiated encoder
VELOCITY_MEASUREMENTS = ("model", "encoder")
#: the longest computation delay a plant holds commands for [samples]
MAX_COMMAND_DELAY = 10


_NOISE_TABLES: dict = {}      # (RMS, seed) -> its noise table, read-only: every run of a tuning draws the same
_NOISE_TABLES_KEPT = 64


def noise_table(rms: float, seed: int) -> np.ndarray:
    """The position noise a plant reads cyclically: ``rms`` times :data:`NOISE_TABLE_LENGTH` standard normal
    samples of the generator seeded with ``seed``, read-only and shared by every plant of the same two numbers
    (a tuning builds thousands of plants with the same noise)."""
    key = (float(rms), int(seed))
    table = _NOISE_TABLES.get(key)
    if table is None:
        table = key[0] * np.random.default_rng(key[1]).standard_normal(NOISE_TABLE_LENGTH)
        table.flags.writeable = False
        if len(_NOISE_TABLES) >= _NOISE_TABLES_KEPT:
            _NOISE_TABLES.pop(next(iter(_NOISE_TABLES)), None)
        _NOISE_TABLES[key] = table
    return table


class Axis:
    """What every axis model shares: the imperfections of a real feed drive between the controller and the
    dynamics (Altintas, Manufacturing Automation, 2nd ed., 2012, ch. 5-6).

    Measurement. ``measure()`` gives the (position, velocity) the drive reports at the current step:

    - the position read by a linear or rotary encoder of ``encoder_resolution`` [m] (0: exact): the reading
      is rounded to a multiple of it (Altintas: encoders of 0.1-1 um on machine-tool axes);
    - with ``measurement_noise`` [m] > 0, white Gaussian noise of that standard deviation added to the
      position before the rounding (electrical noise and interpolation error of the encoder signal). It is
      drawn at construction from ``numpy.random.default_rng(noise_seed)`` into a table of
      :data:`NOISE_TABLE_LENGTH` samples read cyclically, one per step: the same seed gives the same noise,
      run after run, in-process, batched and through the node graph alike. Give each axis its own seed for
      noise independent between axes;
    - the velocity: with ``velocity_measurement`` "model" the drive's own velocity, exact; with "encoder" the
      backward difference of successive position readings divided by the sample time, as a servo loop
      sampled at 1 kHz forms it from the encoder, noise and quantisation included (at step
      0, with no earlier reading, the initial velocity).

    ``measure()`` is pure: it may be called any number of times between steps and gives the same reading.

    Command. ``step(command, t)`` applies the command with ``command_delay`` samples of computation delay
    (the command computed at step k acts over [t_{k+d}, t_{k+d+1}); no command before: the delay of a
    controller that computes during one sample period and writes its output at the next sampling instant is
    d = 1), clipped to +-``saturation`` (the amplifier's or DAC's limit, 0: none) as it reaches the drive.
    """

    encoder_resolution = 0.0
    measurement_noise = 0.0
    noise_seed = 0
    command_delay = 0
    velocity_measurement = "model"
    saturation = 0.0
    position = 0.0
    velocity = 0.0
    _noise = None              # the noise table (B, L for a stacked batch), None without noise
    _held = ()                 # the commands on their way to the drive, oldest first
    _steps = 0                 # steps taken: the index of the current reading's noise sample
    _previous = None           # the position reading one step back ("encoder" velocity), None at step 0
    _reading = None            # (steps, reading): the current step's reading once measure() has taken it

    def _set_measurement(self, encoder_resolution=0.0, measurement_noise=0.0, noise_seed=0, command_delay=0,
                         velocity_measurement="model"):
        """Set the imperfections (called by each model's constructor after its state)."""
        if not encoder_resolution >= 0.0 or not measurement_noise >= 0.0:
            raise ValueError("encoder resolution and measurement noise must be non-negative")
        if int(noise_seed) != noise_seed or noise_seed < 0:
            raise ValueError(f"noise_seed must be a non-negative integer, got {noise_seed!r}")
        if int(command_delay) != command_delay or not 0 <= command_delay <= MAX_COMMAND_DELAY:
            raise ValueError(f"command_delay must be an integer from 0 to {MAX_COMMAND_DELAY}, got {command_delay!r}")
        if velocity_measurement not in VELOCITY_MEASUREMENTS:
            raise ValueError(f"velocity_measurement must be one of {', '.join(VELOCITY_MEASUREMENTS)}, "
                             f"got {velocity_measurement!r}")
        self.encoder_resolution = float(encoder_resolution)
        self.measurement_noise = float(measurement_noise)
        self.noise_seed = int(noise_seed)
        self.command_delay = int(command_delay)
        self.velocity_measurement = velocity_measurement
        # instance attributes, all of them, so that a batch (core/batch.py) stacks them or refuses to
        self._noise = None if self.measurement_noise == 0.0 else noise_table(self.measurement_noise, self.noise_seed)
        self._held = (0.0,) * self.command_delay
        self._steps = 0
        self._previous = None
        self._reading = None

    def _position_reading(self):
        """The encoder's reading of the current position: noise added, then quantised."""
        position, table = self.position, self._noise
        if table is not None:
            i = self._steps % NOISE_TABLE_LENGTH
            position = position + (table[:, i:i + 1] if table.ndim == 2 else float(table[i]))
        return quantize(position, self.encoder_resolution)

    def measure(self) -> tuple[float, float]:
        """The (position, velocity) the drive reports now (pure: the same until the next ``step``)."""
        position = self._position_reading()
        self._reading = (self._steps, position)          # the step's "encoder" velocity differences it
        if self.velocity_measurement == "model" or self._previous is None:
            return position, self.velocity
        return position, (position - self._previous) / self.sample_time

    def step(self, command: float, t: float) -> tuple[float, float]:
        """Take ``command`` (computed at t), apply the one due after the delay, clipped to the saturation,
        over [t, t + Ts), and return the (position, velocity) at t + Ts."""
        if self._held:
            if isinstance(command, np.ndarray):
                command = command.copy()          # a batch's column may be a view of the caller's array
            command, self._held = self._held[0], self._held[1:] + (command,)
        if has_limit(self.saturation):
            command = symmetric_clip(command, self.saturation)
        if self.velocity_measurement == "encoder":
            reading = self._reading
            self._previous = reading[1] if reading is not None and reading[0] == self._steps else \
                self._position_reading()
        self._advance(command, t)
        self._steps += 1
        return self.position, self.velocity

    def _advance(self, command, t: float):
        """The dynamics: apply ``command`` (delayed and clipped) over [t, t + Ts)."""
        raise NotImplementedError


def first_order_hold_terms(gain: float, time_constant: float, sample_time: float) -> tuple:
    """(alpha, pv, vu, pu) of the first-order velocity axis k / (s (tau s + 1)) under a zero-order hold:
    V+ = alpha V + vu U, P+ = P + pv V + pu U (:class:`FirstOrderVelocityAxis`; the ZPETC's model)."""
    alpha = math.exp(-sample_time / time_constant)
    pv = time_constant * (1.0 - alpha)
    return alpha, pv, gain * (1.0 - alpha), gain * (sample_time - pv)


def mass_damper_hold_terms(mass: float, damping: float, sample_time: float) -> tuple:
    """(vv, vw, pv, pw) of the mass-damper M s^2 + B s under a zero-order hold of the acceleration input w:
    V+ = vv V + vw w, P+ = P + pv V + pw w (:class:`MassDamperAxis`; the MPCC's model)."""
    ts, a = sample_time, damping / mass
    if a * ts < 1e-9:
        return 1.0, ts, ts, 0.5 * ts * ts
    one_minus_e = -math.expm1(-a * ts)
    return 1.0 - one_minus_e, one_minus_e / a, one_minus_e / a, (ts - one_minus_e / a) / a


class FirstOrderVelocityAxis(Axis):
    """First-order velocity axis of paper 000 eq. 1-2.

    dP/dt = V,  dV/dt = -V / tau + (k / tau) (T + D)

    with command T and disturbance D held constant over each sample period. The step is the exact
    zero-order-hold discretisation (no Euler error): with alpha = exp(-Ts / tau) and u = T + D,

    V+ = alpha V + k (1 - alpha) u
    P+ = P + tau (1 - alpha) V + k (Ts - tau (1 - alpha)) u

    Parameters
    ----------
    gain : float
        DC gain k [m/s per command unit].
    time_constant : float
        tau [s].
    sample_time : float
        Ts [s].
    disturbance : callable t -> float, optional
        D(t) in command units.
    position, velocity : float
        Initial state [m], [m/s].
    saturation : float
        Actuator limit: the command is clipped to +-saturation before the disturbance adds (0: none).
    encoder_resolution, measurement_noise, noise_seed, command_delay, velocity_measurement :
        The drive's imperfections (encoder [m], position noise [m] and its seed, computation delay
        [samples], the velocity reading): see :class:`Axis`.
    """

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True
    #: every number of its own elementwise too: a batch steps the axes of a member as rows of one object
    batch_axes = True

    def __init__(self, gain: float, time_constant: float, sample_time: float, disturbance=None,
                 position: float = 0.0, velocity: float = 0.0, saturation: float = 0.0,
                 encoder_resolution: float = 0.0, measurement_noise: float = 0.0, noise_seed: int = 0,
                 command_delay: int = 0, velocity_measurement: str = "model"):
        if gain <= 0.0 or time_constant <= 0.0 or sample_time <= 0.0:
            raise ValueError("gain, time constant and sample time must be positive")
        self.gain = float(gain)
        self.time_constant = float(time_constant)
        self.sample_time = float(sample_time)
        self.disturbance = disturbance or NoDisturbance()
        self._alpha, self._pv, self._vu, self._pu = first_order_hold_terms(self.gain, self.time_constant,
                                                                           self.sample_time)
        self.position = float(position)
        self.velocity = float(velocity)
        self.saturation = float(saturation)
        self._set_measurement(encoder_resolution, measurement_noise, noise_seed, command_delay, velocity_measurement)

    def _advance(self, command, t: float):
        u = command + self.disturbance(t)
        p, v = self.position, self.velocity
        self.position = p + self._pv * v + self._pu * u
        self.velocity = self._alpha * v + self._vu * u


def has_limit(limit) -> bool:
    """Whether a limit (0: none) limits anything; a batch of limits does when any of them is set."""
    return limit != 0.0 if limit.__class__ is float else bool(np.any(limit))


def symmetric_clip(value, limit):
    """``value`` clipped to +-``limit``; elementwise for arrays, where a limit of 0 means no limit."""
    if limit.__class__ is float and limit > 0.0:                     # one limit for a run or a whole batch
        return np.minimum(np.maximum(value, -limit), limit) if isinstance(value, np.ndarray) \
            else max(-limit, min(limit, value))
    if isinstance(value, np.ndarray) or isinstance(limit, np.ndarray):
        limit = np.where(np.asarray(limit) > 0.0, limit, np.inf)
        return np.minimum(np.maximum(value, -limit), limit)        # np.clip's numbers, at half its cost on a batch
    return max(-limit, min(limit, value))


def coulomb_friction(velocity: float, positive: float, negative: float) -> float:
    """Coulomb friction in command units: ``positive`` while moving forward, -``negative`` backward, 0 at rest
    (elementwise for arrays)."""
    if isinstance(velocity, np.ndarray):
        return np.where(velocity > 0.0, positive, np.where(velocity < 0.0, -np.asarray(negative), 0.0))
    if velocity > 0.0:
        return positive
    if velocity < 0.0:
        return -negative
    return 0.0


class MassDamperAxis(Axis):
    """Mass-damper feed drive with Coulomb friction and actuator saturation (papers 001 eq. 1, 003 eq. 18,
    004 eq. 12).

    M d2P/dt2 + B dP/dt = K (sat(T) + D - F_c(dP/dt))

    or, with ``disturbance_unit: acceleration``, M d2P/dt2 + B dP/dt = K (sat(T) - F_c) + M D: the
    disturbance D added to the acceleration, as in paper 004 eq. 13-14 (q'' = -(B/M) q' + (K_f/M) u + d).
    The transfer function from command to position is K / (M s^2 + B s) (paper 003's helix axes
    1/(s^2 + 200 s) are M = 1, B = 200, K = 1; its XY stage 16.23/(s^2 + 798.5 s) is M = 1, B = 798.5,
    K = 16.23). The command T is clipped to +-saturation, the disturbance D and the friction F_c (both in
    command units, like the paper's volts) add to it.

    Discretisation: exact zero-order hold of the linear part. With a = B / M, e = exp(-a Ts) and the
    held acceleration input w = K u / M,

    V+ = e V + (1 - e) / a w
    P+ = P + (1 - e) / a V + (Ts - (1 - e) / a) / a w          (a = 0: V+ = V + Ts w, P+ = P + Ts V + Ts^2 w / 2)

    The Coulomb friction is sampled with the velocity at the start of each step and held over it: exact
    while the axis does not reverse within a step, accurate to one sample at reversals (stick-slip is not
    modelled).

    Parameters
    ----------
    mass, damping, gain : float
        M [kg], B [N s/m], K [N per command unit].
    sample_time : float
        Ts [s].
    disturbance : callable t -> float, optional
        D(t) in command units (or m/s^2, see ``disturbance_unit``).
    position, velocity : float
        Initial state [m], [m/s].
    saturation : float
        Actuator limit: the command is clipped to +-saturation (0: none).
    coulomb_positive, coulomb_negative : float
        Coulomb friction moving forward, backward [command units].
    disturbance_unit : str
        "command" or "acceleration".
    encoder_resolution, measurement_noise, noise_seed, command_delay, velocity_measurement :
        The drive's imperfections (encoder [m], position noise [m] and its seed, computation delay
        [samples], the velocity reading): see :class:`Axis`.
    """

    #: steps elementwise on arrays with a leading batch axis (:mod:`contouring_ros.core.batch`)
    batchable = True
    #: every number of its own elementwise too: a batch steps the axes of a member as rows of one object
    batch_axes = True

    def __init__(self, mass: float, damping: float, gain: float, sample_time: float, disturbance=None,
                 position: float = 0.0, velocity: float = 0.0, saturation: float = 0.0,
                 coulomb_positive: float = 0.0, coulomb_negative: float = 0.0,
                 disturbance_unit: str = "command", encoder_resolution: float = 0.0,
                 measurement_noise: float = 0.0, noise_seed: int = 0, command_delay: int = 0,
                 velocity_measurement: str = "model"):
        if mass <= 0.0 or gain <= 0.0 or sample_time <= 0.0 or damping < 0.0:
            raise ValueError("mass, gain and sample time must be positive and damping non-negative")
        self.mass, self.damping, self.gain = float(mass), float(damping), float(gain)
        self.sample_time = ts = float(sample_time)
        self.disturbance = disturbance or NoDisturbance()
        self.saturation = float(saturation)
        self.coulomb_positive, self.coulomb_negative = float(coulomb_positive), float(coulomb_negative)
        self._vv, self._vw, self._pv, self._pw = mass_damper_hold_terms(self.mass, self.damping, ts)
        self._input_scale = self.gain / self.mass
        if disturbance_unit not in ("command", "acceleration"):
            raise ValueError(f"disturbance_unit must be command or acceleration, got {disturbance_unit!r}")
        self._disturbance_scale = 1.0 if disturbance_unit == "command" else self.mass / self.gain
        self.position = float(position)
        self.velocity = float(velocity)
        self._set_measurement(encoder_resolution, measurement_noise, noise_seed, command_delay, velocity_measurement)

    def _advance(self, command, t: float):
        p, v = self.position, self.velocity
        w = self._input_scale * (command + self._disturbance_scale * self.disturbance(t)
                                 - coulomb_friction(v, self.coulomb_positive, self.coulomb_negative))
        self.position = p + self._pv * v + self._pw * w
        self.velocity = self._vv * v + self._vw * w
