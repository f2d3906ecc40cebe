"""numpydoc sections on the public API (issue 11, item 5), checked from the code itself.

For every public function, method, property and class reachable from ``cfm_core.__all__`` and
defined in the modules of ``MODULES``:

- a docstring exists;
- a ``Parameters`` section documents every argument besides self/cls (classes: the constructor's
  arguments, under ``Parameters`` or ``Attributes``);
- a ``Returns`` (or ``Yields``) section exists when the callable returns a value: a return
  annotation other than None, or a ``return <value>`` / ``yield`` in its own body (ast);
- a ``Raises`` section names every one of InputError and NumericalError that its own body raises
  (ast; for a class, the bodies of ``__init__`` and ``__post_init__``);
- properties need a docstring (and Raises as above), not Parameters or Returns (numpydoc
  documents them as attributes).

The checker is :func:`docstring_problems`; the ``test_checker_*`` tests show that it reports a
callable without sections, so this test can fail.
"""

from __future__ import annotations

import ast
import functools
import importlib
import inspect
import textwrap
import types
from dataclasses import fields, is_dataclass

import pytest

import cfm_core
from cfm_core.errors import InputError, NumericalError

#: Modules whose public callables are checked in full (besides what cfm_core.__all__ reaches).
MODULES = [
    "cfm_core.plugins", "cfm_core.errors", "cfm_core.tables",
    "cfm_core.material", "cfm_core.material.cache", "cfm_core.material.codegen", "cfm_core.material.kinematics",
    "cfm_core.material.material", "cfm_core.material.parameters", "cfm_core.material.prony",
    "cfm_core.material.reference", "cfm_core.material.registry", "cfm_core.material.spec", "cfm_core.material.sym",
    "cfm_core.material.terms",
    "cfm_core.scene.scene", "cfm_core.scene.builder", "cfm_core.scene.model",
    "cfm_core.post.filters", "cfm_core.post.histories", "cfm_core.post.writers", "cfm_core.post.plots",
    "cfm_core.simulation.backend", "cfm_core.simulation.result", "cfm_core.simulation.registry",
    "cfm_core.simulation.reference_backend",
    "cfm_plugins", "cfm_plugins.cfm", "cfm_plugins.mooney_rivlin", "cfm_plugins.neo_hookean", "cfm_plugins.ogden",
    "cfm_plugins.volumetric", "cfm_plugins.septa", "cfm_plugins.sphere_quadrature",
    "cfm_core.studies.fit", "cfm_core.studies.fit_output", "cfm_core.studies.lab_tests", "cfm_core.studies.peaks",
]

#: Callables reached from cfm_core.__all__ but defined in modules this change did not document
#: (cfm_core/runs, edited on another branch): expected to fail until their docstrings gain the
#: sections. Not strict, so documenting them does not break the suite; remove entries as they pass.
PENDING: set = set()  # names whose docstrings are known to be incomplete (none now)

ERRORS = ("InputError", "NumericalError")
_PROJECT = ("cfm_core", "cfm_plugins")


# ----------------------------------------------------------------------------- docstring parsing
def sections(doc: str | None) -> dict[str, list[str]]:
    """numpydoc sections of a docstring: header -> body lines (dedented), e.g. ``{"Parameters": [...]}``."""
    lines = inspect.cleandoc(doc or "").splitlines()
    out: dict[str, list[str]] = {}
    current = None
    i = 0
    while i < len(lines):
        line = lines[i]
        underline = lines[i + 1].strip() if i + 1 < len(lines) else ""
        if line.strip() and len(underline) >= 3 and set(underline) == {"-"}:
            current = line.strip()
            out[current] = []
            i += 2
            continue
        if current is not None:
            out[current].append(line)
        i += 1
    return {k: textwrap.dedent("\n".join(v)).splitlines() for k, v in out.items()}


def documented_names(body: list[str]) -> set[str]:
    """Names of the entries of a Parameters-like section (``a, b : float`` documents a and b)."""
    names = set()
    for line in body:
        if line.strip() and not line[0].isspace():
            head = line.split(" : ")[0].rstrip(":").strip()
            names.update(n.strip().lstrip("*") for n in head.split(","))
    return names


# ----------------------------------------------------------------------------- code inspection
def _unwrap(obj):
    """The plain function behind a method descriptor or a cache wrapper (None if there is none)."""
    if isinstance(obj, (staticmethod, classmethod)):
        obj = obj.__func__
    if isinstance(obj, property):
        obj = obj.fget
    if isinstance(obj, functools.cached_property):
        obj = obj.func
    while hasattr(obj, "__wrapped__"):
        obj = obj.__wrapped__
    return obj if isinstance(obj, types.FunctionType) else None


def _function_node(func):
    """The ast node of a function's definition, or None without source."""
    try:
        source = textwrap.dedent(inspect.getsource(func))
    except (OSError, TypeError):
        return None
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name == func.__name__:
            return node
    return None


def _own_nodes(node):
    """The nodes of a function's own body (nested functions, lambdas and classes left out)."""
    stack = list(node.body)
    while stack:
        n = stack.pop()
        yield n
        for child in ast.iter_child_nodes(n):
            if not isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
                stack.append(child)


def _raised(node) -> set[str]:
    """InputError / NumericalError raised directly in a function's own body."""
    out = set()
    for n in _own_nodes(node):
        if isinstance(n, ast.Raise) and n.exc is not None:
            exc = n.exc.func if isinstance(n.exc, ast.Call) else n.exc
            name = exc.attr if isinstance(exc, ast.Attribute) else getattr(exc, "id", None)
            if name in ERRORS:
                out.add(name)
    return out


def _returns_value(func, node) -> str | None:
    """"Returns", "Yields" or None: what the function hands back (annotation first, then its body)."""
    if node is not None and any(isinstance(n, (ast.Yield, ast.YieldFrom)) for n in _own_nodes(node)):
        return "Yields"
    annotation = inspect.signature(func).return_annotation
    if annotation is not inspect.Signature.empty:
        return None if annotation in (None, "None", type(None)) else "Returns"
    if node is None:
        return None
    for n in _own_nodes(node):
        if isinstance(n, ast.Return) and n.value is not None and \
                not (isinstance(n.value, ast.Constant) and n.value.value is None):
            return "Returns"
    return None


def _arguments(func, bound: bool) -> list[str]:
    """Argument names, self/cls left out for methods; ``*args``/``**kwargs`` by their names."""
    names = list(inspect.signature(func).parameters)
    return names[1:] if bound else names


# ----------------------------------------------------------------------------- the checker
def function_problems(func, bound: bool = False, kind: str = "function") -> list[str]:
    """What is missing from the docstring of a function or method (empty list: nothing)."""
    doc = inspect.getdoc(func) if kind != "property" else func.__doc__
    if not (doc or "").strip():
        return ["no docstring"]
    found = sections(doc)
    node = _function_node(func)
    problems = []
    if kind != "property":
        args = _arguments(func, bound)
        if args:
            if "Parameters" not in found:
                problems.append(f"no Parameters section (arguments {args})")
            else:
                missing = [a for a in args if a not in documented_names(found["Parameters"])]
                if missing:
                    problems.append(f"Parameters section does not document {missing}")
        wanted = _returns_value(func, node)
        if wanted and wanted not in found:
            problems.append(f"no {wanted} section")
    if node is not None:
        raised = _raised(node)
        if raised and "Raises" not in found:
            problems.append(f"no Raises section (raises {sorted(raised)})")
        elif raised:
            missing = [e for e in sorted(raised) if e not in documented_names(found["Raises"])]
            if missing:
                problems.append(f"Raises section does not name {missing}")
    return problems


def _constructor_arguments(cls) -> list[str]:
    if is_dataclass(cls):
        return [f.name for f in fields(cls) if f.init]
    init = cls.__dict__.get("__init__")
    return _arguments(init, bound=True) if isinstance(init, types.FunctionType) else []


def class_problems(cls) -> list[str]:
    """What is missing from a class docstring: the constructor's arguments (Parameters or
    Attributes) and the errors its ``__init__`` / ``__post_init__`` raise (Raises)."""
    doc = cls.__dict__.get("__doc__")
    if not (doc or "").strip():
        return ["no docstring"]
    found = sections(doc)
    problems = []
    args = _constructor_arguments(cls)
    if args:
        documented = documented_names(found.get("Parameters", []) + found.get("Attributes", []))
        if not {"Parameters", "Attributes"} & set(found):
            problems.append(f"no Parameters or Attributes section (constructor arguments {args})")
        elif [a for a in args if a not in documented]:
            problems.append(f"constructor arguments {[a for a in args if a not in documented]} not documented")
    raised = set()
    for name in ("__init__", "__post_init__"):
        func = cls.__dict__.get(name)
        if isinstance(func, types.FunctionType) and (node := _function_node(func)) is not None:
            raised |= _raised(node)
    if raised and "Raises" not in found:
        problems.append(f"no Raises section (the constructor raises {sorted(raised)})")
    elif raised and [e for e in sorted(raised) if e not in documented_names(found["Raises"])]:
        problems.append(f"Raises section does not name all of {sorted(raised)}")
    return problems


def docstring_problems(obj) -> dict[str, list[str]]:
    """Problems of a class (and its public methods and properties) or a function: qualified
    name -> list of problems, only for names that have some."""
    out = {}
    name = f"{obj.__module__}.{obj.__qualname__}"
    if inspect.isclass(obj):
        if problems := class_problems(obj):
            out[name] = problems
        for attr, member in vars(obj).items():
            if attr.startswith("_"):
                continue
            func = _unwrap(member)
            if func is None:
                continue
            kind = "property" if isinstance(member, (property, functools.cached_property)) else "method"
            bound = not isinstance(member, staticmethod)
            if problems := function_problems(func, bound=bound, kind=kind):
                out[f"{name}.{attr}"] = problems
    elif (func := _unwrap(obj)) is not None:
        if problems := function_problems(func):
            out[name] = problems
    return out


# ----------------------------------------------------------------------------- what is public
def _defined_in_project(obj) -> bool:
    return (getattr(obj, "__module__", None) or "").split(".")[0] in _PROJECT


def _module_members(module) -> list:
    """Public classes and functions defined in a module; the energy functions of its terms."""
    out = []
    for attr, obj in vars(module).items():
        if attr.startswith("_"):
            continue
        if isinstance(obj, cfm_core.Term) and getattr(obj.energy, "__module__", None) == module.__name__:
            out.append(obj.energy)
        elif (inspect.isclass(obj) or inspect.isfunction(obj)) and obj.__module__ == module.__name__:
            out.append(obj)
    return out


def public_callables() -> dict[str, object]:
    """Qualified name -> class or function: what cfm_core.__all__ reaches, and MODULES."""
    found = {}
    roots = []
    for attr in cfm_core.__all__:
        obj = getattr(cfm_core, attr)
        if isinstance(obj, types.ModuleType):
            roots += _module_members(obj)
        elif _defined_in_project(obj) and (inspect.isclass(obj) or inspect.isfunction(obj)):
            roots.append(obj)
    for name in MODULES:
        roots += _module_members(importlib.import_module(name))
    for obj in roots:
        found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return found


def _checked_names(callables: dict) -> list[str]:
    """Every qualified name the test checks: the callables and the public methods and properties
    of the classes among them."""
    names = set(callables)
    for name, obj in callables.items():
        if inspect.isclass(obj):
            names |= {f"{name}.{attr}" for attr, member in vars(obj).items()
                      if not attr.startswith("_") and _unwrap(member) is not None}
    return sorted(names)


_CALLABLES = public_callables()
_NAMES = _checked_names(_CALLABLES)
_PROBLEMS = {name: problems for obj in _CALLABLES.values() for name, problems in docstring_problems(obj).items()}


@pytest.mark.parametrize("name", [
    pytest.param(n, marks=pytest.mark.xfail(reason="cfm_core/runs is documented on another branch", strict=False))
    if n in PENDING else n for n in _NAMES])
def test_public_docstring_has_numpydoc_sections(name):
    assert name not in _PROBLEMS, f"{name}: {'; '.join(_PROBLEMS[name])}"


def test_the_public_api_is_reached():
    """The collection finds the API a user meets first (a broken walk would pass vacuously)."""
    for name in ("cfm_core.scene.scene.load_scene", "cfm_core.scene.scene.Scene.with_overrides",
                 "cfm_core.material.spec.MaterialSpec.bind", "cfm_core.post.filters.cfc_filter",
                 "cfm_core.plugins.get", "cfm_core.runs.pipeline.drop_test", "cfm_plugins.cfm.lipid",
                 "cfm_core.simulation.backend.Backend.run", "cfm_core.errors.NumericalError"):
        assert name in _NAMES
    assert len(_NAMES) > 100
    assert set(_PROBLEMS) <= set(_NAMES)


# ----------------------------------------------------------------------------- the checker can fail
def _undocumented(x, y):
    """Add two numbers."""
    if x is None:
        raise InputError("x is None")
    return x + y


def _documented(x, y=1.0):
    """Add two numbers.

    Parameters
    ----------
    x, y : float
        The numbers (m).

    Returns
    -------
    float
        Their sum (m).

    Raises
    ------
    InputError
        ``x`` is None.
    """
    if x is None:
        raise InputError("x is None")
    return x + y


def _wrong_error(x) -> None:
    """Check x.

    Parameters
    ----------
    x : float
        A value.

    Raises
    ------
    InputError
        Never.
    """
    if x != x:
        raise NumericalError("x is NaN")


class _Point:
    """A point.

    Parameters
    ----------
    x : float
        Abscissa (m).
    """

    def __init__(self, x, y):
        if x is None:
            raise InputError("x is None")
        self.x, self.y = x, y

    def norm(self, p):
        """The p-norm."""
        return (abs(self.x) ** p + abs(self.y) ** p) ** (1 / p)


def test_checker_reports_missing_sections():
    problems = function_problems(_undocumented)
    assert any("no Parameters section" in p for p in problems)
    assert any("no Returns section" in p for p in problems)
    assert any("no Raises section" in p for p in problems)
    assert function_problems(_documented) == []


def test_checker_reports_an_error_the_raises_section_does_not_name():
    assert function_problems(_wrong_error) == ["Raises section does not name ['NumericalError']"]


def test_checker_reports_classes_and_methods():
    problems = docstring_problems(_Point)
    name = f"{__name__}._Point"
    assert any("['y'] not documented" in p for p in problems[name])
    assert any("Raises" in p for p in problems[name])
    assert any("no Parameters section" in p for p in problems[f"{name}.norm"])
    assert any("no Returns section" in p for p in problems[f"{name}.norm"])


def test_sections_parser():
    doc = _documented.__doc__
    found = sections(doc)
    assert set(found) == {"Parameters", "Returns", "Raises"}
    assert documented_names(found["Parameters"]) == {"x", "y"}
    assert documented_names(found["Raises"]) == {"InputError"}
