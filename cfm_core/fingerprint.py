"""Content fingerprints: what a result depends on, as hashes, for provenance and cache keys.

A cache key or a provenance record must change whenever anything that changes the result
changes: the contents of input files (not their names), the material definition, the code. This
module is the one place these fingerprints are computed; it sits at the bottom of the core (it
imports nothing of the project), so every layer and every cache can use it.

- :func:`file_digest` hashes a file's bytes (a mesh, a measured curve, a lab test);
- :func:`digest` hashes any JSON-able value (options, parameter dicts, scenes) canonically;
- :func:`code_state` says which code ran: the package version, the git commit and whether the
  checkout had uncommitted changes, and a digest of every source file of the project's packages,
  so that a cache keyed on it is invalidated by any edit, committed or not.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import subprocess
from pathlib import Path

#: Folders of the project's import packages (cfm_core, cfm_backends, cfm_plugins, cfm_verification).
PACKAGE_DIRS = ("cfm_core", "backends", "plugins", "verification")

#: The distribution name (``pip install -e .`` installs it under this name).
DISTRIBUTION = "cfm-materials"


def _root() -> Path:
    """The folder holding the package folders (the repository root for a checkout)."""
    return Path(__file__).resolve().parent.parent


def digest_bytes(data: bytes, length: int = 64) -> str:
    """SHA-256 of ``data`` in hexadecimal, cut to ``length`` characters.

    Parameters
    ----------
    data : bytes
        What to hash.
    length : int
        Characters kept (1..64).

    Returns
    -------
    str
        Lower-case hexadecimal digest.
    """
    return hashlib.sha256(data).hexdigest()[:length]


def _canonical(value):
    """A JSON-able value with sorted keys, floats written by ``repr`` (round-trip exact)."""
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, float):
        return repr(value) if not math.isfinite(value) else float(value)
    if isinstance(value, Path):
        return str(value)
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return _canonical(value.tolist())
    return value


def digest(value, length: int = 16) -> str:
    """Hash of a JSON-able value (dicts, lists, numbers, strings, None; numpy values as lists),
    independent of dict order.

    Parameters
    ----------
    value : object
        The value; floats are hashed exactly (their shortest round-trip text).
    length : int
        Hexadecimal characters kept (1..64).

    Returns
    -------
    str
        Lower-case hexadecimal SHA-256 prefix.

    Raises
    ------
    TypeError
        A value JSON cannot represent (after numpy conversion).
    """
    text = json.dumps(_canonical(value), sort_keys=True, separators=(",", ":"))
    return digest_bytes(text.encode(), length)


def file_digest(path, length: int = 64) -> str:
    """SHA-256 of a file's contents (not its name or time stamps).

    Parameters
    ----------
    path : str or path-like
        The file.
    length : int
        Hexadecimal characters kept (1..64).

    Returns
    -------
    str
        Lower-case hexadecimal digest of the bytes.

    Raises
    ------
    OSError
        The file cannot be read.
    """
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:length]


def _git(*args: str) -> str | None:
    """Output of a git command in the package root, or None (no git, not a checkout, error)."""
    try:
        done = subprocess.run(["git", "-C", str(_root()), *args], capture_output=True, text=True, timeout=10,
                              env={**os.environ, "GIT_OPTIONAL_LOCKS": "0"})
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout if done.returncode == 0 else None


def package_version() -> str:
    """The installed version of the cfm-materials distribution (``cfm --version``).

    Returns
    -------
    str
        From the package metadata; ``"unknown"`` when it is not installed (run from a bare copy).
    """
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:
        return "unknown"


@functools.lru_cache(maxsize=1)
def source_digest() -> str:
    """Digest of every Python source file and packaged data file of the project's packages.

    Any edit to the code (committed or not) changes it; byte-compiled files and caches do not
    enter. Computed once per process (~20 ms).

    Returns
    -------
    str
        24 hexadecimal characters.
    """
    root = _root()
    h = hashlib.sha256()
    for folder in PACKAGE_DIRS:
        base = root / folder
        if not base.is_dir():
            continue
        files = sorted(p for p in base.rglob("*") if p.is_file() and p.suffix in (".py", ".toml", ".json")
                       and "__pycache__" not in p.parts)
        for p in files:
            h.update(str(p.relative_to(root)).encode() + b"\0")
            h.update(p.read_bytes() + b"\0")
    return h.hexdigest()[:24]


@functools.lru_cache(maxsize=1)
def code_state() -> dict:
    """Which code is running: version, git commit and state, and the source digest.

    Returns
    -------
    dict
        ``version`` (str, the distribution's), ``commit`` (str, full hash, or None outside a git
        checkout), ``dirty`` (bool, uncommitted changes to tracked files of the checkout, or None
        outside a checkout), ``source_digest`` (str, :func:`source_digest`: changes with any edit).
    """
    commit = _git("rev-parse", "HEAD")
    status = _git("status", "--porcelain", "--untracked-files=no") if commit else None
    return {
        "version": package_version(),
        "commit": commit.strip() if commit else None,
        "dirty": bool(status.strip()) if status is not None else None,
        "source_digest": source_digest(),
    }


def code_label(state: dict | None = None) -> str:
    """One line naming the code: ``cfm-materials 0.2.0, commit 1a2b3c4d (with uncommitted changes)``.

    Parameters
    ----------
    state : dict, optional
        A :func:`code_state` record (default: the running code's).

    Returns
    -------
    str
        Version, short commit (or "not a git checkout") and "(with uncommitted changes)" if dirty.
    """
    s = state or code_state()
    where = f"commit {s['commit'][:10]}" if s.get("commit") else "not a git checkout"
    dirty = " (with uncommitted changes)" if s.get("dirty") else ""
    return f"{DISTRIBUTION} {s.get('version')}, {where}{dirty}"
