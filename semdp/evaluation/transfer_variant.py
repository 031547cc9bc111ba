"""The transfer variant of ``semdp-eval variant=transfer``: a simulated stand-in for the
real-robot transfer experiment (thesis §3.6.4, Table 3.2).

**Simulated, not a real robot.** The thesis trains in simulation, changes object sizes and the
robot shape to match a Franka pushing set-up, and runs the policy without fine-tuning on 10
layouts (success = box pushed into the goal within 60 time steps). Here the "real" side is
another simulation: the same ``sims`` Push task with

- changed object sizes (``sizes``: smaller hazard / pillar / box, a larger goal, like Fig. 3.4),
- a changed robot shape (``sizes["robot_scale"]`` = 1.3: the Point's collision sphere 0.1 ->
  0.13 m and its nose tip 0.15 -> 0.195 m; mass, inertia and actuator response stay the
  trained ones, see :data:`DEFAULT_SIZES`),
- Gaussian observation noise on every observation entry (:class:`ObservationNoise`),
- short episodes (``episode_steps`` low-level steps; default 600 = 60 SEMDP decisions of k = 10
  steps, the same physical time for every method), ended early on success
  (:class:`SuccessOnGoal`),
- 10 fixed layouts: sub-env ``i`` is reset once with seed ``LAYOUT_SEED + i`` (the same layouts
  for every method and training seed).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from semdp.envs import apply_wrapper, plain_wrapper

#: First reset seed of the fixed evaluation layouts.
LAYOUT_SEED = 20_000
#: Real-robot-like object sizes (m): small hazard and pillar, smaller box, large goal; and a
#: 1.3x robot footprint (``robot_scale``, a factor on the collision shapes about the root).
#: Why 1.3: a real pusher (the thesis uses a Franka set-up) is not the simulated sphere + nose,
#: and a 30 % larger footprint is a mismatch of the same relative size as the object changes
#: (pillar and box -25 %, goal +50 %). It makes the robot touch the box and pillars 4.5 cm
#: earlier at the nose (tip 0.195 m) while staying well inside the agent's placement keepout
#: (0.4 m), so the fixed layouts never start in contact. Only the shape changes: the speed and
#: yaw response are the trained ones (sims keeps the robot's mass and inertia).
DEFAULT_SIZES: dict[str, float] = {
    "hazard_radius": 0.2, "pillar_radius": 0.15, "box_half": 0.15, "goal_size": 0.45,
    "robot_scale": 1.3,
}


class ObservationNoise(gym.ObservationWrapper):
    """Adds N(0, ``std``^2) noise to every observation entry (sensor and LiDAR noise), clipped
    into the observation space's bounds (LiDAR readings stay in [0, 1]).

    The noise generator is reseeded by ``reset(seed=...)`` so evaluations are reproducible.
    """

    def __init__(self, env: gym.Env, std: float) -> None:
        super().__init__(env)
        if not std >= 0:
            raise ValueError(f"observation noise std must be >= 0, got {std}")
        self.std = float(std)
        self._rng = np.random.default_rng(0)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset the env (and the noise generator when a seed is given)."""
        if seed is not None:
            self._rng = np.random.default_rng(seed + 1)
        return super().reset(seed=seed, options=options)

    def observation(self, observation: Any) -> Any:
        """The observation plus Gaussian noise, in the observation's dtype."""
        obs = np.asarray(observation)
        if self.std == 0.0:
            return obs
        noisy = obs + self._rng.normal(0.0, self.std, size=obs.shape)
        space = self.observation_space
        if isinstance(space, gym.spaces.Box):
            noisy = np.clip(noisy, space.low, space.high)
        return noisy.astype(obs.dtype)


class SuccessOnGoal(gym.Wrapper):
    """Ends the episode when the box reaches the goal (``info["goal_met"]``).

    ``info["success"]`` is 1.0 on that step and 0.0 on a time-out, so
    :meth:`Algorithm.evaluate` reports the success rate.
    """

    def step(self, action: Any):
        """Step; terminate on success and report ``success`` at the episode end."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        if info.get("goal_met"):
            terminated, info["success"] = True, 1.0
        elif terminated or truncated:
            info["success"] = 0.0
        return obs, reward, terminated, truncated, info


def transfer_wrap(
    env: gym.Env, noise_std: float,
    inner: Callable[[gym.Env], gym.Env] | Mapping[str, Any] | None,
) -> gym.Env:
    """noise -> success -> the method's own wrapper (e.g. the SEMDP one), innermost first."""
    return apply_wrapper(SuccessOnGoal(ObservationNoise(env, noise_std)), inner)


def transfer_env_config(
    env_cfg: Mapping[str, Any], sizes: Mapping[str, float], noise_std: float, episode_steps: int
) -> dict[str, Any]:
    """The perturbed evaluation env of a run's env config (see the module docstring).

    Raises:
        ValueError: not a ``sims`` Push env, or ``episode_steps`` < 1.
    """
    env_id = str(env_cfg.get("id", ""))
    if not (env_id.startswith("sims/Safety") and "Push" in env_id):
        raise ValueError(f"the transfer variant needs a sims Safety Push env, got {env_id!r}")
    if episode_steps < 1:
        raise ValueError(f"episode_steps must be >= 1, got {episode_steps}")
    out = dict(env_cfg)
    out["kwargs"] = {**dict(env_cfg.get("kwargs") or {}), "sizes": dict(sizes),
                     "max_episode_steps": int(episode_steps)}
    inner = env_cfg.get("eval_wrapper") or env_cfg.get("wrapper")
    out["eval_wrapper"] = functools.partial(transfer_wrap, noise_std=float(noise_std),
                                            inner=plain_wrapper(inner))
    return out
