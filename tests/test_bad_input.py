"""Bad input gets one line, for every app: wrong types, NaN and infinity, zero or negative sizes,
empty lists, unknown keys and options, paths that do not exist, corrupt and misfitting policy
files. Each case runs the app's console entry point in a forked process (the imports paid
once) inside an empty working directory, and must end with exit status 1, exactly one line on
stderr, no traceback, no hang, and nothing left behind: no file in the working directory and
none added to the run directory it read. A few cases run the installed console scripts too."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
import torch

from semdp.cli import bench, plan, report, train
from semdp.cli import eval as eval_app
from semdp.evaluation.zoo import entries

TIMEOUT_S = 120.0
ENTRY = "semdp_point_push1_s0"

APPS: dict[str, Callable[[], None]] = {
    "semdp-train": train.main, "semdp-eval": eval_app.main, "semdp-plan": plan.main,
    "semdp-report": report.main, "semdp-bench": bench.main,
}

TRAIN = [  # budget=ci: a case that wrongly passed validation would finish in seconds
    "total_steps=abc budget=ci", "total_steps=nan budget=ci", "total_steps=inf budget=ci",
    "total_steps=0 budget=ci", "total_steps=-5 budget=ci", "seed=1.5 budget=ci",
    "seed=-1 budget=ci", "cost_limit=inf budget=ci", "cost_limit=-1 budget=ci",
    "cost_limit=abc budget=ci", "algo.gamma=nan budget=ci", "algo.gamma=abc budget=ci",
    "algo.hidden_sizes=[] budget=ci", "algo.hidden_sizes=[0] budget=ci",
    "eval_episodes=0 budget=ci",
    "algo.hidden_sizes=abc budget=ci", "eval_every=-1 budget=ci", "env.num_envs=0 budget=ci",
    "torch_threads=0 budget=ci", "algo=nope", "env=nope", "foo=1", "algo.nope=1",
    "resume=/nonexistent/run", "-m seed=0,1 foo=1", "experiment=semdp total_steps=-1",
]
EVAL = [
    "/nonexistent/run", "zoo:nope", "", f"zoo:{ENTRY} episodes=0", f"zoo:{ENTRY} episodes=-1",
    f"zoo:{ENTRY} episodes=abc", f"zoo:{ENTRY} episodes=nan", f"zoo:{ENTRY} clearance=nan",
    f"zoo:{ENTRY} clearance=inf", f"zoo:{ENTRY} clearance=-1", f"zoo:{ENTRY} planner=nope",
    f"zoo:{ENTRY} foo=1", f"zoo:{ENTRY} seeds=[]", f"zoo:{ENTRY} perception=nope",
    f"zoo:{ENTRY} nokeyvalue", f"zoo:{ENTRY} actions=nope", f"zoo:{ENTRY} lambda=nope",
]
PLAN = [
    "start=[0,0] subgoal=[nan,1]", "start=[0,0] subgoal=[inf,1]", "start=abc subgoal=[2,1]",
    "start=[0,0,0] subgoal=[2,1]", "start=[0,0] subgoal=[2,1] obstacles=[[1,nan]]",
    "start=[0,0] subgoal=[2,1] obstacles=[[1,0.3,-1]]", "start=[0,0] subgoal=[2,1] backend=nope",
    "start=[0,0] subgoal=[2,1] backends=[]", "start=[0,0] subgoal=[2,1] backends=[nope]",
    "start=[0,0] subgoal=[2,1] planner.problem.n_waypoints=0",
    "start=[0,0] subgoal=[2,1] planner.problem.n_waypoints=-3",
    "start=[0,0] subgoal=[2,1] planner.problem.clearance=nan", "start=[0,0] subgoal=[2,1] foo=1",
    "planner=nope start=[0,0] subgoal=[2,1]",
]
REPORT = [
    "", "/nonexistent", ". --digits abc", ". --digits -1", ". --late nan", ". --late 2",
    ". --at abc", ". --at -5", ". --compare onlyone", ". --nope", ".",
]
BENCH = [
    "", "nope", "planner backends=[]", "planner backends=[nope]", "planner n=0", "planner n=abc",
    "planner foo=1", "sims steps=abc", "sims steps=-1", "driving speeds=[]",
    "driving speeds=[nan]", "train algos=[]", "train epochs=0", "price set=nope",
    "price episodes=0", "safety episodes=0", "semdp steps=abc",
]
CASES = [(app, args) for app, group in (
    ("semdp-train", TRAIN), ("semdp-eval", EVAL), ("semdp-plan", PLAN),
    ("semdp-report", REPORT), ("semdp-bench", BENCH)) for args in group]


def _files(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _run_forked(main: Callable[[], None], argv: list[str], cwd: Path) -> tuple[int, str]:
    """``main()`` with ``sys.argv = argv`` in a forked child whose working directory is ``cwd``;
    (exit status, stderr). SystemExit is turned into the status and message as Python does."""
    err_path = cwd.parent / f"{cwd.name}.stderr"
    pid = os.fork()
    if pid == 0:  # the child: never returns into pytest
        code = 70
        try:
            os.chdir(cwd)
            err = os.open(err_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 1)
            os.dup2(err, 2)
            sys.stdout = open(1, "w", buffering=1, closefd=False)
            sys.stderr = open(2, "w", buffering=1, closefd=False)
            sys.argv = argv
            from hydra.core.global_hydra import GlobalHydra
            GlobalHydra.instance().clear()
            try:
                main()
                code = 0
            except SystemExit as exit_:
                if isinstance(exit_.code, str):
                    sys.stderr.write(exit_.code + "\n")
                    code = 1
                else:
                    code = int(exit_.code or 0)
        except BaseException:  # a raw exception: print it as Python would
            import traceback
            traceback.print_exc()
            code = 1
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code)
    deadline = time.monotonic() + TIMEOUT_S
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            pytest.fail(f"{argv}: no answer in {TIMEOUT_S:.0f} s (hang)")
        time.sleep(0.05)
    return os.waitstatus_to_exitcode(status), err_path.read_text()


def _assert_one_line(app: str, args: str, code: int, stderr: str, left: set[str]) -> None:
    lines = [line for line in stderr.splitlines() if line.strip()]
    where = f"{app} {args}"
    assert code == 1, f"{where}: exit status {code}, stderr {stderr!r}"
    assert len(lines) == 1, f"{where}: {len(lines)} lines on stderr: {stderr!r}"
    assert "Traceback" not in stderr and lines[0].startswith(f"{app}"), f"{where}: {stderr!r}"
    assert not left, f"{where}: left behind {sorted(left)}"


@pytest.mark.parametrize(("app", "args"), CASES, ids=[f"{a} {s}" for a, s in CASES])
def test_bad_input_gets_one_line_and_leaves_nothing(app: str, args: str, tmp_path: Path) -> None:
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    run_dir = entries()[ENTRY]
    before = _files(run_dir)
    code, stderr = _run_forked(APPS[app], [app, *args.split()], cwd)
    left = _files(cwd) | {f"{run_dir}/{p}" for p in _files(run_dir) - before}
    _assert_one_line(app, args, code, stderr, left)


def _run_copy(tmp_path: Path) -> Path:
    run = tmp_path / "run"
    shutil.copytree(entries()[ENTRY], run)
    return run


CORRUPT: dict[str, Callable[[Path, Path], None]] = {
    "empty": lambda run, _: (run / "policy.pt").write_bytes(b""),
    "truncated": lambda run, _: (run / "policy.pt").write_bytes(
        (run / "policy.pt").read_bytes()[:4096]),
    "not a torch file": lambda run, _: (run / "policy.pt").write_text("hello\n"),
    "a list": lambda run, _: torch.save([1, 2], run / "policy.pt"),
    "another robot's policy": lambda run, _: shutil.copy(
        entries()["semdp_car_push1_s0"] / "policy.pt", run / "policy.pt"),
    "another network size": lambda run, _: (run / "config.yaml").write_text(
        re.sub(r"(hidden_sizes:\n)(?:\s+- \d+\n)+", r"\1  - 64\n  - 64\n",
               (run / "config.yaml").read_text(), count=1)),
    "no policy.pt": lambda run, _: (run / "policy.pt").unlink(),
    "config.yaml not YAML": lambda run, _: (run / "config.yaml").write_text("a: [\n"),
    "no config.yaml": lambda run, _: (run / "config.yaml").unlink(),
}


@pytest.mark.parametrize("damage", list(CORRUPT))
def test_a_corrupt_or_misfitting_run_gets_one_line_naming_it(damage: str,
                                                            tmp_path: Path) -> None:
    run = _run_copy(tmp_path)
    CORRUPT[damage](run, tmp_path)
    before = _files(run)
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    code, stderr = _run_forked(eval_app.main, ["semdp-eval", str(run), "episodes=1"], cwd)
    _assert_one_line("semdp-eval", damage, code, stderr, _files(cwd) | (_files(run) - before))
    assert str(run) in stderr, stderr


@pytest.mark.parametrize("argv", [["semdp-train", "algo=nope"], ["semdp-plan", "foo=1"],
                                  ["semdp-report", "--digits", "abc", "."], ["semdp-bench", "nope"],
                                  ["semdp-eval", "zoo:nope"]])
def test_the_installed_console_scripts_answer_in_one_line(argv: list[str],
                                                         tmp_path: Path) -> None:
    script = Path(sys.executable).with_name(argv[0])
    done = subprocess.run([str(script), *argv[1:]], cwd=tmp_path, capture_output=True,
                          text=True, timeout=TIMEOUT_S)
    _assert_one_line(argv[0], " ".join(argv[1:]), done.returncode, done.stderr,
                     _files(tmp_path))
