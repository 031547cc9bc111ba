"""The env ``semdp-eval`` plays: the run's evaluation env (``env.eval_wrapper``, else
``env.wrapper``), optionally the transfer variant, optionally rendered through a
:class:`~semdp.rendering.recorder.FrameRecorder` put directly around the simulator."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
from omegaconf import DictConfig

from semdp.embedded.timing import find_semdp
from semdp.embedded.wrapper import SafetyEmbeddedEnv
from semdp.envs import apply_wrapper, make_env, plain_wrapper
from semdp.evaluation.errors import EvalError
from semdp.evaluation.loading import env_config
from semdp.evaluation.transfer_variant import DEFAULT_SIZES, transfer_env_config
from semdp.rendering.recorder import FrameRecorder

#: The transfer variant's settings (semdp/evaluation/transfer_variant.py, Table 3.2 stand-in).
TRANSFER_NOISE_STD = 0.05
TRANSFER_EPISODE_STEPS = 600


@dataclass
class EvaluationEnv:
    """The env, its SEMDP wrapper (``None`` for a baseline) and its recorder (``None``)."""

    env: gym.Env
    semdp: SafetyEmbeddedEnv | None
    recorder: FrameRecorder | None
    settings: dict[str, Any]


def _recorded(env: gym.Env, every: int, inner: Any, holder: list[FrameRecorder]) -> gym.Env:
    recorder = FrameRecorder(env, every=every)
    holder.append(recorder)
    return apply_wrapper(recorder, inner)


def build_evaluation_env(
    cfg: DictConfig, variant: str | None, video_size: int | None, video_every: int
) -> EvaluationEnv:
    """One evaluation env of ``cfg``; ``video_size`` set = rendered and recorded.

    Raises:
        EvalError: ``variant=transfer`` on a run that is not a sims Safety Push task.
    """
    env_cfg = env_config(cfg)
    settings: dict[str, Any] = {"variant": variant}
    if variant == "transfer":
        try:
            env_cfg = transfer_env_config(env_cfg, DEFAULT_SIZES, TRANSFER_NOISE_STD,
                                          TRANSFER_EPISODE_STEPS)
        except ValueError as exc:
            raise EvalError(f"variant=transfer: {exc}") from None
        settings.update(sizes=dict(DEFAULT_SIZES), noise_std=TRANSFER_NOISE_STD,
                        episode_steps=TRANSFER_EPISODE_STEPS)
    spec = env_cfg.get("eval_wrapper")
    inner = plain_wrapper(spec if spec is not None else env_cfg.get("wrapper"))
    kwargs = dict(env_cfg.get("kwargs") or {})
    holder: list[FrameRecorder] = []
    wrapper: Any = inner
    if video_size is not None:
        kwargs["render_mode"] = "rgb_array"
        if str(env_cfg["id"]).startswith("sims/Safety"):
            kwargs["render_size"] = int(video_size)
        wrapper = functools.partial(_recorded, every=video_every, inner=inner, holder=holder)
    env = make_env(str(env_cfg["id"]), kwargs, wrapper, bool(env_cfg.get("add_zero_cost")))
    return EvaluationEnv(env, find_semdp(env), holder[0] if holder else None, settings)
