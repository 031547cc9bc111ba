"""Evaluation episodes of a vector env, on one core or split over forked workers.

:meth:`semdp.algos.base.Algorithm.evaluate` runs a fixed quota of episodes per sub-env (so
short episodes are not over-represented) with the mean action. Each sub-env's episodes start
from its own seed (``seed + i``, as a vector reset with an integer seed gives), so the sub-envs
can be shared out: ``workers=2`` forks a helper (:mod:`solvers.workers`) that runs
the second half of the sub-envs while this process runs the first. The layouts are the same
for any split; the policy's forward pass then sees smaller batches, whose floating-point
results may differ in the last bits (as for any change of the evaluation's vector size), so a
chaotic episode can end differently: the numbers are reproducible for a given ``workers``, not
across values of it. Results are ordered by (sub-env, episode) before they are averaged. The
SEMDP envs' counters (plans, timings) of the helper's sub-envs are recorded with this process's
copies as work done elsewhere (step counts and the mean plan time include them; the wall-time
split, which the helper overlapped, does not). Splitting needs ``fork`` and a
vector env built like ``SyncVectorEnv`` (a list ``envs`` of sub-envs); otherwise the episodes
run here.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from semdp.common.vector_stepping import stepper_for
from solvers.workers import Helper, fork_available

#: One finished episode: (sub-env index, episode number in that sub-env, return, cost,
#: success or None).
EpisodeResult = tuple[int, int, float, float, "float | None"]
Policy = Callable[[npt.NDArray[Any]], npt.NDArray[Any]]
#: Name of the sub-env method giving its counters (e.g. the SEMDP wrapper's timings).
COUNTERS = "counters"
#: Name of the sub-env method adding counters measured elsewhere.
ADD_COUNTERS = "add_counters"


def episode_quota(episodes: int, num_envs: int) -> list[int]:
    """Episodes per sub-env: ``episodes`` shared out, the first sub-envs taking the remainder."""
    return [episodes // num_envs + (i < episodes % num_envs) for i in range(num_envs)]


def worker_groups(quota: Sequence[int], workers: int) -> list[list[int]]:
    """Contiguous groups of sub-envs with work, at most ``workers`` of them, each with about
    the same number of episodes."""
    busy = [i for i, q in enumerate(quota) if q > 0]
    workers = max(1, min(int(workers), len(busy)))
    total = sum(quota)
    groups: list[list[int]] = [[] for _ in range(workers)]
    done = 0
    for i in busy:
        # the group whose share of the episodes this sub-env's first episode falls into
        groups[min(workers - 1, done * workers // max(total, 1))].append(i)
        done += quota[i]
    return [g for g in groups if g]


def run_episodes(
    envs: gym.vector.VectorEnv,
    policy: Policy,
    seeds: int | list[int],
    quota: Sequence[int],
    indices: Sequence[int],
) -> list[EpisodeResult]:
    """Run ``quota[indices[j]]`` episodes on sub-env ``j`` of ``envs``, reset with ``seeds``;
    the results carry the global sub-env index ``indices[j]``."""
    obs, _ = envs.reset(seed=seeds)
    stepper = stepper_for(envs)
    n = envs.num_envs
    left = np.array([quota[i] for i in indices])
    count = np.zeros(n, dtype=np.int64)
    ret, cost = np.zeros(n), np.zeros(n)
    results: list[EpisodeResult] = []
    try:
        while left.sum() > 0:
            step = stepper.step(policy(obs))
            obs = step.obs
            ret += step.rewards
            cost += step.costs
            ended = np.flatnonzero(step.ended)
            successes = step.successes if len(ended) else {}
            for j in ended:
                if left[j] > 0:
                    left[j] -= 1
                    results.append((int(indices[j]), int(count[j]), float(ret[j]),
                                    float(cost[j]), successes[j]))
                    count[j] += 1
                ret[j] = cost[j] = 0.0
    finally:
        stepper.close()
    return results


def subset_env(envs: gym.vector.VectorEnv, indices: Sequence[int]) -> gym.vector.VectorEnv | None:
    """A vector env of the same class over the sub-envs ``indices`` (the same objects), or None
    where ``envs`` is not built like ``SyncVectorEnv``. Not to be closed: it shares sub-envs."""
    subs = getattr(envs, "envs", None)
    if not isinstance(subs, (list, tuple)) or not all(isinstance(e, gym.Env) for e in subs):
        return None
    try:
        return type(envs)([lambda e=subs[i]: e for i in indices],  # type: ignore[call-arg]
                          copy=getattr(envs, "copy", True),
                          autoreset_mode=envs.autoreset_mode)
    except TypeError:  # another constructor signature
        return None


def _counters(env: gym.Env) -> dict[str, float] | None:
    try:
        return dict(env.get_wrapper_attr(COUNTERS)())
    except AttributeError:
        return None


def _child_job(
    envs: gym.vector.VectorEnv, policy: Policy, seed: int, quota: list[int], indices: list[int]
) -> Callable[[object], Any]:
    """The helper's handler: the episodes of ``indices`` and its sub-envs' counter deltas."""

    def handle(_: object) -> tuple[list[EpisodeResult], list[dict[str, float] | None]]:
        sub = subset_env(envs, indices)
        assert sub is not None
        before = [_counters(e) for e in sub.envs]
        results = run_episodes(sub, policy, [seed + i for i in indices], quota, indices)
        deltas = []
        for start, env in zip(before, sub.envs, strict=True):
            end = _counters(env)
            deltas.append(None if start is None or end is None else
                          {k: end[k] - start.get(k, 0.0) for k in end})
        return results, deltas

    return handle


def evaluate_episodes(
    envs: gym.vector.VectorEnv,
    policy: Policy,
    episodes: int,
    seed: int,
    workers: int = 1,
) -> list[EpisodeResult]:
    """``episodes`` episodes (a fixed quota per sub-env), ordered by (sub-env, episode).

    Args:
        envs: the evaluation vector env.
        policy: observations (batch) -> env actions.
        episodes: how many.
        seed: the vector reset seed (sub-env ``i`` starts from ``seed + i``).
        workers: processes to share the sub-envs between (this one and forked helpers).
    """
    quota = episode_quota(episodes, envs.num_envs)
    groups = worker_groups(quota, workers) if workers > 1 and fork_available() else []
    own = subset_env(envs, groups[0]) if len(groups) > 1 else None
    if own is None:
        results = run_episodes(envs, policy, seed, quota, range(envs.num_envs))
        return sorted(results, key=lambda r: r[:2])
    helpers: list[tuple[list[int], Helper]] = []
    try:
        for group in groups[1:]:
            worker = Helper.fork(_child_job(envs, policy, seed, quota, group), "semdp-eval")
            worker.send("run")
            helpers.append((group, worker))
        results = run_episodes(own, policy, [seed + i for i in groups[0]], quota, groups[0])
        for group, worker in helpers:
            payload, deltas = worker.receive()
            results.extend(payload)
            for i, delta in zip(group, deltas, strict=True):
                if delta is not None:
                    envs.envs[i].get_wrapper_attr(ADD_COUNTERS)(delta)  # type: ignore[attr-defined]
    finally:
        for _, worker in helpers:
            worker.close()
    return sorted(results, key=lambda r: r[:2])


def summarize(results: Sequence[EpisodeResult]) -> dict[str, Any]:
    """``{"episodes", "return_mean", "return_std", "cost_mean", "cost_std", "success_rate"}``
    (``success_rate`` None when no episode reported success)."""
    rets = np.array([r[2] for r in results])
    costs = np.array([r[3] for r in results])
    succ = [r[4] for r in results if r[4] is not None]
    return {
        "episodes": len(results),
        "return_mean": float(rets.mean()),
        "return_std": float(rets.std()),
        "cost_mean": float(costs.mean()),
        "cost_std": float(costs.std()),
        "success_rate": float(np.mean(succ)) if succ else None,
    }
