"""How the safety filter bounds the bearing of an object seen in one LiDAR bin (beyond the
thesis, §3.5.2; used by the regions of :mod:`semdp.embedded.cost_regions`).

A LiDAR bin gives an object's range exactly but its bearing only to within half a bin (11.25°),
so a region placed at the bin centre can sit up to ``2 d sin(π/32) ≈ 0.196 d`` from the true
object at range ``d``. The filter's ``lidar_bearing_bound`` says how that bearing is bounded:

* ``"aliasing"`` (the default): every lit bin ``i`` (reading ``s``, range ``d = 3 (1 - s)``) is
  a candidate object whose bearing is ``(i + α)`` bins from the heading. The sensor writes
  ``α s`` into bin ``i + 1`` and ``(1 - α) s`` into bin ``i - 1`` and keeps the largest value
  per bin, so the neighbours' readings ``n₊, n₋`` bound ``α``: ``1 - n₋ / s ≤ α ≤ n₊ / s``
  (widened by :data:`ALIAS_TOLERANCE` for the observation's float32 rounding). The object lies
  on the arc of range ``d`` over that interval of bearings; its region is centred on the arc's
  midpoint and grows by the arc's half chord ``2 d sin(Δ/4)`` (``Δ`` the interval's angle) plus
  :data:`RANGE_TOLERANCE`. An isolated object's interval is a point (its region is its cost
  disc), two objects in neighbouring bins widen it up to the whole bin, and a bin whose
  interval is empty holds no object (it is an aliasing ghost). The buttons' neighbours are read
  from the whole channel (:attr:`~semdp.embedded.perception.LidarFrame.whole`), not from the
  channel less the goal button's bins.
* ``"bin"``: every lit bin's region at the bin centre, grown by the whole bin's bound
  ``0.196 d`` (what runs recorded with ``lidar_bearing_bound: true`` used).
* ``"none"``: the planner's reconstruction (peaks only, bin-centre bearings, no bound; recorded
  runs' ``false``).

Both bounds rest on one law, stated and tested: **an object the filter must see is the largest
contribution to its own bin** (its reading there is its own ``s``). Objects the sensor cannot
see at all (a farther object of the same kind in the same bin, or one whose own bin a
neighbour's alias outshines) stay outside any LiDAR filter. ``"gt"`` reads the simulator.
"""

from __future__ import annotations

import math

from semdp.embedded.perception import LidarFrame
from sims.safety_gym.perception import BINS

#: Safety Gym's LiDAR range (m), as the reconstruction assumes.
LIDAR_RANGE = 3.0
#: Largest distance between an object at range d and its bin-centre reconstruction, per metre.
BEARING_ERROR_PER_METRE = 2.0 * math.sin(math.pi / (2 * BINS))
#: How a LiDAR object's bearing is bounded (module docstring); runs recorded before the
#: aliasing bound hold ``True`` / ``False`` (read as ``"bin"`` / ``"none"``: semdp/legacy.py).
BEARING_BOUNDS = ("aliasing", "bin", "none")
#: Widening of the aliasing interval of ``α``: float32 readings carry a relative rounding of
#: 6e-8 each, so a ratio of two is off by less than 2e-7.
ALIAS_TOLERANCE = 1e-6
#: Added to an aliasing region's radius (m): the range ``3 (1 - s)`` of a float32 reading is off
#: by less than 3e-7 m.
RANGE_TOLERANCE = 1e-6
#: Readings at or below this are empty bins (``obstacles_from_lidar``'s ``min_reading``).
MIN_READING = 1e-6


def bin_regions(frame: LidarFrame, bound: str) -> list[tuple[float, float, float, bool]]:
    """``(x, y, grow, own)`` of every lit bin's candidate object (world frame): where the object
    may be and by how much its cost region must grow to hold it, under ``bound`` (``"aliasing"``
    or ``"bin"``, module docstring), and whether the bin surely holds an object: its reading
    is above both neighbours' (an alias is at most its source's reading, which is at most the
    source bin's), so it is an object's own. Other lit bins may hold only an alias of a
    neighbour's object (a candidate all the same).

    ``"bin"``: each point is where :func:`~sims.safety_gym.perception.obstacles_from_lidar`
    (``peaks_only=False``) puts the bin's object, computed with the same operations but without
    that function's input checks and arrays (this runs at most low-level steps near an
    obstacle), grown by the whole bin's bearing error."""
    out: list[tuple[float, float, float, bool]] = []
    width = 2.0 * math.pi / BINS
    px, py = (float(v) for v in frame.position)
    heading = float(frame.heading)
    readings = [float(v) for v in frame.readings]
    whole = readings if frame.whole is None else [float(v) for v in frame.whole]
    aliasing = bound == "aliasing"
    for i, reading in enumerate(readings):
        if reading <= MIN_READING:
            continue
        dist = (1.0 - reading) * LIDAR_RANGE
        own = reading > whole[i - 1] and reading > whole[(i + 1) % BINS]
        if aliasing:
            low = max(0.0, 1.0 - whole[i - 1] / reading - ALIAS_TOLERANCE)
            high = min(1.0, whole[(i + 1) % BINS] / reading + ALIAS_TOLERANCE)
            if low > high:
                continue  # no object's own bin: an aliasing ghost
            angle = heading + (i + 0.5 * (low + high)) * width
            grow = 2.0 * dist * math.sin(0.25 * (high - low) * width) + RANGE_TOLERANCE
            out.append((px + dist * math.cos(angle), py + dist * math.sin(angle), grow, own))
        else:
            angle = heading + (i + 0.5) * width
            x, y = px + dist * math.cos(angle), py + dist * math.sin(angle)
            dx, dy = x - px, y - py
            out.append((x, y, BEARING_ERROR_PER_METRE * math.sqrt(dx * dx + dy * dy), own))
    return out
