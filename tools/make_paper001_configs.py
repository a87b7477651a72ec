"""Write the paper 001 scenario files (config/paper001_*.yaml) from one template.

Paper 001 (Lee, Dixon & Ziegert, adaptive nonlinear contour coupling control), section 4: circles on the
x-y feed drives of a high speed milling machine under a PD controller, Koren's benchmark CCC and the
adaptive TNB CCC (Tables 1-2). Run after changing the template: python tools/make_paper001_configs.py
"""
import math
from pathlib import Path

from scenario_template import shared_section

SCREW = 228.0                     # 2 pi / lead [rad/m] of the x ball screw (see the header)
J_X, B_X_ROT = 0.05916, 0.01725   # x: kg m^2, N m s/rad
M_Y, B_Y = 1144.0, 967.0          # y: kg, N s/m
M_X, B_X = J_X * SCREW**2, B_X_ROT * SCREW**2
OMEGA = 2 * math.pi * 20.0        # PD bandwidth [rad/s], the same on both axes
KP_X, KD_X = M_X * OMEGA**2, 2 * M_X * OMEGA - B_X
KP_Y, KD_Y = M_Y * OMEGA**2, 2 * M_Y * OMEGA - B_Y
ALPHA = KP_X / KD_X               # eq. 38: P = alpha k + 1, D = k
W_BENCHMARK = 5.0e7               # Koren's proportional CCC gain [N/m]
GAMMA = 3.0e6                     # adaptation gains of eq. 26
COUPLING = (422.0 / 360000.0 * KP_X / 2.0, 1359.0 / 58000.0 * KP_Y / 2.0)

HEADER = """\
# Paper 001 (Lee, Dixon & Ziegert, adaptive nonlinear contour coupling control), section 4, case {case}.
# {title}
# Paper's result for this case (Table 2, a machine experiment): max {mce} um, RMS {rms} um.
#
# Readings this file had to choose (the paper gives its gains in the machine's units, so only the ordering
# PD > benchmark CCC > adaptive TNB CCC in RMS contour error is compared):
# - Axes: mass-dampers with the identified parameters. The x axis is a ball screw (J = 0.05916 kg m^2,
#   B = 0.01725 N m s/rad); its lead is not given, so 2 pi / lead = 228 rad/m, the value at which the model's
#   RMS x torque in case I equals Table 3's 3.85 N m, turns it into a linear axis of M = {m_x:.0f} kg,
#   B = {b_x:.0f} N s/m (force = torque * 228). y: M = 1144 kg, B = 967 N s/m. Exact zero-order hold, 1 ms.
# - PD (every controller's axis loop, eq. 38 terms 2-3): both axes critically damped at 20 Hz,
#   P = M w^2, D = 2 M w - B, no feedforward. alpha = P / D = {alpha:.1f} 1/s on both axes (eq. 38: P = alpha k + 1).
# - Benchmark CCC (Koren): proportional gain W along the exact contour normal (osculating-circle estimate,
#   exact on circles). W = 5e7 N/m makes the benchmark's case-I RMS 0.37 of the PD's (paper: 15/43 = 0.35).
# - Adaptive TNB CCC (eq. 38): cross-coupling gains k_c,i with (k_c v / rho)_i / P_i in case I equal to the
#   paper's 422 / 360000 and 1359 / 58000; Gamma = 3e6 on every estimate makes its case-I RMS 0.28 of the
#   PD's (paper: 12/43 = 0.28). Initial estimates: half the true M and B. Cases II and III are predictions.
# - Each axis starts on the circle moving with it; one revolution at the constant feedrate.
"""

BODY = """\
{shared}
/x/plant:
  ros__parameters: {{model: mass_damper, mass: {m_x!r}, damping: {b_x!r}, gain: 1.0}}

/y/plant:
  ros__parameters: {{model: mass_damper, mass: {m_y!r}, damping: {b_y!r}, gain: 1.0}}

/x/servo:
  ros__parameters: {{law: pid, kp: {kp_x!r}, kd: {kd_x!r}}}

/y/servo:
  ros__parameters: {{law: pid, kp: {kp_y!r}, kd: {kd_y!r}}}

/contour_estimator:
  ros__parameters: {{type: osculating_circle}}

/ccc:
  ros__parameters: {ccc}
"""

CASES = {"I": (0.1, 0.2), "II": (0.1, 0.4), "III": (0.06, 0.4)}
PAPER = {("I", "pd"): (119, 43), ("I", "benchmark"): (46, 15), ("I", "adaptive_tnb"): (63, 12),
         ("II", "pd"): (288, 160), ("II", "benchmark"): (149, 56), ("II", "adaptive_tnb"): (125, 28),
         ("III", "pd"): (530, 250), ("III", "benchmark"): (215, 86), ("III", "adaptive_tnb"): (219, 49)}
CONTROLLERS = {
    "pd": ("PD", "{type: none}"),
    "benchmark": ("benchmark CCC (Koren, proportional)",
                  f"{{type: variable_gain, kp: {W_BENCHMARK!r}, ki: 0.0, kd: 0.0}}"),
    "adaptive_tnb": ("adaptive TNB CCC",
                     f"{{type: adaptive_tnb, coupling: [{COUPLING[0]!r}, {COUPLING[1]!r}], alpha: {ALPHA!r},\n"
                     f"                    gamma_mass: [{GAMMA!r}, {GAMMA!r}], gamma_damping: [{GAMMA!r}, {GAMMA!r}],\n"
                     f"                    mass0: [{M_X / 2!r}, {M_Y / 2!r}], damping0: [{B_X / 2!r}, {B_Y / 2!r}]}}"),
}


def main():
    out = Path(__file__).resolve().parent.parent / "config"
    for case, (radius, feedrate) in CASES.items():
        for key, (label, ccc) in CONTROLLERS.items():
            name = f"paper001_case{case}_{key}"
            mce, rms = PAPER[case, key]
            title = f"circle r = {radius} m at {feedrate} m/s, {label}"
            fields = dict(name=name, title=title, case=case, mce=mce, rms=rms, radius=radius,
                          duration=2 * math.pi * radius / feedrate, m_x=M_X, b_x=B_X, m_y=M_Y, b_y=B_Y,
                          kp_x=KP_X, kd_x=KD_X, kp_y=KP_Y, kd_y=KD_Y, alpha=ALPHA, ccc=ccc)
            fields["shared"] = shared_section(
                name, title, {"source": f"001 section 4, Table 2, case {case}", "mce_um": mce, "rms_um": rms},
                ["x", "y"], f"{{type: circle, radius: {radius}}}",
                f"{{type: uniform, theta_start: 0.0, theta_end: 6.283185307179586, duration: {fields['duration']!r}}}")
            (out / f"{name}.yaml").write_text(HEADER.format(**fields) + "\n" + BODY.format(**fields))
            print(out / f"{name}.yaml")


if __name__ == "__main__":
    main()
