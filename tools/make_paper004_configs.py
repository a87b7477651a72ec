"""Write the paper 004 scenario files (config/paper004_*.yaml) from one template.

Paper 004 (Wang, Zhou & Wang, contour tracking control based on an extended state observer), section 5:
three PMLSM axes under ESO-based sliding mode control with a PID cross-coupled controller, on the saddle
and the screw curve, with and without the ESO's disturbance compensation. Run after changing the
template: python tools/make_paper004_configs.py
"""
from pathlib import Path

from scenario_template import shared_section

HEADER = """\
# Paper 004 (Wang, Zhou & Wang, ESO-based contour tracking control), section 5, case {case}.
# {title}
# Paper's result for this case (Table {table}): max contour error {mce} um, mean {tace} um.
#
# Readings this file had to choose:
# - Units. The paper works in millimetres. Lengths here are SI metres and the command unit is 1/1000 of the
#   paper's (the axis equations are linear), so every gain of Table 1 and of the CCC keeps its number; the
#   disturbances d = 800 sin(pi t) ... (mm/s^2, added to the acceleration as in eq. 13-14) become 0.8 m/s^2.
# - Axes: M q'' + B q' = K_f u + M d (model: mass_damper, disturbance_unit: acceleration), exact
#   zero-order-hold discretisation at Ts = 1 ms (the paper gives no sample time).
# - ESO (eq. 16) keeps the model term -(B/M) v^ (dropped in print), so d^ estimates d alone, as eq. 24
#   needs; it is fed the command the actuator receives (SMC output + CCC compensation). "Without ESO" drops
#   d^ from eq. 24 (disturbance_compensation: false); the observer still gives q^ and v^.
# - Contour error: the tracking error's component normal to the reference tangent (eq. 1-9, the tangent-line
#   estimate), gains C_i = n_i (eq. 10-11) on one PID (kp 0.01, ki 0.2, kd 0.02): the multi-axis
#   variable-gain CCC.
# - The run lasts {duration} s (the paper gives no duration); each axis starts on the reference, moving with it.
"""

BODY = """\
{shared}
/x/plant:
  ros__parameters: {{model: mass_damper, mass: 5.8, damping: 244.0, gain: 10.9, disturbance_unit: acceleration,
                    disturbance: {{type: sinusoid, amplitude: 0.8, frequency: 0.5}}}}

/y/plant:
  ros__parameters: {{model: mass_damper, mass: 5.8, damping: 244.0, gain: 10.9, disturbance_unit: acceleration,
                    disturbance: {{type: sinusoid, amplitude: 0.9, frequency: 1.0}}}}

/z/plant:
  ros__parameters: {{model: mass_damper, mass: 1.4, damping: 82.0, gain: 0.82, disturbance_unit: acceleration,
                    disturbance: {{type: sinusoid, amplitude: 0.8, frequency: 2.0}}}}

/x/servo:
  ros__parameters: {{law: eso_smc, mass: 5.8, damping: 244.0, gain: 10.9, c: 500.0, k: 100.0,
                    alphas: [6.0, 11.0, 6.0], sigma: 0.01, disturbance_compensation: {eso}}}

/y/servo:
  ros__parameters: {{law: eso_smc, mass: 5.8, damping: 244.0, gain: 10.9, c: 1000.0, k: 150.0,
                    alphas: [8.0, 19.0, 12.0], sigma: 0.01, disturbance_compensation: {eso}}}

/z/servo:
  ros__parameters: {{law: eso_smc, mass: 1.4, damping: 82.0, gain: 0.82, c: 500.0, k: 120.0,
                    alphas: [9.0, 26.0, 24.0], sigma: 0.01, disturbance_compensation: {eso}}}

/contour_estimator:
  ros__parameters: {{type: tangent_line}}

/ccc:
  ros__parameters: {{type: variable_gain, kp: 0.01, ki: 0.2, kd: 0.02}}
"""

CASES = {
    "saddle": dict(case=1, table=2, duration=2.0,
                   curve="{type: saddle, a: 0.002, b: 0.003, h: 0.0005, omega: 6.283185307179586}",
                   schedule="{type: uniform, theta_start: 0.0, theta_end: 2.0, duration: 2.0}",
                   results={True: (105.7, 12.0), False: (465.0, 200.4)},
                   label="saddle curve x = 2 cos 2 pi t, y = 3 sin 2 pi t, z = 0.5 cos 4 pi t mm"),
    "screw": dict(case=2, table=3, duration=2.0,
                  curve="{type: helix, a: 0.003, b: 0.003, c: 0.0031415926535897933, omega: 3.141592653589793, "
                        "length: 2.5}",
                  schedule="{type: uniform, theta_start: 0.0, theta_end: 2.0, duration: 2.0}",
                  results={True: (23.1, 8.9), False: (52.3, 23.7)},
                  label="screw curve x = 3 cos pi t, y = 3 sin pi t, z = pi t mm"),
}


def main():
    out = Path(__file__).resolve().parent.parent / "config"
    for curve, case in CASES.items():
        for eso in (True, False):
            name = f"paper004_{curve}_{'eso' if eso else 'no_eso'}"
            mce, tace = case["results"][eso]
            title = f"{case['label']}, ESO-SMC {'with' if eso else 'without'} disturbance compensation, PID CCC"
            fields = dict(case, name=name, title=title, mce=mce, tace=tace, eso=str(eso).lower())
            fields["shared"] = shared_section(
                name, title, {"source": f"004 section 5, Table {case['table']}", "mce_um": mce, "tace_um": tace},
                ["x", "y", "z"], case["curve"], case["schedule"])
            (out / f"{name}.yaml").write_text(HEADER.format(**fields) + "\n" + BODY.format(**fields))
            print(out / f"{name}.yaml")


if __name__ == "__main__":
    main()
