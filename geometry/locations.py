"""Candidate handover locations: a world grid of points in the receiver's comfortable space
that the robot can reach, with the features the planner's soft rules score.

What the defaults encode, from the handover literature:

- Human givers place the object roughly midway between the partners, adapting to their
  distance, at about the receiver's elbow-to-chest height (Basili, Huber, Brandt, Hirche &
  Glasauer, "Investigating human-human approach and hand-over", Human Centered Robot
  Systems, 2009). Hence the height band between elbow and chest and the ``midpoint_distance``
  feature.
- Receivers prefer an object brought into their reach with the arm partly, not fully,
  extended and held in front of them rather than into their chest (Cakmak, Srinivasa, Lee,
  Forlizzi & Kiesler, "Human preferences for robot-human hand-over configurations", IROS
  2011); the spatial precision of the handover position matters more to users than its
  timing (Koene, Remazeilles, Prada, Garzo, Puerto, Endo & Wing, "Relative importance of
  spatial and temporal precision for user satisfaction in human-robot object handover",
  AISB 2014). Hence the reach fraction, the minimum distance in front of the torso and the
  lateral offset toward the receiving hand.

Every threshold is an argument (the knowledge base owns the values); this module is geometry
only. Lengths in metres, world frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handover.geometry.bodies import BodyError
from handover.geometry.human import Landmarks

__all__ = ["HandoverLocations", "handover_locations"]


@dataclass(frozen=True)
class HandoverLocations:
    """L candidate locations (rows) and their features, world frame.

    points : (L, 3) m.
    reach_fraction : (L,) distance from the receiving hand's shoulder / the receiver's arm
        reach (1 = a straight arm).
    height_fraction : (L,) ``(z - elbow_height) / (chest_height - elbow_height)``: 0 at the
        elbow, 1 at the chest.
    lateral : (L,) m, offset from the receiver's midline toward the receiving hand's side.
    front_distance : (L,) m, in front of the receiver's torso front plane.
    robot_distance : (L,) m, to the nearest robot shoulder; robot_arm : (L,) int, its index.
    robot_reach_fraction : (L,) robot_distance / robot_reach.
    midpoint_distance : (L,) m, horizontal distance from the midpoint between the receiving
        shoulder and that robot shoulder.
    comfortable : int, how many grid points were comfortable for the receiver before the
        robot's reach was applied.
    robot_gap : float, m, over those comfortable points the least ``robot_distance -
        robot_reach``: <= 0 when some are reachable; > 0 says how far the nearest one is
        beyond the robot's reach (inf if none was comfortable).
    """

    points: np.ndarray
    reach_fraction: np.ndarray
    height_fraction: np.ndarray
    lateral: np.ndarray
    front_distance: np.ndarray
    robot_distance: np.ndarray
    robot_arm: np.ndarray
    robot_reach_fraction: np.ndarray
    midpoint_distance: np.ndarray
    comfortable: int
    robot_gap: float

    def __len__(self) -> int:
        return len(self.points)


def _band(value: tuple[float, float], what: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise BodyError(f"{what} must be a (low, high) pair of numbers, got {value!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        raise BodyError(f"{what} must be finite with low <= high, got {value!r}")
    return lo, hi


def _axis(lo: float, hi: float, step: float) -> np.ndarray:
    """Grid values from ``lo`` by ``step`` up to ``hi`` (inclusive within a rounding)."""
    count = int(np.floor((hi - lo) / step + 1e-9)) + 1
    return lo + step * np.arange(max(count, 0))


def handover_locations(
    receiver: Landmarks,
    robot_shoulders: np.ndarray,
    robot_reach: float,
    hand: str = "right",
    *,
    spacing: float = 0.05,
    reach_fraction: tuple[float, float] = (0.0, 0.95),
    height_fraction: tuple[float, float] = (0.0, 1.0),
    min_front: float | None = None,
    lateral: tuple[float, float] = (-0.10, 0.45),
) -> HandoverLocations:
    """Grid points where ``receiver`` can comfortably take the object with ``hand`` and the
    robot can bring it.

    receiver : the receiver's :class:`~geometry.human.Landmarks`.
    robot_shoulders : (3,) or (s, 3) m, world: the shoulder (first joint) of each arm that
        may give. robot_reach : m, from a robot shoulder to the grasp point.
    hand : "left" | "right", the receiving hand.
    spacing : m, grid step along the receiver's forward, lateral and vertical axes.
    reach_fraction : (low, high) of the receiver's arm reach from the receiving shoulder.
    height_fraction : (low, high) of the elbow-to-chest band (0 elbow, 1 chest; beyond the
        band with values < 0 or > 1).
    min_front : m, least distance in front of the torso's front plane (default: the
        receiver's forearm length, so the object is not offered into the chest).
    lateral : (low, high) m, offset from the midline toward the receiving hand's side.

    The grid is laid in the receiver's frame (forward, toward the hand side, up), starting at
    the lower bounds, so the same input gives the same points in the same order. Returns a
    :class:`HandoverLocations` (possibly with L = 0; see ``robot_gap``).
    """
    shoulder = receiver.shoulder(hand)
    side = receiver.side(hand)
    step = float(spacing)
    if not (np.isfinite(step) and step > 0):
        raise BodyError(f"spacing must be a positive length, got {spacing!r}")
    reach_lo, reach_hi = _band(reach_fraction, "reach_fraction")
    h_lo, h_hi = _band(height_fraction, "height_fraction")
    lat_lo, lat_hi = _band(lateral, "lateral")
    front = receiver.forearm if min_front is None else float(min_front)
    if not np.isfinite(front):
        raise BodyError(f"min_front must be finite, got {min_front!r}")
    robots = np.asarray(robot_shoulders, dtype=float).reshape(-1, 3) if np.size(
        robot_shoulders) else np.zeros((0, 3))  # fmt: skip
    if len(robots) == 0 or not np.isfinite(robots).all():
        raise BodyError(f"robot_shoulders must be finite (3,) or (s, 3) points, got "
                        f"{robot_shoulders!r}")  # fmt: skip
    r_reach = float(robot_reach)
    if not (np.isfinite(r_reach) and r_reach > 0):
        raise BodyError(f"robot_reach must be a positive length, got {robot_reach!r}")

    arm = receiver.arm_reach
    elbow, chest = receiver.elbow_height, receiver.chest_height
    span = chest - elbow
    facing = receiver.facing
    # The receiver's frame: origin on the midline at the front plane, axes forward/side/up.
    origin = receiver.front_point - receiver.front_point[2] * np.array([0.0, 0.0, 1.0])
    shoulder_fwd = float((shoulder - origin) @ facing)
    u = _axis(front, shoulder_fwd + reach_hi * arm, step)
    v = _axis(lat_lo, lat_hi, step)
    z = _axis(elbow + h_lo * span, elbow + h_hi * span, step)
    uu, vv, zz = (g.reshape(-1) for g in np.meshgrid(u, v, z, indexing="ij"))
    points = origin + uu[:, None] * facing + vv[:, None] * side + zz[:, None] * np.array(
        [0.0, 0.0, 1.0])  # fmt: skip

    dist = np.linalg.norm(points - shoulder, axis=1)
    frac = dist / arm
    keep = (frac >= reach_lo) & (frac <= reach_hi)
    points, frac, uu, vv, zz = points[keep], frac[keep], uu[keep], vv[keep], zz[keep]
    comfortable = len(points)

    to_robot = np.linalg.norm(points[:, None] - robots[None], axis=2)  # (L, s)
    nearest = np.argmin(to_robot, axis=1) if comfortable else np.zeros(0, dtype=int)
    robot_dist = to_robot[np.arange(comfortable), nearest]
    gap = float((robot_dist - r_reach).min()) if comfortable else float("inf")
    ok = robot_dist <= r_reach
    points, frac, uu, vv, zz = points[ok], frac[ok], uu[ok], vv[ok], zz[ok]
    nearest, robot_dist = nearest[ok], robot_dist[ok]
    mid = 0.5 * (shoulder + robots[nearest])
    midpoint = np.linalg.norm((points - mid)[:, :2], axis=1)
    return HandoverLocations(
        points=points,
        reach_fraction=frac,
        height_fraction=(zz - elbow) / span,
        lateral=vv,
        front_distance=uu,
        robot_distance=robot_dist,
        robot_arm=nearest,
        robot_reach_fraction=robot_dist / r_reach,
        midpoint_distance=midpoint,
        comfortable=comfortable,
        robot_gap=gap,
    )
