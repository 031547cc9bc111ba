"""How cost_trace_epoch93.json was made (the investigation's script, kept as evidence).

Replays the next epoch of a deterministic SEMDP run from its last checkpoint with every
low-level step recorded (robot state, proposed and applied action, the filter's branch, braking
clearance against the perceived and the true hazards) and dumps the last 60 steps of each env
before its first cost step:

    # 1. reproduce the run up to the epoch before the one with cost (it ends with a checkpoint):
    semdp-train experiment=semdp seed=2 total_steps=184000 tensorboard=false hydra.run.dir=<to92>
    # 2. replay one more epoch with the recording:
    PYTHONPATH=. python outputs/reference/semdp_converged/replay_cost_trace.py <to92> <out>
"""
import collections, json, math, shutil, sys
from pathlib import Path
import numpy as np
from omegaconf import OmegaConf, open_dict
from semdp.embedded.wrapper import SafetyEmbeddedEnv
from semdp.embedded.shield import SafetyShield
from semdp.embedded.robot_models import RobotState
from semdp.train import run

src, dst = Path(sys.argv[1]), Path(sys.argv[2])
if dst.exists():
    shutil.rmtree(dst)
shutil.copytree(src, dst)
cfg = OmegaConf.load(dst / "config.yaml")
with open_dict(cfg):
    cfg.total_steps = int(cfg.total_steps) + int(cfg.algo.steps_per_epoch)
    cfg.final_eval_episodes = 0
    cfg.env.post_train = None
    cfg.tensorboard = False
    cfg.resume = str(dst)
OmegaConf.save(cfg, dst / "config.yaml")
rings = collections.defaultdict(lambda: collections.deque(maxlen=60))
dumps = []
last = {}
orig_filter = SafetyShield.filter


def filt(self, action, base, obs):
    s0 = (self.stats.checked, self.stats.braked, self.stats.escaped)
    out = orig_filter(self, action, base, obs)
    d = [a - b for a, b in zip((self.stats.checked, self.stats.braked, self.stats.escaped), s0)]
    b = base.body
    state = RobotState(b.position.x, b.position.y, b.velocity.x, b.velocity.y, b.angle, b.angular_velocity)
    regions = self.cost_regions(base, obs)
    model = self._model
    brake_clear = self._clearance(model, state, model.backup(state), regions) if len(regions) else None
    act_clear = self._clearance(model, state, np.asarray(action), regions) if len(regions) else None
    hz = base.obstacles(("hazards",))
    true_regions = np.column_stack([hz[:, :2], hz[:, 2]]) if len(hz) else np.zeros((0, 3))
    brake_true = self._clearance(model, state, model.backup(state), true_regions) if len(hz) else None
    out_true = self._clearance(model, state, np.asarray(out), true_regions) if len(hz) else None
    last[id(base)] = dict(pos=[b.position.x, b.position.y], vel=[b.velocity.x, b.velocity.y], yaw=b.angle,
                          w=b.angular_velocity, proposed=np.asarray(action, float).tolist(),
                          applied=np.asarray(out, float).tolist(), branch=d,
                          brake_clear_perceived=brake_clear, action_clear_perceived=act_clear,
                          brake_clear_true=brake_true, applied_clear_true=out_true,
                          min_true=float(min(math.hypot(b.position.x - h[0], b.position.y - h[1]) - h[2] for h in hz)) if len(hz) else None)
    return out


orig = SafetyEmbeddedEnv.low_level_step


def patched(self, window, low_action):
    base = self.env.unwrapped
    done = orig(self, window, low_action)
    rec = dict(last.pop(id(base), {}))
    rec["cost"] = float(window.info.get("cost", 0.0))
    rec["t"] = self.low_level_steps + window.steps
    rec["plan_escape"] = bool(getattr(window.plan, "escape_mode", False))
    rec["plan_fallback"] = bool(getattr(window.plan, "fallback", False))
    rings[id(self)].append(rec)
    if rec["cost"] > 0 and not any(d["env"] == id(self) for d in dumps):
        dumps.append(dict(env=id(self), hazards=base.obstacles(("hazards",)).tolist(), steps=list(rings[id(self)])))
    return done


SafetyShield.filter = filt
SafetyEmbeddedEnv.low_level_step = patched
run(cfg, dst)
(dst / "trace.json").write_text(json.dumps(dumps, indent=1, default=float))
print(len(dumps))
