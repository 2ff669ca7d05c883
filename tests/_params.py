"""Shared test parametrisations."""

import pytest

#: built-in models whose cases run only under ``make test`` (``slow``): the fast loop keeps the
#: small chains (two_fingers, index_thumb, ...), which cover the same code paths
HEAVY_MODELS = ("hand21", "hand21_right", "hand27", "hand27_right", "mouse3d")


def model_params(names, fast=None):
    """``names`` as pytest parameters, the heavy models (or, given ``fast``, every model not in it)
    marked slow."""
    def slow(n):
        return n in HEAVY_MODELS if fast is None else n not in fast
    return [pytest.param(n, marks=pytest.mark.slow) if slow(n) else n for n in names]
