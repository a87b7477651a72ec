"""A global search over the unit box that evaluates a population at a time, and the rule that says whether
independent searches agree.

The search is CMA-ES with restarts of growing population (IPOP-CMA-ES: Auger & Hansen, "A restart CMA
evolution strategy with increasing population size", CEC 2005), on the ``cma`` package (Hansen, "The CMA
evolution strategy: a tutorial", 2016). The first run starts from a given point, each restart from a point
drawn uniformly in the box with twice the population of the run before; every population is handed to the
objective at once, so that a caller can run it as one vectorised batch. It minimises over [0, 1]^n: the
caller maps the box onto its own coordinates (:mod:`contouring_ros.core.tuning_space`).

The last share of a search's budget (``polish``) goes to a poll of the best point found: a pattern search
whose every poll is the 2n coordinate steps and two steps along a random direction, evaluated as one
population; it moves to the best point polled where that is lower and halves the step where none is
(generating set search: Kolda, Lewis & Torczon, "Optimization by direct search", SIAM Review 45, 2003). A
tuned optimum often lies on a constraint (the robustness bound is a stability edge under the perturbations,
where the objective rises by decades within a step); CMA-ES's steps shrink as its population meets it, and
searches that reach the same edge stop at different points of it. The poll walks along the edge to where
no step lowers the value, at the resolution it ends with.

A row of the benchmark is *converged* (:func:`agreement`) when at least :data:`AGREE` of its independent
searches end within :data:`TOLERANCE` of the best of them (SCIENCE: a tuned result is a claim that no better
admissible point exists; several searches ending at one value show it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["TOLERANCE", "AGREE", "SearchTrace", "IPOPCMAES", "Poll", "ipop_cmaes", "run_side_by_side", "Agreement", "agreement"]

TOLERANCE = 0.05     # searches agree when they end within this share of the best one
AGREE = 3            # ... and a row is converged when at least this many of them do


@dataclass
class SearchTrace:
    """What one search did: every point it evaluated (unit box) with its value, in order, and the size of
    each of its runs' populations."""

    points: list = field(default_factory=list)
    values: list = field(default_factory=list)
    populations: list = field(default_factory=list)
    confirmed: bool = False       # a restart came back to the best value (see ``confirm``)

    @property
    def evaluations(self) -> int:
        return len(self.values)

    @property
    def best(self) -> tuple:
        """(the point with the lowest value, that value); (None, inf) before any evaluation."""
        if not self.values:
            return None, math.inf
        i = int(np.argmin(self.values))
        return self.points[i], self.values[i]


class IPOPCMAES:
    """IPOP-CMA-ES over the unit box [0, 1]^n as an ask-and-tell object, so that several searches can run
    side by side with their populations evaluated in one batch: :meth:`ask` the next points (a population,
    cut to what is left of the budget), :meth:`tell` their values, until :attr:`done`.

    First ``design`` scrambled-Sobol points over the box (scipy.stats.qmc, seeded), all at once; then a
    CMA-ES run of population ``popsize`` and step ``sigma`` from the best of them (or from ``start``, where
    it is better: :meth:`known_start`; without a design, from ``start``) until it stops (no change of the
    values beyond 1e-3, of the point beyond 1e-3 of the box, or stagnation), then runs from uniform points of
    the box, each with twice the population of the one before, until ``budget`` evaluations are spent.
    ``confirm``: the search also ends once a restart ends within this of the best value found before it (a
    second run from elsewhere in the box came back to the same optimum: the rest of the budget would confirm
    it again). ``minstd``: per-coordinate smallest step (an integer coordinate's spacing, so the search does
    not stall on one step's plateau). ``polish``: the evaluations kept for the poll of the best point at the
    end (:class:`Poll`, first step ``polish_step``; the CMA-ES runs end where those begin, or sooner when
    confirmed). ``seed`` decides every draw: the same seed, the same trace."""

    def __init__(self, start, budget: int, seed: int, popsize: int = 8, sigma: float = 0.25, minstd=None,
                 confirm: float | None = None, design: int = 0, polish: int = 0, polish_step: float = 0.05):
        self.start = np.clip(np.asarray(start, dtype=float), 0.0, 1.0)
        self.n, self.budget, self.seed, self.sigma = len(self.start), int(budget), int(seed), float(sigma)
        self.minstd, self.confirm = minstd, confirm
        self.trace = SearchTrace()
        self._rng = np.random.default_rng(seed)
        self._size, self._run, self._best_before = max(int(popsize), 2), 0, math.inf
        self._asked, self._es = None, None
        self._over = self.n == 0 or self.budget <= 0
        self._global_budget = self.budget - max(min(int(polish), self.budget - 1), 0)
        self._polish_step, self._poll = float(polish_step), None
        self._design = []
        if not self._over and design > 0:
            import warnings
            from scipy.stats import qmc
            with warnings.catch_warnings():       # a design of any size: the balance of 2^m points is not needed
                warnings.simplefilter("ignore", UserWarning)
                self._design = [list(x) for x in qmc.Sobol(self.n, scramble=True, seed=self.seed).random(int(design))]
        elif not self._over:
            self._new_run(self.start)

    def _new_run(self, x0) -> None:
        import cma
        pad = 1 if self.n == 1 else 0          # cma cannot search one dimension: a second one, ignored
        # its own generator: searches side by side draw what each would draw alone (cma's "seed" would
        # reseed numpy's global one, which every search shares)
        normal = np.random.default_rng((self.seed, self._run)).standard_normal
        options = {"bounds": [0.0, 1.0], "popsize": self._size, "seed": np.nan,
                   "randn": lambda lam, n: normal((lam, n)), "verbose": -9, "tolx": 1e-4, "tolfun": 1e-4,
                   "tolflatfitness": 3}
        if self.minstd is not None:
            options["minstd"] = list(self.minstd) + [0.0] * pad
        self._es = cma.CMAEvolutionStrategy(list(x0) + [0.5] * pad, self.sigma, options)
        self._first = self.trace.evaluations
        self.trace.populations.append(self._size)

    #: the start's value where it was evaluated (a caller that evaluates it first says so): the design's best
    #: point replaces the start as the first run's mean only where it is better
    _start_value = math.inf

    def known_start(self, value: float) -> None:
        """The start's value, evaluated by the caller before the search."""
        self._start_value = float(value)

    @property
    def done(self) -> bool:
        return self._over or self.trace.evaluations >= self.budget

    @property
    def polishing(self) -> bool:
        """Whether the search is in its poll of the best point (its last phase)."""
        return self._poll is not None

    def _to_poll(self) -> None:
        """The global phase over: the poll of the best point with what is left of the budget (or the end)."""
        if self.budget - self.trace.evaluations <= 0 or self._global_budget >= self.budget:
            self._over = True
            return
        point, value = self.trace.best
        self._poll = Poll(point, value, self._polish_step, self.minstd, np.random.default_rng((self.seed, 2 ** 31)))
        if self._poll.done:
            self._over = True

    def ask(self) -> list:
        """The next points to evaluate (lists of n floats in [0, 1]); [] when done."""
        if self.done:
            return []
        left = self.budget - self.trace.evaluations
        if self._poll is not None:
            self._asked = self._poll.ask()[:left]
            return [list(x) for x in self._asked]
        left = self._global_budget - self.trace.evaluations
        if self._es is None:                   # the design first, all at once
            self._asked = self._design[:left]
            return [list(x) for x in self._asked]
        self._asked = self._es.ask()
        return [list(np.asarray(x[:self.n], dtype=float)) for x in self._asked[:left]]

    def tell(self, values) -> None:
        """The values of the points of the last :meth:`ask`, in order."""
        values = [float(v) for v in values]
        asked, self._asked = self._asked, None
        self.trace.points += [np.asarray(x[:self.n], dtype=float) for x in asked[:len(values)]]
        self.trace.values += values
        if self._poll is not None:
            self._poll.tell(asked[:len(values)], values)
            if self._poll.done or len(values) < len(asked):
                self._over = True
            return
        if self.trace.evaluations >= self._global_budget:
            self._to_poll()                    # the global phase's budget spent
            return
        if self._es is None:                   # the design told: CMA-ES from its best point, or the start
            best = int(np.argmin(values)) if values else None
            start_value = self._start_value
            self._new_run(self.start if best is None or start_value <= values[best] else np.asarray(asked[best]))
            return
        self._es.tell(asked, values)
        if not self._es.stop():
            return
        run_best = min(self.trace.values[self._first:], default=math.inf)
        if self.confirm is not None and self._run and abs(run_best - self._best_before) <= self.confirm:
            self.trace.confirmed = True
            self._to_poll()
            return
        self._best_before = min(self._best_before, run_best)
        self._run += 1
        self._size *= 2
        self._new_run(self._rng.uniform(0.0, 1.0, self.n))


def ipop_cmaes(objective_many: Callable, start, budget: int, seed: int, popsize: int = 8,
               sigma: float = 0.25, minstd=None, confirm: float | None = None, design: int = 0,
               polish: int = 0, polish_step: float = 0.05) -> SearchTrace:
    """Minimise ``objective_many`` (a list of points -> their values, one call per population) over the unit
    box from ``start`` within ``budget`` evaluations (:class:`IPOPCMAES`, run alone)."""
    search = IPOPCMAES(start, budget, seed, popsize, sigma, minstd, confirm, design, polish, polish_step)
    while not search.done:
        search.tell(objective_many(search.ask()))
    return search.trace


class Poll:
    """A pattern search over the unit box from ``point`` (value ``value``), a poll at a time: each poll is the
    point plus and minus the step along every coordinate (at least the coordinate's resolution, ``minstd``)
    and along one random direction (``rng``), clipped to the box (a point the clip leaves at the centre is
    left out). The best point polled becomes the centre where it is lower, the step doubled (at most the
    first, ``step``); else the step halves. It is :attr:`done` once the step is below :attr:`RESOLUTION`."""

    RESOLUTION = 1e-3      # the step at which a poll ends [share of the box]

    def __init__(self, point, value: float, step: float, minstd, rng):
        self.centre, self.value = np.asarray(point, dtype=float), float(value)
        self.first = self.step = float(step)
        n = len(self.centre)
        self.resolution = np.zeros(n) if minstd is None else np.asarray(minstd, dtype=float)[:n]
        self._rng = rng
        self.done = n == 0 or not math.isfinite(self.value)

    def ask(self) -> list:
        """This poll's points."""
        n = len(self.centre)
        direction = self._rng.standard_normal(n)
        direction *= self.step / max(float(np.linalg.norm(direction)), 1e-300)
        along = np.diag(np.maximum(self.step, self.resolution))
        points = np.clip(self.centre + np.vstack([along, -along, direction[None], -direction[None]]), 0.0, 1.0)
        moved = np.any(points != self.centre, axis=1)
        return [list(x) for x in points[moved]]

    def tell(self, points, values) -> None:
        """The values of this poll's points."""
        if values and min(values) < self.value:
            best = int(np.argmin(values))
            self.centre, self.value = np.asarray(points[best], dtype=float), float(values[best])
            self.step = min(2.0 * self.step, self.first)
        else:
            self.step /= 2.0
        self.done = self.step < self.RESOLUTION or not points


def run_side_by_side(searches: list, objective_many: Callable) -> None:
    """Run :class:`IPOPCMAES` ``searches`` until each is done, every round's populations handed to
    ``objective_many`` at once (a list, per search still running, of its points -> a list of their values
    per search), so that independent searches share one batch."""
    while True:
        running = [s for s in searches if not s.done]
        if not running:
            return
        asked = [s.ask() for s in running]
        for search, values in zip(running, objective_many(asked)):
            search.tell(values)


@dataclass(frozen=True)
class Agreement:
    """How far a row's independent searches agree: ``searches`` that ended with a value, ``agreed`` of them
    within the tolerance of the best, ``spread`` = the largest value over the smallest (inf when one search
    found nothing), ``converged`` when at least :data:`AGREE` agreed."""

    searches: int
    agreed: int
    spread: float
    converged: bool

    def describe(self) -> str:
        return (f"{self.agreed} of {self.searches} searches within {100 * TOLERANCE:g}% of the best"
                + ("" if self.converged else " (not converged)"))


def agreement(values, tolerance: float = TOLERANCE, needed: int = AGREE) -> Agreement:
    """The :class:`Agreement` of searches that ended at ``values`` (lower is better; nan or inf: the search
    found no admissible point)."""
    values = [float(v) for v in values]
    finite = [v for v in values if math.isfinite(v)]
    if not finite:
        return Agreement(len(values), 0, math.nan, False)
    best = min(finite)
    agreed = sum(1 for v in finite if v <= best * (1.0 + tolerance) + 1e-300)
    spread = max(finite) / best if best > 0 and len(finite) == len(values) else \
        (1.0 if len(finite) == len(values) else math.inf)
    return Agreement(len(values), agreed, spread, agreed >= needed)
