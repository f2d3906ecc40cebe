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
