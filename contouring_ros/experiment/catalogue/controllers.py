"""Contour controllers (core/contouring.py): the ``/ccc`` section. ``gains``: the keys the benchmark tunes
(contouring_ros/studies/gains.py); ``whole_command``: the controller computes every axis' whole command (its servos
must then be 'direct'); ``needs_state``: it uses the reference and the axis states (the CCC node takes them)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core import contouring, estimators, ilc, mpc
from ...core.plants import MAX_COMMAND_DELAY
from ...errors import ConfigError
from ..registry import Entry, Role
from ...core.tuning_space import (adaptive_tnb_space, ilc_space, mpcc_space, pid_contour_space, task_frame_space,
                             tvt_space)
from ..schema import AXIS_GAIN_RANGE, BANDWIDTH_RANGE, DAMPING_RANGE, FORCE_RANGE, GAIN_RANGE, MASS_RANGE, POSITIVE_RANGE, REQUIRED, \
    MAX_STEPS, Param, pid_gains

__all__ = ["CONTROLLERS", "APPROXIMATIONS", "WHOLE_COMMAND_CONTROLLERS"]

CONTROLLERS = Role("controller", description="cross-coupled controller")

# task-frame controllers: the local approximation they act on -> the estimator that reports its errors
APPROXIMATIONS = {"first_order": "tangent_line", "natural_local": "natural_local"}

_LIMIT = "correction limit, 0: none [command units]"
_PID = ("kp", "ki", "kd")


def _per_axis_values(help: str, bounds: tuple, default=REQUIRED) -> Param:
    return Param("floats", default, help=help, bounds=bounds)


def _bandwidth(help: str, default=REQUIRED) -> Param:
    return Param("float", default, "positive", help=help, bounds=BANDWIDTH_RANGE)


def _task_frame_pd(s, c):
    approximation = {"first_order": estimators.first_order_terms,
                     "natural_local": estimators.natural_local_terms}[s["approximation"]]
    return contouring.TaskFramePD(c.curve, approximation, s["mass"], s["damping"], s["gain"],
                                  [s["f_t"], s["f_n"]] + ([s["f_b"]] if s["f_b"] is not None else []), s["zeta"],
                                  s["coulomb_positive"], s["coulomb_negative"])


def _mpcc(s, c):
    return mpc.ModelPredictiveContouring(s["mass"], s["damping"], s["gain"], c.sample_time, s["horizon"],
                                         s["q_contour"], s["q_lag"], s["r_rate"], s["command_limit"] or (),
                                         s["command_delay"], s["disturbance_gain"], s["velocity_estimate"])


#: the largest learned-correction file read [bytes] (a million steps of 3 axes is 24 MB)
MAX_LEARNED_BYTES = 256 << 20


def load_learned(path, where: str, n_axes: int, base=None, steps: int | None = None) -> np.ndarray:
    """The correction table of an ILC pass: the .npy file ``path`` (relative to ``base``, the experiment's
    folder, where relative), a finite real array of steps x ``n_axes``; anything else one ConfigError line
    naming /ccc.learned_file. The file is mapped, not read: only the rows a run of ``steps`` steps plays
    back (all, at most MAX_STEPS, without ``steps``) are converted to float, so a small dtype just under the
    size limit (int8: 256 M values) never becomes a float64 copy eight times its size."""
    path = Path(path)
    if not path.is_absolute() and base is not None:
        path = Path(base) / path

    def refuse(what):
        raise ConfigError(f"{where}: /ccc.learned_file: {str(path)!r} {what}")
    if not path.is_file():
        refuse("is not a file")
    if path.stat().st_size > MAX_LEARNED_BYTES:
        refuse(f"is larger than {MAX_LEARNED_BYTES >> 20} MiB")
    try:
        table = np.load(path, mmap_mode="r", allow_pickle=False)
    except Exception:       # noqa: BLE001 - a text, pickle, .npz, empty or truncated file alike
        refuse("is not a .npy array file (numpy.save of a steps x axes array)")
    if not isinstance(table, np.ndarray) or table.dtype.kind not in "fiu" or table.ndim != 2 \
            or table.shape[1] != n_axes:
        shape = getattr(table, "shape", None)
        refuse(f"holds a {shape} {getattr(table, 'dtype', type(table).__name__)} array, expected finite real "
               f"values, steps x {n_axes} axes")
    if steps is None and table.shape[0] > MAX_STEPS:
        refuse(f"holds {table.shape[0]} steps, more than the {MAX_STEPS} a run may have")
    table = np.array(table[:steps if steps is not None else MAX_STEPS], dtype=float)    # rows past the run: unused
    if not np.all(np.isfinite(table)):
        refuse(f"holds a {table.shape} array, expected finite values, steps x {n_axes} axes")
    return table


def _check_ilc(section, axes):
    if 0.0 < section["q_cutoff"] < 0.01:
        return "q_cutoff", f"{section['q_cutoff']!r} Hz is below 0.01 Hz, where the Q-filter is numerically " \
                           "singular; 0 turns it off"
    return None


def _ilc(s, c):
    """The learned correction of ``learned_file`` (an .npy array, steps x axes), or none (the first pass)."""
    base = Path(c.experiment.path).parent if c.experiment is not None and c.experiment.path else None
    steps = getattr(c.experiment, "n_steps", None) if c.experiment is not None else None
    table = load_learned(s["learned_file"], c.where, c.n_axes, base, steps) if s["learned_file"] else None
    return ilc.LearnedCorrection(c.n_axes, table)


def _check_mpcc(section, axes):
    if not section["q_contour"] and not section["q_lag"]:
        return "q_contour", "with q_contour and q_lag both 0 the MPCC has no error to lower: the axes would stand still"
    for key in ("mass", "damping", "gain"):
        if len(section[key]) != len(axes):
            return key, f"expected one value per axis ({len(axes)}), got {len(section[key])}"
    limits = section["command_limit"]
    if limits is not None and len(limits) not in (1, len(axes)):
        return "command_limit", f"expected 1 value or one per axis ({len(axes)}), got {len(limits)}"
    return None


def _per_axis(name: str, keys: tuple):
    """A check: the Frenet-frame controller ``name`` needs 2 or 3 axes and one value per axis of ``keys``."""
    def check(section, axes):
        if len(axes) not in (2, 3):
            return "type", f"the {name} controller needs 2 or 3 axes (a Frenet frame)"
        for key in keys:
            if section[key] is not None and len(section[key]) != len(axes):
                return key, f"expected one value per axis ({len(axes)}), got {len(section[key])}"
        return None
    return check


_TASK_FRAME_PER_AXIS = _per_axis("task_frame_pd", ("mass", "damping", "gain", "coulomb_positive", "coulomb_negative"))


def _check_task_frame_pd(section, axes):
    if len(axes) == 3 and section["f_b"] is None:
        return "f_b", "missing required key (the binormal bandwidth, for 3 axes)"
    return _TASK_FRAME_PER_AXIS(section, axes)


def _task_frame_estimator(estimator, controller, servos):
    """task_frame_pd acts on the errors of the estimator of its approximation."""
    expected = APPROXIMATIONS[controller["approximation"]]
    if estimator["type"] != expected:
        return ("/contour_estimator.type", f"the task_frame_pd controller with approximation "
                f"{controller['approximation']!r} acts on the errors of the {expected!r} estimator, got "
                f"{estimator['type']!r}")
    return None


for _entry in (
    Entry("none", {}, lambda s, c: contouring.NoCoupling(c.n_axes), gains=(), reads_estimate=False),
    Entry("variable_gain", pid_gains(_LIMIT),
          lambda s, c: contouring.VariableGainCCC(c.curve, s["kp"], s["ki"], s["kd"], c.sample_time, s["output_limit"]),
          gains=_PID, tuning=pid_contour_space),
    Entry("unit_vector", pid_gains(_LIMIT),
          lambda s, c: contouring.UnitVectorCCC(c.n_axes, s["kp"], s["ki"], s["kd"], c.sample_time, s["output_limit"]),
          gains=_PID, tuning=pid_contour_space),
    Entry("task_frame_pd", {
        "approximation": Param("str", choices=tuple(APPROXIMATIONS), help="local contour approximation"),
        "mass": _per_axis_values("axis masses [kg]", MASS_RANGE),
        "damping": _per_axis_values("axis damping [N s/m]", DAMPING_RANGE),
        "gain": _per_axis_values("actuator gains [N per command unit]", AXIS_GAIN_RANGE),
        "coulomb_positive": _per_axis_values("Coulomb friction forward [N]", FORCE_RANGE, None),
        "coulomb_negative": _per_axis_values("Coulomb friction back [N]", FORCE_RANGE, None),
        "f_t": _bandwidth("tangential bandwidth [Hz]"), "f_n": _bandwidth("normal bandwidth [Hz]"),
        "f_b": _bandwidth("binormal bandwidth [Hz]", None),
        "zeta": Param("float", 1.0, "positive", help="damping ratio", bounds=(1e-6, 1e3))},
        _task_frame_pd, check=_check_task_frame_pd, combination=_task_frame_estimator, whole_command=True,
        needs_state=contouring.TaskFramePD.needs_state, gains=("f_t", "f_n", "f_b", "zeta"),
        tuning=task_frame_space),
    Entry("tvt", {
        "kc": Param("float", check="nonnegative", help="tangential velocity gain [1/s]", bounds=GAIN_RANGE),
        "min_feedrate": Param("float", 1e-3, "nonnegative", help="feedrate floor [m/s]", bounds=(0.0, 100.0))},
        lambda s, c: contouring.TangentialVelocityCCC(c.curve, c.schedule, s["kc"], s["min_feedrate"]),
        whole_command=True, needs_state=contouring.TangentialVelocityCCC.needs_state, gains=("kc",),
        tuning=tvt_space),
    Entry("adaptive_tnb", {
        "coupling": _per_axis_values("coupling gains", (-1e12, 1e12)),
        "alpha": Param("float", check="positive", help="tracking gain alpha [1/s]", bounds=POSITIVE_RANGE),
        "gamma_mass": _per_axis_values("mass adaptation gains", GAIN_RANGE),
        "gamma_damping": _per_axis_values("damping adaptation gains", GAIN_RANGE),
        "mass0": _per_axis_values("initial mass estimates [kg]", MASS_RANGE),
        "damping0": _per_axis_values("initial damping estimates [N s/m]", DAMPING_RANGE)},
        lambda s, c: contouring.AdaptiveTNBCCC(c.curve, s["coupling"], s["alpha"], s["gamma_mass"],
                                               s["gamma_damping"], s["mass0"], s["damping0"], c.sample_time),
        check=_per_axis("adaptive_tnb", ("coupling", "gamma_mass", "gamma_damping", "mass0", "damping0")),
        needs_state=contouring.AdaptiveTNBCCC.needs_state, gains=("coupling", "alpha", "gamma_mass", "gamma_damping"),
        reads_estimate=False, tuning=adaptive_tnb_space),
    Entry("ilc", {
        "gamma_tracking": Param("float", 0.0, "nonnegative", help="learning gain on each axis' tracking error "
                                "[command units/m]", bounds=GAIN_RANGE),
        "gamma_contour": Param("float", check="nonnegative", help="learning gain on the contour error vector "
                               "[command units/m]", bounds=GAIN_RANGE),
        "lead": Param("int", 1, "nonnegative", help="phase lead of the learning [steps]", bounds=(0, 1000)),
        "q_cutoff": Param("float", 100.0, "nonnegative", help="Q-filter (zero-phase Butterworth, order 2) cutoff, "
                          "0: none [Hz]", bounds=(0.0, 1e6)),
        "passes": Param("int", 1, "positive", help="passes of the path: run and simulate learn between them",
                        bounds=(1, 1000)),
        "learned_file": Param("str", "", help="the correction this pass plays back (.npy, steps x axes; the "
                              "passes write it), empty: none")},
        _ilc, check=_check_ilc, gains=("gamma_tracking", "gamma_contour", "lead", "q_cutoff"), tuning=ilc_space),
    Entry("mpcc", {
        "mass": _per_axis_values("axis model masses [kg] (a first-order velocity axis: its time constant)",
                                 MASS_RANGE),
        "damping": _per_axis_values("axis model damping [N s/m] (a first-order velocity axis: 1)", DAMPING_RANGE),
        "gain": _per_axis_values("axis model gains [N per command unit] (a first-order velocity axis: its gain)",
                                 AXIS_GAIN_RANGE),
        "horizon": Param("int", 20, "positive", help="steps predicted", bounds=(1, 200)),
        "q_contour": Param("float", 1e6, "nonnegative", help="weight of the squared contour error [1/m^2]",
                           bounds=GAIN_RANGE),
        "q_lag": Param("float", 1e4, "nonnegative", help="weight of the squared lag error [1/m^2]", bounds=GAIN_RANGE),
        "r_rate": Param("float", 1.0, "positive", help="weight of the squared change of a command between steps",
                        bounds=POSITIVE_RANGE),
        "command_limit": Param("floats", None, help="|command| bound, one or one per axis, 0: none [command units]",
                               bounds=(0.0, 1e12)),
        "command_delay": Param("int", 0, "nonnegative", help="the drive's computation delay the model assumes "
                               "[samples]", bounds=(0, MAX_COMMAND_DELAY)),
        "disturbance_gain": Param("float", 0.0, "nonnegative", help="share of each step's velocity prediction error a "
                                  "constant input disturbance estimate takes up, 0: none", bounds=(0.0, 1.0)),
        "velocity_estimate": Param("str", "measured", choices=mpc.VELOCITY_ESTIMATES, help="measured: the drive's "
                                   "velocity reading; model: reconstructed from the last two position readings and "
                                   "the applied command through the axis model (for a velocity differentiated from "
                                   "the encoder)")},
        _mpcc, check=_check_mpcc, whole_command=True, needs_state=mpc.ModelPredictiveContouring.needs_state,
        gains=("horizon", "q_contour", "q_lag", "r_rate"),
        preview=lambda s, experiment, axis: s["command_delay"] + s["horizon"], reads_estimate=False, tuning=mpcc_space),
):
    CONTROLLERS.add(_entry)

# built-in controllers that compute every axis' whole command (their servos must be 'direct', and only theirs;
# a plugin says so with whole_command on its entry)
WHOLE_COMMAND_CONTROLLERS = {name for name, entry in CONTROLLERS.registered().items() if entry.whole_command}
