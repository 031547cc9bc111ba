"""A vector env that steps its Safety-Embedded MDP sub-envs in lockstep (thesis Alg. 2, §3.5).

``gymnasium``'s ``SyncVectorEnv`` steps one SEMDP env after the other: per env a plan, then k
follower forwards and k simulator steps. :class:`LockstepVectorEnv` runs the same phases of
:class:`~semdp.embedded.wrapper.SafetyEmbeddedEnv` for all sub-envs together -- every env plans,
then for each of the k low-level steps all followers act in one batched forward
(:class:`~semdp.embedded.follower_batch.FollowerBatch`) and each env takes its simulator step
through :meth:`SafetyEmbeddedEnv.low_level_step`, the one place where a low-level action is
finalised. Results, autoreset (``SAME_STEP`` only) and the info dict are those of
``SyncVectorEnv``. Sub-envs with other wrappers above the SEMDP wrapper than the cost checks of
:mod:`semdp.envs` fall back to ``SyncVectorEnv.step``.

Selected by ``env.vector`` in the env config (``conf/loop/pipelined.yaml``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import concatenate, create_empty_array, iterate

from semdp.embedded.follower_batch import FollowerBatch
from semdp.embedded.wrapper import SafetyEmbeddedEnv, Window


def _semdp_below(env: gym.Env) -> SafetyEmbeddedEnv | None:
    """The SEMDP wrapper of ``env`` if only the cost checks of :mod:`semdp.envs` sit above it."""
    from semdp.envs import RequireCost, ZeroCost

    while isinstance(env, RequireCost | ZeroCost):
        env = env.env
    return env if isinstance(env, SafetyEmbeddedEnv) else None


class LockstepVectorEnv(gym.vector.VectorEnv):
    """A vector env whose SEMDP sub-envs plan, follow and simulate window by window together.

    Built like ``SyncVectorEnv`` (and holding one, :attr:`sync`, for reset, rendering and the
    fallback); not a subclass of it, so that steppers specialised to ``SyncVectorEnv``'s
    sub-env loop (:mod:`semdp.common.vector_stepping`) go through this :meth:`step`.

    Args:
        env_fns, copy, observation_mode, autoreset_mode: as ``SyncVectorEnv``.
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        copy: bool = True,
        observation_mode: str = "same",
        autoreset_mode: str | AutoresetMode = AutoresetMode.SAME_STEP,
    ) -> None:
        sync = gym.vector.SyncVectorEnv(env_fns, copy=copy, observation_mode=observation_mode,
                                        autoreset_mode=autoreset_mode)
        self.sync = sync
        self.envs, self.num_envs, self.copy = sync.envs, sync.num_envs, copy
        self.metadata, self.render_mode = sync.metadata, sync.render_mode
        self.autoreset_mode = sync.autoreset_mode
        self.single_action_space, self.action_space = sync.single_action_space, sync.action_space
        self.single_observation_space = sync.single_observation_space
        self.observation_space = sync.observation_space
        self._observations = create_empty_array(self.single_observation_space, n=self.num_envs,
                                                fn=np.zeros)
        found = [_semdp_below(env) for env in self.envs]
        self.semdp_envs: list[SafetyEmbeddedEnv] | None = None
        self.followers: FollowerBatch | None = None
        if self.autoreset_mode == AutoresetMode.SAME_STEP and all(s is not None for s in found):
            self.semdp_envs = [s for s in found if s is not None]
            self.followers = FollowerBatch([s.follower for s in self.semdp_envs])

    @property
    def lockstep(self) -> bool:
        """Whether :meth:`step` runs the sub-envs in lockstep (else it is ``SyncVectorEnv``'s)."""
        return self.semdp_envs is not None

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None):
        """``SyncVectorEnv.reset``."""
        return self.sync.reset(seed=seed, options=options)

    def _windows(self, actions: Any) -> list[Window]:
        """Every env's low-level loop, one batched follower forward per low-level step."""
        assert self.semdp_envs is not None and self.followers is not None
        envs = self.semdp_envs
        windows = [env.begin_window(action)
                   for env, action in zip(envs, iterate(self.action_space, actions), strict=True)]
        active = list(range(self.num_envs))
        while active:
            t0 = time.perf_counter()
            inputs = [envs[i].tracking_target(windows[i]) for i in active]
            low_actions = self.followers.act(active, inputs)
            share = (time.perf_counter() - t0) / len(active)
            still = []
            for i, low_action in zip(active, low_actions, strict=True):
                windows[i].follow_s += share
                if not envs[i].low_level_step(windows[i], low_action):
                    still.append(i)
            active = still
        return windows

    def step(self, actions: Any):
        """One SEMDP step of every sub-env; the returns of ``SyncVectorEnv.step``
        (``AutoresetMode.SAME_STEP``: an ended episode's last observation and info are in
        ``infos["final_obs"]`` / ``infos["final_info"]``, the sub-env is reset at once)."""
        if self.semdp_envs is None:
            return self.sync.step(actions)
        windows = self._windows(actions)
        n = self.num_envs
        env_obs: list[Any] = [None] * n
        rewards = np.zeros(n, dtype=np.float64)
        terminations = np.zeros(n, dtype=np.bool_)
        truncations = np.zeros(n, dtype=np.bool_)
        infos: dict[str, Any] = {}
        for i, (env, window) in enumerate(zip(self.semdp_envs, windows, strict=True)):
            obs, reward, terminated, truncated, env_info = env.end_window(window)
            if "cost" not in env_info:  # what RequireCost checks (never true for SEMDP)
                raise KeyError("SafetyEmbeddedEnv returned no info['cost']")
            env_obs[i], rewards[i], terminations[i], truncations[i] = (
                obs, reward, terminated, truncated)
            if terminated or truncated:
                infos = self._add_info(infos, {"final_obs": obs, "final_info": env_info}, i)
                env_obs[i], env_info = self.envs[i].reset()
            infos = self._add_info(infos, env_info, i)
        self._observations = concatenate(self.single_observation_space, env_obs,
                                         self._observations)
        obs_out = np.copy(self._observations) if self.copy else self._observations
        return obs_out, rewards, terminations, truncations, infos

    def render(self):
        """The sub-envs' frames."""
        return self.sync.render()

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """``SyncVectorEnv.call``."""
        return self.sync.call(name, *args, **kwargs)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """``SyncVectorEnv.get_attr``."""
        return self.sync.get_attr(name)

    def set_attr(self, name: str, values: Any) -> None:
        """``SyncVectorEnv.set_attr``."""
        self.sync.set_attr(name, values)

    def close_extras(self, **kwargs: Any) -> None:
        """Close the sub-envs."""
        self.sync.close(**kwargs)
