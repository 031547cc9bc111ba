"""The obstacle distance of Eq. 3.7, defined once: for NumPy arrays and for CasADi symbols alike.

Eq. 3.7 keeps every waypoint ``x_i`` (with the continuous option every segment
``[x_i, x_{i+1}]``, §3.5.2) at least ``c_j = eps' + r_j`` from every obstacle centre ``o_j``. The
distance is written here once, on coordinates, by :func:`point_offset`, :func:`segment_offset`
and :func:`length`; every user evaluates those same lines:

* the certificate and the SCP backend on NumPy arrays (:func:`point_distances`,
  :func:`segment_distances`, :func:`segment_offsets`; broadcast over waypoints x obstacles);
* the LM backend's hinge (Eq. 3.8) and the IPOPT backend's constraints on CasADi SX symbols
  (``ops=CASADI``), and the safety shield's braking certificate (semdp/embedded).

The two forms perform the same IEEE operations in the same order (``x*x + y*y`` under the root,
the projection ``t = (o - a).(b - a) / |b - a|^2`` clipped to [0, 1]), so a CasADi function built
from the symbolic form returns the NumPy form's floats bit for bit (tests/test_planner.py checks
it). ``eps > 0`` gives the smooth form the derivative-based backends use (``eps`` added to the
projection's denominator and under the root); ``eps = 0`` the exact one, where a segment of
length 0 projects to its start.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import casadi as ca
import numpy as np


class Ops(NamedTuple):
    """The operations the distance needs beyond ``+ - *``, for one kind of number."""

    sqrt: Callable[[Any], Any]
    clip01: Callable[[Any], Any]
    #: ``ratio(along, length_sq, eps)``: the projection parameter before clipping.
    ratio: Callable[[Any, Any, float], Any]


def _numpy_ratio(along: np.ndarray, length_sq: np.ndarray, eps: float) -> np.ndarray:
    if eps:
        return along / (length_sq + eps)
    # exact: the projection where the segment has a length, 0 where it is a point (no 0/0)
    return np.divide(along, length_sq, out=np.zeros_like(along), where=length_sq > 0.0)


#: NumPy arrays (any broadcastable shapes).
NUMPY = Ops(np.sqrt, lambda t: np.minimum(np.maximum(t, 0.0), 1.0), _numpy_ratio)
#: CasADi SX / MX expressions (the projection needs ``eps > 0``: no branch on a symbol).
CASADI = Ops(ca.sqrt, lambda t: ca.fmin(ca.fmax(t, 0.0), 1.0),
             lambda along, length_sq, eps: along / (length_sq + eps))


# ---------------------------------------------------------------- the definition (Eq. 3.7)
def point_offset(px: Any, py: Any, ox: Any, oy: Any) -> tuple[Any, Any]:
    """The offset ``x - o`` of a waypoint from an obstacle centre."""
    return px - ox, py - oy


def segment_offset(
    ax: Any, ay: Any, bx: Any, by: Any, ox: Any, oy: Any, *, ops: Ops = NUMPY, eps: float = 0.0
) -> tuple[Any, Any]:
    """The offset ``p - o`` from an obstacle centre to the point ``p`` of segment ``[a, b]``
    nearest to it: ``p = a + t (b - a)``, ``t = clip((o - a).(b - a) / |b - a|^2, 0, 1)``."""
    ex, ey = bx - ax, by - ay
    rx, ry = ox - ax, oy - ay
    t = ops.clip01(ops.ratio(rx * ex + ry * ey, ex * ex + ey * ey, eps))
    return ax + t * ex - ox, ay + t * ey - oy


def squared_length(dx: Any, dy: Any) -> Any:
    """``|d|^2`` of an offset (IPOPT's constraint form ``|x - o|^2 >= c^2``)."""
    return dx * dx + dy * dy


def length(dx: Any, dy: Any, *, ops: Ops = NUMPY, eps: float = 0.0) -> Any:
    """The distance ``|d|`` of an offset (``sqrt(|d|^2 + eps)``, smooth at 0, with ``eps``)."""
    squared = squared_length(dx, dy)
    return ops.sqrt(squared + eps if eps else squared)


def separation(normal: Any, offset: tuple[Any, Any]) -> Any:
    """``n . d``: how far an offset ``d`` reaches along the direction ``n`` (a 2-vector).

    With ``|n| <= 1`` it is at most ``|d|``; IPOPT's continuous rows ask it of both ends of a
    segment (a separating direction per segment and obstacle), which holds iff the whole segment
    keeps the distance."""
    return normal[0] * offset[0] + normal[1] * offset[1]


# ---------------------------------------------------------------- NumPy: waypoints x obstacles
def point_offsets(points: np.ndarray, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`point_offset` of points (n, 2) from centres (m, 2): two arrays (n, m)."""
    return point_offset(points[:, 0, None], points[:, 1, None], centres[:, 0], centres[:, 1])


def segment_offsets(
    points: np.ndarray, centres: np.ndarray, eps: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`segment_offset` of the segments of a polyline (n >= 2 vertices) from centres
    (m, 2): two arrays (n - 1, m)."""
    a, b = points[:-1], points[1:]
    return segment_offset(a[:, 0, None], a[:, 1, None], b[:, 0, None], b[:, 1, None],
                          centres[:, 0], centres[:, 1], eps=eps)


def point_distances(points: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Distances between points (n, 2) and obstacle centres (m, 2): shape (n, m)."""
    return length(*point_offsets(points, centres))


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
    return length(*segment_offsets(points, centres))


# ---------------------------------------------------------------- CasADi: one pair
def symbolic_offset(x: Any, centre: Any) -> tuple[Any, Any]:
    """:func:`point_offset` of CasADi 2-vectors (each call builds its own expression nodes)."""
    return point_offset(x[0], x[1], centre[0], centre[1])


def symbolic_distance(a: Any, b: Any | None, centre: Any, *, eps: float = 0.0) -> Any:
    """The distance of waypoint ``a`` (or of segment ``[a, b]``) to ``centre``, as a CasADi
    expression (2-vectors in, a scalar out)."""
    if b is None:
        return length(*symbolic_offset(a, centre), ops=CASADI, eps=eps)
    offset = segment_offset(a[0], a[1], b[0], b[1], centre[0], centre[1], ops=CASADI, eps=eps)
    return length(*offset, ops=CASADI, eps=eps)
