"""semdp's files of earlier versions (semdp/legacy.py, read on loading only): every committed run
config loads in today's form, and objects pickled before an attribute or option existed come
back as they ran (through the checkpoint loader's unpickler)."""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest
from hydra.utils import instantiate
from omegaconf import OmegaConf

from semdp import legacy
from semdp.embedded.shield import SafetyShield
from semdp.run_config import load_run_config
from solvers.planner import PlannerSettings
from solvers.planner import legacy as planner_legacy

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = sorted((ROOT / "outputs" / "reference").rglob("config.yaml"))


def _nodes(node: object, path: str = ""):
    if isinstance(node, dict):
        yield path, node
        for key, value in node.items():
            yield from _nodes(value, f"{path}.{key}")
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _nodes(value, f"{path}[{i}]")


def test_every_committed_run_config_loads_in_todays_form() -> None:
    """No planner node of an earlier form, no recorded boolean bearing bound, no moved target
    is left; every planner node's settings equal those of its flat form read directly."""
    from hydra._internal.utils import _locate

    assert len(CONFIGS) > 100
    targets, planners, flat = set(), 0, 0
    for path in CONFIGS:
        raw = OmegaConf.to_container(OmegaConf.load(path), resolve=False)
        upgraded = OmegaConf.to_container(load_run_config(path), resolve=False)
        for where, node in _nodes(upgraded):
            target = node.get("_target_")
            targets.add(target)
            assert target not in legacy.RENAMED_TARGETS, (path, where)
            if target == legacy.SHIELD_TARGET:
                assert node.get("lidar_bearing_bound", "aliasing") in ("aliasing", "bin", "none")
            if target == planner_legacy.PLANNER_TARGET:
                planners += 1
                assert not planner_legacy.is_old_planner_node(node), (path, where)
                before = dict(_nodes(raw))[where]
                if isinstance(before.get("backend"), str):  # saved flat: the same settings
                    flat += 1
                    settings = instantiate(OmegaConf.create(node)).settings
                    state = {k: v for k, v in before.items() if k != "_target_"}
                    assert settings == planner_legacy.settings_from_flat(state), (path, where)
    assert planners > 100 and flat > 10
    missing = []
    for target in sorted(t for t in targets if isinstance(t, str)):
        try:
            _locate(target)
        except ImportError:
            missing.append(target)
    assert not missing, f"committed run configs name objects that no longer exist: {missing}"


def test_a_config_of_todays_form_is_left_as_it_is() -> None:
    from semdp.configs import compose_config

    cfg = compose_config("train", ["experiment=semdp", "budget=ci"])
    saved = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
    assert legacy.upgrade_run_config(OmegaConf.create(saved)) == saved


def _legacy_copy(obj: object, drop: tuple[str, ...] = (), **set_: object) -> object:
    """``obj`` pickled as a version without the attributes ``drop`` (and with ``set_``) would
    have pickled it, read back by the checkpoint loader's unpickler."""
    for name in drop:
        del obj.__dict__[name]
    obj.__dict__.update(set_)
    return legacy.loads(pickle.dumps(obj))


def test_a_filter_pickled_before_the_fallback_and_kernel_options_resumes_as_it_was() -> None:
    restored = _legacy_copy(SafetyShield(), drop=("fallback", "kernel", "_buttons"))
    assert type(restored) is SafetyShield
    assert (restored.fallback, restored.kernel, restored._buttons) == ("escape", "compiled", None)
    today = legacy.loads(pickle.dumps(SafetyShield(kernel="python", fallback="brake")))
    assert (today.fallback, today.kernel) == ("brake", "python")  # today's pickles: as they are


def test_a_kept_plan_pickled_without_where_it_was_read_is_planned_afresh() -> None:
    """A filter pickled mid-episode kept its plan's frame as a (statics, homes) pair, without
    the position and time a gremlin row's sight is judged from: the plan and its frame are
    dropped (the next step plans afresh); today's frames come back as they are."""
    from semdp.embedded.cost_regions import no_regions
    from semdp.embedded.moving_certificate import KeptFrame, Plan

    plan = Plan((1.0, 0.0), 5)
    old = _legacy_copy(SafetyShield(), _plan=plan, _plan_seen=(no_regions(), no_regions()))
    assert (old._plan, old._plan_seen) == (None, None)
    frame = KeptFrame(no_regions(), no_regions(), (0.5, -0.2), 3.0)
    today = _legacy_copy(SafetyShield(), _plan=plan, _plan_seen=frame)
    assert today._plan == plan and today._plan_seen.position == (0.5, -0.2)


@pytest.mark.parametrize(("recorded", "bound"), [(True, "bin"), (False, "none")])
def test_a_filter_pickled_with_a_boolean_bound_resumes_as_it_was(recorded, bound) -> None:
    assert _legacy_copy(SafetyShield(), lidar_bearing_bound=recorded).lidar_bearing_bound == bound


def test_a_config_recorded_with_a_boolean_bound_reads_bin() -> None:
    cfg = OmegaConf.create({"shield": {"_target_": legacy.SHIELD_TARGET,
                                       "lidar_bearing_bound": True}})
    assert instantiate(legacy.upgrade_run_config(cfg).shield).lidar_bearing_bound == "bin"


def test_an_on_policy_config_recorded_before_the_written_kernel_reads_autograd() -> None:
    """Such a run ran autograd's derivatives; today's config default is ``written``."""
    old = OmegaConf.create({"algo": {"_target_": "semdp.algos.PPOLag", "vectorization": "auto"},
                            "sac": {"_target_": "semdp.algos.SAC"}})
    upgraded = legacy.upgrade_run_config(old)
    assert upgraded.algo.gradients == "autograd" and "gradients" not in upgraded.sac
    today = OmegaConf.create({"algo": {"_target_": "semdp.algos.CPO", "gradients": "written"}})
    assert legacy.upgrade_run_config(today).algo.gradients == "written"


def test_a_blob_pickled_inside_a_checkpoint_is_read_the_same_way() -> None:
    """A rollout helper pickles its sub-envs into the checkpoint as ``pickle.loads(blob)``: the
    blob's old objects are upgraded too."""
    shield = SafetyShield()
    del shield.__dict__["kernel"]

    class Blob:
        def __reduce__(self):
            return pickle.loads, (pickle.dumps(shield),)

    assert legacy.loads(pickle.dumps(Blob())).kernel == "compiled"


def test_old_planner_pickles_are_read_through_the_checkpoint_unpickler() -> None:
    fixture = pickle.loads((ROOT / "tests" / "data" / "legacy_planners.pkl").read_bytes())
    planners = legacy.loads(fixture["planners"])
    assert all(type(p.settings) is PlannerSettings for p in planners.values())


def test_classes_pickled_from_the_fast_package_load_from_their_new_modules() -> None:
    """``semdp.algos.fast`` was split into kernels and helper processes: a checkpoint that
    pickled one of its classes finds it where it lives now."""
    import io
    import pickle

    from semdp.algos.helpers.option_probe import FasterOption
    from semdp.algos.kernels.written import WrittenDerivatives

    unpickler = legacy.Unpickler(io.BytesIO(pickle.dumps(None)))
    assert unpickler.find_class("semdp.algos.fast.option_probe", "FasterOption") is FasterOption
    assert unpickler.find_class("semdp.algos.fast.written",
                                "WrittenDerivatives") is WrittenDerivatives
