"""The low-level steps before a cost step: replay one epoch of a SEMDP run with every safety
filter call and low-level step recorded (thesis §3.5.1-3.5.2, Alg. 2; the investigation of the
one training episode with cost in outputs/reference/archive/semdp_converged/COMMAND.md).

    python -m semdp.evaluation.cost_trace <run dir> <out dir> [--steps 60] [--epochs 1]

Loads ``<run dir>``'s checkpoint (``config.yaml`` and ``checkpoints/last.pt``; the run itself is
not touched) and trains ``--epochs`` more epochs from it, as the run did after that checkpoint
(no evaluation, no checkpoint, no progress row), while a :class:`CostTracer` records every
:class:`~semdp.embedded.shield.SafetyShield` call and every low-level step of the
:class:`~semdp.embedded.wrapper.SafetyEmbeddedEnv` envs in this process. It writes
``<out dir>/cost_trace.json``: a list with one entry per env that incurred cost in the epoch,
``{"env": id, "hazards": [[x, y, r], ...], "steps": [...]}``, its last ``--steps`` low-level
steps up to and including its first cost step, and prints each epoch's training statistics
(to compare with the run's ``progress.csv`` rows: a replay is exact). A step's fields:

* from the filter (absent for an env without one), all before the step: ``pos``, ``vel``,
  ``yaw``, ``w`` (the robot state the filter read), ``proposed`` and ``applied`` (the
  follower's action and the filter's), ``branch`` (the filter's counter increments
  ``[checked, braked, escaped]``: ``[0, 0, 0]`` nothing within reach, ``[1, 0, 0]`` the action
  certified, ``[1, 1, 0]`` braked, ``[1, 0, 1]`` escaped), ``brake_clear_perceived`` and
  ``action_clear_perceived`` (the certificate of braking and of the proposed action, i.e. the
  smallest ``distance - R`` over one step then the braking manoeuvre, against every cost region
  the filter perceives; None when it perceives none), ``brake_clear_true`` and
  ``applied_clear_true`` (braking and the applied action against the true hazards, no margin;
  None without hazards), ``min_true`` (the root's distance to the nearest true hazard's
  edge), ``regions`` (the perceived regions within :data:`NEAR` m of their edge, rows
  ``[x, y, R, contact]``) and ``objects`` (the true objects of each kind within :data:`NEAR` m
  of their edge, rows ``[x, y, r]``; on Button tasks also ``goal_button`` and
  ``button_timer``, the grace period's steps left);
* from the step: ``cost`` (the inner env's cost of the step), ``cost_terms`` (its named cost
  terms that were not zero, e.g. ``cost_buttons``), ``t`` (the env's lifetime low-level step
  count, this step included), ``plan_escape`` and ``plan_fallback`` (the window's plan).

The recording uses the filter's and the wrapper's ``recorder`` hooks; without a recorder
neither records anything.
"""

from __future__ import annotations

import argparse
import json
import math
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import torch
from omegaconf import DictConfig

from semdp.algos.base import CHECKPOINT_NAME
from semdp.build import build_algorithm, validate_config
from semdp.embedded.shield import FilterRecord, SafetyShield
from semdp.embedded.wrapper import LowLevelRecord, SafetyEmbeddedEnv
from semdp.evaluation.errors import EvalError
from semdp.run_config import load_run_config

#: The trace's file name in the output directory.
TRACE_NAME = "cost_trace.json"
#: Steps kept per env before (and including) its first cost step.
DEFAULT_STEPS = 60
#: A step's ``regions`` and ``objects`` hold those whose edge is within this distance (m).
NEAR = 1.0
#: ``branch`` as the filter's counter increments ``[checked, braked, escaped]``.
BRANCH_COUNTS: dict[str, tuple[int, int, int]] = {
    "unchecked": (0, 0, 0), "kept": (1, 0, 0), "braked": (1, 1, 0), "escaped": (1, 0, 1),
}


def _hazards(base: Any) -> np.ndarray:
    """``(n, 3)`` rows ``[x, y, r]`` of the env's true hazards."""
    return np.asarray(base.obstacles(("hazards",)), dtype=np.float64).reshape(-1, 3)


def _near_objects(base: Any, x: float, y: float) -> dict[str, Any]:
    """The true objects of each kind whose edge is within :data:`NEAR` of ``(x, y)`` (and the
    Button task's goal button and grace-period timer)."""
    out: dict[str, Any] = {}
    for kind, rows in base.obstacles_by_type().items():
        gaps = np.hypot(rows[:, 0] - x, rows[:, 1] - y) - rows[:, 2]
        if (gaps < NEAR).any():
            out[kind] = rows[gaps < NEAR].tolist()
    if getattr(base, "buttons", None):
        out["goal_button"] = list(base.buttons[base.goal_button])
        out["button_timer"] = int(base.button_timer)
    return out


def filter_fields(record: FilterRecord) -> dict[str, Any]:
    """The filter's fields of a trace step (module docstring) from one filter call."""
    shield, state = record.shield, record.state
    regions = shield.cost_regions(record.base, record.obs)
    hazards = _hazards(record.base)
    brake = record.model.backup(state)

    def clearance(first: np.ndarray, against: np.ndarray) -> float | None:
        return shield.clearance(state, np.asarray(first), against) if len(against) else None

    return {
        "pos": [state.x, state.y],
        "vel": [state.vx, state.vy],
        "yaw": state.yaw,
        "w": state.w,
        "proposed": np.asarray(record.proposed, float).tolist(),
        "applied": np.asarray(record.applied, float).tolist(),
        "branch": list(BRANCH_COUNTS[record.branch]),
        "brake_clear_perceived": clearance(brake, regions),
        "action_clear_perceived": clearance(record.proposed, regions),
        "brake_clear_true": clearance(brake, hazards),
        "applied_clear_true": clearance(record.applied, hazards),
        "min_true": (float(min(math.hypot(state.x - h[0], state.y - h[1]) - h[2]
                               for h in hazards)) if len(hazards) else None),
        "regions": _near_regions(shield, record, state.x, state.y),
        "objects": _near_objects(record.base, state.x, state.y),
    }


def _near_regions(shield: SafetyShield, record: FilterRecord, x: float, y: float
                  ) -> list[list[float]]:
    """The filter's regions (rows ``[x, y, R, contact]``) within :data:`NEAR` of their edge."""
    seen = shield._regions(record.base, record.obs)
    regions, contact = seen.rows, seen.contact
    if not len(regions):
        return []
    near = np.hypot(regions[:, 0] - x, regions[:, 1] - y) - regions[:, 2] < NEAR
    return np.column_stack([regions[near], contact[near]]).tolist()


class CostTracer:
    """A recorder for both hooks: keeps each env's last ``steps`` low-level steps and, at its
    first cost step, adds them to :attr:`dumps` (the module docstring's entries).

    Args:
        steps: steps kept per env, the cost step included.
    """

    def __init__(self, steps: int = DEFAULT_STEPS) -> None:
        if steps < 1:
            raise ValueError(f"steps must be >= 1, got {steps}")
        self.steps = int(steps)
        self.dumps: list[dict[str, Any]] = []
        self._recent: dict[int, deque[dict[str, Any]]] = {}
        self._filtered: dict[int, dict[str, Any]] = {}  # by id of the unwrapped env

    def recent(self, env: SafetyEmbeddedEnv) -> list[dict[str, Any]]:
        """``env``'s kept steps, oldest first."""
        return list(self._recent.get(id(env), ()))

    def __call__(self, record: FilterRecord | LowLevelRecord) -> None:
        """Take a filter call (kept until its env's step) or a low-level step."""
        if isinstance(record, FilterRecord):
            self._filtered[id(record.base)] = filter_fields(record)
            return
        env, window = record.env, record.window
        base = env.unwrapped
        row = self._filtered.pop(id(base), {})
        row["cost"] = float(window.info.get("cost", 0.0))
        row["cost_terms"] = sorted(key for key, value in window.info.items()
                                   if key.startswith("cost_") and key != "cost_sum"
                                   and isinstance(value, float) and value > 0)
        row["t"] = record.step
        row["plan_escape"] = bool(getattr(window.plan, "escape_mode", False))
        row["plan_fallback"] = bool(getattr(window.plan, "fallback", False))
        key = id(env)
        recent = self._recent.setdefault(key, deque(maxlen=self.steps))
        recent.append(row)
        if row["cost"] > 0 and not any(dump["env"] == key for dump in self.dumps):
            self.dumps.append({"env": key, "hazards": _hazards(base).tolist(),
                               "steps": list(recent)})


@contextmanager
def recording(tracer: CostTracer) -> Iterator[CostTracer]:
    """Give ``tracer`` every filter call and low-level step in this process while the context
    is open: the classes' ``recorder``, so that the envs a resume unpickles from a checkpoint
    are recorded too and a checkpoint written meanwhile does not hold the tracer."""
    saved = SafetyShield.recorder, SafetyEmbeddedEnv.recorder
    SafetyShield.recorder = tracer
    SafetyEmbeddedEnv.recorder = tracer
    try:
        yield tracer
    finally:
        SafetyShield.recorder, SafetyEmbeddedEnv.recorder = saved


def _replay_epochs(cfg: DictConfig, run_dir: Path, epochs: int) -> list[dict[str, float]]:
    """Train ``epochs`` epochs from ``run_dir``'s checkpoint under its config ``cfg``, as the
    run did after that checkpoint (its learning-rate schedules see the run's ``total_steps``);
    nothing is written. Returns each epoch's training statistics."""
    validate_config(cfg)
    torch.set_num_threads(int(cfg.get("torch_threads", 1)))
    algo = build_algorithm(cfg)
    algo.load_checkpoint(run_dir / "checkpoints" / CHECKPOINT_NAME)
    algo.total_epochs = math.ceil(int(cfg.total_steps) / algo.steps_per_epoch)
    if algo.epoch + epochs > algo.total_epochs:
        raise EvalError(f"{run_dir}: the checkpoint is at epoch {algo.epoch} of "
                        f"{algo.total_epochs}; nothing to replay for {epochs} epoch(s)")
    out = []
    try:
        for _ in range(epochs):
            stats = algo.train_epoch()
            out.append({"epoch": algo.epoch, **{k: float(v) for k, v in stats.items()
                                                if isinstance(v, (int, float))}})
    finally:
        algo.close_helpers()
    return out


def replay_epochs(run_dir: str | Path, out_dir: str | Path, steps: int = DEFAULT_STEPS,
                  epochs: int = 1) -> tuple[list[dict[str, Any]], list[dict[str, float]]]:
    """Replay the ``epochs`` epochs after ``run_dir``'s checkpoint with a :class:`CostTracer`;
    write the entries (module docstring) to ``out_dir`` and return them with each epoch's
    statistics.

    Raises:
        EvalError: ``run_dir`` lacks its config or checkpoint, ``out_dir`` exists, or the run
            has fewer epochs left.
    """
    if epochs < 1:
        raise EvalError(f"epochs must be >= 1, got {epochs}")
    run_dir, out_dir = Path(run_dir), Path(out_dir)
    if not ((run_dir / "config.yaml").is_file()
            and (run_dir / "checkpoints" / CHECKPOINT_NAME).is_file()):
        raise EvalError(f"{run_dir}: needs config.yaml and checkpoints/{CHECKPOINT_NAME}")
    if out_dir.exists():
        raise EvalError(f"{out_dir} exists; give a new directory for the trace")
    tracer = CostTracer(steps)
    cfg = load_run_config(run_dir)
    with recording(tracer):
        stats = _replay_epochs(cfg, run_dir, epochs)
    out_dir.mkdir(parents=True)
    (out_dir / TRACE_NAME).write_text(json.dumps(tracer.dumps, indent=1, default=float))
    return tracer.dumps, stats


def main(argv: list[str] | None = None) -> None:
    """CLI entry point."""
    parser = argparse.ArgumentParser(prog="python -m semdp.evaluation.cost_trace",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", type=Path, help="a SEMDP run with checkpoints/last.pt")
    parser.add_argument("out_dir", type=Path, help="a new directory for the replayed copy")
    parser.add_argument("--steps", type=int, default=DEFAULT_STEPS,
                        help="steps kept per env up to its first cost step")
    parser.add_argument("--epochs", type=int, default=1, help="epochs replayed")
    args = parser.parse_args(argv)
    try:
        dumps, stats = replay_epochs(args.run_dir, args.out_dir, args.steps, args.epochs)
    except EvalError as exc:
        raise SystemExit(f"cost_trace: {exc}") from None
    for row in stats:
        print("replayed " + " ".join(f"{key} {value:.6g}" for key, value in row.items()))
    print(f"{args.out_dir / TRACE_NAME}: {len(dumps)} env(s) with a cost step")


if __name__ == "__main__":
    main()
