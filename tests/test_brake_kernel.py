"""The safety filter's compiled certificate (semdp/embedded/brake_kernel.py) against its plain
path: equal bit for bit on random states and regions, and the same filtered episodes."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from shielded_env import ShieldedEnv

import semdp.envs  # noqa: F401  (registers the sims ids)
from semdp.embedded.brake_kernel import ClearanceKernel, compiles, kernel_for
from semdp.embedded.robot_models import RobotState, robot_model
from semdp.embedded.shield import SafetyShield


def _plain_clearance(model, s: RobotState, regions: np.ndarray) -> float:
    """The plain path's certificate from the state after the first step (as in the filter)."""
    points = np.empty((model.horizon + 1, 2))
    points[0] = (s.x, s.y)
    points[1:] = model.brake_path(s)
    gaps = np.linalg.norm(points[:, None, :] - regions[None, :, :2], axis=-1)
    return float((gaps - regions[None, :, 2]).min())


@pytest.mark.parametrize("native", [False, True])
@pytest.mark.parametrize("robot", ["point", "car"])
def test_kernel_equals_the_plain_path_bit_for_bit(robot: str, native: bool) -> None:
    model, rng = robot_model(robot), np.random.default_rng(7)
    kernel = ClearanceKernel(model, native=native)
    signs = set()
    for _ in range(1500):
        s = RobotState(*rng.uniform(-1.0, 1.0, 2), *rng.uniform(-1.5, 1.5, 2),
                       rng.uniform(-math.pi, math.pi), rng.uniform(-3.0, 3.0))
        n = int(rng.integers(1, 20))  # padded to 1, 2, 4, 8, 16 and 32 slots
        regions = np.column_stack([rng.uniform(-2.0, 2.0, (n, 2)), rng.uniform(0.1, 0.6, n)])
        expected = _plain_clearance(model, s, regions)
        assert kernel(s, regions) == expected
        signs.add(expected >= 0.0)
    assert signs == {True, False}  # both certified and uncertified states were compared


def test_kernels_are_shared_per_model_class_and_only_where_they_compile() -> None:
    assert kernel_for(robot_model("point")) is kernel_for(robot_model("point"))
    assert kernel_for(robot_model("point")) is not kernel_for(robot_model("car"))
    assert kernel_for(robot_model("point"), True) is not kernel_for(robot_model("point"))
    assert not compiles(robot_model("mass"))
    with pytest.raises(ValueError, match="brake_points"):
        ClearanceKernel(robot_model("mass"))


def test_the_shield_rejects_an_unknown_kernel() -> None:
    with pytest.raises(ValueError, match="kernel"):
        SafetyShield(kernel="fortran")


def _filtered_run(robot: str, kernel: str, steps: int = 250, gremlins: str = "orbit"
                  ) -> tuple[np.ndarray, tuple]:
    """Random full-throttle actions on Button1 through the filter: positions and its counts
    (``orbit``: the braking kernel's static certificate; ``moving``: the plan rollouts' too)."""
    shield = SafetyShield(kernel=kernel, gremlins=gremlins)
    env = ShieldedEnv(gym.make(f"sims/Safety{robot.capitalize()}Button1-v0"), shield)
    env.reset(seed=3)
    rng = np.random.default_rng(11)
    positions = []
    for _ in range(steps):
        env.step(np.sign(rng.uniform(-1.0, 1.0, 2)))
        positions.append(np.array(env.unwrapped.robot_position, dtype=np.float64))
    stats = shield.stats
    return np.array(positions), (stats.steps, stats.checked, stats.braked, stats.escaped)


@pytest.mark.parametrize("gremlins", ["orbit", "moving"])
@pytest.mark.parametrize("kernel", ["compiled", "native"])
@pytest.mark.parametrize("robot", ["point", "car"])
def test_the_filter_takes_the_same_decisions_with_every_kernel(
        robot: str, kernel: str, gremlins: str, monkeypatch: pytest.MonkeyPatch) -> None:
    from semdp.embedded import shield as shield_module

    scored = []
    certified_plans = shield_module.certified_plans
    monkeypatch.setattr(shield_module, "certified_plans",
                        lambda *args: scored.append(1) or certified_plans(*args))
    compiled, compiled_stats = _filtered_run(robot, kernel, gremlins=gremlins)
    plain, plain_stats = _filtered_run(robot, "python", gremlins=gremlins)
    assert np.array_equal(compiled, plain)
    assert compiled_stats == plain_stats
    if gremlins == "orbit":
        assert compiled_stats[2] + compiled_stats[3] > 0  # the filter acted in this run
    else:
        assert len(scored) > 0  # the plans were rolled out in this run
