"""Evaluate a committed SEMDP policy (PointPush1, trained for 2e6 env steps) on two of the
episodes its reference recorded, and compare (outputs/reference/zoo.yaml; thesis Alg. 2).

    python examples/evaluate_zoo_policy.py     # results in outputs/eval/semdp_point_push1_s0/
"""

import json

from semdp.evaluation.run import evaluate_run
from semdp.evaluation.zoo import entries

name = "semdp_point_push1_s0"
recorded = json.loads((entries()[name] / "eval.json").read_text())
seeds = recorded["settings"]["seeds"][:2]
out_dir, metrics = evaluate_run(f"zoo:{name}", [f"seeds=[{seeds[0]},{seeds[1]}]"])
for now, then in zip(metrics["episodes"], recorded["episodes"], strict=False):
    print(f"seed {now['seed']}: return {now['return']:.3f} (recorded {then['return']:.3f}), "
          f"cost {now['cost']:.0f}, plans {now['high_level_steps']}, "
          f"fallbacks {now['plan_fallbacks']}")
print(f"results in {out_dir}")
