"""The obstacle distance of thesis Eq. 3.7, defined once (solvers/planner/geometry.py): hand
values, the exact projection, the symbolic form equal to the numeric one bit for bit, IPOPT's
separating-direction rows equal to the distance."""

from __future__ import annotations

import warnings

import casadi as ca
import numpy as np
import pytest

from solvers.planner import geometry
from solvers.planner.geometry import point_distances, segment_distances


def test_geometry_segment_distance_hand_values() -> None:
    points = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    centres = np.array([[1.0, 1.0], [3.0, -1.0], [-1.0, 0.0]])
    expected = np.array([[1.0, np.sqrt(2.0), 1.0], [1.0, np.sqrt(2.0), 3.0]])
    np.testing.assert_allclose(segment_distances(points, centres), expected)
    np.testing.assert_allclose(segment_distances(points[:1], centres),
                               point_distances(points[:1], centres))


def test_geometry_segment_distances_equal_the_clipped_projection_bit_for_bit() -> None:
    """Oracle: the projection parameter by np.where over a 0/0-tolerant division, clipped by
    np.clip (zero-length segments -- a resting plan -- included); no warning either way."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        points = rng.normal(size=(int(rng.integers(2, 12)), 2))
        points[rng.random(len(points)) < 0.3] = points[0]  # repeated waypoints
        centres = rng.normal(size=(int(rng.integers(1, 6)), 2)) * 2.0
        a = points[:-1, None, :]
        ab = (points[1:] - points[:-1])[:, None, :]
        length_sq = np.einsum("nmk,nmk->nm", ab, ab)
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.where(length_sq > 0.0,
                         np.einsum("nmk,nmk->nm", centres[None] - a, ab) / length_sq, 0.0)
        diff = a + np.clip(t, 0.0, 1.0)[..., None] * ab - centres[None]
        expected = np.sqrt(np.einsum("nmk,nmk->nm", diff, diff))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            got = segment_distances(points, centres)
        assert np.array_equal(got, expected)


@pytest.mark.parametrize("eps", [0.0, 1e-12])
@pytest.mark.parametrize("continuous", [False, True])
def test_symbolic_distance_is_the_numeric_one_bit_for_bit(continuous: bool, eps: float) -> None:
    """A CasADi function of :func:`geometry.symbolic_distance` (the LM hinge's distance)
    returns the NumPy form's floats exactly: one definition, two number types."""
    a, b, o = (ca.SX.sym(name, 2) for name in "abo")
    expression = geometry.symbolic_distance(a, b if continuous else None, o, eps=eps)
    function = ca.Function("distance", [a, b, o], [expression])
    rng = np.random.default_rng(1)
    for _ in range(200):
        ends = rng.normal(size=(2, 2)) * rng.uniform(0.01, 5.0)
        centre = rng.normal(size=2) * 2.0
        if continuous:
            numeric = geometry.length(*geometry.segment_offsets(ends, centre[None], eps=eps),
                                      eps=eps)[0, 0]
        else:
            numeric = geometry.length(*geometry.point_offsets(ends[:1], centre[None]),
                                      eps=eps)[0, 0]
        symbolic = float(function(ends[0], ends[1], centre))
        assert symbolic == numeric
        if eps == 0.0:
            exact = (segment_distances(ends, centre[None]) if continuous
                     else point_distances(ends[:1], centre[None]))
            assert numeric == exact[0, 0]


def test_separating_rows_hold_exactly_when_the_segment_keeps_the_distance() -> None:
    """IPOPT's continuous rows ``n . (x - o) >= c`` at both ends of a segment with the unit
    direction from the centre to the segment's nearest point reach exactly the segment's
    distance (Eq. 3.7 along the segment), and no unit direction reaches farther."""
    rng = np.random.default_rng(2)
    for _ in range(200):
        ends = rng.normal(size=(2, 2)) * 2.0
        centre = rng.normal(size=(1, 2))
        dx, dy = geometry.segment_offsets(ends, centre)
        distance = float(geometry.length(dx, dy)[0, 0])
        normal = np.array([dx[0, 0], dy[0, 0]]) / distance
        rows = [geometry.separation(normal, geometry.point_offset(*end, *centre[0]))
                for end in ends]
        assert min(rows) == pytest.approx(distance, abs=1e-12)
        for angle in rng.uniform(0.0, 2.0 * np.pi, size=8):  # any other direction: no farther
            other = np.array([np.cos(angle), np.sin(angle)])
            assert min(geometry.separation(other, geometry.point_offset(*end, *centre[0]))
                       for end in ends) <= distance + 1e-12

