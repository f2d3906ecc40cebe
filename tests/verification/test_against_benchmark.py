"""``python -m cfm_verification.benchmarks.numba --against REV``: another revision's kernels.

Timing both versions compiles two kernel modules (minutes), so the default run checks what the
benchmark reads and refuses; the timing itself is a benchmark, run by hand.
"""

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("numba")
from cfm_backends.numba_explicit import codegen
from cfm_core.errors import InputError
from cfm_verification.benchmarks import against

ROOT = Path(__file__).resolve().parents[2]


def _has(rev: str) -> bool:
    proc = subprocess.run(["git", "rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}"], cwd=ROOT,
                          capture_output=True, text=True)
    return proc.returncode == 0


def test_a_revision_gives_its_kernel_files_and_they_build_a_module():
    if not _has("HEAD"):
        pytest.skip("not a git checkout")
    head_layout = subprocess.run(["git", "show", "HEAD:backends/numba_explicit/kernels/layout.py"], cwd=ROOT,
                                 capture_output=True, text=True).stdout
    if head_layout != (codegen.KERNELS_DIR / "layout.py").read_text():
        pytest.skip("layout.py has uncommitted changes")
    files = against.revision_files("HEAD")
    assert list(files) == list(codegen.KERNEL_FILES)
    for name, text in files.items():
        shown = subprocess.run(["git", "show", f"HEAD:backends/numba_explicit/kernels/{name}"], cwd=ROOT,
                               capture_output=True, text=True).stdout
        assert text == shown
    from fixtures.hand_derived import NeoHookeanStandIn

    from cfm_core.material.registry import make_material

    marked = {**files, "element.py": files["element.py"] + "\n\n# the other revision's element.py\n"}
    text = codegen.module_source(NeoHookeanStandIn(), marked)
    compile(text, "generated", "exec")
    assert text.count("def element_pass(") == 1 and "# the other revision's element.py" in text
    two = codegen.module_source((NeoHookeanStandIn(), make_material("cfm")), marked)
    assert "def element_pass__m1(" in two and two.count("# the other revision's element.py") == 1
    # the second material's element pass is copied from the given files, not the folder's
    marked["element.py"] = marked["element.py"].replace("def element_block(", "def element_block(  ", 1)
    assert "def element_block__m1(  " in codegen.module_source((NeoHookeanStandIn(), make_material("cfm")), marked)


def test_an_unknown_revision_is_an_input_error():
    with pytest.raises(InputError, match="--against 'no-such-revision-x': git cannot show kernels/layout.py"):
        against.revision_files("no-such-revision-x")


def test_a_revision_with_another_layout_is_refused():
    rev = "67e0679"   # before layout.PREFETCH_BLOCKS
    if not _has(rev):
        pytest.skip(f"{rev} is not in this clone")
    with pytest.raises(InputError, match="layout.py differs at that revision"):
        against.revision_files(rev)


def test_the_command_exits_nonzero_with_one_line():
    proc = subprocess.run([sys.executable, "-m", "cfm_verification.benchmarks.numba", "--against", "no-such-rev-y"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "error: --against 'no-such-rev-y'" in proc.stderr


def test_a_layout_differing_only_in_comments_fits():
    """Only the layout's constants decide: a comment changed at the other revision is no refusal."""
    text = (Path(codegen.KERNELS_DIR) / "layout.py").read_text()
    assert against._constants(text + "\n# a note of another revision\n") == against._constants(text)
    changed = text.replace("BLOCK = 32\n", "BLOCK = 16\n", 1)
    assert changed != text and against._constants(changed) != against._constants(text)
