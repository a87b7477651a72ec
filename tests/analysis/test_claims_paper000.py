"""Paper 000's mechanism scenarios act as their headers say, and its CCC checks are not formalities.

The claim rows and ccc_helps entries of config/claims/paper000.yaml are tested by tests/analysis/test_claims.py; here:
the physics each mechanism scenario was chosen for (the tangent-line estimate is off by about kappa e_t^2 / 2
where the axes lag, and exact under the paper's ISMC). That each CCC with its sign flipped fails its ccc_helps
check is tested there too, for every paper.
"""
import math


from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.records.scoring import score_run
from conftest import CONFIG

FROM = 0.3        # s: every paper 000 claim scores from here (the start-up transient left out)


def _scores(name: str):
    loop = build_loop(load_experiment(CONFIG / f"{name}.yaml"))
    return score_run(loop.curve, simulate(loop), FROM)


def test_the_tangent_line_estimate_is_off_by_kappa_e_squared_over_two_where_the_axes_lag():
    """mech_lag: P loops (K_v = k kp) follow 40 mm/s at the vertex of the h = 50 parabola (kappa = 2h = 100 1/m)
    with e_t = v / K_v; the static estimate's worst deviation is about kappa e_t^2 / 2 (within 30%), the
    Newton CEE's is within its 1 nm stopping tolerance."""
    experiment = load_experiment(CONFIG / "paper000_mech_lag_tangent_uv.yaml")
    kv = experiment.plants["x"]["gain"] * experiment.servos["x"]["kp"]
    speed = 2 * experiment.curve["a"] / experiment.schedule["duration"]
    predicted = 2 * experiment.curve["h"] * (speed / kv) ** 2 / 2
    tangent = _scores("paper000_mech_lag_tangent_uv")
    assert 0.7 * predicted <= tangent.estimation_max <= 1.3 * predicted, (tangent.estimation_max, predicted)
    assert _scores("paper000_mech_lag_newton_uv").estimation_max <= 1e-9


def test_under_the_papers_ismc_the_static_estimate_is_already_exact():
    """The faithful ISMC cases track to micrometres: the tangent-line estimate is within 0.1 nm of the exact
    contour error, so the mechanism of the CEE claims cannot act there."""
    for name in ("paper000_b_ismc_h50_vgccc", "paper000_b_ismc_h100_vgccc", "paper000_c_ismc_t1_vgccc"):
        assert _scores(name).estimation_max < 1e-10, name


def test_the_load_mechanism_sits_below_the_observer_corner_and_within_the_bound():
    """mech_load: the load is at the paper's bound |D| <= 0.15 paper units and below the observer's corner."""
    for name in ("paper000_mech_load_ismc", "paper000_mech_load_pidff"):
        experiment = load_experiment(CONFIG / f"{name}.yaml")
        for axis in ("x", "y"):
            load = experiment.plants[axis]["disturbance"]
            assert load["type"] == "sinusoid" and abs(load["amplitude"]) + abs(load.get("offset", 0.0)) <= 1.5e-4
            corner = experiment.servos[axis].get("c", 25.0) / (2 * math.pi)
            assert load["frequency"] < corner
