"""The bench's own error, below every other module (config and plugins both raise it; nothing to import)."""

from __future__ import annotations


class ScenarioError(ValueError):
    """A scenario key or value is wrong; the message names the key and what is allowed."""
