"""``semdp-bench planner``: every planner backend on one seeded problem suite (docs/planner.md).

Usage::

    semdp-bench planner backends=[ipopt,lm,lm_adaptive,scp] n=500 seed=0 batch=[4,16] out=DIR

Variants: ``ipopt``, ``lm`` (fixed lambda, 10 iterations: the training setting), ``lm_adaptive``
(lambda doubled until certified, up to 1024: the evaluation setting), ``scp``; append ``_cont``
for the continuous (segment) certificate, e.g. ``scp_cont``. ``batch=B`` (or a list,
``batch=[4,16]``; ``batch=1`` for none) adds a row ``variant[batchB]`` per variant for
``plan_batch`` on B problems per call (``workers=W`` passes ``workers`` to it; default its own).
Its times are per problem (call time / B), so compare them with the ``mean ms`` column. A
second table sets the batch against a loop of ``plan`` over the same chunks, timed alternately
with it (same machine load), and gives the largest waypoint difference between the two. Writes
``planner_summary.csv``, ``planner_results.csv`` (one row per problem and variant) and
``planner_batch.csv`` to ``out`` (default ``outputs/benchmarks/planner``). The summary's
``plans_sha256`` column (also printed) hashes each variant's plans (waypoints and certificate
flags, problem order): equal digests across two code versions mean bit-identical plans.
"""

from __future__ import annotations

import csv
import hashlib
import platform
import time
from pathlib import Path

import numpy as np

from semdp.benchmarks.arguments import as_choices, as_int, as_list, parse_args
from semdp.paths import REPO_ROOT
from solvers.planner import (
    IpoptSettings,
    LMSettings,
    ProblemSettings,
    SafeTrajectoryPlanner,
    SCPSettings,
    plan_batch,
    random_problems,
    start_batch_workers,
)

THESIS_THESEUS_MS = 63.0


def plans_sha256(results: list) -> str:
    """SHA-256 over a variant's plans in problem order: each plan's waypoint array (float64,
    C order) and its certificate flags (``status``, ``feasible``, ``fallback``, ``escape_mode``,
    ``rescued``). Equal digests mean bit-identical plans (a refactor's regression check)."""
    digest = hashlib.sha256()
    for result in results:
        digest.update(np.ascontiguousarray(result.waypoints, dtype=np.float64).tobytes())
        flags = (result.status, result.feasible, result.fallback, result.escape_mode,
                 result.rescued)
        digest.update(("|".join(str(f) for f in flags) + "\n").encode())
    return digest.hexdigest()

#: The backend settings of each variant (the problem's settings are the defaults).
VARIANTS: dict[str, IpoptSettings | LMSettings | SCPSettings] = {
    "ipopt": IpoptSettings(),
    "lm": LMSettings(iterations=10, adaptive=False, native=False),
    "lm_adaptive": LMSettings(iterations=10, adaptive=True, native=False),
    "scp": SCPSettings(),
    # the same LM as native code (solvers/native.py, backends/native_lm.py; LMSettings' and the
    # configs' default): same plans, faster; not in the default list (backends=[lm,lm_native,...]
    # compares them)
    "lm_native": LMSettings(iterations=10, adaptive=False, native=True),
    "lm_adaptive_native": LMSettings(iterations=10, adaptive=True, native=True),
}


#: Keys and defaults (``workers`` empty: ``plan_batch``'s own; ``out`` empty:
#: ``outputs/benchmarks/planner``).
DEFAULTS: dict[str, str] = {
    "backends": "[ipopt,lm,lm_adaptive,scp]", "n": "500", "seed": "0", "batch": "16",
    "out": "", "max_count": "8", "workers": "",
}


def _variant_kwargs(name: str) -> dict[str, object]:
    base = name.removesuffix("_cont")
    if base not in VARIANTS:
        valid = [*VARIANTS, *(f"{v}_cont" for v in VARIANTS)]
        raise SystemExit(f"unknown backend variant {name!r}; valid: {valid}")
    return {"backend": VARIANTS[base],
            "problem": ProblemSettings(continuous=name.endswith("_cont"))}


def main(argv: list[str]) -> None:
    """Run the suite and print the table."""
    args = parse_args("planner", argv, DEFAULTS)
    names = as_choices(args, "backends", [*VARIANTS, *(f"{v}_cont" for v in VARIANTS)])
    n, seed = as_int(args, "n", minimum=1), as_int(args, "seed")
    sizes = [as_int({"batch": b}, "batch", minimum=1) for b in as_list(args["batch"])]
    workers = as_int(args, "workers", minimum=1) if args["workers"] else None
    out = Path(args["out"]) if args["out"] else REPO_ROOT / "outputs" / "benchmarks" / "planner"
    problems = random_problems(n, seed, max_count=as_int(args, "max_count", minimum=0))
    rows: list[dict[str, object]] = []
    summary: list[dict[str, object]] = []
    objectives: dict[str, np.ndarray] = {}
    reached: dict[str, np.ndarray] = {}
    runs: list[tuple[str, dict[str, object], int]] = [(v, _variant_kwargs(v), 1) for v in names]
    runs += [(f"{v}[batch{b}]", _variant_kwargs(v), b) for b in sizes if b > 1 for v in names]
    batch_rows: list[dict[str, object]] = []
    for label, kwargs, size in runs:
        planner = SafeTrajectoryPlanner(**kwargs).warmup()
        for problem in problems[:20]:  # build every compiled slot count before timing
            planner.plan(problem.start, problem.subgoal, problem.obstacles, warm_start=False)
        times = np.zeros(n)
        results = []
        if size == 1:
            for k, problem in enumerate(problems):
                tic = time.perf_counter()
                result = planner.plan(
                    problem.start, problem.subgoal, problem.obstacles, warm_start=False
                )
                times[k] = time.perf_counter() - tic
                results.append(result)
        else:
            batch_rows.append(_run_batches(planner, problems, size, workers, times, results))
            batch_rows[-1]["variant"] = label
        objective = np.array([r.objective for r in results])
        objectives[label] = objective
        reached[label] = np.array([r.reached_subgoal for r in results])
        feasible = np.array(
            [r.feasible and r.min_clearance >= planner.clearance - 1e-6 for r in results]
        )
        for k, (problem, result) in enumerate(zip(problems, results, strict=True)):
            rows.append({
                "variant": label, "problem": k, "n_obstacles": len(problem.obstacles),
                "time_ms": times[k] * 1e3, "feasible": result.feasible,
                "fallback": result.fallback, "reached_subgoal": result.reached_subgoal,
                "objective": result.objective, "min_clearance": result.min_clearance,
                "min_clearance_continuous": result.min_clearance_continuous,
                "iterations": result.iterations, "status": result.status,
            })
        ms = times * 1e3
        summary.append({
            "variant": label, "n": n, "median_ms": np.median(ms), "mean_ms": np.mean(ms),
            "p95_ms": np.percentile(ms, 95),
            "max_ms": ms.max(), "feasible_pct": 100 * feasible.mean(),
            "fallback_pct": 100 * np.mean([r.fallback for r in results]),
            "reached_pct": 100 * reached[label].mean(),
            "iters_median": float(np.median([r.iterations for r in results])),
            "speedup_vs_theseus": THESIS_THESEUS_MS / np.median(ms),
            "plans_sha256": plans_sha256(results),
        })
    reference = "ipopt" if "ipopt" in objectives else None
    for row in summary:
        label = str(row["variant"])
        if reference is not None:
            gap = objectives[label] - objectives[reference]
            row["obj_gap_median"] = float(np.median(gap))
            row["obj_gap_mean"] = float(np.mean(gap))
            row["reached_vs_ipopt_pct"] = 100 * float(
                np.mean(reached[label][reached[reference]]) if reached[reference].any() else np.nan
            )
        else:
            row["obj_gap_median"] = row["obj_gap_mean"] = row["reached_vs_ipopt_pct"] = float("nan")
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "planner_summary.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(summary[0]))
        writer.writeheader()
        writer.writerows(summary)
    with open(out / "planner_results.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    machine = platform.processor() or platform.machine()
    print(f"planner benchmark: {n} problems, seed {seed}, {machine}")
    header = (
        "| variant | median ms | mean ms | p95 ms | max ms | feasible % | fallback % | reached % "
        "| reached where IPOPT reached % | obj gap to IPOPT (median / mean) | iters (median) "
        "| x faster than Theseus LM (63 ms) |"
    )
    print(header)
    print("|" + "---|" * 12)
    for row in summary:
        print(
            f"| {row['variant']} | {row['median_ms']:.2f} | {row['mean_ms']:.2f} | "
            f"{row['p95_ms']:.2f} | "
            f"{row['max_ms']:.1f} | {row['feasible_pct']:.1f} | {row['fallback_pct']:.1f} | "
            f"{row['reached_pct']:.1f} | {row['reached_vs_ipopt_pct']:.1f} | "
            f"{row['obj_gap_median']:.2g} / {row['obj_gap_mean']:.2g} | "
            f"{row['iters_median']:.0f} | "
            f"{row['speedup_vs_theseus']:.0f} |"
        )
    if batch_rows:
        with open(out / "planner_batch.csv", "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(batch_rows[0]))
            writer.writeheader()
            writer.writerows(batch_rows)
        print()
        print("| variant | B | workers (helpers ready) | loop ms/problem | batch ms/problem "
              "| speed-up | max waypoint diff vs loop (m) |")
        print("|" + "---|" * 7)
        for row in batch_rows:
            print(
                f"| {row['variant']} | {row['batch']} | {row['workers']} ({row['helpers']}) | "
                f"{row['loop_ms']:.3f} | {row['batch_ms']:.3f} | {row['speedup']:.2f} | "
                f"{row['max_diff']:.1e} |"
            )
    print()
    print("| variant | plans SHA-256 (waypoints and certificate flags, problem order) |")
    print("|---|---|")
    for row in summary:
        print(f"| {row['variant']} | {row['plans_sha256']} |")
    print(f"wrote {out / 'planner_summary.csv'} and {out / 'planner_results.csv'}"
          + (f" and {out / 'planner_batch.csv'}" if batch_rows else ""))


def _run_batches(
    planner: SafeTrajectoryPlanner,
    problems: list,
    size: int,
    workers: int | None,
    times: np.ndarray,
    results: list,
) -> dict[str, object]:
    """Time ``plan_batch`` on chunks of ``size`` and a loop of ``plan`` on the same chunks.

    The two alternate chunk by chunk (and which goes first alternates too), so both see the same
    machine load. Fills ``times`` (per problem: call time / chunk size) and ``results`` with the
    batch's and returns the comparison row.
    """
    helpers = start_batch_workers(planner, workers)
    loop_total = batch_total = max_diff = 0.0
    for index, lo in enumerate(range(0, len(problems), size)):
        chunk = problems[lo : lo + size]
        starts = [p.start for p in chunk]
        subgoals = [p.subgoal for p in chunk]
        obstacles = [p.obstacles for p in chunk]
        for batch_first in ((True, False) if index % 2 == 0 else (False, True)):
            tic = time.perf_counter()
            if batch_first:
                out_chunk = plan_batch(planner, starts, subgoals, obstacles, workers=workers)
                elapsed = time.perf_counter() - tic
                batch_total += elapsed
                times[lo : lo + len(chunk)] = elapsed / len(chunk)
            else:
                loop = [planner.plan(s, g, o, warm_start=False)
                        for s, g, o in zip(starts, subgoals, obstacles, strict=True)]
                loop_total += time.perf_counter() - tic
        results.extend(out_chunk)
        for a, b in zip(out_chunk, loop, strict=True):
            max_diff = max(max_diff, float(np.max(np.abs(a.waypoints - b.waypoints))))
    n = len(problems)
    return {
        "variant": "", "batch": size,
        "workers": "default" if workers is None else workers, "helpers": helpers,
        "loop_ms": 1e3 * loop_total / n, "batch_ms": 1e3 * batch_total / n,
        "speedup": loop_total / batch_total, "max_diff": max_diff,
    }
