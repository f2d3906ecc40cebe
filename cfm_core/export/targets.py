"""The export targets: file names, solver, entry point and calling convention of each, and the
implicit tangent routine where the target has a separate one (``tangent``; light: the command line
lists them without importing the code generator)."""

from __future__ import annotations

TARGETS = {
    "abaqus-umat": dict(source="umat.f", card="material.inp", solver="Abaqus/Standard UMAT (for CalculiX, 'cfm calculix "
                        "build' links it into ccx with the adaptor ccx's conventions need)", entry="umat", convention=(
                            "UMAT(STRESS, STATEV, DDSDDE, SSE, SPD, SCD, RPL, DDSDDT, DRPLDE, DRPLDT, STRAN, DSTRAN, "
                            "TIME, DTIME, TEMP, DTEMP, PREDEF, DPRED, CMNAME, NDI, NSHR, NTENS, NSTATV, PROPS, NPROPS, "
                            "COORDS, DROT, PNEWDT, CELENT, DFGRD0, DFGRD1, NOEL, NPT, LAYER, KSPT, KSTEP, KINC); "
                            "STRESS Cauchy 11, 22, 33, 12, 13, 23; DDSDDE the Jaumann-rate tangent of Kirchhoff "
                            "stress / J (engineering shear strains); error: PNEWDT = 0.25")),
    "abaqus-vumat": dict(source="vumat.f", card="material.inp", solver="Abaqus/Explicit VUMAT (double-precision "
                         "executable: abaqus ... double=both)", entry="vumat", convention=(
                             "VUMAT(nblock, ndir, nshr, nstatev, nfieldv, nprops, lanneal, stepTime, totalTime, dt, "
                             "cmname, coordMp, charLength, props, density, strainInc, relSpinInc, tempOld, "
                             "stretchOld, defgradOld, fieldOld, stressOld, stateOld, enerInternOld, enerInelasOld, "
                             "tempNew, stretchNew, defgradNew, fieldNew, stressNew, stateNew, enerInternNew, "
                             "enerInelasNew); arrays (nblock, *); stress corotational (R^T sigma R, F = R U, from "
                             "stretchNew) 11, 22, 33, 12, 23, 31; error: code in the last state variable")),
    "lsdyna-umat": dict(source="umat41.f", card="material.k", solver="LS-DYNA umat41, and utan41 for implicit runs, "
                        "with IHYPER = 1 (double-precision executable, solid elements)", entry="umat41", convention=(
                            "umat41(cm, eps, sig, epsp, hsv, dt1, capa, etype, tt, temper, failel, crv, nnpcrv, cma, "
                            "qmat, elsiz, idele, reject); F in hsv(NHV+1 .. NHV+9) column-major; sig Cauchy xx, yy, "
                            "zz, xy, yz, zx; error: code in hsv(NHV), reject = .true."),
                        tangent=dict(entry="utan41", convention=(
                            "utan41(cm, eps, sig, epsp, hsv, dt1, unsym, capa, etype, tt, temper, es, crv, nnpcrv, "
                            "failel, cma, qmat), called for implicit runs; F in hsv(NHV+1 .. NHV+9) column-major; "
                            "es(6,6) the spatial tangent c/J (push-forward of dS/dE over J, the Truesdell rate of "
                            "Kirchhoff stress / J, no Jaumann stress terms), consistent with the step dt1 for the "
                            "Prony series, rows and columns xx, yy, zz, xy, yz, zx, engineering shear strains; "
                            "unsym = .false. (symmetric); error: es = 0 and a line to unit 6"))),
}
