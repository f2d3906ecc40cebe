"""CalculiX (ccx 2.20) with the project's generated Abaqus UMATs linked in: the ``calculix`` backend.

What is CalculiX's: the elements (C3D8R hexahedra), the time integration (``*STATIC`` or
``*DYNAMIC``, fixed increments for prescribed motion, automatic ones for the drop test), the
Newton iteration and equation solver (SPOOLES), boundary conditions, reaction forces, the rigid
body and the penalty contact (``SURFACE TO SURFACE``). What is the project's: the material (the
UMAT generated from the material's single definition, :mod:`cfm_core.export`), the adaptor
between ccx's PK2 convention and the UMAT's Cauchy / Jaumann one (:file:`adaptor.f`), the build
(:mod:`.build`, ``cfm calculix build``), the decks (:mod:`.deck`, :mod:`.drop`), the reading of
results and the stop after separation (:mod:`.runner`, :mod:`.dropread`).

Result.info: solver, element, deck_lines, increments, threads, setup_time (s), ccx (path), build (key);
drop test also stop ("separated" or "end_time"), umat_cutbacks (iterates the UMAT refused),
energy_note (what the energy balance leaves out, or why there are no energies) and hourglass_note.
"""

from __future__ import annotations

from cfm_core.simulation.backend import Backend

from .options import CalculixOptions

__all__ = ["CalculixBackend"]


class CalculixBackend(Backend):
    """CalculiX ccx with the generated UMAT: single element, relaxation and the drop test."""

    name = "calculix"
    kind = "implicit"
    quasi_static = True
    description = ("CalculiX ccx 2.20 (Debian source, built by 'cfm calculix build') with the generated Abaqus "
                   "UMAT linked in: C3D8R, *STATIC / *DYNAMIC; drop test with a rigid impactor cap and "
                   "frictionless penalty contact")
    options_class = CalculixOptions
    needs_tangent = True
    devices = ("cpu",)
    dtypes = ("float64",)
    #: Not in the automatic backend set of ``cfm verify`` (it needs a local build and its drop
    #: test takes minutes): verified when named (``cfm verify --backends calculix``) and
    #: by tests/backends/test_calculix_*.py.
    experimental = True

    def available(self) -> tuple[bool, str]:
        """Whether a CalculiX build exists in the cache (``cfm calculix build`` makes one).

        Returns
        -------
        ok : bool
            True when a build exists.
        reason : str
            Empty when usable, else how to get it.
        """
        from cfm_core.material.registry import make_material

        from .build import find

        if find() is None:
            return False, "CalculiX is not built here; run `cfm calculix build` (Debian/Ubuntu, apt, ~10 min once)"
        stale = [name for name in ("cfm", "neo-hookean") if find(make_material(name)) is None]
        if stale:
            return False, (f"the CalculiX build here holds an older definition of {', '.join(stale)}; run "
                           f"`cfm calculix build` (seconds: CalculiX itself is kept)")
        return True, ""

    def build(self, materials=None, say=print) -> dict:
        """Build ccx with the generated UMATs of ``materials`` (see :func:`.build.build`).

        Parameters
        ----------
        materials : sequence of str, optional
            Registered material names; default ``cfm`` and ``neo-hookean``.
        say : callable
            Called with one progress line at a time.

        Returns
        -------
        dict
            The build record: ``ccx`` path, ``key``, ``materials``, ``seconds`` (s), ``cached``.
        """
        from .build import DEFAULT_MATERIALS, build

        return build(tuple(materials) if materials else DEFAULT_MATERIALS, say=say)

    def run(self, model, *, progress=None, **options):
        """Run a :class:`cfm_core.scene.Model` in ccx; return a :class:`cfm_core.simulation.result.Result`.

        Options: :class:`.options.CalculixOptions`. Raises InputError (no build with the model's
        material, an unsupported scene, a bad option) or NumericalError (ccx or the UMAT stopped).
        """
        from .build import find
        from .runner import check_ccx, run_ccx

        self.check_model(model)
        opts = CalculixOptions.from_mapping(options)
        rec = find(model.material) or {}
        ccx = check_ccx(rec.get("ccx"))
        from cfm_backends.threads import free_cores

        res = run_ccx(ccx, model, threads=opts.threads or free_cores(), max_increment=opts.max_increment,
                      native=opts.native, keep=opts.keep, separation_time=opts.separation_time, progress=progress,
                      penalty=opts.contact_stiffness)
        res.info.update({"ccx": ccx, "build": rec.get("key")})
        if progress is not None:
            progress(float(res.t[-1]))
        return res
