"""Cross-coupled iterative learning control (core/ilc.py, studies/learning.py): the learning law on known inputs, the
error falling pass by pass on a repeated ellipse (and rising with the learning gain's sign flipped), a batch
of different corrections as each alone, and a learned file that cannot be used refused in one line."""
import numpy as np
import pytest

from contouring_ros.core.batch import simulate_batch
from contouring_ros.core.ilc import LearnedCorrection, learn
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import ConfigError
from contouring_ros.experiment.build import build_loop
from contouring_ros.experiment.validate import parse_experiment
from contouring_ros.studies.learning import next_correction, pass_settings, simulate_last_passes, simulate_passes
from contouring_ros.records.scoring import score_run
from conftest import CONFIG, shortened

TS = 1e-3


def _ellipse(duration=0.5, passes=4, **keys):
    text = shortened(CONFIG / "ilc_ellipse.yaml", duration).replace("passes: 8", f"passes: {passes}")
    for key, value in keys.items():
        text = text.replace(f"    {key}: ", f"    {key}: {value}  # was ", 1)
    return parse_experiment(text, "ilc_ellipse.yaml")


def test_the_law_adds_the_errors_lead_steps_ahead_to_the_last_correction():
    steps = 50
    reference = np.zeros((steps, 2))
    position = np.column_stack([np.arange(steps) * 1e-6, -np.arange(steps) * 2e-6])       # e = -position
    contour = np.column_stack([np.full(steps, 3e-6), np.zeros(steps)])
    previous = np.ones((steps, 2))
    out = learn(previous, reference, position, contour, TS, gamma_tracking=2.0, gamma_contour=5.0, lead=3)
    k = np.arange(steps - 3)
    np.testing.assert_allclose(out[k, 0], 1.0 - 2.0 * (k + 3) * 1e-6 + 5.0 * 3e-6, rtol=0, atol=1e-15)
    np.testing.assert_allclose(out[k, 1], 1.0 + 2.0 * 2 * (k + 3) * 1e-6, rtol=0, atol=1e-15)
    last = [1.0 - 2.0 * 49e-6 + 5.0 * 3e-6, 1.0 + 2.0 * 2 * 49e-6]         # the last error, held
    np.testing.assert_allclose(out[-3:], [last] * 3, rtol=0, atol=1e-15)


def test_the_q_filter_passes_the_slow_part_without_phase_and_stops_the_fast_part():
    steps = 4000
    t = np.arange(steps) * TS
    slow, fast = np.sin(2 * np.pi * 2.0 * t), np.sin(2 * np.pi * 200.0 * t)
    error = np.column_stack([slow + fast, np.zeros(steps)])
    out = learn(None, error, np.zeros((steps, 2)), np.zeros((steps, 2)), TS, 1.0, 0.0, lead=0, q_cutoff=20.0)
    middle = slice(500, 3500)
    assert np.max(np.abs(out[middle, 0] - slow[middle])) < 0.01       # 2 Hz: unchanged, no lag; 200 Hz: gone


def _tace_per_pass(experiment):
    return [score_run(loop.curve, result).tace for loop, result in simulate_passes(experiment)]


def test_the_contour_error_falls_pass_by_pass_on_a_repeated_ellipse():
    tace = _tace_per_pass(_ellipse())
    assert all(later < earlier for earlier, later in zip(tace, tace[1:])), tace
    assert tace[-1] < 0.5 * tace[0], tace


def test_a_flipped_learning_gain_makes_it_rise(monkeypatch):
    import contouring_ros.studies.learning as learning
    def flipped(correction, reference, position, estimate, ts, gamma_tracking, gamma_contour, lead, q_cutoff):
        return learn(correction, reference, position, estimate, ts, -gamma_tracking, -gamma_contour, lead, q_cutoff)
    monkeypatch.setattr(learning, "learn", flipped)
    tace = _tace_per_pass(_ellipse(passes=3))
    assert tace[-1] > tace[0], tace


def test_each_pass_meets_noise_of_its_own_and_the_first_is_the_file_as_it_is():
    text = shortened(CONFIG / "ilc_ellipse.yaml", 0.05).replace("passes: 8", "passes: 3").replace(
        "    time_constant: 0.040\n", "    time_constant: 0.040\n    measurement_noise: 1.0e-6\n"
        "    disturbance: {type: random, std: 0.01, seed: 3}\n")
    experiment = parse_experiment(text, "ilc_ellipse.yaml")
    assert pass_settings(experiment, 1) == {}
    assert pass_settings(experiment, 3)["x/plant.noise_seed"] != pass_settings(experiment, 2)["x/plant.noise_seed"]
    assert pass_settings(experiment, 2)["x/plant.disturbance.seed"] != 3
    # a seed near the top of the range wraps within it (the graph path validates what it writes)
    top = parse_experiment(text.replace("seed: 3}", "seed: 4294967295}"), "ilc_ellipse.yaml")
    assert 0 <= pass_settings(top, 1000)["x/plant.disturbance.seed"] <= 2 ** 32 - 1
    runs = simulate_passes(experiment)
    alone = simulate(build_loop(experiment))
    np.testing.assert_array_equal(runs[0][1].position, alone.position)
    # the noise table each pass's x plant reads, and its random disturbance's seed
    tables = [loop.plants[0]._noise for loop, _ in runs]
    assert not np.array_equal(tables[0], tables[1]) and not np.array_equal(tables[1], tables[2])
    assert len({loop.plants[0].disturbance.seed for loop, _ in runs}) == 3


def test_the_api_gives_a_run_per_pass_and_its_first_is_simulate():
    import contouring_ros as cr
    text = shortened(CONFIG / "ilc_ellipse.yaml", 0.3).replace("passes: 8", "passes: 3")
    experiment = parse_experiment(text, "ilc_ellipse.yaml")
    runs = cr.simulate_passes(experiment)
    tace = [run.scores().tace for run in runs]
    assert len(runs) == 3 and tace[2] < tace[1] < tace[0], tace
    np.testing.assert_array_equal(runs[0].result.position, cr.simulate(experiment).result.position)
    other = parse_experiment(shortened(CONFIG / "paper000_b_ismc_h50_newton.yaml", 0.05), "h50.yaml")
    assert len(cr.simulate_passes(other)) == 1


def test_a_batch_of_different_corrections_gives_each_run_alone_bit_for_bit():
    experiment = _ellipse(duration=0.2)
    first = build_loop(experiment)
    result = simulate(first)
    learned = next_correction(experiment, result, None)
    tables = [np.zeros_like(learned), learned, 2.0 * learned]       # one length: the passes of one experiment

    def loop_with(table):
        loop = build_loop(experiment)
        loop.controller.table = table
        return loop
    batch = simulate_batch([loop_with(table) for table in tables])
    for table, batched in zip(tables, batch):
        alone = simulate(loop_with(table))
        np.testing.assert_array_equal(batched.position, alone.position)
        np.testing.assert_array_equal(batched.correction, alone.correction)


def test_learning_experiments_run_together_pass_by_pass_as_each_runs_alone():
    """simulate_last_passes (the benchmark's tuning of ILC gains): the experiments' passes advance as one
    batch, each learning from its own pass, and each last pass equals its experiment's own passes; a member
    whose learning diverges ends with the pass it diverged in, the others unharmed."""
    gains = [1.0, 2.0, 0.5]
    experiments = [_ellipse(duration=0.2, passes=3, gamma_contour=g) for g in gains]
    diverging = _ellipse(duration=0.2, passes=3, gamma_contour=1e9)
    last = simulate_last_passes(experiments[:2] + [diverging] + experiments[2:])
    assert [len(loop.controller.table) > 0 for loop, _, _ in last] == [True] * 4     # every one played a table
    for experiment, (loop, result, failure) in zip(experiments, last[:2] + last[3:]):
        alone_loop, alone = simulate_passes(experiment)[-1]
        assert failure == "" and result is not None
        np.testing.assert_array_equal(result.position, alone.position)
        np.testing.assert_array_equal(loop.controller.table, alone_loop.controller.table)
    loop, result, failure = last[2]
    assert result is None and failure.startswith("diverged at t = ")
    tace = [score_run(loop.curve, result).tace for loop, result, _ in last[:2] + last[3:]]
    first = [score_run(loop.curve, simulate(build_loop(e))).tace for e in experiments]
    assert all(after < before for after, before in zip(tace, first)), (tace, first)     # they learned


def test_a_learned_file_that_cannot_be_used_is_refused_in_one_line(tmp_path):
    bad = tmp_path / "learned.npy"
    np.save(bad, np.zeros((10, 3)))
    text = shortened(CONFIG / "ilc_ellipse.yaml", 0.05).replace("    passes: 8", f"    passes: 8\n    learned_file: {bad}")
    with pytest.raises(ConfigError, match=r"/ccc\.learned_file: .* holds a \(10, 3\) float64 array, expected .* 2 axes"):
        build_loop(parse_experiment(text, "ilc.yaml"))
    for name, write in (("missing.npy", None), ("text.npy", lambda p: p.write_text("0.1, 0.2\n")),
                        ("empty.npy", lambda p: p.write_bytes(b"")),
                        ("archive.npz", lambda p: np.savez(p, np.zeros((10, 2)))),
                        ("words.npy", lambda p: np.save(p, np.array([["a", "b"]])))):
        if write is not None:
            write(tmp_path / name)
        given = text.replace(str(bad), str(tmp_path / name))
        with pytest.raises(ConfigError, match=r"^ilc\.yaml: /ccc\.learned_file: '.*' (is not|holds)") as raised:
            build_loop(parse_experiment(given, "ilc.yaml"))
        assert "\n" not in str(raised.value) and "allow_pickle" not in str(raised.value), name


def test_a_correction_plays_back_row_by_row_then_zeros():
    controller = LearnedCorrection(2, np.array([[1.0, 2.0], [3.0, 4.0]]))
    assert [list(controller.step(None)) for _ in range(3)] == [[1.0, 2.0], [3.0, 4.0], [0.0, 0.0]]
