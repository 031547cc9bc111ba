"""The command line of ``semdp-eval``: shorthands and ``key=value`` overrides of the saved config.

Arguments use Hydra's override grammar (``key=value``, ``+key=value`` adds a key, lists as
``[1,2]``, quoted strings). A key named in :data:`SHORTHANDS` is an evaluation setting; every
other key is a dotted path into the run's saved (resolved) ``config.yaml``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException

from semdp.embedded.perception import PERCEPTION_MODES
from semdp.evaluation.errors import EvalError

#: Evaluation settings; everything else is a key of the saved config.
SHORTHANDS: dict[str, str] = {
    "episodes": "number of episodes (default 50; variant=transfer: 10 layouts)",
    "seed": "first episode's reset seed; episode i uses seed + i",
    "seeds": "the reset seed of each episode, e.g. [1,2,3]",
    "video": "true: record the first episode (MP4 with imageio-ffmpeg, else GIF)",
    "video_size": "frame side in pixels (Safety Gym envs; default 512)",
    "video_every": "a frame every this many low-level steps (default 2)",
    "planner": "conf/planner name for the evaluation planner (lm, lm_adaptive, ipopt, ...)",
    "clearance": "the evaluation planner's eps' in metres",
    "lambda": "fixed | adaptive: the LM planner's lambda schedule",
    "perception": "lidar | lidar_refined | gt: the evaluation planner's obstacles",
    "variant": "transfer: the perturbed Push variant of semdp/evaluation/transfer_variant.py",
    "actions": "mean (default, as the training runs' evaluations) | sampled: the stochastic "
               "policy's actions, as in training episodes (torch seeded per episode)",
}
LAMBDAS = ("fixed", "adaptive")
VARIANTS = ("transfer",)
ACTIONS = ("mean", "sampled")


@dataclass(frozen=True)
class ConfigOverride:
    """One ``key=value`` (``add``: given as ``+key=value``) for the saved config."""

    key: str
    value: Any
    add: bool = False


@dataclass(frozen=True)
class EvalOptions:
    """What to evaluate and how (see :data:`SHORTHANDS`)."""

    episodes: int | None = None
    seed: int | None = None
    seeds: tuple[int, ...] | None = None
    video: bool = False
    video_size: int = 512
    video_every: int = 2
    planner: str | None = None
    clearance: float | None = None
    lambda_: str | None = None
    perception: str | None = None
    variant: str | None = None
    actions: str = "mean"
    overrides: tuple[ConfigOverride, ...] = ()
    arguments: tuple[str, ...] = field(default=())

    @property
    def changes(self) -> list[str]:
        """The arguments that change the evaluated policy or env (not episodes, seeds, video)."""
        keep = {"planner", "clearance", "lambda", "perception", "variant", "actions"}
        return [a for a in self.arguments
                if a.lstrip("+").split("=", 1)[0] in keep | {o.key for o in self.overrides}]


def _int(key: str, value: Any, low: int, high: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low or (
            high is not None and value > high):
        bounds = f">= {low}" if high is None else f"in [{low}, {high}]"
        raise EvalError(f"{key} must be an integer {bounds}, got {value!r}")
    return value


def _choice(key: str, value: Any, options: tuple[str, ...]) -> str:
    if value not in options:
        raise EvalError(f"{key} must be one of {'|'.join(options)}, got {value!r}")
    return str(value)


def _shorthand(key: str, value: Any) -> tuple[str, Any]:
    """Validated ``(field, value)`` of :class:`EvalOptions` for a shorthand."""
    if key == "episodes":
        return key, _int(key, value, 1)
    if key == "seed":
        return key, _int(key, value, 0)
    if key == "seeds":
        if not isinstance(value, list) or not value:
            raise EvalError(f"seeds must be a non-empty list like [0,1,2], got {value!r}")
        return key, tuple(_int("seeds", v, 0) for v in value)
    if key == "video":
        if not isinstance(value, bool):
            raise EvalError(f"video must be true or false, got {value!r}")
        return key, value
    if key == "video_size":
        return key, _int(key, value, 64, 2048)
    if key == "video_every":
        return key, _int(key, value, 1)
    if key == "planner":
        if not isinstance(value, str) or not value:
            raise EvalError(f"planner must name a conf/planner file, got {value!r}")
        return key, value
    if key == "clearance":
        if isinstance(value, bool) or not isinstance(value, int | float) or not (
                math.isfinite(value) and value >= 0):
            raise EvalError(f"clearance must be a number >= 0 (metres), got {value!r}")
        return key, float(value)
    if key == "lambda":
        return "lambda_", _choice(key, value, LAMBDAS)
    if key == "perception":
        return key, _choice(key, value, PERCEPTION_MODES)
    if key == "actions":
        return key, _choice(key, value, ACTIONS)
    return key, _choice(key, value, VARIANTS)


def parse_arguments(arguments: list[str] | tuple[str, ...]) -> EvalOptions:
    """:class:`EvalOptions` of the command-line overrides.

    Raises:
        EvalError: an argument that is not ``key=value``, a sweep, a deletion, a key given
            twice, a bad shorthand value, or ``seeds`` and ``episodes`` that disagree.
    """
    parser = OverridesParser.create()
    parsed = []
    for text in arguments:
        try:
            parsed.extend(parser.parse_overrides([text]))
        except HydraException:
            raise EvalError(f"cannot read {text!r}: give key=value (Hydra's override "
                            "grammar; quote values with spaces)") from None
    values: dict[str, Any] = {}
    overrides: list[ConfigOverride] = []
    seen: set[str] = set()
    for item, text in zip(parsed, arguments, strict=True):
        key = item.key_or_group
        if item.is_delete() or item.is_sweep_override() or item.package:
            raise EvalError(f"{text!r}: give key=value (or +key=value), one value per key")
        if key in seen:
            raise EvalError(f"{key} is given twice")
        seen.add(key)
        if key in SHORTHANDS and not item.is_add():
            name, value = _shorthand(key, item.value())
            values[name] = value
        else:
            overrides.append(ConfigOverride(key, item.value(), item.is_add()))
    seeds = values.get("seeds")
    if seeds is not None and "seed" in values:
        raise EvalError("give seed= or seeds=, not both")
    if seeds is not None and values.get("episodes", len(seeds)) != len(seeds):
        raise EvalError(f"episodes={values['episodes']} but seeds= lists {len(seeds)} seeds")
    return EvalOptions(**values, overrides=tuple(overrides), arguments=tuple(arguments))
