"""numba's on-disk cache keyed on the content of a whole folder of kernel modules.

``njit(cache=True)`` keys a function's machine code on its own file (and its bytecode), not on
the modules it imports: ``element.py`` inlines ``eig3`` from ``eigen.py``, so after an edit of
``eigen.py`` numba would load the old ``element`` machine code. The generated modules of the
backends do not have this problem (each is one file named by a hash of its full text, kernels
included); the kernel files imported on their own (tests, benchmarks) do.

:func:`key_on_folder` registers a folder: every cached function defined in one of its files is
then stored under ``$CFM_CACHE_DIR/numba-kernels/<folder>-<path hash>/<content digest>/``, with the
same digest as numba's freshness stamp, where the digest covers the text of every ``.py`` file of
the folder and the numba, llvmlite and numpy versions (numba's index adds the CPU and the
function's bytecode). An edit of any file of the folder therefore recompiles every function of
it; folders of older digests are pruned (the newest :data:`KEEP` kept). Installed through numba's
cache-locator list, before numba's own locators, for registered folders only.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

#: Digest folders kept per kernel folder (the newest).
KEEP = 3

_FOLDERS: dict[str, str] = {}  # registered folder (resolved) -> its content digest


def folder_digest(folder) -> str:
    """Digest of a kernel folder: every ``.py`` file's name and text, and the compiler versions.

    Parameters
    ----------
    folder : str or path-like
        The folder.

    Returns
    -------
    str
        24 hexadecimal characters.
    """
    from importlib.metadata import version

    h = hashlib.sha256()
    for path in sorted(Path(folder).glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    h.update(";".join(f"{d} {version(d)}" for d in ("numba", "llvmlite", "numpy")).encode())
    return h.hexdigest()[:24]


def cache_path(folder, digest: str) -> Path:
    """Where the machine code of a registered folder of a given digest is kept (not created).

    Parameters
    ----------
    folder : str or path-like
        The kernel folder.
    digest : str
        Its :func:`folder_digest`.

    Returns
    -------
    pathlib.Path
        ``$CFM_CACHE_DIR/numba-kernels/<folder name>-<hash of its path>/<digest>``.
    """
    from cfm_core.material.cache import cache_dir

    folder = Path(folder).resolve()
    tag = f"{folder.name}-{hashlib.sha1(str(folder).encode()).hexdigest()[:10]}"
    return cache_dir("numba-kernels", tag) / digest


def _prune(parent: Path, keep: Path) -> None:
    """Remove all but the KEEP newest digest folders of one kernel folder."""
    try:
        old = sorted((p for p in parent.iterdir() if p.is_dir() and p != keep),
                     key=lambda p: p.stat().st_mtime, reverse=True)
    except OSError:
        return
    for p in old[KEEP - 1:]:
        shutil.rmtree(p, ignore_errors=True)  # another process may be pruning it too


def _locator_class():
    from numba.core import caching

    class FolderContentLocator(caching._CacheLocator):
        """numba cache locator for functions defined in a registered folder (module docstring)."""

        def __init__(self, py_func, py_file, folder):
            self._lineno = py_func.__code__.co_firstlineno
            self._stamp = _FOLDERS[folder]
            self._path = str(cache_path(folder, self._stamp))

        def get_cache_path(self):
            return self._path

        def get_source_stamp(self):
            return self._stamp

        def get_disambiguator(self):
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func, py_file):
            folder = os.path.dirname(os.path.realpath(py_file))
            if folder not in _FOLDERS:
                return None
            self = cls(py_func, py_file, folder)
            try:
                self.ensure_cache_path()
            except OSError:  # not writable: numba's own locators decide
                return None
            return self

    return FolderContentLocator


def key_on_folder(file_in_folder) -> str:
    """Key numba's cache of every function defined in the folder of ``file_in_folder`` on the
    folder's content (call it at the top of a kernel module, before its ``@njit`` functions).

    Parameters
    ----------
    file_in_folder : str or path-like
        A file of the folder (a kernel module passes its ``__file__``).

    Returns
    -------
    str
        The folder's :func:`folder_digest`, computed once per process.
    """
    from cfm_backends.numba_target import configure

    configure()   # before numba's first compilation in the process
    folder = os.path.dirname(os.path.realpath(file_in_folder))
    if folder in _FOLDERS:
        return _FOLDERS[folder]
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # renamed in numba 0.6x
    if not any(getattr(c, "__name__", "") == "FolderContentLocator" for c in impl._locator_classes):
        impl._locator_classes.insert(0, _locator_class())
    digest = _FOLDERS[folder] = folder_digest(folder)
    path = cache_path(folder, digest)
    path.mkdir(parents=True, exist_ok=True)
    os.utime(path)  # the newest: kept by the pruning
    _prune(path.parent, path)
    return digest
