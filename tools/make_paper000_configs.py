"""Write the paper 000 scenario files (config/paper000_*.yaml) from one template.

The scenarios differ only in the parabola depth h, the traversal time T, the servo law and the contour
estimator/controller pair, so they are generated from one template to keep them consistent. Run it
after changing the template: python tools/make_paper000_configs.py
"""
from pathlib import Path

from scenario_template import shared_section

HEADER = """\
# Paper 000 (Ghaffari & Ulsoy, Newton-based CEE and robust CCC), section {section}.
# {title}
# Paper's result for this case: MCE {mce} um, TACE {tace} um.
#
# Readings this file had to choose where the paper is silent (the same in every paper000_* file):
# - Units. The paper works in millimetres (a_r = 20 mm, h_r in 1/m, gains per mm). Lengths here are SI
#   metres and the actuator command unit is 1/1000 of the paper's, so every gain keeps the paper's number:
#   k = 10.3 (m/s per unit), PID gains per metre = the paper's per millimetre. Only the quantities that are
#   not gains change: the disturbance bound 0.15 -> 1.5e-4 units, and the ISMC boundary layer mu = 1 -> 1e-3
#   m/s (kappa mu, in command units, is the paper's value / 1000).
# - Disturbance: a constant load D_i = +0.15 (paper units) on each axis, the "load" of eq. 2 at the bound
#   |D_i| = 0.15 the paper states.
# - Initial state: each axis starts on the reference, moving with it (initial_state: on_reference).
# - The cross-coupled correction adds to each axis' actuator command (Koren's structure, Fig. 5).
# - Newton CEE: within each 1 ms step the Newton flow (8) with its c' filter runs {iterations} inner
#   iterations of 1 ms of estimator time, starting from the previous step's estimate (Remark 3).
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
    disturbance: {{type: constant, value: 1.5e-4}}

/y/plant:
  ros__parameters:
    model: first_order_velocity
    gain: 10.0
    time_constant: 0.045
    disturbance: {{type: constant, value: 1.5e-4}}

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
ITERATIONS = 20
NEWTON = ("    type: newton  # c' = 500, k' = 500, theta_0 = -a_r\n    k_prime: 500.0\n    c_prime: 500.0\n"
          f"    iterations: {ITERATIONS}\n",
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


def main():
    out = Path(__file__).resolve().parent.parent / "config"
    for stem, section, title, h, T, servo, (estimator, ccc), mce, tace in CASES:
        text = HEADER.format(section=section, title=title, mce=mce, tace=tace, iterations=ITERATIONS) + "\n" + \
            BODY.format(servo_x=servo["x"], servo_y=servo["y"], estimator=estimator, ccc=ccc, shared=shared_section(
                stem, title, {"source": f"000 section {section}", "mce_um": mce, "tace_um": tace}, ["x", "y"],
                f"{{type: parabola, a: 0.02, h: {h}}}",
                f"{{type: uniform, theta_start: -0.02, theta_end: 0.02, duration: {T}}}"))
        (out / f"{stem}.yaml").write_text(text)
        print(out / f"{stem}.yaml")


if __name__ == "__main__":
    main()
