"""Exact point/segment-to-circle distances: the safety certificate of the planner (§3.5.2).

The thesis (§3.5.2) certifies waypoints only and names the discretisation between waypoints as a
source of violations; :func:`segment_distances` gives the exact distance of every segment
``[x_i, x_{i+1}]`` to every obstacle centre, so the whole polyline can be certified too.
"""

from __future__ import annotations

import numpy as np


def point_distances(points: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Euclidean distances between points (n, 2) and obstacle centres (m, 2): shape (n, m)."""
    diff = points[:, None, :] - centres[None, :, :]
    return np.sqrt(np.einsum("nmk,nmk->nm", diff, diff))


def segment_distances(points: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Exact distances between the segments of a polyline and obstacle centres.

    Args:
        points: Polyline vertices, shape (n, 2) with n >= 1.
        centres: Obstacle centres, shape (m, 2).

    Returns:
        Array of shape (max(n - 1, 1), m): entry (k, j) is min over t in [0, 1] of
        ``||points[k] + t (points[k+1] - points[k]) - centres[j]||``. A single point gives its
        point distances.
    """
    if len(points) < 2:
        return point_distances(points, centres)
    a = points[:-1, None, :]
    ab = (points[1:] - points[:-1])[:, None, :]
    ao = centres[None, :, :] - a
    length_sq = np.einsum("nmk,nmk->nm", ab, ab)
    # the projection where the segment has a length, 0 where it is a point (no 0/0 computed)
    along = np.einsum("nmk,nmk->nm", ao, ab)
    t = np.divide(along, length_sq, out=np.zeros_like(along), where=length_sq > 0.0)
    t = np.minimum(np.maximum(t, 0.0), 1.0)  # np.clip's operation without its wrappers
    closest = a + t[..., None] * ab
    diff = closest - centres[None, :, :]
    return np.sqrt(np.einsum("nmk,nmk->nm", diff, diff))


def clearance_margins(
    points: np.ndarray, centres: np.ndarray, clearances: np.ndarray, *, continuous: bool
) -> np.ndarray:
    """Signed margins ``distance - clearance`` per (point or segment, obstacle)."""
    if continuous:
        distances = segment_distances(points, centres)
    else:
        distances = point_distances(points, centres)
    return distances - clearances[None, :]
