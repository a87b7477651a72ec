"""Each paper's central claims, tested under the paper's own reading and where the claim's mechanism acts.

The claims are read from ``config/claims/paper<N>.yaml`` (:mod:`.claims_file`: the format and the verdict
rules); here they are measured.

Machine and uncertainty. A claim is measured on the *realistic* machine of :mod:`contouring_ros.studies.machine`
(encoder, noise, one sample of delay, velocity from the encoder, an actuator limit of 2x the proposed file's
peak command where the file states none): the machine is made from the proposed file (its ideal run's peak
command) and put under BOTH files of the pair. The ratio is the median over :data:`DRAWS` paired draws (draw
j, :func:`contouring_ros.studies.machine.draw_settings`: noise seeds and +-:data:`MISMATCH` on every plant parameter,
the same draw for both files) with the 2.5-97.5 percentile interval of the per-draw ratios;
:func:`~.claims_file.interval_verdict` gives a verdict only where the whole interval has one (else 'undecided').
The ideal machine's ratio (no imperfections, no draws) is kept beside it. Sensitivity: each ``decisive`` entry's
keys are scaled x0.7 and x1.4 in both files alike (on the realistic machine, no draw: seed 0, no mismatch), and
:func:`~.claims_file.robustness` says whether the verdict of the median ratio stays the same ('robust') or flips
('knife-edge', naming where). ``expected`` and ``verdict`` are what the tests hold the measurement to
(the realistic medians, intervals and interval verdicts; the ideal ratios); ``python -m
contouring_ros.studies.claims`` prints the measurement beside them (:func:`main`). The regime maps are made by
:mod:`.claims_maps`, the report by :mod:`.claims_report`.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field

from ..experiment.ros_yaml import read_yaml
from ..errors import ConfigError
from .executors import pool as executor
from ..experiment.scenarios import CONFIG_DIR
from ..records.numbers import median_interval, number
from .claims_file import (METRICS, CCCHelps, Claim, Pair, claim_files, claim_verdict, interval_verdict, load_claims,
                          robustness, scenario_experiment, scenario_value)
from .claims_maps import draw_map, map_ratios
from .machine import draw_settings, machine_settings
from .outcomes import run_outcomes
from .summaries import interval
from .sweep import score_experiments

__all__ = ["DRAWS", "MISMATCH", "SCALES", "ScenarioScores", "peak_commands", "Plan", "plan_pair", "Measured",
           "ClaimResult", "evaluate", "ccc_helps_scores", "um_text", "ratio_text", "paper_ratio_text",
           "interval_text", "sensitivity_text", "main"]

DRAWS = 8               # paired draws per claim pair (noise seeds, model mismatch, disturbance phase)
MISMATCH = 0.1          # model mismatch of a draw: each plant parameter x U(1 - this, 1 + this)
SCALES = (0.7, 1.4)     # the sensitivity factors of each decisive parameter


# ---------------------------------------------------------------------------------------------- measuring


@dataclass
class ScenarioScores:
    """Scores of scenarios (with optional settings applied) at the start times asked for, computed once."""

    workers: int | None = None
    cache: dict = field(default_factory=dict)
    scheduler: str | None = None     # a Dask scheduler's address (contouring_ros.studies.executors), else local processes

    @staticmethod
    def _key(name, settings, from_time):
        return name, repr(sorted((settings or {}).items())), float(from_time)

    def need(self, requests: list) -> None:
        """Simulate every (scenario, settings, from_time) not yet scored, on the process pool."""
        missing = {}
        for name, settings, from_time in requests:
            key = self._key(name, settings, from_time)
            if key not in self.cache:
                missing[key] = (name, settings, from_time)
        by_time = {}
        for key, (name, settings, from_time) in missing.items():
            by_time.setdefault(float(from_time), []).append((key, scenario_experiment(name, settings)))
        for from_time, runs in by_time.items():
            results = score_experiments([e for _, e in runs], self.workers, from_time=from_time, batch=1,
                                        scheduler=self.scheduler)
            for (key, _), (scores, _, failure) in zip(runs, results):
                self.cache[key] = (scores, failure)

    def get(self, name: str, from_time: float, settings: dict | None = None):
        key = self._key(name, settings, from_time)
        if key not in self.cache:
            self.need([(name, settings, from_time)])
        return self.cache[key]


def _scenario_data(name: str) -> dict:
    return read_yaml((CONFIG_DIR / f"{name}.yaml").read_text(), name)


def _peak_command(name: str, from_time: float) -> tuple:
    """The largest |command| per axis of the scenario's ideal run (() where it diverged)."""
    outcome = run_outcomes(_scenario_data(name), {}, [{}], from_time, name)[0]
    return outcome.peak_command if outcome.ok else ()


def peak_commands(names: list, from_time: dict, workers: int | None = None, scheduler: str | None = None) -> dict:
    """name -> its ideal run's peak command per axis, on a process pool (or the Dask cluster at ``scheduler``)."""
    names = list(dict.fromkeys(names))
    if not names:
        return {}
    with executor(min(len(names), workers) if workers else None, scheduler) as (pool, _):
        return dict(zip(names, pool.map(_peak_command, names, [from_time[n] for n in names])))


def _scaled(value, factor: float, where: str):
    if isinstance(value, bool) or value is None:
        raise ConfigError(f"{where}: no number to scale (the file leaves it to a default): name a key it sets")
    if isinstance(value, list):
        return [_scaled(v, factor, where) for v in value]
    if not isinstance(value, (int, float)):
        raise ConfigError(f"{where}: {value!r} is not a number to scale")
    return float(value) * factor


@dataclass(frozen=True)
class Plan:
    """The settings of every run of one claim pair (reading): the machine made from the proposed file, the
    paired draws, the seed-0 run and the decisive parameters' scaled runs, per file (proposed, baseline)."""

    machine: dict
    draws: tuple        # (proposed settings, baseline settings) per draw
    nominal: tuple      # (proposed, baseline): the realistic machine, seed 0, no mismatch
    scaled: dict        # (label, factor) -> (proposed, baseline)


def plan_pair(claim: "Claim", pair: Pair, peak: tuple, draws: int = DRAWS, machine: str = "realistic",
              sensitivity: bool = True) -> Plan:
    data = (_scenario_data(pair.proposed), _scenario_data(pair.baseline))
    made = machine_settings(data[0], machine, peak)
    if machine == "ideal":
        runs = ((dict(), dict()),)
    else:
        runs = tuple(tuple(dict(made, **draw_settings(d, j, MISMATCH)) for d in data) for j in range(draws))
    scaled = {}
    if sensitivity:
        for entry in claim.decisive:
            for factor in SCALES:
                both = []
                for side, name in (("proposed", pair.proposed), ("baseline", pair.baseline)):
                    settings = dict(made)
                    if entry.only in (None, side):
                        for key in entry.keys:
                            base = made.get(key, scenario_value(name, key))
                            settings[key] = _scaled(base, factor, f"claims {claim.paper}/{claim.id}: decisive "
                                                                  f"{entry.label!r}: {name} {key}")
                    both.append(settings)
                scaled[(entry.label, factor)] = tuple(both)
    return Plan(made, runs, (dict(made), dict(made)), scaled)


@dataclass(frozen=True)
class Measured:
    """One pair's scores: ideal (proposed, baseline), per draw, seed 0 and scaled (same shapes)."""

    ideal: tuple
    draws: tuple
    nominal: tuple
    scaled: dict
    machine: dict


def _ratio_of(pair, metric: str):
    if not pair or pair[0] is None or pair[1] is None:
        return None
    proposed, baseline = getattr(pair[0], metric), getattr(pair[1], metric)
    if not baseline or not math.isfinite(proposed) or not math.isfinite(baseline):
        return None
    return proposed / baseline


@dataclass(frozen=True)
class ClaimResult:
    claim: Claim
    measured: dict      # reading -> Measured (or None)

    @property
    def scores(self) -> dict:
        """reading -> the ideal machine's (proposed Scores, baseline Scores)."""
        return {reading: m.ideal for reading, m in self.measured.items() if m is not None}

    def draw_ratios(self, reading: str, metric: str | None = None) -> list:
        m = self.measured.get(reading)
        return [] if m is None else [_ratio_of(d, metric or self.claim.metric) for d in m.draws]

    def value(self, reading: str, side: int, metric: str | None = None):
        """The median of the side's metric over the draws (realistic machine)."""
        m = self.measured.get(reading)
        if m is None:
            return None
        values = [getattr(d[side], metric or self.claim.metric) for d in m.draws if d[side] is not None]
        median = interval(values)[0]
        return None if not math.isfinite(median) else median

    def ideal_value(self, reading: str, side: int, metric: str | None = None):
        m = self.measured.get(reading)
        if m is None or m.ideal[side] is None:
            return None
        return getattr(m.ideal[side], metric or self.claim.metric)

    def interval(self, reading: str, metric: str | None = None) -> tuple:
        """(median, 2.5%, 97.5%) of the per-draw ratios (None each where no draw has one)."""
        ratios = [r for r in self.draw_ratios(reading, metric) if r is not None]
        if not ratios:
            return None, None, None
        return interval(ratios)

    def ratio(self, reading: str, metric: str | None = None):
        return self.interval(reading, metric)[0]

    def ideal_ratio(self, reading: str, metric: str | None = None):
        m = self.measured.get(reading)
        return None if m is None else _ratio_of(m.ideal, metric or self.claim.metric)

    def verdict(self, reading: str) -> str:
        _, low, high = self.interval(reading)
        return interval_verdict(low, high, self.claim.paper_ratio)

    def ideal_verdict(self, reading: str) -> str:
        return claim_verdict(self.ideal_ratio(reading), self.claim.paper_ratio)

    def failures(self, reading: str) -> int:
        """Draws without a ratio (a run diverged)."""
        return sum(1 for r in self.draw_ratios(reading) if r is None)

    def nominal_ratio(self, reading: str):
        m = self.measured.get(reading)
        return None if m is None else _ratio_of(m.nominal, self.claim.metric)

    def scaled_verdicts(self, reading: str) -> dict:
        m = self.measured.get(reading)
        if m is None:
            return {}
        return {key: claim_verdict(_ratio_of(pair, self.claim.metric), self.claim.paper_ratio)
                for key, pair in m.scaled.items()}

    def scaled_ratios(self, reading: str) -> dict:
        m = self.measured.get(reading)
        return {} if m is None else {key: _ratio_of(pair, self.claim.metric) for key, pair in m.scaled.items()}

    def robustness(self, reading: str) -> tuple:
        return robustness(claim_verdict(self.nominal_ratio(reading), self.claim.paper_ratio), self.scaled_verdicts(reading))


def evaluate(claims: list, scores: ScenarioScores | None = None, draws: int = DRAWS, machine: str = "realistic",
             sensitivity: bool = True) -> list:
    """A ClaimResult per claim: its pairs simulated under both readings on the ideal machine and on
    ``machine`` with ``draws`` paired draws, seed 0 and (with ``sensitivity``) the decisive parameters scaled;
    every distinct run once, on the process pool."""
    scores = scores or ScenarioScores()
    pairs = [(c, reading, c.pair(reading)) for c in claims for reading in ("faithful", "mechanism") if c.pair(reading)]
    times = {}
    for c, _, pair in pairs:
        times.setdefault(pair.proposed, c.from_time)
    peaks = peak_commands([pair.proposed for _, _, pair in pairs], times, scores.workers, scores.scheduler) \
        if machine != "ideal" else {}
    plans = {(c.id, reading): plan_pair(c, pair, peaks.get(pair.proposed, ()), draws, machine, sensitivity)
             for c, reading, pair in pairs}
    requests = []
    for c, reading, pair in pairs:
        plan = plans[(c.id, reading)]
        names = (pair.proposed, pair.baseline)
        requests += [(name, None, c.from_time) for name in names]
        for both in list(plan.draws) + [plan.nominal] + list(plan.scaled.values()):
            requests += [(name, settings, c.from_time) for name, settings in zip(names, both)]
    scores.need(requests)

    def got(name, settings, from_time):
        return scores.get(name, from_time, settings or None)[0]

    out = []
    for c in claims:
        measured = {}
        for reading in ("faithful", "mechanism"):
            pair = c.pair(reading)
            if not pair:
                continue
            plan = plans[(c.id, reading)]
            names = (pair.proposed, pair.baseline)
            measured[reading] = Measured(
                ideal=tuple(got(n, None, c.from_time) for n in names),
                draws=tuple(tuple(got(n, s, c.from_time) for n, s in zip(names, both)) for both in plan.draws),
                nominal=tuple(got(n, s, c.from_time) for n, s in zip(names, plan.nominal)),
                scaled={key: tuple(got(n, s, c.from_time) for n, s in zip(names, both))
                        for key, both in plan.scaled.items()},
                machine=plan.machine)
        out.append(ClaimResult(c, measured))
    return out


def ccc_helps_scores(entry: CCCHelps, scores: ScenarioScores | None = None) -> tuple:
    """(metric with the CCC, metric without it) for a CCCHelps entry."""
    scores = scores or ScenarioScores()
    with_ccc = scores.get(entry.scenario, entry.from_time)[0]
    without = scores.get(entry.scenario, entry.from_time, entry.without)[0]
    return (getattr(with_ccc, entry.metric) if with_ccc else math.nan,
            getattr(without, entry.metric) if without else math.nan)



# ---------------------------------------------------------------------------------------------- as text


def um_text(value) -> str:
    """A length [m] in micrometres to 3 digits; '-' for none."""
    return number(value, scale=1e6)


def ratio_text(value) -> str:
    """A measured ratio to 3 digits; '-' for none or one that is not finite."""
    return number(value, finite=True)


def paper_ratio_text(value) -> str:
    """The paper's ratio to 3 digits; '-' where the paper gives no figure."""
    return number(value)


def interval_text(result: ClaimResult, reading: str) -> str:
    """'median [low, high]' of a reading's per-draw ratios, and how many draws diverged; '-' for none."""
    median, low, high = result.interval(reading)
    if median is None:
        return "-"
    failed = result.failures(reading)
    # a narrow interval (an inert term) shown as it is
    return median_interval(median, low, high, narrow_digits=6) + (f" ({failed} draws diverged)" if failed else "")


def sensitivity_text(result: ClaimResult, reading: str) -> str:
    """'robust' or 'knife-edge (the flips)' of a reading; '-' for a claim without decisive parameters."""
    word, flips = result.robustness(reading)
    if word == "not testable":
        return word if result.claim.decisive else "-"
    return word + (f" ({'; '.join(flips)})" if flips else "")


# ---------------------------------------------------------------------------------------------- command line


def main(argv=None) -> int:
    """python -m contouring_ros.studies.claims [FILE ...] [--maps]: evaluate claims files and print each claim's
    ratios and verdicts against what the file expects (for writing a claims file)."""
    import argparse
    parser = argparse.ArgumentParser(prog="python -m contouring_ros.studies.claims", description=main.__doc__)
    parser.add_argument("files", nargs="*", help="claims files (default: config/claims/paper*.yaml)")
    parser.add_argument("--maps", action="store_true", help="also compute and draw the regime maps into --out/maps")
    parser.add_argument("--out", default="reports")
    parser.add_argument("--draws", type=int, default=DRAWS, help=f"paired draws per pair (default {DRAWS})")
    parser.add_argument("--claim", action="append", help="only these claim ids (repeatable)")
    parser.add_argument("--yaml", action="store_true", help="also print the expected values in the file's form")
    args = parser.parse_args(argv)
    try:
        scores = ScenarioScores()
        for path in args.files or claim_files():
            paper = load_claims(path)
            if args.claim:
                import dataclasses
                paper = dataclasses.replace(paper, claims=tuple(c for c in paper.claims if c.id in args.claim),
                                            ccc_helps=())
            for result in evaluate(list(paper.claims), scores, draws=args.draws):
                c = result.claim
                print(f"{paper.paper}/{c.id} [{c.metric}{f' t>={c.from_time:g}' if c.from_time else ''}] paper "
                      f"{paper_ratio_text(c.paper_ratio)}")
                for reading in ("faithful", "mechanism"):
                    if c.pair(reading) is None:
                        continue
                    median, low, high = result.interval(reading)
                    print(f"  {reading:9s} ratio {interval_text(result, reading)} (expected "
                          f"{c.expected.get(f'{reading}_ratio')} {c.expected.get(f'{reading}_interval')}) verdict "
                          f"{result.verdict(reading)!r} (stated {c.verdict.get(reading)!r}); ideal "
                          f"{ratio_text(result.ideal_ratio(reading))} (expected {c.expected.get(f'ideal_{reading}_ratio')})"
                          f" {result.ideal_verdict(reading)!r}; proposed {um_text(result.value(reading, 0))} um,"
                          f" baseline {um_text(result.value(reading, 1))} um")
                    print(f"    seed 0 {ratio_text(result.nominal_ratio(reading))}; " + "; ".join(
                        f"{label} x{f:g} {ratio_text(r)}" for (label, f), r in result.scaled_ratios(reading).items())
                        + f" -> {sensitivity_text(result, reading)}")
                    if args.yaml:
                        print(f"    yaml: {reading}_ratio: {median:.4g}, {reading}_interval: [{low:.6g}, {high:.6g}], "
                              f"ideal_{reading}_ratio: {ratio_text(result.ideal_ratio(reading))}; verdict "
                              f"{result.verdict(reading)}")
                if args.maps:
                    for i, spec in enumerate(c.maps):
                        print("  map:", draw_map(c, spec, map_ratios(c, spec, progress=sys.stderr.isatty()),
                                                 c.map_path(i, args.out)))
            for entry in paper.ccc_helps:
                with_ccc, without = ccc_helps_scores(entry, scores)
                print(f"{paper.paper} ccc_helps {entry.scenario} without {entry.without}: {with_ccc * 1e6:.4g} vs "
                      f"{without * 1e6:.4g} um ({METRICS[entry.metric]}), ratio {with_ccc / without:.3g}, stated "
                      f"factor {entry.factor:g}")
    except ConfigError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
