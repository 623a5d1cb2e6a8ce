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
the same question (a test holds them equal) faster. Prepared once per checker: every shape's
points and axes in the frame of the joint that moves it, the targets' bounding spheres, the
pairs to test. Per batch of configurations (an edge's, a segment's): the shapes are posed by
one product of the joint frames with those points; each shape's centres over the whole batch
make one sphere, tested against every target shape's bounding sphere (the configurations of a
batch lie close together, so few pairs remain); those pairs' bounding spheres are compared per
configuration; a cheap separation test in a box's frame (a capsule beyond one of its slabs,
two boxes apart along one of their face normals, each clearly, by more than a nanometre)
drops most of what remains, and only the rest goes to the exact tests (the cheap kinds
first); a configuration found touching is not tested further.

World frame, metres, radians (metres for prismatic joints).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from handover.geometry.armcollision import Targets, world_hits
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
        self._prepared = _prepare(arm, self.shapes, self._n_attached, targets,
                                  self._allowed, margin)

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

    def all_valid(self, q: np.ndarray) -> bool:
        """Whether every configuration of q (n, dof) is :meth:`valid` (n = 0: True); stops at
        the first that is not (an edge or a path that touches something costs less)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if not self.within_limits(q).all():
            return False
        if not len(q) or not len(self.targets):
            return True
        self.checks += len(q)
        return bool(self._free(q, stop=True).all())

    def _free(self, q: np.ndarray, stop: bool = False) -> np.ndarray:
        """(n,) bool: no shape touches any target, for q (n, dof) within the limits. stop:
        return at the first touch found (then only ``.all()`` of the answer is right)."""
        n = len(q)
        free = np.ones(n, dtype=bool)
        p = self._prepared
        ca, cb, bc, br = self._posed(q)  # (n, c, 3) x 2, (n, b, 3), (n, b, 3, 3)
        t, cap_r, box_h, t_h = self.targets, p.cap_r, p.box_h, p.t_h
        nc, tc = len(cap_r), len(t.cap_target)
        centres = np.concatenate([0.5 * (ca + cb), bc], axis=1)  # (n, S, 3)
        # Broad phase, batch level: each shape's centres over the batch in one sphere
        # (the configurations of an edge or a segment lie close together), against every
        # target shape's bounding sphere: the (shape, target shape) pairs that may meet.
        lo, hi = centres.min(axis=0), centres.max(axis=0)  # (S, 3)
        gap = 0.5 * (lo + hi)[:, None, :] - p.t_centre  # (S, T, 3)
        reach = 0.5 * np.linalg.norm(hi - lo, axis=1)[:, None] + p.reach  # (S, T)
        shp, tgt = np.nonzero(((gap * gap).sum(axis=2) <= reach * reach) & p.mask)
        if not len(shp):
            return free
        # Then per configuration, the pairs' bounding spheres.
        gap = centres[:, shp] - p.t_centre[tgt]  # (n, m, 3)
        reach = p.reach[shp, tgt]
        rows, pair = np.nonzero((gap * gap).sum(axis=2) <= reach * reach)
        shp, tgt = shp[pair], tgt[pair]
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
                touch = _capsules_touch_boxes(ca[i, s], cb[i, s], cap_r[s], t.box_centre[k - tc],
                                              t.box_rot[k - tc], t_h[k - tc])  # fmt: skip
            elif kind == 2:
                s = s - nc
                touch = segment_box_distances(t.cap_a[k], t.cap_b[k], bc[i, s], br[i, s],
                                              box_h[s]) <= t.cap_radius[k]  # fmt: skip
            else:
                s, k = s - nc, k - tc
                touch = _boxes_touch(bc[i, s], br[i, s], box_h[s], t.box_centre[k],
                                     t.box_rot[k], t_h[k])  # fmt: skip
            free[i[touch]] = False
            if stop and not free.all():
                break
        return free

    def _posed(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The shapes at configurations q (n, dof), world: capsule ends (n, c, 3) twice, box
        centres (n, b, 3) and rotations (n, b, 3, 3) (columns the box axes). The joint
        frames in the world, ``F_i = F_(i-1) A_i Z(q_i)`` (``A_0`` with the chain's base
        folded in; ``Z``: a turn about z, or a slide along it), then every point and axis
        carried by the frame that moves it: one matrix product of the frames (n, J * 3, 4)
        with all the points and axes (4, M) gives each in every frame, and each is taken from
        its own (``_Prepared.rows``, ``_Prepared.cols``)."""
        p = self._prepared
        n, dof = len(q), len(p.fold)
        cos, sin = np.cos(q)[..., None], np.sin(q)[..., None]  # (n, dof, 1)
        step = np.repeat(p.fold[None], n, axis=0)  # (n, dof, 4, 4): A_i Z(q_i)
        x, y = p.fold[:, :, 0], p.fold[:, :, 1]  # (dof, 4)
        step[..., 0] = cos * x + sin * y
        step[..., 1] = cos * y - sin * x
        if p.slides.any():
            k = p.slides
            step[:, k, :, :2] = p.fold[k, :, :2]
            step[:, k, :, 3] = p.fold[k, :, 3] + q[:, k, None] * p.fold[k, :, 2]
        frames = np.empty((n, dof + 1, 3, 4))
        frame = step[:, 0]
        frames[:, 0] = frame[:, :3]
        for i in range(1, dof):
            frame = frame @ step[:, i]
            frames[:, i] = frame[:, :3]
        frames[:, dof] = self.arm.base[:3]  # links no joint moves: the chain's base
        every = frames.reshape(n, 3 * (dof + 1), 4) @ p.local  # (n, J * 3, M)
        world = every[:, p.rows, p.cols]  # (n, M, 3)
        nc, nb = p.n_caps, p.n_boxes
        ca, cb, bc = world[:, :nc], world[:, nc : 2 * nc], world[:, 2 * nc : 2 * nc + nb]
        br = world[:, 2 * nc + nb :].reshape(n, nb, 3, 3).transpose(0, 1, 3, 2)
        return ca, cb, bc, br

    def contacts(self, q: np.ndarray) -> list[tuple[str, str]]:
        """What one configuration q (dof,) touches: ``(link, target)`` pairs, links in chain
        order (attached boxes last), targets in order."""
        hits = self.hits(np.asarray(q, dtype=float).reshape(1, -1))[0]
        return [(self.link_names[i], self.targets.names[k]) for i, k in zip(*np.nonzero(hits),
                                                                           strict=True)]


_SLACK = 1e-9
"""m: how clearly apart a cheap separation test must find two shapes to skip their exact test
(so that only the exact tests decide a contact, to the last bit)."""


@dataclass(frozen=True, eq=False)
class _Prepared:
    """What :meth:`ValidityChecker._free` needs that stays the same for a checker.

    fold : (dof, 4, 4) each joint's fixed transform from the frame before it (the kinematics'
    folded ``A_i``, the first from the world: the chain's base folded in); slides : (dof,)
    bool, the prismatic joints.
    local : (4, M) the shapes' points (capsule ends ``a``, then ``b``, then box centres;
    w = 1) and box axes (3 per box, w = 0) in the frame of the joint that moves them (J = dof
    + 1 frames, the last the chain's base for links no joint moves); rows, cols : (M, 3) where
    each point's world coordinates lie in the product ``frames (n, J * 3, 4) @ local``.
    n_caps, n_boxes : the shapes' capsules and boxes (attached boxes included).
    cap_r : (c,) capsule radii and box_h : (b, 3) box half extents, grown by the margin;
    t_h : (Tb, 3) the target boxes' half extents. t_centre : (T, 3) the target shapes'
    bounding spheres' centres (capsules first, then boxes); reach : (S, T) the sum of a shape's
    and a target shape's bounding radii; mask : (S, T) bool, the pairs to test (not allowed).
    """

    fold: np.ndarray
    slides: np.ndarray
    local: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    n_caps: int
    n_boxes: int
    cap_r: np.ndarray
    box_h: np.ndarray
    t_h: np.ndarray
    t_centre: np.ndarray
    reach: np.ndarray
    mask: np.ndarray


def _prepare(arm: ArmModel, shapes: LinkShapes, n_attached: int, targets: Targets,
             allowed: np.ndarray, margin: float) -> _Prepared:
    """The :class:`_Prepared` of ``shapes`` (the arm's links' shapes, then ``n_attached``
    boxes carried in the tool frame) against ``targets``; ``allowed`` (links x targets)."""
    kin = arm.kin
    dof = kin.dof
    tip = shapes.links.index(kin.chain.tip_link)
    link_joint, link_local = kin.link_frames  # (L,), (L, 4, 4) link in its joint's frame
    joint = np.where(link_joint < 0, dof, link_joint).astype(np.intp)  # (L,)
    # The attached boxes ride on the tip link's joint, at the tool frame.
    link_local = np.concatenate([link_local, np.repeat((link_local[tip] @ kin.tcp)[None],
                                                       n_attached, axis=0)])  # fmt: skip
    joint = np.concatenate([joint, np.full(n_attached, joint[tip], dtype=np.intp)])
    c, b = len(shapes.cap_link), len(shapes.box_link)
    ones = np.ones((c, 1))
    cap_a = np.einsum("cij,cj->ci", link_local[shapes.cap_link], np.hstack([shapes.cap_a, ones]))
    cap_b = np.einsum("cij,cj->ci", link_local[shapes.cap_link], np.hstack([shapes.cap_b, ones]))
    box = link_local[shapes.box_link] @ shapes.box_pose  # (b, 4, 4) in the joint frame
    axes = box[:, :, :3].transpose(0, 2, 1).reshape(3 * b, 4)  # each box's x, y, z axes
    local = np.concatenate([cap_a, cap_b, box[:, :, 3], axes]).T  # (4, M)
    owner = np.concatenate([joint[shapes.cap_link], joint[shapes.cap_link],
                            joint[shapes.box_link], np.repeat(joint[shapes.box_link], 3)])
    rows = 3 * owner[:, None] + np.arange(3)  # (M, 3)
    cols = np.repeat(np.arange(len(owner))[:, None], 3, axis=1)
    cap_r = shapes.cap_radius + margin
    box_h = 0.5 * shapes.box_extents + margin
    t = targets
    t_centre = np.concatenate([0.5 * (t.cap_a + t.cap_b), t.box_centre])
    t_radius = np.concatenate([0.5 * np.linalg.norm(t.cap_b - t.cap_a, axis=1) + t.cap_radius,
                               0.5 * np.linalg.norm(t.box_ext, axis=1)])  # fmt: skip
    s_radius = np.concatenate([0.5 * np.linalg.norm(shapes.cap_b - shapes.cap_a, axis=1)
                               + cap_r, np.linalg.norm(box_h, axis=1)])  # fmt: skip
    owner_s = np.concatenate([shapes.cap_link, shapes.box_link])
    owner_t = np.concatenate([t.cap_target, t.box_target])
    fold = kin.folded
    fold[0] = arm.base @ fold[0]
    return _Prepared(fold, np.asarray(kin.prismatic, dtype=bool), local, rows, cols, c, b,
                     cap_r, box_h, 0.5 * t.box_ext, t_centre, s_radius[:, None] + t_radius[None, :],
                     ~allowed[owner_s[:, None], owner_t[None, :]])


def _capsules_touch_boxes(a: np.ndarray, b: np.ndarray, r: np.ndarray, centres: np.ndarray,
                          rots: np.ndarray, half: np.ndarray) -> np.ndarray:
    """(m,) bool: whether capsules (ends a, b (m, 3), radii r (m,)) touch boxes (centres
    (m, 3), rotations (m, 3, 3), half extents (m, 3)): first, in each box's frame, whether the
    segment lies clearly beyond one of its slabs grown by r (then not), then the exact
    segment-box distance of the others."""
    la = np.einsum("mji,mj->mi", rots, a - centres)
    lb = np.einsum("mji,mj->mi", rots, b - centres)
    grown = half + (r + _SLACK)[:, None]
    maybe = np.flatnonzero(~((np.minimum(la, lb) > grown)
                             | (np.maximum(la, lb) < -grown)).any(axis=1))  # fmt: skip
    touch = np.zeros(len(a), dtype=bool)
    if len(maybe):
        w = maybe
        touch[w] = segment_box_distances(a[w], b[w], centres[w], rots[w], half[w]) <= r[w]
    return touch


def _boxes_touch(ca: np.ndarray, ra: np.ndarray, ha: np.ndarray, cb: np.ndarray,
                 rb: np.ndarray, hb: np.ndarray) -> np.ndarray:
    """(m,) bool: whether boxes A and B (centres (m, 3), rotations (m, 3, 3), half extents
    (m, 3)) overlap: first the separating axes of their faces (clearly apart on one: not),
    then :func:`~handover.geometry.collision.boxes_overlap` (all 15 axes) for the others."""
    d = cb - ca
    rel = np.abs(np.einsum("mji,mjk->mik", ra, rb))  # |A_i . B_k|
    apart = (np.abs(np.einsum("mji,mj->mi", ra, d)) > ha + np.einsum("mik,mk->mi", rel, hb)
             + _SLACK).any(axis=1)  # fmt: skip
    apart |= (np.abs(np.einsum("mjk,mj->mk", rb, d)) > hb + np.einsum("mik,mi->mk", rel, ha)
              + _SLACK).any(axis=1)  # fmt: skip
    touch = np.zeros(len(ca), dtype=bool)
    w = np.flatnonzero(~apart)
    if len(w):
        touch[w] = boxes_overlap(ca[w], ra[w], 2.0 * ha[w], cb[w], rb[w], 2.0 * hb[w])
    return touch
