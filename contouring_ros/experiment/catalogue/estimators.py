"""Contour error estimators (core/estimators.py): the ``/contour_estimator`` section."""
from __future__ import annotations

import math

from ...core import curves, estimators
from ..registry import Entry, Role
from ..schema import POSITIVE_RANGE, Param

__all__ = ["ESTIMATORS", "branch_check_settings"]

ESTIMATORS = Role("estimator", description="contour error estimator")

#: the Newton estimate's branch check on a tool path: a sample every 50 um of path (at most 200 000), to
#: within 1 um. At an exact-stop corner the distance to the path is stationary at the kink, and Newton's
#: iteration stays there while the axes move on along the next block (the estimate then lags by the axes'
#: following error, 0.2 mm on the example part); 256 samples of a 0.2 m path are 0.8 mm apart, too sparse
#: to find the next block
TOOL_PATH_CHECK_SPACING, TOOL_PATH_CHECK_TOLERANCE = 5e-5, 1e-6
DEFAULT_CHECK_SAMPLES, DEFAULT_CHECK_TOLERANCE = 256, 1e-4

_TOLERANCE = "stop iterating when the residual and the step are below this [m]"
_ITERATIONS = "iteration cap per control step"


def branch_check_settings(section: dict, curve) -> tuple:
    """(samples, tolerance) of the Newton estimate's branch check: the section's, where it gives them, else
    256 points to 100 um, or on a tool path a point every TOOL_PATH_CHECK_SPACING to 1 um."""
    tool_path = isinstance(curve, curves.ToolPath)
    samples, tolerance = section["branch_check_samples"], section["branch_check_tolerance"]
    if samples is None:
        length = curve.domain[1] - curve.domain[0]
        samples = int(min(max(math.ceil(length / TOOL_PATH_CHECK_SPACING), DEFAULT_CHECK_SAMPLES), 200_000)) \
            if tool_path else DEFAULT_CHECK_SAMPLES
    if tolerance is None:
        tolerance = TOOL_PATH_CHECK_TOLERANCE if tool_path else DEFAULT_CHECK_TOLERANCE
    return samples, tolerance


def _newton(s, c):
    theta0 = s["theta0"] if s["theta0"] is not None else c.schedule.theta_start
    inner = s["inner_step"] or c.sample_time
    samples, tolerance = branch_check_settings(s, c.curve)
    check = estimators.BranchCheck(c.curve, samples, tolerance) if samples else None
    return estimators.NewtonEstimator(c.curve, s["k_prime"], s["c_prime"], theta0, inner, s["tolerance"],
                                      s["max_iterations"], check)


def _planar(section, axes):
    return None if len(axes) == 2 else ("type", "the osculating_circle estimate needs a planar contour (2 axes)")


for _entry in (
    Entry("tangent_line", {}, lambda s, c: estimators.TangentLineEstimator(c.curve)),
    Entry("natural_local", {}, lambda s, c: estimators.NaturalLocalEstimator(c.curve)),
    Entry("osculating_circle", {}, lambda s, c: estimators.OsculatingCircleEstimator(c.curve), check=_planar),
    Entry("foot_point_search", {
        "max_iterations": Param("int", 10, "positive", help=_ITERATIONS, bounds=(1, 1000)),
        "tolerance": Param("float", 1e-6, "positive", help=_TOLERANCE, bounds=(1e-15, 1.0))},
        lambda s, c: estimators.FootPointSearchEstimator(c.curve, s["max_iterations"], s["tolerance"])),
    Entry("newton", {
        "k_prime": Param("float", check="positive", help="Newton step gain k' [1/s]", bounds=POSITIVE_RANGE),
        "c_prime": Param("float", check="positive", help="Newton step gain c' [1/s]", bounds=POSITIVE_RANGE),
        "tolerance": Param("float", 1e-9, "positive", help=_TOLERANCE, bounds=(1e-15, 1.0)),  # inner iterations
        "max_iterations": Param("int", 200, "positive", help=_ITERATIONS, bounds=(1, 10_000)),
        "inner_step": Param("float", 0.0, "nonnegative", help="inner iteration step, 0: the sample time [s]",
                            bounds=(0.0, 1.0)),
        "theta0": Param("float", None, help="initial foot-point parameter (default: the schedule's start)",
                        bounds=(-1e6, 1e6)),
        # None: 256 points, and on a tool path one every TOOL_PATH_CHECK_SPACING (its corners); 0: no check
        "branch_check_samples": Param("int", None, "nonnegative", help="samples of the global branch check, 0: none",
                                      bounds=(0, 10_000)),
        # m; None: 1e-4, 1e-6 on a tool path
        "branch_check_tolerance": Param("float", None, "positive", help="how much closer another branch must be to "
                                        "jump there [m]", bounds=(1e-15, 1e3))},
        _newton),
):
    ESTIMATORS.add(_entry)
