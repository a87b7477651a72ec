"""Per-step export, and --experiment refused for a bag it did not produce."""
import csv
import subprocess
import sys

import numpy as np
import pytest

from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.config import build_loop, load_experiment, parse_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import BagError
from contouring_ros.records.export import export_bag
from contouring_ros.records.scoring import score_bag, score_run
from conftest import CONFIG, DEFAULT, ROOT, cli_with_file_size_limit, shortened


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    experiment = parse_experiment(shortened(DEFAULT, 0.3), "default")
    loop = build_loop(experiment)
    result = simulate(loop)
    path = write_simulation(tmp_path_factory.mktemp("bags") / "short.mcap", experiment, result)
    return path, result, score_run(loop.curve, result)


def test_export_writes_every_signal_of_every_step_with_units(bag, tmp_path):
    path, result, scores = bag
    written, warnings = export_bag(path, csv_dir=tmp_path)
    assert written == [tmp_path / "short.csv"] and not warnings
    with open(written[0]) as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == len(result.time) == 301
    assert {"time_s", "theta", "position_x_m", "position_y_m", "reference_velocity_y_m_s", "command_x",
            "correction_y", "estimate_signed_m", "exact_contour_error_m"} <= set(rows[0])
    np.testing.assert_array_equal([float(r["position_y_m"]) for r in rows], result.position[:, 1])   # repr: exact
    exact = np.array([float(r["exact_contour_error_m"]) for r in rows])
    assert exact.max() == pytest.approx(scores.mce, rel=1e-12) and exact.mean() == pytest.approx(scores.tace, rel=1e-12)


def test_export_command(bag, tmp_path):
    path, _, _ = bag
    out = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "export", str(path), "--csv", str(tmp_path)],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0 and out.stdout.strip() == str(tmp_path / "short.csv")
    none = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "export", str(path)], capture_output=True,
                          text=True, cwd=ROOT)
    assert none.returncode == 2 and none.stderr.count("\n") == 1 and "--csv" in none.stderr


def test_experiment_of_another_curve_or_other_axes_is_refused(bag):
    path, _, scores = bag
    same = load_experiment(DEFAULT).text
    assert score_bag(path, same)[0].mce == scores.mce
    with pytest.raises(BagError, match=r"/reference is not on the curve of --experiment paper000_b_ismc_h100_newton"):
        score_bag(path, (CONFIG / "paper000_b_ismc_h100_newton.yaml").read_text())
    with pytest.raises(BagError, match="has axes x, y, z; the bag has x, y"):
        score_bag(path, (CONFIG / "paper004_saddle_eso.yaml").read_text())


@pytest.mark.parametrize("command", ["export", "plot"])
def test_a_full_disk_gives_one_line_and_leaves_no_truncated_file(bag, tmp_path, command):
    path, _, _ = bag
    out = tmp_path / "out"
    args = ["export", str(path), "--csv", str(out)] if command == "export" else ["plot", str(path), "--out", str(out)]
    done = cli_with_file_size_limit(args, 4096, ROOT)
    assert done.returncode != 0
    assert "Traceback" not in done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and str(out) in errors[0] and "cannot write it" in errors[0], done.stderr
    assert not [p for p in out.iterdir() if p.stat().st_size >= 4096 or p.suffix in (".csv", ".png")] \
        if out.exists() else True
    assert not list(out.glob(".*.part")) if out.exists() else True


def test_plot_out_naming_an_existing_file_is_refused_in_one_line_and_the_file_kept(bag, tmp_path):
    path, _, _ = bag
    existing = tmp_path / "notes.txt"
    existing.write_text("mine")
    done = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "plot", str(path), "--out", str(existing)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode != 0 and "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines()[-1].startswith(f"error: --out {existing}: a file of that name exists")
    assert existing.read_text() == "mine"


def test_an_export_that_fails_keeps_the_whole_file_already_there(bag, tmp_path):
    path, _, _ = bag
    out = tmp_path / "out"
    out.mkdir()
    (out / "short.csv").write_text("a whole earlier export\n")
    done = cli_with_file_size_limit(["export", str(path), "--csv", str(out)], 4096, ROOT)
    assert done.returncode != 0 and "Traceback" not in done.stderr
    assert (out / "short.csv").read_text() == "a whole earlier export\n"
    assert sorted(p.name for p in out.iterdir()) == ["short.csv"]
