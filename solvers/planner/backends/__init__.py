"""The planner's solver backends (thesis §3.5.2), one module each, each with its own settings.

* :mod:`.ipopt` -- :class:`IpoptSettings`: the exact NLP with hard pairwise clearance
  constraints (Eq. 3.3) on IPOPT;
* :mod:`.lm` -- :class:`LMSettings`: the thesis' penalty form (Eq. 3.8, App. B.2.3) with
  Levenberg-Marquardt (its damped steps in :mod:`.banded_least_squares`);
* :mod:`.scp` -- :class:`SCPSettings`: sequential convex QPs on OSQP with tangent half-spaces;
* :mod:`.base` -- the :class:`~.base.Backend` protocol they satisfy.

A backend is built from its settings for a problem (``settings.build(context)``); the settings
object is what a ``conf/planner`` file's ``backend:`` node instantiates.
"""

from __future__ import annotations

from solvers.planner.backends.base import Backend, BackendSettings
from solvers.planner.backends.ipopt import IpoptSettings
from solvers.planner.backends.lm import LMSettings
from solvers.planner.backends.scp import SCPSettings

#: Settings class of each backend, by name.
BACKEND_SETTINGS: dict[str, type[IpoptSettings] | type[LMSettings] | type[SCPSettings]] = {
    "ipopt": IpoptSettings,
    "lm": LMSettings,
    "scp": SCPSettings,
}
#: Names of the solver backends.
BACKENDS: tuple[str, ...] = tuple(BACKEND_SETTINGS)

__all__ = [
    "BACKENDS",
    "BACKEND_SETTINGS",
    "Backend",
    "BackendSettings",
    "IpoptSettings",
    "LMSettings",
    "SCPSettings",
]
