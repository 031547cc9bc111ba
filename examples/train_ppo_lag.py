"""Train PPO-Lagrangian on PointGoal1 from Python for two epochs, then evaluate it (the
algorithm of thesis §2.3 with the Adam multiplier; no Hydra needed).

    python examples/train_ppo_lag.py           # writes runs/ppo_lag_point_goal1/ here
"""

from semdp.algos import PPOLag
from semdp.algos.lagrangian import Lagrange
from semdp.envs import make_vec_env

envs = make_vec_env({"id": "sims/SafetyPointGoal1-v0", "num_envs": 4}, seed=0)
eval_envs = make_vec_env({"id": "sims/SafetyPointGoal1-v0", "num_envs": 2}, seed=1)
agent = PPOLag(envs, eval_envs, seed=0, steps_per_epoch=4000,
               lagrange=Lagrange(cost_limit=25.0))
metrics = agent.learn(total_steps=8000, run_dir="runs/ppo_lag_point_goal1",
                      final_eval_episodes=2)
print(f"{metrics['status']} after {metrics['env_steps']} env steps: evaluation return "
      f"{metrics['eval']['return_mean']:.2f}, cost {metrics['eval']['cost_mean']:.1f}")
