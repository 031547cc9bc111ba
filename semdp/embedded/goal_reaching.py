"""Training environment and weights I/O of the goal-reaching follower (thesis §3.5.3, App. B.2.4).

The follower is a goal-conditioned policy trained obstacle-free: a goal is sampled uniformly
d_min..2 d_min away from the robot (to match the tracking points it sees at run time), the
reward is the decrease of the distance to it (Eq. 3.9), and a goal reached within
``success_radius`` is replaced by a fresh one (the episode goes on), as a tracking point moves
ahead along a plan.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

from semdp.embedded.follower import follower_observation

#: LiDAR channels of obstacles (the "SAC + PPO Lag" low level sees them; the box and the goal
#: LiDAR are task channels and are left out).
OBSTACLE_LIDARS: tuple[str, ...] = ("hazards_lidar", "vases_lidar", "pillars_lidar",
                                    "gremlins_lidar")


def sensor_names(obs_slices: dict[str, slice], include_lidar: bool = False) -> list[str]:
    """The robot's own sensors (every observation part that is not a LiDAR), followed by the
    obstacle LiDAR channels when ``include_lidar``."""
    names = [name for name in obs_slices if not name.endswith("_lidar")]
    if include_lidar:
        names += [name for name in obs_slices if name in OBSTACLE_LIDARS]
    return names


class GoalReachingEnv(gym.Wrapper):
    """Goal-conditioned reaching task on an obstacle-free ``sims`` env (App. B.2.4).

    Observation: the robot sensors of the inner env followed by the goal in the robot frame
    (2,). Reward: ``||p_{t-1} - g|| - ||p_t - g||`` (Eq. 3.9). ``info["success"]`` is 1 on the
    step a goal is reached (it is then resampled); ``info["cost"]`` is 0.

    Args:
        env: an obstacle-free ``sims`` env, e.g. ``sims/SafetyPointGoal0-v0``.
        d_min: minimum goal distance (0.2 m); goals are drawn in [d_min, 2 d_min].
        success_radius: distance at which a goal counts as reached.
        episode_steps: low-level steps per episode (truncation).
        keep_cost: report the inner env's cost (and its terms) instead of 0 -- the low level of
            the "SAC + PPO Lag" ablation is trained with PPO-Lag in the obstacle env.
        include_lidar: append the obstacle LiDAR channels to the observation (same ablation).
        reward_scale: multiplies Eq. 3.9 (the per-step distance decrease is ~0.01 m, too small
            next to SAC's entropy bonus; the optimum is unchanged): 10, the follower's training
            setting (``conf/env/follower.yaml``).
    """

    def __init__(
        self,
        env: gym.Env,
        d_min: float = 0.2,
        success_radius: float = 0.05,
        episode_steps: int = 200,
        reward_scale: float = 10.0,
        keep_cost: bool = False,
        include_lidar: bool = False,
    ) -> None:
        super().__init__(env)
        if not 0 < success_radius < d_min:
            raise ValueError(
                f"need 0 < success_radius < d_min, got success_radius={success_radius}, "
                f"d_min={d_min}"
            )
        if not reward_scale > 0:
            raise ValueError(f"reward_scale must be > 0, got {reward_scale}")
        if episode_steps < 1:
            raise ValueError(f"episode_steps must be >= 1, got {episode_steps}")
        base = env.unwrapped
        self.sensor_names = sensor_names(base.obs_slices, include_lidar)
        self.keep_cost = bool(keep_cost)
        self._slices = [base.obs_slices[name] for name in self.sensor_names]
        dim = sum(s.stop - s.start for s in self._slices) + 2
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(dim,), dtype=np.float32)
        self.d_min = float(d_min)
        self.success_radius = float(success_radius)
        self.episode_steps = int(episode_steps)
        self.reward_scale = float(reward_scale)
        self.goal = np.zeros(2)
        self._t = 0
        self._distance = 0.0
        self._goal_rng = np.random.default_rng()

    def _observe(self, obs: np.ndarray) -> np.ndarray:
        base = self.env.unwrapped
        sensors = np.concatenate([obs[s] for s in self._slices])
        return follower_observation(sensors, base.robot_position, base.robot_heading, self.goal)

    def _sample_goal(self) -> None:
        base = self.env.unwrapped
        radius = self._goal_rng.uniform(self.d_min, 2.0 * self.d_min)
        angle = self._goal_rng.uniform(-math.pi, math.pi)
        self.goal = np.asarray(base.robot_position, dtype=np.float64) + radius * np.array(
            [math.cos(angle), math.sin(angle)]
        )
        self._distance = float(np.linalg.norm(base.robot_position - self.goal))

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset the robot and draw the first goal."""
        obs, info = self.env.reset(seed=seed, options=options)
        if seed is not None:  # goals get their own stream, so the inner layout is unaffected
            self._goal_rng = np.random.default_rng([seed, 0x60A1])
        self._t = 0
        self._sample_goal()
        return self._observe(obs), info

    def step(self, action):
        """One low-level step; reward is the decrease of the goal distance (Eq. 3.9)."""
        obs, _, terminated, truncated, inner_info = self.env.step(action)
        self._t += 1
        base = self.env.unwrapped
        distance = float(np.linalg.norm(base.robot_position - self.goal))
        reward = self.reward_scale * (self._distance - distance)
        self._distance = distance
        success = distance < self.success_radius
        if success:
            self._sample_goal()
        truncated = truncated or self._t >= self.episode_steps
        info = {"cost": 0.0, "success": float(success), "goal_distance": distance}
        if self.keep_cost:
            info.update({k: v for k, v in inner_info.items() if k.startswith("cost")})
        return self._observe(obs), reward, terminated, truncated, info
