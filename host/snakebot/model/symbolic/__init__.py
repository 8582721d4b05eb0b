"""Symbolic models (sympy): the control vector fields, their Lie brackets, and the C
generated from them for the kinematic core.

May import: as the ``model`` layer (``model.robots``, ``formats``, ``facts``, the
package root)."""

from __future__ import annotations

from snakebot.model.symbolic.models import (
    FORMS,
    SymbolicModel,
    lie_bracket,
    model_for,
    snake3,
    trident,
)

__all__ = ["FORMS", "SymbolicModel", "lie_bracket", "model_for", "snake3", "trident"]
