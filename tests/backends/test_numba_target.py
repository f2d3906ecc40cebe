"""numba's vector width (cfm_backends.numba_target): when it asks for 512-bit vectors and when not."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

llvm = pytest.importorskip("llvmlite.binding")
AVX512 = bool(llvm.get_host_cpu_features().get("avx512f", False))


def _fresh(code: str, **env) -> dict:
    """Run ``code`` in a fresh interpreter (numba not yet compiling) and read the JSON it prints."""
    e = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_FEATURES", "NUMBA_CPU_NAME",
                                                          "CFM_NUMBA_VECTOR_WIDTH")}
    e.update(env)
    out = subprocess.run([sys.executable, "-c", code], env=e, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


PROBE = ("import json; from cfm_backends.numba_target import configure; w = configure(); "
         "from numba.core import config; print(json.dumps({'w': w, 'f': config.CPU_FEATURES}))")


def test_default_asks_for_512_bit_vectors_on_avx512():
    r = _fresh(PROBE)
    if AVX512:
        assert r["w"] == 512 and r["f"].endswith(",-prefer-256-bit")
        assert "+avx512f" in r["f"]          # the host's own features, only the tuning flag added
    else:
        assert r["w"] == 0 and r["f"] is None


def test_switch_off_and_user_features_are_respected():
    r = _fresh(PROBE, CFM_NUMBA_VECTOR_WIDTH="256")
    assert r["f"] is None and r["w"] == (256 if AVX512 else 0)
    feats = llvm.get_host_cpu_features().flatten()
    r = _fresh(PROBE, NUMBA_CPU_FEATURES=feats)
    assert r["f"] == feats                 # the user's string untouched
    assert r["w"] == (256 if AVX512 else 0)


def test_no_change_once_numba_has_compiled():
    code = ("import json\nfrom numba import njit\n@njit\ndef f(x):\n    return x + 1\nf(1)\n"
            "from cfm_backends.numba_target import configure\nw = configure()\n"
            "from numba.core import config\nprint(json.dumps({'w': w, 'f': config.CPU_FEATURES}))")
    r = _fresh(code)
    assert r["f"] is None and r["w"] == (256 if AVX512 else 0)


def test_bad_switch_value_is_an_input_error():
    code = ("import json\nfrom cfm_core.errors import InputError\nfrom cfm_backends.numba_target import configure\n"
            "try:\n    configure()\n    print(json.dumps({'msg': None}))\n"
            "except InputError as e:\n    print(json.dumps({'msg': str(e)}))")
    msg = _fresh(code, CFM_NUMBA_VECTOR_WIDTH="1024")["msg"]
    assert msg is not None and "CFM_NUMBA_VECTOR_WIDTH" in msg and "'1024'" in msg and "256" in msg


def test_generated_module_names_its_width():
    """Each width is a module of its own: the cache check of the cold-run notice stays right."""
    from cfm_backends import numba_target
    from cfm_backends.numba_explicit import codegen
    from cfm_core.material.registry import make_material

    text = codegen.module_source(make_material("cfm"))
    assert f"# preferred vector width: {numba_target.configure() or 'default'} " in text


@pytest.mark.slow
@pytest.mark.skipif(not AVX512, reason="needs an AVX-512 CPU")
def test_paper_drop_test_identical_at_both_widths():
    """The paper's drop test (8 mm, 1 mm hexahedra: 5000 elements, whole blocks of 32) gives the
    same bits at 256- and 512-bit vectors: the width changes how many elements an instruction
    handles, not an element's arithmetic. Compiles the kernels at both widths (minutes)."""
    code = ("import json; from cfm_core.scene.builder import build_model; "
            "from cfm_core.scene.scene import builtin_scene; "
            "from cfm_backends.numba_explicit import NumbaExplicitBackend; "
            "m = build_model(builtin_scene('drop-test').with_overrides(element_size=1e-3, end_time=4e-3)); "
            "r = NumbaExplicitBackend().run(m, threads=1); "
            "print(json.dumps({'a': r.acceleration.tolist(), 'w': r.info['vector_width']}))")
    wide, narrow = _fresh(code), _fresh(code, CFM_NUMBA_VECTOR_WIDTH="256")
    assert (wide["w"], narrow["w"]) == (512, 256)
    assert np.array_equal(np.asarray(wide["a"]), np.asarray(narrow["a"]))
