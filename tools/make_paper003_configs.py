"""Write the paper 003 scenario files (config/paper003_*.yaml) from two templates.

Paper 003 (Meng, Lou & Zhou, natural local approximation based contouring control): section IV-A, the
helix on three mismatched axes under the task-frame PD controller, first-order (tangent line) vs natural
local approximation, for two bandwidth sets; sections IV-B/C, the ellipse and the figure-8 on the XY stage
(Tables I-II). Mechanism scenarios (paper003_mech_*): the same experiments where the effect the paper relies
on is present, a tangential tracking error t under curvature kappa (first order leaves kappa t^2 / 2 as contour
error, natural local only its cubic remainder); each header says what physics makes t and why each number.
The claims they back are in config/claims/paper003.yaml. Run after changing the templates:
python tools/make_paper003_configs.py
"""
import sys
from pathlib import Path

from scenario_template import write_reference_methods, shared_section, with_adds

HEADER = """\
# Paper 003 (Meng, Lou & Zhou, natural local approximation based contouring control), section IV-A.
# {title}
# Paper's result for this case: mean contour error {tace} um (4 periods).
#
# Readings this file had to choose:
# - Axes: G = 1 / (s^2 + B s) is a mass-damper with M = 1, B = (200, 225, 180), K = 1 (model: mass_damper),
#   exact zero-order-hold discretisation at Ts = 1 ms; the controller uses the identified
#   B = {identified} (paper: diag(205, 230, 180)) in both the feedback linearization and the feedforward
#   u_d = K^-1 (M w_d'' + B w_d'), as eq. 20 and 25 write it.
# - The controller (eq. 25) computes every axis' whole command: servo law 'direct'. Damping ratios 1.
# - The mean contour error is the time average of the exact contour error over the 4 s (4 periods) of the
#   run (TACE). The helix is extended by half a period beyond the run (length 4.5) so an axis running ahead
#   of its reference is measured against the contour, not against the contour's end point.
# - Initial state: each axis starts on the reference, moving with it.{extra}
"""

MECHANISM_HELIX = """
# - MECHANISM SCENARIO (config/claims/paper003.yaml), not the paper's reading: the identified z damping is 185
#   instead of 180, so the controller over-estimates every axis' damping by the paper's own +5 and the unmodelled
#   force 5 w' is purely tangential. It pushes the axes ahead of the reference: the tangential PD at f_t = 5 Hz
#   holds them at t = 5 |w'| / (2 pi f_t)^2, about 1 mm at the helix's 0.1-0.21 m/s, and it is this t that the
#   paper's mechanism needs (first order leaves kappa t^2 / 2 as contour error, natural local only its cubic
#   remainder). Under the paper's own values the x/y mismatch instead leaves a binormal force -5 gamma_z z'
#   (about 0.44) that the binormal PD holds at about 0.44 / (2 pi f_b)^2, some 100 um: a real contour error
#   no approximation can remove, which hides the approximation's effect."""

BODY = """\
{shared}
/x/plant:
  ros__parameters: {{model: mass_damper, mass: 1.0, damping: 200.0, gain: 1.0}}

/y/plant:
  ros__parameters: {{model: mass_damper, mass: 1.0, damping: 225.0, gain: 1.0}}

/z/plant:
  ros__parameters: {{model: mass_damper, mass: 1.0, damping: 180.0, gain: 1.0}}

/x/servo:
  ros__parameters: {{law: direct}}

/y/servo:
  ros__parameters: {{law: direct}}

/z/servo:
  ros__parameters: {{law: direct}}

/contour_estimator:
  ros__parameters: {{type: {estimator}}}

/ccc:
  ros__parameters:
    type: task_frame_pd
    approximation: {approximation}
    mass: [1.0, 1.0, 1.0]
    damping: {identified}
    gain: [1.0, 1.0, 1.0]
    f_t: 5.0
    f_n: {f_n}
    f_b: {f_b}
    zeta: 1.0
"""

APPROXIMATIONS = {"first_order": ("tangent_line", "first-order (tangent line)"),
                  "natural_local": ("natural_local", "natural local")}
PAPER = {("first_order", 15): 11.46, ("natural_local", 15): 7.10,
         ("first_order", 20): 11.23, ("natural_local", 20): 4.45}


XY_HEADER = """\
# Paper 003 (Meng, Lou & Zhou, natural local approximation based contouring control), section IV-C, {table}.
# {title}
# Paper's result (a machine experiment, Table {table_number}): max {mce} um, RMS {rms} um.
#
# Readings this file had to choose:
# - Axes: the identified XY stage, 16.23 / (s^2 + 798.5 s) and 17.58 / (s^2 + 862.75 s) from volts to metres
#   (model: mass_damper, M = 1), Coulomb friction x+ 0.12, x- 0.11, y+ 0.07, y- 0.06 V, drives saturating at
#   +-10 V; exact zero-order hold at 1 ms. The controller uses the same model (M, B, K and the friction,
#   eq. 25), so what remains is the sampling, the saturation and the approximation.
# - {curve_note}
# - f_t = 15 Hz, damping ratios 1; planar frame with the relative curvature of eq. 27.
# - Each axis starts on the contour moving with it; two periods.
"""

XY_BODY = """\
{shared}
/x/plant:
  ros__parameters: {{model: mass_damper, mass: 1.0, damping: {plant_x}, gain: 16.23, coulomb_positive: 0.12,
                    coulomb_negative: 0.11, saturation: 10.0}}

/y/plant:
  ros__parameters: {{model: mass_damper, mass: 1.0, damping: {plant_y}, gain: 17.58, coulomb_positive: 0.07,
                    coulomb_negative: 0.06, saturation: 10.0}}

/x/servo:
  ros__parameters: {{law: direct, output_limit: 10.0}}

/y/servo:
  ros__parameters: {{law: direct, output_limit: 10.0}}

/contour_estimator:
  ros__parameters: {{type: {estimator}}}

/ccc:
  ros__parameters:
    type: task_frame_pd
    approximation: {approximation}
    mass: [1.0, 1.0]
    damping: [798.5, 862.75]
    gain: [16.23, 17.58]
    coulomb_positive: [0.12, 0.07]
    coulomb_negative: [0.11, 0.06]
    f_t: 15.0
    f_n: {f_n}
    zeta: 1.0
"""

XY_CURVES = {
    "ellipse": dict(table="Table I", table_number="I",
                    curve="{type: ellipse, a: 0.03, b: 0.01, center: [0.03, 0.0]}",
                    schedule="{type: uniform, theta_start: 3.141592653589793, theta_end: -9.42477796076938, "
                             "duration: 2.2222222222222223}",
                    curve_note="Ellipse x = 0.03 (1 - cos wt), y = 0.01 sin wt, w = 1.8 pi: the ellipse of centre "
                               "(0.03, 0) at theta = pi - w t (theta runs down from pi).",
                    results={("natural_local", 60): (27.77, 9.91), ("natural_local", 80): (15.07, 5.60),
                             ("natural_local", 100): (12.21, 3.64), ("first_order", 60): (40.07, 15.15),
                             ("first_order", 80): (37.28, 13.45), ("first_order", 100): (34.17, 13.20)}),
    "figure_eight": dict(table="Table II", table_number="II",
                         curve="{type: figure_eight, a: 0.03, b: 0.03, contour_error_window: 0.5}",
                         schedule="{type: uniform, theta_start: 0.0, theta_end: 12.566370614359172, duration: 4.0}",
                         curve_note="Figure-8 x = 0.03 (1 - cos wt), y = 0.03 sin 2wt, w = pi: theta = w t. It crosses itself, so the "
                                    "exact contour error is measured within 0.5 rad of the reference parameter.",
                         results={("natural_local", 60): (128.29, 42.33), ("natural_local", 80): (75.23, 24.75),
                                  ("natural_local", 100): (54.22, 16.69), ("first_order", 60): (139.61, 39.48),
                                  ("first_order", 80): (107.97, 32.55), ("first_order", 100): (102.16, 31.88)}),
}


def write_xy_stage(out: Path):
    for curve, spec in XY_CURVES.items():
        for approximation, (estimator, label) in APPROXIMATIONS.items():
            for f_n in (60, 80, 100):
                name = f"paper003_{curve}_{approximation}_fn{f_n}"
                mce, rms = spec["results"][approximation, f_n]
                title = f"XY stage {curve.replace('_', '-')}, task-frame PD, {label} approximation, f_n = {f_n} Hz"
                fields = dict(spec, name=name, title=title, mce=mce, rms=rms, estimator=estimator,
                              approximation=approximation, f_n=f"{f_n:.1f}", plant_x=798.5, plant_y=862.75)
                fields["shared"] = shared_section(
                    name, title, {"source": f"003 section IV-C, Table {spec['table_number']}", "mce_um": mce,
                                  "rms_um": rms}, ["x", "y"], spec["curve"], spec["schedule"])
                (out / f"{name}.yaml").write_text(with_adds(name, XY_HEADER.format(**fields) + "\n"
                                                               + XY_BODY.format(**fields)))
                print(out / f"{name}.yaml")


# The XY stage's viscous damping in the mechanism scenarios, as a fraction of the identified (paper: 798.5, 862.75)
MECHANISM_DAMPING = 0.94

XY_MECHANISM = """
# MECHANISM SCENARIO (config/claims/paper003.yaml), not the paper's reading. What the paper's mechanism needs:
# a tangential tracking error t where the contour bends (first order leaves kappa t^2 / 2 as contour error,
# natural local only its cubic remainder). Under the faithful reading (the controller's model equals the plant)
# eq. 25 cancels the plant and t is some 0.02 mm: nothing for the approximation to act on. The paper's machine
# had t: Table {table_number} reports a tracking error e of {paper_e} mm RMS, the same for every f_n and both methods.
# - Physics: the running stage's viscous damping is {percent}% below the identified model on both axes
#   (B = {plant_x}, {plant_y} instead of 798.5, 862.75: a ball screw's viscous friction falls as its lubricant warms
#   after identification). The controller keeps the paper's identified model, so its feedforward and feedback
#   linearization push with an unmodelled force dB w' (dB = B_model - B_stage, {percent}% of B) along the
#   velocity, i.e. along the tangent, and the tangential PD at f_t = 15 Hz holds the axes ahead of the
#   reference at t = dB |w'| / (M (2 pi f_t)^2).
# - Why {percent}%: it is the size of mismatch that gives the tracking error the paper's own machine showed on the
#   ellipse (Table I, e RMS 0.65-0.66 mm; ours 0.69 mm RMS). The sign is the paper's own (its helix controller
#   also over-estimates the damping, 205 vs 200). The same machine runs the figure-8 with the same {percent}%:
#   ours then tracks to 0.85 mm RMS against the paper's 2.13 mm, so the mechanism is, if anything, weaker here
#   than on the paper's machine. The other sign (stage damping 6% above the model) gives a t of the same size and
#   RMS ratios natural local / first order of 0.08 (ellipse) and 0.07 (figure-8), against 0.10 and 0.15 here.
# - The paper's control input (Table I, U_x 6.03 V RMS) matches the exact model (ours 6.01 V); with the
#   mismatch ours is 5.66 V. So part of the paper's t must come from an effect that leaves the RMS voltage
#   alone (e.g. an unmodelled drive lag); the damping mismatch is the simplest force that produces the same t.
# - Everything else is the faithful file paper003_{curve}_{approximation}_fn100 (f_n = 100 Hz, the tables'
#   headline row).
"""


def write_xy_mechanism(out: Path):
    plant_x, plant_y = round(798.5 * MECHANISM_DAMPING, 6), round(862.75 * MECHANISM_DAMPING, 6)
    paper_e = {"ellipse": "0.65-0.66", "figure_eight": "2.13-2.18"}
    for curve, spec in XY_CURVES.items():
        for approximation, (estimator, label) in APPROXIMATIONS.items():
            f_n = 100
            name = f"paper003_mech_{curve}_{approximation}"
            mce, rms = spec["results"][approximation, f_n]
            title = (f"XY stage {curve.replace('_', '-')}, task-frame PD, {label} approximation, f_n = {f_n} Hz "
                     f"(mechanism: stage damping {round(100 * (1 - MECHANISM_DAMPING))}% below the identified)")
            fields = dict(spec, name=name, title=title, mce=mce, rms=rms, estimator=estimator, curve=curve,
                          approximation=approximation, f_n=f"{f_n:.1f}", plant_x=plant_x, plant_y=plant_y,
                          paper_e=paper_e[curve], percent=round(100 * (1 - MECHANISM_DAMPING)))
            fields["shared"] = shared_section(
                name, title, {"source": f"003 section IV-C, Table {spec['table_number']} (mechanism scenario)",
                              "mce_um": mce, "rms_um": rms}, ["x", "y"], spec["curve"], spec["schedule"])
            header = XY_HEADER.format(**fields).replace(
                "The controller uses the same model (M, B, K and the friction,\n#   eq. 25), so what remains is the "
                "sampling, the saturation and the approximation.",
                "The controller uses this identified model (M, B, K and the\n#   friction, eq. 25); the plant's "
                "damping differs (below).")
            (out / f"{name}.yaml").write_text(with_adds(name, header + XY_MECHANISM.format(**fields) + "\n"
                                                         + XY_BODY.format(**fields)))
            print(out / f"{name}.yaml")


def main(out=None):
    out = Path(out) if out else Path(__file__).resolve().parent.parent / "config"
    write_xy_stage(out)
    write_xy_mechanism(out)
    for mechanism in (False, True):
        identified = "[205.0, 230.0, 185.0]" if mechanism else "[205.0, 230.0, 180.0]"
        for approximation, (estimator, label) in APPROXIMATIONS.items():
            for f_n, f_b in ((15, 10), (20, 15)):
                name = (f"paper003_mech_helix_{approximation}_f{f_n}_{f_b}" if mechanism
                        else f"paper003_helix_{approximation}_f{f_n}_{f_b}")
                title = (f"Helix, task-frame PD, {label} approximation, f_t = 5, f_n = {f_n}, f_b = {f_b} Hz"
                         + (" (mechanism: every axis' damping over-estimated by 5, identified B_z = 185)"
                            if mechanism else ""))
                fields = dict(name=name, title=title, tace=PAPER[approximation, f_n], identified=identified,
                              estimator=estimator, approximation=approximation, f_n=f"{f_n:.1f}", f_b=f"{f_b:.1f}",
                              extra=MECHANISM_HELIX if mechanism else "")
                fields["shared"] = shared_section(
                    name, title, {"source": "003 section IV-A", "tace_um": PAPER[approximation, f_n]}, ["x", "y", "z"],
                    "{type: helix, a: 0.03, b: 0.01, c: 0.1, omega: 6.283185307179586, length: 4.5}",
                    "{type: uniform, theta_start: 0.0, theta_end: 4.0, duration: 4.0}")
                (out / f"{name}.yaml").write_text(with_adds(name, HEADER.format(**fields) + "\n" + BODY.format(**fields)))
                print(out / f"{name}.yaml")


# ------------------------------------------------------------------------------------------------------------
# Reference methods: the literature's methods on the paper's scenarios, for the benchmark
# (tools/scenario_template.py, REFERENCE_WHAT).

MPCC = {"/ccc": "type: mpcc  # on the task-frame PD's own axis model\nmass: [1.0, 1.0]\ndamping: [798.5, 862.75]\n"
                "gain: [16.23, 17.58]\nhorizon: 10\nq_contour: 1.0e+6\nq_lag: 1.0e+4\nr_rate: 1.0e-6\n"
                "command_limit: [10.0]  # the drives' saturation\ndisturbance_gain: 0.2  # offset-free under Coulomb friction"}
MPCC_HELIX = {"/ccc": "type: mpcc  # on the task-frame PD's own axis model\nmass: [1.0, 1.0, 1.0]\n"
                      "damping: [205.0, 230.0, 180.0]\ngain: [1.0, 1.0, 1.0]\nhorizon: 10\nq_contour: 1.0e+6\n"
                      "q_lag: 1.0e+4\nr_rate: 1.0e-6\ndisturbance_gain: 0.2"}
REFERENCE_METHODS = [
    ("paper003_ellipse_natural_local_fn100", "paper003_ellipse_mpcc", "mpcc", "ellipse, MPCC (horizon 10)", MPCC, ""),
    ("paper003_figure_eight_natural_local_fn100", "paper003_figure_eight_mpcc", "mpcc",
     "figure eight, MPCC (horizon 10)", MPCC, ""),
    ("paper003_helix_natural_local_f15_10", "paper003_helix_mpcc", "mpcc", "helix, MPCC (horizon 10)", MPCC_HELIX, ""),
]

if __name__ == "__main__":
    main(*sys.argv[1:2])       # the output directory, default config/
    write_reference_methods(sys.argv[1] if sys.argv[1:] else Path(__file__).resolve().parent.parent / "config",
                            "003", REFERENCE_METHODS)
