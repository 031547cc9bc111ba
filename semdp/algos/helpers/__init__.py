"""Helper processes of the on-policy algorithms: a seam that changes no number (same seed, same
``progress.csv``).

``vectorization`` / ``parallel_critics`` (``conf/algo/*.yaml``, read by
:mod:`semdp.algos.speedups`, which hands them to the algorithm) pick the **rollout collector**
and the **critic runner**: forked helper processes that roll out part of the sub-envs
(:mod:`~semdp.algos.helpers.rollout_helper`) and regress the critics during the actor update
(:mod:`~semdp.algos.helpers.critic_helper`), chosen per epoch by ``auto``
(:mod:`~semdp.algos.helpers.option_probe`, :mod:`~semdp.algos.helpers.modes`). The plain path
(:class:`~semdp.algos.rollout.LocalCollector`, the critics regressed in the trainer) is
``vectorization=sync parallel_critics=false``.
"""
