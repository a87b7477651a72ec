"""A lockstep bag is a pure function of its experiment: the default experiment's payloads, pinned.

Every published value is computed with operations whose rounding does not depend on the numpy or BLAS
build (elementwise IEEE arithmetic, math.sqrt/exp/fsum, and the explicit products of
:func:`contouring_ros.core.geometry.dot`, ``norm``, ``matvec``, ``matmul`` in place of ``@``, np.dot and
np.linalg.norm on the one-step path), so the bag of the default experiment is byte-identical on any
machine. This test pins a SHA-256 per topic of its payloads, concatenated in step order, as
:func:`contouring_ros.records.bag_writer.write_simulation` writes them (the graph's bags carry the same payloads:
tests/graph/test_graph.py and tests/experiment/test_every_scenario.py).

Updating the hashes: any deliberate numeric change anywhere on the published path (a curve, the schedule,
a plant, servo, estimator or controller, the experiment file, the message layout) legitimately changes
them. Check first that the change is intended and that the other tests (batch, graph, every scenario)
pass, then print the new table with ``.venv/bin/python tests/graph/test_payload_hashes.py`` and paste it over
``EXPECTED`` below, saying in the commit which change moved which topics. A hash that moves without
such a change (a numpy, scipy or Python upgrade, another machine) is the bug this test is here to catch.
"""
from __future__ import annotations

import hashlib
import sys
from pathlib import Path

from mcap.reader import make_reader

from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.simulation import simulate

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))     # tests/: its conftest, when run as a script
from conftest import DEFAULT  # noqa: E402

STEPS = 2001     # the default experiment: 2 s at 1 kHz, steps 0..2000

EXPECTED = {
    "/ccc/correction": "dec9d1c71d5dc2f5ac84b05a0559af90167a7436e887c31d721d300764905146",
    "/clock": "9d3f66567128ed75e24c5a665bacecfce3384578ca09180b04cd27aa68db0a71",
    "/contour_error": "54283e0964b0469649637e701a658cc30bb3386ec07ae011cf534f8dfcc631d0",
    "/reference": "bd25989b534f24a16b01078d882d609231bc628b77b01152e2a74cc18989e2a9",
    "/x/command": "910ed88720accee1007124f8a46992d4056e38ae789becd39f9f831bbd327f64",
    "/x/state": "5c85aa3e2491b1dbe8b77736042faf51d7772530fb73723d4a2fe2dc5f7e0a79",
    "/y/command": "818756adeb97086192f302c20f3c4f3d739533b8be2018bb90bf088c941b4b91",
    "/y/state": "f96551269ee479c2993f43d039c1281aa176d27af0ef07bc252efc83ccf38eb9",
}


def payload_hashes(directory: Path) -> dict:
    """{topic: (messages, SHA-256 hex of the concatenated payloads)} of the default experiment's bag."""
    experiment = load_experiment(DEFAULT)
    bag = write_simulation(Path(directory) / "default.mcap", experiment, simulate(build_loop(experiment)))
    payloads = {}
    with open(bag, "rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=True):
            payloads.setdefault(channel.topic, []).append(message.data)
    return {topic: (len(messages), hashlib.sha256(b"".join(messages)).hexdigest())
            for topic, messages in sorted(payloads.items())}


def test_default_experiment_payloads_are_pinned(tmp_path):
    hashes = payload_hashes(tmp_path)
    assert {count for count, _ in hashes.values()} == {STEPS}
    changed = {topic: digest for topic, (_, digest) in hashes.items() if EXPECTED.get(topic) != digest}
    assert sorted(hashes) == sorted(EXPECTED), f"topics differ: {sorted(hashes)} vs {sorted(EXPECTED)}"
    assert not changed, ("payloads changed on " + ", ".join(changed) + " (see this file's docstring to update):\n"
                         + _table(hashes))


def _table(hashes: dict) -> str:
    return "\n".join(f'    "{topic}": "{digest}",' for topic, (_, digest) in hashes.items())


if __name__ == "__main__":
    import tempfile
    with tempfile.TemporaryDirectory() as directory:
        print("EXPECTED = {\n" + _table(payload_hashes(Path(directory))) + "\n}")
