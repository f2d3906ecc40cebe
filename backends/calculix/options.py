"""Options of the calculix backend's ``run`` (one typed declaration: unit, default, range, meaning)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cfm_core.simulation.options import Options, document, option


@document
@dataclass(frozen=True)
class CalculixOptions(Options):
    """Options of the CalculiX backend (SI units)."""

    owner = "calculix backend"

    threads: int = option(None, "-", "threads of ccx (OMP_NUM_THREADS, CCX_NPROC_EQUATION_SOLVER, CCX_NPROC_RESULTS, "
                          "CCX_NPROC_STIFFNESS)", kind="int", low=1, high=256,
                          none="the cores free to this process (cfm_backends.threads.free_cores)")
    max_increment: float = option(math.inf, "s", "largest time increment: prescribed motion, fixed increments "
                                  "(DIRECT) also bounded by the output interval and 20 per prescribed segment; drop "
                                  "test, automatic increments up to it (inf: 50 us)", low=0.0, low_open=True)
    native: bool = option(False, "-", "CalculiX's own *HYPERELASTIC, NEO HOOKE instead of the generated UMAT "
                          "(neo-hookean material only)", kind="bool")
    separation_time: float = option(2e-4, "s", "drop test: stop this long after the impactor left the specimen "
                                    "(as the other backends)", low=0.0)
    contact_stiffness: float = option(1e11, "Pa/m", "drop test: penalty stiffness of the impactor and plate "
                                      "contact (PRESSURE-OVERCLOSURE=LINEAR)", low=0.0, low_open=True)
    keep: str = option(None, "-", "folder to run ccx in and keep (deck, .dat, .frd, .sta)", kind="str",
                       none="a temporary folder")
