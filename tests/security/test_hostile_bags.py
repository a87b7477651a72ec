"""Hostile bags: whatever a file holds, every reader (score, compare, export, replay) answers in bounded time
and memory with one line naming the problem, or reads what it can with a warning, never a traceback.

Compressed chunks are decompressed with a bound on the real output (never more than the size the chunk
declares, itself at most 64 MiB, whatever a zstd frame says about its own size; lz4 alike), a chunk holds at
most 2^20 records, read one at a time, and a whole bag may decompress to at most 64 times its size (256 MiB
at least). Crafted contents (a stored sample time that is none, a /reference naming only theta or an axis
twice, steps stamped off the experiment's steps, stray messages on other topics) are refused in one line or
left out with a warning."""
from __future__ import annotations

import io
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest

from contouring_ros.wire import cdr
from contouring_ros import cli
from contouring_ros.records.bag_reader import read_metadata
from contouring_ros.records.bag_writer import EXPERIMENT_METADATA, BagWriter
from contouring_ros.errors import BagError
from contouring_ros.records.scoring import read_run
from conftest import ROOT, recorded_bag

MiB = 1 << 20

# the peak resident memory of this process in kB (VmHWM: ru_maxrss keeps the parent's peak across exec)
PEAK = "int(next(l for l in open('/proc/self/status') if l.startswith('VmHWM')).split()[1])"
# reads a bag in a process of its own; prints its steps (or the error) and its peak memory in kB
MEASURE = """
import sys
from contouring_ros.errors import BagError
from contouring_ros.records.scoring import read_run
try:
    run = read_run(sys.argv[1])
    print("steps", run.complete_steps, "warnings", len(run.warnings))
    for w in run.warnings:
        print("warning:", w)
except BagError as error:
    print("error:", error)
print("peak_kb", PEAK)
""".replace("PEAK", PEAK)


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A 0.5 s run's bag, its bytes, the offset of its first chunk and of its summary."""
    result, path, data, (_, chunks) = recorded_bag(tmp_path_factory.mktemp("bags"), 0.5, "base.mcap")
    summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 29 + 9)[0]
    return path, data, chunks[0][0], summary_start, len(result.time)


def _chunk(compression: str, declared: int, payload: bytes, crc: int = 0) -> bytes:
    name = compression.encode()
    body = struct.pack("<QQQI", 0, 0, declared, crc) + struct.pack("<I", len(name)) + name + \
        struct.pack("<Q", len(payload)) + payload
    return bytes([0x06]) + struct.pack("<Q", len(body)) + body


def _zstd_zeros(size: int) -> bytes:
    """A zstd frame of ``size`` zero bytes that states its own content size."""
    import zstandard
    out = io.BytesIO()
    with zstandard.ZstdCompressor().stream_writer(out, size=size, closefd=False) as writer:
        for _ in range(size // MiB):
            writer.write(bytes(MiB))
    return out.getvalue()


def _with(base, tmp_path, *inserted: bytes, summary: bool = False):
    """The base bag with records inserted before its first chunk (the summary cut off unless ``summary``:
    then it is kept, and its chunk index no longer fits the file)."""
    _, data, first, summary_start, _ = base
    rest = data[first:] if summary else data[first:summary_start]
    path = tmp_path / "hostile.mcap"
    path.write_bytes(data[:first] + b"".join(inserted) + rest)
    return path


def _measure(path, timeout=60):
    out = subprocess.run([sys.executable, "-c", MEASURE, str(path)], capture_output=True, text=True, cwd=ROOT,
                         timeout=timeout)
    assert "Traceback" not in out.stderr, out.stderr
    lines = out.stdout.splitlines()
    peak = int(lines[-1].split()[1]) * 1024
    return lines[:-1], peak


@pytest.mark.parametrize("summary", [False, True])
@pytest.mark.parametrize("case", ["zstd stating its own size", "lz4", "honest 1 GiB", "zeros", "tiny records"])
def test_compressed_and_huge_chunks_read_in_bounded_time_and_memory(base, tmp_path, case, summary):
    """Each hostile chunk is a damaged chunk (named, skipped) and every step of the run is still read, in
    well under a minute and 300 MB, whether the summary's chunk index fits the file or not."""
    if case == "zstd stating its own size":
        chunk = _chunk("zstd", 1000, _zstd_zeros(1 << 30))          # was: 1.1 GB and no end
        reason = "decompresses to more than the 1000 bytes it declares"
    elif case == "lz4":
        import lz4.frame
        chunk = _chunk("lz4", 1000, lz4.frame.compress(bytes(512 * MiB)))
        reason = "decompresses to more than the 1000 bytes it declares"
    elif case == "honest 1 GiB":
        chunk = _chunk("zstd", 1 << 30, _zstd_zeros(1 << 30))
        reason = "declares 1073741824 bytes of records, more than the 64 MiB"
    elif case == "zeros":                  # honestly declared, under the cap: parsed 9 bytes at a time before
        chunk = _chunk("zstd", 60 * MiB, _zstd_zeros(60 * MiB))
        reason = "a record of opcode 0x00 in a chunk"
    else:                                  # 64 MiB of empty messages, uncompressed (was: 546 MB)
        message = bytes([0x05]) + struct.pack("<Q", 22) + struct.pack("<HIQQ", 999, 0, 0, 0)
        records = message * (64 * MiB // len(message))
        chunk = _chunk("", len(records), records, zlib.crc32(records))
        reason = "more than 1048576 records"
    lines, peak = _measure(_with(base, tmp_path, chunk, summary=summary))
    assert lines[0] == f"steps {base[4]} " + lines[0].split(" ", 2)[2], lines
    assert any("is damaged" in line and reason in line for line in lines), lines
    assert peak < 300e6, peak


def test_a_bag_that_decompresses_to_far_more_than_its_size_is_refused(base, tmp_path):
    """Ten chunks of 60 MiB of zeros each (a few kB compressed): past 64 times the file's size (256 MiB at
    least) the bag is refused in one line, without decompressing the rest."""
    chunk = _chunk("zstd", 60 * MiB, _zstd_zeros(60 * MiB))
    lines, peak = _measure(_with(base, tmp_path, *[chunk] * 10), timeout=30)
    assert len(lines) == 1 and lines[0].startswith("error: ") and "refused as a decompression bomb" in lines[0], lines
    assert peak < 300e6


def test_a_file_of_chunk_opcodes_is_scanned_quickly(base, tmp_path):
    """After a damaged record the reader scans for the next chunk; 64 MiB of 0x06 bytes (the chunk opcode) are
    passed over by the regex engine, not tried byte by byte (was: minutes)."""
    lines, peak = _measure(_with(base, tmp_path, b"\x06" * (64 * MiB)), timeout=30)
    assert lines[0].startswith(f"steps {base[4]} "), lines


def test_replay_play_of_a_bomb_stays_in_bounded_memory(base, tmp_path):
    from contouring_ros.run.runner import DomainLease, private_environment
    path = _with(base, tmp_path, _chunk("zstd", 1000, _zstd_zeros(1 << 30)), summary=True)
    script = f"import sys\nfrom contouring_ros import cli\ncode = cli.main(sys.argv[1:])\nprint('peak_kb', {PEAK})\n" \
        "sys.exit(code)\n"
    with DomainLease() as lease:
        out = subprocess.run([sys.executable, "-c", script, "replay", str(path), "--play", "--rate", "0",
                              "--wait-subscribers", "0"], env=private_environment(lease.domain_id),
                             capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr
    assert "decompresses to more than" in out.stdout + out.stderr
    assert int(out.stdout.split("peak_kb")[1].split()[0]) * 1024 < 400e6


# ---- crafted contents ------------------------------------------------------------------------------------

def _messages(path):
    from mcap.reader import make_reader
    with open(path, "rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages():
            yield channel.topic, schema.name, message.log_time, message.data


def _rewrite(base, tmp_path, change=None, metadata=None, extra=(), first=()):
    """The base bag written again: ``change(topic, log_time, data)`` gives the messages to write instead of
    each one; ``metadata`` updates the experiment's record; ``extra``: (topic, type, log_time, data) added;
    ``first``: the same, with their channels listed before the base bag's."""
    source = base[0]
    records = read_metadata(source)
    experiment = dict(records[EXPERIMENT_METADATA])
    experiment.update(metadata or {})
    records[EXPERIMENT_METADATA] = experiment
    messages, types = [], {}
    for topic, type_name, log_time, data in first:
        types[topic] = type_name
        messages.append((topic, log_time, data))
    for topic, type_name, log_time, data in _messages(source):
        types[topic] = type_name
        messages += change(topic, log_time, data) if change else [(topic, log_time, data)]
    for topic, type_name, log_time, data in extra:
        types[topic] = type_name
        messages.append((topic, log_time, data))
    path = tmp_path / "crafted.mcap"
    with BagWriter(path, list(types.items()), metadata=records) as writer:
        for topic, log_time, data in messages:
            writer.write(topic, log_time, data)
    return path


def _reference(data, names):
    message = cdr.decode_joint_trajectory(data)
    point = message.points[0] if hasattr(message, "points") else message
    sec, nanosec = divmod(cdr.stamp_ns(data), 1_000_000_000)
    count = len(names)
    return cdr.encode_joint_trajectory(sec, nanosec, names, list(point.positions)[-count:],
                                       list(point.velocities)[-count:], list(point.accelerations)[-count:])


@pytest.mark.parametrize("stored", ["0", "1e-12", "1e300", "nan", "-0.001", "soon"])
def test_a_stored_sample_time_that_is_none_is_named_and_the_experiment_s_used(base, tmp_path, stored):
    run = read_run(_rewrite(base, tmp_path, metadata={"sample_time": stored}))
    assert run.complete_steps == base[4]
    assert any(f"sample_time {stored!r} is not a sample time" in w for w in run.warnings), run.warnings
    assert run.result.time[-1] == pytest.approx(0.5)


@pytest.mark.parametrize("names, message", [
    (["theta"], "names the joints ['theta']: expected one or more axes, then 'theta'"),
    (["x", "x", "theta"], "names the axis 'x' twice"),
    (["x", "y"], "expected one or more axes, then 'theta'"),
    (["x", "y", "z", "theta"], "its experiment has axes x, y; the bag has x, y, z"),
    (["x", "../y", "theta"], "names '../y', not an axis name"),
])
def test_a_reference_naming_other_joints_is_refused_in_one_line(base, tmp_path, names, message):
    def change(topic, log_time, data):
        return [(topic, log_time, _reference(data, names) if topic == "/reference" else data)]
    with pytest.raises(BagError, match=message.replace("[", r"\[").replace("]", r"\]").replace(".", r"\.")):
        read_run(_rewrite(base, tmp_path, change))


@pytest.mark.parametrize("sec, nanosec", [(2**31 - 1, 0), (0, 1500_000), (-5, 0)])
def test_a_step_stamped_off_the_experiment_s_steps_is_left_out_with_a_warning(base, tmp_path, sec, nanosec):
    """Step 3's messages are stamped at ``sec``, ``nanosec`` instead (t = 2^31 s gave "travel time
    2.147e+09 s" with no warning)."""
    def change(topic, log_time, data):
        if log_time == 3_000_000 and topic != "/clock":
            data = data[:4] + struct.pack("<iI", sec, nanosec) + data[12:]
        return [(topic, log_time, data)]
    run = read_run(_rewrite(base, tmp_path, change))
    assert run.complete_steps == base[4] - 1
    assert run.result.time[-1] == pytest.approx(0.5)
    assert any("1 step stamped off the experiment's steps" in w for w in run.warnings), run.warnings


def test_stray_messages_on_other_topics_are_left_out_with_a_warning(base, tmp_path):
    """A JointState topic of someone else's (one message, then one of another layout, then bytes that are no
    JointState at all) and a second /reference under another namespace: warned about, the run read whole."""
    stray = [("/foo/joint_states", "sensor_msgs/msg/JointState", 1_000_000, cdr.encode_joint_state(0, 0, ["a"], [1.0])),
             ("/foo/joint_states", "sensor_msgs/msg/JointState", 2_000_000,
              cdr.encode_joint_state(0, 0, ["a", "b"], [1.0, 2.0], [0.0, 1.0])),
             ("/bar", "sensor_msgs/msg/JointState", 2_000_000, b"\x00\x01\x00\x00garbage"),
             ("/other/reference", "trajectory_msgs/msg/JointTrajectory", 0,
              cdr.encode_joint_trajectory(0, 0, ["x", "theta"], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]))]
    reference = read_run(base[0])
    run = read_run(_rewrite(base, tmp_path, extra=stray))
    assert run.complete_steps == base[4]
    np.testing.assert_array_equal(run.result.position, reference.result.position)
    text = "\n".join(run.warnings)
    assert "/foo/joint_states left out" in text and "/bar left out" in text and "/other/reference (1 messages) left out" in text


def test_a_graph_topic_that_is_not_its_type_is_named(base, tmp_path):
    def change(topic, log_time, data):
        return [(topic, log_time, b"\x00\x01\x00\x00" + b"\xff" * 7 if topic == "/x/state" and log_time == 0 else data)]
    with pytest.raises(BagError, match=r"/x/state: a message that is not a sensor_msgs/msg/JointState"):
        read_run(_rewrite(base, tmp_path, change))


@pytest.mark.parametrize("command", ["score", "compare", "export", "replay"])
def test_every_bag_command_answers_crafted_bags_in_one_line(base, tmp_path, capsys, command):
    """score, compare, export and replay on a bag whose /reference names only theta: exit 2, one line."""
    def change(topic, log_time, data):
        return [(topic, log_time, _reference(data, ["theta"]) if topic == "/reference" else data)]
    path = str(_rewrite(base, tmp_path, change))
    extra = {"export": ["--csv", str(tmp_path / "csv")], "replay": ["--estimator", "tangent_line"]}.get(command, [])
    assert cli.main([command, path, *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {path}: its /reference names the joints"), err


@pytest.mark.parametrize("rate", ["nan", "inf", "-1", "fast"])
def test_a_rate_that_is_no_rate_is_refused_before_anything_plays(base, capsys, rate):
    with pytest.raises(SystemExit) as info:             # was: --rate nan taken as 0
        cli.main(["replay", str(base[0]), "--play", "--rate", rate])
    assert info.value.code == 2 and "--rate: expected 0 (as fast as possible) or a positive factor" in \
        capsys.readouterr().err


def test_thousands_of_stray_topics_and_a_huge_stored_experiment_are_bounded(base, tmp_path):
    state = cdr.encode_joint_state(0, 0, ["a"], [1.0])
    stray = [(f"/stray/t{i}", "sensor_msgs/msg/JointState", 0, state) for i in range(5000)]
    run = read_run(_rewrite(base, tmp_path, extra=stray))
    assert run.complete_steps == base[4]
    assert any("more than 4096 JointState and JointTrajectory topics" in w for w in run.warnings)
    crowd = [(f"/stray/t{i}", "sensor_msgs/msg/JointState", 0, state) for i in range(4100)]
    run = read_run(_rewrite(base, tmp_path, first=crowd))     # listed before the run's own: not crowding them out
    assert run.complete_steps == base[4]
    assert any("more than 4096 JointState and JointTrajectory topics; from /stray/t4096 on" in w for w in run.warnings)
    text = read_metadata(base[0])[EXPERIMENT_METADATA]["yaml"]
    with pytest.raises(BagError, match="an experiment file has at most 1048576"):
        read_run(_rewrite(base, tmp_path, metadata={"yaml": text + "#" * (2 << 20)}))
