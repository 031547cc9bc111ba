"""Reading planners pickled before the planner's settings were split (training checkpoints).

A checkpoint pickles the training vector env (semdp's ``Algorithm.save_checkpoint``), planners
included. Before the split a pickled :class:`~solvers.planner.SafeTrajectoryPlanner` held the
flat settings object, a ``PlanningContext`` and its backend objects, from modules that no longer
exist (``solvers.planner.context``, ``lm_backend``, ...). Importing :mod:`solvers.planner`
registers those module names with stand-in classes (:data:`REMOVED`) that keep an object's
pickled state and nothing else; the planner's ``__setstate__`` then rebuilds itself from the
settings (converted by :meth:`~solvers.planner.settings.PlannerSettings.from_flat`), the pickled
GP prior (:func:`legacy_context`) and the warm-start memory, so a resumed run plans as before.
"""

from __future__ import annotations

import sys
import types

from solvers.planner.problem.context import ProblemContext
from solvers.planner.problem.gp_prior import GPPrior
from solvers.planner.problem.settings import ProblemSettings

#: The classes of the removed modules that a pickled planner can name.
REMOVED: dict[str, tuple[str, ...]] = {
    "solvers.planner.context": ("PlanningContext",),
    "solvers.planner.certificate": ("Certificate",),
    "solvers.planner.backend": ("Iterate",),
    "solvers.planner.ipopt_backend": ("IpoptBackend",),
    "solvers.planner.ipopt": ("IpoptProgram",),
    "solvers.planner.lm_backend": ("LMBackend",),
    "solvers.planner.lm": ("LMWeights", "LMKernel"),
    "solvers.planner.scp_backend": ("ScpBackend",),
    "solvers.planner.scp": ("ScpProgram",),
}


class RemovedClass:
    """An object of a removed planner class, kept as its pickled state (:attr:`state`)."""

    state: object = None

    def __init__(self, *args: object, **kwargs: object) -> None:
        cls = type(self)
        raise TypeError(f"{cls.__module__}.{cls.__qualname__} no longer exists (the planner's "
                        "settings were split); it is only read from old pickles")

    def __setstate__(self, state: object) -> None:
        self.state = state


def register_removed_modules() -> None:
    """Make the removed module names importable with stand-ins for their pickled classes."""
    for module_name, class_names in REMOVED.items():
        if module_name in sys.modules:
            continue
        module = types.ModuleType(module_name, "A removed planner module: stand-ins for old "
                                  "pickles (solvers/planner/legacy_pickles.py).")
        for name in class_names:
            setattr(module, name, type(name, (RemovedClass,),
                                       {"__module__": module_name, "__qualname__": name}))
        sys.modules[module_name] = module


def legacy_context(pickled: object, problem: ProblemSettings) -> ProblemContext:
    """The problem context of a pickled ``PlanningContext``: its GP prior as pickled (the
    numbers the run planned with), the rest derived from ``problem`` as before."""
    state = pickled.state if isinstance(pickled, RemovedClass) else None
    prior = state.get("prior") if isinstance(state, dict) else None
    return ProblemContext(problem, prior if isinstance(prior, GPPrior) else None)


register_removed_modules()
