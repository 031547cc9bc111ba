"""Play evaluation episodes (the mean action, or the sampled one) and summarise them.

Per episode: reset seed, return, cost, length (low-level env steps) and, at episode end,
``success`` when the env reports it. For a Safety-Embedded MDP run also the plan statistics its
wrapper reports in ``info`` (docs/semdp.md, "The wrapper, the planner and the
certificate"): high-level steps (plans),
fallbacks (``plan_fallback``: the stationary plan replaced an uncertified one), escapes
(``plan_escape``: the start was inside eps'), rescues (``plan_rescued``: IPOPT re-solved a plan
LM could not certify), the smallest certified clearance (``plan_min_clearance``) and, with the
low-level safety filter on, the low-level commands it replaced (``shield_interventions``), of
which by an escape action rather than braking (``shield_escapes``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from semdp.embedded.perception import perceive_obstacles
from semdp.evaluation.environment import EvaluationEnv


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def play_episode(algo: Any, ev: EvaluationEnv, seed: int, record: bool = False,
                 sampled: bool = False) -> dict[str, Any]:
    """One episode from ``reset(seed=seed)``; ``record`` fills ``ev.recorder.frames``.

    ``sampled``: act with the stochastic policy's samples (torch's generator seeded with
    ``seed``, so an episode replays exactly) instead of its mean action.
    """
    if sampled:
        torch.manual_seed(seed)
    if ev.recorder is not None:
        ev.recorder.active = record
        ev.recorder.frames = []
    obs, _ = ev.env.reset(seed=seed)
    semdp = ev.semdp
    ret = cost = 0.0
    length = steps = fallbacks = escapes = rescues = shielded = 0
    shield = getattr(semdp, "shield", None)
    escaped_before = shield.stats.escaped if shield is not None else 0
    min_clearance = math.inf
    success = None
    while True:
        if record and ev.recorder is not None and semdp is not None:
            base = semdp.env.unwrapped
            ev.recorder.perceived = perceive_obstacles(base, np.asarray(obs), semdp.perception,
                                                       semdp.obstacle_kinds)
            ev.recorder.clearance = getattr(semdp.planner, "clearance", None)
        action = algo.predict(np.asarray(obs)[None], deterministic=not sampled)[0]
        obs, reward, terminated, truncated, info = ev.env.step(action)
        ret += float(reward)
        cost += float(info["cost"])
        steps += 1
        length += int(info.get("low_level_steps", 1))
        if semdp is not None:
            fallbacks += bool(info.get("plan_fallback"))
            escapes += bool(info.get("plan_escape"))
            rescues += bool(info.get("plan_rescued"))
            shielded += int(info.get("shield_interventions", 0))
            min_clearance = min(min_clearance, float(info.get("plan_min_clearance", math.inf)))
        if terminated or truncated:
            for key in ("success", "is_success"):
                if key in info:
                    success = float(info[key])
            break
    episode: dict[str, Any] = {"seed": int(seed), "return": ret, "cost": cost, "length": length,
                               "success": success}
    if semdp is not None:
        episode.update(high_level_steps=steps, plan_fallbacks=fallbacks, plan_escapes=escapes,
                       plan_rescues=rescues, plan_min_clearance=_finite(min_clearance),
                       shield_interventions=shielded,
                       shield_escapes=(shield.stats.escaped - escaped_before
                                       if shield is not None else 0))
    return episode


def summarise(episodes: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Means over the episodes (the ``eval`` block of ``metrics.json``)."""
    rets = np.array([e["return"] for e in episodes], dtype=np.float64)
    costs = np.array([e["cost"] for e in episodes], dtype=np.float64)
    succ = [e["success"] for e in episodes if e["success"] is not None]
    out: dict[str, Any] = {
        "episodes": len(episodes),
        "return_mean": float(rets.mean()), "return_std": float(rets.std()),
        "cost_mean": float(costs.mean()), "cost_std": float(costs.std()),
        "length_mean": float(np.mean([e["length"] for e in episodes])),
        "success_rate": float(np.mean(succ)) if succ else None,
        "episodes_with_cost": int(np.sum(costs > 0)),
    }
    if episodes and "high_level_steps" in episodes[0]:
        plans = int(sum(e["high_level_steps"] for e in episodes))
        low = max(int(sum(e["length"] for e in episodes)), 1)
        shielded = int(sum(e.get("shield_interventions", 0) for e in episodes))
        shield_escapes = int(sum(e.get("shield_escapes", 0) for e in episodes))
        clearances = [e["plan_min_clearance"] for e in episodes
                      if e["plan_min_clearance"] is not None]
        out.update(
            plans=plans,
            plan_fallbacks=int(sum(e["plan_fallbacks"] for e in episodes)),
            plan_escapes=int(sum(e["plan_escapes"] for e in episodes)),
            plan_rescues=int(sum(e["plan_rescues"] for e in episodes)),
            plan_fallback_rate=sum(e["plan_fallbacks"] for e in episodes) / max(plans, 1),
            plan_escape_rate=sum(e["plan_escapes"] for e in episodes) / max(plans, 1),
            plan_rescue_rate=sum(e["plan_rescues"] for e in episodes) / max(plans, 1),
            shield_interventions=shielded,
            shield_rate=shielded / low,
            shield_escape_rate=shield_escapes / low,
            plan_min_clearance=min(clearances) if clearances else None,
            plan_min_clearance_mean=float(np.mean(clearances)) if clearances else None,
        )
    return out
