"""How a fit ended: the :class:`Status` enumeration and its host-side names."""

from __future__ import annotations

import equinox as eqx
import numpy as np

__all__ = ["Status", "STATUS_NAMES", "status_name"]


class Status(eqx.Enumeration):
    """Outcome of a fit (an ``equinox.Enumeration``; compare with ``result.status == Status.ok``).

    - ``ok``: a stopping rule fired (small step or stagnant cost) and the Jacobian at the
      result has full rank (every degree of freedom is determined by the features).
    - ``max_steps``: the iteration cap was reached first (the fast mode of one update per
      frame always ends here); ``q`` is the last iterate.
    - ``diverged``: the cost grew past ``divergence_factor`` times its start value, or ended
      above it; ``q`` is the starting state.
    - ``singular``: a stopping rule fired but the Jacobian at the result is rank-deficient
      (some degree of freedom is not determined by the features, e.g. a link with every
      feature masked, or the depth of a free palm seen by one orthographic camera). ``q`` is
      finite; the undetermined directions kept their start values (minimum-norm steps).
    - ``nonfinite``: an iterate or its cost became NaN or inf; ``q`` is the starting state.
    """

    ok = "converged"
    max_steps = "iteration cap reached before convergence"
    diverged = "cost grew: solve diverged, starting state returned"
    singular = "converged, but the Jacobian is rank-deficient: some DOF are not determined by the features"
    nonfinite = "non-finite iterate or cost, starting state returned"


#: Status names in code order: ``STATUS_NAMES[code]``.
STATUS_NAMES = ("ok", "max_steps", "diverged", "singular", "nonfinite")


def status_name(status) -> str | np.ndarray:
    """Host-side name(s) of a status or a batch of statuses: ``'ok'`` or an array of names."""
    codes = np.asarray(status._value)
    names = np.array(STATUS_NAMES)[codes]
    return str(names) if names.ndim == 0 else names
