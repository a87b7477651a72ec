"""Write the paper 002 scenario files (config/paper002_*.yaml) from one template.

Paper 002 (TVT-based cross-coupled control), section 4: the butterfly curve on two closed velocity loops,
with the traditional velocity-loop CCC on the tangent-line (C1) and osculating-circle (C2) estimates and the
tangential velocity tracking CCC (C3). Run after changing the template:
python tools/make_paper002_configs.py
"""
from pathlib import Path

from scenario_template import shared_section

HEADER = """\
# Paper 002 (TVT-based cross-coupled control), section 4: {title}.
# A machine experiment: only the ordering is compared, max contour error C3 < C2 < C1 (paper: C3 65% below
# C1 and 50% below C2) and C3's estimation deviation within 1 um.
#
# Readings this file had to choose (the paper's equations and Table 2 are lost from its text):
# - Curve: Fay's butterfly r(u) = exp(cos u) - 2 cos 4u scaled by 10 mm (about 95 x 75 mm). It crosses itself,
#   so the exact contour error is measured against the branch within 0.3 rad of the reference parameter
#   (contour_error_window), as paper 003 does; the largest lag here is 0.04 rad.
# - Feedrate: 100 mm/s maximum (Fig. 6b), 1 m/s^2 tangential and 1 m/s^2 normal (centripetal) acceleration
#   bounds, from rest to rest (schedule: feedrate).
# - Axes: closed velocity loops modelled as matched first-order systems (the paper's own model), time
#   constant 5 ms, velocity command in m/s (model: first_order_velocity, gain 1).
# - C1, C2: P position loops of 40 1/s (the paper's) with velocity feedforward; a P-type CCC of 140 1/s (the
#   paper's gain) along the estimate's normal, added to the velocity commands (variable_gain, kp only).
# - C3: foot point by tangential-error backstepping, at most 10 iterations, 1 um (the paper's), from the
#   previous foot point; velocity command f(theta*) t + 140 E; from rest the commanded feedrate is at least
#   1 mm/s until the end of the path (the profile is 0 at the start point).
"""

BODY = """\
{shared}
/x/plant:
  ros__parameters: {{model: first_order_velocity, gain: 1.0, time_constant: 0.005}}

/y/plant:
  ros__parameters: {{model: first_order_velocity, gain: 1.0, time_constant: 0.005}}

/x/servo:
  ros__parameters: {servo}

/y/servo:
  ros__parameters: {servo}

/contour_estimator:
  ros__parameters: {estimator}

/ccc:
  ros__parameters: {ccc}
"""

P_LOOP = "{law: pid_feedforward, kp: 40.0, ki: 0.0, kd: 0.0, gain: 1.0, time_constant: 0.0}"
P_CCC = "{type: variable_gain, kp: 140.0, ki: 0.0, kd: 0.0}"
METHODS = {
    "c1_tangent_line": ("C1, velocity-loop CCC on the tangent-line estimate", P_LOOP, "{type: tangent_line}", P_CCC),
    "c2_osculating_circle": ("C2, velocity-loop CCC on the osculating-circle estimate", P_LOOP,
                             "{type: osculating_circle}", P_CCC),
    "c3_tvt": ("C3, TVT-based CCC", "{law: direct}", "{type: foot_point_search, max_iterations: 10, tolerance: 1.0e-6}",
               "{type: tvt, kc: 140.0, min_feedrate: 0.001}"),
}


def main():
    out = Path(__file__).resolve().parent.parent / "config"
    for key, (label, servo, estimator, ccc) in METHODS.items():
        name = f"paper002_butterfly_{key}"
        title = f"butterfly at 100 mm/s, {label}"
        fields = dict(name=name, title=title, servo=servo, estimator=estimator, ccc=ccc, shared=shared_section(
            name, title, {"source": "002 section 4 (ordering only)"}, ["x", "y"],
            "{type: butterfly, scale: 0.01, contour_error_window: 0.3}",
            "{type: feedrate, theta_start: 0.0, theta_end: 6.283185307179586, feedrate: 0.1, acceleration: 1.0, "
            "normal_acceleration: 1.0}"))
        (out / f"{name}.yaml").write_text(HEADER.format(**fields) + "\n" + BODY.format(**fields))
        print(out / f"{name}.yaml")


if __name__ == "__main__":
    main()
