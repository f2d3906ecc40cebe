"""A warm ``cfm drop-test`` imports only what it uses (issue 15, item 3: under 2 s end to end).

sympy is needed only to generate a material's code when it is not cached, scipy.optimize only by
fits and calibrations, pandas only by sweeps and ``to_dataframe``, dask never on this path; each
costs 0.2-0.4 s to import. The numba kernel files are read as text, never imported as modules
(that defines a dispatcher per kernel, ~0.1-0.4 s). The command runs in a fresh interpreter (as the ``cfm`` console
script does) and reports the modules it imported. The same run with the generated-code cache
switched off must import sympy, so the check sees an import when there is one.
"""

import json
import os
import subprocess
import sys

import pytest

from cfm_core.material.registry import make_material

pytest.importorskip("numba")

#: Deferred heavy imports that must not happen on the warm drop-test path.
HEAVY = ("sympy", "scipy.optimize", "pandas", "dask", "distributed",
         "cfm_backends.numba_explicit.kernels.element")   # the standalone kernels: every dispatcher defined

PROBE = r"""
import json, sys
from cfm_core.cli.__main__ import console
heavy = sys.argv[1].split(",")
sys.argv = ["cfm", *sys.argv[2:]]
code = console()
print(json.dumps({"code": code, "imported": [m for m in heavy if m in sys.modules]}))
"""


def _drop_test_imports(out, **env) -> list[str]:
    """The modules of HEAVY that ``cfm drop-test`` (a small specimen) imported in a fresh process."""
    args = ["drop-test", "--quiet", "--thickness", "0.004", "--element-size", "0.002", "--width", "0.01",
            "--out", str(out)]
    proc = subprocess.run([sys.executable, "-c", PROBE, ",".join(HEAVY), *args], capture_output=True, text=True,
                          env={**os.environ, **env}, timeout=600)
    assert proc.returncode == 0, proc.stderr
    record = json.loads(proc.stdout.strip().splitlines()[-1])
    assert record["code"] == 0 and (out / "acceleration.csv").is_file() and (out / "acceleration.png").is_file()
    return record["imported"]


def test_warm_drop_test_imports_no_heavy_module(tmp_path):
    if os.environ.get("CFM_NO_CODEGEN_CACHE"):
        pytest.skip("the generated-code cache is switched off")
    make_material("cfm").numba_source()  # the material's generated module is in the cache now
    assert _drop_test_imports(tmp_path / "warm") == []
    # control: without the cache the code is generated, which needs sympy (the check can see it)
    assert "sympy" in _drop_test_imports(tmp_path / "nocache", CFM_NO_CODEGEN_CACHE="1")
