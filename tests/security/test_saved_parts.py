"""Benchmark parts: a file from elsewhere runs no code and anything that is not a whole part of this format
is one line naming the file; a part comes back as it was saved (values, types, shared objects)."""
import dataclasses
import gzip
import hashlib
import json
import math
import pickle

import numpy as np
import pytest

from contouring_ros.studies import benchmark, benchmark_parts, parts, tuning
from contouring_ros.cli import main
from contouring_ros.errors import ConfigError
from contouring_ros.studies.search import agreement


def _part() -> benchmark.Part:
    """A small part by hand: one scenario, a tuned proposed row that refers to itself, an excluded row."""
    family = benchmark.Family("003", "mech", ["a", "b"], "a", 0.25, {"a": {"/**": {"ros__parameters": {"x": 1}}}})
    combination = benchmark.Combination("newton", "unit_vector", "ismc", {"/ccc": {"kp": 1.0}}, ("ccc.kp",))
    draws = [tuning.Outcome(tace=1e-6, mce=2e-6, peak_command=(1.0, np.float64(2.5))),
             tuning.Outcome(failure="diverged at t = 1 s")]
    tuned = tuning.Tuned(gains={"ccc.kp": np.float64(2.0)}, draws=draws, nominal=draws[0], robust_worst=math.inf,
                         search_tace=[math.nan, 3e-6], agreement=agreement([math.inf, 3e-6, 3.1e-6, 3.05e-6]),
                         point={"f_p": 12.5, "r_d": 0.0})
    proposed = benchmark.Row(family, combination, tuned=tuned, status="ok")
    proposed.reference = proposed
    excluded = benchmark.Row(family, None, benchmark.Excluded("tangent_line", "tvt", "ismc", "not paired"))
    return benchmark.Part([family], [proposed, excluded], tuning.Protocol(evaluations=6), 1.5, 2.5, 2, "cmd")


def _file(path, payload: dict, **header) -> None:
    """A part file with ``payload`` and a header whose checksum matches it (unless ``header`` says otherwise)."""
    text = json.dumps(payload).encode()
    head = {"format": parts.FORMAT, "version": parts.VERSION, "sha256": hashlib.sha256(text).hexdigest(),
            "bytes": len(text), **header}
    path.write_bytes(gzip.compress(json.dumps(head).encode() + b"\n" + text))


def _payload(path) -> dict:
    return json.loads(gzip.decompress(path.read_bytes()).partition(b"\n")[2])


def test_a_part_comes_back_with_its_values_types_and_shared_objects(tmp_path):
    part = _part()
    path = benchmark_parts.save_part(part, tmp_path / "p.part")
    back, = benchmark_parts.load_parts([path])
    assert back is not part and parts.dumps(back) == parts.dumps(part)      # nan fields: equal by their bytes
    proposed = back.rows[0]
    assert proposed.reference is proposed and proposed.family is back.families[0] is back.rows[1].family
    assert type(proposed.tuned.gains["ccc.kp"]) is np.float64 and proposed.tuned.robust_worst == math.inf
    assert math.isnan(proposed.tuned.search_tace[0]) and proposed.tuned.nominal is proposed.tuned.draws[0]
    assert back.protocol == part.protocol and back.rows[0].tuned.agreement == part.rows[0].tuned.agreement
    assert back.rows[0].tuned.converged and back.rows[0].tuned.point == {"f_p": 12.5, "r_d": 0.0}
    assert proposed.combination.gain_keys == ("ccc.kp",) and back.methods == ()
    assert path.read_bytes() == benchmark_parts.save_part(part, tmp_path / "q.part").read_bytes()    # deterministic


def test_a_pickle_runs_nothing_and_is_one_line(tmp_path, capsys):
    marker = tmp_path / "ran"

    class Payload:
        def __reduce__(self):
            return (open, (str(marker), "w"))
    (tmp_path / "evil.pkl").write_bytes(pickle.dumps(Payload()))
    assert main(["benchmark", "--from-parts", str(tmp_path / "evil.pkl"), "--out", str(tmp_path / "out")]) == 2
    assert not marker.exists()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "evil.pkl" in err and "not a benchmark part" in err


@pytest.mark.parametrize("change, message", [
    (lambda p: p["fields"].update(seconds="fast"), r"part\.seconds: a str where benchmark.Part's field holds float"),
    (lambda p: p["fields"]["rows"][0]["fields"].update(tuned={"$": "obj", "class": "os.system", "id": 99,
                                                              "fields": {}}), "class 'os.system' is not one"),
    (lambda p: p["fields"].update(extra=1), "Part has no field 'extra'"),
    (lambda p: p["fields"].pop("command"), r"part\.command: missing"),
    (lambda p: p["fields"]["rows"].append({"$": "ref", "id": 12345}), "refers to object 12345"),
    (lambda p: p["fields"]["families"].append("a"), "a scenario that is not a Family"),
    (lambda p: p["fields"]["rows"][1]["fields"].update(tuned="x"), "a row whose tuning is not Tuned"),
    (lambda p: p["fields"].update(seconds={"$": "float", "v": "__import__('os')"}), "is not a non-finite float"),
    (lambda p: p["fields"].update(seconds={"$": "np", "dtype": "O", "v": 1}), "dtype object is not one"),
])
def test_a_part_with_odd_contents_is_one_line_naming_what(tmp_path, change, message):
    payload = _payload(benchmark_parts.save_part(_part(), tmp_path / "p.part"))
    change(payload)
    _file(tmp_path / "odd.part", payload)
    with pytest.raises(ConfigError, match=message):
        benchmark_parts.load_parts([tmp_path / "odd.part"])


def test_a_changed_cut_or_foreign_file_is_refused_before_anything_is_built(tmp_path, monkeypatch):
    good = benchmark_parts.save_part(_part(), tmp_path / "p.part")
    payload = _payload(good)
    _file(tmp_path / "sum.part", payload, sha256="0" * 64)
    _file(tmp_path / "version.part", payload, version=99)
    (tmp_path / "cut.part").write_bytes(good.read_bytes()[:-20])
    (tmp_path / "text.part").write_text("{}")
    (tmp_path / "gz.part").write_bytes(gzip.compress(b"not json\n{}"))
    built = []
    monkeypatch.setattr(parts._Builder, "obj", lambda *a: built.append(a))
    for name, message in [("sum", "do not match its checksum"), ("version", "format version 99"),
                          ("cut", "not a readable benchmark part"), ("text", "not gzip data"),
                          ("gz", "no part header"), ("missing", "cannot read it")]:
        with pytest.raises(ConfigError, match=f"^--from-parts .*{name}.part: .*{message}"):
            benchmark_parts.load_parts([tmp_path / f"{name}.part"])
    assert built == []


def test_sizes_are_bounded_before_reading_or_decompressing(tmp_path, monkeypatch):
    path = tmp_path / "bomb.part"
    path.write_bytes(gzip.compress(b"\0" * 5_000_000))          # 5 MB of text in ~5 kB
    monkeypatch.setattr(parts, "MAX_TEXT_BYTES", 1_000_000)
    with pytest.raises(ConfigError, match="decompresses to over"):
        benchmark_parts.load_parts([path])
    monkeypatch.setattr(parts, "MAX_FILE_BYTES", 100)
    with pytest.raises(ConfigError, match="over the 0 MiB a part may have"):
        benchmark_parts.load_parts([path])


def test_a_field_added_to_a_class_is_carried_without_touching_the_serialiser(monkeypatch):
    @dataclasses.dataclass
    class Later:
        a: float
        convergence: list = dataclasses.field(default_factory=list)     # a field added later
    monkeypatch.setitem(parts.CLASSES, "test.Later", Later)
    back = parts.loads(parts.dumps(Later(1.0, [0.5, 0.25])))
    assert back == Later(1.0, [0.5, 0.25])
    text = gzip.decompress(parts.dumps(Later(1.0)))
    older = json.loads(text.partition(b"\n")[2])
    del older["fields"]["convergence"]                 # a file written before the field existed: its default
    payload = json.dumps(older).encode()
    head = {"format": parts.FORMAT, "version": parts.VERSION, "sha256": hashlib.sha256(payload).hexdigest(),
            "bytes": len(payload)}
    assert parts.loads(gzip.compress(json.dumps(head).encode() + b"\n" + payload)) == Later(1.0, [])
