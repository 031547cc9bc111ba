"""The cost trace (semdp.evaluation.cost_trace) and the recorder hooks it uses: a planted hazard
next to the robot, fields against hand-computed values, no change without a recorder, and the
replay of a run's next epoch against the uninterrupted run."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from omegaconf import OmegaConf

import semdp.envs  # noqa: F401  (registers the sims ids)
from semdp.embedded.follower import ProportionalFollower
from semdp.embedded.robot_models import RobotState, robot_model
from semdp.embedded.shield import SafetyShield
from semdp.embedded.straight import StraightLinePlanner
from semdp.embedded.wrapper import SafetyEmbeddedEnv
from semdp.evaluation.cost_trace import TRACE_NAME, CostTracer, recording, replay_epochs
from semdp.evaluation.errors import EvalError

HAZARD = (0.4, 0.0)
MARGIN = 0.05


def _env(shield: bool, hazard: tuple[float, float] = HAZARD) -> SafetyEmbeddedEnv:
    """A Point at the origin facing +x, a hazard ``hazard`` (radius 0.2 m) ahead."""
    env = SafetyEmbeddedEnv(
        gym.make("sims/SafetyPointGoal1-v0"), planner=StraightLinePlanner(),
        follower=ProportionalFollower(gain=8.0),
        shield=SafetyShield(margin=MARGIN, perception="gt") if shield else None)
    layout = {"agent": (0.0, 0.0), "agent_yaw": 0.0, "hazards": [hazard], "vases": [(-1.5, 1.5)],
              "goal": (-1.5, -1.5)}
    env.reset(seed=0, options={"layout": layout})
    return env


def _clearance_by_hand(first: np.ndarray, radius: float) -> float:
    """Smallest distance to the hazard's disc of ``radius`` over one step of ``first`` from
    the planted state, then the Point's braking manoeuvre."""
    model = robot_model("point")
    s = model.step(RobotState(0.0, 0.0, 1.5, 0.0, 0.0, 0.0), np.asarray(first, dtype=float))
    points = np.vstack([[s.x, s.y], model.brake_path(s)])
    return float((np.linalg.norm(points - HAZARD, axis=1) - radius).min())


def test_a_recorded_step_has_the_planted_state_and_hand_computed_clearances() -> None:
    # 1.5 m/s straight at a hazard whose edge is 0.2 m ahead: neither the action nor braking is
    # certified, so the filter escapes (as in tests/test_shield.py).
    env = _env(shield=True)
    env.unwrapped.body.velocity = (1.5, 0.0)
    reference = _env(shield=True)  # the same state, filtered without a recorder
    reference.unwrapped.body.velocity = (1.5, 0.0)
    expected = reference.shield.filter(np.array([1.0, 0.0]), reference.unwrapped,
                                       reference.begin_window(np.array([1.0, 0.0])).obs)
    tracer = CostTracer(steps=5)
    env.recorder = env.shield.recorder = tracer
    window = env.begin_window(np.array([1.0, 0.0]))
    env.low_level_step(window, np.array([1.0, 0.0]))
    (row,) = tracer.recent(env)
    radius = env.unwrapped.hazard_radius
    assert radius == 0.2
    assert row["pos"] == [0.0, 0.0] and row["vel"] == [1.5, 0.0]
    assert row["yaw"] == 0.0 and row["w"] == 0.0
    assert row["proposed"] == [1.0, 0.0]
    assert row["applied"] == expected.tolist() != [1.0, 0.0]
    assert row["branch"] == [1, 0, 1]  # checked, not braked, escaped
    assert row["min_true"] == pytest.approx(0.4 - radius, abs=1e-12)
    brake = robot_model("point").backup(RobotState(0.0, 0.0, 1.5, 0.0, 0.0, 0.0))
    assert row["brake_clear_true"] == pytest.approx(_clearance_by_hand(brake, radius), abs=1e-12)
    assert row["brake_clear_true"] < 0  # braking is not certified
    assert row["applied_clear_true"] == pytest.approx(
        _clearance_by_hand(expected, radius), abs=1e-12)
    # "gt" perception: the filter's region is the hazard grown by the margin
    assert row["brake_clear_perceived"] == pytest.approx(
        _clearance_by_hand(brake, radius + MARGIN), abs=1e-12)
    assert row["action_clear_perceived"] == pytest.approx(
        _clearance_by_hand(np.array([1.0, 0.0]), radius + MARGIN), abs=1e-12)
    # within 1 m: the hazard's region (x, y, R + margin, not a contact) and the hazard itself;
    # the vase at (-1.5, 1.5) is 2 m away
    assert row["regions"] == [[0.4, 0.0, radius + MARGIN, 0.0]]
    assert row["objects"] == {"hazards": [[0.4, 0.0, radius]]}
    assert row["cost"] == 0.0 and row["t"] == 1
    assert row["plan_escape"] is False and row["plan_fallback"] is False
    assert tracer.dumps == []


def test_the_dump_holds_the_last_steps_up_to_the_first_cost_step() -> None:
    env = _env(shield=False, hazard=(0.6, 0.0))  # no filter: the Point drives into the hazard
    tracer = CostTracer(steps=4)
    env.recorder = tracer
    costs = []
    for _ in range(6):
        _, _, _, _, info = env.step(np.array([1.0, 0.0]))
        costs.append(info["cost"])
    assert sum(costs) > 0
    (dump,) = tracer.dumps
    assert dump["env"] == id(env)
    assert dump["hazards"] == [[0.6, 0.0, 0.2]]
    steps = dump["steps"]
    assert len(steps) == 4
    assert [s["cost"] > 0 for s in steps] == [False, False, False, True]
    first = steps[-1]["t"]
    assert [s["t"] for s in steps] == [first - 3, first - 2, first - 1, first]
    assert set(steps[-1]) == {"cost", "cost_terms", "t", "plan_escape",
                              "plan_fallback"}  # no filter fields
    assert steps[-1]["cost_terms"] == ["cost_hazards"] and steps[-2]["cost_terms"] == []
    k = next(i for i, cost in enumerate(costs) if cost > 0)  # its high-level step
    assert 10 * k < first <= 10 * (k + 1)


def _trajectory(env: SafetyEmbeddedEnv) -> list[tuple]:
    rng = np.random.default_rng(4)
    out = []
    for _ in range(8):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, 2))
        body = env.unwrapped.body
        out.append((obs.tobytes(), reward, terminated, truncated, info["cost"],
                    info["shield_interventions"], tuple(body.position), tuple(body.velocity),
                    body.angle, body.angular_velocity))
    out.append(env.shield.stats)  # the filter's counts too
    return out


def test_recording_changes_nothing_and_ends_with_its_context() -> None:
    plain = _trajectory(_env(shield=True, hazard=(0.35, 0.1)))
    assert any(step[5] for step in plain[:-1])  # the filter acted
    hooked = _env(shield=True, hazard=(0.35, 0.1))
    tracer = CostTracer(steps=100)
    hooked.recorder = hooked.shield.recorder = tracer
    assert _trajectory(hooked) == plain
    assert [row["t"] for row in tracer.recent(hooked)] == list(range(1, 81))
    assert all("branch" in row for row in tracer.recent(hooked))
    tracer = CostTracer()
    with recording(tracer):  # every instance, through the classes
        env = _env(shield=True, hazard=(0.35, 0.1))
        assert _trajectory(env) == plain
    assert [row["t"] for row in tracer.recent(env)] == list(range(21, 81))  # the last 60
    assert SafetyShield.recorder is None and SafetyEmbeddedEnv.recorder is None
    with pytest.raises(ValueError, match="steps"):
        CostTracer(steps=0)


def test_the_replay_trains_exactly_the_next_epoch_and_writes_nothing_to_the_run(
        tmp_path: Path) -> None:
    """A ``budget=ci`` main job stopped after epoch 3 of 4, replayed from its checkpoint, gives
    the training statistics of epoch 4 of the same seed's 4-epoch run; the run directory is left
    as it was; a run whose checkpoint is its last epoch has nothing to replay."""
    short, full = tmp_path / "short", tmp_path / "full"
    for run_dir, steps in ((short, 1200), (full, 1600)):
        subprocess.run([sys.executable, "-m", "semdp.cli.train", "experiment=semdp", "budget=ci",
                        f"total_steps={steps}", "seed=3", "algo.learning_starts=200",
                        "tensorboard=false",
                        f"hydra.run.dir={run_dir}"], check=True, capture_output=True,
                       timeout=600)
    config = OmegaConf.load(short / "config.yaml")  # as if stopped after epoch 3 of 4
    config.total_steps = 1600
    OmegaConf.save(config, short / "config.yaml")
    before = sorted((p.name, p.stat().st_mtime_ns) for p in short.rglob("*"))
    dumps, (stats,) = replay_epochs(short, tmp_path / "trace")
    assert sorted((p.name, p.stat().st_mtime_ns) for p in short.rglob("*")) == before
    assert json.loads((tmp_path / "trace" / TRACE_NAME).read_text()) == dumps
    with open(full / "progress.csv", newline="") as f:
        row = list(csv.DictReader(f))[3]
    assert stats["epoch"] == 4 == int(row["epoch"])
    for key in ("ep_return", "ep_cost", "loss_q", "loss_pi", "alpha", "entropy"):
        assert stats[key] == pytest.approx(float(row[key]), rel=1e-12, abs=1e-12), key
    with pytest.raises(EvalError, match="nothing to replay"):
        replay_epochs(full, tmp_path / "trace_full")
    with pytest.raises(EvalError, match="exists"):
        replay_epochs(short, tmp_path / "trace")
    with pytest.raises(EvalError, match="nothing to replay for 2"):
        replay_epochs(short, tmp_path / "trace_two", epochs=2)
