"""On-disk cache of generated material code (and the folder numba kernels are compiled into).

Location: ``$CFM_CACHE_DIR`` or ``~/.cache/cfm``. Set ``CFM_NO_CODEGEN_CACHE=1`` to bypass it.
A generated source is keyed by a fingerprint of everything it is derived from (:func:`spec_fingerprint`):

- the generator: the text of every module of :mod:`cfm_core.material` (the code generator and the
  symbolic layer it traces with), the sympy version (its simplification and printing shape the
  code) and the project's version;
- for each term its kind, name, parameter declarations and the values its closure captures, the
  full text of the file defining its energy function and of every file that function reaches
  through its globals and closure (a helper of another module, such as the CFM lipid term calling
  the Neo-Hookean energy), followed within the term's own top-level package, ``cfm_plugins`` and
  ``cfm_core``.

A term defined where no source file exists (an interactive session) is never cached.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import inspect
import os
import re
import sys
import tempfile
import types
from pathlib import Path

from .. import fingerprint

#: The code generator's file. Its text, and that of every module beside it, enters every
#: fingerprint; read as files, not imported (importing it imports sympy, which a run whose
#: generated code is cached does not need).
CODEGEN_FILE = Path(__file__).with_name("codegen.py")

#: Top-level packages whose functions a term's energy may call and whose text is then followed.
FOLLOWED_PACKAGES = ("cfm_core", "cfm_plugins")


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


def _source_file(obj) -> str | None:
    try:
        path = inspect.getsourcefile(obj)
    except TypeError:
        return None
    return path if path and os.path.isfile(path) else None


@functools.lru_cache(maxsize=1)
def generator_digest() -> str:
    """Digest of what the code generator depends on: the text of every module of
    :mod:`cfm_core.material`, the sympy version and the project's version (once per process).

    Returns
    -------
    str
        24 hexadecimal characters.
    """
    from importlib.metadata import PackageNotFoundError, version

    h = hashlib.sha256()
    for path in sorted(CODEGEN_FILE.parent.glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    try:
        sympy = version("sympy")
    except PackageNotFoundError:  # pragma: no cover - sympy is a dependency
        sympy = "none"
    h.update(f"sympy {sympy}; {fingerprint.DISTRIBUTION} {fingerprint.package_version()}".encode())
    return h.hexdigest()[:24]


def _top(obj) -> str:
    return (getattr(obj, "__module__", None) or getattr(obj, "__name__", "") or "").split(".")[0]


@functools.lru_cache(maxsize=1)
def _installed_roots() -> tuple:
    """Folders of the Python installation: the standard library and every site-packages."""
    import site
    import sysconfig

    roots = {sysconfig.get_paths()[k] for k in ("stdlib", "platstdlib", "purelib", "platlib")}
    roots |= set(getattr(site, "getsitepackages", lambda: [])())
    roots.add(getattr(site, "getusersitepackages", lambda: "")() or "")
    return tuple(os.path.realpath(r) + os.sep for r in roots if r)


def _user_module_file(obj) -> str | None:
    """The source file of ``obj`` (a function or module) when it is the user's own code: a file outside
    the standard library and site-packages (a helper module beside a plugin, imported from its folder)."""
    path = getattr(obj, "__file__", None) if isinstance(obj, types.ModuleType) else _source_file(obj)
    if not path or not os.path.isfile(path):
        return None
    real = os.path.realpath(path)
    return None if real.startswith(_installed_roots()) else path


def _code_names(code) -> set:
    """Global and attribute names used by a code object and the functions nested in it."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _code_names(const)
    return names


def dependency_files(func, packages=FOLLOWED_PACKAGES) -> list[str] | None:
    """Source files a term's energy function depends on: its own and, recursively, those of the
    functions, terms and modules it reaches through its globals and closure, within its own
    top-level package and ``packages``, and in any module that is the user's own code (outside the
    standard library and site-packages: a helper module beside a plugin file, whose edits must
    regenerate the code as the plugin's own do).

    Parameters
    ----------
    func : function
        An energy function (``Term.energy``).
    packages : tuple of str
        Top-level packages followed besides ``func``'s own.

    Returns
    -------
    list of str or None
        Absolute paths, sorted; None when ``func`` itself has no source file (defined
        interactively).
    """
    reached = _reach(func, packages)
    return None if reached is None else reached[0]


def global_values(func, packages=FOLLOWED_PACKAGES) -> list[str] | None:
    """The plain values (numbers, strings, containers and arrays of them; other objects by type)
    that the functions :func:`dependency_files` follows read from their globals, as stable text
    ``module.function:name=digest``. A value imported by name from another file (``from consts
    import SCALE``) is not in the file that uses it: its edit changes the energy, so it must change
    the fingerprint too (it left the code caches returning the old code's results).

    Parameters
    ----------
    func : function
        An energy function (``Term.energy``).
    packages : tuple of str
        Top-level packages followed besides ``func``'s own.

    Returns
    -------
    list of str or None
        Sorted; None when ``func`` has no source file.
    """
    reached = _reach(func, packages)
    return None if reached is None else reached[1]


def _value_text(value) -> str:
    """A global's value as stable text: by content where it is data, else by type (and the file
    defining the type, when it is the user's own: its edits count through the file)."""
    try:
        return fingerprint.digest(value)
    except (TypeError, ValueError):
        kind = type(value)
        path = _user_module_file(kind)
        return f"<{kind.__module__}.{kind.__qualname__}{' ' + fingerprint.file_digest(path, 16) if path else ''}>"


def _reach(func, packages):
    """(files, values) of :func:`dependency_files` and :func:`global_values`, one walk."""
    if _source_file(func) is None:
        return None
    follow = {_top(func), *packages}
    files, values, seen, todo = set(), set(), set(), [func]
    while todo:
        obj = todo.pop()
        if id(obj) in seen:
            continue
        seen.add(id(obj))
        if isinstance(getattr(obj, "energy", None), types.FunctionType):  # a Term
            todo.append(obj.energy)
            continue
        if isinstance(obj, types.ModuleType):
            path = getattr(obj, "__file__", None)
            if (_top(obj) in follow or _user_module_file(obj)) and path and os.path.isfile(path):
                files.add(path)
            continue
        if not isinstance(obj, types.FunctionType) or not (_top(obj) in follow or _user_module_file(obj)):
            continue
        path = _source_file(obj)
        if path:
            files.add(path)
        names = _code_names(obj.__code__)
        for n in sorted(names):
            if n not in obj.__globals__:
                continue
            value = obj.__globals__[n]
            todo.append(value)
            if isinstance(value, types.ModuleType) and (_top(value) in follow or _user_module_file(value)):
                todo += [getattr(value, m) for m in names if isinstance(getattr(value, m, None), types.FunctionType)]
            elif not (isinstance(value, (types.FunctionType, types.ModuleType, types.BuiltinFunctionType, type))
                      or hasattr(value, "energy") or callable(value)):
                values.add(f"{obj.__module__}.{obj.__qualname__}:{n}={_value_text(value)}")
        todo += [c.cell_contents for c in (obj.__closure__ or ()) if _cell_set(c)]
    return sorted(files), sorted(values)


def _cell_set(cell) -> bool:
    try:
        cell.cell_contents
    except ValueError:  # an empty cell
        return False
    return True


def _closure_value(value):
    """A closure value as stable text: numbers and arrays by content, functions by name."""
    if isinstance(value, (types.FunctionType, types.ModuleType)) or hasattr(value, "energy"):
        return f"<{type(value).__name__} {getattr(value, '__module__', '')}.{getattr(value, '__qualname__', getattr(value, 'name', ''))}>"
    try:
        return fingerprint.digest(value)
    except TypeError:
        return repr(value)


def spec_fingerprint(spec) -> str | None:
    """Hash identifying the generated code of a material spec, or None if it cannot be cached.

    Parameters
    ----------
    spec : MaterialSpec
        The spec; :func:`generator_digest`, and for each term its kind, name, parameters, energy
        qualname, closure values, the plain values its functions read from their globals
        (:func:`global_values`) and the text of every file its energy depends on
        (:func:`dependency_files`) enter the hash.

    Returns
    -------
    str or None
        24 hexadecimal characters (SHA-256 prefix), or None when a term's energy has no source
        file (defined interactively), so its code must not be cached.
    """

    h = hashlib.sha256()
    h.update(generator_digest().encode())
    terms = spec.isochoric + ((spec.volumetric,) if spec.volumetric else ())
    for term in terms:
        reached = _reach(term.energy, FOLLOWED_PACKAGES)
        if reached is None:
            return None
        files, values = reached
        closure = [_closure_value(c.cell_contents) for c in (term.energy.__closure__ or ()) if _cell_set(c)]
        h.update(repr((term.kind, term.name, term.parameters, term.energy.__qualname__, closure, values)).encode())
        for text in sorted(fingerprint.digest_bytes(Path(f).read_bytes()) for f in files):
            h.update(text.encode())
    return h.hexdigest()[:24]


def definition_digest(spec) -> str | None:
    """Hash identifying everything a material spec defines: its code (:func:`spec_fingerprint`) and
    what is not in the code, the Prony series' default g_i and tau_i and the default moduli
    convention; or None where the code cannot be fingerprinted (a term defined interactively).

    The generated code does not depend on the Prony series (its values are run-time parameters), so
    :func:`spec_fingerprint` alone keys the code caches; results (provenance, the sweep's run cache)
    are keyed by this digest: two plugins with the same terms and other Prony defaults gave the same
    run id and the second reused the first one's results (67.3 g for 170.0 g).

    Parameters
    ----------
    spec : MaterialSpec
        The material definition.

    Returns
    -------
    str or None
        24 hexadecimal characters.
    """
    code = spec_fingerprint(spec)
    if code is None:
        return None
    prony = tuple(spec.prony.defaults) if spec.prony is not None else ()
    return fingerprint.digest({"code": code, "prony": repr(prony), "moduli": spec.default_moduli}, 24)


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
    return cached_text(lambda: spec_fingerprint(spec), dialect, generate)


def cached_text(key, kind: str, generate) -> str:
    """Return the generated source stored under ``key()`` or generate, store and return it.

    Parameters
    ----------
    key : callable
        ``key() -> str or None``: digest of everything the text is derived from (the caller's to
        make complete: a key that misses an input returns stale text); None: never cached. Not
        called when ``CFM_NO_CODEGEN_CACHE`` is set (a digest reads files).
    kind : str
        What the text is (``"math"``, ``"numba-module"``, ...); part of the file name.
    generate : callable
        ``generate() -> str``, called on a cache miss, when ``CFM_NO_CODEGEN_CACHE`` is set or
        when the key is None.

    Returns
    -------
    str
        The text. A new entry is written to a temporary file and renamed into place (atomic),
        under ``cache_dir("codegen")/<key>-<kind>.py``.
    """
    digest = None if os.environ.get("CFM_NO_CODEGEN_CACHE") else key()
    if digest is None:
        return generate()
    path = cache_dir("codegen") / f"{digest}-{kind}.py"
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
