"""Levenberg-Marquardt: the one solver of the small nonlinear least-squares problems of an
encode (a table's coefficients refined on renders, :mod:`brdfkit.basis.refine_on_screen`;
fitted through a residual's correction, :mod:`brdfkit.residual.encoding`).

A problem is ``min_x |r(x)|^2`` over a few unknowns ``x`` (one channel's ``K``
coefficients); each iteration solves the damped normal equations with Marquardt's scaling
of the damping (the diagonal of ``J^T J``), ``(J^T J + mu diag(J^T J)) dx = -J^T r``, and
takes the step only where it lowers the cost, raising ``mu`` by :data:`UP` until one does
(at most :data:`TRIES` times), lowering it by :data:`DOWN` after a step taken. The
problem is done when no damping lowers the cost, or when a step lowers it by at most
:data:`TOLERANCE` of its value before the step. Everything is float64 and counted in
iterations: the same problem gives the same bytes.

Examples
--------
>>> import numpy as np
>>> t = np.linspace(0.0, 1.0, 20)
>>> y = 2.0 * np.exp(-1.5 * t)
>>> def evaluate(x):
...     e = np.exp(-x[1] * t)
...     return x[0] * e - y, e
>>> def jacobian(x, e):
...     return np.stack([e, -x[0] * t * e], axis=1)
>>> np.round(levenberg_marquardt(evaluate, jacobian, np.array([1.0, 1.0]), steps=50), 6).tolist()
[2.0, 1.5]
"""

from __future__ import annotations

import numpy as np

__all__ = ["DAMPING", "DAMPING_MIN", "UP", "DOWN", "TRIES", "TOLERANCE", "LevenbergMarquardt",
           "levenberg_marquardt"]

DAMPING = 1e-3
"""The damping ``mu`` a problem starts with (relative to the diagonal of ``J^T J``)."""
DAMPING_MIN = 1e-7
"""The damping's floor after successful steps."""
UP = 4.0
"""Factor of the damping after a trial step that does not lower the cost."""
DOWN = 3.0
"""Divisor of the damping after a step taken."""
TRIES = 8
"""Trial steps an iteration makes, each more damped, before the problem is done."""
TOLERANCE = 1e-6
"""A step that lowers the cost by at most this share of it ends the problem."""


class LevenbergMarquardt:
    """The iterations of one problem, one at a time (:meth:`step`), so that a caller can
    check something between them (the held-out error of a refinement).

    Parameters
    ----------
    evaluate
        ``evaluate(x) -> (r, state)``: the residuals ``(R,)`` float64 at ``x`` and what
        ``jacobian`` needs of that evaluation (anything).
    jacobian
        ``jacobian(x, state) -> J``: ``(R, n)`` float64, ``d r / d x`` at ``x``.
    x0
        ``(n,)`` the start.

    Attributes
    ----------
    x, cost
        The iterate (float64 ``(n,)``) and ``|r(x)|^2``.
    iterations
        Steps taken.
    done
        No further step will be taken (module docstring).
    """

    def __init__(self, evaluate, jacobian, x0):
        self.evaluate, self.jacobian = evaluate, jacobian
        self.x = np.array(x0, np.float64)
        self.r, self.state = evaluate(self.x)
        self.cost = float(self.r @ self.r)
        self.damping, self.iterations, self.done = DAMPING, 0, False

    def step(self) -> bool:
        """One iteration (nothing once :attr:`done`); returns :attr:`done`."""
        if self.done:
            return True
        jac = self.jacobian(self.x, self.state)
        jtj, g = jac.T @ jac, jac.T @ self.r
        scale = np.diag(np.maximum(np.diag(jtj), 1e-30))
        for _ in range(TRIES):
            trial = self.x - np.linalg.solve(jtj + self.damping * scale, g)
            r, state = self.evaluate(trial)
            cost = float(r @ r)
            if cost < self.cost:
                self.done = self.cost - cost <= TOLERANCE * self.cost
                self.x, self.r, self.state, self.cost = trial, r, state, cost
                self.damping = max(self.damping / DOWN, DAMPING_MIN)
                self.iterations += 1
                return self.done
            self.damping *= UP
        self.done = True
        return True


def levenberg_marquardt(evaluate, jacobian, x0, steps: int) -> np.ndarray:
    """``x`` after at most ``steps`` iterations of :class:`LevenbergMarquardt` (fewer when
    the problem is done): float64 ``(n,)``."""
    lm = LevenbergMarquardt(evaluate, jacobian, x0)
    for _ in range(int(steps)):
        if lm.step():
            break
    return lm.x
