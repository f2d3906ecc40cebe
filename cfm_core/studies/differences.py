"""Forward-difference Jacobians of drop-test objectives (calibrate, fit_peaks).

The perturbed points of one Jacobian are handed to the objective together, so that their drop
tests go to the runner as one set (in parallel on Dask, as batches on torch). A step that would
leave the upper bound of its coordinate is taken backwards.
"""

from __future__ import annotations

from typing import Callable

import numpy as np


def forward_steps(x, upper, h) -> list[float]:
    """The signed step of each coordinate: ``h_i``, or ``-h_i`` where ``x_i + h_i`` passes ``upper_i``.

    Parameters
    ----------
    x : ndarray, shape (p,)
        The point, in the fitted coordinates.
    upper : ndarray, shape (p,)
        Upper bounds of the coordinates.
    h : sequence of float, length p
        Step sizes (> 0), in the units of the coordinates.

    Returns
    -------
    list of float
        The steps, length p.
    """
    return [-hi if xi + hi > ui else hi for xi, hi, ui in zip(x, h, upper)]


def forward_jacobian(values: Callable[[list], list], x, f0, steps, scale=1.0) -> np.ndarray:
    """Forward-difference Jacobian of f / scale: column i is (f(x + h_i e_i) - f(x)) / scale / h_i.

    Parameters
    ----------
    values : callable
        ``values(points) -> [f(point), ...]``: the vector f (shape (m,)) at every point of the list,
        all evaluated in one call.
    x : ndarray, shape (p,)
        The point.
    f0 : ndarray, shape (m,)
        f(x).
    steps : sequence of float, length p
        Signed steps (:func:`forward_steps`).
    scale : float or ndarray of shape (m,)
        Divides the differences (e.g. the targets of relative residuals); 1: none.

    Returns
    -------
    ndarray, shape (m, p)
        The Jacobian.
    """
    x = np.asarray(x, dtype=float)
    points = [x + h * np.eye(x.size)[i] for i, h in enumerate(steps)]
    return np.column_stack([(f - f0) / scale / h for f, h in zip(values(points), steps)])
