"""The planner's files of earlier versions (solvers/planner/legacy.py, read on loading only):
flat and split-but-flat-problem config nodes become today's node, a saved flat node plans as the
composed one, ``semdp-eval``'s shorthands edit it, and planners pickled by the old code
(tests/data/legacy_planners.pkl) plan exactly as they did."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
from hydra.utils import instantiate
from omegaconf import OmegaConf

from solvers.planner import (
    IpoptSettings,
    LMSettings,
    PlannerSettings,
    ProblemSettings,
    SafeTrajectoryPlanner,
    SCPSettings,
    legacy,
)

ROOT = Path(__file__).resolve().parents[1]
SAVED_RUN = ROOT / "outputs" / "reference" / "archive" / "semdp_converged" / "point_push1_s0"
PROBLEM = ([0.0, 0.0], [2.5, 1.0], [[1.0, 0.3], [0.4, -0.8], [1.8, 1.2]])


def _settings(node: dict) -> PlannerSettings:
    return instantiate(OmegaConf.create(legacy.planner_node(node))).settings


def test_flat_nodes_give_the_split_settings() -> None:
    flat = {"_target_": legacy.PLANNER_TARGET, "backend": "lm", "lm_adaptive": True,
            "lm_iterations": 7, "clearance": 0.6, "rescue_backend": "ipopt",
            "ipopt_max_iter": 100, "scp_trust_region": 0.5}
    assert _settings(flat) == PlannerSettings(
        ProblemSettings(clearance=0.6), LMSettings(iterations=7, adaptive=True),
        IpoptSettings(max_iter=100))  # the ipopt_* keys configure the rescue
    scp = {"_target_": legacy.PLANNER_TARGET, "backend": "scp", "scp_trust_region": 0.5,
           "lm_margin": 0.03}
    assert _settings(scp) == PlannerSettings(backend=SCPSettings(trust_region=0.5))
    pickled = {key: value for key, value in flat.items() if key != "_target_"}  # an object's state
    assert legacy.settings_from_flat(pickled) == _settings(flat)


def test_a_node_with_the_problem_beside_its_backend_node_nests_it() -> None:
    split = {"_target_": legacy.PLANNER_TARGET, "clearance": 0.7, "continuous": True,
             "backend": {"_target_": "solvers.planner.LMSettings", "iterations": 4},
             "rescue_backend": None}
    node = legacy.planner_node(split)
    assert node["problem"] == {"_target_": legacy.PROBLEM_TARGET, "clearance": 0.7,
                               "continuous": True}
    assert not legacy.is_old_planner_node(node) and legacy.planner_node(node) == node
    assert _settings(split) == PlannerSettings(ProblemSettings(clearance=0.7, continuous=True),
                                               LMSettings(iterations=4))


@pytest.mark.parametrize(
    ("flat", "match"),
    [
        ({"backend": "lm", "lm_lambada": 2.0}, r"unknown planner settings \['lm_lambada'\]"),
        ({"backend": "lm", "lm_iterations": 0}, "iterations must be an integer >= 1"),
        ({"backend": "sqp"}, "backend must be one of"),
    ],
)
def test_flat_settings_are_validated(flat, match) -> None:
    with pytest.raises(ValueError, match=match):
        legacy.settings_from_flat(flat)


def test_a_saved_flat_node_plans_as_the_composed_node() -> None:
    from semdp.configs import compose_node
    from semdp.run_config import load_run_config

    raw = OmegaConf.load(SAVED_RUN / "config.yaml").env.eval_wrapper.planner
    assert raw.backend == "lm" and raw.lm_adaptive is True  # the flat form, as committed
    saved = load_run_config(SAVED_RUN).env.eval_wrapper.planner
    assert saved.backend.adaptive is True and saved.problem.clearance == raw.clearance
    old = instantiate(saved)
    new = instantiate(compose_node("planner", "lm_adaptive", ["rescue_backend=ipopt"]))
    assert old.settings == new.settings
    a = old.plan(*PROBLEM, warm_start=False)
    b = new.plan(*PROBLEM, warm_start=False)
    np.testing.assert_array_equal(a.waypoints, b.waypoints)


def test_eval_shorthands_edit_a_saved_flat_node() -> None:
    from semdp.evaluation.config_edits import edited_config
    from semdp.evaluation.options import parse_arguments
    from semdp.run_config import load_run_config

    saved = load_run_config(SAVED_RUN)
    fixed = edited_config(saved, parse_arguments(["lambda=fixed", "clearance=0.6"]))
    node = fixed.env.eval_wrapper.planner
    assert node.backend.adaptive is False and node.problem.clearance == 0.6
    assert instantiate(node).settings.backend.adaptive is False
    replaced = edited_config(saved, parse_arguments(["planner=lm_adaptive", "lambda=fixed"]))
    node = replaced.env.eval_wrapper.planner
    assert node.backend._target_ == "solvers.planner.LMSettings" and node.backend.adaptive is False
    assert instantiate(node).settings.rescue == IpoptSettings() and "lm_adaptive" not in node
    assert saved.env.eval_wrapper.planner.backend.adaptive is True  # the saved config untouched


def test_planners_pickled_by_the_old_code_plan_as_they_did() -> None:
    """The fixture holds three planners pickled before the split (LM + rescue, continuous SCP,
    IPOPT with options), each with a previous plan in its warm-start memory, and the waypoints
    the old code planned after unpickling them (warm-started)."""
    fixture = pickle.loads((ROOT / "tests" / "data" / "legacy_planners.pkl").read_bytes())
    with pytest.raises(ModuleNotFoundError):  # the classes know nothing of earlier versions
        pickle.loads(fixture["planners"])
    planners = legacy.loads(fixture["planners"])
    assert planners["lm_rescue"].settings == PlannerSettings(
        ProblemSettings(n_waypoints=6, clearance=0.4), LMSettings(iterations=7, adaptive=True),
        IpoptSettings())
    assert planners["ipopt"].settings.backend == IpoptSettings(first_max_iter=0,
                                                               options={"tol": 1e-6})
    for name, planner in planners.items():
        assert type(planner) is SafeTrajectoryPlanner and type(planner.settings) is PlannerSettings
        assert planner.memory.previous is not None, name
        result = planner.plan(*fixture["problem"], warm_start=True)
        # the same plan to the last few bits: numpy's and IPOPT's kernels depend on the processor
        # (an AVX-512 machine differs from the recording by up to 2e-11 m, IPOPT at tol 1e-6)
        np.testing.assert_allclose(result.waypoints, fixture["expected_waypoints"][name],
                                   rtol=0.0, atol=1e-9)
    again = pickle.loads(pickle.dumps(planners["lm_rescue"]))  # and they pickle the new way
    assert again.settings == planners["lm_rescue"].settings


def test_removed_classes_are_only_read_from_pickles() -> None:
    stand_in = legacy.find_class("solvers.planner.lm_backend", "LMBackend")
    with pytest.raises(TypeError, match="only read from old pickles"):
        stand_in()
