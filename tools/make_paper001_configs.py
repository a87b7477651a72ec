"""Write the paper 001 scenario files (config/paper001_*.yaml) from one template.

Paper 001 (Lee, Dixon & Ziegert, adaptive nonlinear contour coupling control), section 4: circles on the
x-y feed drives of a high speed milling machine under a PD controller, Koren's benchmark CCC and the
adaptive TNB CCC (Tables 1-2). Run after changing the template: python tools/make_paper001_configs.py

Besides the paper's nine runs (the faithful reading: case I, II, III x PD, benchmark, adaptive TNB CCC) it
writes:
- paper001_caseII_adaptive_tnb_frozen / _uncoupled: the faithful case II run with adaptation off (Gamma = 0)
  and with the cross-coupling term off (k_c = 0): the baselines of the claims that adaptation and the
  coupling term matter (the paper runs neither);
- paper001_mech_mismatch_{adaptive_tnb,frozen,benchmark}: adaptation's mechanism acting: the true plant
  differs from the identified model the controller starts from (a 1.5 t fixture and workpiece on the x
  table), two revolutions of case II;
- paper001_mech_coupling_{adaptive_tnb,uncoupled}: the coupling term's mechanism acting: a tangential error
  the feedforward has not removed (viscous friction twice the identified), a small fast circle (v / rho
  comparable to alpha)
  and the coupling gain of the paper's own design (k_c = k, the PD's derivative gain, eq. 25 and 38).
Every file's header says what it reads into the paper and why its numbers were chosen; the readings are
also listed in config/claims/paper001.yaml.
"""
import math
import sys
from pathlib import Path

from scenario_template import write_reference_methods, shared_section, with_adds

SCREW = 228.0                     # 2 pi / lead [rad/m] of the x ball screw (see the header)
J_X, B_X_ROT = 0.05916, 0.01725   # x: kg m^2, N m s/rad
M_Y, B_Y = 1144.0, 967.0          # y: kg, N s/m
M_X, B_X = J_X * SCREW**2, B_X_ROT * SCREW**2
ALPHA = 40.0                      # 1/s: the paper's P / D = 360000 / 9e6 = 58000 / 1.45e6 = 1/25 per servo cycle


def critically_damped_pd(mass, damping, alpha=ALPHA):
    """(P, D) with P = alpha D and M s^2 + (B + D) s + P critically damped: (B + D)^2 = 4 M P."""
    b = 4.0 * mass * alpha - 2.0 * damping
    d = (b + math.sqrt(b * b - 4.0 * damping * damping)) / 2.0
    return alpha * d, d


(KP_X, KD_X), (KP_Y, KD_Y) = critically_damped_pd(M_X, B_X), critically_damped_pd(M_Y, B_Y)
W_BENCHMARK = 2.2e7               # Koren's proportional CCC gain [N/m]: case I RMS 0.35 of the PD's (paper 15/43)
# Adaptation gains of eq. 26 from an adaptation time constant TAU_A on case II (rho 0.1 m, v 0.4 m/s): a
# quasi-static force error f gives r = f / D, so m^' = Gamma_m x_d'' r converges at the rate
# Gamma_m <x_d''^2> / D; Gamma_m = D / (TAU_A <x_d''^2>), Gamma_b = D / (TAU_A <x_d'^2>), <.> over a circle.
TAU_A = 0.25                      # s: 20 times the axis loops' time constant 1 / omega_n = 12.5 ms
V_II, A_II = 0.4, 0.4**2 / 0.1
GAMMA_MASS = (KD_X / (TAU_A * A_II**2 / 2), KD_Y / (TAU_A * A_II**2 / 2))
GAMMA_DAMPING = (KD_X / (TAU_A * V_II**2 / 2), KD_Y / (TAU_A * V_II**2 / 2))
# The experiment's cross-coupling gains, as fractions of the proportional gains: (k v / rho)_i / P_i
COUPLING_RATIO = (422.0 / 360000.0, 1359.0 / 58000.0)
ENCODER = (2.0e-6, 1.0e-6)        # m: x rotary encoder (2 um at the table), y linear encoder (1 um)
WORKPIECE = 1500.0                # kg on the x table, absent when the axes were identified (mechanism)
FRICTION = 2.0                    # true / identified viscous friction, both axes (mechanism)
MECH_RADIUS, MECH_FEEDRATE = 0.02, 0.2   # m, m/s: v / rho = 10 1/s = alpha / 4 (mechanism)

CASES = {"I": (0.1, 0.2), "II": (0.1, 0.4), "III": (0.06, 0.4)}
PAPER = {("I", "pd"): (119, 43), ("I", "benchmark"): (46, 15), ("I", "adaptive_tnb"): (63, 12),
         ("II", "pd"): (288, 160), ("II", "benchmark"): (149, 56), ("II", "adaptive_tnb"): (125, 28),
         ("III", "pd"): (530, 250), ("III", "benchmark"): (215, 86), ("III", "adaptive_tnb"): (219, 49)}

READINGS = """\
# Readings this file had to choose (the paper gives its gains in the PMAC controller's units, so magnitudes
# are compared only loosely; every reading is also in config/claims/paper001.yaml):
# - Axes: mass-dampers with the identified parameters (eq. 1, section 4). The x axis is a ball screw
#   (J = 0.05916 kg m^2, B = 0.01725 N m s/rad); its lead is not given, so 2 pi / lead = 228 rad/m, the value
#   at which the model's RMS x torque in case I equals Table 3's 3.85 N m, turns it into a linear axis of
#   M = {m_x:.0f} kg, B = {b_x:.0f} N s/m (force = torque * 228). y: M = 1144 kg, B = 967 N s/m. Exact
#   zero-order hold, 1 ms (the PMAC's servo update). Encoders as in section 4: x 2 um, y 1 um at the table.
# - PD (every controller's axis loop, eq. 38 terms 2-3): the paper's gains have D / P = 25 servo cycles on
#   both axes (9e6 / 360000 = 1.45e6 / 58000), read as the PMAC derivative acting on counts per servo cycle:
#   alpha = P / D = 40 1/s, common to both axes as eq. 38 has it (P = alpha k + 1 ~ alpha k, D = k). P itself
#   is the largest gain without overshoot of the axis poles ("lowest following error without overshoot"):
#   M s^2 + (B + D) s + P critically damped, omega_n = 80 rad/s on both axes. No feedforward.
# - Benchmark CCC (Koren [4]): proportional gain W along the exact contour normal (osculating-circle
#   estimate, exact on circles). Its gain 3584 is in PMAC units; W = 2.2e7 N/m makes the benchmark's case-I
#   RMS 0.35 of the PD's, the paper's 15/43 (a calibration of the baseline, the same in every case).
# - Adaptive TNB CCC (eq. 38): alpha = 40 1/s as above; initial estimates theta^(0) = the identified M, B
#   (section 4: "for the initial best-guess estimate ... these values are used"). Gamma (the paper's is in
#   PMAC units) from an adaptation time constant of 0.25 s on case II: Gamma_m = D / (0.25 <x_d''^2>),
#   Gamma_b = D / (0.25 <x_d'^2>), the same in every file. Cross-coupling gains k_c,i with
#   (k_c v / rho)_i / P_i in case I equal to the paper's 422 / 360000 and 1359 / 58000 (k_c held constant
#   over the cases, as eq. 38's k is); the design value of eq. 25 is k_c = k = D (used in the mechanism
#   files), the paper's are 1/43 (x) and 1/2 (y) of it.
# - The contour error is scored exactly (distance to the circle), as the paper's radial error.
"""

HEADER = """\
# Paper 001 (Lee, Dixon & Ziegert, adaptive nonlinear contour coupling control), {section}
# {title}
# {compared}
#
{readings}{extra}"""

BODY = """\
{shared}
/x/plant:
  ros__parameters: {{model: mass_damper, mass: {m_x_true!r}, damping: {b_x_true!r}, gain: 1.0,
                    encoder_resolution: {enc_x!r}}}

/y/plant:
  ros__parameters: {{model: mass_damper, mass: {m_y!r}, damping: {b_y_true!r}, gain: 1.0,
                    encoder_resolution: {enc_y!r}}}

/x/servo:
  ros__parameters: {{law: pid, kp: {kp_x!r}, kd: {kd_x!r}}}

/y/servo:
  ros__parameters: {{law: pid, kp: {kp_y!r}, kd: {kd_y!r}}}

/contour_estimator:
  ros__parameters: {{type: osculating_circle}}

/ccc:
  ros__parameters: {ccc}
"""


def adaptive(coupling, gamma=1.0):
    return (f"{{type: adaptive_tnb, coupling: [{coupling[0]!r}, {coupling[1]!r}], alpha: {ALPHA!r},\n"
            f"                    gamma_mass: [{gamma * GAMMA_MASS[0]!r}, {gamma * GAMMA_MASS[1]!r}],\n"
            f"                    gamma_damping: [{gamma * GAMMA_DAMPING[0]!r}, {gamma * GAMMA_DAMPING[1]!r}],\n"
            f"                    mass0: [{M_X!r}, {M_Y!r}], damping0: [{B_X!r}, {B_Y!r}]}}")


BENCHMARK = f"{{type: variable_gain, kp: {W_BENCHMARK!r}, ki: 0.0, kd: 0.0}}"
PAPER_COUPLING = tuple(ratio * kp * 0.1 / 0.2 for ratio, kp in zip(COUPLING_RATIO, (KP_X, KP_Y)))   # case I v/rho
DESIGN_COUPLING = (KD_X, KD_Y)
CONTROLLERS = {"pd": ("PD", "{type: none}"), "benchmark": ("benchmark CCC (Koren, proportional)", BENCHMARK),
               "adaptive_tnb": ("adaptive TNB CCC", adaptive(PAPER_COUPLING))}

MECH_MISMATCH = """\
# Mechanism scenario (adaptation; claims adaptive_vs_benchmark and adaptation_under_mismatch): the
# paper's argument for the adaptive feedforward is uncertain inertia and friction (abstract, eq. 26). In the
# faithful files the plant IS the identified model and theta^(0) is that model, so there is nothing to learn.
# Here the x table carries a {workpiece:.0f} kg fixture and workpiece that the identification (on the empty
# table) did not see: true M_x = {m_x_true:.0f} kg, while the controller starts from the identified {m_x:.0f} kg.
# On a circle the missing feedforward Delta M x_d'' = {workpiece:.0f} kg * 1.6 m/s^2 = 2.4 kN is a normal
# force, about 120 um at the x axis' stiffness P_x: far above the 1-2 um encoders, so it dominates the contour
# error until the estimate converges. Case II's circle (rho 0.1 m, v 0.4 m/s, 1.6 m/s^2: the paper's 0.1 m
# circle with the most excitation) for two revolutions ({duration:.3f} s): adaptation (time constant 0.25 s)
# has converged after the first second, which the steady-state claim scores. The PD gains stay those designed
# for the identified mass (with the heavier table the x loop is then slightly underdamped).
"""

MECH_COUPLING = """\
# Mechanism scenario (coupling; claim coupling_term): the cross-coupling term k v F R F^T e~ (eq. 38-39)
# is what turns the world-frame PD into a PD on the frame's errors: without it the derivative gain acting on
# the rotating error vector, D e~' = D (v F R^T F^T e~ + ...), pushes a tangential error e_t into the normal
# direction with stiffness D v / rho, i.e. a normal error (v / rho) / alpha * e_t. That acts only when (1) a
# tangential error exists that the feedforward has not removed and (2) v / rho is comparable to alpha.
# (1): uncertain friction, the paper's own premise: the hydrostatic guideways' and screw's viscous friction
# scales with the oil's viscosity, which doubles for an oil about 20 K colder than when the axes were
# identified, so the true B is {friction:g} x the identified B on both axes while theta^(0) = the identified
# M, B. The missing feedforward Delta B x_d' is a force opposing the feed, constant along the circle, which
# the adaptation (time constant about 1 s for friction at this feedrate) removes only slowly.
# (2): a small fast circle, rho = {radius} m at v = {feedrate} m/s (v / rho = 10 1/s = alpha / 4;
# 2 m/s^2, below case III's 2.67), one revolution from on the circle. The coupling gain is the paper's own
# design value k_c = k = D_i (eq. 25 and 38: one gain k multiplies r, whose world-frame form contains the
# coupling term), not the experiment's much smaller gains.
"""


def write(out, name, section, title, compared, paper, radius, feedrate, revolutions, ccc, extra="",
          m_x_true=M_X, friction=1.0):
    duration = revolutions * 2 * math.pi * radius / feedrate
    fields = dict(m_x=M_X, b_x=B_X, m_y=M_Y, b_y=B_Y, kp_x=KP_X, kd_x=KD_X, kp_y=KP_Y, kd_y=KD_Y, ccc=ccc,
                  enc_x=ENCODER[0], enc_y=ENCODER[1], m_x_true=m_x_true, b_x_true=friction * B_X,
                  b_y_true=friction * B_Y, workpiece=WORKPIECE, duration=duration, friction=friction, radius=radius,
                  feedrate=feedrate)
    fields["shared"] = shared_section(
        name, title, paper, ["x", "y"], f"{{type: circle, radius: {radius}}}",
        f"{{type: uniform, theta_start: 0.0, theta_end: {revolutions * 2 * math.pi!r}, duration: {duration!r}}}")
    header = HEADER.format(section=section, title=title, compared=compared,
                           readings=READINGS.format(**fields), extra=("#\n" + extra.format(**fields)) if extra else "")
    path = out / f"{name}.yaml"
    path.write_text(with_adds(name, header + "\n" + BODY.format(**fields)))
    print(path)


def main(out=None):
    out = Path(out) if out else Path(__file__).resolve().parent.parent / "config"
    for case, (radius, feedrate) in CASES.items():
        for key, (label, ccc) in CONTROLLERS.items():
            mce, rms = PAPER[case, key]
            write(out, f"paper001_case{case}_{key}", f"section 4, case {case}.",
                  f"circle r = {radius} m at {feedrate} m/s, {label}",
                  f"Paper's result for this case (Table 2, a machine experiment): max {mce} um, RMS {rms} um.",
                  {"source": f"001 section 4, Table 2, case {case}", "mce_um": mce, "rms_um": rms},
                  radius, feedrate, 1, ccc)
    radius, feedrate = CASES["II"]
    for key, label, ccc in (("frozen", "adaptation off (Gamma = 0)", adaptive(PAPER_COUPLING, 0.0)),
                            ("uncoupled", "cross-coupling term off (k_c = 0)", adaptive((0.0, 0.0)))):
        write(out, f"paper001_caseII_adaptive_tnb_{key}", "section 4, case II, an ablation the paper does not run.",
              f"circle r = {radius} m at {feedrate} m/s, adaptive TNB CCC with {label}",
              "No result in the paper: the baseline of a claim (config/claims/paper001.yaml).",
              {"source": "001 section 4, case II (ablation)"}, radius, feedrate, 1, ccc)
    m_x_true = M_X + WORKPIECE
    for key, label, ccc in (("adaptive_tnb", "adaptive TNB CCC", adaptive(PAPER_COUPLING)),
                            ("frozen", "adaptive TNB CCC with adaptation off (Gamma = 0)",
                             adaptive(PAPER_COUPLING, 0.0)),
                            ("benchmark", "benchmark CCC (Koren, proportional)", BENCHMARK)):
        write(out, f"paper001_mech_mismatch_{key}", "mechanism scenario: parameter mismatch.",
              f"circle r = {radius} m at {feedrate} m/s, x table {WORKPIECE:.0f} kg heavier than identified, {label}",
              "No result in the paper: a mechanism scenario of config/claims/paper001.yaml.",
              {"source": "001 mechanism: parameter mismatch"}, radius, feedrate, 2, ccc, MECH_MISMATCH,
              m_x_true=m_x_true)
    for key, label, coupling in (("adaptive_tnb", "adaptive TNB CCC, k_c = D", DESIGN_COUPLING),
                                 ("uncoupled", "adaptive TNB CCC, coupling term off (k_c = 0)", (0.0, 0.0))):
        write(out, f"paper001_mech_coupling_{key}", "mechanism scenario: the coupling term.",
              f"circle r = {MECH_RADIUS} m at {MECH_FEEDRATE} m/s, friction {FRICTION:g} x identified, {label}",
              "No result in the paper: a mechanism scenario of config/claims/paper001.yaml.",
              {"source": "001 mechanism: coupling term"}, MECH_RADIUS, MECH_FEEDRATE, 1, adaptive(coupling),
              MECH_COUPLING, friction=FRICTION)


# ------------------------------------------------------------------------------------------------------------
# Reference methods: the literature's methods on the paper's scenarios, for the benchmark
# (tools/scenario_template.py, REFERENCE_WHAT).

# the paper's PD on each axis; the ZPETC's model of a mass-damper M x'' + B x' = K u is K / B, M / B
ZPETC = {"/x/servo": "law: zpetc  # the paper's PD, derivative on the velocity\nkp: 19610586.489482205\nki: 0.0\n"
                     "kd: 490264.66223705513\ngain: 0.0011151703311163747  # K / B\n"
                     "time_constant: 3.429565217391304  # M / B [s]",
         "/y/servo": "law: zpetc  # the paper's PD, derivative on the velocity\nkp: 7244033.465559332\nki: 0.0\n"
                     "kd: 181100.83663898328\ngain: 0.001034126163391934  # K / B\n"
                     "time_constant: 1.1830403309203723  # M / B [s]",
         "/ccc": "type: none"}
ILC = {"/ccc": "type: ilc  # u_j+1 = Q[u_j + gamma_contour eps_j(k + lead)], on the paper's PD axes\n"
               "gamma_contour: 1.0e+7\ngamma_tracking: 0.0\nlead: 5\nq_cutoff: 10.0\npasses: 4"}
REFERENCE_METHODS = [
    (f"paper001_case{case}_adaptive_tnb", f"paper001_case{case}_zpetc", "zpetc",
     f"case {case}: PD + ZPETC feedforward, no CCC", ZPETC, "the paper's PD") for case in ("I", "II", "III")
] + [("paper001_caseIII_adaptive_tnb", "paper001_caseIII_ilc", "ilc",
      "case III: PD axes, cross-coupled ILC over 4 passes", ILC, "")]

if __name__ == "__main__":
    main(*sys.argv[1:2])       # the output directory, default config/
    write_reference_methods(sys.argv[1] if sys.argv[1:] else Path(__file__).resolve().parent.parent / "config",
                            "001", REFERENCE_METHODS)
