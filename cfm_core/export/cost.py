"""Cost of one UMAT call at a Gauss point, measured in Fortran (no Python in the loop).

``python -m cfm_core.export.cost [MATERIAL]`` compiles the generated UMAT with a small driver
that calls it ``n`` times at a compressed, sheared state (stress, DDSDDE and the Prony update
every call, as Abaqus/Standard does per integration point and iteration) and prints the time per
call. Compiled with the harness's flags (gfortran -O2).
"""

from __future__ import annotations

import ctypes
import sys

import numpy as np

from ..material.registry import make_material
from . import layout
from .generate import generate, sizes
from .harness import compile_library

DRIVER = """
      subroutine cfmbench(ncall, props, nprops, nstatv, f1, seconds)
      implicit none
      integer, parameter :: dp = selected_real_kind(15, 307)
      integer, intent(in) :: ncall, nprops, nstatv
      real(dp), intent(in) :: props(nprops), f1(3,3)
      real(dp), intent(out) :: seconds
      real(dp) :: stress(6), statev(nstatv), ddsdde(6,6), sse, spd
      real(dp) :: scd, rpl, ddsddt(6), drplde(6), drpldt, stran(6)
      real(dp) :: dstran(6), time(2), predef(1), dpred(1), coords(3)
      real(dp) :: drot(3,3), pnewdt, f0(3,3)
      character(len=80) :: cmname
      real(dp) :: c0, c1
      integer :: k
      cmname = 'CFM'
      f0 = 0.0d0
      drot = 0.0d0
      do k = 1, 3
        f0(k,k) = 1.0d0
        drot(k,k) = 1.0d0
      end do
      stran = 0.0d0
      dstran = 0.0d0
      time = 0.0d0
      predef = 0.0d0
      dpred = 0.0d0
      coords = 0.0d0
      spd = 0.0d0
      call cpu_time(c0)
      do k = 1, ncall
        stress = 0.0d0
        statev = 0.0d0
        sse = 0.0d0
        scd = 0.0d0
        pnewdt = 1.0d0
        call umat(stress, statev, ddsdde, sse, spd, scd, rpl, ddsddt,
     &    drplde, drpldt, stran, dstran, time, 1.0d-4, 0.0d0, 0.0d0,
     &    predef, dpred, cmname, 3, 3, 6, nstatv, props, nprops,
     &    coords, drot, pnewdt, 1.0d-3, f0, f1, 1, 1, 1, 1, 1, k)
      end do
      call cpu_time(c1)
      seconds = (c1 - c0) / dble(ncall)
      end subroutine cfmbench
"""


def umat_cost(material, calls: int = 200_000) -> float:
    """Seconds per UMAT call (stress, DDSDDE, Prony update) of ``material``, timed in Fortran.

    Parameters
    ----------
    material : Material
        A bound material; its generated UMAT is compiled with the driver.
    calls : int
        Number of calls timed.

    Returns
    -------
    float
        Processor time per call (s, Fortran ``cpu_time``: robust on a shared machine) at F = diag(0.7, 1.15, 1.2) with a 0.1 shear.

    Raises
    ------
    InputError
        gfortran is not installed.
    """
    ex = generate(material, "abaqus-umat")
    lib = compile_library(ex.files["umat.f"] + DRIVER, "umat-cost")
    fn = lib.function("cfmbench")
    props = layout.props(material)
    F = np.asfortranarray([[0.7, 0.1, 0.0], [0.0, 1.15, 0.0], [0.0, 0.0, 1.2]])
    out = np.zeros(1)
    ints = [np.array([v], dtype=np.int32) for v in (calls, props.size, sizes(material.spec)["NS"])]
    args = [ints[0], props, ints[1], ints[2], F, out]
    fn(*[a.ctypes.data_as(ctypes.c_void_p) for a in args])
    return float(out[0])


if __name__ == "__main__":  # pragma: no cover - a measurement for docs/user/export.md
    name = sys.argv[1] if len(sys.argv) > 1 else "cfm"
    seconds = umat_cost(make_material(name))
    print(f"{name}: {seconds * 1e6:.2f} us CPU per UMAT call (stress + DDSDDE + Prony update), gfortran -O2, one core")
