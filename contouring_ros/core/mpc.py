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

The QP is condensed onto the N commands of each axis (n N variables, box constraints only) and solved by
OSQP (Stellato et al., Math. Prog. Comp. 12, 2020) where a limit is set; without limits its unconstrained
optimum is the solution of one linear system. Every solve's wall time is kept (:attr:`solve_times`).
"""
from __future__ import annotations

import time

import numpy as np

from ..errors import ContouringError
from .plants import mass_damper_hold_terms

__all__ = ["ModelPredictiveContouring", "MemberBatch", "sampled_mass_damper", "VELOCITY_ESTIMATES"]

VELOCITY_ESTIMATES = ("measured", "model")


def sampled_mass_damper(mass: float, damping: float, gain: float, sample_time: float) -> tuple:
    """(A, B) of x = (P, V): x+ = A x + B u for K / (M s^2 + B s) under a zero-order hold, as
    :class:`~contouring_ros.core.plants.MassDamperAxis` steps it."""
    vv, vw, pv, pw = mass_damper_hold_terms(float(mass), float(damping), float(sample_time))
    scale = float(gain) / float(mass)
    return np.array([[1.0, pv], [0.0, vv]]), np.array([pw * scale, vw * scale])


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
        now (a deadbeat observer: where the drive's velocity is its differentiated encoder, the reported one
        is the mean over the last step, half a sample late, which a fast axis mode turns into a wrong state).
    """

    needs_state = True
    #: a batch (:mod:`contouring_ros.core.batch`) steps each member's own object (:meth:`batch_of`)
    batchable = True

    @classmethod
    def batch_of(cls, members: list) -> "MemberBatch":
        """The batch of ``members``: each solves its own QP on its row of the batch's signals, with the same
        numbers as alone (the rest of the loop runs vectorised around it)."""
        return MemberBatch(members)

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
        self.last_position = None            # the axes' position readings of the last step
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
        self._free, self._forced = np.array(free), np.array(forced_all)            # (n, N, 2), (n, N, N)
        self._forced_sum = self._forced.sum(axis=2)          # the response to a constant input of 1, (n, N)
        difference = np.eye(big_n) - np.eye(big_n, k=-1)
        # the rate's Hessian, r_rate D^T D on each axis' block of the diagonal
        self._rates = np.kron(np.eye(n), self.r_rate * difference.T @ difference)
        self._rate_first = self.r_rate * difference.T[:, 0]      # times the previous command: the first change
        self.held = [np.zeros(n) for _ in range(self.delay)]      # computed, not yet applied (oldest first)
        self.previous = np.zeros(n)          # the last command computed
        self.applied = None                  # the command applied over the last step (None before the first)
        self.last_velocity = None            # the axes' velocities of the last step
        self.disturbance = np.zeros(n)       # constant input disturbance estimate [command units]
        self.ahead = np.zeros((0, n))
        self.solve_times = []                # wall time of each step's solve [s]
        self.unconverged = 0                 # solves that ended at OSQP's iteration limit (their iterate, clipped)
        self._solver = None
        self._plan = None                    # the last solution, warm start of the next

    def look_ahead(self, positions) -> None:
        """This step's reference positions at k + 1 .. k + :attr:`preview`, an array (preview, n)."""
        self.ahead = np.asarray(positions, dtype=float)

    def _reconstructed_velocity(self, position) -> np.ndarray:
        """Each axis' velocity now from P_k, P_k-1 and the command u (+ disturbance d) applied between them:
        P_k = P_k-1 + pv V_k-1 + b0 (u + d) gives V_k-1, and V_k = vv V_k-1 + b1 (u + d)."""
        out = np.empty(self.n)
        for i, (a_matrix, b_vector) in enumerate(self.models):
            drive = self.applied[i] + self.disturbance[i]
            before = (position[i] - self.last_position[i] - b_vector[0] * drive) / a_matrix[0, 1]
            out[i] = a_matrix[1, 1] * before + b_vector[1] * drive
        return out

    def _estimate_disturbance(self, position, velocity) -> None:
        if self.disturbance_gain and self.applied is not None:
            for i, (a_matrix, b_vector) in enumerate(self.models):
                predicted = a_matrix[1, 1] * self.last_velocity[i] + b_vector[1] * (self.applied[i] + self.disturbance[i])
                self.disturbance[i] += self.disturbance_gain * (velocity[i] - predicted) / b_vector[1]

    def _weights(self, reference_position) -> np.ndarray:
        """(N, n, n): q_contour (I - t t^T) + q_lag t t^T at each predicted step, t the unit tangent of the
        reference there (central differences of the preview; isotropic q_contour where it stands still)."""
        points = np.vstack([reference_position, self.ahead[:self.preview]])
        steps = self.delay + 1 + np.arange(self.horizon)              # rows of the predicted points
        after = np.minimum(steps + 1, len(points) - 1)
        tangents = points[after] - points[steps - 1]
        lengths = np.linalg.norm(tangents, axis=1)
        moving = lengths > 1e-15
        t = tangents / np.where(moving, lengths, 1.0)[:, None]
        along = t[:, :, None] * t[:, None, :] * moving[:, None, None]
        return self.q_contour * (np.eye(self.n) - along) + self.q_lag * along

    def step(self, estimate=None, reference=None, position=None, velocity=None) -> np.ndarray:
        position, velocity = np.asarray(position, dtype=float), np.asarray(velocity, dtype=float)
        if self.velocity_estimate == "model" and self.applied is not None:
            velocity = self._reconstructed_velocity(position)
        self.last_position = position
        self._estimate_disturbance(position, velocity)
        n, big_n = self.n, self.horizon
        # the state when the command computed now acts: the held commands applied first
        states = []
        for i, (a_matrix, b_vector) in enumerate(self.models):
            x = np.array([position[i], velocity[i]])
            for command in self.held:
                x = a_matrix @ x + b_vector * (command[i] + self.disturbance[i])
            states.append(x)
        targets = self.ahead[self.delay:self.delay + big_n]          # (N, n)
        weights = self._weights(np.asarray(reference.position, dtype=float))
        # e_j = offsets[:, j] + forced[:, j] @ U: H = F^T W F + the rate's, f = F^T W offsets - the first change's
        offsets = np.einsum("ajk,ak->aj", self._free, np.asarray(states)) \
            + self._forced_sum * self.disturbance[:, None] - targets.T                # (n, N)
        weighted = np.einsum("jab,bjk->ajbk", weights, self._forced)                   # W F, (n, N, n, N)
        hessian = np.einsum("aji,ajbk->aibk", self._forced, weighted).reshape(n * big_n, n * big_n) + self._rates
        linear = np.einsum("aji,jab,bj->ai", self._forced, weights, offsets)
        linear -= self._rate_first[None, :] * self.previous[:, None]
        linear = linear.reshape(n * big_n)
        started = time.perf_counter()
        plan = self._solve(hessian, linear)
        self.solve_times.append(time.perf_counter() - started)
        command = plan[::big_n].copy()             # each axis' first command
        self._plan = plan
        self.last_velocity = velocity
        if self.delay:
            self.applied = self.held[0]
            self.held = self.held[1:] + [command]
        else:
            self.applied = command
        self.previous = command
        return command

    def _solve(self, hessian, linear) -> np.ndarray:
        """argmin U^T H U + 2 f^T U within the command limits."""
        if not np.isfinite(self.limits).any():
            return np.linalg.solve(hessian, -linear)
        scale = 1.0 / max(float(np.max(np.abs(np.diag(hessian)))), 1e-300)   # OSQP's tolerances act on O(1) costs
        hessian, linear = hessian * scale, linear * scale
        if self._solver is None:
            self._set_up_solver(hessian, linear)
        else:
            self._solver.update(Px=(2.0 * hessian[self._upper])[self._order], q=2.0 * linear)
            if self._plan is not None:
                self._solver.warm_start(x=self._plan)
        result = self._solver.solve(raise_error=False)
        plan = np.asarray(result.x, dtype=float)
        if result.info.status == "maximum iterations reached" and np.all(np.isfinite(plan)):
            self.unconverged += 1       # the last iterate, within the bounds once clipped: still a usable plan
        elif result.info.status not in ("solved", "solved inaccurate") or not np.all(np.isfinite(plan)):
            raise ContouringError(f"step {len(self.solve_times)}: the MPCC quadratic programme was not solved "
                                  f"(OSQP: {result.info.status}): its weights q_contour, q_lag and r_rate may "
                                  "span too many decades")
        return np.clip(plan, -self._bounds, self._bounds)

    def _set_up_solver(self, hessian, linear) -> None:
        """OSQP, set up once with the first step's QP; what does not change from step to step (the Hessian's
        pattern, the bounds) is kept for the updates."""
        import osqp
        from scipy import sparse
        size = len(linear)
        self._upper = rows, columns = np.triu_indices(size)
        bounds = np.repeat(self.limits, self.horizon)
        self._bounds = np.where(np.isfinite(bounds), bounds, 1e30)
        # the whole upper triangle stored, zeros included, so that every step's update keeps the pattern
        pattern = sparse.csc_matrix((np.arange(1.0, len(rows) + 1.0), (rows, columns)), shape=(size, size))
        self._order = pattern.data.astype(int) - 1
        upper = sparse.csc_matrix(((2.0 * hessian[rows, columns])[self._order], pattern.indices, pattern.indptr),
                                  shape=(size, size))
        self._solver = osqp.OSQP()
        self._solver.setup(upper, 2.0 * linear, sparse.eye(size, format="csc"), -self._bounds, self._bounds,
                           verbose=False, eps_abs=1e-10, eps_rel=1e-10, polishing=False, max_iter=4000)


class MemberBatch:
    """B contour controllers of one class stepped one after another, each on its row of a batch's signals
    ((B, n) arrays, (B, 1) columns): a batch for a controller whose step is an optimisation of its own (the
    MPCC's QP) and so cannot run on stacked numbers. Each member returns what it would alone. It reads the
    reference's position and the axes' state, not the contour estimate (the MPCC's ``reads_estimate`` is
    False)."""

    needs_state = True

    def __init__(self, members: list):
        self.members = list(members)
        self.preview = getattr(self.members[0], "preview", 0)

    def look_ahead(self, positions) -> None:
        """Each member's reference preview: ``positions`` (B, preview, n)."""
        for member, ahead in zip(self.members, positions):
            member.look_ahead(ahead)

    def step(self, estimate=None, reference=None, position=None, velocity=None) -> np.ndarray:
        out = np.empty((len(self.members), self.members[0].n))
        position, velocity = np.asarray(position, dtype=float), np.asarray(velocity, dtype=float)
        reference_position = np.asarray(reference.position, dtype=float)
        for j, member in enumerate(self.members):
            out[j] = member.step(None, _ReferenceRow(reference_position[j]), position[j], velocity[j])
        return out


class _ReferenceRow:
    """One member's reference position, all that a :class:`MemberBatch` member reads of the reference."""

    __slots__ = ("position",)

    def __init__(self, position):
        self.position = position
