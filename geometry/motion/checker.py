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
the same question (a test holds them equal) faster: the targets' bounding spheres and the
pairs to test are prepared once per checker; one array operation compares every (configuration,
shape, target shape) pair's bounding spheres, only the pairs whose spheres meet go to their
exact tests (the cheap kinds first), and a configuration found touching is not tested further.

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
        cap_r = self.shapes.cap_radius + mg
        box_h = 0.5 * self.shapes.box_extents + mg
        t_h = 0.5 * t.box_ext
        # Broad phase over every (configuration, shape, target shape) at once: bounding
        # spheres (capsules: about their middle; boxes: about their centre).
        centres = np.concatenate([0.5 * (ca + cb), bc], axis=1)  # (n, c + b, 3)
        radii = np.concatenate([0.5 * np.linalg.norm(cb - ca, axis=2) + cap_r,
                                np.broadcast_to(np.linalg.norm(box_h, axis=1),
                                                (n, len(box_h)))], axis=1)  # fmt: skip
        gap = centres[:, :, None, :] - p["t_centre"]  # (n, S, T, 3)
        reach = radii[:, :, None] + p["t_radius"]
        near = ((gap * gap).sum(axis=3) <= reach * reach) & p["mask"]
        rows, shp, tgt = np.nonzero(near)
        nc, tc = len(cap_r), len(t.cap_target)
        kinds = (shp >= nc).astype(int) * 2 + (tgt >= tc)  # 0 cc, 1 cb, 2 bc, 3 bb
        for kind in (0, 3, 1, 2):  # the cheap exact tests first
            pick = np.flatnonzero((kinds == kind) & free[rows])
            if not len(pick):
                continue
            i, s, k = rows[pick], shp[pick], tgt[pick]
            if kind == 0:
                touch = segment_segment_distances(ca[i, s], cb[i, s], t.cap_a[k],
                                                  t.cap_b[k]) <= cap_r[s] + t.cap_radius[k]
            elif kind == 1:
                k = k - tc
                touch = segment_box_distances(ca[i, s], cb[i, s], t.box_centre[k], t.box_rot[k],
                                              t_h[k]) <= cap_r[s]  # fmt: skip
            elif kind == 2:
                s = s - nc
                touch = segment_box_distances(t.cap_a[k], t.cap_b[k], bc[i, s], br[i, s],
                                              box_h[s]) <= t.cap_radius[k]  # fmt: skip
            else:
                s, k = s - nc, k - tc
                touch = boxes_overlap(bc[i, s], br[i, s], 2.0 * box_h[s], t.box_centre[k],
                                      t.box_rot[k], t.box_ext[k])  # fmt: skip
            free[i[touch]] = False
        return free

    def contacts(self, q: np.ndarray) -> list[tuple[str, str]]:
        """What one configuration q (dof,) touches: ``(link, target)`` pairs, links in chain
        order (attached boxes last), targets in order."""
        hits = self.hits(np.asarray(q, dtype=float).reshape(1, -1))[0]
        return [(self.link_names[i], self.targets.names[k]) for i, k in zip(*np.nonzero(hits),
                                                                           strict=True)]


def _pairs(shapes: LinkShapes, targets: Targets, allowed: np.ndarray
           ) -> dict[str, np.ndarray]:
    """The target shapes' bounding spheres (capsules first, then boxes): ``t_centre`` (T, 3),
    ``t_radius`` (T,); and ``mask`` (S, T) bool, the (link shape, target shape) pairs to
    test (link shapes: capsules first, then boxes), those not ``allowed`` (links x targets)."""
    t_centre = np.concatenate([0.5 * (targets.cap_a + targets.cap_b), targets.box_centre])
    t_radius = np.concatenate([0.5 * np.linalg.norm(targets.cap_b - targets.cap_a, axis=1)
                               + targets.cap_radius,
                               0.5 * np.linalg.norm(targets.box_ext, axis=1)])  # fmt: skip
    owner_s = np.concatenate([shapes.cap_link, shapes.box_link])
    owner_t = np.concatenate([targets.cap_target, targets.box_target])
    mask = ~allowed[owner_s[:, None], owner_t[None, :]]
    return {"t_centre": t_centre, "t_radius": t_radius, "mask": mask}
