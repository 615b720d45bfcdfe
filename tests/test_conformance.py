"""The conformance kit passes on every registered implementation."""

from __future__ import annotations

import pytest

from knitframe.plugins import load_registry
from knitframe.testing import check_entry

ENTRIES = load_registry().entries()


@pytest.mark.parametrize("entry", ENTRIES, ids=[f"{e.kind}:{e.name}" for e in ENTRIES])
def test_plugin_conforms(entry):
    """Each registered plugin honours the contract of its kind."""
    check_entry(entry)


def test_kit_catches_a_broken_objective():
    """The objective check fails for an objective that ignores non-uniformity."""
    from knitframe.testing import check_design_objective

    class Flat:
        name = "flat"
        description = "always zero"

        def score(self, tension, area, radius=None):
            return 0.0

    with pytest.raises(AssertionError, match="non-uniform"):
        check_design_objective(Flat)
