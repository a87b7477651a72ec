"""Figures and the HTML report of recorded runs: 2- and 3-axis runs together, one colour and one name per run
in every figure, runs that diverged or recorded (almost) nothing."""
import html
from dataclasses import replace

import numpy as np
import pytest
from conftest import CONFIG, DEFAULT, shortened

from contouring_ros.records.bag import RecordedRun
from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.records.comparison import run_names
from contouring_ros.records.figures import figures
from contouring_ros.records.html_report import html_report
from contouring_ros.cli import main
from contouring_ros.config import build_loop, parse_experiment
from contouring_ros.core.simulation import simulate
from contouring_ros.records.scoring import read_run, score_run

FIGURES = ["path", "error_map", "contour_error", "estimate", "tracking", "effort"]
PLANAR, SPATIAL = "paper000_b_ismc_h50_newton", "paper004_saddle_eso"


def _bag(path, text):
    experiment = parse_experiment(text, "experiment")
    loop = build_loop(experiment)
    result = simulate(loop)
    return write_simulation(path, experiment, result), score_run(loop.curve, result)


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    """A 2-axis and a 3-axis run, 0.3 s each, as bags named unlike their experiments."""
    folder = tmp_path_factory.mktemp("bags")
    return [_bag(folder / "first_bag.mcap", shortened(DEFAULT, 0.3)),
            _bag(folder / "second_bag.mcap", shortened(CONFIG / f"{SPATIAL}.yaml", 0.3))]


@pytest.fixture(scope="module")
def drawn(bags):
    runs = [(path.stem, read_run(path)) for path, _ in bags]
    return runs, figures(runs)


def _run_of(label: str, names: list):
    return next((name for name in names if label == name or label.startswith(name + " ")), None)


def test_plot_writes_every_figure_and_a_report_with_ratios_and_experiments(bags, tmp_path):
    import matplotlib.image
    (first, _), (second, _) = bags
    out = tmp_path / "figures"
    assert main(["plot", str(first), str(second), "--out", str(out), "--html", "--baseline", str(second)]) == 0
    for name in FIGURES:
        pixels = matplotlib.image.imread(out / f"{name}.png")
        assert pixels.std() > 0.05, name              # not a blank canvas
    page = (out / "report.html").read_text()
    assert page.count("data:image/png;base64,") == len(FIGURES)
    assert "src=\"http" not in page and "<link" not in page            # self-contained
    ratios = page.split(f"Ratios to {SPATIAL}")[1].split("</table>")[0]  # the baseline named by --baseline
    assert "<td>MCE</td>" in ratios and "<td>TACE</td>" in ratios and ratios.count("<tr>") == 6
    assert ">tracking error max z [um]<" in page                        # per-axis rows by axis name
    for path in (first, second):
        text = read_run(path).experiment_text
        assert f"<pre>{html.escape(text)}</pre>" in page
    assert page.count("<details>") == 2
    differences = page.split("<h2>Differences</h2>")[1].split("</table>")[0]     # how the experiments differ
    assert (f"<td><code>axes</code></td><td>{html.escape(str(['x', 'y', 'z']))}</td>"      # the baseline first
            f"<td>{html.escape(str(['x', 'y']))}</td>") in differences
    assert "<code>sample_time</code>" not in differences                       # the same in both


def test_three_axis_run_gets_a_3d_path_beside_the_planar_one(drawn):
    _, figs = drawn
    assert sorted(figs) == sorted(FIGURES)
    path_axes = figs["path"].axes
    assert sum(ax.name == "3d" for ax in path_axes) == 1
    labels = {(ax.get_xlabel(), ax.get_ylabel()) for ax in path_axes}
    assert {("x [mm]", "y [mm]"), ("x [mm]", "z [mm]"), ("y [mm]", "z [mm]")} <= labels
    assert any(ax.name == "3d" for ax in figs["error_map"].axes)
    rows = [ax.get_ylabel() for ax in figs["tracking"].axes]
    assert rows == ["x tracking error [um]", "y tracking error [um]", "z tracking error [um]"]


def test_each_run_has_one_colour_and_its_experiment_name_in_every_figure(drawn):
    from matplotlib.colors import to_hex
    runs, figs = drawn
    names = run_names(runs)
    assert names == [PLANAR, SPATIAL]                    # from the bags' experiments, not the file names
    colours = {name: set() for name in names}
    for figure_name, fig in figs.items():
        seen = set()
        for ax in fig.axes:
            for line in ax.get_lines():
                run = _run_of(line.get_label(), names)
                if run:
                    colours[run].add(to_hex(line.get_color()))
                    seen.add(run)
            run = _run_of(ax.get_title().split("\n")[0], names)
            if figure_name == "error_map" and run:     # coloured by error: the run is named in its colour
                colours[run].add(to_hex(ax.title.get_color()))
                seen.add(run)
        assert seen == set(names), figure_name
        if fig.legends:
            assert set(names) <= {text.get_text() for text in fig.legends[0].get_texts()}, figure_name
    assert all(len(c) == 1 for c in colours.values()), colours
    assert colours[PLANAR] != colours[SPATIAL]


def test_runs_of_one_experiment_get_distinct_names(drawn):
    runs, _ = drawn
    run = runs[0][1]
    assert run_names([(f"{PLANAR}_20250101_120000", run), (f"{PLANAR}_20250102_080000", run)]) == [
        f"{PLANAR} (20250101_120000)", f"{PLANAR} (20250102_080000)"]
    assert run_names([("a", run), ("a", run)]) == [f"{PLANAR} #1", f"{PLANAR} #2"]


def _cut(run: RecordedRun, steps: int) -> RecordedRun:
    return replace(run, result=replace(run.result, **{k: v[:steps].copy() for k, v in vars(run.result).items()}))


def test_runs_with_no_steps_one_step_or_huge_values_still_plot(bags, tmp_path):
    (path, scores), _ = bags
    run = read_run(path)
    blown = _cut(run, len(run.result.time))
    blown.result.position[50:, 0] = np.linspace(0.0, 1e3, len(run.result.time) - 50)   # 1 km off the path
    blown.result.position[-3:] = [[np.inf, np.nan]] * 3
    blown.result.command[-10:, 1] = 1e300
    runs = [("good", run), ("zero", _cut(run, 0)), ("one", _cut(run, 1)), ("blown", blown)]
    figs = figures(runs)
    assert sorted(figs) == sorted(FIGURES)
    report = html_report(runs, [scores, None, None, None], tmp_path / "report.html", drawn=figs)
    page = report.read_text()
    assert page.count("data:image/png;base64,") == len(FIGURES)
    titles = [ax.get_title() for ax in figs["error_map"].axes]
    assert f"{PLANAR} (zero)\nno steps recorded" in titles       # four runs of one experiment, told apart
    assert f"{PLANAR} (blown)" in page
    x_tracking = figs["tracking"].axes[0]                          # the good run is not flattened by it
    assert x_tracking.get_ylim()[1] < 100.0
    assert [text.get_text() for text in x_tracking.texts] == [f"off scale: {PLANAR} (blown)"]


def test_error_maps_of_compared_runs_share_one_colour_scale(bags):
    """Every panel of the error map has the same colour scale (one colour bar), so runs and ILC passes are
    compared by eye: linear where the runs' largest errors are within tenfold, else logarithmic down to a
    tenth of the smallest of them."""
    from matplotlib.colors import LogNorm
    (path, _), _ = bags
    run = read_run(path)
    worse = _cut(run, len(run.result.time))
    worse.result.position[:] = worse.result.reference_position + 3e-6 * (worse.result.position
                                                                         - worse.result.reference_position) / 1e-7
    for pair, logarithmic in (([("a", run), ("b", run)], False), ([("a", run), ("worse", worse)], True)):
        fig = figures(pair)["error_map"]
        maps = [c for ax in fig.axes if ax.get_label() != "<colorbar>" for c in ax.collections
                if c.get_array() is not None]
        assert len(maps) == 2 and maps[0].norm is maps[1].norm
        bars = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
        assert len(bars) == 1
        norm = maps[0].norm
        assert isinstance(norm, LogNorm) == logarithmic
        largest = [float(np.nanmax(c.get_array())) for c in maps]
        assert norm.vmax == pytest.approx(max(largest), rel=0.05)
        if logarithmic:
            assert norm.vmin == pytest.approx(min(largest) / 10.0, rel=0.05)
