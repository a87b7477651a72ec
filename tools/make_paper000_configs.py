"""Write the paper 000 scenario files (config/paper000_*.yaml) from one template.

The scenarios differ only in the parabola depth h, the traversal time T, the servo law and the contour
estimator/controller pair, so they are generated from one template to keep them consistent. Run it
after changing the template: python tools/make_paper000_configs.py
"""
import sys
from pathlib import Path

from scenario_template import write_reference_methods, shared_section, with_adds

HEADER = """\
# Paper 000 (Ghaffari & Ulsoy, Newton-based CEE and robust CCC), section {section}.
# {title}
# Paper's result for this case: MCE {mce} um, TACE {tace} um.
#
# Readings this file had to choose where the paper is silent (the same in every paper000_* file):
# - Units. The paper works in millimetres (a_r = 20 mm, h_r in 1/m, gains per mm). Lengths here are SI
#   metres and the actuator command unit is 1000 times the paper's (a command's number is 1/1000 of the
#   paper's: the load bound 0.15 is 1.5e-4 here), so every gain keeps the paper's number:
#   k = 10.3 (m/s per unit), PID gains per metre = the paper's per millimetre. Only the quantities that are
#   not gains change: the disturbance bound 0.15 -> 1.5e-4 units, and the ISMC boundary layer mu = 1 -> 1e-3
#   m/s (kappa mu, in command units, is the paper's value / 1000).
# - Disturbance: a constant load D_i = +0.15 (paper units) on each axis, the "load" of eq. 2 at the bound
#   |D_i| = 0.15 the paper states.
# - Initial state: each axis starts on the reference, moving with it (initial_state: on_reference).
# - The cross-coupled correction adds to each axis' actuator command (Koren's structure, Fig. 5).
# - Newton CEE: within each 1 ms step the Newton flow (8) with its c' filter advances in inner iterations
#   of 1 ms of estimator time, from the previous step's estimate (Remark 3), until it has converged: the
#   tangential residual |E^T U| (14) and the step of the foot point both within {tolerance} m, at most
#   {max_iterations} iterations a step (a step that reaches the cap is counted on /diagnostics). The paper
#   states no count or stopping rule; here a step takes about 40 iterations.
# - Disturbance observer (eq. 24-26, ISMC cases only): the factor c missing from eq. 25 is restored so that
#   xi equals D for the model of eq. 2.
"""

BODY = """\
{shared}
/x/plant:
  ros__parameters:
    model: first_order_velocity
    gain: 10.3
    time_constant: 0.040
    disturbance: {disturbance_x}

/y/plant:
  ros__parameters:
    model: first_order_velocity
    gain: 10.0
    time_constant: 0.045
    disturbance: {disturbance_y}

/x/servo:
  ros__parameters:
{servo_x}
/y/servo:
  ros__parameters:
{servo_y}
/contour_estimator:
  ros__parameters:
{estimator}
/ccc:
  ros__parameters:
{ccc}"""

PIDFF = {"x": "    law: pid_feedforward  # PID_1 = 8.08 + 93.2/s + 0.24 s with reference feedforward\n"
              "    kp: 8.08\n    ki: 93.2\n    kd: 0.24\n    gain: 10.3\n    time_constant: 0.040\n",
         "y": "    law: pid_feedforward  # PID_2 = 9.36 + 108/s + 0.3 s with reference feedforward\n"
              "    kp: 9.36\n    ki: 108.0\n    kd: 0.3\n    gain: 10.0\n    time_constant: 0.045\n"}
ISMC = {"x": "    law: ismc\n    a: 12.5\n    b: 12.5\n    mu: 1.0e-3\n    kappa: 0.2985\n"
             "    gain: 10.3\n    time_constant: 0.040\n    observer: true\n    c: 25.0\n    d: 25.0\n",
        "y": "    law: ismc\n    a: 11.1\n    b: 11.1\n    mu: 1.0e-3\n    kappa: 0.3\n"
             "    gain: 10.0\n    time_constant: 0.045\n    observer: true\n    c: 22.2\n    d: 22.2\n"}
TOLERANCE, MAX_ITERATIONS = "1.0e-9", 200       # Newton CEE stopping rule: metres, inner iterations a step
NEWTON = ("    type: newton  # c' = 500, k' = 500, theta_0 = -a_r\n    k_prime: 500.0\n    c_prime: 500.0\n"
          f"    tolerance: {TOLERANCE}\n    max_iterations: {MAX_ITERATIONS}\n",
          "    type: unit_vector  # G_i^c = 1 + 10/s + 0.1 s on each axis (eq. 15)\n"
          "    kp: 1.0\n    ki: 10.0\n    kd: 0.1\n")
VARIABLE_GAIN = ("    type: tangent_line  # static CEE of the variable-gain CCC\n",
                 "    type: variable_gain  # G_c = 8 + 80/s + 0.6 s (Koren & Lo)\n"
                 "    kp: 8.0\n    ki: 80.0\n    kd: 0.6\n")

CASES = [
    # file stem, section, title, h, T, servo, pair, MCE, TACE
    ("paper000_a_pidff_h50_vgccc", "IV-A", "PID + feedforward, variable-gain CCC, h = 50, T = 2 s", 50.0, 2.0,
     PIDFF, VARIABLE_GAIN, 58.7, 39.5),
    ("paper000_a_pidff_h50_newton", "IV-A", "PID + feedforward, Newton CEE + unit-vector CCC, h = 50, T = 2 s",
     50.0, 2.0, PIDFF, NEWTON, 23.2, 7.0),
    ("paper000_b_ismc_h50_vgccc", "IV-B", "ISMC + disturbance estimate, variable-gain CCC, h = 50, T = 2 s",
     50.0, 2.0, ISMC, VARIABLE_GAIN, 15.3, 1.6),
    ("paper000_b_ismc_h50_newton", "IV-B", "ISMC + disturbance estimate, Newton CEE + unit-vector CCC, "
     "h = 50, T = 2 s", 50.0, 2.0, ISMC, NEWTON, 0.55, 0.11),
    ("paper000_b_ismc_h100_vgccc", "IV-B", "ISMC + disturbance estimate, variable-gain CCC, h = 100, T = 2 s",
     100.0, 2.0, ISMC, VARIABLE_GAIN, 23.0, 4.6),
    ("paper000_b_ismc_h100_newton", "IV-B", "ISMC + disturbance estimate, Newton CEE + unit-vector CCC, "
     "h = 100, T = 2 s", 100.0, 2.0, ISMC, NEWTON, 2.0, 0.31),
    ("paper000_c_ismc_t1_vgccc", "IV-C", "ISMC + disturbance estimate, variable-gain CCC, h = 50, T = 1 s",
     50.0, 1.0, ISMC, VARIABLE_GAIN, 241.0, 7.6),
    ("paper000_c_ismc_t1_newton", "IV-C", "ISMC + disturbance estimate, Newton CEE + unit-vector CCC, "
     "h = 50, T = 1 s", 50.0, 1.0, ISMC, NEWTON, 1.2, 0.19),
]


CONSTANT_LOAD = "{type: constant, value: 1.5e-4}"    # the faithful load: D_i = +0.15 paper units


def main(out=None):
    out = Path(out) if out else Path(__file__).resolve().parent.parent / "config"
    for stem, section, title, h, T, servo, (estimator, ccc), mce, tace in CASES:
        text = HEADER.format(section=section, title=title, mce=mce, tace=tace, tolerance=TOLERANCE,
                             max_iterations=MAX_ITERATIONS) + "\n" + \
            BODY.format(servo_x=servo["x"], servo_y=servo["y"], estimator=estimator, ccc=ccc,
                        disturbance_x=CONSTANT_LOAD, disturbance_y=CONSTANT_LOAD, shared=shared_section(
                stem, title, {"source": f"000 section {section}", "mce_um": mce, "tace_um": tace}, ["x", "y"],
                f"{{type: parabola, a: 0.02, h: {h}}}",
                f"{{type: uniform, theta_start: -0.02, theta_end: 0.02, duration: {T}}}"))
        (out / f"{stem}.yaml").write_text(with_adds(stem, text))
        print(out / f"{stem}.yaml")


# ------------------------------------------------------------------------------------------------------------
# Mechanism scenarios (config/paper000_mech_*.yaml): where the effect each claim relies on is present. They
# keep every reading of the faithful files above (units, plants, CEE and CCC gains, Newton stopping rule) and
# change only what the header of each family says, chosen from the physics. Claims: config/claims/paper000.yaml.

MECH_COMMON = """\
# Readings shared with the faithful paper000_* files: lengths in metres and the command unit 1000 times the
# paper's (a command's number is 1/1000 of the paper's; every gain keeps the paper's number); plants
# k = 10.3 / 10.0 m/s per unit, tau = 40 / 45 ms (eq. 2);
# the CCC correction adds to each axis' command (Fig. 5); Newton CEE (8, 11) iterated within each 1 ms step
# from the previous step's estimate with the faithful files' stopping rule:
#   {newton}
# Unit-vector CCC: one PID 1 + 10/s + 0.1 s per axis on the components E*_i of the contour error vector
# (eq. 15 read as PID on E*_i = |E*| eps_i: a PID on the unit vector eps_i itself would command a correction
# of constant size, 1 unit or about 10 m/s, for any error). Variable-gain CCC 8 + 80/s + 0.6 s on the signed
# tangent-line estimate, C = its unit normal (Koren & Lo's linear-contour gains; their curvature terms are not
# used, as the paper gives none). ISMC (20-22) with mu = 1e-3 m/s; disturbance estimate (24-26) with the
# factor c missing from eq. 25 restored, its filters starting in the steady state of the initial motion with
# no load. PID + feedforward: PID(R - P) + (tau R'' + R') / k, no disturbance compensation. Each axis starts
# on the reference, moving with it. Scores are taken from t = 0.3 s (config/claims/paper000.yaml, from_time):
# the start-up transient (the load stepping in at t = 0 against integrators at zero) is left out.
"""

LAG_HEADER = """\
# Paper 000 (Ghaffari & Ulsoy), MECHANISM scenario: lagging drives on a curve (claims newton_ccc_vs_vgccc and
# newton_cee_accuracy).
# {title}
# No paper figure: the paper's own ISMC cases cannot show its mechanism (see below).
#
# The mechanism the paper relies on: a static CEE replaces the contour by its tangent line at the reference
# point (eq. 5-7), so where the axis lags the reference by a tangential error e_t on a curve of curvature kappa
# the static estimate is off by about kappa e_t^2 / 2; a CCC driving that estimate to zero leaves a contour
# error of that size, while the Newton CEE (8-14) finds the true foot point. Under the paper's ISMC with exact
# feedforward and the disturbance estimate the tracking error is a few micrometres, so kappa e_t^2 / 2 is
# about 1e-9 m and the static estimate is exact: the mechanism never acts there.
#
# What makes it act here, from the physics of a feed drive: the axis loop is a plain proportional position
# loop without feedforward (law: pid, ki = kd = 0), the classic CNC servo of Koren's CCC, whose following
# error is e_t = v / K_v. Only the servo differs from the faithful files; plants, load, contour, CEE and
# CCC gains are the paper's.
# - kp = 2.5 units/m: K_v = k kp = 25.8 / 25.0 1/s on x / y, a typical machine-tool position-loop gain
#   (1.5 (m/min)/mm); the loop tau s^2 + s + K_v has damping 0.49 / 0.47. The same kp on both axes keeps the
#   paper's asymmetric axes (k, tau differ).
# - T = 1 s (the paper's fast case IV-C): 40 mm/s at the vertex, e_t = 1.6 mm against a 10 mm radius of
#   curvature (h = 50: kappa = 100 1/m), so the tangent-line estimate is off by about 130 um there.
# - The constant load D = +0.15 paper units on each axis stays (the faithful reading): on a P loop it
#   leaves a static offset D / kp = 60 um per axis, which every CCC has to remove.
# The regime map of the claims sweeps T and kp: the mechanism is off at high K_v and slow feed.
#
"""

LOAD_HEADER = """\
# Paper 000 (Ghaffari & Ulsoy), MECHANISM scenario: a time-varying load (claim ismc_vs_pidff).
# {title}
# No paper figure.
#
# The mechanism the paper relies on for ISMC + disturbance estimate against PID + feedforward (IV-A vs IV-B):
# rejecting a load the PID's integral cannot follow. The faithful files use a constant load, which the PID
# integral removes within a fraction of a second, so after the start-up both servos track to a fraction of a
# micrometre. Here the load varies in time, inside the paper's bound |D_i| <= 0.15:
# - D_x = 1.5e-4 sin(2 pi f t), D_y = 1.5e-4 cos(2 pi f t) (command units; 0.15 paper units, the bound):
#   a once-per-revolution ball-screw load, one screw a quarter turn ahead of the other.
# - f = 2 Hz: the x axis moves at 20 mm/s (h = 50, T = 2 s, the paper's IV-A/IV-B case), i.e. 2 rev/s
#   on a 10 mm-lead screw; 2 Hz is below the observer's corner c = d = 25 rad/s (4 Hz), where the
#   disturbance estimate (24-26) can follow the load.
# - Both files: Newton CEE + unit-vector CCC (the paper's proposed CCC); only the servo differs (PID + FF
#   with the IV-A gains, or ISMC + disturbance estimate with the IV-B gains), as in the paper's comparison.
# The regime map sweeps the load frequency (across the observer's bandwidth) and amplitude (across the
# ISMC's robustness bound M = mu (kappa - b tau / k) = 2.5e-4 of eq. 23).
#
"""

LAG_KP = 2.5          # units/m: K_v = 25 1/s (see LAG_HEADER)
P_LOOP = {axis: f"    law: pid  # proportional position loop, no feedforward: K_v = k kp\n"
                f"    kp: {LAG_KP}\n    ki: 0.0\n    kd: 0.0\n" for axis in ("x", "y")}
LOAD_FREQUENCY = 2.0  # Hz (see LOAD_HEADER)
SINE_LOAD = {"x": f"{{type: sinusoid, amplitude: 1.5e-4, frequency: {LOAD_FREQUENCY}, phase: 0.0}}",
             "y": f"{{type: sinusoid, amplitude: 1.5e-4, frequency: {LOAD_FREQUENCY}, phase: 1.5707963267948966}}"}
TANGENT_UNIT_VECTOR = ("    type: tangent_line  # static CEE, with the proposed unit-vector CCC\n", NEWTON[1])

MECH_CASES = [
    # file stem, header, title, h, T, servo, (estimator, ccc), disturbances
    ("paper000_mech_lag_newton_uv", LAG_HEADER, "P-loop axes (K_v = 25 1/s), h = 50, T = 1 s: Newton CEE + "
     "unit-vector CCC", 50.0, 1.0, P_LOOP, NEWTON, {"x": CONSTANT_LOAD, "y": CONSTANT_LOAD}),
    ("paper000_mech_lag_tangent_vg", LAG_HEADER, "P-loop axes (K_v = 25 1/s), h = 50, T = 1 s: tangent-line CEE "
     "+ variable-gain CCC", 50.0, 1.0, P_LOOP, VARIABLE_GAIN, {"x": CONSTANT_LOAD, "y": CONSTANT_LOAD}),
    ("paper000_mech_lag_tangent_uv", LAG_HEADER, "P-loop axes (K_v = 25 1/s), h = 50, T = 1 s: tangent-line CEE "
     "+ unit-vector CCC (only the CEE differs from mech_lag_newton_uv)", 50.0, 1.0, P_LOOP,
     TANGENT_UNIT_VECTOR, {"x": CONSTANT_LOAD, "y": CONSTANT_LOAD}),
    ("paper000_mech_load_pidff", LOAD_HEADER, "PID + feedforward (IV-A gains), 2 Hz load at the bound, h = 50, "
     "T = 2 s: Newton CEE + unit-vector CCC", 50.0, 2.0, PIDFF, NEWTON, SINE_LOAD),
    ("paper000_mech_load_ismc", LOAD_HEADER, "ISMC + disturbance estimate (IV-B gains), 2 Hz load at the bound, "
     "h = 50, T = 2 s: Newton CEE + unit-vector CCC", 50.0, 2.0, ISMC, NEWTON, SINE_LOAD),
]


def write_mechanism_scenarios(out=None):
    out = Path(out) if out else Path(__file__).resolve().parent.parent / "config"
    common = MECH_COMMON.format(newton=", ".join(line.strip() for line in NEWTON[0].splitlines()[1:]))
    for stem, header, title, h, T, servo, (estimator, ccc), disturbance in MECH_CASES:
        text = header.format(title=title) + common + "\n" + BODY.format(
            servo_x=servo["x"], servo_y=servo["y"], estimator=estimator, ccc=ccc,
            disturbance_x=disturbance["x"], disturbance_y=disturbance["y"],
            shared=shared_section(stem, title, {"source": "000 mechanism scenario (no paper figure)"}, ["x", "y"],
                                  f"{{type: parabola, a: 0.02, h: {h}}}",
                                  f"{{type: uniform, theta_start: -0.02, theta_end: 0.02, duration: {T}}}"))
        (out / f"{stem}.yaml").write_text(with_adds(stem, text))
        print(out / f"{stem}.yaml")


# ------------------------------------------------------------------------------------------------------------
# Reference methods (config/paper000_zpetc_*.yaml, paper000_ilc_t1.yaml): the literature's methods on the
# paper's scenarios, for the benchmark (tools/scenario_template.py, REFERENCE_WHAT).

ZPETC_AXES = {"x": "law: zpetc  # PID_1 of section IV-A, derivative on the velocity\nkp: 8.08\nki: 93.2\nkd: 0.24\n"
                   "gain: 10.3\ntime_constant: 0.040",
              "y": "law: zpetc  # PID_2 of section IV-A, derivative on the velocity\nkp: 9.36\nki: 108.0\nkd: 0.3\n"
                   "gain: 10.0\ntime_constant: 0.045"}
ZPETC = {"/x/servo": ZPETC_AXES["x"], "/y/servo": ZPETC_AXES["y"], "/ccc": "type: none"}
ILC = {"/ccc": "type: ilc  # u_j+1 = Q[u_j + gamma_contour eps_j(k + lead)], on the ISMC axes\ngamma_contour: 10.0\n"
               "gamma_tracking: 0.0\nlead: 5\nq_cutoff: 10.0\npasses: 4"}
PID_WORDS = "PID_1, PID_2 of section IV-A"
REFERENCE_METHODS = [
    ("paper000_b_ismc_h50_newton", "paper000_zpetc_h50", "zpetc", "PID + ZPETC feedforward, no CCC, h = 50, T = 2 s",
     ZPETC, PID_WORDS),
    ("paper000_b_ismc_h100_newton", "paper000_zpetc_h100", "zpetc", "PID + ZPETC feedforward, no CCC, h = 100, "
     "T = 2 s", ZPETC, PID_WORDS),
    ("paper000_c_ismc_t1_newton", "paper000_zpetc_t1", "zpetc", "PID + ZPETC feedforward, no CCC, h = 50, T = 1 s",
     ZPETC, PID_WORDS),
    ("paper000_c_ismc_t1_newton", "paper000_ilc_t1", "ilc", "ISMC + disturbance estimate, Newton CEE, cross-coupled "
     "ILC over 4 passes, h = 50, T = 1 s", ILC, ""),
]

if __name__ == "__main__":
    main(*sys.argv[1:2])       # the output directory, default config/
    write_mechanism_scenarios(*sys.argv[1:2])
    write_reference_methods(sys.argv[1] if sys.argv[1:] else Path(__file__).resolve().parent.parent / "config",
                            "000", REFERENCE_METHODS)
