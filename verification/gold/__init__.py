"""Gold-standard regression suite: named cases with stored reference values.

Each case (:mod:`.cases`) runs one scene or material-point history on one backend and reduces it to
key outputs (:mod:`.record`): step count, time steps (s), energies (J), the signal's peak, time
of peak and samples, the drop-test summary. The stored references live in
``verification/gold/data/<case>.json`` with the commit that produced them and, per case, where the
value was checked independently (the check runs when the reference is written). The regression
test (tests/regression/test_gold.py) recomputes every case and compares with a relative tolerance
of :data:`RTOL`.

Regenerate after an intended change, printing every difference first::

    python -m cfm_verification.gold            # compare only, exit 1 on a difference
    python -m cfm_verification.gold --update   # rewrite the references (runs the independent checks)
    python -m cfm_verification.gold --update --only skfem   # only cases whose name contains 'skfem'

``--update`` runs from committed code only (``--allow-dirty`` to override, stamped so) and writes
nothing whose independent check fails; a reference records the code state and the digests of
its inputs (:mod:`.store`).
"""

#: Relative tolerance (-) of every stored value (arrays: relative to the array's largest magnitude).
RTOL = 1e-3
