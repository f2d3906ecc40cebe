"""Typed backend options: checked at construction, unknown names listed, one table for docs."""

import math
from dataclasses import dataclass

import pytest

from cfm_core import InputError
from cfm_core.simulation.options import Options, document, option


@document
@dataclass(frozen=True)
class Demo(Options):
    """Demo options."""

    owner = "demo backend"
    safety: float = option(0.9, "-", "time-step safety factor", low=0.0, high=1.0, low_open=True)
    dt_max: float = option(math.inf, "s", "largest step", low=0.0, low_open=True)
    dt: float = option(None, "s", "first step", kind="float", low=0.0, low_open=True, none="automatic")
    threads: int = option(None, "-", "threads", kind="int", low=1, none="library default")
    solver: str = option("auto", "-", "linear solver", choices=("auto", "direct", "cg"))
    warm_up: bool = option(True, "-", "compile first")


def test_defaults_and_overrides():
    o = Demo.from_mapping({"safety": 0.5, "threads": 2})
    assert (o.safety, o.threads, o.dt, o.dt_max, o.solver) == (0.5, 2, None, math.inf, "auto")
    assert o.replace(dt=1e-6).dt == 1e-6 and o.as_dict()["safety"] == 0.5


@pytest.mark.parametrize("name, value, words", [
    ("safety", 1.5, ["safety = 1.5", "(0, 1]"]), ("safety", 0.0, ["(0, 1]"]), ("safety", "x", ["'x'"]),
    ("safety", math.nan, ["nan"]), ("dt", -1.0, ["dt = -1.0 s", "None (automatic)"]),
    ("threads", 1.5, ["an integer"]), ("threads", True, ["threads = True"]),
    ("solver", "lu", ["'auto', 'direct', 'cg'"]), ("warm_up", 1, ["True or False"]),
    # integers beyond the float range (TOML, JSON): OverflowError tracebacks before
    pytest.param("safety", 10 ** 400, ["safety = 1000...0 (an integer of 401 digits)", "(0, 1]"], id="safety-huge"),
    pytest.param("threads", 10 ** 400, ["threads = 1000...0 (an integer of 401 digits)", "an integer"],
                 id="threads-huge"),
    pytest.param("dt", -10 ** 400, ["dt = -1000...0 (an integer of 401 digits) s"], id="dt-huge"),
])
def test_bad_values_name_field_value_and_what_is_allowed(name, value, words):
    with pytest.raises(InputError) as err:
        Demo.from_mapping({name: value})
    text = str(err.value)
    assert text.startswith("demo backend: option " + name)
    for w in words:
        assert w in text


def test_unknown_names_are_listed():
    with pytest.raises(InputError, match=r"unknown option\(s\) hourglas; allowed: safety, dt_max, dt, threads"):
        Demo.from_mapping({"hourglas": 0.1})


def test_docstring_table_comes_from_the_declaration():
    assert "safety" in Demo.__doc__ and "time-step safety factor" in Demo.__doc__
    assert "None (automatic)" in Demo.table()


def test_a_default_of_none_must_state_its_kind():
    """option(None, ...) without kind= used to accept anything unchecked (skfem's rtol, dt_max, ...:
    rtol='1e-7' crashed in the stepper with a TypeError traceback, dt_max=-1 ran on forever)."""
    with pytest.raises(TypeError, match="kind="):
        option(None, "s", "largest step", low=0.0)


def test_a_number_with_a_named_setting():
    """error_tol: a number in (0, inf), the word 'auto', or None."""

    @dataclass(frozen=True)
    class Tol(Options):
        owner = "demo backend"
        error_tol: float = option("auto", "-", "local error tolerance", kind="float", choices=("auto",), low=0.0,
                                  low_open=True, none="off")

    assert [Tol(error_tol=v).error_tol for v in ("auto", 2e-3, None)] == ["auto", 2e-3, None]
    for bad in ("x", -1.0, "1e-3", math.nan):
        with pytest.raises(InputError, match=r"a number in \(0, inf\), or 'auto', or None \(off\)"):
            Tol(error_tol=bad)


def test_every_declared_option_of_every_backend_checks_its_values():
    """No backend's option takes just any value where a number is meant: every option whose
    default is None names its kind, and the skfem ones that did not now refuse text and bad ranges."""
    from cfm_core import plugins
    from cfm_core.simulation.registry import backend_for

    for name in plugins.names("backends"):
        try:
            cls = getattr(backend_for(name), "options_class", None)
        except Exception:  # a backend not installed here
            continue
        for opt, spec in (cls.specs() if cls is not None else {}).items():
            if spec.kind == "any" and not spec.choices:  # an array, or torch objects the backend checks itself
                assert opt in ("initial_velocity", "device", "dtype"), f"{name}.{opt} accepts any value unchecked"
    pytest.importorskip("skfem")
    from cfm_backends.skfem_implicit.options import SkfemOptions

    for opt in ("dt", "dt_min", "dt_max", "rtol", "atol", "penalty", "frame_interval", "error_tol"):
        for bad in (-1.0, "abc"):
            with pytest.raises(InputError, match=f"option {opt} = "):
                SkfemOptions.from_mapping({opt: bad})


def test_torch_compile_takes_a_mode_name_or_a_boolean():
    """--option compile=maybe ended in torch's RuntimeError traceback; now an InputError listing the modes."""
    pytest.importorskip("torch")
    from cfm_backends.torch_explicit.options import TorchOptions

    assert [TorchOptions(compile=v).compile for v in (False, True, "max-autotune")] == [False, True, "max-autotune"]
    with pytest.raises(InputError, match=r"option compile = 'maybe' is not allowed; expected one of False, True"):
        TorchOptions.from_mapping({"compile": "maybe"})
