"""Cross-coupled iterative learning control: the same path machined pass after pass, the errors of one pass
correcting the next (K. L. Barton and A. G. Alleyne, "A cross-coupled iterative learning control design for
precision motion control", IEEE Transactions on Control Systems Technology 16(6), 2008; the learning law's
parts as in D. A. Bristow, M. Tharayil and A. G. Alleyne, "A survey of iterative learning control", IEEE
Control Systems Magazine 26(3), 2006).

During a pass the controller plays back its learned correction u_j(k), one value per axis added to the
servo commands as a cross-coupled controller's are. Between passes (:func:`learn`):

    u_{j+1}(k) = Q[ u_j(k) + gamma_t e_j(k + lead) + gamma_c eps_j(k + lead) ]

e the axis tracking errors (reference - position), eps the estimated contour error vector (from the
position towards the contour, as the CCCs read it), resolved along the axes: the contour term is the
cross-coupling, which learns what the axes must do together, the tracking term each axis alone. ``lead``
steps of phase lead cover the loop's delay (the survey's P-type law with lead); Q is a zero-phase
Butterworth low-pass (scipy.signal.filtfilt) of order 2 at ``q_cutoff`` Hz, which keeps the learning from
amplifying what the loop cannot follow.
"""
from __future__ import annotations

import numpy as np

__all__ = ["LearnedCorrection", "learn"]


class LearnedCorrection:
    """Plays back a learned per-axis correction: step k returns row k of ``table`` (zeros past its end or
    without one: the first pass).

    Parameters
    ----------
    n_axes : int
    table : ndarray (steps, n_axes), optional
        u_j, the correction this pass plays back.
    """

    batchable = True

    def __init__(self, n_axes: int, table=None):
        self.n_axes = int(n_axes)
        self.table = np.zeros((0, self.n_axes)) if table is None else np.asarray(table, dtype=float)
        self.k = 0

    def step(self, estimate, reference=None, position=None, velocity=None) -> np.ndarray:
        table, k = self.table, self.k
        self.k = k + 1
        if k < table.shape[-2]:
            return table[..., k, :].copy()
        return np.zeros(self.n_axes)


def learn(correction, reference_position, position, estimate_vector, sample_time: float, gamma_tracking: float,
          gamma_contour: float, lead: int = 1, q_cutoff: float = 0.0) -> np.ndarray:
    """u_{j+1} from pass j: its ``correction`` u_j (steps, n; None or shorter: zeros after its end), the
    reference and the measured positions and the contour error estimate of each of its steps (module
    docstring). ``q_cutoff`` 0 (or at or above the Nyquist frequency): no Q-filter."""
    reference_position, position = np.asarray(reference_position, dtype=float), np.asarray(position, dtype=float)
    steps, n = position.shape
    previous = np.zeros((steps, n))
    if correction is not None and len(correction):
        used = min(len(correction), steps)
        previous[:used] = np.asarray(correction, dtype=float)[:used]
    error = gamma_tracking * (reference_position - position) + gamma_contour * np.asarray(estimate_vector, dtype=float)
    shifted = np.vstack([error[lead:], np.repeat(error[-1:], min(lead, steps), axis=0)]) if lead else error
    out = previous + shifted
    nyquist = 0.5 / sample_time
    if 0.0 < q_cutoff < nyquist and steps > 15:
        from scipy import signal     # here, not at the top: scipy.signal takes a node 1.7 s to import
        sections = signal.butter(2, q_cutoff / nyquist, output="sos")   # second-order sections: sound at any cutoff
        out = signal.sosfiltfilt(sections, out, axis=0)
    return out
