"""Obstacle perception for the planner: LiDAR reconstruction (thesis default) or ground truth."""

from __future__ import annotations

import numpy as np

from sims.safety_gym.perception import obstacles_from_lidar

#: Object types the planner avoids (thesis §3.6.1: not the box, not the goal).
OBSTACLE_KINDS: tuple[str, ...] = ("hazards", "vases", "pillars", "gremlins")

#: ``lidar``: the thesis' reconstruction (bin-centre bearing); ``lidar_refined``: the same peaks
#: at the bearing implied by the aliasing of the neighbouring bins (exact for an isolated object;
#: beyond the thesis); ``gt``: the simulator's ground truth ("Ours w/ gt").
PERCEPTION_MODES: tuple[str, ...] = ("lidar", "lidar_refined", "gt")


def perceive_obstacles(
    env,
    obs: np.ndarray,
    mode: str = "lidar",
    kinds: tuple[str, ...] = OBSTACLE_KINDS,
    use_radii: bool = False,
    lidar_max_dist: float = 3.0,
) -> np.ndarray:
    """Obstacles as an (m, 3) array of [x, y, radius] for the planner.

    Args:
        env: the unwrapped Safety Gym replica env (``robot_position``, ``robot_heading``,
            ``obs_slices``, ``obstacles``).
        obs: the env's current flat observation.
        mode: ``"lidar"`` reconstructs positions from each type's 16 LiDAR bins (the thesis'
            default, noisy: bin-centre angle, distance (1 - reading) * max);
            ``"lidar_refined"`` places each peak at the bearing its neighbours' aliasing implies
            (exact for an isolated object); ``"gt"`` reads the simulator's ground truth
            ("Ours w/ gt").
        kinds: object types that are obstacles.
        use_radii: ground truth only: keep the objects' radii (clearance eps' + r). The thesis
            plans around centres (r = 0) and sets eps' = 0.5 m to cover the object sizes.
        lidar_max_dist: LiDAR range (Safety Gym: 3 m).
    """
    if mode == "gt":
        obstacles = np.asarray(env.obstacles(kinds=kinds), dtype=np.float64).reshape(-1, 3)
        if not use_radii:
            obstacles = obstacles.copy()
            obstacles[:, 2] = 0.0
        return obstacles
    if mode not in PERCEPTION_MODES:
        raise ValueError(f"perception mode must be one of {PERCEPTION_MODES}, got {mode!r}")
    position = np.asarray(env.robot_position, dtype=np.float64)
    heading = float(env.robot_heading)
    points = []
    for kind in kinds:
        key = f"{kind}_lidar"
        if key in env.obs_slices:
            found = obstacles_from_lidar(
                obs[env.obs_slices[key]], position, heading, max_dist=lidar_max_dist,
                refine_bearing=mode == "lidar_refined",
            )
            if len(found):
                points.append(np.asarray(found, dtype=np.float64).reshape(-1, 2))
    if not points:
        return np.zeros((0, 3))
    centres = np.concatenate(points)
    return np.hstack([centres, np.zeros((len(centres), 1))])
