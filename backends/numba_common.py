"""Text helpers both numba code generators share (the numba backend's ``codegen`` and the skfem
backend's ``compiled``): neither imports numba here, they only read and assemble source text.

Kernel files are ordinary modules with a *standalone block* (between ``# >>> standalone`` and
``# <<< standalone``) that gives them their imports and material stubs when imported on their
own; the generators remove it (:func:`strip_standalone`) before concatenating the kernels after a
material's generated scalar code, whose functions (:func:`material_functions`) they wrap in
``njit``.
"""

from __future__ import annotations

import ast
import re

#: The standalone block of a kernel file, with its closing line.
STANDALONE_BLOCK = re.compile(r"^# >>> standalone.*?^# <<< standalone[^\n]*\n", re.S | re.M)


def strip_standalone(text: str) -> str:
    """A kernel file's text without its standalone block(s).

    Parameters
    ----------
    text : str
        Source text of a kernel file.

    Returns
    -------
    str
        The same text with every ``# >>> standalone`` ... ``# <<< standalone`` block removed.
    """
    return STANDALONE_BLOCK.sub("", text)


def material_functions(source: str) -> list[str]:
    """Names of the top-level functions defined by a material's numba source.

    Parameters
    ----------
    source : str
        Python source (:meth:`cfm_core.material.Material.numba_source`).

    Returns
    -------
    list of str
        The names, in the order they are defined.
    """
    tree = ast.parse(source)
    return [node.name for node in tree.body if isinstance(node, ast.FunctionDef)]
