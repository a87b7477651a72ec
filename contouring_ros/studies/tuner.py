"""One combination's tuning as an object with named steps (the protocol: :mod:`contouring_ros.studies.tuning`):
a batch of points measured on the nominal plant and, for those that could become their search's choice, at
every robustness perturbation; the populations of independent searches evaluated side by side as one batch;
what each search ends with; more searches while they do not agree; the best search kept; the draws, the ideal
machine and the margins of the kept gains."""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from ..core.tuning_space import Space
from ..errors import ConfigError
from .gains import sections_with_gains
from .loops import experiment_margins, loop_robustness, worst_margins
from .machine import actuator_limits, draw_settings, perturbations
from .objective import DIVERGED, UNSTABLE, Constraints
from .outcomes import experiment_for, experiment_outcomes, run_outcomes
from .search import IPOPCMAES, Agreement, agreement, run_side_by_side
from .space import tuned_servo, tuning_space
from .tuning import Evaluation, Outcome, Protocol, Search, Tuned

__all__ = ["best_search", "chosen_point", "compared_values", "lowest_objective", "searches_agreement",
           "median_tace", "selection_candidates", "Tuning", "tune"]


def best_search(searches: list) -> Search:
    """The search a combination keeps from its independent searches, judged by what each search itself
    measured, never by the draws: a robust chosen point with the lowest nominal TACE; where no search found
    one, a not-robust point with the lowest worst case over the perturbations; where none found an admissible
    point, the first search's status. Ties go to the earlier search."""
    robust = [s for s in searches if s.status == "ok" and math.isfinite(s.tace)]
    if robust:
        return min(robust, key=lambda s: s.tace)
    fallback = [s for s in searches if s.chosen is not None]
    if fallback:
        return min(fallback, key=lambda s: s.chosen.worst if math.isfinite(s.chosen.worst) else math.inf)
    return searches[0]


def compared_values(searches: list) -> tuple:
    """(what a row's searches are compared by, each search's value): the nominal TACE of the robust choices
    (inf for a search without one); where no search found an admissible point, the lowest objective each
    reached, penalties included (:attr:`~contouring_ros.studies.tuning.Search.penalised`): what the searches
    minimised, so that they agree when each ended at the same optimum of it, the same conflict of constraints
    (a not-robust choice's own worst case is not what a search minimises: two searches at one optimum of the
    objective can hold choices whose worst cases differ severalfold)."""
    values = [s.value for s in searches]
    if any(math.isfinite(v) for v in values):
        return "nominal TACE", values
    return "lowest objective as a TACE (no search found an admissible point)", [s.penalised for s in searches]


def searches_agreement(searches: list, protocol: Protocol) -> Agreement:
    """How far a row's searches agree (:func:`contouring_ros.studies.search.agreement` with the protocol's
    tolerance) on their :func:`compared_values`."""
    return agreement(compared_values(searches)[1], protocol.agreement, protocol.agree)


def chosen_point(mine: list) -> tuple:
    """(the point a search with evaluations ``mine`` ends with, whether it is robust): its admissible point
    (robust, quiet, unsaturated) of lowest nominal TACE; where it has none, its point of lowest worst case
    among those that met every other constraint (not robust: quiet and unsaturated, within the Ms bound); else
    (None, False): a point that breaks the noise bound or the saturation share is never given, robust or not."""
    admissible = [e for e in mine if e.admissible]
    if admissible:
        return min(admissible, key=lambda e: e.outcome.tace), True
    fragile = [e for e in mine if e.outcome.failure.startswith("not robust") and e.quiet]
    if fragile:
        return min(fragile, key=lambda e: e.worst), False
    return None, False


def selection_candidates(evaluations: list, best: float, tolerance: float, count: int, spacing: float) -> list:
    """The admissible points of ``evaluations`` whose nominal TACE is within ``tolerance`` (a share) of
    ``best``, lowest first, at most ``count`` of them and each at least ``spacing`` (in every coordinate's
    share of its range, the largest) from those before it: the points a row's agreement would count as one
    result (:func:`searches_agreement`), one of each neighbourhood (two points of the same gains, as two unit
    points of one option of a choice coordinate are, count once)."""
    near = sorted((e for e in evaluations if e.admissible and e.outcome.tace <= best * (1.0 + tolerance)),
                  key=lambda e: e.outcome.tace)
    out = []
    for e in near:
        if len(out) >= count:
            break
        if all(e.gains != o.gains and max((abs(a - b) for a, b in zip(e.unit, o.unit)), default=0.0) >= spacing
               for o in out):
            out.append(e)
    return out


def median_tace(outcomes: list) -> float:
    """The median steady-state TACE of ``outcomes``, a diverged one counting as inf."""
    return float(np.median([o.tace if o.ok else math.inf for o in outcomes])) if outcomes else math.inf


def lowest_objective(mine: list) -> float:
    """The lowest objective of a search's evaluations ``mine`` among the points that ran (penalties
    included); inf where every point diverged or was refused unrun."""
    return min((e.objective for e in mine if e.objective < UNSTABLE), default=math.inf)


@dataclass
class _Run:
    """One search under way: its index and its evaluations."""

    index: int
    evaluations: list = field(default_factory=list)


class Tuning:
    """One combination's tuning (see :mod:`contouring_ros.studies.tuning`), as named steps: :meth:`measure` a
    batch of points, each on the nominal plant and at every robustness perturbation, in one vectorised batch,
    judged by the :class:`~contouring_ros.studies.objective.Constraints`; :meth:`evaluate` one round of the
    populations of searches side by side (:meth:`population`: one search's); :meth:`search` from given seeds
    and :meth:`choose` what each ends with; :meth:`search_until_agreed` more searches while they do not agree
    (:meth:`more`, up to the cap); :meth:`keep` the best; :meth:`draws` for its gains. :meth:`run` is all of
    them in order."""

    def __init__(self, data: dict, sections: dict, keys: tuple, machine: dict, noise_limit: float, from_time: float,
                 protocol: Protocol, where: str = "tuning", robust_floor: float = 0.0, space: Space | None = None):
        self.data, self.sections, self.machine, self.where = data, sections, machine, where
        self.from_time, self.protocol = from_time, protocol
        self.constraints = Constraints(protocol, noise_limit, robust_floor)
        self.space, self.validated = tuning_space(data, sections, keys, protocol, where, machine)
        self.servo_tuned = tuned_servo(experiment_for(data, sections, {}, where)) is not None
        if space is not None:
            self.space = space
        self.checks = perturbations(data, protocol.perturbation)
        self.limits = [actuator_limits(data, dict(machine, **change)) for change in [{}] + self.checks]
        self.tuned = Tuned(file_gains=({k: sections["/ccc"][k] for k in keys}), space=self.space.describe())

    # --- runs ----------------------------------------------------------------------------------------
    def with_gains(self, gains: dict) -> dict:
        """The combination's sections with the raw ``gains`` set."""
        return sections_with_gains(self.sections, gains)

    #: the robustness runs of a batch go in stages: each search's best STAGES[0] points that could become its
    #: choice, then the rest of those that still could (an admissible point among the first lowers the bar)
    STAGES = (2, math.inf)

    def measure(self, points: list, groups: list | None = None, best: dict | None = None) -> list:
        """An Evaluation per (unit point, values, gains): every point on the nominal plant in one batch, then,
        in :attr:`STAGES`, the points that could become their search's choice with each plant parameter at
        +-perturbation (:func:`~contouring_ros.studies.machine.perturbations`), each batch run as one where the
        classes allow. A point is refused unrun where its linear loop is unstable; beyond the Ms bound
        (:func:`~contouring_ros.studies.loops.loop_robustness`), not robust (its worst TACE over the
        perturbations above robust_factor x its nominal TACE and above the floor), too noisy or saturated it is
        inadmissible, its objective paying for it continuously across each bound
        (:mod:`contouring_ros.studies.objective`), so that a search can settle on an optimum on a bound.

        ``groups[i]``: which search point i belongs to (default: all one); ``best[group]``: that search's best
        admissible objective so far (default, or a search not named: none yet). A point whose nominal objective is
        not below its search's best admissible objective (the points of this batch checked before it
        included) cannot become that search's choice: an admissible point's objective is its nominal one,
        and the penalties only add. Its robustness runs are not made; its objective is the nominal one (a
        lower bound) and it is not admissible (:attr:`Evaluation.worst` nan). Every point that could be
        chosen is run at every perturbation, so a search chooses what it would were every point checked."""
        groups = [0] * len(points) if groups is None else groups
        best = {group: (best or {}).get(group, math.inf) for group in groups}
        out, outcomes, loops = self._nominal(points)
        waiting = sorted((i for i, o in outcomes.items() if o.ok and not out[i].outcome.failure.startswith("Ms")),
                         key=lambda i: out[i].objective)
        for stage in self.STAGES:
            checked = self._could_be_chosen(waiting, out, groups, best, stage)
            if not checked:
                break
            self._perturbed(checked, out, outcomes, loops)
            for i in checked:
                if out[i].admissible:
                    best[groups[i]] = min(best[groups[i]], out[i].objective)
            done = set(checked)
            waiting = [i for i in waiting if i not in done]
        return out

    def _nominal(self, points: list) -> tuple:
        """(an Evaluation per point, {i: point i's nominal Outcome}, {i: its linear loop's (Ms, stable, allowed
        Ms) or None}): the points that are not refused (a ConfigError, an unstable linear loop) run on the
        nominal plant in one batch, each judged without its robustness runs."""
        out, nominal, owners, loops = [], [], [], {}
        for unit, values, gains in points:
            out.append(Evaluation(gains, Outcome(), DIVERGED, False, unit=unit, point=values))
            try:
                here = experiment_for(self.data, self.with_gains(gains), self.machine, self.where)
            except ConfigError as error:
                out[-1].outcome = Outcome(failure=f"refused: {error}")
                continue
            robustness = loop_robustness(here, self.servo_tuned) if self.protocol.ms_limit else None
            if robustness is not None and not robustness[1]:
                out[-1].outcome = Outcome(failure="refused: its linear loop is unstable")
                out[-1].objective = UNSTABLE
                continue
            loops[len(out) - 1] = robustness
            nominal.append(here)
            owners.append(len(out) - 1)
        outcomes = dict(zip(owners, experiment_outcomes(nominal, self.from_time, [self.limits[0]] * len(nominal))))
        for i, outcome in outcomes.items():
            self.constraints.judge(out[i], outcome, None, loops[i])
        return out, outcomes, loops

    @staticmethod
    def _could_be_chosen(waiting: list, out: list, groups: list, best: dict, stage: float) -> list:
        """Of the points ``waiting`` (by objective), those whose nominal objective is below their search's best
        admissible one, at most ``stage`` of each search."""
        counts, checked = {}, []
        for i in waiting:
            if out[i].objective < best[groups[i]] and counts.get(groups[i], 0) < stage:
                counts[groups[i]] = counts.get(groups[i], 0) + 1
                checked.append(i)
        return checked

    def _perturbed(self, checked: list, out: list, outcomes: dict, loops: dict) -> None:
        """The points ``checked`` run at every perturbation, in one batch, and judged with those runs."""
        perturbed = [experiment_for(self.data, self.with_gains(out[i].gains), dict(self.machine, **change),
                                    self.where) for i in checked for change in self.checks]
        runs = experiment_outcomes(perturbed, self.from_time, self.limits[1:] * len(checked))
        self.tuned.robustness_runs += len(runs)
        n = len(self.checks)
        for k, i in enumerate(checked):
            self.constraints.judge(out[i], outcomes[i], runs[k * n:(k + 1) * n], loops[i])

    def evaluate(self, runs: list, asked: list) -> list:
        """One round of searches side by side: every search's points (``asked[i]`` of ``runs[i]``, unit points)
        measured in one batch (:meth:`measure`). Returns each search's objectives."""
        best = {run.index: min((e.objective for e in run.evaluations if e.admissible), default=math.inf)
                for run in runs}
        groups = [run.index for run, units in zip(runs, asked) for _ in units]
        evaluations = self.measure([(list(u), *self.space.decode(u)) for units in asked for u in units],
                                   groups, best)
        out, at = [], 0
        for run, units in zip(runs, asked):
            mine = evaluations[at:at + len(units)]
            at += len(units)
            for e in mine:
                e.search = run.index
            run.evaluations += mine
            out.append([e.objective for e in mine])
        self.tuned.evaluations += evaluations
        return out

    def population(self, run: _Run, units: list) -> list:
        """The objectives of one search's population ``units`` (:meth:`evaluate` of that search alone)."""
        return self.evaluate([run], [units])[0]

    def _round(self, runs: list, searches: list, asked: list) -> list:
        """One round of :func:`contouring_ros.studies.search.run_side_by_side`: ``asked`` is the points of the
        ``searches`` still running, ``runs`` every search's run in the same order."""
        return self.evaluate([run for run, search in zip(runs, searches) if not search.done], asked)

    # --- searches --------------------------------------------------------------------------------------
    def start(self, index: int) -> list:
        """Search 0 starts from the file's gains, the others from a point drawn uniformly in the box (from
        their seed); each then goes from the best of its design's points where that is better."""
        if index == 0:
            return self.space.start(self.validated)
        rng = np.random.default_rng(10_000 + self.protocol.seed + index)
        return list(rng.uniform(0.0, 1.0, len(self.space.dimensions)))

    def search(self, indices: list, optimiser=None, evaluations: int | None = None) -> list:
        """Searches ``indices`` (search i: seed protocol.seed + i) and the choice each ends with
        (:meth:`choose`). Search 0 evaluates the file's gains first. The searches run side by side, their
        populations in one batch (:func:`contouring_ros.studies.search.run_side_by_side`); another ``optimiser``
        runs them one at a time. ``evaluations``: each search's budget (default: the protocol's)."""
        p = self.protocol
        evaluations = p.evaluations if evaluations is None else int(evaluations)
        runs = [_Run(i) for i in indices]
        for run in runs:
            if run.index == 0:
                self.evaluate([run], [[self.start(0)]])
        budget = {run.index: evaluations - len(run.evaluations) for run in runs}
        if optimiser is not None:
            for run in runs:
                optimiser(functools.partial(self.population, run), self.start(run.index), budget[run.index],
                          p.seed + run.index)
        else:
            self._side_by_side(runs, budget, evaluations)
        return [self.choose(run.evaluations) for run in runs]

    def _side_by_side(self, runs: list, budget: dict, evaluations: int) -> None:
        """The ``runs`` as IPOP-CMA-ES searches side by side, each within its ``budget``, search 0 told the
        value of its start (the file's gains, evaluated first)."""
        p = self.protocol
        searches = [IPOPCMAES(self.start(run.index), budget[run.index], p.seed + run.index, p.popsize, p.step,
                              self.space.steps, math.log10(1.0 + p.agreement), p.design,
                              round(p.polish * evaluations), p.polish_step) for run in runs]
        for run, search in zip(runs, searches):
            if run.evaluations:                      # search 0: the file's gains, evaluated first
                search.known_start(run.evaluations[0].objective)
        run_side_by_side(searches, functools.partial(self._round, runs, searches))

    def choose(self, mine: list) -> Search:
        """What a search ends with: its admissible point (robust, quiet, unsaturated) of lowest nominal TACE;
        where it has none, its point of lowest worst case among those that met every other constraint,
        marked not robust; else no admissible gain."""
        p = self.protocol
        chosen, robust = chosen_point(mine)
        lowest = lowest_objective(mine)
        if robust:
            return Search(chosen, "ok", chosen.worst / chosen.outcome.tace, len(mine), lowest)
        if chosen is not None:
            status = (f"not robust: no point of the search stays within {p.robust_factor:g}x at "
                      f"+-{100 * p.perturbation:g}% of a plant parameter while meeting the other constraints "
                      f"(given: the point with the lowest worst case)")
            return Search(chosen, status, chosen.worst / chosen.outcome.tace, len(mine), lowest)
        failures = sorted({e.outcome.failure.split(":")[0].split(" at t = ")[0] for e in mine if e.outcome.failure})
        limit = self.constraints.noise_limit
        noisy = [e.outcome.noise / limit for e in mine if e.outcome.noise == e.outcome.noise and limit > 0]
        return Search(None, "no admissible gain: every point diverged or broke a constraint"
                      + (f" (least noise {min(noisy):.3g} x the bound)" if noisy else "")
                      + (f" ({'; '.join(failures)})" if failures else ""), evaluations=len(mine), lowest=lowest)

    # --- the whole tuning ----------------------------------------------------------------------------
    def search_until_agreed(self, optimiser=None) -> list:
        """protocol.searches searches, then more side by side while they do not agree (:meth:`more`), then
        rounds of longer ones while they still do not (:meth:`Protocol.budgets`); with nothing to tune, search 0
        alone (the file's gains, measured once)."""
        p = self.protocol
        if not self.space.dimensions:
            return self.search([0], optimiser)
        searches = self.search(list(range(p.searches)), optimiser)
        more = self.more(searches)
        while more:
            searches += self.search(list(range(len(searches), len(searches) + more)), optimiser)
            more = self.more(searches)
        for evaluations in p.budgets():           # Protocol.budget_growth: longer searches while they disagree
            if searches_agreement(searches, p).converged:
                break
            searches += self.search(list(range(len(searches), len(searches) + p.searches)), optimiser, evaluations)
        return searches

    def more(self, searches: list) -> int:
        """How many more searches to run after ``searches``: none once they agree (:func:`searches_agreement`)
        or they reach the cap (the larger of protocol.max_searches and protocol.searches), else as many as the
        agreement lacks (at least one), within the cap."""
        p = self.protocol
        cap = max(p.max_searches, p.searches)
        if len(searches) >= cap:
            return 0
        agreed = searches_agreement(searches, p)
        if agreed.converged:
            return 0
        return min(max(p.agree - agreed.agreed, 1), cap - len(searches))

    def keep(self, searches: list) -> Search:
        """The search kept (:func:`best_search`), recorded in :attr:`tuned` with the searches' agreement, each
        search's TACE and evaluations, and the kept point: of a robust result, the one :meth:`select` picks
        over the selection draws."""
        p, tuned = self.protocol, self.tuned
        kept = best_search(searches)
        # nothing to tune: no search to agree with, the file's gains are the answer
        tuned.agreement = searches_agreement(searches, p) if self.space.dimensions else Agreement(1, 1, 1.0, True)
        tuned.search_tace = [s.tace for s in searches]
        tuned.search_evaluations = [s.evaluations for s in searches]
        tuned.status = kept.status
        if kept.chosen is not None and kept.status == "ok" and self.space.dimensions and p.selection_draws:
            chosen = self.select(kept.chosen)
            kept = Search(chosen, kept.status, chosen.worst / chosen.outcome.tace, kept.evaluations, kept.lowest)
        tuned.search = kept.chosen.search if kept.chosen is not None else searches.index(kept)
        tuned.robust_worst = kept.robust_worst
        if kept.chosen is not None:
            chosen = kept.chosen
            tuned.gains, tuned.nominal, tuned.point = chosen.gains, chosen.outcome, chosen.point
            tuned.point_text = self.space.text(chosen.point)
            tuned.at_bound = self.space.at_bound(chosen.unit)
        return kept

    def select(self, best: Evaluation) -> Evaluation:
        """Of the admissible points whose nominal TACE is within the agreement's tolerance of ``best``'s (the
        lowest; :func:`selection_candidates`, from every search), the one of lowest median TACE over the
        protocol's selection draws: draws ``draws`` to ``draws + selection_draws - 1``, never the report's
        own, so that the interval the report gives is not the one the point was picked on. The objective is
        the nominal TACE; two points it cannot tell apart can differ severalfold under model mismatch and
        noise, which the report's median sees. Ties go to the lower nominal TACE."""
        p = self.protocol
        candidates = selection_candidates(self.tuned.evaluations, best.outcome.tace, p.agreement,
                                          p.selection_candidates, p.selection_spacing)
        if len(candidates) < 2:
            self.tuned.selection = [(best.outcome.tace, math.nan)]
            return best
        settings = [dict(self.machine, **draw_settings(self.data, j, p.mismatch))
                    for j in range(p.draws, p.draws + p.selection_draws)]
        runs = run_outcomes(self.data, [self.with_gains(e.gains) for e in candidates for _ in settings],
                            settings * len(candidates), self.from_time, self.where)     # a refused run counts as inf
        self.tuned.selection_runs += len(runs)
        n = len(settings)
        medians = [median_tace(runs[k * n:(k + 1) * n]) for k in range(len(candidates))]
        self.tuned.selection = [(e.outcome.tace, m) for e, m in zip(candidates, medians)]
        return candidates[min(range(len(candidates)), key=lambda k: (medians[k], candidates[k].outcome.tace))]

    def draws(self, gains: dict) -> Tuned:
        """The kept ``gains`` run over the protocol's draws (:func:`~contouring_ros.studies.machine.draw_settings`)
        and on the file's own machine, and their loop's margins on the machine, recorded in :attr:`tuned`."""
        tuned, p = self.tuned, self.protocol
        final = self.with_gains(gains)
        tuned.draws = run_outcomes(self.data, final, [dict(self.machine, **draw_settings(self.data, j, p.mismatch))
                                                      for j in range(p.draws)], self.from_time, self.where)
        tuned.ideal = run_outcomes(self.data, final, [{}], self.from_time, self.where)[0]   # the file's machine
        tuned.margins = worst_margins(experiment_margins(experiment_for(self.data, final, self.machine, self.where)))
        return tuned

    def run(self, optimiser=None) -> Tuned:
        """protocol.searches searches, then more while they do not agree (:meth:`search_until_agreed`), up to
        protocol.max_searches; the best kept (:meth:`keep`); then the draws, the ideal machine and the margins
        of the kept gains (:meth:`draws`)."""
        kept = self.keep(self.search_until_agreed(optimiser))
        if kept.chosen is None:
            return self.tuned
        return self.draws(kept.chosen.gains)


def tune(data: dict, sections: dict, keys: tuple, machine: dict, noise_limit: float, from_time: float,
         protocol: Protocol, where: str = "tuning", optimiser=None, robust_floor: float = 0.0,
         space: Space | None = None) -> Tuned:
    """Tune the combination ``sections`` (see :mod:`contouring_ros.studies.tuning` and :class:`Tuning`) on
    ``data`` with the machine settings ``machine``; then run the draws and the ideal machine. ``keys``: the
    controller's raw gains (its file gains in the report; the log box of a plugin without a space).
    ``optimiser``: another search over the unit box, ``optimiser(objective_many, start, budget, seed)``, to
    check the tuning against it. ``space``: another space (e.g. :func:`contouring_ros.core.tuning_space.log_box`
    of the raw gains). ``robust_floor`` [m]: a point is also robust when its worst TACE over the perturbations
    is at most this (the benchmark gives the proposed method's worst with the paper's gains,
    :func:`~contouring_ros.studies.outcomes.worst_case`): the same robustness as the paper's own design is
    enough, where that design itself degrades by more than robust_factor (otherwise only points far worse
    than the paper's would pass, and their error is large enough to hide any degradation)."""
    return Tuning(data, sections, keys, machine, noise_limit, from_time, protocol, where, robust_floor, space).run(optimiser)
