"""Parameter sweeps over the in-process simulation."""
import csv

import pytest
import yaml

from contouring_ros.config import build_loop, parse_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import ConfigError
from contouring_ros.records.scoring import score_run
from contouring_ros.studies.sweep import run_sweep, write_sweep_csv
from contouring_ros.experiment.settings import parse_grid
from conftest import DEFAULT, cli_with_file_size_limit, shortened


def test_sweep_ranks_every_combination_and_matches_single_runs(tmp_path):
    text = shortened(DEFAULT, 0.3)
    grid = parse_grid(["ccc.kp=0.5,4", "x/servo.kappa=0.2985,0.5"])
    rows = run_sweep(text, grid, workers=2)
    assert len(rows) == 4
    assert [r.scores.mce for r in rows] == sorted(r.scores.mce for r in rows)
    best = rows[0]
    data = yaml.safe_load(text)            # the best combination written by hand, run on its own
    data["/ccc"]["ros__parameters"]["kp"] = best.settings["ccc.kp"]
    data["/x/servo"]["ros__parameters"]["kappa"] = best.settings["x/servo.kappa"]
    loop = build_loop(parse_experiment(yaml.safe_dump(data), "one"))
    assert score_run(loop.curve, simulate(loop)) == best.scores
    path = tmp_path / "sweep.csv"
    write_sweep_csv(rows, path)
    table = list(csv.reader(path.open()))
    assert table[0][:3] == ["rank", "ccc.kp", "x/servo.kappa"] and len(table) == 5


def test_sweep_refuses_an_invalid_combination_naming_it():
    with pytest.raises(ConfigError, match=r"ccc.kp.*-1.*expected a value >= 0"):
        run_sweep(shortened(DEFAULT, 0.1), parse_grid(["ccc.kp=1,-1"]), workers=1)


@pytest.mark.parametrize("spec", ["ccc.kp", "=1,2", "ccc.kp="])
def test_malformed_grid(spec):
    with pytest.raises(ConfigError, match="expected key=value1,value2"):
        parse_grid([spec])


def test_grid_values_are_read_like_the_experiment_file():
    # exponent floats without a dot are numbers, as in the YAML files (YAML 1.2, the ROS parser)
    assert parse_grid(["x/servo.kd=7e5,1.5e-4,2,true"]) == {"x/servo.kd": [7e5, 1.5e-4, 2, True]}


def test_a_sweep_csv_that_cannot_be_written_leaves_the_earlier_file_whole(tmp_path):
    """Reports and tables are written beside their path and renamed (errors.write_atomically): a full disk
    (here RLIMIT_FSIZE: every write past 300 bytes fails, as ENOSPC does) gives one line and keeps what was there."""
    experiment = tmp_path / "short.yaml"
    experiment.write_text(shortened(DEFAULT, 0.02))
    out = tmp_path / "sweep.csv"
    earlier = "rank,ccc.kp,status,mce_m\n1,1,ok,0.001\n"        # a whole earlier sweep's table
    out.write_text(earlier)
    done = cli_with_file_size_limit(["sweep", str(experiment), "--grid", "ccc.kp=1,2", "--out", str(out)], 300)
    assert done.returncode != 0 and "Traceback" not in done.stderr, done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and str(out) in errors[0] and "cannot write it" in errors[0], done.stderr
    assert out.read_text() == earlier
    assert sorted(p.name for p in tmp_path.iterdir()) == ["short.yaml", "sweep.csv"]


def test_a_newton_group_smaller_than_its_batch_minimum_runs_one_by_one_with_the_batch_s_results(monkeypatch):
    """The Newton estimate's batch iterates until its slowest member converges, at a cost per step that hardly
    depends on the batch size: below NewtonEstimator.batch_minimum members the runs go one by one (the row
    says why), and give what the batch gives, bit for bit. The minimum is lower where the kernel runs
    compiled (it iterates member by member), and only the speed depends on it."""
    from contouring_ros.core.batch import batch_minimum
    from contouring_ros.core.estimators import NewtonEstimator
    from contouring_ros.studies.sweep import experiments_for, simulate_experiments
    experiments = [e for _, e in experiments_for(shortened(DEFAULT, 0.2), [{"ccc.kp": kp} for kp in (0.5, 1.0, 2.0)])]
    loop = build_loop(experiments[0])
    minimum, setter = batch_minimum(loop)
    assert (minimum, setter) == (loop.estimator.batch_minimum, "NewtonEstimator")
    assert minimum in (NewtonEstimator.PURE_BATCH_MINIMUM, NewtonEstimator.COMPILED_BATCH_MINIMUM) and minimum > 3
    _, alone, alone_why, failures = simulate_experiments(experiments)
    assert failures == ["", "", ""]
    assert all(f"pays off from {minimum}" in why for why in alone_why), alone_why
    monkeypatch.setattr(NewtonEstimator, "PURE_BATCH_MINIMUM", 2)
    monkeypatch.setattr(NewtonEstimator, "COMPILED_BATCH_MINIMUM", 2)
    _, batch, batch_why, _ = simulate_experiments(experiments)
    assert batch_why == ["", "", ""]
    for a, b in zip(alone, batch):
        for name in ("position", "command", "estimate_vector", "theta"):
            assert (getattr(a, name) == getattr(b, name)).all(), name


def test_a_class_without_a_batch_minimum_batches_from_two_members():
    from contouring_ros.core.batch import batch_minimum
    from contouring_ros.studies.sweep import experiments_for
    _, experiment = experiments_for(shortened(DEFAULT.parent / "paper000_mech_lag_tangent_uv.yaml", 0.1), [{}])[0]
    assert experiment.estimator["type"] == "tangent_line"
    assert batch_minimum(build_loop(experiment)) == (2, None)


def test_the_sweep_s_progress_counts_every_simulated_step():
    """The progress bar moves with the steps the workers simulate (every 256 steps of a run, every 256 steps
    times the members of a batch), and a chunk tops up what its diverged runs did not take, so that the count
    ends at every combination's steps exactly."""
    import multiprocessing

    from contouring_ros.core import progress
    from contouring_ros.core.batch import simulate_batch
    from contouring_ros.core.simulation import simulate
    from contouring_ros.studies.sweep import _score_chunk, experiments_for
    experiments = [e for _, e in experiments_for(shortened(DEFAULT, 0.6), [{"ccc.kp": kp} for kp in (1.0, 2.0, 1e9)])]
    counter = multiprocessing.Value("q", 0)
    progress.attach(counter)
    try:
        simulate(build_loop(experiments[0]))                       # 601 steps: two additions of 256
        assert counter.value == 512
        simulate_batch([build_loop(e) for e in experiments[:2]])   # two members
        assert counter.value == 512 + 2 * 512
        counter.value = 0
        scores, _, failures = _score_chunk(experiments)            # kp = 1e9 diverges at once
        assert scores[2] is None and failures[2]
        assert counter.value == sum(e.n_steps for e in experiments) == 3 * 601
    finally:
        progress.attach(None)


def test_the_sweep_s_summary_speaks_of_combinations_not_chunks():
    from contouring_ros.studies.sweep import SweepRow, sweep_summary
    why = "runs faster one by one: a batch with the NewtonEstimator pays off from 12 combinations of one kind"
    rows = [SweepRow({"ccc.kp": k}, object(), why) for k in range(6)]
    assert sweep_summary(rows, 4.24, 2) == f"6 combinations in 4.2 s on 2 processes: all run one by one ({why})"
    mixed = [SweepRow({}, object()), SweepRow({}, object()), SweepRow({}, None, "no batch path", "diverged at ...")]
    assert sweep_summary(mixed, 1.0, 1) == ("3 combinations in 1.0 s on 1 process: 2 run together in vectorised "
                                            "batches, 1 one by one (no batch path)\n"
                                            "1 without scores (diverged), listed last with the reason")
