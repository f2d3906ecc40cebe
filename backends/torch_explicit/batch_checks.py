"""Checks of a torch batch: which models may share one, and the error of a run that failed.

Split from :mod:`.batch` (the batched time loop); see its docstring for what a batch shares.
"""

from __future__ import annotations

import numpy as np

from cfm_backends.explicit import errors
from cfm_core.errors import InputError, NumericalError

from . import material as mat

# error codes per run (flags on the device)
OK, INVERTED, NONFINITE, COLLAPSE, STATE, NEWTON, FALLBACK = 0, 1, 2, 3, 4, 5, 6


def check_batch(models) -> None:
    """InputError unless the models can run as one batch (see the module docstring)."""
    if not models:
        raise InputError("torch batch: no models given.")
    m0 = models[0]
    if m0.sphere is None or m0.prescribed is not None:
        raise InputError(f"torch batch: model '{m0.name}' is not a drop test (a rigid sphere and no prescribed "
                         f"motion); run it alone with TorchExplicitBackend().run.")
    k0 = len(mat.prony(m0.material)[0])
    s0 = m0.sphere
    for i, m in enumerate(models[1:], 1):
        p0, pm = m0.part_list(), m.part_list()
        same = [("nodes", np.array_equal(m.nodes, m0.nodes)), ("hexes", np.array_equal(m.hexes, m0.hexes)),
                ("density", m.density == m0.density),
                ("parts", len(pm) == len(p0) and all(
                    a.density == b.density and np.array_equal(a.elements, b.elements) and a.material.spec == b.material.spec
                    and len(mat.prony(a.material)[0]) == len(mat.prony(b.material)[0]) for a, b in zip(pm, p0))),
                ("fixed_dofs", np.array_equal(np.asarray(m.fixed_dofs), np.asarray(m0.fixed_dofs))),
                ("sphere_nodes", np.array_equal(m.sphere_nodes, m0.sphere_nodes)),
                ("plane_nodes", np.array_equal(m.plane_nodes, m0.plane_nodes)),
                ("plane", m.plane == m0.plane), ("friction", m.friction == m0.friction),
                ("gravity", m.gravity == m0.gravity), ("symmetry_factor", m.symmetry_factor == m0.symmetry_factor),
                ("stop_after_separation", m.stop_after_separation == m0.stop_after_separation),
                ("material", m.material.spec == m0.material.spec and len(mat.prony(m.material)[0]) == k0),
                ("sphere", m.sphere is not None and m.sphere.radius == m0.sphere.radius
                 and tuple(m.sphere.center[:2]) == tuple(m0.sphere.center[:2])
                 and (m.sphere.shape, m.sphere.edge_radius, tuple(m.sphere.moves))
                 == (s0.shape, s0.edge_radius, tuple(s0.moves))),
                ("prescribed", m.prescribed is None)]
        bad = [name for name, ok in same if not ok]
        if bad:
            raise InputError(f"torch batch: model {i} ('{m.name}') differs from model 0 ('{m0.name}') in "
                             f"{', '.join(bad)}; a batch shares the mesh, density, constraints, contact, the "
                             f"impactor's shape, radius and free axes, the parts and their material definitions (parameter values, Prony terms, "
                             f"velocity, impactor mass and end time may differ). Run it in another batch.")


def run_error(b: int, model, c: int, e, ren, dtype, collapse: float, general: bool = False):
    """The NumericalError of batch run ``b`` from its error code ``c`` and record ``e`` (element, t,
    value, m0, m1, m2, dt0); ``ren``: the batch's renumbering (parts) or None; ``collapse``: the
    option's collapse ratio; ``general``: the impactor uses :mod:`.impactor_contact`."""
    import torch

    el, t, val, m = int(e[0]), e[1], e[2], e[3:6]
    if ren is not None:            # parts: internal element -> the user's
        el = ren.user_element(el)
    where = f"batch run {b} ('{model.name}')"
    if c == INVERTED:
        err = errors.inverted(model, el, t, val, e[6])
    elif c == NONFINITE:
        material = model.part_list()[int(model.element_part()[el])].material
        err = errors.nonfinite(material, f"element {el} at t = {t:.6g} s", m, val, t, el,
                               float32=dtype == torch.float32)
    elif c == COLLAPSE:
        err = errors.collapse(model, t, el, val, e[6], collapse)
    elif c == STATE:
        err = errors.state(model, t)
    elif c == NEWTON:
        err = NumericalError(f"contact Newton iteration of the {model.sphere.shape} impactor did not converge in "
                             f"{_fixed(general)} iterations at t = {t:.6g} s (sync-free batch); run with "
                             f"sync_free=False.", time=t, quantity="contact")
    else:
        err = NumericalError(f"an element needed the Jacobi eigen fallback for a C that is not isotropic to "
                             f"round-off at t = {t:.6g} s (sync-free batch); run with sync_free=False.",
                             time=t, quantity="eigen fallback")
    err.args = (f"{where}: {err.args[0]}",) + err.args[1:]
    return err


def _fixed(general: bool) -> int:
    from .batch_contact import FIXED_ITERATIONS
    from .impactor_contact import ITERATIONS

    return ITERATIONS if general else FIXED_ITERATIONS
