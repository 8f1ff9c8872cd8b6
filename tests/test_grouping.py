"""The test run's grouping under xdist works (``make test``: ``--dist loadgroup``, groups set in
tests/conftest.py): with pytest 9.2 and pytest-xdist 3.8 the groups were silently ignored
(pytest-xdist #1386) and two Chromiums raced on two cores."""

import os

import pytest


def test_a_module_is_one_group_under_xdist(request, pytestconfig):
    if not pytestconfig.getoption("loadgroup", default=False):  # set on xdist workers only
        assert os.environ.get("CI") != "true", "CI runs make test, which runs xdist --dist loadgroup"
        pytest.skip("not under xdist --dist loadgroup (a developer's plain pytest run)")
    assert request.node.nodeid.endswith("@tests/test_grouping.py"), request.node.nodeid
