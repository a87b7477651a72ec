"""Each paper's claims (config/claims/paper<N>.yaml): every claim row measured under both readings and held to
its stated ratio and verdicts; every CCC lowers the contour error on its paper's mechanism scenario by its
stated factor; the verdict rule, steady-state scores and the regime map machinery on known cases."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from contouring_ros.bag import write_simulation
from contouring_ros.claims import (Claim, MapAxis, Pair, RegimeMap, ScenarioScores, ccc_helps_scores, claim_files,
                                   draw_map, evaluate, load_claims, map_ratios, verdict)
from contouring_ros.config import WHOLE_COMMAND_CONTROLLERS, build_loop, parse_experiment
from contouring_ros.core.metrics import score
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import ConfigError, Diverged, ScoreError
from contouring_ros.scoring import score_run
from conftest import DEFAULT, ROOT, shortened

FILES = claim_files()
CLAIMS = [(paper.paper, c) for paper in map(load_claims, FILES) for c in paper.claims]
HELPS = [entry for paper in map(load_claims, FILES) for entry in paper.ccc_helps]


@pytest.fixture(scope="module")
def scores():
    """Every scenario the claims name, simulated once for the whole module."""
    cache = ScenarioScores()
    cache.need([(name, None, c.from_time) for _, c in CLAIMS for reading in ("faithful", "mechanism")
                if c.pair(reading) for name in (c.pair(reading).proposed, c.pair(reading).baseline)]
               + [(e.scenario, None, e.from_time) for e in HELPS] + [(e.scenario, e.without, e.from_time) for e in HELPS])
    return cache


def test_verdict_rule():
    assert verdict(0.05, 0.069) == "holds"
    assert verdict(0.30, 0.069) == "holds"            # 70% of the way: 1 - 0.30 >= 0.75 * 0.931
    assert verdict(0.35, 0.069) == "holds weaker"
    assert verdict(0.96, 0.069) == "does not hold"
    assert verdict(1.04, 0.5) == "does not hold"
    assert verdict(1.2, 0.5) == "reversed"
    assert verdict(None, 0.5) == "not testable"
    assert verdict(math.nan, 0.5) == "not testable"


def test_every_paper_has_claims_and_maps():
    papers = {paper for paper, _ in CLAIMS}
    assert papers == {"000", "001", "002", "003", "004"}
    for paper, claim in CLAIMS:
        assert 1 <= sum(1 for p, _ in CLAIMS if p == paper) <= 3
        assert claim.maps, f"{paper}/{claim.id} has no regime map"
        assert claim.reason.count(". ") <= 3, f"{paper}/{claim.id}: the reason is more than three sentences"
        assert claim.faithful is not None


@pytest.mark.parametrize("paper, claim", CLAIMS, ids=[f"{p}-{c.id}" for p, c in CLAIMS])
def test_claim_row_is_measured_as_stated(paper, claim: Claim, scores):
    result = evaluate([claim], scores)[0]
    tolerance = claim.expected.get("tolerance", 0.1)
    for reading in ("faithful", "mechanism"):
        if claim.pair(reading) is None:
            continue
        ours, expected = result.ratio(reading), claim.expected.get(f"{reading}_ratio")
        assert ours is not None, f"{reading}: no ratio (a run diverged?)"
        assert expected is not None, f"{reading}: the claims file states no expected ratio"
        assert abs(ours / expected - 1.0) <= tolerance, f"{reading}: ratio {ours:.4g}, stated {expected}"
        assert result.verdict(reading) == claim.verdict[reading], f"{reading}: ratio {ours:.4g}"


@pytest.mark.parametrize("entry", HELPS, ids=[f"{e.paper}-{e.scenario}" for e in HELPS])
def test_each_ccc_lowers_the_contour_error_on_its_mechanism_scenario(entry, scores):
    with_ccc, without = ccc_helps_scores(entry, scores)
    assert with_ccc * entry.factor <= without, f"with the CCC {with_ccc * 1e6:.4g} um, without {without * 1e6:.4g} um"


@pytest.mark.parametrize("entry", HELPS, ids=[f"{e.paper}-{e.scenario}" for e in HELPS])
def test_the_ccc_check_fails_when_the_ccc_sign_is_flipped(entry):
    """The check above is not a formality: with the correction's sign flipped the CCC no longer lowers the
    contour error by its factor (the ``without`` run, unchanged, is the reference)."""
    from contouring_ros.claims import _experiment
    experiment = _experiment(entry.scenario)
    loop = build_loop(experiment)
    kind = experiment.controller["type"]
    if kind == "tvt":                    # its output is the whole velocity command: flip the contour term
        loop.controller.kc = -loop.controller.kc
    elif kind == "task_frame_pd":        # the whole command too: flip the normal (and binormal) PD gains of eq. 24
        assert loop.controller.kp[1:].min() > 0
        loop.controller.kp[1:] *= -1.0
        loop.controller.kd[1:] *= -1.0
    elif kind in WHOLE_COMMAND_CONTROLLERS:
        pytest.fail(f"{kind} computes the whole command: say here how its contour action is flipped")
    else:
        step = loop.controller.step
        loop.controller.step = lambda *args: -step(*args)
    try:
        flipped = getattr(score_run(loop.curve, simulate(loop), entry.from_time), entry.metric)
    except Diverged:
        return                        # flipped, the loop diverges: the check fails, as it must
    without = build_loop(_experiment(entry.scenario, entry.without))
    baseline = getattr(score_run(without.curve, simulate(without), entry.from_time), entry.metric)
    assert not flipped * entry.factor <= baseline


# --------------------------------------------------------------------------------------- steady-state scores


def _default_run(duration=0.6):
    experiment = parse_experiment(shortened(DEFAULT, duration), "default")
    loop = build_loop(experiment)
    return experiment, loop, simulate(loop)


def test_scores_from_a_time_cover_only_the_later_samples():
    _, loop, run = _default_run()
    whole, errors = score(loop.curve, run.time, run.position, run.reference_position, run.estimate_vector,
                          run.command, theta=run.theta)
    later = score_run(loop.curve, run, from_time=0.3)
    kept = run.time >= 0.3 - 1e-12
    assert later.steps == kept.sum() == 301 and later.from_time == 0.3
    assert later.mce == pytest.approx(errors[kept].max(), rel=1e-12)
    assert later.tace == pytest.approx(errors[kept].mean(), rel=1e-12)
    assert later.rms == pytest.approx(np.sqrt(np.mean(errors[kept] ** 2)), rel=1e-12)
    assert later.mce < whole.mce          # the start-up spike is left out
    with pytest.raises(ScoreError, match="no samples at t >= 5"):
        score_run(loop.curve, run, from_time=5.0)


def test_score_command_from_keeps_the_json_keys(tmp_path):
    experiment, loop, run = _default_run()
    bag = write_simulation(tmp_path / "run.mcap", experiment, run)
    cli = [sys.executable, "-m", "contouring_ros.cli", "score", str(bag), "--json"]
    whole = json.loads(subprocess.run(cli, capture_output=True, text=True, cwd=ROOT, check=True).stdout)["run"]
    later = json.loads(subprocess.run(cli + ["--from", "0.3"], capture_output=True, text=True, cwd=ROOT,
                                      check=True).stdout)["run"]
    assert set(later) == set(whole) and later["from_time"] == 0.3 and whole["from_time"] == 0.0
    assert later["mce"] == pytest.approx(score_run(loop.curve, run, 0.3).mce, rel=1e-12)
    assert later["tracking_max_by_axis"].keys() == {"x", "y"} and later["units"]["mce"] == "m"
    bad = subprocess.run(cli + ["--from", "9"], capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "no samples at t >= 9" in bad.stderr


# --------------------------------------------------------------------------------------- regime maps


def test_a_regime_map_is_the_ratio_of_the_two_runs_cell_by_cell(tmp_path, monkeypatch):
    claim = Claim(paper="000", id="test", claim="", paper_figure="", paper_ratio=0.5, metric="tace", from_time=0.1,
                  faithful=Pair("paper000_b_ismc_h50_newton", "paper000_b_ismc_h50_vgccc"), mechanism=None,
                  expected={}, verdict={}, reason="")
    spec = RegimeMap("faithful", MapAxis("T", ("schedule.duration", "duration"), (0.3, 0.4)),
                     MapAxis("h", ("curve.h",), (50.0, 200.0)))
    ratios = map_ratios(claim, spec, workers=1)
    assert ratios["tace"].shape == (2, 2)
    from contouring_ros.claims import _experiment
    for j, h in enumerate((50.0, 200.0)):
        for i, duration in enumerate((0.3, 0.4)):
            settings = {"schedule.duration": duration, "duration": duration, "curve.h": h}
            tace = []
            for name in (claim.faithful.proposed, claim.faithful.baseline):
                loop = build_loop(_experiment(name, settings))
                tace.append(score_run(loop.curve, simulate(loop), 0.1).tace)
            assert ratios["tace"][j, i] == pytest.approx(tace[0] / tace[1], rel=1e-9)
    png = draw_map(claim, spec, ratios, tmp_path / "maps" / "map.png")
    assert png.stat().st_size > 10000


def test_a_claims_file_with_a_mistake_is_refused_naming_the_key(tmp_path):
    path = tmp_path / "paper009.yaml"
    path.write_text('paper: "009"\ntitle: t\nreadings: []\nclaims:\n  - id: a\n    claim: c\n    paper_figure: f\n'
                    '    paper_ratio: 0.5\n    metric: tace_um\n    faithful: null\n    expected: {}\n'
                    '    verdict: {}\n    reason: r\n')
    with pytest.raises(ConfigError, match=r"paper009.yaml: claims\[0\].metric: expected one of mce"):
        load_claims(path)
    path.write_text(path.read_text().replace("tace_um", "tace").replace("faithful: null",
                                                                         "faithful: {proposed: nope, baseline: x}"))
    with pytest.raises(ConfigError, match=r"claims\[0\].faithful.proposed: no scenario file config/nope.yaml"):
        load_claims(path)
