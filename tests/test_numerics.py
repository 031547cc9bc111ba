"""The pinned CPU kernels (semdp.numerics): set where unset, never over the user's choice, off
with SEMDP_FREE_KERNELS=1, and in effect for torch when semdp is imported first."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

import pytest

from semdp.numerics import PINNED, pin_cpu_kernels

X86 = platform.machine().lower() in ("x86_64", "amd64")


@pytest.mark.skipif(not X86, reason="the pin is for x86-64 (MKL)")
def test_the_pin_sets_what_is_unset_and_keeps_what_the_user_set(
        monkeypatch: pytest.MonkeyPatch) -> None:
    for key in PINNED:
        monkeypatch.delenv(key, raising=False)
    monkeypatch.setenv("MKL_CBWR", "COMPATIBLE")
    monkeypatch.delenv("SEMDP_FREE_KERNELS", raising=False)
    assert pin_cpu_kernels() == {"ATEN_CPU_CAPABILITY": "avx2", "OPENBLAS_CORETYPE": "Haswell"}
    assert os.environ["MKL_CBWR"] == "COMPATIBLE"
    assert os.environ["ATEN_CPU_CAPABILITY"] == "avx2"


def test_free_kernels_leave_the_environment_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    for key in PINNED:
        monkeypatch.delenv(key, raising=False)
    monkeypatch.setenv("SEMDP_FREE_KERNELS", "1")
    assert pin_cpu_kernels() == {}


@pytest.mark.skipif(not X86, reason="the pin is for x86-64 (MKL)")
def test_torch_runs_at_the_pinned_level_when_semdp_comes_first() -> None:
    code = "import semdp, torch; print(torch.backends.cpu.get_cpu_capability())"
    env = {k: v for k, v in os.environ.items() if k not in PINNED}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, check=True).stdout.strip()
    assert out == "AVX2"


@pytest.mark.skipif(not X86, reason="the pin is for x86-64")
def test_numpys_openblas_runs_the_pinned_kernels_when_semdp_comes_first() -> None:
    code = ("import semdp, numpy, ctypes, glob, os; "
            "lib = [m for m in open('/proc/self/maps').read().split() if 'openblas' in m "
            "and m.endswith('.so')][0]; "
            "f = ctypes.CDLL(lib).scipy_openblas_get_corename64_; f.restype = ctypes.c_char_p; "
            "print(f().decode())")
    env = {k: v for k, v in os.environ.items() if k not in PINNED}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    if out.returncode != 0:
        pytest.skip(f"numpy's OpenBLAS does not report its kernels here: {out.stderr[-200:]}")
    assert out.stdout.strip().lower() == "haswell"


def test_mkl_runs_its_compatible_branch_on_intel_and_avx2_elsewhere() -> None:
    from semdp.numerics import mkl_branch

    assert mkl_branch("GenuineIntel") == "COMPATIBLE"
    assert mkl_branch("AuthenticAMD") == "AVX2"
    assert mkl_branch("") == "AVX2"


@pytest.mark.skipif(not X86, reason="the pin is for x86-64 (MKL)")
def test_the_pin_picks_the_branch_of_this_machines_vendor(monkeypatch: pytest.MonkeyPatch) -> None:
    from semdp.numerics import cpu_vendor, mkl_branch

    for key in PINNED:
        monkeypatch.delenv(key, raising=False)
    monkeypatch.delenv("SEMDP_FREE_KERNELS", raising=False)
    assert pin_cpu_kernels()["MKL_CBWR"] == mkl_branch(cpu_vendor())
    assert os.environ["MKL_CBWR"] == mkl_branch(cpu_vendor())
