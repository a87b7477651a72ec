"""Damaged bags: chunks are read with their CRCs checked; a damaged chunk gives a warning
naming the steps lost, and every intact chunk after it is still read, with the summary's chunk index or,
without a summary, by scanning for the next chunk record."""
from __future__ import annotations

import random
import re
import subprocess
import sys

import numpy as np
import pytest

from contouring_ros.errors import BagError
from contouring_ros.records.bag_reader import iter_records
from contouring_ros.records.scoring import read_run
from conftest import recorded_bag

LOST = re.compile(r"the (?:chunk|record) at byte (\d+) is damaged \((.+)\): steps (\d+)\.\.(\d+) lost \((\d+) steps?, "
                  r"t = [0-9.]+\.\.[0-9.]+ s\); read on from the chunk at byte (\d+)")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    result, _, data, (complete, chunks) = recorded_bag(tmp_path_factory.mktemp("bags"), 2.0, "run.mcap")
    assert complete and len(chunks) >= 5
    return result, data, chunks


def _write(tmp_path, name, data):
    path = tmp_path / name
    path.write_bytes(bytes(data))
    return path


def _steps_of(chunk) -> np.ndarray:
    """The steps whose messages the chunk (offset, length, start_ns, end_ns) holds, boundaries included."""
    _, _, start, end = chunk
    return np.arange(start // 1_000_000, end // 1_000_000 + 1)


def _check_damage(run, result, chunk, next_chunk, reasons):
    """One warning naming the chunk and exactly the steps missing from the run; every later step kept."""
    warnings = [w for w in run.warnings if "is damaged" in w]
    assert len(warnings) == 1, run.warnings
    match = LOST.search(warnings[0])
    assert match, warnings[0]
    offset, reason, first, last, count, resumed = match.groups()
    assert int(offset) == chunk[0] and int(resumed) == next_chunk[0]
    assert any(r in reason for r in reasons), reason
    total = len(result.time)
    kept = np.round(run.result.time / 1e-3).astype(int)
    lost = np.setdiff1d(np.arange(total), kept)
    assert lost.tolist() == list(range(int(first), int(last) + 1)) and len(lost) == int(count)
    assert set(lost) <= set(_steps_of(chunk).tolist())         # only the damaged chunk's steps
    assert kept[-1] == total - 1 and len(kept) == total - len(lost)   # every chunk after it was read
    np.testing.assert_array_equal(run.result.position, result.position[kept])
    np.testing.assert_array_equal(run.result.command, result.command[kept])
    return lost


def test_intact_bag_reads_without_warnings(recorded, tmp_path):
    result, data, _ = recorded
    run = read_run(_write(tmp_path, "intact.mcap", data))
    assert not run.warnings and run.complete_steps == len(result.time)


def test_one_flipped_byte_in_a_mid_file_chunk(recorded, tmp_path):
    result, data, chunks = recorded
    middle = len(chunks) // 2
    chunk = chunks[middle]
    damaged = bytearray(data)
    damaged[chunk[0] + chunk[1] // 2] ^= 0x10
    run = read_run(_write(tmp_path, "flipped.mcap", damaged))
    lost = _check_damage(run, result, chunk, chunks[middle + 1], ("CRC mismatch", "cannot be decompressed"))
    assert 0 < len(lost) < len(result.time) // 3


def test_flipped_crc_is_caught_by_the_crc_check(recorded, tmp_path):
    """The records decompress; only the chunk's CRC says they are not what was written."""
    result, data, chunks = recorded
    chunk = chunks[2]
    damaged = bytearray(data)
    damaged[chunk[0] + 9 + 24] ^= 0x01          # the uncompressed_crc field of the chunk's header
    run = read_run(_write(tmp_path, "crc.mcap", damaged))
    _check_damage(run, result, chunk, chunks[3], ("CRC mismatch",))


@pytest.mark.parametrize("summary", [True, False], ids=["with summary", "summary cut away"])
@pytest.mark.parametrize("where", ["inside", "over the header"])
def test_four_kilobytes_corrupted_mid_file(recorded, tmp_path, summary, where):
    result, data, chunks = recorded
    middle = len(chunks) // 2
    chunk = chunks[middle]
    start = chunk[0] + chunk[1] // 3 if where == "inside" else chunk[0] - 100
    damaged = bytearray(data)
    damaged[start:start + 4096] = random.Random(13).randbytes(4096)
    if not summary:    # the writer died after the last chunk: no data end, summary or footer
        damaged = damaged[:chunks[-1][0] + chunks[-1][1]]
    run = read_run(_write(tmp_path, "garbage.mcap", damaged))
    _check_damage(run, result, chunk, chunks[middle + 1],
                  ("CRC mismatch", "cannot be decompressed", "header", "no MCAP record", "cannot be read"))
    if not summary:
        assert any("ends early" in w for w in run.warnings)


def test_two_damaged_chunks_each_named(recorded, tmp_path):
    result, data, chunks = recorded
    damaged = bytearray(data)
    for chunk in (chunks[1], chunks[4]):
        damaged[chunk[0] + chunk[1] // 2] ^= 0xFF
    run = read_run(_write(tmp_path, "two.mcap", damaged))
    found = [LOST.search(w) for w in run.warnings]
    assert [int(m.group(1)) for m in found if m] == [chunks[1][0], chunks[4][0]]
    assert run.result.time[-1] == pytest.approx(result.time[-1])


def test_score_exits_0_with_the_warning(recorded, tmp_path):
    result, data, chunks = recorded
    chunk = chunks[len(chunks) // 2]
    damaged = bytearray(data)
    damaged[chunk[0] + chunk[1] // 2: chunk[0] + chunk[1] // 2 + 4096] = bytes(4096)
    path = _write(tmp_path, "scored.mcap", damaged)
    done = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "score", str(path)], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert re.search(r"warning: .*the chunk at byte \d+ is damaged .*: steps \d+\.\.\d+ lost", done.stderr)
    assert "Traceback" not in done.stderr and "MCE" in done.stdout.upper()


def test_records_reader_without_a_damage_list_warns_in_times(recorded, tmp_path):
    """Other readers of iter_records (playback) get a warning with the time range lost."""
    _, data, chunks = recorded
    chunk = chunks[3]
    damaged = bytearray(data)
    damaged[chunk[0] + chunk[1] // 2] ^= 0x10
    warnings: list = []
    messages = sum(1 for record in iter_records(_write(tmp_path, "play.mcap", damaged), warnings)
                   if hasattr(record, "log_time"))
    assert messages > 0 and len(warnings) == 1
    assert re.search(r"the chunk at byte \d+ is damaged .*: messages from t = [0-9.]+ s to t = [0-9.]+ s lost",
                     warnings[0]), warnings[0]


def test_not_an_mcap_file(tmp_path):
    path = _write(tmp_path, "text.mcap", b"hello, not a bag\n" * 10)
    with pytest.raises(BagError, match="not an MCAP file"):
        read_run(path)
