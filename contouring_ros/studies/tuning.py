"""Fair tuning: every gain of a method tuned on its own, by one optimiser, under the same constraints, on a
machine with the imperfections every real feed drive has; its result given with an interval.

How control engineers compare controllers (Åström & Hägglund, Advanced PID Control, ISA, 2006, ch. 7;
Garpinger & Hägglund, "Software-based optimal PID design with robustness and noise sensitivity
constraints", J. Process Control 33, 2015): at equal robustness and equal noise sensitivity, not at equal
gains; performance is then the error. Here, per combination (estimator x contour controller x servo set of a
scenario):

Machine. The scenario runs on a *realistic* machine (:data:`~contouring_ros.studies.machine.REALISTIC`): an
encoder of 0.1 um, 0.05 um RMS of position noise, one sample of computation delay and velocity from the
differentiated encoder (Altintas, Manufacturing Automation, 2nd ed., 2012, ch. 5-6: encoders of 0.1-1 um, servo
loops at 1 kHz with velocity from the encoder), and an actuator limit: the paper's where its file states one,
else :data:`~contouring_ros.studies.machine.SATURATION_MARGIN` times the largest command the proposed method
needs with the paper's gains on the ideal machine. A key the scenario file sets itself is kept. The ideal
machine (none of these) stays available for comparison.

Search. Each method is searched in its physical tuning space
(:func:`~contouring_ros.studies.space.tuning_space`: its catalogue entry's ``tuning``,
:mod:`contouring_ros.core.tuning_space`): loop bandwidths and corner frequencies in Hz below the Nyquist
frequency, damping ratios, weight ratios, each with a range a control engineer would accept; a plugin that
states none is searched over the log box of its raw gains. Every combination gets :attr:`Protocol.searches`
independent searches (search i: seed ``seed + i``; the first starts from the file's gains, evaluated first, the
others from uniform random points of the box), each IPOP-CMA-ES
(:func:`contouring_ros.studies.search.ipop_cmaes`: restarts with a doubled population, every population run as
one vectorised batch, robustness checks batched too) of at most :attr:`Protocol.evaluations` evaluations. The
row is *converged* when at least :attr:`Protocol.agree` searches end within :attr:`Protocol.agreement` of the
best nominal TACE (:func:`~contouring_ros.studies.tuner.searches_agreement`); while it is not, as many more
searches as the agreement lacks run side by side (seeds continuing), up to :attr:`Protocol.max_searches`, the
same cap for every method; with :attr:`Protocol.budget_growth` above 1, rounds of :attr:`Protocol.searches`
new searches follow, each round with twice the evaluations per search of the one before, while the searches
(all of them) do not agree, up to that factor (a search that stops where an admissible straight path still
falls to the best, ``tools/tune_row.py --segments``, is one too short for its row). The best search is kept
(:func:`~contouring_ros.studies.tuner.best_search`). The objective cannot tell apart points within the
agreement's tolerance, and under model mismatch and noise two of them can differ severalfold; so of a robust
result, the admissible points of every search within that tolerance of the best nominal TACE
(:attr:`Protocol.selection_candidates` of them at most, each :attr:`Protocol.selection_spacing` from the others)
run over :attr:`Protocol.selection_draws` draws of their own, and the one of lowest median TACE there is kept
(:meth:`~contouring_ros.studies.tuner.Tuning.select`); the report's draws then run once, for its gains.

Constraints (the same for every method of a scenario, measured in simulation):

- stable: the run did not diverge;
- noise sensitivity: the RMS of the command's sample-to-sample change in the steady state (RMS over the
  axes) at most :attr:`Protocol.noise_factor` times the proposed method's with the paper's gains on the
  same machine and seed;
- saturation: at most :attr:`Protocol.saturation_share` of the steady-state steps with an axis' command
  at or beyond its limit;
- peak sensitivity, where the loop is linear (PID, PID + feedforward, ZPETC and cascade servos with a linear
  contour controller; :func:`~contouring_ros.studies.loops.loop_robustness`): the closed loop stable and Ms at
  most :data:`MS_LIMIT` (Åström & Hägglund's 1.4-2), or the drive's own Ms where its servo alone already
  exceeds that; a point beyond it is refused before it runs;
- robustness: with each plant parameter (gain, time constant, mass, damping) at plus and minus
  :attr:`Protocol.perturbation` on every axis, the run stays stable and its steady-state TACE within
  :attr:`Protocol.robust_factor` times the nominal one, or no worse than the proposed method's worst TACE
  there with the paper's gains (the same robustness as the paper's own design is enough: where that design
  itself degrades by more than the factor, a rule relative to a point's own error alone would pass only
  points far worse than the paper's, whose large error hides their degradation). Every point that could
  become its search's choice (its nominal objective below the search's best admissible one) is run at
  every perturbation (:meth:`~contouring_ros.studies.tuner.Tuning.measure`), so a search chooses what it
  would were every point checked; a point that could not is left unchecked, its objective the nominal one.
  Where no point of a search is robust, its point of lowest worst case among those that meet every other
  constraint (noise, saturation, Ms) is given, marked "not robust"; where none meets them, it has no
  admissible gain.

Objective: the steady-state TACE of the exact contour error (median seed).

Interval. The tuned gains then run :attr:`Protocol.draws` times, draw j with noise seed j, a model
mismatch drawn uniformly within +-:attr:`Protocol.mismatch` of every plant parameter and a disturbance
phase (:func:`~contouring_ros.studies.machine.draw_settings`) (the same draws for
every method of the scenario, so ratios are paired draw by draw); the report gives the median and the
2.5-97.5 percentile interval of each figure and ratio.

This module holds the protocol's numbers (:class:`Protocol`) and what a tuning records (:class:`Outcome`,
:class:`Evaluation`, :class:`Search`, :class:`Tuned`; saved in benchmark parts under these names). The steps
are their own modules: the machine and its draws (:mod:`~contouring_ros.studies.machine`), a method's gains
(:mod:`~contouring_ros.studies.gains`), the runs and their figures (:mod:`~contouring_ros.studies.outcomes`), the
linear loops and their Ms (:mod:`~contouring_ros.studies.loops`), the tuning space
(:mod:`~contouring_ros.studies.space`), the objective and its penalties (:mod:`~contouring_ros.studies.objective`),
the searches (:mod:`~contouring_ros.studies.tuner`) and the medians and intervals
(:mod:`~contouring_ros.studies.summaries`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["MS_LIMIT", "Protocol", "Outcome", "Evaluation", "Search", "Tuned"]

MS_LIMIT = 2.0      # peak sensitivity a linear loop may reach (Åström & Hägglund: 1.4-2)


@dataclass(frozen=True)
class Protocol:
    """The tuning protocol: the same numbers for every method of a benchmark."""

    evaluations: int = 400         # evaluations per search (the file's gains included in the first)
    design: int = 48               # each search's first points: scrambled Sobol over the whole box, one batch
    popsize: int = 16              # the first CMA-ES run's population; each restart doubles it (IPOP)
    step: float = 0.25             # CMA-ES's first step [share of each coordinate's range]
    polish: float = 0.25           # share of a search's evaluations kept for the poll of its best point at the end
    polish_step: float = 0.05      # ... its first step [share of each coordinate's range]
    searches: int = 3              # independent searches per combination (seeds seed, seed + 1, ...)
    max_searches: int = 6          # ... more, side by side, while they do not agree, up to this many
    budget_growth: int = 4         # ... then rounds of `searches` new searches with 2x, 4x, ... the evaluations,
    #                                while they do not agree, up to this many x (1: none)
    agreement: float = 0.05        # searches agree when they end within this share of the best nominal TACE
    agree: int = 3                 # ... and a row is converged when at least this many do
    decades: float = 8.0           # the log box of a plugin that states no space: each gain's span either side
    noise_factor: float = 2.0      # noise sensitivity at most this x the proposed method's (paper's gains)
    saturation_share: float = 0.01  # share of steady-state steps at the actuator limit, at most
    perturbation: float = 0.2      # robustness: each plant parameter x (1 +- this)
    robust_factor: float = 3.0     # ... with steady-state TACE at most this x the larger of the nominal and the floor
    ms_limit: bool = True          # refuse points whose linear loop has Ms over MS_LIMIT (see loop_robustness)
    draws: int = 8                 # noise seeds x model-mismatch draws of the interval
    selection_draws: int = 8       # draws (after the interval's own) the kept point is picked over (0: none)
    selection_candidates: int = 8  # ... from at most this many points within the agreement of the best
    selection_spacing: float = 0.02  # ... each this far from the others (share of a coordinate's range)
    mismatch: float = 0.1          # model mismatch of a draw: each plant parameter x U(1 - this, 1 + this)
    seed: int = 1                  # search i's seed is seed + i (its CMA-ES samples and, from search 1 on, its start)

    def _growth_text(self) -> str:
        if not self.budgets():
            return ""
        return (f" (then, while they do not agree, {self.searches} more searches with 2x the evaluations, and so "
                f"on up to {self.budget_growth}x)")

    def budgets(self) -> list:
        """The evaluations per search of each round after the first searches: 2x, 4x, ... up to
        :attr:`budget_growth` x :attr:`evaluations` (empty: no growth). A protocol whose searches could never
        agree (fewer than :attr:`agree` of them, a quick look) gets none."""
        if max(self.searches, self.max_searches) < self.agree:
            return []
        out, factor = [], 2
        while factor <= self.budget_growth:
            out.append(factor * self.evaluations)
            factor *= 2
        return out

    def describe(self) -> str:
        return (f"each method in its physical tuning space (bandwidths and corner frequencies in Hz, damping and "
                f"weight ratios; a plugin without one: each raw gain log-scaled over +-{self.decades:g} decades); "
                f"{self.searches} to {max(self.searches, self.max_searches)} independent searches per combination "
                f"(the first from the file's gains, the others from uniform random points), each "
                f"{self.design} scrambled-Sobol points over the box, then IPOP-CMA-ES from the best point "
                f"(population {self.popsize}, doubled at each restart; the searches' populations run as one "
                f"batch), the last {100 * self.polish:g}% of them a pattern search's polls of the best point (first step "
                f"{self.polish_step:g} of the box, halved to 0.001), at most {self.evaluations} evaluations in all{self._growth_text()}; "
                f"converged when {self.agree} searches end within "
                f"{100 * self.agreement:g}% of the best nominal TACE; noise sensitivity <= {self.noise_factor:g} "
                f"x the proposed method's; <= {100 * self.saturation_share:g}% of steps saturated; "
                f"{f'linear loops stable with Ms <= {MS_LIMIT:g}; ' if self.ms_limit else ''}robust: stable at "
                f"+-{100 * self.perturbation:g}% of each plant parameter with TACE <= {self.robust_factor:g} x "
                f"nominal, or no worse than the proposed method's worst there with the paper's gains; "
                + (f"of the points within {100 * self.agreement:g}% of the best nominal TACE, the one of lowest "
                   f"median over {self.selection_draws} draws of its own kept; " if self.selection_draws else "")
                + f"{self.draws} draws (noise seed, +-{100 * self.mismatch:g}% model mismatch)")


@dataclass(frozen=True)
class Outcome:
    """One run's figures (steady state unless said); ``failure`` is set (and the figures nan) when it diverged."""

    tace: float = math.nan
    mce: float = math.nan
    rms: float = math.nan
    noise: float = math.nan        # RMS of the command's sample-to-sample change (RMS over axes)
    saturated: float = math.nan    # share of steps with an axis' command at or beyond its limit
    effort: float = math.nan       # RMS command (RMS over axes), whole run
    peak_command: tuple = ()       # largest |command| per axis, whole run
    failure: str = ""

    @property
    def ok(self) -> bool:
        return not self.failure


@dataclass
class Evaluation:
    """One point of the search."""

    gains: dict
    outcome: Outcome
    objective: float
    admissible: bool
    worst: float = math.nan        # the worst steady-state TACE over the robustness runs (nan: not checked)
    unit: list = field(default_factory=list)     # where in the search's unit box
    point: dict = field(default_factory=dict)    # the tuning space's values there
    search: int = 0                              # which search evaluated it
    quiet: bool = False                          # it met the noise bound and the saturation share


@dataclass
class Tuned:
    """A combination's tuned result."""

    gains: dict = field(default_factory=dict)
    file_gains: dict = field(default_factory=dict)
    at_bound: list = field(default_factory=list)       # gains at an end of their span (not an optimum there)
    evaluations: list = field(default_factory=list)    # every Evaluation of the search, in order
    nominal: Outcome | None = None                     # the tuned gains, seed 0, nominal plant
    robust_worst: float = math.nan                     # worst TACE over the +-perturbation runs / nominal
    robustness_runs: int = 0
    selection_runs: int = 0                            # runs of the points the kept one was picked from
    draws: list = field(default_factory=list)          # Outcome per draw
    ideal: Outcome | None = None                       # the tuned gains on the ideal machine
    margins: object = None                             # worst_margins of the tuned loop on the machine, if linear
    status: str = "ok"
    cpu: float = math.nan                              # CPU seconds the tuning, its checks and draws took
    search: int = 0                                    # which of the searches was kept
    search_tace: list = field(default_factory=list)    # each search's chosen nominal TACE [m] (nan: none)
    search_evaluations: list = field(default_factory=list)   # each search's evaluations
    agreement: object = None                           # search.Agreement of the searches
    point: dict = field(default_factory=dict)          # the kept gains in the tuning space's coordinates
    point_text: str = ""                               # ... as the space writes them (units, terms off)
    space: str = ""                                    # the tuning space, described
    selection: list = field(default_factory=list)      # (nominal TACE, median over the selection draws) [m]
    #                                                    of each point the kept one was picked from

    @property
    def converged(self) -> bool:
        """Whether the searches agreed (:func:`contouring_ros.studies.search.agreement`)."""
        return bool(self.agreement is not None and self.agreement.converged)

    @property
    def ok(self) -> bool:
        return self.nominal is not None and self.status == "ok"


@dataclass
class Search:
    """What one search of a :class:`~contouring_ros.studies.tuner.Tuning` ends with: the chosen Evaluation
    (None: no admissible point), the status it gives the combination and the chosen point's worst TACE over the
    perturbations / its nominal."""

    chosen: Evaluation | None
    status: str
    robust_worst: float = math.nan
    evaluations: int = 0
    lowest: float = math.inf      # the lowest objective it reached, penalties included (inf: no point ran)

    @property
    def tace(self) -> float:
        """The chosen point's nominal TACE (nan where there is none or it diverged)."""
        return self.chosen.outcome.tace if self.chosen is not None else math.nan

    @property
    def value(self) -> float:
        """What the searches of a row are compared by (:func:`contouring_ros.studies.search.agreement`): the
        nominal TACE of a robust choice; inf where the search found none."""
        return self.tace if self.status == "ok" and math.isfinite(self.tace) else math.inf

    @property
    def penalised(self) -> float:
        """The lowest objective it reached as a TACE [m], 10^objective um: the nominal TACE of the point
        there times 10^(PENALTY x the decades a constraint is broken by there)
        (:mod:`~contouring_ros.studies.objective`); inf where no point ran."""
        return 10.0 ** self.lowest * 1e-6 if math.isfinite(self.lowest) else math.inf
