"""The module names of version 0.1 stay importable, warn, and give the objects of the new layout."""

import importlib

import pytest

import cfm_core
from cfm_core import compat


def test_old_names_give_the_new_objects_with_a_deprecation_warning():
    from cfm_core.runs import pipeline
    from cfm_core.studies import measured

    with pytest.warns(DeprecationWarning, match="cfm_core.runs.pipeline.drop_test"):
        from cfm_core import simulate
        assert simulate.drop_test is pipeline.drop_test
    with pytest.warns(DeprecationWarning, match="cfm_core.studies.measured.read_measured"):
        from cfm_core.calibrate import read_measured
    assert read_measured is measured.read_measured


@pytest.mark.parametrize("old", sorted(compat.MOVED))
def test_every_old_name_resolves_to_existing_modules(old):
    module = importlib.import_module(f"cfm_core.{old}")
    for target in compat.MOVED[old]:
        importlib.import_module(f"cfm_core.{target}")
    with pytest.raises(AttributeError, match="was moved"):
        module.no_such_name_anywhere


def test_unknown_top_level_names_still_raise():
    with pytest.raises(AttributeError):
        cfm_core.no_such_module
