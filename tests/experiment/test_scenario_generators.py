"""tools/make_paper<N>_configs.py regenerate every paper scenario file of config/ byte for byte."""
import subprocess
import sys

import pytest

from conftest import ROOT

GENERATORS = sorted((ROOT / "tools").glob("make_paper*_configs.py"))


@pytest.mark.parametrize("generator", GENERATORS, ids=[g.stem for g in GENERATORS])
def test_generator_reproduces_the_committed_files(generator, tmp_path):
    out = subprocess.run([sys.executable, str(generator), str(tmp_path)], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    written = sorted(tmp_path.glob("*.yaml"))
    paper = generator.stem[len("make_paper"):-len("_configs")]
    assert [p.name for p in written] == sorted(p.name for p in (ROOT / "config").glob(f"paper{paper}_*.yaml"))
    for path in written:
        assert path.read_bytes() == (ROOT / "config" / path.name).read_bytes(), f"{path.name} differs"


def test_every_paper_has_a_generator():
    papers = {p.name[5:8] for p in (ROOT / "config").glob("paper???_*.yaml")}
    assert papers == {g.stem[len("make_paper"):-len("_configs")] for g in GENERATORS}
