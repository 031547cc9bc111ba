"""Soft Actor-Critic, the SEMDP's high level (thesis §3.5.1), in one subpackage:

* :mod:`~semdp.algos.sac.algorithm` -- :class:`SAC`: collection, the replay buffer and the three
  loops (``learner``);
* :mod:`~semdp.algos.sac.learner` -- one update: the losses, defined once, and the optimisers;
* :mod:`~semdp.algos.sac.twin_q` -- the twin critic, one forward;
* :mod:`~semdp.algos.sac.replay` -- the replay buffer (shared memory for a learner process);
* :mod:`~semdp.algos.sac.n_step` -- n-step returns;
* :mod:`~semdp.algos.sac.learner_host` and :mod:`~semdp.algos.sac.learner_process` -- where the
  updates run (this process or a process of their own, the same numbers).

The written-out gradients (``gradients="written"``) are :mod:`semdp.algos.kernels.sac_written`.
"""

from semdp.algos.sac.algorithm import SAC

__all__ = ["SAC"]
