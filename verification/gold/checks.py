"""Independent checks of gold references, run when a reference is written (``--update``).

Each check takes the raw output of :func:`.record.run_case` and returns one line saying what the
value was checked against and how closely; it raises :class:`CheckFailed` when the value is not
confirmed, and the reference is then not written. Checks:

- truth-point: the stress history against :func:`cfm_verification.truths.stress_history`
  (hand-written Eq. 2-7, summed Prony integral; itself checked against mpmath), 1e-9 relative;
- energy-fd: the elastic Cauchy stress against central differences of the energy
  (sigma = J^-1 dW/dF F^T, step 1e-6), 1e-6 relative: checks stress against energy;
- prony-energy-fd: (viscoelastic materials without a hand-written truth, e.g. cfm-septa) the
  stress history against the hereditary integral (:func:`cfm_verification.truths.prony_convolution`)
  of the instantaneous isochoric stress, with the volumetric stress added; both from central
  differences of the elastic energy (S = F^-1 dW/dF; U(J) = W(J^1/3 I), S_vol = J U'(J) C^-1; the
  isochoric part scaled to its instantaneous value by the named Prony values), 1e-6 relative;
- truth-uniaxial: the single element's reaction force against the quasi-static uniaxial-stress
  truth (:func:`cfm_verification.truths.uniaxial_force`), the agreement tolerances of the suite;
- uniaxial-reference: (non-CFM materials, no hand-written truth) against the quasi-static
  uniaxial solution of :func:`cfm_core.simulation.point.uniaxial`, 1e-2 relative (L2);
- truth-relaxation: the relaxation test against the hereditary-integral truth (free: uniaxial
  stress; confined: F = diag(1, 1, l)), 2e-3 relative L2;
- energy-momentum: energy-balance error within the 1 % rule, and the contact impulse equal to the
  impactor's momentum change m (v0 - v_end) to 1e-6 relative;
- cross-backend: the run against numba on the same scene (explicit-explicit tolerance, 1e-6);
- paper-table: energy-momentum, and the 8 mm row of docs/paper/results.json (the README's table:
  peak, time of peak, duration) to 1e-3.
"""

from __future__ import annotations

import json

import numpy as np

from .. import truths
from ..agreement import ENERGY_LIMIT, TOLERANCES
from ..compare import compare_union


class CheckFailed(AssertionError):
    """A gold value not confirmed by its independent check."""


def _require(ok: bool, text: str) -> str:
    if not ok:
        raise CheckFailed(text)
    return text


def truth_point(case, raw) -> str:
    truth = truths.stress_history(raw["material"], raw["t"], raw["F"])
    d = float(np.linalg.norm(raw["stress"] - truth) / np.linalg.norm(truth))
    return _require(d <= 1e-9, f"cfm_verification.truths.stress_history (hand-written Eq. 2-7 + summed Prony "
                               f"integral): rel L2 {d:.2e} <= 1e-9")


def energy_fd(case, raw) -> str:
    from cfm_core.material import reference as ref

    mat, F, s = raw["material"], raw["F"], raw["stress"]
    idx = np.linspace(1, F.shape[0] - 1, 6).astype(int)
    worst, h = 0.0, 1e-6
    for k in idx:
        P = np.zeros((3, 3))
        for i in range(3):
            for j in range(3):
                Fp, Fm = F[k].copy(), F[k].copy()
                Fp[i, j] += h
                Fm[i, j] -= h
                P[i, j] = (ref.energy(mat, Fp[None])[0] - ref.energy(mat, Fm[None])[0]) / (2 * h)
        sig = P @ F[k].T / np.linalg.det(F[k])
        v = np.array([sig[0, 0], sig[1, 1], sig[2, 2], sig[0, 1], sig[1, 2], sig[0, 2]])
        worst = max(worst, float(np.abs(v - s[k]).max() / np.abs(s).max()))
    return _require(worst <= 1e-6, f"Cauchy stress = J^-1 dW/dF F^T by central differences of the energy at "
                                   f"{idx.size} points: max difference {worst:.2e} of the largest stress (limit 1e-6)")


def _pk2_by_differences(material, F, h=1e-6):
    """(S_iso, S_vol), each (n, 3, 3) in Pa, of an elastic material at F (n, 3, 3) from central
    differences of its energy: S = F^-1 dW/dF, U(J) = W(J^1/3 I) - W(I), S_vol = J U'(J) C^-1."""
    from cfm_core.material import reference as ref

    F = np.asarray(F, dtype=float)
    P = np.zeros_like(F)
    for i in range(3):
        for j in range(3):
            Fp, Fm = F.copy(), F.copy()
            Fp[:, i, j] += h
            Fm[:, i, j] -= h
            P[:, i, j] = (ref.energy(material, Fp) - ref.energy(material, Fm)) / (2 * h)
    S = np.linalg.solve(F, P)
    J = np.linalg.det(F)
    eye = np.eye(3)
    dU = (ref.energy(material, ((J + h) ** (1 / 3))[:, None, None] * eye)
          - ref.energy(material, ((J - h) ** (1 / 3))[:, None, None] * eye)) / (2 * h)
    S_vol = (J * dU)[:, None, None] * np.linalg.inv(np.einsum("nki,nkj->nij", F, F))
    return S - S_vol, S_vol


def prony_energy_fd(case, raw) -> str:
    from cfm_core.material.registry import make_material

    mat, t, F, s = raw["material"], raw["t"], raw["F"], raw["stress"]
    gammas, taus = truths.prony_values(mat)
    _require(bool(gammas), f"{mat.name} has no Prony series: this check is for viscoelastic materials")
    elastic = make_material(case.overrides["material"], dict(mat.values), moduli=mat.moduli, elastic=True)
    S_iso, S_vol = _pk2_by_differences(elastic, F)
    S = truths.prony_convolution(t, truths.iso_scale(mat) * S_iso, gammas, taus) + S_vol
    sig = np.einsum("nik,nkl,njl->nij", F, S, F) / np.linalg.det(F)[:, None, None]
    v = np.stack([sig[:, 0, 0], sig[:, 1, 1], sig[:, 2, 2], sig[:, 0, 1], sig[:, 1, 2], sig[:, 0, 2]], axis=1)
    d = float(np.linalg.norm(s - v) / np.linalg.norm(v))
    return _require(d <= 1e-6, f"hereditary integral (cfm_verification.truths.prony_convolution, {len(gammas)} Prony "
                               f"terms) of the stress by central differences of the elastic energy: rel L2 {d:.2e} "
                               f"<= 1e-6")


def _reaction_vs(t, force, raw, limit, what) -> str:
    run = raw["run"]
    m = compare_union(run["t"], run["y"], t, force, fill=None)
    return _require(m["rel_l2"] <= limit and abs(m["peak_diff"]) <= limit,
                    f"{what}: rel L2 {m['rel_l2']:.2e}, peak {m['peak_diff']:+.2e} (limit {limit:g})")


def truth_uniaxial(case, raw) -> str:
    from ..agreement import quasistatic_truth

    t, force = quasistatic_truth(raw["scene"])
    kind = "quasistatic-implicit" if case.backend == "skfem" else "quasistatic-explicit"
    return _reaction_vs(t, force, raw, TOLERANCES[kind][0], "quasi-static uniaxial truth "
                        "(cfm_verification.truths.uniaxial_force)")


def uniaxial_reference(case, raw) -> str:
    from cfm_core.scene.builder import build_model
    from cfm_core.simulation.point import uniaxial

    meta = build_model(raw["scene"]).meta
    model = build_model(raw["scene"])
    t, _, P, _ = uniaxial(model.material, meta["rate"], meta["stretch"], steps=400, hold=meta["hold"])
    return _reaction_vs(t, P * meta["size"] ** 2, raw, 1e-2, "quasi-static uniaxial solution "
                        "(cfm_core.simulation.point.uniaxial)")


def truth_relaxation(case, raw) -> str:
    from cfm_core.scene.builder import build_model

    model = build_model(raw["scene"])
    meta, mat = model.meta, model.material
    rate = abs(1.0 - meta["stretch"]) / meta["load_time"]
    tr = np.asarray(raw["run"]["t"], float)
    if meta["lateral"] == "free":
        t, force = truths.uniaxial_force(mat, rate, meta["stretch"], meta["size"], steps=200, times=tr)
    else:
        tl = meta["load_time"]
        t = np.unique(np.concatenate([np.linspace(0, tl, 201), tr]))
        lam = 1.0 + (meta["stretch"] - 1.0) * np.minimum(t / tl, 1.0)
        F = np.zeros((t.size, 3, 3))
        F[:, 0, 0] = F[:, 1, 1] = 1.0
        F[:, 2, 2] = lam
        force = truths.stress_history(mat, t, F)[:, 2] * meta["size"] ** 2  # sigma33 x current area (= initial)
    y = np.asarray(raw["run"]["y"], float)
    ref = np.interp(tr, t, force)  # exact: every output time is a row of the truth
    d = float(np.linalg.norm(y - ref) / np.linalg.norm(ref))
    return _require(d <= 2e-3, f"hereditary-integral truth ({meta['lateral']} lateral faces) at the run's output "
                               f"times: rel L2 {d:.2e} (limit 2e-3)")


def energy_momentum(case, raw) -> str:
    run = raw["run"]
    res = run["result"]
    err = run["energy_error"]
    imp = float(np.asarray(res.impulse)[-1])
    mass = raw["scene"].impactor.mass
    v0 = float(np.asarray(res.impactor_v)[0])
    dmom = mass * abs(float(np.asarray(res.impactor_v)[-1]) - v0)
    rel = abs(abs(imp) - dmom) / dmom
    return _require(err <= ENERGY_LIMIT and rel <= 1e-6,
                    f"energy-balance error {err:.2e} <= {ENERGY_LIMIT:g}; contact impulse {imp:.6g} N s = impactor "
                    f"momentum change {dmom:.6g} N s to {rel:.1e} (limit 1e-6)")


def cross_backend(case, raw) -> str:
    from ..runs import run_scene

    other = run_scene(raw["scene"], "numba")
    run = raw["run"]
    m = compare_union(run["t"], run["y"], other["t"], other["y"])
    lim = TOLERANCES["explicit-explicit"][0]
    return _require(m["rel_l2"] <= lim, f"numba on the same scene: rel L2 {m['rel_l2']:.2e} <= {lim:g} "
                                        f"(shares mesh geometry and generated material code; separate element, "
                                        f"contact and time integration)")


def paper_table(case, raw) -> str:
    from ..paper_compare import RESULTS_JSON

    data = json.loads(RESULTS_JSON.read_text())
    h = raw["scene"].specimen.thickness
    row = next(r for r in data["rows"] if r["moduli"] == "long-term" and abs(r["thickness"] - h) < 1e-9)
    s = raw["run"]["summary"]
    d = {k: (s[k] - row[k]) / abs(row[k]) for k in ("peak_g", "t_peak", "duration")}
    balance = energy_momentum(case, raw)
    return _require(all(abs(v) <= 1e-3 for v in d.values()),
                    f"{balance}; docs/paper/results.json (commit {str(data.get('commit'))[:12]}), the README's table: "
                    + ", ".join(f"{k} {v:+.1e}" for k, v in d.items()) + " (limit 1e-3); the paper's experiment: "
                    f"{s['peak_g']:.1f} g against 52.5 g")


CHECKS = {"truth-point": truth_point, "energy-fd": energy_fd, "prony-energy-fd": prony_energy_fd, "truth-uniaxial": truth_uniaxial,
          "uniaxial-reference": uniaxial_reference, "truth-relaxation": truth_relaxation,
          "energy-momentum": energy_momentum, "cross-backend": cross_backend, "paper-table": paper_table}
