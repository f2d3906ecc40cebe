"""The explicit time loop (numba): central differences with a stable step recomputed every step.

One step n (time t^n, positions x^n, velocities v^{n-1/2}, previous step dt_{n-1/2}):

1. element pass at x^n: stresses (Prony with dt_{n-1/2}), forces, stress work, L_e / c_e;
2. dt_{n+1/2} = min(safety min_e L_e / c_e, dt_max); dtn = (dt_{n-1/2} + dt_{n+1/2}) / 2;
3. v^{n+1/2} = v^{n-1/2} + dtn a^n, x^{n+1} = x^n + dt_{n+1/2} v^{n+1/2} (fixed dofs stay);
   prescribed dofs move to X + u(t^{n+1}); the sphere moves with gravity only;
4. kinematic contact (sphere, plane) corrects x^{n+1}, v^{n+1/2} and the sphere;
5. energies and the record of step n (time t^n), then t^{n+1} = t^n + dt_{n+1/2}.

The contact force on the impactor at step n is M dV / dtn (dV its velocity correction), so
that V^{n+1/2} - V^{n-1/2} = dtn (F^n - M g) / M exactly; the impulse recorded at t^n is
sum_{k<n} F^k dtn_k + F^n dt_{n-1/2} / 2 (the velocity change up to t^n).

Runs until ``t_stop``, the end time, separation, a failure, or until ``hist`` is full, and
returns (rows written, code); codes and array layouts are in ``layout``.
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import math

import numpy as np
from numba import njit
from cfm_backends.numba_cache import key_on_folder

from .constitutive import prony_step
from .contact import plane_contact, sphere_contact
from .element import element_pass, energy_pass, gather_update
from .layout import *  # noqa: F401,F403

key_on_folder(__file__)  # numba's cache of these kernels is keyed on every file of the folder
# <<< standalone


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def advance(geo, mat, par, ipar, sc, st, cnt, presc, hist, t_stop):
    """Advance the model; see the module docstring. All arrays are modified in place."""
    conn, slot, chunks, mass, free, pmask, hptr, hrow = geo
    p, gam, tau = mat
    x, v, vold, ed, eh, fb, fint, fhg, dvc, bdt, bemin, status, errv = st
    snodes, plnodes, scr = cnt
    pnodes, px0, ptimes, pvals = presc
    sym = par[P_SYM]
    has_sphere = ipar[I_SPHERE] != 0
    has_plane = ipar[I_PLANE] != 0
    M = par[P_SMASS]
    rows = 0
    decay = np.zeros(gam.shape[0])
    gain = np.zeros(gam.shape[0])
    while rows < hist.shape[0]:
        t = sc[S_T]
        dtp = sc[S_DTPREV]
        # 1. elements
        prony_step(dtp, gam, tau, decay, gain)
        work, nbad = element_pass(x, v, conn, slot, chunks, ed, eh, fb, p, decay, gain, par[P_GINF], bdt, bemin,
                                  status, errv, par[P_RHO], par[P_HG], ipar[I_HGWAVE])
        if nbad > 0:
            for e in range(status.shape[0]):
                if status[e] != 0:
                    b = e // BLOCK
                    sc[S_ERRE] = e
                    sc[S_ERRV] = errv[b, 0]
                    sc[S_ERRM0] = errv[b, 1]
                    sc[S_ERRM1] = errv[b, 2]
                    sc[S_ERRM2] = errv[b, 3]
                    return rows, R_INVERTED if status[e] == 1 else R_NONFINITE
        sc[S_IE] += work
        # 2. stable step
        bmin = np.argmin(bdt)
        emin = bemin[bmin]
        dtc = par[P_SAFETY] * bdt[bmin]
        if sc[S_DT0] == 0.0 and math.isfinite(dtc):
            sc[S_DT0] = dtc
        dt = min(dtc, par[P_DTMAX])
        if not (dt > 0.0 and math.isfinite(dt)) or dtc < par[P_COLLAPSE] * sc[S_DT0]:
            sc[S_ERRE] = emin
            sc[S_ERRV] = dtc
            return rows, R_COLLAPSE
        dtn = 0.5 * (dtp + dt)
        # 3. central differences
        for k in range(snodes.shape[0]):
            I = snodes[k]
            dvc[I, 0] = 0.0
            dvc[I, 1] = 0.0
            dvc[I, 2] = 0.0
        for k in range(plnodes.shape[0]):
            I = plnodes[k]
            dvc[I, 0] = 0.0
            dvc[I, 1] = 0.0
            dvc[I, 2] = 0.0
        gather_update(fb, hptr, hrow, mass, free, fint, fhg, x, v, vold, dtn, dt)
        reaction = 0.0
        if ipar[I_PRESC] != 0:
            d = ipar[I_PDOF]
            u = np.interp(t + dt, ptimes, pvals)
            for k in range(pnodes.shape[0]):
                I = pnodes[k]
                target = px0[k] + u
                v[I, d] = (target - x[I, d]) / dt
                x[I, d] = target
                reaction += fint[I, d] - fhg[I, d]
        Zn = sc[S_Z]
        Vo = sc[S_V]
        Vs = Vo - dtn * par[P_GRAV]
        Zs = Zn + dt * Vs
        # 4. contact
        force = 0.0
        pen = 0.0
        dV = 0.0
        if has_sphere:
            dZ, dV, pen = sphere_contact(x, v, dvc, mass, free, snodes, scr, par[P_CX], par[P_CY],
                                         Zs, Vs, par[P_RADIUS], M, par[P_MU], dt)
            Zs += dZ
            Vs += dV
            force = M * dV / dtn
        if has_plane:
            plane_contact(x, v, dvc, mass, free, plnodes, par[P_PLANEZ], par[P_MU], dt)
        # 5. energies (modelled part) and the record of step n
        ke, ai, bi, ah, bh, ac, bc, ax, bx, pz = energy_pass(mass, v, vold, fint, fhg, dvc, pmask, dtn)
        Vf = Vo
        if has_sphere:
            Vf = Vo + dtp / (dtp + dt) * (Vs - Vo)      # velocity at t^n, for the record
            ke += 0.5 * M * Vo * Vs
            fs = 0.5 * M * dV                          # dtn/2 x contact force on the sphere
            ac += fs * Vo
            bc += fs * Vs
            fg = -0.5 * dtn * M * par[P_GRAV]
            ax += fg * Vo
            bx += fg * Vs
            pz += M * Vs
        if sc[S_STEPS] == 0.0:
            sc[S_KE0] = ke
        hist[rows, H_T] = t
        hist[rows, H_F] = force * sym
        hist[rows, H_IMP] = (sc[S_IMP] + 0.5 * dtp * force) * sym
        hist[rows, H_Z] = Zn
        hist[rows, H_V] = Vf
        hist[rows, H_R] = reaction * sym
        hist[rows, H_KE] = ke * sym
        hist[rows, H_IE] = sc[S_IE] * sym
        hist[rows, H_HG] = -(sc[S_WHG] + ah) * sym
        hist[rows, H_C] = -(sc[S_WC] + ac) * sym
        hist[rows, H_EXT] = (sc[S_WEXT] + ax) * sym
        hist[rows, H_WINT] = (sc[S_WINT] + ai) * sym
        hist[rows, H_DT] = dt
        hist[rows, H_PEN] = pen
        hist[rows, H_PZ] = pz * sym
        rows += 1
        sc[S_WINT] += ai + bi
        sc[S_WHG] += ah + bh
        sc[S_WC] += ac + bc
        sc[S_WEXT] += ax + bx
        sc[S_IMP] += force * dtn
        sc[S_Z] = Zs
        sc[S_V] = Vs
        sc[S_T] = t + dt
        sc[S_DTPREV] = dt
        sc[S_STEPS] += 1.0
        if dt < sc[S_DTMIN]:
            sc[S_DTMIN] = dt
        if dt > sc[S_DTMAX]:
            sc[S_DTMAX] = dt
        if pen > sc[S_MAXPEN]:
            sc[S_MAXPEN] = pen
        if not math.isfinite(ke + pz + Zs):
            return rows, R_STATE
        if t >= par[P_TEND]:
            return rows, R_DONE
        if has_sphere and ipar[I_STOPSEP] != 0:
            if force > 0.0:
                sc[S_SEEN] = 1.0
                sc[S_SEPT] = 0.0
            elif sc[S_SEEN] != 0.0 and Vf > 0.0:
                sc[S_SEPT] += dt
                if sc[S_SEPT] >= par[P_SEPTIME]:
                    return rows, R_SEPARATED
            else:
                sc[S_SEPT] = 0.0
        if sc[S_T] >= t_stop:
            return rows, R_CHUNK
    return rows, R_CHUNK
