"""Pinned CPU kernels, so that the same seed gives the same numbers on every x86-64 machine.

torch's linear algebra runs on MKL, which by default picks its code path by the processor
(AVX2, AVX-512, ...) and, on some, by the memory alignment of each array: the same seed then
gives a different last bit on another machine, or in a helper process of the same machine,
and a closed-loop rollout amplifies that bit into a different episode within a few hundred
steps (a committed policy's 50-episode evaluation moves by about 0.1). Measured on an AVX-512
AMD EPYC: with MKL's defaults, PPO-Lag with and without its helper processes diverged at the
second epoch and every golden learning curve differed from the one recorded on an AVX2
machine; with the pin below the helper runs agree and every re-run is bit-identical.

:func:`pin_cpu_kernels` sets, before torch is imported and only where the user has not:

* ``MKL_CBWR`` -- MKL's conditional numerical reproducibility, the same bits whatever the
  alignment: ``AVX2`` on AMD processors and ``COMPATIBLE`` on Intel ones
  (:func:`mkl_branch`). MKL honours its AVX2 branch on Intel processors only; on an AMD EPYC
  it runs the branch it uses for every non-Intel processor, and the committed policies'
  evaluations were recorded there. On an Intel Xeon (AVX-512) the AVX2 branch gave other last
  bits, and 62 of the 63 evaluation checks of the policy zoo (``tests/test_zoo.py``) other
  episodes; the ``COMPATIBLE`` branch reproduced all 63. Training's larger products still
  differ in the last bits between the two vendors under every branch tried (the golden
  learning curves are recorded per vendor: ``tests/data/golden/``). The compatible branch is
  slower: a 128 x 128 MLP's forward and backward on a batch of 256 took 1.21 ms against
  0.66 ms on the AVX2 branch (one thread, the same Intel Xeon), and the main job 7.0 min
  instead of about 5 on two cores; ``MKL_CBWR=AVX2`` set by the user is kept (faster, and
  reproducible on Intel processors only);
* ``ATEN_CPU_CAPABILITY=avx2`` -- torch's own vectorised kernels at the same level;
* ``OPENBLAS_CORETYPE=Haswell`` -- numpy's and scipy's OpenBLAS (the follower's network in
  numpy, the planner's banded Cholesky) at the AVX2 kernels too: OpenBLAS 0.3.31 chooses its
  AVX-512 kernels on an AVX-512 AMD EPYC, and the SEMDP golden learning curves then differ from
  the AVX2 ones from the first epoch (measured; with the pin they agree). OpenBLAS reads it
  when it loads, so semdp must be imported before numpy for it to act.

x86-64 only (elsewhere there is no MKL, and OpenBLAS has no Haswell kernels).
``SEMDP_FREE_KERNELS=1`` leaves all three unset (the processor's fastest paths; runs are then
reproducible on that machine kind only).
"""

from __future__ import annotations

import os
import platform

#: The environment this module sets (each only if unset); ``MKL_CBWR`` by :func:`mkl_branch`.
PINNED: dict[str, str] = {"MKL_CBWR": "AVX2", "ATEN_CPU_CAPABILITY": "avx2",
                          "OPENBLAS_CORETYPE": "Haswell"}


def cpuinfo_field(name: str) -> str:
    """The first ``name`` field of ``/proc/cpuinfo`` (Linux), else ``""``."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith(name):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return ""


def cpu_vendor() -> str:
    """The processor's vendor (``GenuineIntel``, ``AuthenticAMD``), else ``""``."""
    return cpuinfo_field("vendor_id")


def mkl_branch(vendor: str) -> str:
    """The ``MKL_CBWR`` branch pinned on a processor of ``vendor`` (see the module docstring):
    ``COMPATIBLE`` on Intel, whose AVX2 branch differs from what MKL runs on other vendors'
    processors, ``AVX2`` elsewhere."""
    return "COMPATIBLE" if vendor == "GenuineIntel" else "AVX2"


def _has_avx2() -> bool:
    try:
        with open("/proc/cpuinfo") as f:
            return any(line.startswith("flags") and " avx2" in line for line in f)
    except OSError:  # not Linux: trust the architecture (every x86-64 we run on has AVX2)
        return True


def pin_cpu_kernels() -> dict[str, str]:
    """Set :data:`PINNED` where unset (x86-64 with AVX2, unless ``SEMDP_FREE_KERNELS=1``);
    return what was set. Must run before torch is imported to take effect."""
    if os.environ.get("SEMDP_FREE_KERNELS") == "1":
        return {}
    if platform.machine().lower() not in ("x86_64", "amd64") or not _has_avx2():
        return {}
    done = {}
    for key, value in {**PINNED, "MKL_CBWR": mkl_branch(cpu_vendor())}.items():
        if key not in os.environ:
            os.environ[key] = value
            done[key] = value
    return done
