"""The helper-process toolkit (solvers/workers): replies, errors, deaths, timeouts, shutdown,
no orphans, and forks that are safe after torch started its thread pool."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from solvers.workers import Helper, HelperError, describe_exit, fork_available
from solvers.workers.helper import single_threaded

ROOT = Path(__file__).resolve().parents[1]
needs_fork = pytest.mark.skipif(not fork_available(), reason="needs the fork start method")


def _gone(pid: int, within: float = 10.0) -> bool:
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        try:
            if os.waitpid(pid, os.WNOHANG)[0] == pid:
                return True
        except ChildProcessError:  # not our child: look at /proc
            stat = Path(f"/proc/{pid}/stat")
            if not stat.exists() or stat.read_text().rsplit(")", 1)[1].split()[0] == "Z":
                return True
        time.sleep(0.05)
    return False


class Doubler:
    """A spawned helper's handler (built from ``argv``)."""

    def __init__(self, factor: str = "2") -> None:
        self.factor = int(factor)

    def __call__(self, request: object) -> object:
        if request == "boom":
            raise ValueError("planted failure")
        if request == "sleep":
            time.sleep(30)
        if request == "pid":
            return os.getpid()
        return request * self.factor  # type: ignore[operator]


@pytest.mark.skipif(not Path("/proc/self/comm").exists(), reason="Linux process names")
def test_helpers_show_their_name_to_ps() -> None:
    spawned = Helper.spawn("tests.test_workers:Doubler", "named-spawned")
    try:
        spawned.request(1)
        assert Path(f"/proc/{spawned.pid}/comm").read_text().strip() == "named-spawned"
    finally:
        spawned.close()
    if fork_available():
        forked = Helper.fork(lambda _: Path("/proc/self/comm").read_text().strip(), "named-fork")
        try:
            assert forked.request(None) == "named-fork"
        finally:
            forked.close()


def test_describe_exit_by_hand() -> None:
    assert describe_exit(None) == "still running"
    assert describe_exit(0) == "exit code 0"
    assert describe_exit(-9) == "killed by SIGKILL"


@needs_fork
def test_forked_helper_sees_the_callers_objects_and_replies_in_order() -> None:
    state = {"offset": 7}  # set before the fork: the helper has its own copy
    helper = Helper.fork(lambda x: x + state["offset"], "adder")
    try:
        helper.send(1)
        helper.send(2)
        assert [helper.receive(), helper.receive()] == [8, 9]
        assert helper.request(10) == 17
    finally:
        helper.close()
    assert not helper.alive and _gone(helper.pid)


@pytest.mark.parametrize("start", ["fork", "spawn"])
def test_a_handler_error_is_raised_with_the_helpers_name_and_traceback(start: str) -> None:
    if start == "fork" and not fork_available():
        pytest.skip("needs fork")
    helper = (Helper.fork(Doubler(), "doubler") if start == "fork" else
              Helper.spawn("tests.test_workers:Doubler", "doubler", argv=["3"]))
    try:
        with pytest.raises(HelperError, match=r"doubler \(pid \d+\) failed:(.|\n)*planted"):
            helper.request("boom")
        assert helper.request(5) == (10 if start == "fork" else 15)  # it keeps serving
    finally:
        helper.close()


@pytest.mark.parametrize("start", ["fork", "spawn"])
def test_a_killed_helper_fails_the_caller_with_one_line(start: str) -> None:
    if start == "fork" and not fork_available():
        pytest.skip("needs fork")
    helper = (Helper.fork(Doubler(), "victim") if start == "fork" else
              Helper.spawn("tests.test_workers:Doubler", "victim"))
    try:
        assert helper.request("pid") == helper.pid
        helper.send("sleep")
        os.kill(helper.pid, signal.SIGKILL)
        started = time.monotonic()
        with pytest.raises(HelperError) as caught:
            helper.receive()
        assert time.monotonic() - started < 10
        message = str(caught.value)
        assert message == f"helper process victim (pid {helper.pid}) died (killed by SIGKILL)"
        with pytest.raises(HelperError, match="died"):
            helper.send(1)
    finally:
        helper.close()


def test_no_reply_within_the_timeout_and_close_stops_a_busy_helper() -> None:
    helper = Helper.spawn("tests.test_workers:Doubler", "sleeper")
    helper.send("sleep")
    with pytest.raises(HelperError, match=r"sleeper \(pid \d+\) gave no reply within 0.3 s"):
        helper.receive(timeout=0.3)
    started = time.monotonic()
    helper.close(timeout=0.5)  # asked to quit, busy: terminated
    assert time.monotonic() - started < 5 and _gone(helper.pid)


def test_a_spawned_handler_that_cannot_be_built_is_reported() -> None:
    helper = Helper.spawn("tests.test_workers:NoSuchHandler", "broken")
    try:
        with pytest.raises(HelperError, match=r"broken \(pid \d+\) failed:(.|\n)*NoSuchHandler"):
            helper.request(1)
    finally:
        helper.close()


def test_a_request_that_does_not_pickle_is_the_callers_error() -> None:
    helper = Helper.spawn("tests.test_workers:Doubler", "doubler")
    try:
        with pytest.raises((TypeError, AttributeError, ValueError)):
            helper.send(lambda: 0)
        assert helper.request(4) == 8  # nothing was sent
    finally:
        helper.close()


CALLER = textwrap.dedent("""
    import sys, time
    from solvers.workers import Helper
    from tests.test_workers import Doubler
    forked = Helper.fork(Doubler(), "forked")
    spawned = Helper.spawn("tests.test_workers:Doubler", "spawned")
    assert forked.request(1) == 2 and spawned.request(1) == 2
    print(forked.pid, spawned.pid, flush=True)
    time.sleep(60)
""")


@needs_fork
def test_helpers_end_when_their_caller_is_killed() -> None:
    """No orphans: ``kill -9`` of the caller ends both kinds of helper."""
    caller = subprocess.Popen([sys.executable, "-c", CALLER], cwd=ROOT, stdout=subprocess.PIPE,
                              text=True)
    try:
        assert caller.stdout is not None
        pids = [int(p) for p in caller.stdout.readline().split()]
        assert len(pids) == 2
        caller.kill()
        caller.wait(10)
        assert all(_gone(pid) for pid in pids), "a helper outlived its caller"
    finally:
        if caller.poll() is None:
            caller.kill()


TORCH_FORK = textwrap.dedent("""
    import torch
    from solvers.workers import Helper
    layer = torch.nn.Linear(256, 256)
    x = torch.randn(512, 256)
    layer(x).sum().backward()  # the caller's OpenMP pool is running now
    assert torch.get_num_threads() == THREADS, torch.get_num_threads()

    def work(_):
        out = None
        for _ in range(20):
            out = layer(x)
            out.sum().backward()
        return torch.get_num_threads(), float(out.detach().double().sum())

    helper = Helper.fork(work, "torch-user")
    threads, value = helper.request(None, timeout=60)
    helper.close()
    print(threads, value)
""")


@needs_fork
@pytest.mark.parametrize("threads", [1, 2])
def test_a_fork_after_torch_started_its_threads_does_not_hang(threads: int) -> None:
    """The root cause of a hang on idle machines: GNU OpenMP's pool does not survive fork. In a
    fresh interpreter with torch's default threads (here set explicitly, so the case is the same
    on any machine), a forked helper's first matrix products must finish, on one thread."""
    pytest.importorskip("torch")
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    code = TORCH_FORK.replace("THREADS", str(threads)).replace(
        "import torch\n", f"import torch\ntorch.set_num_threads({threads})\n", 1)
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, text=True,
                          capture_output=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    helper_threads, value = done.stdout.split()
    assert int(helper_threads) == 1 and float(value) == float(value)


def test_single_threaded_leaves_torch_alone_when_it_was_not_imported() -> None:
    code = ("import sys; from solvers.workers.helper import single_threaded; single_threaded();"
            " print('torch' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, text=True,
                          capture_output=True, timeout=60, check=True)
    assert done.stdout.strip() == "False"
    assert single_threaded() is None
