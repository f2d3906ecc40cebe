"""Fixtures shared by the backend tests."""

import os

import pytest


@pytest.fixture(scope="module")
def ccx():
    """The calculix backend when CalculiX is built here; else a skip naming how to get it (a
    failure with ``CFM_REQUIRE_CALCULIX=1``)."""
    from cfm_core.simulation.registry import get_backend

    b = get_backend("calculix")
    ok, why = b.available()
    if not ok:
        if os.environ.get("CFM_REQUIRE_CALCULIX") == "1":
            pytest.fail(f"{why}; CFM_REQUIRE_CALCULIX=1 requires it")
        pytest.skip(why)
    return b
