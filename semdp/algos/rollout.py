"""One epoch's rollout: act, step, record (the first stage of PPO/TRPO, thesis Eqs. 2.4-2.7).

:class:`LocalCollector` is the plain rollout collector: this process steps every sub-env
(:mod:`semdp.algos.helpers.rollout_helper` is the one that lends part of them to a helper process).
The sampling noise of the epoch is drawn beforehand (``torch.randn(n, act_dim)`` per step is
what ``Normal.sample`` draws; a sample is ``noise * std + mean`` as in ``torch.normal``), so a
rollout split between processes acts exactly as one process would: each evaluates the actor on
the full ``n``-row batch with its own rows in their places (the others zero: a row of a matrix
product depends on that row only, but the kernel chosen depends on the batch shape), and the
critics, the time-out bootstraps and the episode bookkeeping run afterwards on the merged records
(:meth:`semdp.algos.on_policy.OnPolicyAlgorithm.value_rollout`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from torch.distributions import Normal

from semdp.common.networks import GaussianActor
from semdp.common.normalization import RunningNormalizer
from semdp.common.vector_stepping import stepper_for


@dataclass
class RolloutPart:
    """Per-step records of ``k`` sub-envs over ``n_steps`` steps (leading axes ``(t, i)``).

    Attributes:
        raw_obs: observations acted on, as the envs returned them (float64).
        obs: the same normalised, as the actor saw them (float32).
        actions, log_probs: the sampled actions in [-1, 1] units and their log-densities.
        rewards, costs, terminated, truncated: the step results.
        final_obs: ``(t, i)`` -> the last observation of the episode that ended there.
        last_obs: the observations after the last step (the next rollout starts there).
        simulation_s, policy_s: seconds stepping the envs and acting.
    """

    raw_obs: np.ndarray
    obs: np.ndarray
    actions: np.ndarray
    log_probs: np.ndarray
    rewards: np.ndarray
    costs: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    final_obs: dict[tuple[int, int], np.ndarray] = field(default_factory=dict)
    last_obs: np.ndarray | None = None
    simulation_s: float = 0.0
    policy_s: float = 0.0


def noise_for(n_steps: int, num_envs: int, act_dim: int) -> torch.Tensor:
    """The rollout's sampling noise ``(n_steps, num_envs, act_dim)``, drawn from torch's global
    generator one step at a time, as the per-step ``Normal.sample`` calls would."""
    return torch.stack([torch.randn(num_envs, act_dim) for _ in range(n_steps)])


def roll_part(
    actor: GaussianActor,
    normalizer: RunningNormalizer,
    to_env_action: Callable[[Any], np.ndarray],
    stepper: Any,
    rows: range,
    num_envs: int,
    noise: torch.Tensor,
    obs: np.ndarray,
) -> RolloutPart:
    """Act and step the sub-envs ``rows`` of a ``num_envs`` batch for ``len(noise)`` steps.

    Args:
        actor, normalizer, to_env_action: the policy of this epoch.
        stepper: steps exactly the sub-envs ``rows`` (``step(actions) -> StepResult``).
        rows: positions of these sub-envs in the batch.
        num_envs: the batch size the actor is evaluated on.
        noise: ``(n_steps, len(rows), act_dim)`` standard-normal draws of these rows.
        obs: ``(len(rows), obs_dim)`` the current observations.
    """
    perf = time.perf_counter
    n_steps, k = noise.shape[0], len(rows)
    obs_dim, act_dim = obs.shape[1], noise.shape[2]
    whole = k == num_envs
    part = RolloutPart(
        raw_obs=np.zeros((n_steps, k, obs_dim)),
        obs=np.zeros((n_steps, k, obs_dim), dtype=np.float32),
        actions=np.zeros((n_steps, k, act_dim), dtype=np.float32),
        log_probs=np.zeros((n_steps, k), dtype=np.float32),
        rewards=np.zeros((n_steps, k)), costs=np.zeros((n_steps, k)),
        terminated=np.zeros((n_steps, k), dtype=bool), truncated=np.zeros((n_steps, k), dtype=bool),
    )
    batch = np.zeros((num_envs, obs_dim), dtype=np.float32)
    padded_noise = torch.zeros(num_envs, act_dim)
    local = slice(rows.start, rows.stop)
    with torch.inference_mode():
        std = actor.log_std.exp().expand(num_envs, -1)
        for t in range(n_steps):
            t0 = perf()
            part.raw_obs[t] = obs
            normalised = normalizer(obs)
            part.obs[t] = normalised
            if whole:
                x, eps = torch.as_tensor(normalised), noise[t]
            else:
                batch[local] = normalised
                padded_noise[local] = noise[t]
                x, eps = torch.as_tensor(batch), padded_noise
            mean = actor.mean(x)
            actions = eps.clone().mul_(std).add_(mean)  # torch.normal(mean, std) on this noise
            log_probs = Normal(mean, std, validate_args=False).log_prob(actions).sum(-1)
            actions, log_probs = actions[local], log_probs[local]
            part.actions[t], part.log_probs[t] = actions.numpy(), log_probs.numpy()
            env_actions = to_env_action(actions)
            t1 = perf()
            step = stepper.step(env_actions)
            t2 = perf()
            part.rewards[t], part.costs[t] = step.rewards, step.costs
            part.terminated[t], part.truncated[t] = step.terminated, step.truncated
            for i, final in step.final_obs.items():
                part.final_obs[t, i] = final
            obs = np.asarray(step.obs, dtype=np.float64).reshape(k, obs_dim)
            part.policy_s += t1 - t0
            part.simulation_s += t2 - t1
    part.last_obs = obs
    return part


class LocalCollector:
    """The plain rollout collector: every sub-env steps in this process.

    Args:
        actor, normalizer, to_env_action: the algorithm's policy (read at every rollout).
    """

    #: Whether the latest rollout used a helper process (never, here).
    used_helper = False
    #: Whether the envs are meant to step in a helper (``vectorization="async"``/``auto``).
    in_helper = False

    def __init__(
        self,
        actor: GaussianActor,
        normalizer: RunningNormalizer,
        to_env_action: Callable[[Any], np.ndarray],
    ) -> None:
        self.actor, self.normalizer, self.to_env_action = actor, normalizer, to_env_action

    def collect(
        self, envs: Any, obs: np.ndarray, noise: torch.Tensor, seconds: dict[str, float]
    ) -> RolloutPart:
        """Roll out all sub-envs of ``envs`` from ``obs`` with ``noise`` (one row per step)."""
        part = roll_part(self.actor, self.normalizer, self.to_env_action, stepper_for(envs),
                         range(envs.num_envs), envs.num_envs, noise, obs)
        seconds["policy"] += part.policy_s
        seconds["simulation"] += part.simulation_s
        return part

    def snapshot(self, envs: Any) -> Any:
        """The training envs for a checkpoint (all of them are here)."""
        return envs

    def stop(self, fetch: bool) -> None:
        """Nothing to stop (no helper)."""
