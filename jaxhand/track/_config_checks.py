"""The value checks every part of :class:`~jaxhand.TrackConfig` runs when it is built: each raises
:class:`~jaxhand.InputError` naming the field and the value."""

from __future__ import annotations

from .._errors import InputError, finite_number

__all__ = ["need", "flag", "count", "finite_number"]


def need(ok: bool, where: str, message: str) -> None:
    """Raise ``InputError("where: message")`` unless ``ok``."""
    if not ok:
        raise InputError(f"{where}: {message}")


def flag(value, where: str) -> None:
    """``value`` must be a bool."""
    need(isinstance(value, bool), where, f"expected true or false, got {value!r}")


def count(value, where: str) -> None:
    """``value`` must be an int >= 0 (not a bool)."""
    need(isinstance(value, int) and not isinstance(value, bool) and value >= 0, where,
         f"expected an integer >= 0, got {value!r}")
