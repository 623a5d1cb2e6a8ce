"""One arm in one world: whether configurations are collision-free, for many at once.

An :class:`ArmModel` is an arm chain of a URDF placed in the world: its kinematics (tool frame
= the grasp frame, through ``tcp``), its links' capsules and boxes
(:meth:`RobotModel.chain_shapes <handover.geometry.urdf.RobotModel.chain_shapes>`, the links the
joints move) and the chain's base link in the world.

A :class:`ValidityChecker` is the project's vectorised link model
(:func:`~handover.geometry.armcollision.world_hits`) for that arm against fixed
:class:`~handover.geometry.armcollision.Targets` (the scene's boxes, the bodies, the other arm's
links at its configuration), with boxes carried rigidly in the tool frame (the gripper, the
held object: ``attached``) tested like links. A configuration is valid when it lies within the
joint limits and no link or attached box touches any target (touching counts; ``margin`` m
grows every link and attached shape). The arm's links are not tested against each other.

:meth:`ValidityChecker.hits` gives the whole (configuration, link, target) matrix through
``world_hits``; :meth:`ValidityChecker.valid`, what a planner asks thousands of times, answers
the same question (a test holds them equal) faster: the (shape, target shape) pairs are
listed once per checker, a pair goes to its exact test only if its bounding volumes meet (a
capsule's bounding sphere against a box itself, not the box's sphere: a table is large), and
a configuration found touching is not tested further.

World frame, metres, radians (metres for prismatic joints).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from handover.geometry.armcollision import Targets, posed_boxes, posed_capsules, world_hits
from handover.geometry.bodies import Body
from handover.geometry.collision import _check_boxes, _check_rigid, boxes_overlap
from handover.geometry.gripper import Box
from handover.geometry.kinematics import Kinematics
from handover.geometry.proximity import segment_box_distances, segment_segment_distances
from handover.geometry.urdf import LinkShapes, RobotModel

__all__ = ["ArmModel", "ValidityChecker", "obstacles"]


@dataclass(frozen=True, eq=False)
class ArmModel:
    """An arm chain placed in the world.

    kin : its :class:`Kinematics` in the chain's base-link frame (tool frame = grasp frame).
    shapes : collision shapes of ``kin.chain.links`` (indexed like ``Kinematics.link_poses``).
    base : (4, 4) the chain's base link in the world.
    """

    kin: Kinematics
    shapes: LinkShapes
    base: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "base", _check_rigid(self.base, "ArmModel base"))
        if self.shapes.links != self.kin.chain.links:
            raise ValueError("ArmModel shapes must be those of the chain's links, in order")

    @classmethod
    def from_urdf(cls, model: RobotModel, base_link: str, tip_link: str, *,
                  tcp: np.ndarray | None = None, base_pose: np.ndarray | None = None
                  ) -> ArmModel:
        """The chain ``base_link`` -> ``tip_link`` of ``model``, its tool frame ``tcp`` (4, 4)
        from the tip link (default identity), the URDF's root at ``base_pose`` (4, 4) in the
        world (default identity)."""
        chain = model.chain(base_link, tip_link)
        root = np.eye(4) if base_pose is None else _check_rigid(base_pose, "base_pose")
        base = root @ model.fixed_pose(base_link)
        return cls(Kinematics(chain, tcp), model.chain_shapes(chain), base)

    @property
    def dof(self) -> int:
        return self.kin.dof

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.kin.chain.joint_names

    def link_poses(self, q: np.ndarray) -> np.ndarray:
        """(n, L, 4, 4) world poses of the chain's links for q (n, dof)."""
        return self.base @ self.kin.link_poses(q)

    def tool_poses(self, q: np.ndarray) -> np.ndarray:
        """(n, 4, 4) world poses of the tool (grasp) frame for q (n, dof)."""
        return self.base @ self.kin.fk(q)

    def targets(self, q: np.ndarray, prefix: str = "") -> Targets:
        """This arm's links at one configuration q (dof,) as fixed :class:`Targets` named
        ``prefix + link`` (the other arm, for an arm that moves while this one waits)."""
        poses = self.link_poses(np.asarray(q, dtype=float).reshape(1, -1))[0]
        return Targets.from_shapes(self.shapes, poses,
                                   [prefix + link for link in self.shapes.links])


def obstacles(boxes: Sequence[Box] = (), bodies: Sequence[Body] = (),
              others: Sequence[Targets] = ()) -> Targets:
    """Targets from world boxes ``(name, extents (3,), pose (4, 4))``, bodies and further
    targets (another arm's links), in that order, all in the world frame."""
    out = Targets.from_boxes(list(boxes)) if len(boxes) else Targets()
    for body in bodies:
        out = out + Targets.from_body(body)
    for other in others:
        out = out + other
    return out


class ValidityChecker:
    """The arm's links (and boxes carried in its tool frame) against fixed targets.

    arm : the :class:`ArmModel`. targets : what its links must not touch, world.
    attached : boxes ``(name, extents (3,), pose (4, 4) in the tool frame)`` carried by the
        tool (the gripper's palm and fingers, the held object), tested like links.
    margin : m, >= 0, grows every link and attached shape.
    allowed : ``(link or attached box, target)`` name pairs never tested (the held object
        on the table it is lifted from, as MoveIt's allowed collision matrix).
    """

    def __init__(self, arm: ArmModel, targets: Targets, *, attached: Sequence[Box] = (),
                 margin: float = 0.0, allowed: Sequence[tuple[str, str]] = ()) -> None:
        margin = float(margin)
        if not (np.isfinite(margin) and margin >= 0):
            raise ValueError(f"margin must be a number of metres >= 0, got {margin}")
        self.arm = arm
        self.targets = targets
        self.margin = margin
        names, centres, rots, exts = _check_boxes(list(attached))
        shapes = arm.shapes
        n_links = len(shapes.links)
        self._tip = shapes.links.index(arm.kin.chain.tip_link)
        self._tcp = arm.kin.tcp
        local = np.zeros((len(names), 4, 4))
        local[:, :3, :3], local[:, :3, 3], local[:, 3, 3] = rots, centres, 1.0
        self._n_attached = len(names)
        # The attached boxes as extra links, each posed at the tool frame.
        self.shapes = LinkShapes(
            shapes.links + names,
            shapes.cap_link, shapes.cap_a, shapes.cap_b, shapes.cap_radius,
            np.concatenate([shapes.box_link, n_links + np.arange(len(names))]).astype(np.intp),
            np.concatenate([shapes.box_pose, local]),
            np.concatenate([shapes.box_extents, exts]),
        )  # fmt: skip
        self.checks = 0  # configurations checked so far (for benchmarks)
        allowed = {(str(a), str(b)) for a, b in allowed}
        unknown = sorted(a for a, _ in allowed if a not in self.shapes.links) + sorted(
            b for _, b in allowed if b not in targets.names)
        if unknown:
            raise ValueError(f"allowed names no link, attached box or target: {unknown}")
        self._allowed = np.zeros((len(self.shapes.links), len(targets.names)), dtype=bool)
        for a, b in allowed:
            self._allowed[self.shapes.links.index(a), targets.names.index(b)] = True
        self._pairs = _pairs(self.shapes, targets, self._allowed)

    @property
    def link_names(self) -> tuple[str, ...]:
        """The chain's links, then the attached boxes (axis 1 of :meth:`hits`)."""
        return self.shapes.links

    def _poses(self, q: np.ndarray) -> np.ndarray:
        poses = self.arm.link_poses(q)
        if self._n_attached:
            tool = poses[:, self._tip] @ self._tcp
            poses = np.concatenate(
                [poses, np.repeat(tool[:, None], self._n_attached, axis=1)], axis=1)
        return poses

    def hits(self, q: np.ndarray) -> np.ndarray:
        """(n, L + A, K) bool: which link (or attached box) touches which target, for
        configurations q (n, dof)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        self.checks += len(q)
        hits = world_hits(self.shapes, self._poses(q), self.targets, margin=self.margin)
        hits[:, self._allowed] = False
        return hits

    def within_limits(self, q: np.ndarray) -> np.ndarray:
        """(n,) bool: configurations q (n, dof) within the joint limits."""
        return self.arm.kin.chain.within_limits(np.atleast_2d(q))

    def valid(self, q: np.ndarray) -> np.ndarray:
        """(n,) bool: within the joint limits and touching nothing, for q (n, dof)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        ok = self.within_limits(q)
        if ok.any() and len(self.targets):
            rows = np.flatnonzero(ok)
            self.checks += len(rows)
            ok[rows] = self._free(q[rows])
        return ok

    def _free(self, q: np.ndarray) -> np.ndarray:
        """(n,) bool: no shape touches any target, for q (n, dof) within the limits."""
        n = len(q)
        free = np.ones(n, dtype=bool)
        poses = self._poses(q)
        ca, cb = posed_capsules(self.shapes, poses)  # (n, c, 3)
        bc, br = posed_boxes(self.shapes, poses)  # (n, b, 3), (n, b, 3, 3)
        t, mg, p = self.targets, self.margin, self._pairs
        cap_r = self.shapes.cap_radius
        box_h = 0.5 * self.shapes.box_extents + mg
        t_h = 0.5 * t.box_ext
        # Capsule - capsule.
        s, k = p["cc"]
        if len(s) and free.any():
            rows = np.flatnonzero(free)
            a, b = ca[rows][:, s], cb[rows][:, s]
            reach = cap_r[s] + t.cap_radius[k] + mg
            mid = 0.5 * (a + b) - 0.5 * (t.cap_a[k] + t.cap_b[k])
            near = np.linalg.norm(mid, axis=2) <= (0.5 * np.linalg.norm(b - a, axis=2)
                                                   + p["cc_half"] + reach)  # fmt: skip
            i, j = np.nonzero(near)
            touch = segment_segment_distances(a[i, j], b[i, j], t.cap_a[k[j]],
                                              t.cap_b[k[j]]) <= reach[j]  # fmt: skip
            free[rows[i[touch]]] = False
        # Capsule - box: the capsule's bounding sphere against the box, then exact.
        s, k = p["cb"]
        if len(s) and free.any():
            rows = np.flatnonzero(free)
            a, b = ca[rows][:, s], cb[rows][:, s]
            reach = cap_r[s] + mg
            mid = ((0.5 * (a + b) - t.box_centre[k])[..., None, :] @ t.box_rot[k])[..., 0, :]
            out = np.linalg.norm(np.maximum(np.abs(mid) - t_h[k], 0.0), axis=2)
            near = out <= 0.5 * np.linalg.norm(b - a, axis=2) + reach
            i, j = np.nonzero(near)
            touch = segment_box_distances(a[i, j], b[i, j], t.box_centre[k[j]], t.box_rot[k[j]],
                                          t_h[k[j]]) <= reach[j]  # fmt: skip
            free[rows[i[touch]]] = False
        # Box - box.
        s, k = p["bb"]
        if len(s) and free.any():
            rows = np.flatnonzero(free)
            c, r = bc[rows][:, s], br[rows][:, s]
            near = np.linalg.norm(c - t.box_centre[k], axis=2) <= (
                np.linalg.norm(box_h[s], axis=1) + np.linalg.norm(t_h[k], axis=1))
            i, j = np.nonzero(near)
            touch = boxes_overlap(c[i, j], r[i, j], 2.0 * box_h[s[j]], t.box_centre[k[j]],
                                  t.box_rot[k[j]], t.box_ext[k[j]])  # fmt: skip
            free[rows[i[touch]]] = False
        # Box - capsule: the target capsule's sphere against the box, then exact.
        s, k = p["bc"]
        if len(s) and free.any():
            rows = np.flatnonzero(free)
            c, r = bc[rows][:, s], br[rows][:, s]
            mid = ((0.5 * (t.cap_a[k] + t.cap_b[k]) - c)[..., None, :] @ r)[..., 0, :]
            out = np.linalg.norm(np.maximum(np.abs(mid) - box_h[s], 0.0), axis=2)
            near = out <= p["bc_half"] + t.cap_radius[k]
            i, j = np.nonzero(near)
            touch = segment_box_distances(t.cap_a[k[j]], t.cap_b[k[j]], c[i, j], r[i, j],
                                          box_h[s[j]]) <= t.cap_radius[k[j]]  # fmt: skip
            free[rows[i[touch]]] = False
        return free

    def contacts(self, q: np.ndarray) -> list[tuple[str, str]]:
        """What one configuration q (dof,) touches: ``(link, target)`` pairs, links in chain
        order (attached boxes last), targets in order."""
        hits = self.hits(np.asarray(q, dtype=float).reshape(1, -1))[0]
        return [(self.link_names[i], self.targets.names[k]) for i, k in zip(*np.nonzero(hits),
                                                                           strict=True)]


def _pairs(shapes: LinkShapes, targets: Targets, allowed: np.ndarray
           ) -> dict[str, np.ndarray]:
    """Every (link shape, target shape) pair of each kind not ``allowed`` (links x targets
    bool), as index arrays, and the target capsules' half lengths."""
    def grid(links: np.ndarray, owners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s, t = np.meshgrid(np.arange(len(links)), np.arange(len(owners)), indexing="ij")
        s, t = s.ravel(), t.ravel()
        keep = ~allowed[links[s], owners[t]]
        return s[keep], t[keep]

    half = 0.5 * np.linalg.norm(targets.cap_b - targets.cap_a, axis=1)
    cl, bl = shapes.cap_link, shapes.box_link
    tc, tb = targets.cap_target, targets.box_target
    out = {"cc": grid(cl, tc), "cb": grid(cl, tb), "bb": grid(bl, tb), "bc": grid(bl, tc)}
    out["cc_half"] = half[out["cc"][1]]
    out["bc_half"] = half[out["bc"][1]]
    return out
