"""Shared pytest configuration: the ``slow`` marker runs only with --runslow; numba's vector width
fixed before any test compiles (every worker process the same width, as a ``cfm`` run gets)."""

import pytest


def pytest_configure(config):
    # A test module that compiles its own numba function first would otherwise fix numba's default
    # width for its whole worker process (cfm_backends.numba_target): that worker would compile and
    # run the kernels at another width than the others and than a user's run.
    from cfm_backends.numba_target import configure

    try:
        configure()
    except ImportError:       # numba not installed: the numba tests skip themselves
        pass


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", default=False, help="run slow studies (paper table, convergence)")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="slow study: run with --runslow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
