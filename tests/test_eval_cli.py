"""``semdp-eval`` (docs/evaluation.md): real ``budget=ci`` SEMDP and
PPO-Lag runs evaluated with overrides and a video read back with imageio; every bad argument
gives one line on stderr and exit code 1; the shorthands on the saved config; the overlay."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import imageio.v2 as imageio
import numpy as np
import pytest
from omegaconf import OmegaConf

from semdp.evaluation.config_edits import edited_config
from semdp.evaluation.errors import EvalError
from semdp.evaluation.options import parse_arguments
from semdp.evaluation.run import evaluate_run
from semdp.legacy import upgrade_run_config
from semdp.rendering import video as video_module
from semdp.rendering.overlay import COST, PERCEIVED, FrameNotes, annotate, world_to_pixel
from semdp.rendering.recorder import FrameRecorder

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def _script(name: str) -> str:
    """A console script of this environment (beside the interpreter, else on PATH)."""
    path = BIN / name
    return str(path) if path.is_file() else (shutil.which(name) or name)


def _run(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run([*args], cwd=REPO, text=True, capture_output=True, timeout=600)
    if check:
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A ``budget=ci`` SEMDP run and a ``budget=ci`` PPO-Lag run."""
    root = tmp_path_factory.mktemp("runs")
    out = {"semdp": root / "semdp", "ppo_lag": root / "ppo_lag"}
    _run(_script("semdp-train"), "experiment=semdp", "budget=ci", f"hydra.run.dir={out['semdp']}")
    _run(_script("semdp-train"), "algo=ppo_lag", "env=point_goal1", "budget=ci",
         f"hydra.run.dir={out['ppo_lag']}")
    return out


def _eval_dirs(run_dir: Path) -> list[Path]:
    return sorted(run_dir.glob("eval_*"))


def _expected_frames(length: int, every: int) -> int:
    return 1 + length // every + (1 if length % every else 0)


def _read_frames(path: Path) -> list[np.ndarray]:
    frames = []
    with imageio.get_reader(path) as reader:  # its len() is inf for a video: no list(reader)
        for frame in reader:
            frames.append(frame)
    return frames


def test_semdp_run_evaluates_with_plan_statistics_and_an_mp4(runs: dict[str, Path]) -> None:
    before = _eval_dirs(runs["semdp"])
    proc = _run(_script("semdp-eval"), str(runs["semdp"]), "episodes=3", "lambda=fixed",
                "video=true", "video_every=5")
    (out_dir,) = sorted(set(_eval_dirs(runs["semdp"])) - set(before))
    assert str(out_dir) in proc.stdout
    metrics = json.loads((out_dir / "metrics.json").read_text())
    assert metrics["status"] == "completed" and metrics["label"] == "Ours [eval lambda=fixed]"
    assert metrics["arguments"] == ["episodes=3", "lambda=fixed", "video=true", "video_every=5"]
    assert metrics["settings"]["planner"]["backend"]["adaptive"] is False
    assert metrics["settings"]["seeds"] == [10000, 10001, 10002]
    episodes = metrics["episodes"]
    assert len(episodes) == 3 and metrics["eval"]["episodes"] == 3
    for episode in episodes:
        assert {"return", "cost", "length", "high_level_steps", "plan_fallbacks",
                "plan_escapes", "plan_rescues", "plan_min_clearance"} <= set(episode)
        assert episode["length"] == 10 * episode["high_level_steps"]
    ev = metrics["eval"]
    assert ev["return_mean"] == pytest.approx(np.mean([e["return"] for e in episodes]))
    assert ev["plans"] == sum(e["high_level_steps"] for e in episodes)
    assert ev["plan_min_clearance"] == min(e["plan_min_clearance"] for e in episodes)
    assert (out_dir / "config.yaml").is_file() and (out_dir / "progress.csv").is_file()
    video = metrics["video"]
    path = Path(video["path"])
    assert path.suffix == ".mp4" and path.parent == out_dir
    frames = _read_frames(path)
    assert len(frames) == video["frames"] == _expected_frames(episodes[0]["length"], 5)
    assert frames[0].shape == (512, 512, 3)


def test_ppo_lag_run_evaluates_and_writes_an_mp4(runs: dict[str, Path]) -> None:
    out_dir, metrics = evaluate_run(runs["ppo_lag"], ["episodes=2", "seed=7", "video=true",
                                                      "video_size=256"])
    assert out_dir.parent == runs["ppo_lag"]
    assert [e["seed"] for e in metrics["episodes"]] == [7, 8]
    assert metrics["eval"]["episodes"] == 2 and "plans" not in metrics["eval"]
    assert metrics["label"] == "ppo_lag [eval]" and metrics["settings"]["planner"] is None
    assert all(e["length"] == 1000 for e in metrics["episodes"])
    frames = _read_frames(Path(metrics["video"]["path"]))
    assert len(frames) == _expected_frames(1000, 2) == metrics["video"]["frames"]
    assert frames[0].shape == (256, 256, 3)
    on_disk = json.loads((out_dir / "metrics.json").read_text())
    assert on_disk["eval"] == metrics["eval"]


def test_sampled_actions_replay_per_seed_and_differ_from_the_mean_action(
    runs: dict[str, Path]
) -> None:
    args = ["episodes=2", "seed=3"]
    _, mean = evaluate_run(runs["ppo_lag"], args)
    _, sampled = evaluate_run(runs["ppo_lag"], [*args, "actions=sampled"])
    _, again = evaluate_run(runs["ppo_lag"], ["actions=sampled", "seeds=[3,4]"])
    assert mean["settings"]["actions"] == "mean" and sampled["settings"]["actions"] == "sampled"
    assert sampled["label"] == "ppo_lag [eval actions=sampled]"
    assert again["episodes"] == sampled["episodes"]  # torch seeded with each episode's seed
    assert [e["return"] for e in sampled["episodes"]] != [e["return"] for e in mean["episodes"]]


def test_transfer_variant_and_label_override(runs: dict[str, Path]) -> None:
    _, metrics = evaluate_run(runs["semdp"], ["variant=transfer", "episodes=2",
                                              "label=Ours on the variant"])
    assert metrics["label"] == "Ours on the variant"
    assert metrics["settings"]["variant"] == "transfer"
    assert metrics["settings"]["seeds"] == [20000, 20001]
    assert all(e["length"] <= 600 and e["success"] in (0.0, 1.0) for e in metrics["episodes"])


def _mixed_run(runs: dict[str, Path], tmp_path: Path) -> Path:
    """PPO-Lag's config with the SEMDP run's (SAC) checkpoint."""
    mixed = tmp_path / "mixed"
    (mixed / "checkpoints").mkdir(parents=True)
    shutil.copy(runs["ppo_lag"] / "config.yaml", mixed / "config.yaml")
    for name in ("last.pt", "last.pt.sig"):  # the account's own, signed
        shutil.copy(runs["semdp"] / "checkpoints" / name, mixed / "checkpoints" / name)
    return mixed


BAD: list[tuple[str, list[str], str]] = [
    ("missing", [], "no such run directory"),
    ("unfinished", [], "is not a finished run: no config.yaml and no checkpoints/last.pt"),
    ("ppo_lag", ["env.eval_wrapper.planer=lm"], "unknown key 'env.eval_wrapper.planer'"),
    ("semdp", ["env.eval_wrapper.planer=lm"], "unknown key 'env.eval_wrapper.planer'"),
    ("mixed", [], "checkpoints/last.pt was not written by ppo_lag"),
    ("ppo_lag", ["clearance=0.6"], "clearance= applies to Safety-Embedded MDP runs"),
    ("semdp", ["planner=nope"], "unknown planner 'nope'"),
    ("semdp", ["episodes=0"], "episodes must be an integer >= 1"),
    ("semdp", ["seeds=[1,2]", "episodes=3"], "episodes=3 but seeds= lists 2 seeds"),
    ("semdp", ["lambda=sometimes"], "lambda must be one of fixed|adaptive"),
    ("semdp", ["planner=ipopt", "lambda=fixed"], "lambda= needs the LM planner"),
    ("ppo_lag", ["variant=transfer"], "variant=transfer: the transfer variant needs"),
    ("semdp", ["env.eval_wrapper.k=0"], "cannot build the run with these overrides"),
    ("semdp", ["novalue"], "cannot read 'novalue'"),
    ("ppo_lag", ["actions=greedy"], "actions must be one of mean|sampled"),
]


def _bad_run_dir(runs: dict[str, Path], tmp_path: Path, run: str) -> Path:
    if run == "missing":
        return tmp_path / "nope"
    if run == "unfinished":
        return tmp_path
    if run == "mixed":
        return _mixed_run(runs, tmp_path)
    return runs[run]


@pytest.mark.parametrize(("run", "args", "message"), BAD, ids=[f"{r}-{m[:24]}" for r, _, m in BAD])
def test_bad_arguments_exit_with_one_line_and_write_nothing(
    runs: dict[str, Path], tmp_path: Path, run: str, args: list[str], message: str
) -> None:
    from semdp.cli.eval import main

    run_dir = _bad_run_dir(runs, tmp_path, run)
    before = _eval_dirs(run_dir) if run_dir.is_dir() else []
    with pytest.raises(SystemExit) as exit_info:  # SystemExit(str): exit code 1, str on stderr
        main([str(run_dir), *args])
    text = str(exit_info.value.code)
    assert text.startswith("semdp-eval: ") and message in text and "\n" not in text, text
    assert (_eval_dirs(run_dir) if run_dir.is_dir() else []) == before


@pytest.mark.parametrize("case", [0, 2, 4], ids=["missing", "unknown-key", "other-algorithm"])
def test_bad_arguments_from_the_console_script(
    runs: dict[str, Path], tmp_path: Path, case: int
) -> None:
    run, args, message = BAD[case]
    proc = _run(_script("semdp-eval"), str(_bad_run_dir(runs, tmp_path, run)), *args,
                check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert proc.stderr.startswith("semdp-eval: ") and message in proc.stderr


def test_no_arguments_prints_the_usage_in_one_line_and_exits_1() -> None:
    proc = _run(sys.executable, "-m", "semdp.cli.eval", check=False)
    assert proc.returncode == 1 and proc.stdout == ""
    assert proc.stderr.startswith("semdp-eval: semdp-eval RUN_DIR") and proc.stderr.count("\n") == 1


# ---------------------------------------------------------------- shorthands on a saved config
def _semdp_config() -> Any:
    from semdp.configs import compose_config

    cfg = compose_config("train", ["experiment=semdp", "env=semdp_car_push1", "budget=ci"])
    return OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))  # as saved


def test_planner_shorthand_composes_the_node_and_keeps_the_runs_clearance_and_rescue() -> None:
    saved = _semdp_config()
    saved.env.eval_wrapper.planner.problem.clearance = 0.6
    cfg = edited_config(saved, parse_arguments(["planner=lm"]))
    node = cfg.env.eval_wrapper.planner
    assert node.backend._target_ == "solvers.planner.LMSettings" and node.backend.adaptive is False
    assert node.problem.clearance == 0.6 and node.rescue_backend == "ipopt"  # the Car's rescue
    assert saved.env.eval_wrapper.planner.backend.adaptive is True  # the saved config is untouched
    straight = edited_config(saved, parse_arguments(["planner=straight"])).env.eval_wrapper
    assert straight.planner.rescue_backend is None and straight.planner.problem.clearance == 0.6
    both = edited_config(saved, parse_arguments(["clearance=0.25", "perception=gt",
                                                 "lambda=fixed"])).env.eval_wrapper
    assert (both.planner.problem.clearance, both.perception, both.planner.backend.adaptive) == (
        0.25, "gt", False)
    assert cfg.env.wrapper.planner.problem.clearance == 0.5  # training planner untouched


def test_legacy_string_planner_and_follower_become_nodes() -> None:
    legacy = OmegaConf.create({"env": {"id": "sims/SafetyPointPush1-v0", "wrapper": None,
                                       "eval_wrapper": {
        "_target_": "semdp.embedded.wrapper.SafetyEmbeddedEnv", "_partial_": True,
        "_recursive_": False, "planner": "lm_adaptive", "planner_kwargs": {"clearance": 0.6},
        "follower": "auto", "perception": "lidar"}}})
    cfg = edited_config(upgrade_run_config(legacy), parse_arguments(["lambda=fixed"]))
    node = cfg.env.eval_wrapper
    assert "planner_kwargs" not in node and "_recursive_" not in node and node.follower is None
    assert node.planner.problem.clearance == 0.6 and node.planner.backend.adaptive is False


def test_added_keys_and_parse_errors() -> None:
    saved = _semdp_config()
    cfg = edited_config(saved, parse_arguments(["+env.kwargs.render_size=128", "label=x"]))
    assert cfg.env.kwargs.render_size == 128 and cfg.label == "x"
    with pytest.raises(EvalError, match="give seed= or seeds="):
        parse_arguments(["seed=1", "seeds=[1]"])
    with pytest.raises(EvalError, match="given twice"):
        parse_arguments(["episodes=1", "episodes=2"])
    with pytest.raises(EvalError, match="one value per key"):
        parse_arguments(["seed=1,2"])


# ---------------------------------------------------------------- frames
def test_overlay_is_aligned_with_the_renderer_and_marks_cost() -> None:
    import sims  # noqa: F401

    env = gym.make("sims/SafetyPointGoal1-v0", render_mode="rgb_array", render_size=256)
    env.reset(seed=3)
    base = env.unwrapped
    frame = env.render()
    transform = world_to_pixel(base, 256)
    assert transform is not None
    px, _ = transform
    u, v = px(*map(float, base.body.position))
    assert tuple(frame[round(v) + 3, round(u) - 3]) == (210, 40, 40)  # the robot's colour
    hazard = np.array([[*base.hazards[0], 0.0]])
    notes = FrameNotes(5, 1.0, 1.0, True, perceived=hazard, clearance=0.3)
    drawn = annotate(frame, base, notes)
    hu, hv = px(*hazard[0, :2])
    assert tuple(drawn[round(hv), round(hu)]) == PERCEIVED
    assert tuple(drawn[1, 128]) == COST  # the red frame of a step with cost
    env.close()


def test_recorder_counts_frames_and_writes_a_gif_without_ffmpeg(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import sims  # noqa: F401

    env = FrameRecorder(gym.make("sims/SafetyPointGoal1-v0", render_mode="rgb_array",
                                 render_size=64, max_episode_steps=7), every=3)
    env.active = True
    env.reset(seed=0)
    done = False
    while not done:
        _, _, term, trunc, _ = env.step(env.action_space.sample())
        done = term or trunc
    assert len(env.frames) == _expected_frames(7, 3) == 4
    monkeypatch.setattr(video_module, "mp4_available", lambda: False)
    path = video_module.write_video(env.frames, tmp_path / "ep", fps=10)
    assert path.suffix == ".gif" and len(_read_frames(path)) == 4
    assert math.isclose(len(env.frames), 4)
