"""Post-processing: what happens to a backend's histories after the run (backend-neutral).

Flow: :class:`~cfm_core.simulation.Result` -> histories.py (uniform grid, box average of the
impulse, SAE J211/1 CFC filter from filters.py) -> metrics.py (peak, duration, pulse width,
comparisons) -> summary.py (summary.json content) -> writers.py (atomic CSV/JSON/VTU files) and
plots.py (PNG figures); compare.py compares finished runs of any backends. Post-processing never
knows which backend ran (docs/conventions.md section 3).
"""

from .filters import cfc_filter
from .histories import G0, acceleration_histories, reaction_histories, resample_acceleration
from .metrics import compare_histories, drop_test_metrics, reaction_metrics, relative_l2
from .summary import SUMMARY_UNITS, summarize, summarize_reaction

__all__ = ["cfc_filter", "G0", "acceleration_histories", "reaction_histories", "resample_acceleration",
           "compare_histories", "drop_test_metrics", "reaction_metrics", "relative_l2", "SUMMARY_UNITS",
           "summarize", "summarize_reaction"]
