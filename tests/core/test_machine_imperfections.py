"""The imperfections of a real feed drive on both plant types (core/plants.py, Axis): measurement noise,
encoder quantisation, computation delay, velocity from the differentiated encoder. Known answers, pure core."""
import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from contouring_ros.config import build_loop, parse_experiment
from contouring_ros.core.batch import NotBatchable, batchable, simulate_batch, stack
from contouring_ros.core.plants import NOISE_TABLE_LENGTH, FirstOrderVelocityAxis, MassDamperAxis, quantize
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import ConfigError
from contouring_ros.studies.sweep import combinations
from contouring_ros.experiment.settings import parse_grid
from conftest import CONFIG, DEFAULT, shortened

TS = 0.001
PLANTS = {"first_order_velocity": lambda **keys: FirstOrderVelocityAxis(10.3, 0.04, TS, **keys),
          "mass_damper": lambda **keys: MassDamperAxis(1.0, 798.5, 16.23, TS, **keys)}
both = pytest.mark.parametrize("model", sorted(PLANTS))


def _readings(plant, commands):
    """(position, velocity) readings at steps 0 .. len(commands), the plant stepping through ``commands``."""
    out = [plant.measure()]
    for k, command in enumerate(commands):
        plant.step(command, k * TS)
        out.append(plant.measure())
    return np.array(out)


def _commands(n=400, seed=7):
    return 0.05 * np.random.default_rng(seed).standard_normal(n)


@both
def test_the_same_seed_gives_the_same_noise_and_another_seed_other_noise(model):
    make = PLANTS[model]
    one, again, other = (_readings(make(measurement_noise=1e-6, noise_seed=seed), _commands()) for seed in (3, 3, 4))
    np.testing.assert_array_equal(one, again)
    assert np.all(one[:, 0] != other[:, 0])


@both
def test_the_noise_has_the_standard_deviation_given_and_repeats_after_its_table(model):
    sigma, position = 2e-6, 0.0123
    still = PLANTS[model](measurement_noise=sigma, noise_seed=5, position=position)
    readings = _readings(still, np.zeros(NOISE_TABLE_LENGTH))[:, 0]
    assert still.position == position and still.velocity == 0.0
    error = readings[:8000] - position
    assert abs(np.std(error) / sigma - 1.0) < 0.05 and abs(np.mean(error)) < 0.05 * sigma
    assert readings[NOISE_TABLE_LENGTH] == readings[0]


@both
def test_noisy_readings_are_multiples_of_the_encoder_resolution(model):
    resolution = 1e-7
    plant = PLANTS[model](measurement_noise=3e-7, noise_seed=1, encoder_resolution=resolution)
    positions = _readings(plant, _commands(2000))[:, 0]
    counts = positions / resolution
    assert_allclose(counts, np.round(counts), rtol=0.0, atol=1e-6)
    assert len(np.unique(np.round(counts))) > 10                 # the noise moves the reading across counts
    np.testing.assert_array_equal(positions, [quantize(p, resolution) for p in positions])


@both
def test_measure_is_pure(model):
    plant = PLANTS[model](measurement_noise=1e-6, noise_seed=2, encoder_resolution=1e-7,
                          velocity_measurement="encoder", command_delay=1)
    for k, command in enumerate(_commands(50)):
        first = plant.measure()
        assert all(plant.measure() == first for _ in range(3))
        plant.step(command, k * TS)


@both
def test_without_imperfections_the_plant_reads_its_state(model):
    plant = PLANTS[model](position=0.001, velocity=0.002)
    assert plant._noise is None and plant._held == ()
    for k, command in enumerate(_commands(20)):
        assert plant.measure() == (plant.position, plant.velocity)
        plant.step(command, k * TS)


def _step_response(model, steps=300, **keys):
    return _readings(PLANTS[model](**keys), np.full(steps, 0.3))


def _analytic(model, t):
    """Position of the plant from rest under a command 0.3 applied from t = 0 (0 before)."""
    t = np.maximum(t, 0.0)
    if model == "first_order_velocity":
        k, tau = 10.3, 0.04
        return k * 0.3 * (t - tau * (1 - np.exp(-t / tau)))
    a, gain = 798.5, 16.23
    return gain * 0.3 / a * (t - (1 - np.exp(-a * t)) / a)


@both
@pytest.mark.parametrize("delay", [0, 1, 3])
def test_a_delayed_command_shifts_the_response_by_the_delay(model, delay):
    undelayed = _step_response(model)
    delayed = _step_response(model, command_delay=delay)
    t = TS * np.arange(len(delayed))
    assert_allclose(delayed[:, 0], _analytic(model, t - delay * TS), rtol=1e-10, atol=1e-16)
    assert np.all(delayed[:delay + 1] == 0.0)                           # no command before the first arrives
    assert_allclose(delayed[delay:], undelayed[:len(undelayed) - delay], rtol=0.0, atol=1e-15)


@both
def test_the_saturation_clips_the_command_that_reaches_the_drive(model):
    clipped = PLANTS[model](command_delay=1, saturation=0.1)
    plain = PLANTS[model]()
    commands = [5.0, -5.0, 0.05, 0.0]
    for k, command in enumerate(commands):
        clipped.step(command, k * TS)
        plain.step([0.0, 0.1, -0.1, 0.05][k], k * TS)
        assert (clipped.position, clipped.velocity) == (plain.position, plain.velocity)


@both
def test_encoder_velocity_is_the_backward_difference_of_the_readings(model):
    plant = PLANTS[model](measurement_noise=2e-7, noise_seed=9, encoder_resolution=1e-7,
                          velocity_measurement="encoder", velocity=0.01)
    readings = _readings(plant, _commands())
    assert readings[0, 1] == 0.01                                  # step 0: the initial velocity
    np.testing.assert_array_equal(readings[1:, 1], (readings[1:, 0] - readings[:-1, 0]) / TS)


@both
def test_model_velocity_is_the_exact_state_velocity(model):
    plant = PLANTS[model](measurement_noise=2e-7, noise_seed=9, encoder_resolution=1e-7)
    for k, command in enumerate(_commands(100)):
        position, velocity = plant.measure()
        assert velocity == plant.velocity and position != plant.position
        plant.step(command, k * TS)


@both
def test_a_stacked_batch_of_seeds_equals_each_plant_alone(model):
    keys = {"measurement_noise": 5e-7, "encoder_resolution": 1e-7, "command_delay": 2,
            "velocity_measurement": "encoder"}
    alone = [PLANTS[model](noise_seed=seed, **keys) for seed in (1, 2, 3)]
    batch = stack([PLANTS[model](noise_seed=seed, **keys) for seed in (1, 2, 3)])
    assert batch._noise.shape == (3, NOISE_TABLE_LENGTH)
    commands = 0.05 * np.random.default_rng(0).standard_normal((200, 3, 1))
    for k, command in enumerate(commands):
        position, velocity = (np.broadcast_to(v, (3, 1))[:, 0] for v in batch.measure())
        for j, plant in enumerate(alone):
            assert_allclose((position[j], velocity[j]), plant.measure(), rtol=1e-12, atol=1e-18)
            plant.step(command[j, 0], k * TS)
        batch.step(command, k * TS)


def _imperfect(path, duration, **keys):
    """The experiment at ``path`` cut to ``duration``, with ``keys`` on every plant."""
    data = yaml.safe_load(shortened(path, duration))
    for axis in data["/**"]["ros__parameters"]["axes"]:
        data[f"/{axis}/plant"]["ros__parameters"].update(keys)
    return yaml.safe_dump(data)


MACHINE = {"measurement_noise": 1e-7, "encoder_resolution": 1e-7, "command_delay": 1,
           "velocity_measurement": "encoder"}


@pytest.mark.parametrize("path", [DEFAULT, CONFIG / "paper004_saddle_eso.yaml"], ids=["first-order", "mass-damper"])
def test_simulate_batch_of_seeds_equals_each_run_alone(path):
    text = _imperfect(path, 0.2, **MACHINE)
    grid = parse_grid(["x/plant.noise_seed=1,2,3"])
    loops = [build_loop(experiment) for _, experiment in combinations(text, grid)]
    assert batchable(loops)
    singles = [simulate(build_loop(experiment)) for _, experiment in combinations(text, grid)]
    for run, alone in zip(simulate_batch(loops), singles):
        for name, value in vars(alone).items():
            assert np.max(np.abs(getattr(run, name) - value)) <= 1e-12 * np.max(np.abs(value)), name
    assert not np.array_equal(singles[0].position, singles[1].position)


def test_plants_that_differ_in_kind_of_imperfection_refuse_to_stack():
    make = PLANTS["mass_damper"]
    for keys in ({"measurement_noise": 1e-7}, {"command_delay": 1}, {"velocity_measurement": "encoder"}):
        with pytest.raises(NotBatchable):
            stack([make(), make(**keys)])


def test_the_keys_reach_every_plant_and_default_to_an_ideal_machine():
    ideal = build_loop(parse_experiment(shortened(DEFAULT, 0.1), "ideal.yaml"))
    for plant in ideal.plants:
        assert (plant.measurement_noise, plant.noise_seed, plant.command_delay, plant.velocity_measurement,
                plant.encoder_resolution) == (0.0, 0, 0, "model", 0.0)
    for path in (DEFAULT, CONFIG / "paper004_saddle_eso.yaml"):
        loop = build_loop(parse_experiment(_imperfect(path, 0.1, noise_seed=3, **MACHINE), "real.yaml"))
        for plant in loop.plants:
            assert (plant.measurement_noise, plant.noise_seed, plant.command_delay, plant.velocity_measurement,
                    plant.encoder_resolution) == (1e-7, 3, 1, "encoder", 1e-7)


@pytest.mark.parametrize("key, value, expected", [
    ("measurement_noise", -1e-7, "/x/plant.measurement_noise: expected a value >= 0"),
    ("measurement_noise", "loud", "/x/plant.measurement_noise: expected a number"),
    ("noise_seed", -1, "/x/plant.noise_seed: expected a value >= 0"),
    ("noise_seed", 1.5, "/x/plant.noise_seed: expected an integer"),
    ("command_delay", -1, "/x/plant.command_delay: expected a value >= 0"),
    ("command_delay", 11, "/x/plant.command_delay: expected a value from 0 to 10"),
    ("command_delay", 0.5, "/x/plant.command_delay: expected an integer"),
    ("velocity_measurement", "foo", "/x/plant.velocity_measurement: expected one of model, encoder, got 'foo'"),
])
def test_bad_values_are_refused_in_one_line_naming_the_key(key, value, expected):
    data = yaml.safe_load(shortened(DEFAULT, 0.1))
    data["/x/plant"]["ros__parameters"][key] = value
    with pytest.raises(ConfigError) as info:
        parse_experiment(yaml.safe_dump(data), "exp.yaml")
    message = str(info.value)
    assert "\n" not in message and message.startswith("exp.yaml: ") and expected in message


@pytest.mark.parametrize("keys", [{"measurement_noise": -1.0}, {"noise_seed": -1}, {"command_delay": 11},
                                  {"velocity_measurement": "foo"}])
def test_the_core_refuses_what_the_validator_refuses(keys):
    with pytest.raises(ValueError):
        MassDamperAxis(1.0, 1.0, 1.0, TS, **keys)
