"""The compare dropdown's runs (issue 43, item 6): a ghost is never the shown run again."""

from __future__ import annotations

import pytest

from tests._helpers import require

require("viser")


def _runs(system: str, settings: dict, compare: str) -> dict:
    from web.generic import GenericView

    view = GenericView.__new__(GenericView)  # runs() needs only the system and the plotted names
    view.system, view.plot_y, view.plot_x = system, None, None
    return view.runs(settings, {"compare": compare})


@pytest.mark.parametrize("compare", ["all", "Γ = 0"])
def test_a_model_without_constraints_gets_no_gamma_zero_ghost(compare):
    """The minimal formulation has nothing to stabilize: before, compare "all" listed
    "minimal, Γ = 0" — the shown run again, drawn as its own ghost."""
    runs = _runs("sliding-particle", {"formulation": "minimal", "gamma1": -20.0, "dt": 0.05}, compare)
    assert "minimal, Γ = 0" not in runs
    assert list(runs) == (["minimal", "nonminimal"] if compare == "all" else ["minimal"])


def test_a_model_with_constraints_keeps_its_gamma_zero_ghost():
    runs = _runs("sliding-particle", {"formulation": "nonminimal", "gamma1": -20.0, "dt": 0.05}, "all")
    assert list(runs) == ["nonminimal", "minimal", "nonminimal, Γ = 0"]
    assert runs["nonminimal, Γ = 0"]["gamma1"] == 0.0
