"""Stepping a gymnasium ``SyncVectorEnv`` (``AutoresetMode.SAME_STEP``) without merging infos.

``SyncVectorEnv.step`` merges every sub-env's info dict into per-key arrays, which costs more
than a step of the Safety Gym replica; the algorithms only read the step cost, the true last
observation of an episode that ended and its success flag. :class:`VectorStepper` makes the same
calls on the same sub-envs in the same order (``step(actions[i])``, then ``reset()`` without
arguments where an episode ended), so the sub-envs evolve exactly as under
``SyncVectorEnv.step``, and returns a :class:`StepResult` with what ``SyncVectorEnv.step`` read
by :func:`merged_step_result` would give. Other vector envs go through their own ``step``
(:class:`MergedInfoStepper`); :func:`stepper_for` picks.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

SUCCESS_KEYS: tuple[str, ...] = ("success", "is_success")


@dataclass
class StepResult:
    """One vector step.

    Attributes:
        obs: next observations ``(n, *obs_shape)``; where an episode ended, the first
            observation of the next one.
        rewards, terminated, truncated: per sub-env.
        costs: ``info["cost"]`` of the step (0 where a sub-env reports none).
        final_obs: sub-env index -> the true last observation of the episode that ended.
        final_infos: sub-env index -> the ``success``/``is_success`` entries of the last info
            of the episode that ended (the only entries the algorithms read).
    """

    obs: np.ndarray
    rewards: npt.NDArray[np.float64]
    terminated: npt.NDArray[np.bool_]
    truncated: npt.NDArray[np.bool_]
    costs: npt.NDArray[np.float64]
    final_obs: dict[int, np.ndarray] = field(default_factory=dict)
    final_infos: dict[int, dict[str, Any]] = field(default_factory=dict)

    @property
    def ended(self) -> npt.NDArray[np.bool_]:
        """Episode ended by termination or time-out."""
        return np.logical_or(self.terminated, self.truncated)

    @property
    def successes(self) -> dict[int, float | None]:
        """Sub-env index -> success flag of the episode that ended (:func:`success_flags`)."""
        return success_flags(self.final_infos)

    @classmethod
    def concatenate(cls, first: StepResult, second: StepResult) -> StepResult:
        """The results of two groups of sub-envs, ``second``'s indices after ``first``'s."""
        offset = len(first.rewards)
        return cls(
            np.concatenate([first.obs, second.obs]),
            np.concatenate([first.rewards, second.rewards]),
            np.concatenate([first.terminated, second.terminated]),
            np.concatenate([first.truncated, second.truncated]),
            np.concatenate([first.costs, second.costs]),
            {**first.final_obs, **{offset + i: o for i, o in second.final_obs.items()}},
            {**first.final_infos, **{offset + i: f for i, f in second.final_infos.items()}},
        )

    def final_observations(self) -> np.ndarray:
        """``obs`` with the rows of ended episodes replaced by their true last observation."""
        out = np.array(self.obs, copy=True)
        for i, final in self.final_obs.items():
            out[i] = final
        return out


def success_flags(final_infos: Mapping[int, Mapping[str, Any]]) -> dict[int, float | None]:
    """Success of each ended episode as gymnasium's merged ``infos["final_info"]`` reports it.

    The key is ``"success"`` when any episode ending in this step reports it, else
    ``"is_success"``; an ended episode without the key then counts as 0 (the merged array's
    default), and every flag is ``None`` when no ended episode has the key.
    """
    key = next((k for k in SUCCESS_KEYS if any(k in info for info in final_infos.values())), None)
    if key is None:
        return dict.fromkeys(final_infos)
    return {i: float(info.get(key, 0.0)) for i, info in final_infos.items()}


def _success_entries(info: Mapping[str, Any]) -> dict[str, Any]:
    return {k: info[k] for k in SUCCESS_KEYS if k in info}


class VectorStepper:
    """Steps the sub-envs of a SAME_STEP ``SyncVectorEnv`` in this process.

    Args:
        envs: the vector env; its sub-envs are stepped directly (its own step buffers are not
            updated, which SAME_STEP autoreset never reads).
        indices: the sub-envs to step (all by default); ``actions`` and the result have one row
            per index, in this order.
    """

    def __init__(self, envs: gym.vector.SyncVectorEnv, indices: range | None = None) -> None:
        if envs.autoreset_mode != gym.vector.AutoresetMode.SAME_STEP:
            raise ValueError(f"VectorStepper needs AutoresetMode.SAME_STEP, got "
                             f"{envs.autoreset_mode}")
        self.envs = envs
        self.indices = range(envs.num_envs) if indices is None else indices
        space = envs.single_observation_space
        self._obs_shape = (len(self.indices), *space.shape)
        self._obs_dtype = space.dtype

    def step(self, actions: np.ndarray) -> StepResult:
        """Step every sub-env with its row of ``actions``; reset those whose episode ended."""
        subs = [self.envs.envs[i] for i in self.indices]
        n = len(subs)
        obs = np.empty(self._obs_shape, dtype=self._obs_dtype)
        rewards = np.zeros(n, dtype=np.float64)
        terminated = np.zeros(n, dtype=np.bool_)
        truncated = np.zeros(n, dtype=np.bool_)
        costs = np.zeros(n, dtype=np.float64)
        final_obs: dict[int, np.ndarray] = {}
        final_infos: dict[int, dict[str, Any]] = {}
        for i, env in enumerate(subs):
            o, reward, term, trunc, info = env.step(actions[i])
            rewards[i], terminated[i], truncated[i] = reward, term, trunc
            if "cost" in info:
                costs[i] = float(info["cost"])
            if term or trunc:
                final_obs[i], final_infos[i] = o, _success_entries(info)
                o, _ = env.reset()
            obs[i] = o
        return StepResult(obs, rewards, terminated, truncated, costs, final_obs, final_infos)

    def close(self) -> None:
        """Nothing to release (the vector env stays open)."""


def merged_step_result(obs: Any, rewards: Any, terminated: Any, truncated: Any,
                       infos: Mapping[str, Any]) -> StepResult:
    """What a SAME_STEP vector env's ``step`` returned, as a :class:`StepResult`: the step costs
    (``info["cost"]``; an ended episode's from its final info), the true last observations and
    the success entries of the episodes that ended, read from the merged infos."""
    ended = np.logical_or(terminated, truncated)
    n = len(ended)
    costs = np.zeros(n, dtype=np.float64)
    if "cost" in infos:
        mask = infos.get("_cost", np.ones(n, dtype=bool))
        costs[mask] = np.asarray(infos["cost"], dtype=np.float64)[mask]
    final_obs: dict[int, np.ndarray] = {}
    final_infos: dict[int, dict[str, Any]] = {}
    if np.any(ended):
        final_info = infos["final_info"]
        for i in np.flatnonzero(ended):
            final_obs[int(i)] = infos["final_obs"][i]
            costs[i] = float(final_info["cost"][i])
            final_infos[int(i)] = {k: final_info[k][i] for k in SUCCESS_KEYS if k in final_info}
    return StepResult(np.asarray(obs), np.asarray(rewards, dtype=np.float64),
                      np.asarray(terminated), np.asarray(truncated), costs, final_obs,
                      final_infos)


class MergedInfoStepper:
    """Any SAME_STEP vector env through its own ``step``, read from the merged infos."""

    def __init__(self, envs: gym.vector.VectorEnv) -> None:
        self.envs = envs

    def step(self, actions: np.ndarray) -> StepResult:
        """``envs.step(actions)`` as a :class:`StepResult` (:func:`merged_step_result`)."""
        return merged_step_result(*self.envs.step(actions))

    def close(self) -> None:
        """Nothing to release (the vector env stays open)."""


def stepper_for(envs: gym.vector.VectorEnv) -> VectorStepper | MergedInfoStepper:
    """:class:`VectorStepper` for a SAME_STEP ``SyncVectorEnv``, else :class:`MergedInfoStepper`
    (also for subclasses of ``SyncVectorEnv``, whose own ``step`` may do more, and for vector
    envs built like it, e.g. the SEMDP lockstep env with its batched follower)."""
    if (type(envs) is gym.vector.SyncVectorEnv
            and envs.autoreset_mode == gym.vector.AutoresetMode.SAME_STEP):
        return VectorStepper(envs)
    return MergedInfoStepper(envs)
