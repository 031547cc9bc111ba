"""The filter's moving-gremlin certificate (``SafetyShield(gremlins="moving")``): its plan
rollouts are the robot model's steps, it lets a robot cross an orbit disc that the static
certificate stops it at, a robot driven at a gremlin's home from many phases of its orbit is
never touched, and the same robots are touched when the certificate ignores the gremlins'
motion (each at the place it is now: the check the law makes sound)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from shielded_env import ShieldedEnv

import semdp.envs  # noqa: F401  (registers the sims ids)
from semdp.embedded import moving_certificate
from semdp.embedded.cost_regions import Regions, no_regions
from semdp.embedded.exit_planning import EXIT_STEPS, exit_reach, presses_without_exit
from semdp.embedded.moving_certificate import (
    HOLDS,
    Gremlins,
    KeptFrame,
    Plan,
    certified_plans,
    plans_for,
)
from semdp.embedded.perception import gremlin_offset, gremlin_offsets
from semdp.embedded.plan_rollouts import rollout
from semdp.embedded.robot_models import RobotState, robot_model
from semdp.embedded.shield import SafetyShield

ROBOTS = ("point", "car", "mass")
#: The robots' yaw that drives them along +x under :data:`FORWARD`.
YAW = {"point": 0.0, "car": math.pi / 2, "mass": 0.0}
FORWARD = {"point": [1.0, 0.0], "car": [1.0, 1.0], "mass": [1.0, 0.0]}
CORNERS = [(1.6, 1.6), (-1.6, 1.6), (1.6, -1.6), (-1.6, -1.6)]

#: The settings the bench episodes replayed below were recorded with: the moving-gremlin
#: certificate and the thesis' 0.2 m tracking look-ahead (the Point's default is 0.4 m since).
RECORDED = ("env.gremlins=moving", "robot.lookahead=0.2")


@pytest.mark.parametrize("kernel", ["python", "compiled", "native"])
@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("first", [None, (0.7, -0.3)])
def test_plan_rollouts_are_the_models_steps(robot: str, first: tuple | None, kernel: str) -> None:
    """Every kernel's rollout equals ``model.step`` (and the backup) by hand, bit for bit."""
    model = robot_model(robot)
    start = RobotState(0.1, -0.2, 0.3, -0.4, 1.0, 0.5)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.2, 1.2, (12, 2))
    holds = rng.integers(0, 8, 12)
    first_action = None if first is None else np.array(first)
    points = rollout(model, start, first_action, actions, holds, 15, kernel=kernel)
    poses = rollout(model, start, first_action, actions, holds, 15, with_yaw=True, kernel=kernel)
    for i in range(12):
        s, by_hand = start, []
        for k in range(15):
            held = k - (first is not None)
            if held < 0:
                a = first_action
            else:
                a = actions[i] if held < holds[i] else model.backup(s)
            s = model.step(s, a)
            by_hand.append((s.x, s.y, s.yaw))
        np.testing.assert_array_equal(poses[i], np.array(by_hand))
        np.testing.assert_array_equal(points[i], np.array(by_hand)[:, :2])


def test_the_offsets_on_arrays_are_the_gremlin_law() -> None:
    times = np.concatenate([np.linspace(0.0, 0.5, 101), np.linspace(0.0, 60.0, 1001), [-1.0]])
    by_hand = np.array([gremlin_offset(t) for t in times])
    np.testing.assert_allclose(gremlin_offsets(times), by_hand, rtol=0, atol=1e-15)


def test_plans_are_every_escape_at_every_hold() -> None:
    model = robot_model("point")
    plans = plans_for(model)
    assert plans[0] == Plan((0.0, 0.0), 0)
    assert len(plans) == len(set(plans)) == 1 + len(model.escapes) * (len(HOLDS) - 1)
    assert Plan((1.0, 0.0), 7).shorter() == Plan((1.0, 0.0), 6)
    assert Plan((1.0, 0.0), 0).shorter().hold == 0


@pytest.mark.parametrize("robot", ROBOTS)
def test_one_plan_alone_scores_as_in_the_set(robot: str) -> None:
    """The kept plan alone (one rollout, as the filter tries it first) is certified exactly
    when it is among all plans: the same trajectory under the same certificate (the
    clearance's value may differ: each checks the static regions its own trajectories
    reach)."""
    model = robot_model(robot)
    state = RobotState(-0.9, 0.1, 0.4, 0.0, 0.2, 0.0)
    static = np.array([[0.2, 0.9, 0.35], [-1.6, -0.4, 0.3]])
    gremlins = Gremlins(np.array([[0.0, 0.0, 0.7]]), 2.0, model.h * model.substeps)
    plans = plans_for(model)
    first = np.array([0.5, 0.2])
    together = certified_plans(model, state, first, plans, static, gremlins, 0.05)
    assert (together >= 0.0).any() and (together < 0.0).any()
    for i, plan in enumerate(plans):
        alone = certified_plans(model, state, first, [plan], static, gremlins, 0.05)
        assert (alone[0] >= 0.0) == (together[i] >= 0.0), plan


def _drive_at_a_gremlin(robot: str, mode: str, seed: int, wait: int,
                        steps: int = 200) -> tuple[float, list[float]]:
    """A robot 1.5 m west of a gremlin's home, idle for ``wait`` steps (the orbit's phase),
    then commanded east at full speed: (cost, its x after each commanded step)."""
    env = ShieldedEnv(gym.make(f"sims/Safety{robot.capitalize()}Button1-v0"),
                      SafetyShield(perception="lidar", gremlins=mode))
    layout = {"agent": (-1.5, 0.0), "agent_yaw": YAW[robot], "buttons": CORNERS,
              "gremlins": [(0.0, 0.0)], "hazards": []}
    env.reset(seed=seed, options={"layout": layout})
    base = env.unwrapped
    cost, xs = 0.0, []
    for _ in range(wait):
        _, _, _, _, info = env.step(np.zeros(2))
        cost += info["cost"]
    for _ in range(steps):
        _, _, _, _, info = env.step(np.array(FORWARD[robot]))
        cost += info["cost"]
        xs.append(float(base.robot_position[0]))
    return cost, xs


def test_a_mass_crosses_an_orbit_disc_the_static_filter_stops_it_at() -> None:
    """The orbit disc (radius 0.66 m with the Mass's extent and the margin) stops the static
    filter's Mass at its edge; under the moving certificate the Mass crosses it, untouched,
    whatever the orbit's phase when it sets off."""
    for wait in (0, 37, 74, 111):
        cost, xs = _drive_at_a_gremlin("mass", "orbit", 0, wait)
        assert cost == 0.0 and max(xs) < -0.6
        cost, xs = _drive_at_a_gremlin("mass", "moving", 0, wait)
        assert cost == 0.0 and xs[-1] > 0.7, wait


@pytest.mark.parametrize("robot", ROBOTS)
def test_a_robot_driven_at_a_gremlins_home_is_never_touched(robot: str) -> None:
    """Eight phases of the orbit, about 0.8 rad apart: the robot gets within 0.5 m of the
    home (the static filter keeps it 0.66-0.76 m away) and the gremlin never touches it."""
    nearest = math.inf
    for wait in range(0, 320, 40):
        cost, xs = _drive_at_a_gremlin(robot, "moving", 1, wait, steps=150)
        assert cost == 0.0, wait
        nearest = min(nearest, *(abs(x) for x in xs))
    assert nearest < 0.5


def test_ignoring_the_gremlins_motion_gets_robots_touched(monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    """The same drives with each gremlin checked where it is now at every step of a plan (a
    snapshot, as the thesis' planner sees it): some robot is touched."""
    def snapshot(self: Gremlins, steps: int) -> np.ndarray:
        now = self.homes[:, :2] + gremlin_offset(self.time)
        return np.broadcast_to(now, (steps, *now.shape))

    monkeypatch.setattr(moving_certificate.Gremlins, "centres", snapshot)
    assert any(_drive_at_a_gremlin(robot, "moving", 1, wait, steps=150)[0] > 0.0
               for robot in ROBOTS for wait in range(0, 320, 40))


@pytest.mark.parametrize("robot", ["point", "car"])
def test_random_commands_on_button_tasks_cost_nothing(robot: str) -> None:
    """Uniform random commands on full Button1 and Button2 layouts (hazards, gremlins, wrong
    buttons), seeds not used while developing the certificate: no cost of any kind."""
    rng = np.random.default_rng(7)
    for task, seed in (("Button1", 901), ("Button2", 902), ("Button1", 903)):
        env = ShieldedEnv(gym.make(f"sims/Safety{robot.capitalize()}{task}-v0"),
                          SafetyShield(perception="lidar", gremlins="moving"))
        env.reset(seed=seed)
        cost = 0.0
        for _ in range(300):
            _, _, _, _, info = env.step(rng.uniform(-1.0, 1.0, 2))
            cost += info["cost"]
        assert cost == 0.0, (task, seed)


def test_an_unknown_gremlin_model_is_refused() -> None:
    with pytest.raises(ValueError, match=r"shield gremlins must be one of \('orbit', 'moving'\)"):
        SafetyShield(gremlins="teleport")


def _press_from_inside_a_disc() -> tuple[float, float]:
    """A Point at rest inside a gremlin's orbit disc (the gremlin starts at its home, 0.45 m
    behind the robot), the goal button 0.3 m ahead, commanded at it at full thrust for 30
    steps: (presses, cost)."""
    env = ShieldedEnv(gym.make("sims/SafetyPointButton1-v0"),
                      SafetyShield(perception="lidar", gremlins="moving"))
    layout = {"agent": (0.45, 0.0), "agent_yaw": 0.0, "gremlins": [(0.0, 0.0)], "hazards": [],
              "buttons": [(0.75, 0.0), (-1.6, 1.6), (1.6, -1.6), (-1.6, -1.6)]}
    seed = next(s for s in range(40)
                if env.reset(seed=s, options={"layout": layout}) and env.unwrapped.goal_button == 0)
    env.reset(seed=seed, options={"layout": layout})  # the goal is the button ahead
    presses = cost = 0.0
    for _ in range(30):
        _, _, _, _, info = env.step(np.array([1.0, 0.0]))
        presses += info["goal_met"]
        cost += info["cost"]
    return presses, cost


def test_plans_do_not_run_into_the_goal_button(monkeypatch: pytest.MonkeyPatch) -> None:
    """The plans model no contacts, and the goal button is a body that is no cost region: a
    plan through it is not what the robot does (it presses the button, stops against it and,
    the goal moved, must leave a wrong button within 10 steps with the gremlin coming round:
    a trained PointButton1 run's epoch 6 touched both, 1.25 cost per episode; 0 replayed with
    the button's region). Inside an orbit disc the filter keeps the robot off the goal button;
    with no goal-button region the same command presses it."""
    presses, cost = _press_from_inside_a_disc()
    assert presses == 0.0 and cost == 0.0
    monkeypatch.setattr(SafetyShield, "goal_button", lambda self, base, obs: no_regions())
    presses, _ = _press_from_inside_a_disc()
    assert presses >= 1.0


def test_a_point_leaves_the_button_it_pressed_by_the_exit_not_by_plans() -> None:
    """Episode 20317 of ``semdp-bench safety`` (PointButton1, goal-seeking subgoals, evaluation
    wrapper): the Point presses the goal button near a gremlin's orbit disc and starts its grace
    period touching it. Inside that static region no plan of the set is certified and each
    scores the same depth at its first step; taking the best of them every step alternated
    between ways out, the Point stayed on the button and touched it after the grace period
    (1 cost step, ``cost_buttons``, checked with the rule patched out). The exit of
    :mod:`semdp.embedded.exit_planning` takes it off: no cost."""
    from semdp.benchmarks.safety import build_semdp_env, make_policy
    from semdp.evaluation.safety_eval import evaluate_safety

    env = build_semdp_env("point", "Button1", "eval", RECORDED)
    stats = evaluate_safety(env, make_policy("goal", env, 20317), 1, seed=20317)
    assert stats["escape_rate"] > 0 and stats["return_mean"] > 1.0  # pressed, then escaped
    assert stats["cost_steps_total"] == 0


def test_a_point_inside_an_orbit_disc_commits_to_one_best_effort_plan() -> None:
    """Episode 9627 of the button regressions (PointButton1, goal-seeking subgoals, evaluation
    wrapper) under the moving certificate: the Point finds itself inside a gremlin's orbit disc
    with no plan certified. The plan with the largest clearance, chosen afresh at every step,
    alternated between driving on and reversing as the LiDAR's candidates came and went; the
    Point rocked in place for 45 steps until the gremlin came round (7 cost steps,
    ``cost_gremlins``; checked with the commitment patched out). Kept one step shorter unless
    another plan clears more by the margin, the best-effort plan takes it out: no cost."""
    from semdp.benchmarks.safety import build_semdp_env, make_policy
    from semdp.evaluation.safety_eval import evaluate_safety

    env = build_semdp_env("point", "Button1", "eval", RECORDED)
    stats = evaluate_safety(env, make_policy("goal", env, 9627), 1, seed=9627)
    assert stats["escape_rate"] > 0  # the best-effort plans ran
    assert stats["cost_steps_total"] == 0


def test_a_car_does_not_keep_a_best_effort_plan_that_turns_it_in_place() -> None:
    """Episode 20307 of ``semdp-bench safety`` (CarButton2, subgoals aimed at the nearest
    hazard, evaluation wrapper) under the moving certificate: inside an orbit disc with no plan
    certified, the best-effort plan kept for as long as it lasted turned the Car in place for
    40 steps until the gremlin came round (12 cost steps, ``cost_gremlins``; checked with the
    bound on keeping it patched out). Chosen afresh after at most ``EXIT_STEPS`` steps: no
    cost."""
    from semdp.benchmarks.safety import build_semdp_env, make_policy
    from semdp.evaluation.safety_eval import evaluate_safety

    env = build_semdp_env("car", "Button2", "eval", ("env.gremlins=moving",))
    stats = evaluate_safety(env, make_policy("adversarial", env, 20307), 1, seed=20307)
    assert stats["escape_rate"] > 0
    assert stats["cost_steps_total"] == 0


def test_a_command_the_certificate_keeps_is_not_counted_as_replaced() -> None:
    """The SEMDP counts a low-level command as replaced when the filter returns another object
    (``info["shield_interventions"]``, the shield % of the safety table). A Mass crossing an
    orbit disc under the moving certificate keeps its command at most steps: the filter returns
    that very command (a copy of it was counted as replaced, and the shield % read 20-58 % on
    Button tasks where it replaced far fewer)."""
    env = gym.make("sims/SafetyMassButton1-v0")
    shield = SafetyShield(perception="lidar", gremlins="moving")
    layout = {"agent": (-1.5, 0.0), "agent_yaw": YAW["mass"], "buttons": CORNERS,
              "gremlins": [(0.0, 0.0)], "hazards": []}
    obs, _ = env.reset(seed=0, options={"layout": layout})
    shield.bind(env.unwrapped)
    shield.new_episode()
    copies = kept = 0
    for _ in range(150):
        command = np.array(FORWARD["mass"], dtype=np.float64)
        applied = shield.filter(command, env.unwrapped, obs)
        kept += applied is command
        copies += applied is not command and np.array_equal(applied, command)
        obs, *_ = env.step(applied)
    assert shield.stats.checked > 0 and kept > 100
    assert copies == 0


def test_a_car_keeps_its_plan_when_the_lidar_candidates_change() -> None:
    """Episode 20311 of ``semdp-bench safety`` (CarButton2, random subgoals from seed 20300,
    evaluation wrapper; the subgoals of its 11 earlier episodes drawn first): the Car crosses
    a gremlin's orbit disc under a certified plan while the LiDAR's gremlin candidates (every
    lit bin) come and go. Checked against the last frame's candidates alone, the kept plan was
    lost in the middle of the disc; the best uncertified plan then reversed the Car 0.4 m
    deeper, onto a wrong button's region, where it rocked until the gremlin came round
    (3 cost steps, ``cost_gremlins``; checked with that rule patched in). Kept against the
    candidates it was certified against, plus any new one they do not explain: no cost."""
    from semdp.benchmarks.safety import build_semdp_env
    from semdp.evaluation.safety_eval import evaluate_safety

    env = build_semdp_env("car", "Button2", "eval", ("env.gremlins=moving",))
    rng = np.random.default_rng(20300)
    rng.uniform(-1.0, 1.0, size=(11 * 100, 2))  # the 11 earlier episodes' 100 subgoals each
    stats = evaluate_safety(env, lambda _obs: rng.uniform(-1.0, 1.0, size=2), 1, seed=20311)
    assert stats["plans"] == 100
    assert stats["cost_steps_total"] == 0


def _rows(rows: list[list[float]], spread: list[float], keepout: float | list[float],
          own: bool | list[bool] = True) -> Regions:
    """Hand-placed :class:`Regions` (contact and orbit flags irrelevant to the identity of
    their objects)."""
    m = len(rows)
    return Regions(np.array(rows, dtype=float).reshape(-1, 3), np.zeros(m, bool),
                   np.zeros(m, bool), np.array(spread, dtype=float),
                   np.broadcast_to(np.asarray(keepout, dtype=float), (m,)).copy(),
                   np.broadcast_to(np.asarray(own, dtype=bool), (m,)).copy())


def _statics_only(statics: Regions) -> KeptFrame:
    """A kept frame of static rows and no gremlin homes."""
    return KeptFrame(statics, _rows([], [], 0.4), (0.0, 0.0), 0.0)


def test_only_rows_the_kept_rows_cannot_explain_are_added() -> None:
    """Oracle by hand: a row's object lies within its spread of its centre, two objects' centres
    are at least the sum of their keepouts apart, so today's row ``b`` holds kept row ``a``'s
    object when ``spread_a + |c_a - c_b| + spread_b < keepout_a + keepout_b``; every other row
    is added (it may hold an object not seen when the plan was certified)."""
    kept = _rows([[0.0, 0.0, 0.9]], [0.1], 0.4)                      # a gremlin's home
    today = _rows([[0.25, 0.0, 0.9], [0.5, 0.0, 0.9], [0.6, 0.0, 0.9], [1.2, 0.0, 0.8],
                   [0.0, 0.1, 0.9]],
                  [0.15, 0.15, 0.15, 0.0, np.inf], 0.4)
    # 0.5 and 0.75 < 0.8: the same home; 0.85, 1.3 and inf >= 0.8: maybe another gremlin
    np.testing.assert_array_equal(today.unexplained_by(kept).rows, today.rows[2:])
    # a kept row that may be a neighbour's alias holds no object to be the same as
    alias = kept._replace(own=np.zeros(1, bool))
    np.testing.assert_array_equal(today.unexplained_by(alias).rows, today.rows)
    hazard = _rows([[0.0, 0.0, 0.3]], [0.05], 0.18)
    button = _rows([[0.2, 0.0, 0.4], [0.35, 0.0, 0.4]], [0.1, 0.1], 0.2)
    # 0.35 < 0.38 = 0.18 + 0.2 (no button can be that close to the hazard), 0.5 >= 0.38
    np.testing.assert_array_equal(button.unexplained_by(hazard).rows, button.rows[1:])
    assert len(today.unexplained_by(_rows([], [], 0.4)).rows) == len(today.rows)


#: A trained CarButton1 run's kept plan one step after it was certified, with both steps'
#: static rows and gremlin homes (rows, spreads, keepouts) as the filter built them
#: (outputs/reference/semdp_button1_moving/COMMAND.md, "Training episodes with cost").
KEPT_FRAMES = Path(__file__).resolve().parent / "data" / "kept_plan_frames.json"


def _kept_frames() -> tuple[dict, dict]:
    fx = json.loads(KEPT_FRAMES.read_text())["plan_lost"]
    out = []
    for key in ("certified", "next"):
        node = fx[key]
        out.append({"statics": _rows(**node["statics"]), "homes": _rows(**node["homes"]),
                    "time": node["time"], "plan": Plan(tuple(node["plan"][0]), node["plan"][1]),
                    "state": node.get("state")})
    return out[0], out[1]


def _kept_check(shield: SafetyShield, then: dict, now: dict
                ) -> tuple[RobotState, Gremlins, object]:
    model = robot_model("car")
    state = RobotState(*now["state"])
    gremlins = Gremlins(now["homes"].rows, now["time"], model.h * model.substeps)
    shield._plan_seen = KeptFrame(then["statics"], then["homes"], tuple(now["state"][:2]),
                                  then["time"])
    frame = shield._kept_frame(model, state, None, now["plan"], now["statics"], now["homes"],
                               gremlins)
    return state, gremlins, frame


def test_a_car_keeps_its_plan_when_a_static_region_widens() -> None:
    """The Car deep in an orbit disc follows a plan certified 0.002 m clear of a wrong button's
    region; one step later the button's LiDAR region is 0.011 m wider and 0.011 m off, and
    the same plan, one step shorter, is 0.002 m into it: checked against today's rows alone
    the plan is lost, and the Car then chattered between best-effort plans until the gremlin
    came round (``cost_gremlins``, 52 steps later). The button is the one it was certified
    against (its rows 0.011 m apart, spreads under 0.11 m, two buttons at least 0.4 m
    apart): the plan is kept."""
    then, now = _kept_frames()
    shield = SafetyShield(gremlins="moving")
    model = robot_model("car")
    state = RobotState(*now["state"])
    gremlins = Gremlins(now["homes"].rows, now["time"], model.h * model.substeps)
    points, ends = moving_certificate.plan_points(model, state, None, [now["plan"]])
    today = moving_certificate.clearances(points, ends, state, now["statics"].rows, gremlins,
                                          shield.margin)[0]
    assert -0.01 < today < 0.0  # the hole: today's rows alone refuse the plan
    added = now["statics"].unexplained_by(then["statics"]).rows
    assert np.hypot(*(added[:, :2] - (0.845, -0.489)).T).min() > 0.1  # the button's row is not
    _, _, frame = _kept_check(shield, then, now)
    assert frame is not None


def test_a_kept_plan_meets_an_object_not_seen_when_it_was_certified() -> None:
    """The same step with a hazard planted on the kept plan's path, 0.4 m from every row the
    plan was certified against (no kept row can hold it): the plan is not kept. Explaining
    every row by the kept ones (no keepout bound) would keep it."""
    then, now = _kept_frames()
    model = robot_model("car")
    state = RobotState(*now["state"])
    points, _ = moving_certificate.plan_points(model, state, None, [now["plan"]])
    x, y = points[0, 12]
    planted = _rows([[x, y, 0.3]], [0.05], 0.18)
    assert len(planted.unexplained_by(then["statics"]).rows) == 1
    now = {**now, "statics": now["statics"].plus(planted)}
    _, _, frame = _kept_check(SafetyShield(gremlins="moving"), then, now)
    assert frame is None


#: The last low-level steps before the first cost step of a trained PointButton1 run's epoch 9
#: (outputs/reference/semdp_button1_moving/COMMAND.md, "Training episodes with cost").
POCKET_TRACE = (Path(__file__).resolve().parents[1] / "outputs" / "reference"
                / "semdp_button1_moving" / "traces" / "ours_point_s0_epoch9.json")


def _pocket(t: int, shift: float = 0.0) -> tuple[RobotState, np.ndarray, np.ndarray]:
    """The recorded robot state, goal-button region and orbit discs (each disc moved ``shift``
    m away from the goal button) at the trace's low-level step ``t``."""
    step = next(s for s in json.loads(POCKET_TRACE.read_text())[0]["steps"] if s["t"] == t)
    state = RobotState(*step["pos"], *step["vel"], step["yaw"], step["w"])
    goal = np.array([[*step["objects"]["goal_button"], 0.308]])  # button + extent + margin
    regions = np.array(step["regions"])
    orbits = regions[regions[:, 2] >= 0.7, :3]  # orbit discs: 0.355 + 0.141 + extent + margin
    away = orbits[:, :2] - goal[0, :2]
    orbits[:, :2] += shift * away / np.linalg.norm(away, axis=1, keepdims=True)
    return state, goal, orbits


def test_a_press_whose_way_out_crosses_an_orbit_disc_is_refused() -> None:
    """The trained run pressed the goal button 0.015 m outside an orbit disc, in a pocket
    between two: certified by the static rule (one step, then braking, clear of every region;
    the goal button is none), the pressed button then a wrong one that its exit left into the
    disc, where the gremlin touched it 41 steps after the press. From its pose the step before
    the press, no exit plan leaves the button without entering a disc: refused. With the discs
    0.3 m farther away, or with the robot farther from the button a few steps earlier, the
    same press is not refused."""
    model = robot_model("point")
    state, goal, orbits = _pocket(42864)
    assert len(orbits) >= 2
    assert presses_without_exit(model, state, goal, orbits, 0.05).all()
    state, goal, orbits = _pocket(42864, shift=0.3)
    assert not presses_without_exit(model, state, goal, orbits, 0.05).any()
    assert not presses_without_exit(model, *_pocket(42860), 0.05).any()


def test_the_exit_reach_bounds_every_exit_from_a_press() -> None:
    """Oracle: the model's own steps. From a press (at rest, or with the few centimetres per
    second a contact leaves), every exit plan (an escape held 1 to 10 steps, then braked) stays
    within the exit reach and the filter's margin of where it started."""
    for robot in ROBOTS:
        model = robot_model(robot)
        holds = np.tile(np.arange(1, EXIT_STEPS + 1), len(model.escapes))
        for vx, vy in ((0.0, 0.0), (0.04, -0.03), (-0.05, 0.0)):
            points = rollout(model, RobotState(0.0, 0.0, vx, vy, 0.7, 0.0), None,
                             np.repeat(model.escapes, EXIT_STEPS, axis=0), holds,
                             EXIT_STEPS + model.horizon)
            assert np.hypot(points[..., 0], points[..., 1]).max() <= exit_reach(model) + 0.05


def test_a_region_that_widens_around_the_car_does_not_end_its_kept_plan() -> None:
    """A trained CarButton1 run (its epoch 6 replayed with the kept static rows): the Car
    0.033 m outside a wrong button's contact region, its plan certified against two rows of
    that button; the next LiDAR row of the button is 0.056 m wider than the button's region and
    holds the Car, and the moving certificate gave up its plan ("inside a static region"),
    chattered and was hit by a gremlin 63 steps later. A kept row of the button's own (read
    above both neighbours) holds the same button (the spreads and the distance under the two
    buttons' keepouts) and the Car is outside it: not inside. Without a kept plan, with a
    planted row that no kept row explains, or with the Car inside the kept row too: inside.
    With no margin: the Car is 0.023 m into today's row, within the default margin, which
    clears it alone (:func:`test_a_car_in_a_buttons_margin_keeps_planning`)."""
    fx = json.loads(KEPT_FRAMES.read_text())["region_widens"]
    state = RobotState(*fx["state"])
    kept, today = _rows(**fx["kept_statics"]), _rows(**fx["today_statics"])
    button = np.array(fx["button"])
    shield = SafetyShield(margin=0.0, gremlins="moving")
    inside = np.hypot(today.rows[:, 0] - state.x, today.rows[:, 1] - state.y) < today.rows[:, 2]
    assert inside.sum() == 1
    assert np.hypot(*(today.rows[inside, :2] - button[:2]).T)[0] < 0.1  # the button's row
    assert shield._inside_static(state, today)  # no kept plan: today's rows
    shield._plan_seen = _statics_only(kept)
    assert not shield._inside_static(state, today)
    planted = _rows([[state.x + 0.1, state.y - 0.1, 0.3]], [0.05], 0.18)
    assert len(planted.unexplained_by(kept).rows) == 1
    assert shield._inside_static(state, today.plus(planted))
    holding = kept.where(np.hypot(kept.rows[:, 0] - button[0], kept.rows[:, 1] - button[1])
                         < 0.15)
    assert len(holding.rows)
    grown = holding._replace(rows=holding.rows + np.array([0.0, 0.0, 0.1]))  # the Car in it too
    shield._plan_seen = _statics_only(grown)
    assert shield._inside_static(state, today)


def test_an_alias_row_does_not_clear_a_button_the_robot_pressed() -> None:
    """``semdp-bench safety`` (MassButton1, goal-seeking subgoals, seed 34000): the Mass
    presses the goal button, inside the button's own rows; a kept row of the goal LiDAR 0.095 m
    off the button is a neighbour bin's alias (no object of its own) and the Mass is outside it.
    Taken for the button, it cleared the Mass, which followed its plan and rested on the
    button, a wrong one once the goal moved, until its grace period ended (``cost_buttons``).
    An alias row explains nothing: inside."""
    fx = json.loads(KEPT_FRAMES.read_text())["mass_pressed"]
    state = RobotState(*fx["state"])
    kept, today = _rows(**fx["kept_statics"]), _rows(**fx["today_statics"])
    shield = SafetyShield(gremlins="moving")
    shield._plan_seen = _statics_only(kept)
    assert shield._inside_static(state, today)
    near = np.hypot(kept.rows[:, 0] - fx["button"][0], kept.rows[:, 1] - fx["button"][1]) < 0.2
    outside = np.hypot(kept.rows[:, 0] - state.x, kept.rows[:, 1] - state.y) >= kept.rows[:, 2]
    assert (near & outside & ~kept.own).any() and not (near & outside & kept.own).any()
    shield._plan_seen = _statics_only(kept._replace(own=np.ones(len(kept.own), bool)))
    assert not shield._inside_static(state, today)  # every row taken for an object's own


def test_a_car_in_a_buttons_margin_keeps_planning() -> None:
    """The same run replayed further: the Car, following a plan inside an orbit disc, drifted
    0.017 m into a wrong button's region, within the margin (0.002 m outside the button's
    contact region plus margin, by the simulator). Counted as inside, the moving certificate
    gave up its plan; the static escapes chattered and a gremlin touched the Car 20 steps
    later. Within the margin it is not inside (the plans' depth floor keeps them out of the
    button); with no margin it is."""
    fx = json.loads(KEPT_FRAMES.read_text())["car_in_margin"]
    state = RobotState(*fx["state"])
    today = _rows(**fx["today_statics"])
    depth = (np.hypot(today.rows[:, 0] - state.x, today.rows[:, 1] - state.y)
             - today.rows[:, 2])
    assert -0.05 < depth.min() < 0.0
    shield = SafetyShield(gremlins="moving")
    assert not shield._inside_static(state, today)
    assert SafetyShield(margin=0.0, gremlins="moving")._inside_static(state, today)


def test_a_gremlin_row_is_in_sight_of_a_frame_within_the_lidar_range() -> None:
    """Oracle by hand: a gremlin's body at ``home + o(t)``; a row may hold a gremlin whose
    home lies within its spread of the row's centre. In sight when the body's distance from
    where the frame was read, plus the spread and the law's tolerance (0.005 m), is under the
    range (3 m) less 0.001 m."""
    t = 1.3
    o = gremlin_offset(t)
    homes = _rows([[2.0 - o[0], -o[1], 0.76]] * 4 + [[-o[0], 2.5 - o[1], 0.76]],
                  [0.9, 0.993, 0.995, np.inf, 0.49], 0.4)
    frame = KeptFrame(_rows([], [], 0.4), _rows([], [], 0.4), (0.0, 0.0), t)
    # 2 + 0.9 + 0.005 = 2.905, 2.998, 3.0, inf; 2.5 + 0.49 + 0.005 = 2.995 (< 2.999)
    np.testing.assert_array_equal(frame.in_sight(homes), [True, True, False, False, True])
    # read 0.5 s later the bodies sit elsewhere on their orbits (0.35 m from home)
    later = frame._replace(time=t + 0.5)
    body = homes.rows[:, :2] + gremlin_offset(t + 0.5)
    far = np.hypot(*body.T) + homes.spread + 0.005
    np.testing.assert_array_equal(later.in_sight(homes), far < 2.999)
    assert (later.in_sight(homes) != frame.in_sight(homes)).any()


def _gremlin_in_sight() -> tuple[KeptFrame, dict]:
    """The frames of ``kept_plan_frames.json``'s ``gremlin_in_sight`` entry."""
    fx = json.loads(KEPT_FRAMES.read_text())["gremlin_in_sight"]

    def regions(node: dict) -> Regions:
        return Regions(np.array(node["rows"]).reshape(-1, 3), np.array(node["contact"], bool),
                       np.array(node["orbit"], bool), np.array(node["spread"]),
                       np.array(node["keepout"]), np.array(node["own"], bool))

    then, now = fx["certified"], fx["next"]
    frame = KeptFrame(regions(then["statics"]), regions(then["homes"]),
                      tuple(then["position"]), then["time"])
    return frame, {**now, "statics": regions(now["statics"]), "homes": regions(now["homes"]),
                   "plan": Plan(tuple(now["plan"][0]), now["plan"][1])}


def test_a_gremlin_row_in_sight_of_the_kept_frame_does_not_end_the_plan() -> None:
    """``semdp-bench safety`` (CarButton1, goal-seeking subgoals, seeds 33000, episode 16):
    the Car inside an orbit disc follows a plan certified against a frame read 0.08 s before.
    Today's gremlin rows hold four candidates that no kept row of an object's own explains
    (one a far candidate with a 0.46 m bound), and with them added the plan is not certified:
    the Car lost its plan, found none certified for 50 steps and was hit (41 cost steps).
    Every one of them lay within the LiDAR's range when the kept frame was read, so any gremlin
    it may hold lit a row of that frame, which the plan is clear of: the plan is kept. Read
    3 m farther away, the frame had not seen them all: they are added and the plan is lost."""
    frame, now = _gremlin_in_sight()
    model = robot_model("car")
    state = RobotState(*now["state"])
    gremlins = Gremlins(now["homes"].rows, now["time"], model.h * model.substeps)
    start = np.array(now["start"])
    added = now["homes"].unexplained_by(frame.homes)
    assert len(added.rows) and frame.in_sight(added).all()
    statics = frame.statics.plus(now["statics"].unexplained_by(frame.statics))
    points, ends = moving_certificate.plan_points(model, state, start, [now["plan"]])
    every = Gremlins(frame.homes.plus(added).rows, now["time"], gremlins.dt)
    assert moving_certificate.clearances(points, ends, state, statics.rows, every, 0.05)[0] < 0.0
    shield = SafetyShield(gremlins="moving")

    def kept(seen: KeptFrame) -> KeptFrame | None:
        shield._plan_seen = seen
        return shield._kept_frame(model, state, start, now["plan"], now["statics"],
                                  now["homes"], gremlins)

    assert kept(frame) is not None
    far = frame._replace(position=(frame.position[0] + 3.0, frame.position[1]))
    assert not far.in_sight(added).all()
    assert kept(far) is None
