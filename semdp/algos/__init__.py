"""Safe RL algorithms (docs/training.md, "Algorithms and recorded choices"): PPO, PPO-Lag,
SP-PPO-Lag, TRPO-Lag, CPO, SAC.

Hierarchy (at most two levels below the shared bases): ``OnPolicyAlgorithm -> PPO -> PPOLag ->
SPPPOLag``, ``OnPolicyAlgorithm -> TRPO -> TRPOLag / CPO``, ``Algorithm -> SAC``. Everything else
is composition: :mod:`semdp.algos.lagrangian`, :mod:`semdp.algos.gae`, the speed-ups behind
their seams: derivative kernels (:mod:`semdp.algos.kernels`) and helper processes
(:mod:`semdp.algos.helpers`), handed to the on-policy algorithms by :mod:`semdp.algos.speedups`, ...
"""

from semdp.algos.base import Algorithm
from semdp.algos.cpo import CPO
from semdp.algos.on_policy import OnPolicyAlgorithm
from semdp.algos.ppo import PPO, PPOLag
from semdp.algos.sac import SAC
from semdp.algos.sp_ppo_lag import SPPPOLag
from semdp.algos.trpo import TRPO
from semdp.algos.trpo_lag import TRPOLag

__all__ = [
    "CPO", "PPO", "SAC", "TRPO", "Algorithm", "OnPolicyAlgorithm", "PPOLag", "SPPPOLag", "TRPOLag",
]
