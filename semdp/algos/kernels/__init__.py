"""Derivative kernels: the gradients of the default MLPs written out in place of autograd, an
opt-in of the presets (``gradients="written"``; the Python default is ``"autograd"``).

:mod:`~semdp.algos.kernels.written` holds the on-policy kernel (the stacked critic regression,
PPO's clipped-surrogate step, TRPO's and CPO's Fisher-vector product) and
:mod:`~semdp.algos.kernels.sac_written` SAC's. The losses themselves are defined once, in the
algorithms' files; each kernel is checked against them when an algorithm is built, and fails
there, naming the option to turn off, if an edit to a loss is not mirrored. The on-policy
numbers differ from autograd's in the last bits (learning curves within noise); SAC's equal
autograd's bit for bit.
"""
