"""Where the benchmark's tuning searches: each tunable method's space in physical coordinates.

A control engineer does not tune a loop over raw gains spanning sixteen decades; he chooses bandwidths and
corner frequencies below the Nyquist frequency, damping ratios and weight ratios (Åström & Hägglund,
Advanced PID Control, 2006, ch. 4-7). Each built-in controller (and the ZPETC servo, a reference method
whose PID is ours to choose) states its space in its catalogue entry (``tuning``: a function
(section, :class:`TuningContext`) -> :class:`Space` or None); a plugin without one is searched in the log
box of its raw gains (:func:`log_box`).

A :class:`Space` is a list of :class:`Dimension` (a name, a unit and a range; log-scaled, or integer) and the
map from a point to the raw keys of the experiment file. The search (:mod:`contouring_ros.studies.search`) moves in
the unit box; :meth:`Space.decode` maps a unit point to physical values and raw gains.

Frequencies of a gain acting on position through an axis: the frequency at which that term alone gives the
loop a gain of one through the axis' plant, ``|P(j w)|`` (position per command unit, the plant entry's
``response``: :func:`first_order_response`, :func:`mass_damper_response`), the geometric mean over the axes
where one gain serves every axis.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

__all__ = ["Dimension", "Space", "TuningContext", "OFF_SHARE", "first_order_response", "mass_damper_response",
           "pid_contour_space", "pid_at_ms_space", "pid_servo_space", "pid_servo_at_ms_space", "task_frame_space",
           "tvt_space", "adaptive_tnb_space", "ilc_space", "mpcc_space", "log_box", "combine", "crossover", "gain_magnitude"]

OFF_SHARE = 0.02     # the lowest this share of a range that can be off means off (0)


@dataclass(frozen=True)
class Dimension:
    """One coordinate of a tuning space: ``value`` ranges over [low, high] in ``unit``, on a log scale
    (``scale`` 'log') or over the integers (``scale`` 'int'); with ``off``, the lowest :data:`OFF_SHARE` of
    the range means 0 (the term is off); ``choice``: an integer that picks one of several options (no end of
    it is a bound an optimum could lie beyond)."""

    name: str
    unit: str
    low: float
    high: float
    scale: str = "log"
    off: bool = False
    choice: bool = False

    def value(self, u: float) -> float:
        """The value at ``u`` in [0, 1] (clipped)."""
        u = min(max(float(u), 0.0), 1.0)
        if self.scale == "int":
            return float(round(self.low + u * (self.high - self.low)))
        if self.off and u <= OFF_SHARE:
            return 0.0
        lo, hi = math.log10(self.low), math.log10(self.high)
        return 10.0 ** (lo + u * (hi - lo))

    def position(self, value: float) -> float:
        """The unit coordinate of ``value`` (clipped into the range; 0 where it is off or not positive)."""
        if self.scale == "int":
            return min(max((float(value) - self.low) / (self.high - self.low), 0.0), 1.0)
        if not (value > 0 and math.isfinite(value)):
            return 0.0
        lo, hi = math.log10(self.low), math.log10(self.high)
        return min(max((math.log10(value) - lo) / (hi - lo), 0.0), 1.0)

    @property
    def step(self) -> float:
        """The smallest step worth taking in the unit box: an integer's spacing, else 0."""
        return 0.5 / (self.high - self.low) if self.scale == "int" and self.high > self.low else 0.0

    def text(self, value: float) -> str:
        if self.off and value == 0.0:
            return f"{self.name} off"
        if self.scale == "int":
            return f"{self.name} {int(value)}{' ' + self.unit if self.unit else ''}"
        return f"{self.name} {value:.3g}{' ' + self.unit if self.unit else ''}"


@dataclass(frozen=True)
class TuningContext:
    """What a space's ranges and maps may depend on: the sample time and each axis' plant and servo sections
    (validated: every key present), and the plant entries' frequency responses."""

    sample_time: float
    plants: dict                     # axis -> plant section
    servos: dict                     # axis -> servo section
    responses: dict = field(default_factory=dict)     # axis -> w -> |P(jw)| (position per command unit), or None
    scaled_loops: object = None      # margins.GainScaledLoops of the contour controller's PID, where linear
    servo_loops: dict = field(default_factory=dict)   # axis -> margins.GainScaledLoops of its servo's PID alone

    @property
    def nyquist(self) -> float:
        return 0.5 / self.sample_time

    def response(self, w: float, axes=None) -> float | None:
        """|P(j w)| of the axes (geometric mean), None where an axis' plant states none."""
        axes = list(axes if axes is not None else self.plants)
        values = []
        for axis in axes:
            response = self.responses.get(axis)
            if response is None:
                return None
            values.append(float(response(w)))
        if not values or not all(v > 0 and math.isfinite(v) for v in values):
            return None
        return math.exp(sum(math.log(v) for v in values) / len(values))


@dataclass(frozen=True)
class Space:
    """A tuning space: its :class:`Dimension` list, ``gains`` mapping {name: value} to the raw keys it sets
    ({key: value}: a ``/ccc`` key, or ``<axis>/servo.<key>``; a per-axis list's value is its largest entry,
    the others keep their proportions) and ``point`` mapping the file's raw sections back to {name: value}
    (where to start)."""

    dimensions: tuple
    gains: Callable
    point: Callable
    kind: str = "physical"           # physical | log box

    def decode(self, u) -> tuple:
        """({name: value}, raw gains) of the unit point ``u``."""
        values = {d.name: d.value(x) for d, x in zip(self.dimensions, u)}
        return values, self.gains(values)

    def start(self, sections: dict) -> list:
        """The unit point of the file's own gains (clipped into the box)."""
        values = self.point(sections)
        return [d.position(values.get(d.name, 0.0)) for d in self.dimensions]

    @property
    def steps(self) -> list:
        return [d.step for d in self.dimensions]

    def at_bound(self, u) -> list:
        """What of the point ``u`` sits at an end of its range (an optimum there is not an optimum)."""
        out = []
        for d, x in zip(self.dimensions, u):
            if d.choice:
                continue
            if d.off and d.value(x) == 0.0:
                out.append(f"{d.name} off")
            elif x >= 1.0 - 1e-3:
                out.append(f"{d.name} at the upper bound")
            elif x <= 1e-3 and not d.off:
                out.append(f"{d.name} at the lower bound")
        return out

    def text(self, values: dict) -> str:
        return ", ".join(d.text(values[d.name]) for d in self.dimensions if d.name in values)

    def describe(self) -> str:
        parts = []
        for d in self.dimensions:
            unit = f" {d.unit}" if d.unit else ""
            span = f"{int(d.low)}-{int(d.high)}" if d.scale == "int" else f"{d.low:.3g}-{d.high:.3g}"
            parts.append(f"{d.name} {span}{unit}{' (or off)' if d.off else ''}")
        return ", ".join(parts)


# ------------------------------------------------------------------------------- plant responses


def first_order_response(section: dict, w: float) -> float:
    """|x / u| at w [rad/s] of a first-order velocity axis K / (s (tau s + 1)) (paper 000 eq. 1)."""
    return section["gain"] / (w * math.hypot(1.0, w * section["time_constant"]))


def mass_damper_response(section: dict, w: float) -> float:
    """|x / u| at w [rad/s] of a mass-damper axis g / (s (m s + c)) (paper 001 eq. 1, paper 004 eq. 12)."""
    return section["gain"] / (w * math.hypot(section["damping"], w * section["mass"]))


def crossover(gain: float, loop: Callable, low: float = 1e-6, high: float = 1e7) -> float:
    """The angular frequency w where ``gain * loop(w)`` = 1 (``loop`` falling with w), by bisection on log w;
    the nearer end where there is none within [low, high]."""
    if gain <= 0:
        return 0.0
    lo, hi = math.log(low), math.log(high)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if gain * loop(math.exp(mid)) > 1.0:
            lo = mid
        else:
            hi = mid
    return math.exp(0.5 * (lo + hi))


# ---------------------------------------------------------------------------------------- spaces


def _hz(name: str, low: float, high: float, off: bool = False) -> Dimension:
    return Dimension(name, "Hz", low, high, "log", off)


def gain_magnitude(value) -> float:
    """The size of a gain: its absolute value, or a per-axis list's largest entry (0 for an empty list)."""
    values = [abs(float(v)) for v in (value if isinstance(value, list) else [value])]
    return max(values) if values else 0.0


def _pid_dimensions(context: TuningContext, prefix: str = "") -> tuple:
    top = context.nyquist / 4.0
    return (_hz(f"{prefix}f_p", 0.1, top, off=True), _hz(f"{prefix}f_i", 0.1, top, off=True),
            Dimension(f"{prefix}r_d", "", 1e-2, 3.0, "log", off=True))


def _pid_gains(values: dict, response: Callable, prefix: str = "") -> dict:
    """kp, ki, kd of a PID whose proportional term alone crosses over at f_p, whose integral term alone at
    f_i (each through ``response``, the axis' |P(j w)|) and whose derivative term is r_d times the
    proportional one at w_p."""
    f_p, f_i, r_d = values[f"{prefix}f_p"], values[f"{prefix}f_i"], values[f"{prefix}r_d"]
    w_p, w_i = 2 * math.pi * f_p, 2 * math.pi * f_i
    kp = 1.0 / response(w_p) if f_p > 0 else 0.0
    ki = w_i / response(w_i) if f_i > 0 else 0.0
    kd = r_d * kp / w_p if f_p > 0 and r_d > 0 else 0.0
    return {"kp": kp, "ki": ki, "kd": kd}


def _pid_point(kp: float, ki: float, kd: float, response: Callable, prefix: str = "") -> dict:
    w_p = crossover(kp, response)
    w_i = crossover(ki, lambda w: response(w) / w)
    return {f"{prefix}f_p": w_p / (2 * math.pi), f"{prefix}f_i": w_i / (2 * math.pi),
            f"{prefix}r_d": kd * w_p / kp if kp > 0 else 0.0}


def pid_at_ms_space(context: TuningContext) -> Space:
    """A linear PID contour controller searched at a chosen peak sensitivity (the MIGO design: Åström &
    Hägglund, Advanced PID Control, 2006, ch. 7): its PI corner frequency f_c = ki / (2 pi kp) (0.01 Hz to
    an eighth of the sample rate, or off), its derivative time t_d = kd / kp (10 us to 0.1 s, or off), and
    the Ms its coupled loops reach (1.2 to the bound) and which range of gain scales keeps every axis'
    coupled loop at that Ms (``gain_range``: 0 the lowest, from 0; 1 the highest whose loops are stable,
    below the gain whose proportional term alone crosses over at an eighth of the sample rate); the gain scale
    is that range's top (``context.scaled_loops``, a :class:`contouring_ros.core.margins.GainScaledLoops`).
    The Ms of a coupled loop need not rise with the scale: around a PID + feedforward servo it can keep the
    bound again at gains 10-30x the lowest range's top, and the low-error gains can lie there. Every point
    is a stable loop within the bound, and the bound is an edge of the box."""
    loops = context.scaled_loops
    top_gain = 1.0 / context.response(2 * math.pi * context.nyquist / 4.0)

    def gains(values):
        shape = {"kp": 1.0, "ki": 2 * math.pi * values["f_c"], "kd": values["t_d"]}
        scale = loops.largest_scale(shape, values["ms"] / loops.limit, top_gain, highest=values["gain_range"] >= 1)
        return {key: scale * value for key, value in shape.items()}

    def point(sections):
        ccc = sections["/ccc"]
        kp, ki, kd = (gain_magnitude(ccc.get(k, 0.0)) for k in ("kp", "ki", "kd"))
        if kp <= 0:
            return {"f_c": context.nyquist / 4.0, "t_d": 0.0, "ms": loops.limit, "gain_range": 0}
        shape = {"kp": kp, "ki": ki, "kd": kd}
        share = loops.peak(shape)
        lowest = loops.largest_scale(shape, share * (1.0 + 1e-6), highest=False)
        return {"f_c": ki / (2 * math.pi * kp), "t_d": kd / kp, "ms": loops.limit * share,
                "gain_range": 0 if lowest >= 1.0 - 1e-4 else 1}
    return Space((_hz("f_c", 0.01, context.nyquist / 4.0, off=True), Dimension("t_d", "s", 1e-5, 0.1, "log", off=True),
                  Dimension("ms", "", 1.2, loops.limit, "log"), Dimension("gain_range", "", 0, 1, "int", choice=True)),
                 gains, point)


def pid_contour_space(section: dict, context: TuningContext) -> Space | None:
    """A PID contour controller (Koren's CCC, Koren & Lo's variable gain, paper 000's unit vector): the
    proportional and integral terms' crossover frequencies f_p, f_i (0.1 Hz to an eighth of the sample
    rate, or off) through the axes' mean plant, and the derivative-to-proportional ratio r_d at f_p
    (0.01 to 3, or off). None where a plant states no response. Where the coupled loops are linear
    (``context.scaled_loops``), the search is at a chosen Ms instead (:func:`pid_at_ms_space`)."""
    if context.response(1.0) is None:
        return None
    if context.scaled_loops is not None:
        return pid_at_ms_space(context)

    def gains(values):
        return _pid_gains(values, context.response)

    def point(sections):
        ccc = sections["/ccc"]
        return _pid_point(gain_magnitude(ccc.get("kp", 0.0)), gain_magnitude(ccc.get("ki", 0.0)),
                          gain_magnitude(ccc.get("kd", 0.0)), context.response)
    return Space(_pid_dimensions(context), gains, point)


def pid_servo_at_ms_space(context: TuningContext, prefix: str = "servo ") -> Space:
    """The PID of a servo on every axis searched at a chosen peak sensitivity of each axis' loop, as
    :func:`pid_at_ms_space` searches a contour controller's: its PI corner frequency f_c = ki / (2 pi kp), its
    derivative time t_d = kd / kp and the Ms every axis' loop reaches (1.2 to the bound); each axis' gain scale
    is the largest that keeps its own loop stable at that Ms (``context.servo_loops``), at most the gain whose
    proportional term alone crosses over at an eighth of the sample rate through that axis' plant (none where
    no gain does: the point is refused)."""
    axes = list(context.servos)
    loops = context.servo_loops
    limit = loops[axes[0]].limit
    top = {a: 1.0 / context.response(2 * math.pi * context.nyquist / 4.0, [a]) for a in axes}

    def gains(values):
        shape = {"kp": 1.0, "ki": 2 * math.pi * values[f"{prefix}f_c"], "kd": values[f"{prefix}t_d"]}
        out = {}
        for axis in axes:
            scale = loops[axis].largest_scale(shape, values[f"{prefix}ms"] / limit, top[axis])
            out.update({f"{axis}/servo.{k}": scale * v for k, v in shape.items()})
        return out

    def point(sections):
        first = sections[f"/{axes[0]}/servo"]
        kp, ki, kd = (float(first.get(k, 0.0)) for k in ("kp", "ki", "kd"))
        if kp <= 0:
            return {f"{prefix}f_c": context.nyquist / 4.0, f"{prefix}t_d": 0.0, f"{prefix}ms": limit}
        return {f"{prefix}f_c": ki / (2 * math.pi * kp), f"{prefix}t_d": kd / kp,
                f"{prefix}ms": limit * loops[axes[0]].peak({"kp": kp, "ki": ki, "kd": kd})}
    return Space((_hz(f"{prefix}f_c", 0.01, context.nyquist / 4.0, off=True),
                  Dimension(f"{prefix}t_d", "s", 1e-5, 0.1, "log", off=True),
                  Dimension(f"{prefix}ms", "", 1.2, limit, "log")), gains, point)


def pid_servo_space(section: dict, context: TuningContext) -> Space | None:
    """The PID of a servo on every axis (the ZPETC's feedback, Tomizuka 1987): f_p, f_i, r_d as
    :func:`pid_contour_space`'s, each axis' gains through its own plant; where every axis' loop is linear
    (``context.servo_loops``), at a chosen Ms instead (:func:`pid_servo_at_ms_space`)."""
    if context.response(1.0) is None:
        return None
    if context.servo_loops and set(context.servo_loops) == set(context.servos):
        return pid_servo_at_ms_space(context)
    prefix = "servo "
    axes = list(context.servos)

    def gains(values):
        out = {}
        for axis in axes:
            own = _pid_gains(values, lambda w, a=axis: context.response(w, [a]), prefix)
            out.update({f"{axis}/servo.{k}": v for k, v in own.items()})
        return out

    def point(sections):
        first = sections[f"/{axes[0]}/servo"]
        return _pid_point(float(first.get("kp", 0.0)), float(first.get("ki", 0.0)), float(first.get("kd", 0.0)),
                          lambda w: context.response(w, [axes[0]]), prefix)
    return Space(_pid_dimensions(context, prefix), gains, point)


def task_frame_space(section: dict, context: TuningContext) -> Space:
    """Paper 003's task-frame PD (eq. 22-25): its tangential, normal and (3 axes) binormal bandwidths
    0.5 Hz to a fifth of the sample rate, and its damping ratio 0.3-3."""
    names = ["f_t", "f_n"] + (["f_b"] if section.get("f_b") is not None else [])
    dims = tuple(_hz(n, 0.5, context.nyquist * 0.4) for n in names) + (Dimension("zeta", "", 0.3, 3.0),)

    def gains(values):
        return {d.name: values[d.name] for d in dims}

    def point(sections):
        return {d.name: float(sections["/ccc"].get(d.name) or 1.0) for d in dims}
    return Space(dims, gains, point)


def tvt_space(section: dict, context: TuningContext) -> Space:
    """Paper 002's tangential velocity tracking CCC: its gain kc = 2 pi f_c [1/s], f_c 0.05 Hz to a quarter
    of the sample rate."""
    dims = (_hz("f_c", 0.05, context.nyquist / 2.0),)
    return Space(dims, lambda v: {"kc": 2 * math.pi * v["f_c"]},
                 lambda s: {"f_c": float(s["/ccc"]["kc"]) / (2 * math.pi)})


def _ratio(name: str, low: float, high: float, off: bool = False) -> Dimension:
    return Dimension(name, "x file", low, high, "log", off)


def _relative(section: dict, key: str, fallback: float = 1.0) -> float:
    value = gain_magnitude(section.get(key, 0.0))
    return value if value > 0 else fallback


def adaptive_tnb_space(section: dict, context: TuningContext) -> Space:
    """Paper 001's adaptive TNB controller (eq. 20-26, 38-39): the tracking gain alpha = 2 pi f_alpha (0.1 Hz
    to four times the sample rate), the coupling gains 0.01-100 x the file's and the mass and damping
    adaptation gains 1e-3-1e3 x the file's (or off: no adaptation); per-axis lists keep their proportions.
    alpha weighs the error against its rate in the filtered error r = e' + alpha e (eq. 20): a gain, not the
    frequency of a sampled signal, so the Nyquist frequency does not bound it; the sampled loop's stability
    and robustness do, and the search's checks measure them. On paper 001's case II the tuned alpha is about
    2 pi 2.2 kHz (alpha Ts 14), robust, and a bound at a quarter of the sample rate held every search at it."""
    dims = (_hz("f_alpha", 0.1, 8.0 * context.nyquist), _ratio("coupling", 1e-2, 1e2),
            _ratio("gamma_mass", 1e-3, 1e3, off=True), _ratio("gamma_damping", 1e-3, 1e3, off=True))
    base = {k: _relative(section, k) for k in ("coupling", "gamma_mass", "gamma_damping")}

    def gains(values):
        return {"alpha": 2 * math.pi * values["f_alpha"],
                **{k: values[k] * base[k] for k in base}}

    def point(sections):
        ccc = sections["/ccc"]
        return {"f_alpha": float(ccc["alpha"]) / (2 * math.pi),
                **{k: gain_magnitude(ccc.get(k, 0.0)) / base[k] for k in base}}
    return Space(dims, gains, point)


def ilc_space(section: dict, context: TuningContext) -> Space:
    """Iterative learning control (Arimoto et al. 1984; Bristow, Tharayil & Alleyne, IEEE CSM 26(3), 2006):
    the learning gains on the contour error (0.01-100 x the file's) and on each axis' tracking error
    (1e-3-10 x the file's contour gain, or off), the learning's lead 0-20 steps and the Q-filter's cutoff
    2 Hz to the Nyquist frequency."""
    base = _relative(section, "gamma_contour")
    dims = (_ratio("gamma_contour", 1e-2, 1e2, off=True), _ratio("gamma_tracking", 1e-3, 1e1, off=True),
            Dimension("lead", "steps", 0, 20, "int"), _hz("q_cutoff", 2.0, context.nyquist))

    def gains(values):
        return {"gamma_contour": values["gamma_contour"] * base, "gamma_tracking": values["gamma_tracking"] * base,
                "lead": int(values["lead"]), "q_cutoff": values["q_cutoff"]}

    def point(sections):
        ccc = sections["/ccc"]
        return {"gamma_contour": float(ccc["gamma_contour"]) / base, "gamma_tracking": float(ccc["gamma_tracking"]) / base,
                "lead": int(ccc["lead"]), "q_cutoff": float(ccc["q_cutoff"]) or context.nyquist}
    return Space(dims, gains, point)


def mpcc_space(section: dict, context: TuningContext) -> Space:
    """Model predictive contouring control (Lam, Manzie & Good, CDC 2010): the horizon 5-30 steps and the
    weights as ratios to the contour weight (the optimum depends on the ratios alone): the lag weight
    1e-5-10 x it (or off) and the command-rate weight 1e-3-1e3 x the file's ratio."""
    q = float(section["q_contour"]) or 1.0
    rate = float(section["r_rate"]) / q
    dims = (Dimension("horizon", "steps", 5, 30, "int"), Dimension("lag/contour", "", 1e-5, 10.0, off=True),
            _ratio("rate/contour", 1e-3, 1e3))

    def gains(values):
        return {"horizon": int(values["horizon"]), "q_contour": q, "q_lag": values["lag/contour"] * q,
                "r_rate": values["rate/contour"] * rate * q}

    def point(sections):
        ccc = sections["/ccc"]
        return {"horizon": int(ccc["horizon"]), "lag/contour": float(ccc["q_lag"]) / q,
                "rate/contour": float(ccc["r_rate"]) / q / rate}
    return Space(dims, gains, point)


def log_box(section: dict, keys: tuple, decades: float) -> Space:
    """A plugin's space where it states none: each raw gain of ``keys`` on a log scale ``decades`` either
    side of its anchor (its file value; a gain that is 0 there, one from its sibling: ki 30 kp, kd 1e-3 kp;
    else 1), the lowest end meaning off."""
    anchors = {}
    for key in keys:
        value = gain_magnitude(section[key])
        if value <= 0.0:
            sibling, ratio = {"ki": ("kp", 30.0), "kd": ("kp", 1e-3)}.get(key, (None, 1.0))
            base = gain_magnitude(section.get(sibling, 0.0)) if sibling else 0.0
            value = base * ratio if base > 0.0 else 1.0
        anchors[key] = value
    dims = tuple(Dimension(k, "", anchors[k] * 10.0 ** -decades, anchors[k] * 10.0 ** decades, "log", True)
                 for k in keys)
    return Space(dims, lambda v: {k: v[k] for k in keys},
                 lambda s: {k: gain_magnitude(s["/ccc"][k]) for k in keys}, "log box")


def combine(first: Space | None, second: Space | None) -> Space | None:
    """One space of two: the dimensions of both, the gains of both (names must differ)."""
    if first is None or second is None:
        return first or second

    def gains(values):
        return {**first.gains(values), **second.gains(values)}

    def point(sections):
        return {**first.point(sections), **second.point(sections)}
    kind = first.kind if first.kind == second.kind else "mixed"
    return Space(first.dimensions + second.dimensions, gains, point, kind)
