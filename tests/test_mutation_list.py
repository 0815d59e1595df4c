"""scripts/mutate.py stays runnable as the code moves: every mutation's snippet occurs exactly once in its file
and its test files exist (a refactoring or a reformatting that loses a snippet fails here, not months later when
someone runs the mutations)."""

from __future__ import annotations

from graph_helpers import script


def test_every_mutation_applies_to_the_current_code() -> None:
    result = script("mutate.py", "--list", timeout=60)
    assert result.returncode == 0, [
        line for line in result.stdout.splitlines() if "  [cannot apply" in line or "  [no test file" in line
    ]
    assert result.stdout.count("\n    tests: ") >= 25
