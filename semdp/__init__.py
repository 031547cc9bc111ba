"""semdp: safe RL on top of exact constrained optimisation.

Composes the two libraries of this project -- :mod:`solvers` (CasADi/IPOPT/OSQP planners and
the self-paced Lagrangian toy NLP) and :mod:`sims` (pymunk Safety Gym replica and driving
tasks) -- with torch RL algorithms, the Safety-Embedded MDP wrapper and the Hydra apps.
"""

from semdp.numerics import pin_cpu_kernels

__version__ = "0.1.0"

# Before anything imports torch: the same seed, the same bits on every x86-64 machine.
pin_cpu_kernels()
