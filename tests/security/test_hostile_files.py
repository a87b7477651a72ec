"""Hostile and malformed experiment files: each is refused before any node starts, in
well under a second, with one line naming the file and the key; numbers have bounds; the file itself must
be a small regular UTF-8 file; values the ROS 2 parameter parser would read differently are refused; bag
names stay inside the bag folder."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from contouring_ros import config
from contouring_ros.config import load_experiment, parse_experiment
from contouring_ros.errors import ConfigError
from conftest import CONFIG, DEFAULT

BASE = DEFAULT.read_text()
GLOBAL = "    sample_time: 0.001\n"
X_PLANT_GAIN = "    gain: 10.3\n    time_constant: 0.040\n    disturbance"
KP, KD = "    kp: 1.0\n", "    kd: 0.1\n"
AXES = '    axes: ["x", "y"]'
CURVE = "    curve: {type: parabola, a: 0.02, h: 50.0}\n"
SCHEDULE = "    schedule: {type: uniform, theta_start: -0.02, theta_end: 0.02, duration: 2.0}\n"
NAME = "      name: paper000_b_ismc_h50_newton\n"
CIRCLE = "    curve: {type: circle, radius: 0.02, center: CENTER}\n"
FEEDRATE = "    schedule: {type: feedrate, feedrate: FEED, acceleration: 1.0}\n"

# (case, old, new, the key the message must name (after "file: "), a fragment of the message)
CASES = [
    ("tiny sample time", GLOBAL, "    sample_time: 1.0e-10\n", "sample_time", "expected a value from 1e-05 to 1"),
    ("long sample time", GLOBAL, "    sample_time: 2.0\n", "sample_time", "from 1e-05 to 1"),
    ("endless duration", GLOBAL, GLOBAL + "    duration: 1.0e9\n", "duration", "from 0 to 3600"),
    ("too many steps", GLOBAL, "    sample_time: 1.0e-5\n    duration: 3000.0\n", "duration", "steps; at most 1e+07"),
    ("huge branch check", "    c_prime: 500.0\n", "    c_prime: 500.0\n    branch_check_samples: 2000000000\n",
     "/contour_estimator.branch_check_samples", "from 0 to 10000"),
    ("huge Newton iterations", "    max_iterations: 200\n", "    max_iterations: 100000000\n",
     "/contour_estimator.max_iterations", "from 1 to 10000"),
    ("denormal feedrate", SCHEDULE, FEEDRATE.replace("FEED", "1.0e-310"), "schedule.feedrate",
     "ROS 2 reads '1.0e-310' as the string"),
    ("feedrate too small", SCHEDULE, FEEDRATE.replace("FEED", "1.0e-300"), "schedule.feedrate", "from 1e-06 to 100"),
    ("schedule of years", SCHEDULE, FEEDRATE.replace("FEED", "1.0e-5"), "schedule", "at most 3600 s"),
    ("feedrate samples", SCHEDULE, FEEDRATE.replace("FEED", "0.1").replace("}", ", samples: 1000000000}"),
     "schedule.samples", "from 2 to 1e+06"),
    ("gain beyond range", KP, "    kp: 1.0e13\n", "/ccc.kp", "from 0 to 1e+12"),
    ("stall timeout", GLOBAL, GLOBAL + "    stall_timeout: 1.0e9\n", "stall_timeout", "from 0.001 to 3600"),
    ("deep nesting", NAME, NAME + "      deep: " + "[" * 5000 + "]" * 5000 + "\n", "experiment.deep",
     "nested deeper than 16 levels"),
    ("deep mappings", NAME, NAME + "      deep: " + "{a: " * 3000 + "1" + "}" * 3000 + "\n", "experiment.deep.a",
     "nested deeper than 16 levels"),
    ("NUL in the name", NAME, '      name: "paper\\0name"\n', "experiment.name", "no '/' or '..'"),
    ("very long name", NAME, "      name: " + "a" * 5000 + "\n", "experiment.name", "1 to 100 ASCII"),
    ("name escapes bags/", NAME, "      name: ../../outside\n", "experiment.name", "no '/' or '..'"),
    ("name with a slash", NAME, "      name: runs/mine\n", "experiment.name", "no '/'"),
    ("non-ASCII name", NAME, "      name: réglage\n", "experiment.name", "ASCII"),
    ("bare y in axes", AXES, "    axes: [x, y]", "axes", "ROS 2 reads 'y' as the boolean true"),
    ("bare n in axes", AXES, "    axes: [x, n]", "axes", "ROS 2 reads 'n' as the boolean false"),
    ("on/off as axes", AXES, "    axes: [on, off]", "axes", "expected a non-empty list of names"),
    ("yes as a key", KP, KP + "    yes: 1\n", "/ccc.yes", "is read as the boolean true"),
    ("mixed int and float list", CURVE, CIRCLE.replace("CENTER", "[0, 0.5]"), "curve.center",
     "a list of integers and decimals"),
    ("empty list", AXES, "    axes: []", "axes", "an empty list"),
    ("nested list", CURVE, CIRCLE.replace("CENTER", "[[0.0, 0.0]]"), "curve.center", "item 1 is a list"),
    ("mapping in a list", CURVE, CIRCLE.replace("CENTER", "[{x: 0.0}, 0.0]"), "curve.center", "item 1 is a mapping"),
    ("empty mapping", "    paper:\n", "    paper: {}\n    unused:\n", "paper", "an empty mapping"),
    ("integer beyond int64", X_PLANT_GAIN, X_PLANT_GAIN.replace("10.3", "99999999999999999999"), "/x/plant.gain",
     "integers are 64-bit in ROS 2"),
    ("integer of 5000 digits", X_PLANT_GAIN, X_PLANT_GAIN.replace("10.3", "9" * 5000), "/x/plant.gain", "cannot read"),
    ("non-ASCII axis", AXES, '    axes: ["x", "\u00ff"]', "axes", "1 to 32 ASCII letters"),
    ("axis named theta", AXES, '    axes: ["x", "theta"]', "axes", "not one of"),
    ("axis with __", AXES, '    axes: ["x", "y__z"]', "axes", "single _"),
    ("non-ASCII key", X_PLANT_GAIN, X_PLANT_GAIN.replace("gain", "g\u00e4in"), "/x/plant.g\u00e4in",
     "a parameter name is"),
    ("sexagesimal", SCHEDULE, SCHEDULE.replace("duration: 2.0", "duration: 1:30"), "schedule.duration",
     "ROS 2 reads '1:30' as the string '1:30', not as the integer 90"),
    ("underscored number", KP, "    kp: 1_0\n", "/ccc.kp", "ROS 2 reads '1_0' as the string"),
    ("null value", KD, "    kd: ~\n", "/ccc.kd", "not as null"),
    ("empty value", KD, "    kd:\n", "/ccc.kd", "no value"),
    ("explicit tag", KP, "    kp: !!float 1\n", "/ccc.kp", "explicit YAML tags"),
    ("bare nan", KP, "    kp: nan\n", "/ccc.kp", "ROS 2 reads 'nan' as the number nan"),
    ("infinity", KP, "    kp: .inf\n", "/ccc.kp", "expected finite numbers"),
    ("overflowing exponent", KP, "    kp: 1e999\n", "/ccc.kp", "ROS 2 reads '1e999' as the string"),
    ("hex float", KP, "    kp: 0x1p3\n", "/ccc.kp", "ROS 2 reads '0x1p3' as the number 8.0"),
    ("leading zero", KP, "    kp: 09\n", "/ccc.kp", "ROS 2 reads '09' as the number 9.0"),
    ("a date", "      description:", "      date: 2024-01-01\n      description:", "experiment.date", "date"),
    ("string with a line break", KD, KD + '/recorder:\n  ros__parameters:\n    bag: "a\\nb.mcap"\n', "/recorder.bag",
     "control characters"),
    ("list too long", CURVE, CIRCLE.replace("CENTER", "[" + ", ".join(["0.0"] * 5000) + "]"), "curve.center",
     "at most 4096 items"),
    ("alias", NAME, "      name: &n paper\n      again: *n\n", "experiment.again", "aliases"),
    ("circle centre in 3-D", CURVE, CIRCLE.replace("CENTER", "[0.0, 0.0, 0.0]"), "curve.center",
     "expected 2 coordinates (the circle curve is 2-dimensional), got 3"),
    ("ellipse centre of 1 coordinate", CURVE, "    curve: {type: ellipse, a: 0.02, b: 0.01, center: [0.0]}\n",
     "curve.center", "expected 2 coordinates"),
    ("line of mixed dimensions", CURVE, "    curve: {type: line, start: [0.0, 0.0, 0.0], end: [0.1, 0.0]}\n", "curve",
     "same dimension"),
    ("renamed key", "    max_iterations: 200\n", "    iterations: 20\n", "/contour_estimator.iterations",
     "`iterations` is now `max_iterations`"),
]


def _refused(path_or_text, tmp_path=None, name="case.yaml"):
    start = time.perf_counter()
    with pytest.raises(ConfigError) as info:
        load_experiment(path_or_text)
    elapsed = time.perf_counter() - start
    message = str(info.value)
    assert "\n" not in message and "Traceback" not in message
    assert elapsed < 5.0, f"took {elapsed:.2f} s"     # refused before any work: no hang, no huge read (a shared
                                                      # 2-core machine can take 0.6 s where a quiet one takes 0.1)
    return message


@pytest.mark.parametrize("case,old,new,key,fragment", CASES, ids=[c[0] for c in CASES])
def test_malformed_file_is_refused_naming_the_key(tmp_path, case, old, new, key, fragment):
    assert old in BASE, case
    path = tmp_path / "case.yaml"
    path.write_text(BASE.replace(old, new, 1), encoding="utf-8")
    message = _refused(path)
    assert message.startswith(f"{path}: {key}: ") or case.startswith("deep") and \
        message.startswith(f"{path}: {key}"), message
    assert fragment in message, message


def test_there_are_at_least_thirty_cases():
    assert len(CASES) >= 30


def test_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "experiment.yaml"
    os.mkfifo(fifo)
    message = _refused(fifo)
    assert message == f"{fifo}: not a regular file (a FIFO); an experiment is a YAML file"


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/null", "/dev/urandom"])
def test_devices_are_refused_without_reading(device):
    if not Path(device).exists():
        pytest.skip(f"no {device}")
    assert _refused(Path(device)) == f"{device}: not a regular file (a character device); an experiment is a YAML file"


def test_link_to_a_device_and_a_directory_are_refused(tmp_path):
    link = tmp_path / "zero.yaml"
    link.symlink_to("/dev/zero")
    assert "a character device" in _refused(link)
    assert _refused(tmp_path) == f"{tmp_path}: not a regular file (a directory); an experiment is a YAML file"
    assert "cannot read (No such file or directory)" in _refused(tmp_path / "missing.yaml")


def test_large_binary_and_odd_named_files(tmp_path):
    big = tmp_path / "big.yaml"
    big.write_text(BASE + "#" * (config.MAX_FILE_BYTES + 1))
    assert "too large" in _refused(big)
    latin = tmp_path / "latin.yaml"
    latin.write_bytes(BASE.replace("ISMC", "\u00e9").encode("latin-1"))
    assert "not UTF-8" in _refused(latin)
    nul = tmp_path / "nul.yaml"
    nul.write_bytes(BASE.encode() + b"\x00")
    assert "contains NUL bytes" in _refused(nul)
    odd = tmp_path / "line\nbreak.yaml"
    odd.write_text("- 1\n")
    message = _refused(odd)
    assert message.startswith(str(tmp_path / "line\\nbreak.yaml"))
    long_name = tmp_path / ("x" * 300 + ".yaml")
    assert "cannot read" in _refused(long_name)


def test_denormal_without_the_ros_reading_is_refused_too():
    """parse_experiment (texts, not files for the nodes) skips the ROS parser check; the bounds still hold."""
    text = BASE.replace(SCHEDULE, FEEDRATE.replace("FEED", "1.0e-310"))
    with pytest.raises(ConfigError, match=r"^<experiment>: schedule.feedrate: 1e-310 is a denormal number"):
        parse_experiment(text)
    with pytest.raises(ConfigError, match=r"/x/plant.gain: expected a value from 1e-09 to 1e\+09, got an integer"):
        parse_experiment(BASE.replace(X_PLANT_GAIN, X_PLANT_GAIN.replace("10.3", "9" * 40)))


def test_every_number_has_bounds_and_every_key_a_meaning():
    """Every numeric key of every built-in type (and of the shared section) states a finite range of its own,
    and every key says what it means: both live on the key's Param, in the type's catalogue module."""
    tables = {"shared": {"": config.GLOBALS}, **{name: role.builtin() for name, role in config.ROLES.items()}}
    for registry, types in tables.items():
        for type_name, specs in types.items():
            for key, spec in specs.items():
                if spec.kind in config.NUMERIC_KINDS:
                    assert spec.bounds is not None, f"{registry} {type_name}.{key} has no bounds"
                    low, high = spec.bounds
                    assert low < high and abs(low) < float("inf") > abs(high)
                if spec.kind != "dict":
                    assert spec.help, f"{registry} {type_name}.{key} does not say what it means"


def test_every_shipped_file_agrees_with_the_ros_parser():
    for path in sorted(CONFIG.glob("*.yaml")):
        load_experiment(path)


def _rcl_parser():
    """The ROS 2 parameter parser itself (librcl_yaml_param_parser of the ROS wheels), or None."""
    import ctypes
    lib = Path(sys.prefix) / "lib"
    try:
        rcutils = ctypes.CDLL(str(lib / "librcutils.so"))
        parser = ctypes.CDLL(str(lib / "librcl_yaml_param_parser.so"))
    except OSError:
        return None

    class Allocator(ctypes.Structure):
        _fields_ = [(name, ctypes.c_void_p) for name in ("allocate", "deallocate", "reallocate", "zero_allocate",
                                                          "state")]
    rcutils.rcutils_get_default_allocator.restype = Allocator
    parser.rcl_yaml_node_struct_init.restype = ctypes.c_void_p
    parser.rcl_yaml_node_struct_init.argtypes = [Allocator]
    parser.rcl_parse_yaml_file.argtypes = [ctypes.c_char_p, ctypes.c_void_p]
    parser.rcl_parse_yaml_file.restype = ctypes.c_bool
    parser.rcl_yaml_node_struct_fini.argtypes = [ctypes.c_void_p]

    def parses(path) -> bool:
        params = parser.rcl_yaml_node_struct_init(rcutils.rcutils_get_default_allocator())
        ok = parser.rcl_parse_yaml_file(str(path).encode(), params)
        rcutils.rcutils_reset_error()
        if ok:
            parser.rcl_yaml_node_struct_fini(params)
        return ok
    return parses


@pytest.mark.parametrize("value,kind", [
    ("y", "bool"), ("Off", "bool"), ("1:30", "string"), ("1_000", "string"), ("99999999999999999999", "double"),
    ("-9223372036854775808", "integer"), ("0x1F", "integer"), ("010", "integer"), ("09", "double"),
    ("1e-310", "string"), ("1e999", "string"), ("0x1p3", "double"), ("nan", "double"), (".inf", "double"),
    ("~", "string"), ("2024-01-01", "string"), ("1.", "double"), (".5", "double"), ("+3", "integer")])
def test_scalars_are_read_as_the_ros_parser_reads_them(value, kind):
    """config._ros_scalar follows rcl_yaml_param_parser's get_value (checked against the library itself
    where the ROS wheels hold it: a list of the value and a known integer parses only if both are integers)."""
    assert config._ros_scalar(value, None)[0] == kind
    assert config._ros_scalar(value, "'") == ("string", value)


def test_the_ros_parser_refuses_what_the_validator_refuses(tmp_path):
    parses = _rcl_parser()
    if parses is None:
        pytest.skip("no librcl_yaml_param_parser in this environment")
    good = tmp_path / "good.yaml"
    good.write_text(BASE)
    assert parses(good)
    for name, text in [("mixed", BASE.replace(CURVE, CIRCLE.replace("CENTER", "[0, 0.5]"))),
                       ("bare y", BASE.replace(AXES, "    axes: [x, y]")),
                       ("empty", BASE.replace(KD, "    kd:\n"))]:
        path = tmp_path / f"{name.replace(' ', '_')}.yaml"
        path.write_text(text)
        assert not parses(path), name
        with pytest.raises(ConfigError):
            load_experiment(path)


def test_cli_refuses_in_one_line_without_traceback(tmp_path):
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    bad = tmp_path / "bad.yaml"
    bad.write_text(BASE.replace(GLOBAL, "    sample_time: 1.0e-10\n"))
    escape = tmp_path / "escape.yaml"
    escape.write_text(BASE.replace(NAME, "      name: ../../outside\n"))
    for path in (fifo, Path("/dev/zero"), bad, escape):
        done = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "run", str(path)], capture_output=True,
                              text=True, timeout=60, cwd=tmp_path)
        assert done.returncode == 2, done.stderr
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and str(path) in lines[0] and "Traceback" not in done.stderr, done.stderr
    assert not (tmp_path / "bags").exists() and not (tmp_path.parent / "outside").exists()


def test_default_bag_name_stays_in_the_bag_folder(tmp_path):
    from contouring_ros.run.runner import default_bag_path
    experiment = load_experiment(DEFAULT)
    bags = tmp_path / "bags"
    for name in ("../../outside", "a/b", "..", "x" * 500, "name\x00nul", ""):
        odd = type(experiment)(**{**vars(experiment), "info": {"experiment": {"name": name}}})
        path = default_bag_path(odd, bags)
        assert path.resolve().parent == bags.resolve(), (name, path)
        assert len(path.name) < 200 and path.suffix == ".mcap"
    assert default_bag_path(experiment, bags).name.startswith("paper000_b_ismc_h50_newton_")
