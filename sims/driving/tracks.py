"""Centre lines of the driving tasks: a circle and a seeded random smooth open path (App. A.2).

Both tracks answer the same questions in plain Python floats:

* :meth:`project` -- Frenet coordinates of a point: arc length ``s``, signed lateral distance
  ``d`` (positive to the *left* of the direction of travel; for the counter-clockwise circle that
  is towards its centre), and the path heading and curvature at the projection.
* :meth:`point_at` -- the centre-line point at arc length ``s``.
"""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi


def wrap_angle(angle: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (angle + math.pi) % TWO_PI - math.pi


class CircleTrack:
    """Counter-clockwise circle of radius ``radius`` about the origin.

    Args:
        radius: Circle radius [m] (> 0).
    """

    def __init__(self, radius: float) -> None:
        if not (math.isfinite(radius) and radius > 0.0):
            raise ValueError(f"radius must be a finite positive number, got {radius!r}")
        self.radius = float(radius)
        self.curvature_max = 1.0 / self.radius

    def project(self, x: float, y: float, hint: int = 0) -> tuple[float, float, float, float, int]:
        """Frenet coordinates of ``(x, y)``.

        Returns:
            ``(s, d, path_heading, curvature, hint)``; ``s`` in [0, 2 pi R), ``hint`` unused (0).
        """
        rho = math.sqrt(x * x + y * y)
        theta = math.atan2(y, x)
        if theta < 0.0:
            theta += TWO_PI
        return self.radius * theta, self.radius - rho, theta + 0.5 * math.pi, 1.0 / self.radius, 0

    def point_at(self, s: float) -> tuple[float, float]:
        """Centre-line point at arc length ``s`` (periodic)."""
        theta = s / self.radius
        return self.radius * math.cos(theta), self.radius * math.sin(theta)

    def heading_at(self, s: float) -> float:
        """Centre-line heading at arc length ``s``."""
        return s / self.radius + 0.5 * math.pi

    def curvature_at(self, s: float) -> float:
        """Centre-line curvature at arc length ``s`` [1/m]."""
        return 1.0 / self.radius


class RandomPathTrack:
    """Seeded random smooth open path sampled every ``spacing`` metres.

    The heading along the path is a sum of sinusoids in the arc length,
    ``psi(s) = sum_i A_i (sin(w_i s + p_i) - sin(p_i))``, with ``sum_i A_i <= max_heading``
    (< pi/2), so the path always advances along +x and cannot intersect itself. Its curvature
    ``kappa(s) = sum_i A_i w_i cos(w_i s + p_i)`` is bounded by ``max_curvature`` (amplitudes are
    scaled down when needed). Wavelengths are drawn from ``wavelength_range``.

    Args:
        rng: Numpy generator (the env's ``np_random``), consumed once here.
        length: Path length [m].
        spacing: Sample spacing [m].
        modes: Number of sinusoids.
        max_heading: Upper bound on the heading deviation from +x [rad] (< pi/2).
        max_curvature: Upper bound on |kappa| [1/m].
        wavelength_range: ``(min, max)`` wavelength of the sinusoids [m].
    """

    def __init__(
        self,
        rng: np.random.Generator,
        length: float = 120.0,
        spacing: float = 0.05,
        modes: int = 3,
        max_heading: float = 1.0,
        max_curvature: float = 1.0 / 1.5,
        wavelength_range: tuple[float, float] = (4.0, 16.0),
    ) -> None:
        if not 0.0 < max_heading < 0.5 * math.pi:
            raise ValueError(f"max_heading must be in (0, pi/2), got {max_heading!r}")
        if not (max_curvature > 0.0 and spacing > 0.0 and length > 10 * spacing and modes >= 1):
            raise ValueError("need max_curvature > 0, spacing > 0, length > 10 spacing, modes >= 1;"
                             f" got {max_curvature!r}, {spacing!r}, {length!r}, {modes!r}")
        lo, hi = wavelength_range
        if not 0.0 < lo <= hi:
            raise ValueError(
                f"wavelength_range must satisfy 0 < min <= max, got {wavelength_range}")
        omegas = TWO_PI / rng.uniform(lo, hi, size=modes)
        phases = rng.uniform(0.0, TWO_PI, size=modes)
        weights = rng.uniform(0.2, 1.0, size=modes)
        amplitudes = weights / weights.sum() * max_heading * rng.uniform(0.5, 1.0)
        peak_curvature = float(np.sum(amplitudes * omegas))
        if peak_curvature > max_curvature:
            amplitudes *= max_curvature / peak_curvature

        count = math.ceil(length / spacing) + 1
        s = np.arange(count) * spacing
        arg = np.outer(s, omegas) + phases
        heading = np.sin(arg) @ amplitudes - float(np.sum(amplitudes * np.sin(phases)))
        curvature = np.cos(arg) @ (amplitudes * omegas)
        # trapezoidal integration of the unit tangent
        cos_h, sin_h = np.cos(heading), np.sin(heading)
        xs = np.concatenate([[0.0], np.cumsum(0.5 * spacing * (cos_h[1:] + cos_h[:-1]))])
        ys = np.concatenate([[0.0], np.cumsum(0.5 * spacing * (sin_h[1:] + sin_h[:-1]))])

        self.spacing = float(spacing)
        self.length = float(s[-1])
        self.curvature_max = float(max_curvature)
        self.xs: list[float] = xs.tolist()
        self.ys: list[float] = ys.tolist()
        self.headings: list[float] = heading.tolist()
        self.curvatures: list[float] = curvature.tolist()
        self.last_index = count - 1

    def nearest_index(self, x: float, y: float, hint: int) -> int:
        """Index of the nearest sample, found by walking from ``hint`` (local search)."""
        xs, ys = self.xs, self.ys
        i = min(max(hint, 0), self.last_index)
        best = (xs[i] - x) ** 2 + (ys[i] - y) ** 2
        while i < self.last_index:
            dist = (xs[i + 1] - x) ** 2 + (ys[i + 1] - y) ** 2
            if dist >= best:
                break
            i += 1
            best = dist
        while i > 0:
            dist = (xs[i - 1] - x) ** 2 + (ys[i - 1] - y) ** 2
            if dist >= best:
                break
            i -= 1
            best = dist
        return i

    def project(self, x: float, y: float, hint: int = 0) -> tuple[float, float, float, float, int]:
        """Frenet coordinates of ``(x, y)``, expanded to second order about the nearest sample.

        Args:
            x: World x [m].
            y: World y [m].
            hint: Index to start the local search from (the previous result).

        Returns:
            ``(s, d, path_heading, curvature, index)``.
        """
        i = self.nearest_index(x, y, hint)
        heading = self.headings[i]
        curvature = self.curvatures[i]
        c = math.cos(heading)
        sn = math.sin(heading)
        dx = x - self.xs[i]
        dy = y - self.ys[i]
        along = c * dx + sn * dy
        # second-order Taylor expansion of the path about sample i (|along| <= spacing / 2)
        return (i * self.spacing + along, c * dy - sn * dx - 0.5 * curvature * along * along,
                heading + curvature * along, curvature, i)

    def _index(self, s: float) -> tuple[int, float]:
        u = s / self.spacing
        i = int(u)
        if i < 0:
            return 0, 0.0
        if i >= self.last_index:
            return self.last_index - 1, 1.0
        return i, u - i

    def point_at(self, s: float) -> tuple[float, float]:
        """Centre-line point at arc length ``s`` (linear interpolation; clamped to the ends)."""
        i, f = self._index(s)
        return (self.xs[i] + f * (self.xs[i + 1] - self.xs[i]),
                self.ys[i] + f * (self.ys[i + 1] - self.ys[i]))

    def heading_at(self, s: float) -> float:
        """Centre-line heading at arc length ``s`` (clamped to the ends)."""
        i, f = self._index(s)
        return self.headings[i] + f * (self.headings[i + 1] - self.headings[i])

    def curvature_at(self, s: float) -> float:
        """Centre-line curvature at arc length ``s`` [1/m] (clamped to the ends)."""
        i, f = self._index(s)
        return self.curvatures[i] + f * (self.curvatures[i + 1] - self.curvatures[i])
