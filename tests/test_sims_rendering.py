"""Top-down frames, overlays and GIF export."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from sims.rendering import save_gif
from sims.safety_gym import SafetyGymEnv
from sims.safety_gym.render import COLOURS


def _has_colour(frame: np.ndarray, colour) -> bool:
    return bool(np.any(np.all(frame == np.array(colour, dtype=np.uint8), axis=-1)))


def test_render_draws_every_object_type_in_its_colour() -> None:
    for task, level, kinds in (("push", 2, ("hazards", "pillars", "push_box", "goal")),
                               ("button", 2, ("hazards", "buttons", "gremlins")),
                               ("goal", 2, ("hazards", "vases", "goal"))):  # fmt: skip
        env = SafetyGymEnv("point", task, level, render_mode="rgb_array", render_size=200)
        env.reset(seed=0)
        frame = env.render()
        assert frame.shape == (200, 200, 3) and frame.dtype == np.uint8
        for kind in (*kinds, "robot"):
            assert _has_colour(frame, COLOURS[kind]), (task, kind)
    assert SafetyGymEnv("point", "goal", 1).render() is None  # render_mode None


def test_render_shows_heading_and_overlay() -> None:
    env = SafetyGymEnv("car", "goal", 0, render_mode="rgb_array")
    env.reset(seed=0, options={"layout": {"agent": (0, 0), "agent_yaw": 0.0}})
    plain = env.render()
    env.reset(seed=0, options={"layout": {"agent": (0, 0), "agent_yaw": 1.5}})
    turned = env.render()
    assert not np.array_equal(plain, turned)
    assert not _has_colour(turned, COLOURS["subgoal"])
    env.set_overlay(waypoints=np.array([[0, 0], [0.5, 0.5], [1.0, 0.4]]), subgoal=[1.0, 0.4])
    with_overlay = env.render()
    assert _has_colour(with_overlay, COLOURS["subgoal"]) and _has_colour(with_overlay, (20, 20, 20))
    env.set_overlay()
    np.testing.assert_array_equal(env.render(), turned)


def test_save_gif_writes_all_frames(tmp_path) -> None:
    env = SafetyGymEnv("mass", "push", 1, render_mode="rgb_array", render_size=64)
    env.reset(seed=0)
    frames = [env.render()]
    for _ in range(4):
        for _ in range(5):  # 0.15 m between frames: every frame differs
            env.step((1.0, 0.3))
        frames.append(env.render())
    path = save_gif(frames, tmp_path / "sub" / "episode.gif", fps=25)
    with Image.open(path) as gif:
        assert gif.n_frames == 5 and gif.size == (64, 64)
        assert gif.info["duration"] == 40
    with pytest.raises(ValueError, match="no frames"):
        save_gif([], tmp_path / "x.gif")
    with pytest.raises(ValueError, match="shape"):
        save_gif([frames[0], frames[0][:10]], tmp_path / "x.gif")
