"""Model predictive contouring control: a quadratic programme over a horizon, solved every step, that trades
contour error, lag error and the command's rate within the drives' command limits (D. Lam, C. Manzie and
M. Good, "Model predictive contouring control for biaxial systems", IEEE Transactions on Control Systems
Technology, 2013; docs/REFERENCES.md).

What is the paper's and what is not. The cost splits each predicted position error e_j = P_j - R_j along the
path: its lag part along the unit tangent t_j and its contour part across it, weighted q_lag and q_contour
(the paper's contouring and lag errors, linearised at the reference points), plus r_rate times the squared
change of each axis' command; the command limits are constraints. The paper also makes the path's progress
a decision variable (a virtual input that the cost rewards); here the interpolator's schedule sets the
progress, as it does for every other method of the catalogue, so that all are scored on the same reference
and travel time: the horizon's reference points are the interpolator's preview
(docs/ARCHITECTURE.md, "Reference preview"). The prediction model is each axis' mass-damper
K / (M s^2 + B s) (a first-order velocity axis k / (s (tau s + 1)) is M = tau, B = 1, K = k) sampled
exactly under a zero-order hold, with the drive's computation delay; an optional estimate of a constant
input disturbance (the velocity's one-step prediction error, ``disturbance_gain``) makes it offset-free
under a constant load, which the paper's model does not include.

The QP is condensed onto the N commands of each axis (n N variables, box constraints only). Its
unconstrained optimum is the solution of one linear system; where it lies within the command limits it is
the QP's solution (the cost is convex), and only where it does not is the QP solved by OSQP (Stellato et al.,
Math. Prog. Comp. 12, 2020), warm-started from the last plan. The arithmetic runs on rows: a controller alone
is one row, a batch of B controllers (the benchmark's tuning, sweeps) is B rows built, condensed and solved
together, each row with the same numbers as alone (stacked matrix products and linear solves compute each
matrix on its own). Every step's solve wall time is kept (:attr:`solve_times`).
"""
from __future__ import annotations

import time

import numpy as np

from ..errors import ContouringError
from .plants import mass_damper_hold_terms

__all__ = ["ModelPredictiveContouring", "ContouringBatch", "sampled_mass_damper", "reconstructed_velocity",
           "VELOCITY_ESTIMATES"]

VELOCITY_ESTIMATES = ("measured", "model")


def sampled_mass_damper(mass: float, damping: float, gain: float, sample_time: float) -> tuple:
    """(A, B) of x = (P, V): x+ = A x + B u for K / (M s^2 + B s) under a zero-order hold, as
    :class:`~contouring_ros.core.plants.MassDamperAxis` steps it."""
    vv, vw, pv, pw = mass_damper_hold_terms(float(mass), float(damping), float(sample_time))
    scale = float(gain) / float(mass)
    return np.array([[1.0, pv], [0.0, vv]]), np.array([pw * scale, vw * scale])


def reconstructed_velocity(position, last_position, drive, a_matrix_pv, a_matrix_vv, b_position, b_velocity):
    """Each axis' velocity now from P_k, P_k-1 and the drive u + d applied between them, through the sampled
    model x+ = A x + B (u + d) of :func:`sampled_mass_damper`: P_k = P_k-1 + pv V_k-1 + b0 (u + d) gives
    V_k-1, and V_k = vv V_k-1 + b1 (u + d) (a deadbeat observer)."""
    before = (position - last_position - b_position * drive) / a_matrix_pv
    return a_matrix_vv * before + b_velocity * drive


class ModelPredictiveContouring:
    """Model predictive contouring control of every axis' whole command (pair it with ``direct`` servos).

    Parameters
    ----------
    mass, damping, gain : sequence of float
        Each axis' model M [kg], B [N s/m], K [N per command unit].
    sample_time : float
        Ts [s].
    horizon : int
        N, the steps predicted.
    q_contour, q_lag : float
        Weights of the squared contour and lag errors [1/m^2].
    r_rate : float
        Weight of the squared change of a command between steps [1/command unit^2].
    command_limit : sequence of float
        Each axis' |command| bound (0: none).
    command_delay : int
        The drive's computation delay the model assumes [samples]: a command acts this many steps later.
    disturbance_gain : float
        0 .. 1: how much of each step's velocity prediction error a constant input disturbance estimate takes
        up (0: none).
    velocity_estimate : str
        'measured': each axis' velocity as the drive reports it; 'model': the velocity reconstructed from the
        last two position readings and the command applied between them through the axis model, carried to
        now (:func:`reconstructed_velocity`; where the drive's velocity is its differentiated encoder, the
        reported one is the mean over the last step, half a sample late, which a fast axis mode turns into a
        wrong state).
    """

    needs_state = True
    #: a batch (:mod:`contouring_ros.core.batch`) is :class:`ContouringBatch` (:meth:`batch_of`)
    batchable = True

    @classmethod
    def batch_of(cls, members: list) -> "ContouringBatch":
        """The batch of ``members``: their QPs built and solved as rows of one computation, each with the
        numbers it has alone."""
        return ContouringBatch(members)

    def __init__(self, mass, damping, gain, sample_time, horizon: int = 20, q_contour: float = 1e6,
                 q_lag: float = 1e4, r_rate: float = 1.0, command_limit=(), command_delay: int = 0,
                 disturbance_gain: float = 0.0, velocity_estimate: str = "measured"):
        n = len(mass)
        self.n, self.horizon, self.delay = n, int(horizon), int(command_delay)
        self.q_contour, self.q_lag, self.r_rate = float(q_contour), float(q_lag), float(r_rate)
        self.disturbance_gain = float(disturbance_gain)
        if velocity_estimate not in VELOCITY_ESTIMATES:
            raise ValueError(f"velocity_estimate must be one of {', '.join(VELOCITY_ESTIMATES)}, got {velocity_estimate!r}")
        self.velocity_estimate = velocity_estimate
        limits = np.zeros(n) if command_limit is None or len(command_limit) == 0 else \
            np.broadcast_to(np.asarray(command_limit, dtype=float), (n,))
        self.limits = np.where(limits > 0.0, limits, np.inf)
        self.models = [sampled_mass_damper(m, b, k, sample_time) for m, b, k in zip(mass, damping, gain)]
        self.preview = self.delay + self.horizon        # reference steps ahead: k + D + 1 .. k + D + N
        big_n = self.horizon
        # per axis: the position j + 1 steps after the state x_D (j = 0 .. N-1) = free[j] @ x_D + forced[j] @ U
        free, forced_all = [], []
        for a_matrix, b_vector in self.models:
            powers = [np.eye(2)]
            for _ in range(big_n):
                powers.append(a_matrix @ powers[-1])
            free.append(np.array([powers[j + 1][0] for j in range(big_n)]))
            forced = np.zeros((big_n, big_n))
            for j in range(big_n):
                for i in range(j + 1):
                    forced[j, i] = (powers[j - i] @ b_vector)[0]
            forced_all.append(forced)
        self.free, self.forced = np.array(free), np.array(forced_all)            # (n, N, 2), (n, N, N)
        difference = np.eye(big_n) - np.eye(big_n, k=-1)
        # the rate's Hessian, r_rate D^T D on each axis' block of the diagonal
        self.rates = np.kron(np.eye(n), self.r_rate * difference.T @ difference)
        self.rate_first = self.r_rate * difference.T[:, 0]      # times the previous command: the first change
        self._rows = _Rows([self])

    @property
    def solve_times(self) -> list:
        """Wall time of each step's solve [s]."""
        return self._rows.solve_times

    @property
    def unconverged(self) -> int:
        """Solves that ended at OSQP's iteration limit (their iterate, clipped, was used)."""
        return int(self._rows.unconverged[0])

    def look_ahead(self, positions) -> None:
        """This step's reference positions at k + 1 .. k + :attr:`preview`, an array (preview, n)."""
        self._rows.ahead = np.asarray(positions, dtype=float)[None]

    def step(self, estimate=None, reference=None, position=None, velocity=None) -> np.ndarray:
        rows = self._rows.step(np.asarray(reference.position, dtype=float)[None],
                               np.asarray(position, dtype=float)[None], np.asarray(velocity, dtype=float)[None])
        return rows[0]


class _Rows:
    """The QPs of B controllers of one shape (axes, horizon, delay, velocity estimate), each a row: their
    constants stacked along a first axis, their state kept as (B, ...) arrays, built and solved together."""

    def __init__(self, members: list):
        first = members[0]
        self.n, self.horizon, self.delay, self.preview = first.n, first.horizon, first.delay, first.preview
        self.model_velocity = first.velocity_estimate == "model"
        size = len(members)
        self.q_contour = np.array([m.q_contour for m in members])[:, None, None, None]
        self.q_lag = np.array([m.q_lag for m in members])[:, None, None, None]
        self.disturbance_gain = np.array([m.disturbance_gain for m in members])[:, None]
        # x+ = A x + B (u + d) with A = [[1, pv], [0, vv]], B = (b0, b1), each (B, n)
        a_matrices = np.array([[a for a, _ in m.models] for m in members])
        b_vectors = np.array([[b for _, b in m.models] for m in members])
        self.pv, self.vv = a_matrices[:, :, 0, 1], a_matrices[:, :, 1, 1]
        self.b0, self.b1 = b_vectors[:, :, 0], b_vectors[:, :, 1]
        self.free = np.array([m.free for m in members])                     # (B, n, N, 2)
        self.forced = np.array([m.forced for m in members])                 # (B, n, N, N)
        self.forced_transposed = np.ascontiguousarray(self.forced.transpose(0, 1, 3, 2))
        self.forced_sum = self.forced.sum(axis=3)          # the response to a constant input of 1, (B, n, N)
        self.rates = np.array([m.rates for m in members])                   # (B, n N, n N)
        self.rate_first = np.array([m.rate_first for m in members])      # (B, N)
        self.bounds = np.array([np.repeat(m.limits, self.horizon) for m in members])   # (B, n N), inf: none
        # the step's state
        self.held = [np.zeros((size, self.n)) for _ in range(self.delay)]   # computed, not yet applied (oldest first)
        self.previous = np.zeros((size, self.n))       # the last command computed
        self.applied = None                           # the command applied over the last step (None before the first)
        self.last_position = None                     # the axes' position readings of the last step
        self.last_velocity = None                     # the axes' velocities of the last step
        self.disturbance = np.zeros((size, self.n))    # constant input disturbance estimate [command units]
        self.ahead = np.zeros((size, 0, self.n))
        self.solve_times = []                         # wall time of each step's solve [s]
        self.unconverged = np.zeros(size, dtype=int)   # solves that ended at OSQP's iteration limit
        self.solvers = [None] * size                  # each row's OSQP, set up when its limits first bind
        self.plans = None                             # the last solutions, the warm starts of the next

    def _weights(self, reference_position) -> np.ndarray:
        """(B, N, n, n): q_contour (I - t t^T) + q_lag t t^T at each predicted step, t the unit tangent of the
        reference there (central differences of the preview; isotropic q_contour where it stands still)."""
        points = np.concatenate([reference_position[:, None, :], self.ahead[:, :self.preview]], axis=1)
        steps = self.delay + 1 + np.arange(self.horizon)              # rows of the predicted points
        after = np.minimum(steps + 1, points.shape[1] - 1)
        tangents = points[:, after] - points[:, steps - 1]            # (B, N, n)
        squared = tangents[:, :, 0] * tangents[:, :, 0]
        for i in range(1, self.n):
            squared = squared + tangents[:, :, i] * tangents[:, :, i]
        lengths = np.sqrt(squared)
        moving = lengths > 1e-15
        t = tangents / np.where(moving, lengths, 1.0)[:, :, None]
        along = t[:, :, :, None] * t[:, :, None, :] * moving[:, :, None, None]
        return self.q_contour * (np.eye(self.n) - along) + self.q_lag * along

    def step(self, reference_position, position, velocity) -> np.ndarray:
        """Each row's command now, (B, n), from its reference position, axes' positions and velocities."""
        if self.applied is not None:
            drive = self.applied + self.disturbance
            if self.model_velocity:
                velocity = reconstructed_velocity(position, self.last_position, drive, self.pv, self.vv,
                                                  self.b0, self.b1)
            predicted = self.vv * self.last_velocity + self.b1 * drive
            self.disturbance = np.where(self.disturbance_gain != 0.0, self.disturbance + self.disturbance_gain *
                                        (velocity - predicted) / self.b1, self.disturbance)
        self.last_position = position
        n, big_n = self.n, self.horizon
        # the state when the command computed now acts: the held commands applied first
        p, v = position, velocity
        for command in self.held:
            drive = command + self.disturbance
            p, v = p + self.pv * v + self.b0 * drive, self.vv * v + self.b1 * drive
        states = np.stack([p, v], axis=2)[:, :, :, None]                          # (B, n, 2, 1)
        targets = self.ahead[:, self.delay:self.delay + big_n].transpose(0, 2, 1)   # (B, n, N)
        weights = self._weights(reference_position)                               # (B, N, n, n)
        # e_j = offsets[:, j] + forced[:, j] @ U: H = F^T W F + the rate's, f = F^T W offsets - the first change's
        offsets = (self.free @ states)[..., 0] + self.forced_sum * self.disturbance[:, :, None] - targets
        size = len(position)
        hessian = np.empty((size, n * big_n, n * big_n))
        linear = np.empty((size, n * big_n))
        for a in range(n):
            weighted_offsets = weights[:, :, a, 0] * offsets[:, 0]
            for c in range(1, n):
                weighted_offsets = weighted_offsets + weights[:, :, a, c] * offsets[:, c]
            rows = slice(a * big_n, (a + 1) * big_n)
            linear[:, rows] = (self.forced_transposed[:, a] @ weighted_offsets[:, :, None])[..., 0] \
                - self.rate_first * self.previous[:, a, None]
            for c in range(n):
                hessian[:, rows, c * big_n:(c + 1) * big_n] = \
                    self.forced_transposed[:, a] @ (weights[:, :, a, c, None] * self.forced[:, c])
        hessian += self.rates
        started = time.perf_counter()
        plans = self._solve(hessian, linear)
        self.solve_times.append(time.perf_counter() - started)
        command = plans[:, ::big_n].copy()            # each axis' first command
        self.plans = plans
        self.last_velocity = velocity
        if self.delay:
            self.applied = self.held[0]
            self.held = self.held[1:] + [command]
        else:
            self.applied = command
        self.previous = command
        return command

    def _solve(self, hessian, linear) -> np.ndarray:
        """Each row's argmin U^T H U + 2 f^T U within its command limits: the unconstrained optimum where it
        is within them, else OSQP's."""
        try:
            plans = np.linalg.solve(hessian, -linear[:, :, None])[..., 0]
        except np.linalg.LinAlgError:        # a singular row: solved alone, the rest as they are in the stack
            plans = np.full(linear.shape, np.nan)
            for row in range(len(linear)):
                try:
                    plans[row] = np.linalg.solve(hessian[row], -linear[row])
                except np.linalg.LinAlgError:
                    pass
        outside = ~np.all(np.abs(plans) <= self.bounds, axis=1)       # NaN is outside
        for row in np.flatnonzero(outside):
            if np.isfinite(self.bounds[row]).any():
                plans[row] = self._solve_bounded(row, hessian[row], linear[row])
            elif not np.all(np.isfinite(plans[row])):
                raise ContouringError(f"step {len(self.solve_times)}: the MPCC's unconstrained optimum is not "
                                      "defined: its weights q_contour, q_lag and r_rate may leave the cost flat")
        return plans

    def _solve_bounded(self, row: int, hessian, linear) -> np.ndarray:
        scale = 1.0 / max(float(np.max(np.abs(np.diag(hessian)))), 1e-300)   # OSQP's tolerances act on O(1) costs
        hessian, linear = hessian * scale, linear * scale
        bounds = np.where(np.isfinite(self.bounds[row]), self.bounds[row], 1e30)
        solver = self.solvers[row]
        if solver is None:
            solver = self.solvers[row] = self._set_up_solver(hessian, linear, bounds)
        else:
            solver.update(Px=(2.0 * hessian[self._upper])[self._order], q=2.0 * linear)
        if self.plans is not None:
            solver.warm_start(x=self.plans[row])
        result = solver.solve(raise_error=False)
        plan = np.asarray(result.x, dtype=float)
        if result.info.status == "maximum iterations reached" and np.all(np.isfinite(plan)):
            self.unconverged[row] += 1       # the last iterate, within the bounds once clipped: still a usable plan
        elif result.info.status not in ("solved", "solved inaccurate") or not np.all(np.isfinite(plan)):
            raise ContouringError(f"step {len(self.solve_times)}: the MPCC quadratic programme was not solved "
                                  f"(OSQP: {result.info.status}): its weights q_contour, q_lag and r_rate may "
                                  "span too many decades")
        return np.clip(plan, -bounds, bounds)

    def _set_up_solver(self, hessian, linear, bounds):
        """An OSQP for one row, set up with the QP where its limits first bind; what does not change from step
        to step (the Hessian's pattern, the bounds) is kept for the updates."""
        import osqp
        from scipy import sparse
        size = len(linear)
        self._upper = rows, columns = np.triu_indices(size)
        # the whole upper triangle stored, zeros included, so that every step's update keeps the pattern
        pattern = sparse.csc_matrix((np.arange(1.0, len(rows) + 1.0), (rows, columns)), shape=(size, size))
        self._order = pattern.data.astype(int) - 1
        upper = sparse.csc_matrix(((2.0 * hessian[rows, columns])[self._order], pattern.indices, pattern.indptr),
                                  shape=(size, size))
        solver = osqp.OSQP()
        solver.setup(upper, 2.0 * linear, sparse.eye(size, format="csc"), -bounds, bounds,
                     verbose=False, eps_abs=1e-10, eps_rel=1e-10, polishing=False, max_iter=4000)
        return solver


class ContouringBatch:
    """B model predictive contouring controllers stepped as one, each on its row of a batch's signals ((B, n)
    arrays): members of one shape (axes, horizon, delay, velocity estimate) are rows of one computation, so a
    batch's QPs are built and solved together. Each member returns what it would alone. It reads the
    reference's position and the axes' state, not the contour estimate (the MPCC's ``reads_estimate`` is
    False)."""

    needs_state = True

    def __init__(self, members: list):
        self.preview = members[0].preview
        shapes = {}
        for j, member in enumerate(members):
            shape = (member.n, member.horizon, member.delay, member.velocity_estimate)
            shapes.setdefault(shape, []).append(j)
        self.n = members[0].n
        self.size = len(members)
        self.groups = [(np.array(rows), _Rows([members[j] for j in rows])) for rows in shapes.values()]

    @property
    def solve_times(self) -> list:
        """Wall time of each step's solves, every row's together [s]."""
        return [sum(times) for times in zip(*(group.solve_times for _, group in self.groups))]

    def look_ahead(self, positions) -> None:
        """Each member's reference preview: ``positions`` (B, preview, n)."""
        positions = np.asarray(positions, dtype=float)
        for rows, group in self.groups:
            group.ahead = positions[rows]

    def step(self, estimate=None, reference=None, position=None, velocity=None) -> np.ndarray:
        position, velocity = np.asarray(position, dtype=float), np.asarray(velocity, dtype=float)
        reference_position = np.asarray(reference.position, dtype=float)
        if len(self.groups) == 1:
            return self.groups[0][1].step(reference_position, position, velocity)
        out = np.empty((self.size, self.n))
        for rows, group in self.groups:
            out[rows] = group.step(reference_position[rows], position[rows], velocity[rows])
        return out
