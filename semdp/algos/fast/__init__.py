"""Speed-ups of the on-policy algorithms, each behind one of two seams and none changing a number
(and SAC's written-out gradients, :mod:`~semdp.algos.fast.sac_written`, behind SAC's
``gradients`` argument: autograd's floats bit for bit).

The plain path (:mod:`semdp.algos.on_policy`, :mod:`semdp.algos.rollout`, :mod:`semdp.algos.ppo`)
runs everything in one process with autograd. Two constructor arguments of the on-policy
algorithms (``conf/algo/*.yaml``) swap parts of it for the modules here:

* ``gradients="written"`` -- the **update kernel**, an opt-in of the presets (the Python default
  is ``"autograd"``): the derivatives of the default MLPs written out
  (:mod:`~semdp.algos.fast.written`: the stacked critic regression, PPO's clipped-surrogate
  step, TRPO's and CPO's Fisher-vector product); the numbers differ in the last bits, the
  learning curves within noise. The losses themselves are defined once, in the algorithms'
  files; the kernels are checked against them when an algorithm is built.
* ``vectorization`` / ``parallel_critics`` -- the **rollout collector** and the critic runner:
  forked helper processes that roll out part of the sub-envs
  (:mod:`~semdp.algos.fast.rollout_helper`) and regress the critics during the actor update
  (:mod:`~semdp.algos.fast.critic_helper`), chosen per epoch by ``auto``
  (:mod:`~semdp.algos.fast.option_probe`); same seed, same ``progress.csv``.
"""
