"""Memory bounded by construction: a sweep grid is counted before any combination is made, a part program
is counted before any block is read, a learned correction is read only as far as the run plays it back,
and a long run's reference is not kept step by step past a stated count."""
import tracemalloc

import numpy as np
import pytest

from contouring_ros.studies import sweep
from contouring_ros.cli import main
from contouring_ros.config import build_loop, parse_experiment
from contouring_ros.core import gcode
from contouring_ros.core.interpolation import ReferenceTable
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import ConfigError
from contouring_ros.experiment.catalogue import curves as curve_catalogue
from contouring_ros.experiment.catalogue.controllers import load_learned
from contouring_ros.experiment.files import load_experiment
from contouring_ros.experiment.schema import MAX_STEPS

from conftest import CONFIG, DEFAULT, shortened


def test_a_grid_of_a_trillion_combinations_is_refused_before_any_is_made(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sweep, "experiments_for", lambda *a: pytest.fail("combinations were made"))
    grid = {f"key{i}": list(range(100)) for i in range(6)}
    tracemalloc.start()
    with pytest.raises(ConfigError, match=r"^--grid: 100 x 100 x 100 x 100 x 100 x 100 = 1e\+12 combinations, over "
                                          f"the {sweep.MAX_COMBINATIONS} a sweep runs"):
        sweep.combinations(DEFAULT.read_text(), grid)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 1_000_000
    (tmp_path / "e.yaml").write_text(shortened(DEFAULT, 0.02))
    specs = [f"--grid=ccc.k{i}={','.join(str(v) for v in range(100))}" for i in range(6)]
    assert main(["sweep", str(tmp_path / "e.yaml"), *specs, "--out", str(tmp_path / "s.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "combinations, over the" in err and not (tmp_path / "s.csv").exists()


def test_a_part_program_over_the_stated_lines_is_refused_before_a_block_is_read(tmp_path, monkeypatch):
    monkeypatch.setattr(curve_catalogue, "MAX_PROGRAM_LINES", 50)
    monkeypatch.setattr(gcode, "parse_program", lambda *a, **k: pytest.fail("the program was parsed"))
    (tmp_path / "long.ngc").write_text("G21 G90 G17 F600\n" + "".join(f"G1 X{i % 2} Y{i}\n" for i in range(60)))
    text = (CONFIG / "gcode_example_part.yaml").read_text().replace("parts/example_part.ngc", "long.ngc")
    (tmp_path / "e.yaml").write_text(text)
    with pytest.raises(ConfigError, match="long.ngc: 61 lines, over the 50 a part program may have"):
        load_experiment(tmp_path / "e.yaml")


def test_a_learned_correction_is_converted_only_as_far_as_the_run_plays_it(tmp_path):
    path = tmp_path / "learned.npy"
    table = np.lib.format.open_memmap(path, mode="w+", dtype=np.int8, shape=(4_000_000, 2))
    table[:] = 3
    del table
    tracemalloc.start()
    read = load_learned(path, "e.yaml", 2, steps=1000)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert read.shape == (1000, 2) and read.dtype == float and np.all(read == 3.0)
    assert peak < 1_000_000                # a float64 copy of the whole file would be 64 MB
    huge = tmp_path / "huge.npy"
    np.lib.format.open_memmap(huge, mode="w+", dtype=np.int8, shape=(MAX_STEPS + 1, 1))
    with pytest.raises(ConfigError, match=f"holds {MAX_STEPS + 1} steps, more than the {MAX_STEPS}"):
        load_learned(huge, "e.yaml", 1)


def test_a_long_run_keeps_its_reference_only_up_to_the_stated_steps_and_gives_the_same_numbers(monkeypatch):
    import dataclasses
    monkeypatch.setattr(ReferenceTable, "KEPT_STEPS", 100)
    experiment = parse_experiment(shortened(DEFAULT, 0.3).replace("h: 50.0", "h: 51.0"), "short")   # a path of its own
    loop = build_loop(experiment)
    bounded = simulate(loop)
    assert len(loop.reference_table._steps) == 100 and len(bounded.time) == 301
    computed = simulate(dataclasses.replace(build_loop(experiment), reference_table=None))   # each step computed
    for name in ("reference_position", "position", "command", "estimate_vector"):
        assert np.array_equal(getattr(bounded, name), getattr(computed, name)), name        # bit for bit
