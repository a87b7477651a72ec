"""Outputs never destroy what a user owns: an input of the command, a file of another kind (without --force),
one output over another, a destination that cannot be written: each is one line and a non-zero exit, before
any work, and every file that was there is as it was."""
import pytest

from contouring_ros.records import outputs
from contouring_ros.cli import main
from contouring_ros.errors import OutputError
from contouring_ros.records.outputs import write_atomically

from conftest import DEFAULT, recorded_bag, shortened


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "short.yaml").write_text(shortened(DEFAULT, 0.05))
    (tmp_path / "notes.txt").write_text("a user's notes\n")
    return tmp_path


def _refused(capsys, argv, *phrases):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "Traceback" not in err, err
    for phrase in phrases:
        assert phrase in err, err
    return err


def _state(folder) -> dict:
    return {p.name: p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize("bag, phrase", [
    ("notes.txt", "--bag notes.txt: exists and is not an MCAP bag"),
    ("short.yaml", "--bag short.yaml: an input of this command"),
    ("a_folder", "--bag a_folder: a folder"),
    ("notes.txt/run.mcap", "notes.txt is a file, not a folder"),
    ("/proc/run.mcap", "--bag /proc/run.mcap: cannot be written in /proc"),
])
def test_run_never_deletes_what_is_at_its_bag_path(folder, capsys, bag, phrase):
    (folder / "a_folder").mkdir()
    before = _state(folder)
    _refused(capsys, ["run", "short.yaml", "--composed", "--bag", bag], phrase)
    assert _state(folder) == before


def test_export_never_writes_over_its_input_nor_one_table_over_another(folder, capsys):
    _, bag, data, _ = recorded_bag(folder, 0.05, "run.csv")            # a bag whose name ends in .csv
    _refused(capsys, ["export", "run.csv", "--csv", "."], "--csv run.csv: an input of this command")
    assert bag.read_bytes() == data
    (folder / "a").mkdir()
    (folder / "b").mkdir()
    recorded_bag(folder / "a", 0.05, "s.mcap")
    recorded_bag(folder / "b", 0.05, "s.mcap")
    _refused(capsys, ["export", "a/s.mcap", "b/s.mcap", "--csv", "tables"], "two outputs of this command would share")
    assert not (folder / "tables").exists()
    (folder / "tables").mkdir()
    (folder / "tables" / "s.csv").write_text("my,own,table\n1,2,3\n")
    _refused(capsys, ["export", "a/s.mcap", "--csv", "tables"], "exists and is not an exported table")
    assert (folder / "tables" / "s.csv").read_text() == "my,own,table\n1,2,3\n"
    assert main(["export", "a/s.mcap", "--csv", "tables", "--force"]) == 0
    assert (folder / "tables" / "s.csv").read_text().startswith("time_s,")
    assert main(["export", "a/s.mcap", "--csv", "tables"]) == 0          # its own table again: replaced


def test_sweep_never_replaces_its_experiment_or_a_file_of_another_kind(folder, capsys):
    before = _state(folder)
    grid = ["--grid", "ccc.kp=1,2", "--workers", "1"]
    _refused(capsys, ["sweep", "short.yaml", *grid, "--out", "short.yaml"], "--out short.yaml: an input")
    _refused(capsys, ["sweep", "short.yaml", *grid, "--out", "short.yaml", "--force"], "an input")
    _refused(capsys, ["sweep", "short.yaml", *grid, "--out", "notes.txt"], "exists and is not a sweep table")
    assert _state(folder) == before
    assert main(["sweep", "short.yaml", *grid, "--out", "ranked.csv"]) == 0
    assert main(["sweep", "short.yaml", *grid, "--out", "ranked.csv"]) == 0     # its own kind: replaced
    assert (folder / "ranked.csv").read_text().startswith("rank,")


def test_plot_benchmark_and_paper_refuse_a_users_file_before_any_work(folder, capsys):
    recorded_bag(folder, 0.05, "run.mcap")
    _refused(capsys, ["plot", "run.mcap", "--out", "notes.txt"], "--out notes.txt: a file of that name exists")
    (folder / "reports").mkdir()
    (folder / "reports" / "benchmark.md").write_text("my notes on the benchmark\n")
    (folder / "reports" / "paper000.md").write_text("my notes on paper 000\n")
    before = _state(folder)
    _refused(capsys, ["benchmark", "--scenarios", "paper001_caseI", "--out", "reports"],
             "reports/benchmark.md: exists and is not a Markdown report")
    _refused(capsys, ["benchmark", "--from-parts", "notes.txt", "--save-part", "notes.txt", "--out", "fresh"],
             "--save-part notes.txt: an input")
    _refused(capsys, ["paper", "000", "--no-maps", "--out", "reports"], "reports/paper000.md: exists and is not")
    assert _state(folder) == before


def test_every_atomic_write_of_a_command_obeys_its_rules(tmp_path):
    mine = tmp_path / "input.yaml"
    mine.write_text("a: 1\n")
    (tmp_path / "notes.txt").write_text("mine\n")
    with outputs.Outputs([mine]):
        with pytest.raises(OutputError, match="an input of this command"):
            write_atomically(mine, lambda tmp: tmp.write_text("rank,x\n"))
        with pytest.raises(OutputError, match="another kind of file"):
            write_atomically(tmp_path / "notes.txt", lambda tmp: tmp.write_bytes(b"\x89PNG\r\n\x1a\n"))
        write_atomically(tmp_path / "t.csv", lambda tmp: tmp.write_text("rank,x\n1,2\n"))
        with pytest.raises(OutputError, match="written twice"):
            write_atomically(tmp_path / "t.csv", lambda tmp: tmp.write_text("rank,x\n3,4\n"))
    assert mine.read_text() == "a: 1\n" and (tmp_path / "notes.txt").read_text() == "mine\n"
    assert (tmp_path / "t.csv").read_text() == "rank,x\n1,2\n"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]         # no temporary file left
    write_atomically(tmp_path / "notes.txt", lambda tmp: tmp.write_text("the API writes as asked\n"))


def test_a_learning_run_never_writes_its_passes_over_a_users_files(folder, capsys):
    (folder / "r_pass2_learned.npy").write_text("not a correction\n")
    (folder / "r_pass3.mcap").write_text("not a bag\n")
    before = _state(folder)
    ilc = str(DEFAULT.parent / "ilc_ellipse.yaml")
    _refused(capsys, ["run", ilc, "--composed", "--bag", "r.mcap"], "--bag r_pass")
    assert _state(folder) == before
    (folder / "r_pass3.mcap").unlink()
    _refused(capsys, ["run", ilc, "--composed", "--bag", "r.mcap"], "--bag r_pass2_learned.npy: exists and is not "
             "a learned correction")
    assert (folder / "r_pass2_learned.npy").read_text() == "not a correction\n"


def test_a_users_gzip_file_is_not_taken_for_a_part(folder, capsys):
    import gzip
    (folder / "data.gz").write_bytes(gzip.compress(b"my,own,data\n"))
    before = _state(folder)
    _refused(capsys, ["benchmark", "--scenarios", "paper001_caseI", "--save-part", "data.gz", "--out", "fresh"],
             "--save-part data.gz: exists and is not a benchmark part")
    assert _state(folder) == before
