"""``cfm calculix build``: CalculiX (ccx 2.20) from Debian's source package with the generated UMATs linked in.

Two stages, both cached below :func:`cfm_core.material.cache.cache_dir` ``("calculix", ...)``:

1. ``lib-2.20``: ``apt-get source calculix-ccx`` and its build dependencies (``apt-get build-dep``, as
   root; a ``deb-src`` entry for the configured Debian archive is added when none exists), then
   CalculiX's own objects compiled with Debian's flags (``debian/rules``) into ``ccx_2.20.a``.
   Done once per machine (minutes).
2. ``<key>``: the generated Abaqus UMAT of each material (``cfm export``'s code, its ``umat``
   renamed ``cfmu_<n>``), the project's adaptor (:file:`adaptor.f`: ccx's PK2 / dS/dE convention to
   the UMAT's Cauchy / Jaumann one, and the dispatch on the material name) and ccx's main program
   linked against the library into ``ccx`` (seconds). ``key`` digests the UMATs' code (comment
   lines excluded: the header names the commit), the adaptor and the CalculiX version;
   ``build.json`` beside it lists the materials with their definition hashes.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import time
from pathlib import Path

from cfm_core.errors import InputError
from cfm_core.fingerprint import digest
from cfm_core.material.cache import cache_dir, spec_fingerprint

VERSION = "2.20"
PACKAGE = "calculix-ccx"
DEFAULT_MATERIALS = ("cfm", "neo-hookean")
CFLAGS = ("-Wall -O2 -I/usr/include/spooles -DARCH=\"Linux\" -DSPOOLES -DARPACK -DMATRIXSTORAGE "
          "-DUSE_MT=1")
FFLAGS = "-O2 -fallow-argument-mismatch"
LIBS = ["-lspooles", "-lpthread", "-larpack", "-llapack", "-lblas", "-lm", "-lc", "-fopenmp"]
ADAPTOR = Path(__file__).with_name("adaptor.f")
#: ccx 2.20's umat_abaqus.f returns the UMAT's tangent only when ccx asks for it (icmd /= 3); the
#: C3D8R hourglass force of the stress-only call (resultsmech.f, hgforce) then reads an undefined
#: elas(1) and the elements distort. The link stage compiles a copy that always returns it.
UMAT_ABAQUS_PATCH = ("      if(icmd.ne.3) then", "      if(.true.) then")
#: Version of the dispatch written by :func:`linked_source`; raise it when that template changes.
LINK_VERSION = 2


def _template_routine(template: str, kind: str, name: str) -> str:
    """The text of one routine (``kind`` ``{P}<name>``) of an export template, unformatted."""
    m = re.search(rf"(?ms)^      {kind} \{{P\}}{name}\(.*?^      end {kind} \{{P\}}{name}\n", template)
    if m is None:
        raise InputError(f"CalculiX build: the export's templates have no {kind} {{P}}{name}; the adaptor needs it.")
    return m.group(0)


def adaptor_source() -> str:
    """:file:`adaptor.f` with its 3x3 helpers ``cfmad_det3`` and ``cfmad_inv3`` in place of the line
    ``CFM-HELPERS``: the export's own ``{P}det3`` (:data:`cfm_core.export.kernel.CORE`) and
    ``{P}inv3`` (:data:`cfm_core.export.abaqus.UMAT`) with the prefix ``cfmad_``, so that the
    adaptor and the UMATs invert F with the same code.

    Returns
    -------
    str
        The fixed-form Fortran source of ccx's ``umat`` entry (its dispatch still a marker).
    """
    from cfm_core.export import abaqus, fortran, kernel

    helpers = (_template_routine(kernel.CORE, "function", "det3") + "\n"
               + _template_routine(abaqus.UMAT, "subroutine", "inv3"))
    helpers = helpers.replace("{P}", "cfmad_").replace("{DP}", fortran.DP)
    return ADAPTOR.read_text().replace("!     CFM-HELPERS\n", helpers)


def link_digest() -> str:
    """Digest of what the project links around the UMATs (adaptor, umat_abaqus.f patch, dispatch).

    :func:`find` uses only builds with the current one, so that a changed adaptor is never run
    from an older build (``cfm calculix build`` relinks in seconds).

    Returns
    -------
    str
        20 hex digits.
    """
    return digest({"adaptor": adaptor_source(), "patch": UMAT_ABAQUS_PATCH, "link": LINK_VERSION})[:20]


def tag(name: str) -> str:
    """The CalculiX material name of a project material (after the ``ABAQUS`` prefix): upper case, ``_``.

    Parameters
    ----------
    name : str
        Registered material name, e.g. ``"neo-hookean"``.

    Returns
    -------
    str
        E.g. ``"NEO_HOOKEAN"`` (at most 60 characters).
    """
    return re.sub(r"[^0-9A-Z]", "_", name.upper())[:60]


def _run(cmd, cwd=None, log=None, env=None):
    out = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=env)
    if log is not None:
        log.write(f"$ {' '.join(cmd)}\n{out.stdout}{out.stderr}\n")
    if out.returncode != 0:
        tail = (out.stdout + out.stderr)[-1500:]
        raise InputError(f"CalculiX build: '{' '.join(cmd)}' failed (exit {out.returncode}):\n{tail}")
    return out


def _ensure_deb_src(log, say) -> None:
    """Add a deb-src entry mirroring the configured Debian 'deb' entries when apt knows no source."""
    if subprocess.run(["apt-cache", "showsrc", PACKAGE], capture_output=True, text=True).stdout.strip():
        return
    lines = []
    for path in sorted(Path("/etc/apt/sources.list.d").glob("*.sources")):
        for stanza in path.read_text().split("\n\n"):
            if re.search(r"^Types:.*\bdeb\b", stanza, re.M) and "debian" in stanza:
                lines.append(re.sub(r"^Types:.*$", "Types: deb-src", stanza.strip(), flags=re.M))
    legacy = Path("/etc/apt/sources.list")
    if legacy.exists():
        lines += [ln.replace("deb ", "deb-src ", 1) for ln in legacy.read_text().splitlines()
                  if ln.startswith("deb ") and "debian" in ln]
    if not lines:
        raise InputError("CalculiX build: apt knows no source package 'calculix-ccx' and no Debian 'deb' entry was "
                         "found to mirror; add a deb-src line for your Debian archive and run it again.")
    target = Path("/etc/apt/sources.list.d/cfm-debian-src.sources")
    body = "\n\n".join(ln for ln in lines if ln.startswith("Types:"))
    if body:
        target.write_text(body + "\n")
    else:
        target.with_suffix(".list").write_text("\n".join(lines) + "\n")
    say(f"added Debian source entries ({target.parent}); apt-get update")
    _run(["apt-get", "update", "-q"], log=log)


def _library(log, say) -> Path:
    """CalculiX's sources and ``ccx_2.20.a`` (built once); returns the ``src`` folder."""
    root = cache_dir("calculix", f"lib-{VERSION}")
    src = root / f"calculix-ccx-{VERSION}" / f"ccx_{VERSION}" / "src"
    if (src / f"ccx_{VERSION}.a").exists() and (src / f"ccx_{VERSION}.o").exists():
        return src
    if shutil.which("apt-get") is None:
        raise InputError("CalculiX build: needs apt (Debian or Ubuntu) to fetch the source package calculix-ccx.")
    if os.geteuid() == 0:
        say("apt-get update; apt-get build-dep calculix-ccx (gfortran, libspooles-dev, libarpack2-dev, liblapack-dev)")
        _run(["apt-get", "update", "-q"], log=log)
        _ensure_deb_src(log, say)
        _run(["apt-get", "build-dep", "-y", "-q", PACKAGE], log=log,
             env={**os.environ, "DEBIAN_FRONTEND": "noninteractive"})
    missing = [p for p in ("/usr/include/spooles/SPOOLES.h",) if not Path(p).exists()]
    if missing or shutil.which("gfortran") is None:
        raise InputError("CalculiX build: the build dependencies are missing (gfortran, libspooles-dev, "
                         "libarpack2-dev, liblapack-dev); run 'cfm calculix build' as root, or install them "
                         "with 'apt-get build-dep calculix-ccx'.")
    if not src.exists():
        say("apt-get source calculix-ccx")
        _run(["apt-get", "source", "-q", PACKAGE], cwd=root, log=log)
        found = sorted(root.glob(f"calculix-ccx-{VERSION}*"))
        if not found:
            raise InputError(f"CalculiX build: apt-get source did not give calculix-ccx {VERSION} in {root}.")
        if found[0].name != f"calculix-ccx-{VERSION}":
            found[0].rename(root / f"calculix-ccx-{VERSION}")
    jobs = str(max(1, os.cpu_count() or 1))
    say(f"compiling CalculiX {VERSION} ({jobs} jobs; several minutes)")
    _run(["make", f"-j{jobs}", f"ccx_{VERSION}.a", f"ccx_{VERSION}.o", f"CFLAGS={CFLAGS}", f"FFLAGS={FFLAGS}"],
         cwd=src, log=log)
    return src


def _umat_code(material) -> str:
    from cfm_core.export.generate import generate

    return generate(material, "abaqus-umat").files["umat.f"]


def _code_only(text: str) -> str:
    return "\n".join(ln for ln in text.splitlines() if ln[:1] not in ("c", "C", "!", "*") and ln.strip())


def linked_source(mats, sources=None) -> tuple[str, dict]:
    """The Fortran source linked into ccx: the adaptor with its dispatch, then the renamed UMATs.

    Parameters
    ----------
    mats : sequence of Material
        Bound materials (their UMATs are generated unless given in ``sources``).
    sources : dict, optional
        Material name -> generated UMAT source (``umat.f`` of ``cfm export``).

    Returns
    -------
    source : str
        One fixed-form source: ``umat`` (ccx's entry, :file:`adaptor.f`) and ``cfmu_<n>``.
    names : dict
        Material name -> {"tag": CalculiX name after ``ABAQUS``, "definition": definition hash}.
    """
    sources = sources or {m.spec.name: _umat_code(m) for m in mats}
    dispatch, names, parts = [], {}, []
    for n, m in enumerate(mats, 1):
        t = tag(m.spec.name)
        text = re.sub(r"(?im)^(\s+)subroutine umat\(", rf"\1subroutine cfmu_{n}(", sources[m.spec.name])
        text = re.sub(r"(?im)^(\s+)end subroutine umat\b", rf"\1end subroutine cfmu_{n}", text)
        parts.append(text)
        dispatch += [f"      if (cmname(1:{len(t) + 1}) .eq. '{t} ') then",
                     "        found = 1",
                     f"        call cfmu_{n}(sig, statev, dd, e1, e2, e3, e4, ddsddt,",
                     "     &    drplde, e5, stran, dstran, time, dtl, temp, dtemp, predef,",
                     "     &    dpred, cmname, ndi, nshr, ntens, nstatv, props, nprops,",
                     "     &    coords, drot, pnew, celent, dfgrd0, dfgrd1, noel, npt,",
                     "     &    layer, kspt, kstep(1), kinc)",
                     "      end if"]
        names[m.spec.name] = {"tag": t, "definition": spec_fingerprint(m.spec)}
    adaptor = adaptor_source().replace("!     CFM-DISPATCH\n", "\n".join(dispatch) + "\n")
    return "\n".join([adaptor, *parts]), names


def build(materials=DEFAULT_MATERIALS, say=print) -> dict:
    """Build ccx with the generated UMATs of ``materials`` linked in (cached); return its record.

    Parameters
    ----------
    materials : sequence of str
        Registered material names (their UMATs are generated from the materials' definitions).
    say : callable
        Called with one line of progress at a time.

    Returns
    -------
    dict
        ``ccx`` (path of the executable), ``key``, ``materials`` ({name: {"tag", "definition"}}),
        ``version``, ``seconds`` (this call's wall time, s), ``library_seconds`` (the library stage's,
        s, 0 when cached), ``cached`` (bool).

    Raises
    ------
    InputError
        A material is unknown, a tool or build dependency is missing, or a build step fails
        (the message carries the tail of its output; the full log is ``build.log`` in the cache).
    """
    from cfm_core.material.registry import make_material

    t0 = time.perf_counter()
    mats = [make_material(name) for name in dict.fromkeys(materials)]
    sources = {m.spec.name: _umat_code(m) for m in mats}
    adaptor = adaptor_source()
    key = digest({"version": VERSION, "adaptor": adaptor, "patch": UMAT_ABAQUS_PATCH, "link": LINK_VERSION,
                  "cflags": CFLAGS,
                  "fflags": FFLAGS,
                  "umats": {k: _code_only(v) for k, v in sources.items()}})[:20]
    out = cache_dir("calculix", key)
    record_path = out / "build.json"
    if record_path.exists() and (out / "ccx").exists():
        record = json.loads(record_path.read_text())
        _, names = linked_source(mats, sources)
        if any(record["materials"].get(k) != v for k, v in names.items()):
            # the same UMAT code (the key) from a newer definition digest: the build holds it too
            record["materials"] = {**record["materials"], **names}
            record_path.write_text(json.dumps(record, indent=2) + "\n")
        return {**record, "cached": True, "seconds": time.perf_counter() - t0}
    with open(cache_dir("calculix") / "build.log", "a") as log:
        t1 = time.perf_counter()
        src = _library(log, say)
        lib_seconds = time.perf_counter() - t1
        stage = out / "stage"
        shutil.rmtree(stage, ignore_errors=True)
        stage.mkdir()
        text, names = linked_source(mats, sources)
        (stage / "cfm_umats.f").write_text(text)
        original = (src / "umat_abaqus.f").read_text()
        if original.count(UMAT_ABAQUS_PATCH[0]) != 1:
            raise InputError(f"CalculiX build: {src / 'umat_abaqus.f'} is not the expected ccx {VERSION} source.")
        (stage / "umat_abaqus.f").write_text(original.replace(*UMAT_ABAQUS_PATCH))
        say(f"compiling the UMATs of {', '.join(names)} and linking ccx")
        objs = []
        for f in sorted(stage.glob("*.f")):
            _run(["gfortran", "-O2", "-ffixed-form", *FFLAGS.split(), "-c", f.name, "-o", f.stem + ".o"], cwd=stage,
                 log=log)
            objs.append(f.stem + ".o")
        _run(["gfortran", "-O2", "-o", "ccx", *objs, str(src / f"ccx_{VERSION}.o"), str(src / f"ccx_{VERSION}.a"),
              *LIBS], cwd=stage, log=log)
        shutil.move(str(stage / "ccx"), out / "ccx")
        shutil.rmtree(stage, ignore_errors=True)
    record = {"ccx": str(out / "ccx"), "key": key, "version": VERSION, "materials": names, "link": link_digest(),
              "library_seconds": lib_seconds, "link_seconds": time.perf_counter() - t1 - lib_seconds}
    record_path.write_text(json.dumps(record, indent=2) + "\n")
    return {**record, "cached": False, "seconds": time.perf_counter() - t0}


def find(material=None) -> dict | None:
    """The newest cached build with the current adaptor (:func:`link_digest`) and, when given,
    ``material``'s current definition; or None.

    Parameters
    ----------
    material : Material, optional
        A bound material; the build must carry its UMAT (same definition hash).

    Returns
    -------
    dict or None
        The build record (see :func:`build`), or None when no such build exists.
    """
    want = None if material is None else (material.spec.name, spec_fingerprint(material.spec))
    records = []
    for path in cache_dir("calculix").glob("*/build.json"):
        try:
            rec = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if not Path(rec.get("ccx", "")).exists() or rec.get("link") != link_digest():
            continue
        if want is not None and rec["materials"].get(want[0], {}).get("definition") != want[1]:
            continue
        records.append((path.stat().st_mtime, rec))
    return max(records, key=lambda r: r[0])[1] if records else None
