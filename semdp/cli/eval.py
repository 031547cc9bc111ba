"""``semdp-eval RUN_DIR [key=value ...]``: evaluate a finished run (docs/evaluation.md).

    semdp-eval outputs/train/<run>                                   # 50 episodes, as trained
    semdp-eval outputs/train/<run> lambda=fixed label="Ours w/o Lag" # an evaluation-time ablation
    semdp-eval outputs/train/<run> planner=ipopt clearance=0.6 perception=gt episodes=20
    semdp-eval outputs/train/<run> variant=transfer                  # Table 3.2 stand-in
    semdp-eval outputs/train/<run> episodes=1 video=true             # MP4 of the first episode
    semdp-eval zoo:<name>                    # a committed policy (outputs/reference/zoo.yaml)

Writes ``RUN_DIR/eval_<time>/metrics.json``; a bad argument prints one line naming it and exits 1.
"""

from __future__ import annotations

import logging
import sys

from semdp.evaluation.errors import EvalError
from semdp.evaluation.options import SHORTHANDS
from semdp.evaluation.run import evaluate_run

USAGE = "usage: semdp-eval RUN_DIR|zoo:NAME [key=value ...]"


def _help() -> str:
    lines = [USAGE, "", __doc__.split("\n\n")[1].rstrip(), "", "evaluation settings:"]
    lines += [f"  {key:<12} {text}" for key, text in SHORTHANDS.items()]
    lines += ["  any other key=value sets a key of RUN_DIR/config.yaml (+key=value adds one)"]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Console entry point."""
    args = sys.argv[1:] if argv is None else list(argv)
    if not args:
        raise SystemExit(f"semdp-eval: {USAGE.removeprefix('usage: ')}: give a run directory "
                         "(semdp-eval --help lists the settings)")
    if args[0] in ("-h", "--help"):
        print(_help())
        return
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        out_dir, metrics = evaluate_run(args[0], args[1:])
    except EvalError as exc:
        raise SystemExit(f"semdp-eval: {exc}") from None
    ev = metrics["eval"]
    line = (f"{out_dir}: {metrics['label']}: return {ev['return_mean']:.3f} ± "
            f"{ev['return_std']:.3f}, cost {ev['cost_mean']:.3f} over {ev['episodes']} episodes")
    if "plans" in ev:
        line += (f"; plans {ev['plans']}, fallbacks {ev['plan_fallbacks']}, escapes "
                 f"{ev['plan_escapes']}, rescues {ev['plan_rescues']}")
    if metrics["video"]:
        line += f"; video {metrics['video']['path']}"
    print(line)


if __name__ == "__main__":
    main()
