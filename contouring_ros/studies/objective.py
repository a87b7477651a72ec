"""What a point of a tuning search is worth: its objective, the log of its steady-state TACE, with the
penalties of the constraints it breaks (noise sensitivity, saturation, peak sensitivity Ms of its linear loop,
robustness to the plant's parameters), each continuous across its bound so that a search can settle on an
optimum that lies on it, and whether it is admissible. The protocol: :mod:`contouring_ros.studies.tuning`."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from .tuning import Evaluation, Outcome, Protocol

__all__ = ["PENALTY", "DIVERGED", "UNSTABLE", "objective", "Constraints"]

PENALTY = 10.0      # objective added per decade (log10) a constraint is exceeded by; diverged: 100
DIVERGED = 100.0    # the objective of a run that diverged (and of a point before it is run)
UNSTABLE = 50.0 + PENALTY * 3.0     # the objective of a point refused unrun: its linear loop is unstable


def objective(outcome: Outcome, noise_limit: float, protocol: Protocol) -> tuple:
    """(objective, admissible): log10 of the TACE in um, plus :data:`PENALTY` per decade the noise bound is
    exceeded by and per unit share of steps saturated beyond the allowed share (continuous across each
    bound, so that a search can settle on an optimum that lies on it); 100 for a run that diverged."""
    if not outcome.ok or not math.isfinite(outcome.tace):
        return DIVERGED, False
    value = math.log10(max(outcome.tace, 1e-15) * 1e6)
    excess = 0.0
    if math.isfinite(noise_limit) and outcome.noise > noise_limit:
        excess += math.log10(outcome.noise / noise_limit)
    if outcome.saturated > protocol.saturation_share:
        excess += 10.0 * (outcome.saturated - protocol.saturation_share)
    admissible = (not math.isfinite(noise_limit) or outcome.noise <= noise_limit) \
        and outcome.saturated <= protocol.saturation_share
    return value + PENALTY * excess, admissible


@dataclass(frozen=True)
class Constraints:
    """The constraints every point of a combination's searches is judged by: the ``protocol``'s, the noise
    bound ``noise_limit`` (inf: none) and the robustness floor ``robust_floor`` [m] (a point is also robust
    when its worst TACE over the perturbations is at most this)."""

    protocol: Protocol
    noise_limit: float
    robust_floor: float = 0.0

    def judge(self, evaluation: Evaluation, nominal: Outcome, perturbed: list | None, ms: tuple | None) -> None:
        """The objective and admissibility of a point from its nominal run, its perturbed runs (None: not run,
        the point is then not admissible) and its linear loop's (Ms, stable, allowed Ms) (None: no linear
        loop)."""
        value, admissible = objective(nominal, self.noise_limit, self.protocol)
        evaluation.outcome, evaluation.objective, evaluation.admissible = nominal, value, admissible
        evaluation.quiet = admissible and nominal.ok
        if not nominal.ok:
            return
        if ms is not None and ms[0] > ms[2]:
            self._over_ms(evaluation, nominal, ms)
            return
        if perturbed is None:                    # robustness not checked (yet): not admissible
            evaluation.admissible = False
            return
        self._robustness(evaluation, nominal, perturbed)

    @staticmethod
    def _over_ms(evaluation: Evaluation, nominal: Outcome, ms: tuple) -> None:
        """The penalty of a linear loop whose Ms ``ms[0]`` is over the allowed ``ms[2]``: not admissible."""
        evaluation.objective += PENALTY * math.log10(ms[0] / ms[2])
        evaluation.admissible = False
        evaluation.outcome = dataclasses.replace(nominal, failure=f"Ms {ms[0]:.3g} over {ms[2]:.3g}")

    def _robustness(self, evaluation: Evaluation, nominal: Outcome, perturbed: list) -> None:
        """The worst TACE over the ``perturbed`` runs, and where it is above both robust_factor x the nominal
        TACE and the floor, the penalty of a point that is not robust (at most 3 decades): not admissible."""
        p = self.protocol
        evaluation.worst = max((o.tace if o.ok else math.inf for o in perturbed), default=nominal.tace)
        bound = max(p.robust_factor * nominal.tace, self.robust_floor)
        if evaluation.worst > bound:
            evaluation.objective += PENALTY * min(math.log10(evaluation.worst / bound) if bound > 0 else 3.0, 3.0)
            evaluation.admissible = False
            evaluation.outcome = dataclasses.replace(
                nominal, failure=f"not robust: {evaluation.worst / nominal.tace:.3g}x the nominal TACE at "
                                 f"+-{100 * p.perturbation:g}% of a plant parameter")
