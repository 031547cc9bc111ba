"""The SAC learner process' handler (started by
:class:`semdp.algos.sac.learner_host.ProcessLearner` as a :class:`solvers.workers.Helper`; the high
level of thesis Alg. 2, docs/semdp.md, "The main job's loop").

Requests: ``("init", settings, fd, layout, nbytes, threads)`` maps the replay file through the
inherited descriptor and builds the learner; ``("load", state)``; ``("run", n_updates, size)``
replies with the round's logs and the new actor weights; ``("state",)``.
"""

from __future__ import annotations

from typing import Any


class LearnerServer:
    """Answers the training process' requests with a
    :class:`~semdp.algos.sac.learner.SACLearner`."""

    def __init__(self) -> None:
        self.core: Any = None

    def __call__(self, request: tuple[Any, ...]) -> Any:
        import torch

        from semdp.algos.sac.learner import SACLearner
        from semdp.algos.sac.replay import attach

        command, *args = request
        if command == "init":
            settings, fd, layout, nbytes, threads = args
            torch.set_num_threads(int(threads))
            self.core = SACLearner(settings, attach(fd, layout, nbytes))
            return None
        if self.core is None:
            raise RuntimeError(f"learner request {command!r} before init")
        if command == "run":
            return self.core.run(*args), self.core.actor_vector().numpy()
        if command == "load":
            self.core.load_state_dict(args[0])
            return None
        if command == "state":
            return self.core.state_dict()
        raise ValueError(f"unknown learner request {command!r}")
