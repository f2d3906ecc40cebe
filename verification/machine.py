"""Where a verification report was made: git commit and machine (platform, CPUs, library versions)."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path


def git_commit(cwd=None) -> str:
    """``git rev-parse HEAD`` of the project (or of ``cwd``), "unknown" when git cannot tell."""
    cwd = Path(cwd) if cwd else Path(__file__).resolve().parent.parent
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    text = out.stdout.strip()
    if out.returncode != 0 or not text:
        return "unknown"
    try:
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=cwd,
                               capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        dirty = ""
    return text + (" (with uncommitted changes)" if dirty else "")


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def machine_info() -> dict:
    """Platform, CPU count, Python and the versions of the numerical libraries (plain strings)."""
    return {
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "python": sys.version.split()[0],
        **{name: _version(dist) for name, dist in (("numpy", "numpy"), ("scipy", "scipy"), ("numba", "numba"),
                                                   ("torch", "torch"), ("scikit-fem", "scikit-fem"),
                                                   ("matplotlib", "matplotlib"), ("cfm-materials", "cfm-materials"))},
    }
