"""Planner settings and pickles from before the settings were split (solvers/planner/settings.py,
``PlannerSettings.from_flat``; solvers/planner/legacy_pickles.py): flat keywords, a saved flat
``config.yaml`` node with ``semdp-eval``'s shorthands, and planners pickled by the old code
(tests/data/legacy_planners.pkl) plan exactly as they did."""

from __future__ import annotations

import importlib
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
)

ROOT = Path(__file__).resolve().parents[1]
SAVED_RUN = ROOT / "outputs" / "reference" / "archive" / "semdp_converged" / "point_push1_s0"
PROBLEM = ([0.0, 0.0], [2.5, 1.0], [[1.0, 0.3], [0.4, -0.8], [1.8, 1.2]])


def test_flat_keywords_give_the_split_settings() -> None:
    planner = SafeTrajectoryPlanner(backend="lm", lm_adaptive=True, lm_iterations=7,
                                    clearance=0.6, rescue_backend="ipopt", ipopt_max_iter=100,
                                    scp_trust_region=0.5)
    assert planner.settings == PlannerSettings(
        ProblemSettings(clearance=0.6), LMSettings(iterations=7, adaptive=True),
        IpoptSettings(max_iter=100))  # the ipopt_* keys configure the rescue
    scp = SafeTrajectoryPlanner(backend="scp", scp_trust_region=0.5, lm_margin=0.03)
    assert scp.settings == PlannerSettings(backend=SCPSettings(trust_region=0.5))


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"backend": "ipopt", "lm_lambda": 2048.0}, ValueError,
         r"lm settings \(lm_\* keys\): lambda_ \(2048.0\) must be <= lambda_max"),
        ({"backend": "lm", "ipopt_options": [1]}, ValueError, "options must be a mapping"),
        ({"backend": "lm", "lm_iterations": 0}, ValueError, "iterations must be an integer >= 1"),
        ({"backend": LMSettings(), "lm_adaptive": True}, ValueError, "need the backend as a name"),
        ({"backend": "lm", "lm_adaptiv": True}, TypeError, "unexpected keyword"),
        ({"backend": "sqp", "lm_adaptive": True}, ValueError, "backend must be one of"),
    ],
)
def test_flat_keywords_are_validated(kwargs, error, match) -> None:
    with pytest.raises(error, match=match):
        SafeTrajectoryPlanner(**kwargs)


def test_from_flat_names_unknown_keys() -> None:
    with pytest.raises(ValueError, match=r"unknown planner settings \['lm_lambada'\]"):
        PlannerSettings.from_flat({"backend": "lm", "lm_lambada": 2.0})


def _saved_config():
    return OmegaConf.load(SAVED_RUN / "config.yaml")


def test_a_saved_flat_node_plans_as_the_composed_node() -> None:
    from semdp.configs import compose_node

    saved = _saved_config().env.eval_wrapper.planner
    assert saved.backend == "lm" and saved.lm_adaptive is True  # the flat form
    old = instantiate(saved)
    new = instantiate(compose_node("planner", "lm_adaptive", ["rescue_backend=ipopt"]))
    assert old.settings == new.settings
    a = old.plan(*PROBLEM, warm_start=False)
    b = new.plan(*PROBLEM, warm_start=False)
    np.testing.assert_array_equal(a.waypoints, b.waypoints)


def test_eval_shorthands_edit_flat_and_split_nodes() -> None:
    from semdp.evaluation.config_edits import edited_config
    from semdp.evaluation.options import parse_arguments

    saved = _saved_config()
    fixed = edited_config(saved, parse_arguments(["lambda=fixed", "clearance=0.6"]))
    node = fixed.env.eval_wrapper.planner
    assert node.lm_adaptive is False and node.clearance == 0.6  # still flat
    assert instantiate(node).settings.backend.adaptive is False
    replaced = edited_config(saved, parse_arguments(["planner=lm_adaptive", "lambda=fixed"]))
    node = replaced.env.eval_wrapper.planner
    assert node.backend._target_ == "solvers.planner.LMSettings" and node.backend.adaptive is False
    assert node.rescue_backend == "ipopt" and "lm_adaptive" not in node
    assert saved.env.eval_wrapper.planner.lm_adaptive is True  # the saved config is untouched


def test_planners_pickled_by_the_old_code_plan_as_they_did() -> None:
    """The fixture holds three planners pickled before the split (LM + rescue, continuous SCP,
    IPOPT with options), each with a previous plan in its warm-start memory, and the waypoints
    the old code planned after unpickling them (warm-started)."""
    fixture = pickle.loads((ROOT / "tests" / "data" / "legacy_planners.pkl").read_bytes())
    planners = pickle.loads(fixture["planners"])
    assert planners["lm_rescue"].settings == PlannerSettings(
        ProblemSettings(n_waypoints=6, clearance=0.4), LMSettings(iterations=7, adaptive=True),
        IpoptSettings())
    assert planners["ipopt"].settings.backend == IpoptSettings(first_max_iter=0,
                                                               options={"tol": 1e-6})
    for name, planner in planners.items():
        assert planner.memory.previous is not None, name
        result = planner.plan(*fixture["problem"], warm_start=True)
        # the same plan to the last few bits: numpy's and IPOPT's kernels depend on the processor
        # (an AVX-512 machine differs from the recording by up to 2e-11 m, IPOPT at tol 1e-6)
        np.testing.assert_allclose(result.waypoints, fixture["expected_waypoints"][name],
                                   rtol=0.0, atol=1e-9)
    again = pickle.loads(pickle.dumps(planners["lm_rescue"]))  # and they pickle the new way
    assert again.settings == planners["lm_rescue"].settings


def test_removed_classes_are_only_read_from_pickles() -> None:
    module = importlib.import_module("solvers.planner.lm_backend")
    with pytest.raises(TypeError, match="only read from old pickles"):
        module.LMBackend()
