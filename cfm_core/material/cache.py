"""On-disk cache of generated material code (and the folder numba kernels are compiled into).

Location: ``$CFM_CACHE_DIR`` or ``~/.cache/cfm``. Set ``CFM_NO_CODEGEN_CACHE=1`` to bypass it.
A generated source is keyed by a fingerprint of everything it is derived from: for each term its
kind, name, parameter declarations, the full text of the file defining its energy function and
the values its closure captures, plus the text of :mod:`cfm_core.material.codegen`. A term defined where
no source file exists (an interactive session) is never cached.
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import re
import sys
import tempfile
from pathlib import Path

#: The code generator's file: its text enters every fingerprint. Read as a file, not imported
#: (importing it imports sympy, which a run whose generated code is cached does not need).
CODEGEN_FILE = Path(__file__).with_name("codegen.py")


def cache_dir(*parts: str) -> Path:
    """The cache folder (created), optionally a subfolder; the temporary folder if home is read-only.

    Parameters
    ----------
    *parts : str
        Subfolder names below the cache root (``$CFM_CACHE_DIR`` or ``~/.cache/cfm``), e.g.
        ``"codegen"``.

    Returns
    -------
    pathlib.Path
        The folder, created and probed writable; if the root is not writable,
        ``<tempdir>/cfm-cache/<parts>`` instead.
    """
    root = Path(os.environ.get("CFM_CACHE_DIR") or Path.home() / ".cache" / "cfm")
    path = root.joinpath(*parts)
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".probe-{os.getpid()}"
        probe.write_text("")
        probe.unlink()
    except OSError:
        path = Path(tempfile.gettempdir()).joinpath("cfm-cache", *parts)
        path.mkdir(parents=True, exist_ok=True)
    return path


def _file_text(func) -> str | None:
    try:
        path = inspect.getsourcefile(func)
    except TypeError:
        return None
    if not path or not os.path.isfile(path):
        return None
    return Path(path).read_text()


def spec_fingerprint(spec) -> str | None:
    """Hash identifying the generated code of a material spec, or None if it cannot be cached.

    Parameters
    ----------
    spec : MaterialSpec
        The spec; each term's kind, name, parameters, energy qualname and closure values, the full
        text of the file defining each energy and the text of :mod:`cfm_core.material.codegen`
        enter the hash.

    Returns
    -------
    str or None
        24 hexadecimal characters (SHA-256 prefix), or None when a term's energy has no source
        file (defined interactively), so its code must not be cached.
    """

    h = hashlib.sha256()
    h.update(CODEGEN_FILE.read_bytes())
    terms = spec.isochoric + ((spec.volumetric,) if spec.volumetric else ())
    for term in terms:
        text = _file_text(term.energy)
        if text is None:
            return None
        closure = [c.cell_contents for c in (term.energy.__closure__ or ())]
        h.update(repr((term.kind, term.name, term.parameters, term.energy.__qualname__, closure)).encode())
        h.update(text.encode())
    return h.hexdigest()[:24]


def codegen_cache(spec, dialect: str, generate) -> str:
    """Return the cached source for (spec, dialect) or generate, store and return it.

    Parameters
    ----------
    spec : MaterialSpec
        The spec the source is generated from (keyed by :func:`spec_fingerprint`).
    dialect : str
        ``"math"``, ``"numpy"`` or ``"torch"``; part of the file name.
    generate : callable
        ``generate() -> str``, called on a cache miss, when ``CFM_NO_CODEGEN_CACHE`` is set or
        when the spec cannot be cached.

    Returns
    -------
    str
        Python source of the generated module. A new entry is written to a temporary file and
        renamed into place (atomic), under ``cache_dir("codegen")/<fingerprint>-<dialect>.py``.
    """
    key = None if os.environ.get("CFM_NO_CODEGEN_CACHE") else spec_fingerprint(spec)
    if key is None:
        return generate()
    path = cache_dir("codegen") / f"{key}-{dialect}.py"
    if path.is_file():
        return path.read_text()
    text = generate()
    tmp = path.with_suffix(f".tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)
    return text


_GENERATED: dict[str, object] = {}


def generated_name(text: str, prefix: str, label: str) -> str:
    """Module name of generated source ``text``: ``{prefix}_{label}_{hash}`` (see :func:`import_generated`).

    Parameters
    ----------
    text : str
        The module's source.
    prefix : str
        Start of the name, one per backend.
    label : str
        Readable part (a material name; other characters than letters, digits and _ become _).

    Returns
    -------
    str
        A valid module name, the same for the same text in every process.
    """
    digest = hashlib.sha256(text.encode()).hexdigest()[:20]
    return f"{prefix}_{re.sub(r'[^0-9A-Za-z_]', '_', str(label))[:40]}_{digest}"


def import_generated(text: str, prefix: str, subdir: str = "numba", label: str = "material"):
    """Import a generated Python module from its source text, through a file in the cache folder.

    The file is named after ``prefix``, ``label`` and a hash of ``text``, so that compilers that
    cache by file (numba's ``cache=True``) find their cache again in the next process; the module
    is imported once per process.

    Parameters
    ----------
    text : str
        The module's source.
    prefix : str
        Start of the module name (e.g. ``"cfm_numba"``), one per backend.
    subdir : str
        Folder below the cache directory (:func:`cache_dir`).
    label : str
        Readable part of the name (a material name; other characters become ``_``).

    Returns
    -------
    module
        The imported module (also in ``sys.modules``).
    """
    modname = generated_name(text, prefix, label)
    mod = _GENERATED.get(modname)
    if mod is not None:
        return mod
    path = cache_dir(subdir) / f"{modname}.py"
    if not path.exists() or path.read_text() != text:
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, path)
    spec = importlib.util.spec_from_file_location(modname, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[modname] = mod
    spec.loader.exec_module(mod)
    _GENERATED[modname] = mod
    return mod
