"""Safe trajectory planner (thesis §3.5.2): planted solutions, the safety property, escape mode,
fallback, bad inputs, settings, batch, configs."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from solvers.planner import (
    IpoptSettings,
    LMSettings,
    PlannerSettings,
    ProblemSettings,
    SafeTrajectoryPlanner,
    SCPSettings,
    plan_batch,
    random_problems,
)
from solvers.planner.backends.lm import LMBackend
from solvers.planner.geometry import point_distances, segment_distances
from solvers.planner.problem import build_gp_prior

BACKENDS = ["ipopt", "lm", "scp"]
EPS = 0.5
CONF_PLANNER = Path(__file__).resolve().parents[1] / "conf" / "planner"


@pytest.fixture(scope="module")
def planners() -> dict[tuple[str, bool], SafeTrajectoryPlanner]:
    """One planner per (backend, continuous); LM in the adaptive (evaluation) mode."""
    return {
        (backend, continuous): SafeTrajectoryPlanner(
            backend=LMSettings(adaptive=True) if backend == "lm" else backend,
            problem=ProblemSettings(continuous=continuous),
        )
        for backend in BACKENDS
        for continuous in (False, True)
    }


def _sampled_segment_clearance(waypoints: np.ndarray, obstacles: np.ndarray) -> float:
    """Independent oracle: distance to obstacle surfaces sampled densely along the polyline."""
    t = np.linspace(0.0, 1.0, 201)[None, :, None]
    points = (waypoints[:-1, None, :] * (1 - t) + waypoints[1:, None, :] * t).reshape(-1, 2)
    radii = obstacles[:, 2] if obstacles.shape[1] == 3 else np.zeros(len(obstacles))
    diff = points[:, None, :] - obstacles[None, :, :2]
    return float((np.sqrt((diff**2).sum(-1)) - radii[None, :]).min())


def _check_property(planner: SafeTrajectoryPlanner, problems: list) -> None:
    for k, problem in enumerate(problems):
        result = planner.plan(problem.start, problem.subgoal, problem.obstacles, warm_start=False)
        assert not result.escape_mode
        assert result.feasible, (k, result.status)
        np.testing.assert_allclose(result.waypoints[0], problem.start, atol=1e-12)
        if len(problem.obstacles):
            obstacles = problem.obstacles
            radii = obstacles[:, 2] if obstacles.shape[1] == 3 else 0.0
            independent = point_distances(result.waypoints, obstacles[:, :2]) - radii
            assert independent.min() >= EPS - 1e-6, (k, result.status, independent.min())
            assert result.min_clearance == pytest.approx(independent.min(), abs=1e-12)
            if planner.problem.continuous:
                assert result.min_clearance_continuous >= EPS - 1e-6, (k, result.status)
                sampled = _sampled_segment_clearance(result.waypoints, obstacles)
                assert sampled >= EPS - 1e-6, (k, result.status, sampled)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("subgoal", [(2.0, 0.0), (2.0, 2.0), (-1.5, 0.7), (0.0, -2.0)])
def test_planner_reaches_subgoal_in_open_space(planners, backend: str, subgoal) -> None:
    start = np.array([0.3, -0.2])
    goal = start + np.array(subgoal)
    result = planners[(backend, False)].plan(start, goal, [])
    assert np.linalg.norm(result.waypoints[-1] - goal) < 1e-3
    assert result.reached_subgoal and result.feasible and not result.fallback
    assert result.min_clearance == np.inf


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("continuous", [False, True])
def test_planner_bends_around_obstacle_on_straight_line(planners, backend, continuous) -> None:
    planner = planners[(backend, continuous)]
    result = planner.plan([0.0, 0.0], [2.0, 0.0], [[1.0, 0.0]])
    assert not result.fallback
    assert result.min_clearance >= EPS - 1e-6
    if continuous:
        assert result.min_clearance_continuous >= EPS - 1e-6
    # it goes around (one side), not stopping in front of the obstacle
    assert np.abs(result.waypoints[:, 1]).max() > 0.45
    assert np.linalg.norm(result.waypoints[-1] - [2.0, 0.0]) < 0.05
    assert np.all(np.sign(result.waypoints[1:, 1]) == np.sign(result.waypoints[15, 1]))


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("continuous", [False, True])
def test_planner_property_every_waypoint_keeps_clearance(planners, backend, continuous) -> None:
    problems = random_problems(60, seed=11) + random_problems(40, seed=12, radius_share=1.0)
    _check_property(planners[(backend, continuous)], problems)


@pytest.mark.slow
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("continuous", [False, True])
def test_planner_property_every_waypoint_keeps_clearance_1000(planners, backend, continuous):
    problems = random_problems(700, seed=100) + random_problems(300, seed=101, radius_share=1.0)
    _check_property(planners[(backend, continuous)], problems)


@pytest.mark.parametrize("backend", BACKENDS)
def test_planner_fixed_lambda_lm_is_also_safe(backend) -> None:
    planner = SafeTrajectoryPlanner(backend=backend)  # LM's default: fixed lambda
    _check_property(planner, random_problems(40, seed=21))


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("continuous", [False, True])
@pytest.mark.parametrize(
    "obstacles",
    [
        [[0.3, 0.1], [1.5, 1.5]],  # one violated, one clear
        [[0.1, 0.0], [-0.1, 0.0]],  # between two violated ones (outward directions cancel)
        [[0.3, 0.1], [-0.2, 0.45]],  # two violated ones
        [[0.0, 0.0], [1.2, 0.0]],  # start exactly at a centre
    ],
)
def test_planner_escape_mode_leaves_without_getting_closer(
    planners, backend, continuous, obstacles
) -> None:
    start = np.zeros(2)
    obstacles = np.array(obstacles)
    result = planners[(backend, continuous)].plan(start, [2.0, 0.0], obstacles)
    assert result.escape_mode and not result.feasible and not result.fallback
    start_distances = np.linalg.norm(obstacles - start, axis=1)
    violated = start_distances < EPS
    distances = (segment_distances if continuous else point_distances)(result.waypoints, obstacles)
    assert np.all(distances[:, violated] >= start_distances[violated] - 1e-6)
    assert np.all(distances[:, ~violated] >= EPS - 1e-6)
    # it leaves: the deepest violation at the end is smaller than at the start
    depth_end = EPS - np.linalg.norm(result.waypoints[-1] - obstacles[violated], axis=1)
    assert np.max(depth_end) < np.max(EPS - start_distances[violated]) - 0.05


@pytest.mark.parametrize("backend", BACKENDS)
def test_planner_falls_back_to_stationary_when_backend_plan_is_unsafe(monkeypatch, backend):
    planner = SafeTrajectoryPlanner(backend=backend)
    original = planner.solver.solve

    def unsafe(prep, warm):
        plan = original(prep, warm)
        plan.z[: 2 * (planner.n_waypoints - 1)] = np.tile(prep.centres[0], planner.n_waypoints - 1)
        return plan

    monkeypatch.setattr(planner.solver, "solve", unsafe)
    result = planner.plan([0.0, 0.0], [2.0, 0.0], [[1.0, 0.0]])
    assert result.fallback and result.status.startswith("fallback")
    assert result.feasible
    np.testing.assert_array_equal(result.waypoints, np.zeros((30, 2)))
    np.testing.assert_array_equal(result.velocities, np.zeros((30, 2)))


# Recorded from a CarPush1 evaluation episode: the robot root 0.44 m from one hazard and 0.51 m
# from another whose centres are 0.88 m apart, so every point between them is inside a clearance.
# LM (fixed or adaptive lambda) cannot find an escape plan its certificate accepts; IPOPT can.
CAR_ESCAPE = (
    [-0.04953882, -0.32584997],
    [-1.76023832, -2.06276834],
    [[-0.2285962, 0.14792139], [-0.2312672, -0.72840131], [0.68019654, -1.10284113]],
)


@pytest.mark.parametrize("adaptive", [False, True])
def test_ipopt_rescues_an_lm_escape_plan_that_fails_the_certificate(adaptive) -> None:
    start, subgoal, obstacles = CAR_ESCAPE
    lm = LMSettings(adaptive=adaptive)
    plain = SafeTrajectoryPlanner(backend=lm).plan(start, subgoal, obstacles)
    assert plain.fallback and plain.escape_mode and not plain.rescued
    result = SafeTrajectoryPlanner(backend=lm, rescue_backend="ipopt").plan(
        start, subgoal, obstacles)
    assert result.rescued and not result.fallback and result.escape_mode
    assert result.backend == "lm" and result.status.startswith("rescued by ipopt")
    centres = np.array(obstacles)
    start_distances = np.linalg.norm(centres - start, axis=1)
    violated = start_distances < EPS
    distances = point_distances(result.waypoints, centres)
    assert np.all(distances[:, violated] >= start_distances[violated] - 1e-6)
    assert np.all(distances[:, ~violated] >= EPS - 1e-6)
    # it leaves: the end is outside every clearance (the start was 0.06 m inside one)
    assert np.min(np.linalg.norm(centres - result.waypoints[-1], axis=1)) > EPS - 1e-3


def test_rescue_is_not_used_when_the_backend_plan_passes(monkeypatch) -> None:
    planner = SafeTrajectoryPlanner(backend="lm", rescue_backend="ipopt").warmup()
    # warmup builds the rescue's (cold) programs
    assert {kind for _, kind in planner.rescue_solver.programs} == {"cold"}

    def forbidden(prep, warm):
        raise AssertionError("IPOPT must not run when LM's plan passes the certificate")

    monkeypatch.setattr(planner.rescue_solver, "solve", forbidden)
    result = planner.plan([0.0, 0.0], [2.0, 0.0], [[1.0, 0.3]])
    assert not result.rescued and not result.fallback and result.feasible
    assert SafeTrajectoryPlanner(backend="ipopt", rescue_backend="ipopt").rescue_backend is None


def test_planner_falls_back_when_backend_raises(monkeypatch) -> None:
    planner = SafeTrajectoryPlanner(backend="scp")

    def broken(prep, warm):
        raise RuntimeError("solver crashed")

    monkeypatch.setattr(planner.solver, "solve", broken)
    result = planner.plan([1.0, 1.0], [2.0, 0.0], [[1.0, 0.0]])
    assert result.fallback and "solver crashed" in result.status
    np.testing.assert_array_equal(result.waypoints, np.tile([1.0, 1.0], (30, 1)))


def test_planner_lm_adaptive_raises_lambda_until_certified() -> None:
    # a weak obstacle weight: fixed lambda = 1 ends inside the clearance (then shortened), the
    # adaptive mode doubles lambda until the full plan passes the certificate (App. B.2.3)
    weak = LMSettings(obstacle_weight=1.0, margin=0.01)
    start, subgoal = [2.3391915818202227, -1.4057515875805011], [0.36389889695733535, -0.5210884431]
    obstacles = [[3.4636816, -0.8881663], [0.0308653, -0.3905293], [-0.6212173, -3.3086943],
                 [1.8644620, -2.1355353]]
    fixed = SafeTrajectoryPlanner(backend=weak).plan(start, subgoal, obstacles)
    assert fixed.status.startswith("solved_shortened") and fixed.multiplier == 1.0
    adaptive = SafeTrajectoryPlanner(backend=dataclasses.replace(weak, adaptive=True))
    result = adaptive.plan(start, subgoal, obstacles)
    assert result.multiplier > 1.0 and result.status == "solved" and not result.fallback
    assert result.min_clearance >= EPS
    assert result.objective < fixed.objective


def test_planner_lm_repair_shortens_instead_of_falling_back() -> None:
    # a penalty solution without margin always ends slightly inside: it is shortened, not dropped
    planner = SafeTrajectoryPlanner(backend=LMSettings(margin=0.0))
    result = planner.plan([0.0, 0.0], [2.0, 0.0], [[1.0, 0.0]])
    assert result.status.startswith("solved_shortened")
    assert result.min_clearance >= EPS and not result.fallback


@pytest.mark.parametrize("obstacles", [[], None, np.zeros((0, 2)), np.zeros((0, 3))])
def test_planner_accepts_empty_obstacles(planners, obstacles) -> None:
    result = planners[("ipopt", False)].plan([0, 0], [1, 1], obstacles)
    assert result.feasible and result.reached_subgoal and result.n_considered == 0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"start": [0.0, np.nan]}, "start must be finite"),
        ({"subgoal": [np.inf, 0.0]}, "subgoal must be finite"),
        ({"start": [0.0, 0.0, 0.0]}, r"start must have shape \(2,\)"),
        ({"subgoal": "ab"}, "subgoal must"),
        ({"obstacles": [[1.0, 2.0, 3.0, 4.0]]}, r"obstacles must have shape \(m, 2\)"),
        ({"obstacles": [1.0, 2.0]}, r"obstacles must have shape \(m, 2\)"),
        ({"obstacles": [[1.0, np.nan]]}, "obstacles must be finite"),
        ({"obstacles": [[1.0, 1.0, -0.1]]}, "radii must be >= 0"),
        ({"obstacles": [[1.0, "x"]]}, "obstacles must be"),
    ],
)
def test_planner_rejects_bad_input(planners, kwargs, match) -> None:
    args = {"start": [0.0, 0.0], "subgoal": [1.0, 1.0], "obstacles": [[2.0, 2.0]]} | kwargs
    for backend in BACKENDS:
        with pytest.raises(ValueError, match=match):
            planners[(backend, False)].plan(**args)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"backend": "sqp"}, "backend must be one of"),
        ({"problem": {"clearance": 0.6}}, "problem must be a ProblemSettings"),
        ({"rescue_backend": "scp"}, "rescue_backend must be"),
        ({"backend": {"iterations": 5}}, "backend must be one of"),
    ],
)
def test_planner_constructor_rejects_bad_settings(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        SafeTrajectoryPlanner(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"clearance": -0.1}, "clearance must be"),
        ({"sigma_smooth": 0.0}, "sigma_smooth must be"),
        ({"n_waypoints": 2}, "n_waypoints must be"),
        ({"dt": float("nan")}, "dt must be"),
    ],
)
def test_problem_settings_reject_bad_values(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        ProblemSettings(**kwargs)


@pytest.mark.parametrize("backend", BACKENDS)
def test_planner_keeps_nearest_obstacles_and_certifies_all(backend) -> None:
    planner = SafeTrajectoryPlanner(backend=backend, problem=ProblemSettings(max_obstacles=2))
    rng = np.random.default_rng(3)
    obstacles = np.vstack([[1.0, 0.05], [1.6, -0.6], [0.9, 0.9], rng.uniform(-2, 3, (9, 2))])
    obstacles = obstacles[np.linalg.norm(obstacles, axis=1) > EPS + 0.05]
    result = planner.plan([0.0, 0.0], [2.5, 0.0], obstacles)
    assert result.n_considered == 2
    assert point_distances(result.waypoints, obstacles).min() >= EPS - 1e-9
    assert result.feasible


def test_planner_drops_unreachable_obstacles(planners) -> None:
    planner = planners[("ipopt", False)]
    result = planner.plan([0, 0], [1, 0], [[100.0, 0.0], [0.0, planner.reach + 1.0]])
    assert result.n_considered == 0 and result.feasible


@pytest.mark.parametrize("backend", BACKENDS)
def test_planner_batch_matches_loop(planners, backend) -> None:
    planner = planners[(backend, False)]
    problems = random_problems(12, seed=5)
    starts = [p.start for p in problems]
    subgoals = [p.subgoal for p in problems]
    obstacles = [p.obstacles for p in problems]
    # workers=1: one after the other here (helper processes: tests/test_planner_batch.py)
    batch = plan_batch(planner, starts, subgoals, obstacles, workers=1)
    loop = [
        planner.plan(s, g, o, warm_start=False)
        for s, g, o in zip(starts, subgoals, obstacles, strict=True)
    ]
    for a, b in zip(batch, loop, strict=True):
        np.testing.assert_allclose(a.waypoints, b.waypoints, atol=1e-9)
        assert a.fallback == b.fallback and a.feasible == b.feasible


def test_planner_batch_rejects_mismatched_shapes(planners) -> None:
    with pytest.raises(ValueError, match="one entry per start"):
        plan_batch(planners[("lm", False)], [[0, 0], [1, 1]], [[1, 1], [2, 2]], [[]])


def test_planner_warm_start_reuses_previous_plan(planners) -> None:
    planner = planners[("ipopt", False)]
    first = planner.plan([0, 0], [2, 0], [[1, 0.1]])
    second = planner.plan(first.waypoints[3], [2, 0], [[1, 0.1]], warm_start=True)
    assert second.feasible and not second.fallback and second.reached_subgoal


def test_planner_pickles_without_compiled_solvers(planners) -> None:
    import pickle

    for backend in BACKENDS:
        planner = planners[(backend, False)]
        before = planner.plan([0, 0], [2, 0], [[1, 0.1]], warm_start=False)
        clone = pickle.loads(pickle.dumps(planner))
        after = clone.plan([0, 0], [2, 0], [[1, 0.1]], warm_start=False)
        np.testing.assert_allclose(after.waypoints, before.waypoints, atol=1e-9)


def test_gp_prior_reach_matches_continuous_minimum_energy() -> None:
    # min over accelerations of int ||a||^2 from rest to displacement D in time T is 3 D^2 / T^3;
    # the discrete GP prior (exact for the constant-velocity model) gives the same coefficient.
    prior = build_gp_prior(30, 10.0 / 29.0)
    assert prior.reach_coef[-1] == pytest.approx(3.0 / 10.0**3, rel=1e-9)
    target = np.array([1.2, -0.7])
    assert prior.smoothness(prior.goal_map @ target) == pytest.approx(
        prior.reach_coef[-1] * target @ target, rel=1e-9
    )


def _compose_planner(name: str):
    """``conf/planner/<name>.yaml`` composed by Hydra (the files use defaults lists)."""
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=str(CONF_PLANNER.parent), version_base="1.3"):
        return compose(config_name=f"planner/{name}").planner


@pytest.mark.parametrize("name", ["ipopt", "lm", "lm_adaptive", "scp"])
def test_planner_configs_instantiate(name: str) -> None:
    from hydra.utils import instantiate

    planner = instantiate(_compose_planner(name))
    assert isinstance(planner, SafeTrajectoryPlanner)
    assert planner.backend == name.split("_")[0]
    backend = planner.settings.backend
    assert isinstance(backend, {"ipopt": IpoptSettings, "lm": LMSettings, "scp": SCPSettings}[
        planner.backend])
    assert getattr(backend, "adaptive", False) == (name == "lm_adaptive")
    # the node is the backend's defaults (and the problem's): the files change no default
    expected = dataclasses.replace(type(backend)(), adaptive=True) if name == "lm_adaptive" \
        else type(backend)()
    assert planner.settings == PlannerSettings(ProblemSettings(), expected)
    assert planner.plan([0, 0], [1, 0], [[0.5, 0.6]]).feasible


def test_the_problem_node_mirrors_the_problem_settings() -> None:
    """``conf/planner/_base.yaml``'s ``problem:`` holds exactly the fields of ProblemSettings,
    in order, with their defaults: a planner key is defined once (the dataclass)."""
    from omegaconf import OmegaConf

    node = OmegaConf.to_container(OmegaConf.load(CONF_PLANNER / "_base.yaml"))["problem"]
    assert node.pop("_target_") == "solvers.planner.ProblemSettings"
    fields = {f.name: f.default for f in dataclasses.fields(ProblemSettings)}
    assert list(node) == list(fields) and node == fields


@pytest.mark.parametrize("name", sorted(p.stem for p in CONF_PLANNER.glob("*.yaml")
                                        if not p.stem.startswith("_")))
def test_every_conf_planner_key_is_a_constructor_argument(name: str) -> None:
    import inspect

    from hydra.utils import get_class

    node = _compose_planner(name)
    parameters = inspect.signature(get_class(node._target_).__init__).parameters
    keys = set(node) - {"_target_"}
    assert keys <= set(parameters) - {"self"}, sorted(keys - set(parameters))
    backend = node.get("backend")
    if backend is not None:  # the backend node holds only its own class's knobs
        fields = {f.name for f in dataclasses.fields(get_class(backend._target_))}
        assert set(backend) - {"_target_"} == fields, (name, sorted(backend))
    if name.startswith(("lm", "ipopt", "scp")):
        assert not [k for k in node if k.startswith(("lm_", "ipopt_", "scp_"))]


@pytest.mark.parametrize(
    ("cls", "kwargs", "match"),
    [
        (ProblemSettings, {"continuous": "yes"}, "continuous must be a boolean"),
        (LMSettings, {"adaptive": 2}, "adaptive must be a boolean"),
        (ProblemSettings, {"n_waypoints": 3.5}, "n_waypoints must be an integer >= 3"),
        (LMSettings, {"iterations": "10"}, "iterations must be an integer"),
        (ProblemSettings, {"clearance": "0.5"}, "clearance must be a finite number >= 0"),
        (ProblemSettings, {"goal_tolerance": True}, "goal_tolerance must be a finite number > 0"),
        (IpoptSettings, {"options": ["tol", 1e-6]}, "options must be a mapping"),
        (ProblemSettings, {"max_obstacles": None}, "max_obstacles must be an integer"),
        (LMSettings, {"lambda_": 2048.0}, r"lambda_ \(2048.0\) must be <= lambda_max"),
        (LMSettings, {"margin": -0.01}, "margin must be a finite number >= 0"),
        (IpoptSettings, {"first_max_iter": -1}, "first_max_iter must be an integer >= 0"),
        (SCPSettings, {"trust_region": 0.0}, "trust_region must be a finite number > 0"),
        (SCPSettings, {"max_iterations": 0}, "max_iterations must be an integer >= 1"),
    ],
)
def test_settings_reject_wrong_types(cls, kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        cls(**kwargs)
    with pytest.raises(ValueError, match=match):  # as Hydra builds it: the node's object first
        SafeTrajectoryPlanner(**{"problem" if cls is ProblemSettings else "backend": cls(**kwargs)})


def test_settings_are_frozen_normalised_and_rebuild_the_planner() -> None:
    problem = ProblemSettings(n_waypoints=np.int64(20), continuous=np.bool_(True))
    settings = PlannerSettings(problem, LMSettings(iterations=np.int64(5)),
                               rescue=IpoptSettings(options={"tol": 1e-6}))
    assert type(problem.n_waypoints) is int and problem.continuous is True
    assert type(settings.backend.iterations) is int and settings.rescue_backend == "ipopt"
    rebuilt = PlannerSettings(dataclasses.replace(problem), dataclasses.replace(settings.backend),
                              IpoptSettings(options={"tol": 1e-6}))
    assert rebuilt == settings and hash(rebuilt) == hash(settings)
    with pytest.raises(dataclasses.FrozenInstanceError):
        problem.clearance = 0.6  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        settings.backend.iterations = 3  # type: ignore[misc]
    planner = SafeTrajectoryPlanner.from_settings(settings)
    assert planner.settings is settings and planner.n_waypoints == 20
    assert planner.problem is problem and planner.problem.continuous
    assert planner.solver.context.prior.n_waypoints == 20 and planner.backend == "lm"
    assert planner.rescue_solver.options["tol"] == 1e-6
    # nothing to rescue an IPOPT plan with; a name gives the backend's defaults
    assert PlannerSettings(backend="ipopt", rescue="ipopt").rescue is None
    assert PlannerSettings(backend="scp").backend == SCPSettings()
    with pytest.raises(AttributeError):
        planner.clearance = 0.6
    same = SafeTrajectoryPlanner(backend=settings.backend, rescue_backend=settings.rescue,
                                 problem=problem)
    assert same.settings == settings
    a = planner.plan([0, 0], [1.5, 0.5], [[0.8, 0.2]])
    b = same.plan([0, 0], [1.5, 0.5], [[0.8, 0.2]])
    np.testing.assert_array_equal(a.waypoints, b.waypoints)


def test_pickled_planner_drops_compiled_solvers_and_keeps_its_memory() -> None:
    import pickle

    planner = SafeTrajectoryPlanner(backend="lm", rescue_backend="ipopt")
    planner.rescue_solver.warmup([0], attempts=("cold",))
    planner.plan([0, 0], [2, 0], [[1, 0.1]])
    assert planner.solver.kernels and planner.rescue_solver.programs
    clone = pickle.loads(pickle.dumps(planner))
    assert clone.solver.kernels == {} and clone.rescue_solver.programs == {}
    assert clone.settings == planner.settings
    for got, want in zip(clone.memory.previous, planner.memory.previous, strict=True):
        np.testing.assert_array_equal(got, want)


def test_lm_iterates_say_whether_they_passed_and_the_planner_trusts_them(monkeypatch) -> None:
    """``Iterate.passed`` from the LM backend equals the certificate's check of its plan, and the
    planner that skips re-checking such plans before deciding on a rescue returns the plans of
    one that re-checks every plan (random problems, some failing, with the IPOPT rescue)."""
    rng = np.random.default_rng(7)
    problems = []
    for _ in range(60):
        m = int(rng.integers(0, 6))
        obstacles = np.column_stack([rng.uniform(-0.5, 2.5, (m, 2)), rng.uniform(0.0, 0.3, m)])
        problems.append((rng.uniform(-0.2, 0.2, 2), rng.uniform(0.5, 2.5, 2), obstacles))
    planner = SafeTrajectoryPlanner(backend=LMSettings(margin=0.0), rescue_backend="ipopt")
    certificate = planner.context.certificate
    seen = {True: 0, False: 0}
    for start, subgoal, obstacles in problems:
        prep = planner.context.prepare(start, subgoal, obstacles,
                                       reach=planner.solver.selection_reach)
        iterate = planner.solver.solve(prep, None)
        assert iterate.passed == certificate.passes(prep, iterate.z)
        seen[iterate.passed] += 1
    assert seen[True] and seen[False]
    trusted = [planner.plan(*p) for p in problems]
    original = LMBackend.repair
    monkeypatch.setattr(LMBackend, "repair", lambda self, prep, plan: dataclasses.replace(
        original(self, prep, plan), passed=False))
    rechecked = SafeTrajectoryPlanner(backend=LMSettings(margin=0.0), rescue_backend="ipopt")
    for a, (start, subgoal, obstacles) in zip(trusted, problems, strict=True):
        b = rechecked.plan(start, subgoal, obstacles)
        assert np.array_equal(a.waypoints, b.waypoints)
        assert (a.status, a.fallback, a.rescued) == (b.status, b.fallback, b.rescued)
