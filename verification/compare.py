"""Compare two signal histories over the UNION of their time ranges.

:func:`cfm_core.post.compare_histories` (used by ``cfm compare``) looks at the common window only,
so a run that stops just after the peak agrees perfectly with one that goes on. Here each history
is extended by ``fill`` outside its own range (0 for a drop test: the impactor acceleration is zero
before contact and after separation) and the two are compared on one uniform grid spanning both.
Besides the relative L2 error and the peak difference, the verdict uses the time of peak and the
duration of the event, and flags a drop-test signal that ends while still loaded.

Units: times in s, the signals in any one unit (m/s^2 for accelerations, N for forces).
"""

from __future__ import annotations

import math

import numpy as np

#: A drop-test signal whose last sample is above this fraction of its peak ended in contact.
ENDS_LOADED_FRACTION = 0.02
#: Level (fraction of the peak) that defines the event's duration from a filtered signal.
DURATION_FRACTION = 0.05


def _span(t, y, level) -> tuple[float, float]:
    """First and last time where |y| >= level (s)."""
    on = np.flatnonzero(np.abs(y) >= level)
    return float(t[on[0]]), float(t[on[-1]])


def compare_union(t1, y1, t2, y2, fill: float | None = 0.0) -> dict:
    """Compare history 1 with the reference history 2 (t increasing, 1-D, same unit).

    fill: the value of a history outside its own time range (0 for impactor accelerations); None
    holds each history's end values (a quasi-static force). Returns floats:

    - rel_l2 (-): ||y1 - y2|| / ||y2|| on a uniform grid over [min(t1[0], t2[0]), max(t1[-1], t2[-1])]
      with the finer of the two median spacings (linear interpolation);
    - peak_diff (-): (p1 - p2) / |p2|, p the sample of largest magnitude; t_peak_diff (s);
    - t_peak (s) of the reference, duration (s) of each (first to last |y| >= 5 % of its peak) and
      duration_diff (s); end_diff (s) = t1[-1] - t2[-1];
    - ends_loaded_1, ends_loaded_2 (-): |y[-1]| / peak of each (a drop test that ends while loaded
      was cut short).
    """
    t1, y1, t2, y2 = (np.asarray(v, dtype=float) for v in (t1, y1, t2, y2))
    start, end = min(t1[0], t2[0]), max(t1[-1], t2[-1])
    dt = min(float(np.median(np.diff(t1))), float(np.median(np.diff(t2))))
    n = int(math.ceil((end - start) / dt)) + 1
    grid = np.linspace(start, end, n)

    def on_grid(t, y):
        if fill is None:
            return np.interp(grid, t, y)
        return np.interp(grid, t, y, left=fill, right=fill)

    g1, g2 = on_grid(t1, y1), on_grid(t2, y2)
    i1, i2 = int(np.argmax(np.abs(y1))), int(np.argmax(np.abs(y2)))
    p1, p2 = float(y1[i1]), float(y2[i2])
    d1 = _span(t1, y1, DURATION_FRACTION * abs(p1))
    d2 = _span(t2, y2, DURATION_FRACTION * abs(p2))
    return {
        "rel_l2": float(np.linalg.norm(g1 - g2) / np.linalg.norm(g2)),
        "peak_diff": (p1 - p2) / abs(p2),
        "t_peak": float(t2[i2]),
        "t_peak_diff": float(t1[i1] - t2[i2]),
        "duration": d2[1] - d2[0],
        "duration_diff": (d1[1] - d1[0]) - (d2[1] - d2[0]),
        "end_diff": float(t1[-1] - t2[-1]),
        "ends_loaded_1": abs(float(y1[-1])) / abs(p1) if p1 else 0.0,
        "ends_loaded_2": abs(float(y2[-1])) / abs(p2) if p2 else 0.0,
    }
