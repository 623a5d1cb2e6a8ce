"""The robot's arms, from its KB document and URDF: kinematics, reachability, inverse
kinematics and collisions, in the world frame.
Longer than 500 lines: one class, the arms in the world, whose methods share each arm's base
transform, chain and tool frame (a split would pass them back and forth).

:func:`robot_arms` (or :meth:`RobotArms.load`) turns a :class:`~handover.engine.spec.robotspec.
RobotSpec` with ``arms`` into a :class:`RobotArms`: per arm (``left``/``right``) an
:class:`~handover.engine.assets.robot_load.Arm`
with its chain, its :class:`~handover.geometry.kinematics.Kinematics` (tool frame = the grasp
frame, through the arm's ``tcp``), its base in the world and its links' collision shapes; and
the robot's body (:class:`~handover.geometry.bodies.Body`, world). A robot without arms gives
``None``.

World poses: ``base_pose`` (the URDF root link in the world) @ the arm's base link in the root
frame @ FK(q) (tip link) @ ``tcp`` = the grasp frame ``[n o a p]`` (m). Joint values are
radians (metres for prismatic joints).

- The URDF is parsed once per content hash and path in a process
  (:func:`handover.engine.assets.robot_load.robot_model`, a small bounded cache).
- Each arm's reachability map (:class:`~handover.geometry.reach.ReachMap`) is built on first
  use and saved in ``reach_dir`` (:func:`reach_dir`: ``<grasp database>/reach``), named by the
  URDF's hash, the chain, the tcp and the map's parameters, so a changed URDF or tcp gets a new
  map. A :class:`RobotArms` keeps the maps it read or built (without a folder, only there):
  whoever keeps the arms keeps their maps, a :class:`handover.Planner` (its ``arms_cache``)
  or, for plans made without one, this process (:func:`plan_arms`, at most
  :data:`ARMS_KEPT` robots).
- :meth:`RobotArms.reachable` screens poses with the map; :meth:`RobotArms.solve` is exact
  damped-least-squares IK with seeded restarts (same input, same answer; a target's answer
  does not depend on the other targets of the batch).
- :meth:`RobotArms.collisions` names what an arm's links touch at configurations: world boxes,
  bodies (the receiver's), the robot's own body (except the link the arm is mounted on) and
  the other arm; :meth:`RobotArms.contacts` says which link touches what, and
  :meth:`RobotArms.solve_each` gives several answers per pose (starts whose links clear given
  bodies first), for a plan that wants one whose links clear the world
  (:mod:`handover.engine.plan.arms.solve`).

Errors in the robot's files are :class:`~handover.engine.errors.KBError` at the YAML node,
with the URDF's own file:line in the message (:func:`handover.engine.assets.robot_load.check_robot`,
also run by ``handover kb validate``). Loading and checking live in
:mod:`handover.engine.assets.robot_load`.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from handover.engine.assets.lru import LRU
from handover.engine.assets.robot_load import Arm, assemble, frame_pose, kb_relative
from handover.engine.errors import KBError, UsageError
from handover.engine.spec.robotspec import SIDES, RobotSpec
from handover.geometry.armcollision import Targets, arms_hits, world_hits
from handover.geometry.bodies import Body
from handover.geometry.frames import invert_transform
from handover.geometry.kinematics import IKResult
from handover.geometry.reach import ReachMap
from handover.geometry.urdf import LinkShapes, RobotModel, RobotModelError

if TYPE_CHECKING:
    from handover.engine.assets.graspdb import GraspDB
    from handover.engine.store.kb import KB

__all__ = ["RobotArms", "Solution", "plan_arms", "reach_dir", "robot_arms", "ARMS_KEPT",
           "PLAN_ARMS"]

REACH_FOLDER = "reach"
"""The folder of reachability maps inside the grasp database's folder."""

IK_RESTARTS = 10
"""Random restarts per target after its first start (the field notes: one start misses 19-28 % of
reachable poses; 5 restarts 3 %, 20 restarts 0.3 %)."""

START_LIBRARY = 4096

IK_KEPT = 50_000
"""Inverse-kinematics answers a :class:`RobotArms` keeps (:meth:`RobotArms.ik_from`), by arm,
target and starts: a plan asks the same pick-up poses whatever the receiver, and a warm
planner the same poses again; about 0.5 KB each."""

SPARED_SAMPLES = 256
"""Configurations per arm that find the robot body's primitives its links always touch
(:meth:`RobotArms.spared`)."""
"""Configurations per arm whose grasp poses start inverse kinematics (the nearest first)."""

CORE = 1
"""The map's core (:meth:`RobotArms.reach_map` with ``core``): its rim eroded by one voxel,
precision against inverse kinematics 0.94 instead of 0.83 for a recall of 0.93 instead of
0.995 (``ReachMap.build``). Plans screen every row with the cores; exact checks of an arm
the core rejects but the whole map holds come after (:mod:`handover.engine.plan.arms.solve`)."""


def _absent():
    raise KeyError("an inverse-kinematics answer looked up is no longer kept")


def reach_dir(db: GraspDB | None) -> Path | None:
    """Where reachability maps are cached: ``<db folder>/reach`` for a grasp database on disk,
    None (maps kept in the process only) without one or for an in-memory database."""
    from handover.engine.assets.graspdb import MemoryDB

    if db is None or isinstance(db, MemoryDB):
        return None
    return db.root / REACH_FOLDER


class Solution(NamedTuple):
    """Inverse kinematics of m grasp poses for one arm.

    q : (m, dof) joint values within the limits (for a failure: the closest attempt).
    ok : (m,) bool, reached within 0.1 mm and 1 mrad. position_error : (m,) m.
    rotation_error : (m,) rad.
    """

    q: np.ndarray
    ok: np.ndarray
    position_error: np.ndarray
    rotation_error: np.ndarray


@dataclass(eq=False)
class RobotArms:
    """A robot's arms and body in the world (see the module docstring).

    spec : the robot's document. model : its URDF. urdf : the URDF's path relative to the KB
    folder (posix). base_pose : (4, 4) the root link in the world. arms : side -> :class:`Arm`.
    body : the robot's body in the world. reach_dir : where maps are cached (None: memory).
    map_params : :meth:`ReachMap.build` parameters (``samples``, ``voxel``, ``directions``,
    ...); the defaults of :meth:`ReachMap.cached` where absent.
    """

    spec: RobotSpec
    model: RobotModel
    urdf: str
    base_pose: np.ndarray
    arms: dict[str, Arm]
    body: Body
    reach_dir: Path | None = None
    map_params: dict = field(default_factory=dict)
    _maps: dict = field(default_factory=dict, repr=False)
    _library: dict = field(default_factory=dict, repr=False)
    _rest: dict = field(default_factory=dict, repr=False)
    _distal: dict = field(default_factory=dict, repr=False)
    _spared: dict = field(default_factory=dict, repr=False)
    _answers: LRU = field(default_factory=lambda: LRU(IK_KEPT), repr=False)

    @classmethod
    def load(
        cls,
        kb: KB,
        robot: str | RobotSpec,
        *,
        reach_dir: Path | str | None = None,
        map_params: dict | None = None,
    ) -> RobotArms:
        """The arms of ``robot`` (an id or a document of ``kb``). Raises
        :class:`~handover.engine.errors.KBError` for a robot without arms or with a URDF
        problem (located at the YAML node, the URDF's file:line in the message)."""
        spec = kb.robot(robot) if isinstance(robot, str) else robot
        if not spec.arms:
            raise KBError([kb.issue(spec, f"robot '{spec.id}' has no arms (give 'urdf' and "
                                          "'arms')")])  # fmt: skip
        built, issues = assemble(kb, spec)
        errors = [i for i in issues if i.severity == "error"]
        if errors or built is None:
            raise KBError(errors)
        model, arms, body = built
        return cls(
            spec,
            model,
            kb_relative(kb, spec),
            frame_pose(spec.base_pose),
            arms,
            body,
            None if reach_dir is None else Path(reach_dir),
            dict(map_params or {}),
        )

    # ------------------------------------------------------------------ arms and poses

    @property
    def sides(self) -> tuple[str, ...]:
        """The arms' sides, ``left`` first."""
        return tuple(s for s in SIDES if s in self.arms)

    def arm(self, side: str) -> Arm:
        """The arm on ``side``; UsageError if the robot has none there."""
        if side not in self.arms:
            raise UsageError(f"robot '{self.spec.id}' has no {side!r} arm "
                             f"(arms: {', '.join(self.sides)})")  # fmt: skip
        return self.arms[side]

    def _to_base(self, arm: Arm, poses_world: np.ndarray) -> np.ndarray:
        poses = np.asarray(poses_world, dtype=float)
        if poses.ndim == 2:
            poses = poses[None]
        if poses.ndim != 3 or poses.shape[1:] != (4, 4):
            raise ValueError(f"poses must have shape (m, 4, 4), got {poses.shape}")
        return invert_transform(arm.base) @ poses

    def fk(self, side: str, q: np.ndarray) -> np.ndarray:
        """(n, 4, 4) grasp-frame poses in the world for configurations q (n, dof)."""
        arm = self.arm(side)
        return arm.base @ arm.kin.fk(q)

    def link_poses(self, side: str, q: np.ndarray) -> np.ndarray:
        """(n, L, 4, 4) world poses of ``arm.chain.links`` for q (n, dof)."""
        arm = self.arm(side)
        return arm.base @ arm.kin.link_poses(q)

    def joints_dict(self, side: str, q: np.ndarray) -> dict[str, float]:
        """One configuration q (dof,) as ``{joint name: rad (m for prismatic)}``."""
        return self.arm(side).chain.as_dict(q)

    def within_limits(self, side: str, q: np.ndarray) -> np.ndarray:
        """(n,) bool: configurations q (n, dof) within the arm's joint limits."""
        return self.arm(side).chain.within_limits(np.atleast_2d(q))

    # ------------------------------------------------------------------ reachability and IK

    def reach_map(self, side: str, core: bool = False) -> ReachMap:
        """The arm's reachability map: kept by these arms once read or built, else from
        ``reach_dir``, else built (and saved there). core : the map with its rim eroded
        (:data:`CORE`)."""
        arm = self.arm(side)
        key = (side, core)
        if key in self._maps:
            return self._maps[key]
        if core:  # eroded in memory from the whole map: no second sampling, no second file
            found = self._core(self.reach_map(side))
        elif self.reach_dir is None:
            found = ReachMap.build(arm.kin, **self.map_params)
        else:
            found = ReachMap.cached(arm.kin, self.reach_dir, self.model.content_hash,
                                    **self.map_params)  # fmt: skip
        self._maps[key] = found
        return found

    @property
    def kept_maps(self) -> tuple[ReachMap, ...]:
        """The reachability maps these arms keep (read or built so far: per arm the whole map
        and its core)."""
        return tuple(self._maps.values())

    def _core(self, whole: ReachMap) -> ReachMap:
        """``whole`` eroded by :data:`CORE`, read from ``reach_dir`` when saved there before
        (named after the whole map's key), else eroded and saved."""
        path = None if self.reach_dir is None or not whole.key else \
            self.reach_dir / f"reach-{whole.key}-eroded{CORE}.npz"
        if path is not None and path.is_file():
            try:
                found = ReachMap.load(path)
                if found.key == f"{whole.key}-eroded{CORE}":
                    return found
            except RobotModelError:
                pass  # eroded again below
        core = whole.eroded(CORE)
        if path is not None:
            core.save(self.reach_dir)
        return core

    def reachable(self, side: str, poses_world: np.ndarray) -> np.ndarray:
        """(m,) bool: whether the map says the arm reaches grasp poses (m, 4, 4), world, m.
        A screen: ``False`` is (nearly) certain, ``True`` wants :meth:`solve` to confirm."""
        arm = self.arm(side)
        return self.reach_map(side).reachable(self._to_base(arm, poses_world))

    def reachable_at(self, side: str, points: np.ndarray, approaches: np.ndarray,
                     core: bool = False) -> np.ndarray:
        """(m,) bool: :meth:`reachable` for grasp positions points (m, 3) with approach
        directions approaches (m, 3, unit), world, m (no 4x4 poses needed). core : ask the
        map's core (:data:`CORE`)."""
        arm = self.arm(side)
        rot, t = arm.base[:3, :3], arm.base[:3, 3]
        local = (np.asarray(points, dtype=float).reshape(-1, 3) - t) @ rot
        return self.reach_map(side, core).lookup(
            local, np.asarray(approaches, float).reshape(-1, 3) @ rot)

    def reach_index(self, side: str, points: np.ndarray) -> np.ndarray:
        """(m,) in [0, 1]: the fraction of approach directions the arm's map holds at world
        positions points (m, 3), m (0: the arm reaches there in no way)."""
        arm = self.arm(side)
        local = (np.asarray(points, dtype=float).reshape(-1, 3) - arm.base[:3, 3]) \
            @ arm.base[:3, :3]
        return self.reach_map(side).reach_index(local)

    def solve(
        self,
        side: str,
        poses_world: np.ndarray,
        q0: np.ndarray | None = None,
        *,
        restarts: int = IK_RESTARTS,
    ) -> Solution:
        """Joint values putting the arm's grasp frame at poses (m, 4, 4), world, m.

        q0 : (dof,) or (m, dof) first guess, then (for the targets not reached) the
        ``restarts`` configurations of the start library whose poses lie nearest; without a
        first guess, the ``restarts + 1`` nearest. A target's answer depends on it alone (not on
        the others asked with it); the same input gives the same answer.
        """
        arm = self.arm(side)
        targets = self._to_base(arm, poses_world)
        if q0 is not None:
            start = np.broadcast_to(np.asarray(q0, dtype=float).reshape(-1, arm.dof),
                                    (len(targets), arm.dof))
            result = self.ik_from(side, targets, start[:, None, :])
            if restarts and not result.success.all():  # then from the library
                again = np.flatnonzero(~result.success)
                alt = self.ik_from(side, targets[again], self._nearest(side, targets[again],
                                                                    restarts))
                take = again[alt.success]
                q, ok = result.q.copy(), result.success.copy()
                pe, re = result.position_error.copy(), result.rotation_error.copy()
                q[take], ok[take] = alt.q[alt.success], True
                pe[take], re[take] = alt.position_error[alt.success], \
                    alt.rotation_error[alt.success]
                return Solution(q, ok, pe, re)
            return Solution(result.q, result.success, result.position_error,
                            result.rotation_error)
        result = self.ik_from(side, targets, self._nearest(side, targets, restarts + 1))
        return Solution(result.q, result.success, result.position_error, result.rotation_error)

    def solve_each(
        self,
        side: str,
        poses_world: np.ndarray,
        count: int,
        *,
        avoid: Sequence[Body] = (),
        pool: int = 32,
    ) -> Solution:
        """Several inverse-kinematics answers per pose, for a caller that wants one whose
        links clear something: ``q`` (m, count, dof), ``ok``, ``position_error``,
        ``rotation_error`` (m, count), each pose solved from each of ``count`` starts on its
        own. The starts: among the ``pool`` configurations of the start library whose grasp
        poses lie nearest the pose (as :meth:`solve`), those whose links touch none of
        ``avoid`` (bodies, world) first, nearest first. Deterministic; a pose's answers depend
        on it alone."""
        arm = self.arm(side)
        targets = self._to_base(arm, poses_world)
        m, dof = len(targets), arm.dof
        pool = min(max(count, pool), START_LIBRARY)
        starts = self._nearest(side, targets, pool)  # (m, pool, dof)
        if avoid and m:
            obstacles = Targets()
            for body in avoid:
                obstacles = obstacles + Targets.from_body(body)
            touch = world_hits(arm.shapes, self.link_poses(side, starts.reshape(-1, dof)),
                               obstacles).any(axis=(1, 2)).reshape(m, pool)  # fmt: skip
            order = np.argsort(touch, axis=1, kind="stable")  # clear ones first
            starts = np.take_along_axis(starts, order[:, :, None], axis=1)
        starts = starts[:, :count]
        count = starts.shape[1]
        result = self.ik_from(side, np.repeat(targets, count, axis=0),
                              starts.reshape(-1, 1, dof))  # fmt: skip
        return Solution(result.q.reshape(m, count, dof), result.success.reshape(m, count),
                        result.position_error.reshape(m, count),
                        result.rotation_error.reshape(m, count))

    def ik_from(self, side: str, targets: np.ndarray, starts: np.ndarray) -> IKResult:
        """:meth:`~handover.geometry.kinematics.Kinematics.ik_from` of the arm on ``side``:
        targets (m, 4, 4), base frame, m, from starts (m, r, dof) each, remembered per target
        and its starts (a target's answer depends on them alone, so a remembered answer is
        the one solving would give, to the bit). ``attempts`` counts the starts tried now
        (0 for a remembered answer)."""
        arm = self.arm(side)
        targets = np.ascontiguousarray(targets, dtype=float).reshape(-1, 4, 4)
        starts = np.ascontiguousarray(starts, dtype=float)
        m = len(targets)
        keys = [(side, hashlib.blake2b(t.tobytes() + s.tobytes(), digest_size=16).digest())
                for t, s in zip(targets, starts, strict=True)]
        q = np.empty((m, arm.dof))
        ok = np.zeros(m, dtype=bool)
        pos_err, rot_err = np.empty(m), np.empty(m)
        attempts = np.zeros(m, dtype=np.int64)
        todo = []
        for i, key in enumerate(keys):  # read before solving: storing may drop old answers
            if key in self._answers:
                q[i], ok[i], pos_err[i], rot_err[i] = self._answers.fetch(key, _absent)
            else:
                todo.append(i)
        if todo:
            rows = np.array(todo)
            found = arm.kin.ik_from(targets[rows], starts[rows])
            q[rows], ok[rows] = found.q, found.success
            pos_err[rows], rot_err[rows] = found.position_error, found.rotation_error
            attempts[rows] = found.attempts
            for j, i in enumerate(todo):
                self._answers.put(keys[i], (found.q[j].copy(), bool(found.success[j]),
                                            float(found.position_error[j]),
                                            float(found.rotation_error[j])))
        return IKResult(q, ok, pos_err, rot_err, attempts)

    def answer_keys(self) -> set:
        """The keys of the inverse-kinematics answers kept (:meth:`ik_from`)."""
        return set(self._answers)

    def answers_since(self, known: set) -> dict:
        """The answers kept whose keys are not in ``known`` (an :meth:`answer_keys`): what
        this process solved since, for another process to :meth:`remember`."""
        return {k: self._answers.fetch(k, _absent) for k in self._answers if k not in known}

    def remember(self, answers: dict) -> None:
        """Keep ``answers`` (from :meth:`answers_since` of the same arms in another process:
        an answer depends on its key alone, so it is the one solving here would give)."""
        for key, answer in answers.items():
            self._answers.put(key, answer)

    def _library_distances(self, side: str, targets: np.ndarray) -> np.ndarray:
        """(m, L) distances from targets (m, 4, 4), base frame, to the grasp poses of the
        arm's start library (:data:`START_LIBRARY` configurations drawn within the limits, seed
        0): metres of position plus 0.1 m per radian-like unit of the rotations' Frobenius
        distance."""
        arm = self.arm(side)
        if side not in self._library:
            rng = np.random.default_rng(0)
            q = arm.kin.random_configurations(START_LIBRARY, rng)
            self._library[side] = (q, arm.kin.fk(q))
        _, poses = self._library[side]
        d = np.linalg.norm(targets[:, None, :3, 3] - poses[None, :, :3, 3], axis=2)
        d += 0.1 * np.linalg.norm((targets[:, None, :3, :3] - poses[None, :, :3, :3])
                                  .reshape(len(targets), len(poses), 9), axis=2)
        return d

    def start_distance(self, side: str, poses_world: np.ndarray) -> np.ndarray:
        """(m,) how far each grasp pose (m, 4, 4), world, lies from the nearest pose of the
        arm's start library (:meth:`_library_distances`): the smaller, the likelier inverse
        kinematics reaches it from there."""
        arm = self.arm(side)
        return self._library_distances(side, self._to_base(arm, poses_world)).min(axis=1)

    def _nearest(self, side: str, targets: np.ndarray, count: int) -> np.ndarray:
        """(m, count, dof) starts for targets (m, 4, 4), base frame: the configurations of the
        arm's start library whose grasp poses lie nearest each target
        (:meth:`_library_distances`), nearest first."""
        d = self._library_distances(side, targets)
        q = self._library[side][0]
        count = min(count, len(q))
        near = np.argpartition(d, count - 1, axis=1)[:, :count]
        order = np.take_along_axis(d, near, axis=1).argsort(axis=1, kind="stable")
        return q[np.take_along_axis(near, order, axis=1)]

    # ------------------------------------------------------------------ collisions

    def contacts(
        self,
        side: str,
        q: np.ndarray,
        *,
        boxes: Sequence[tuple[str, np.ndarray, np.ndarray]] = (),
        bodies: Sequence[Body] = (),
        other: tuple[str, np.ndarray] | None = None,
        own_body: bool = True,
        margin: float = 0.0,
    ) -> list[list[tuple[str, str]]]:
        """For each configuration q (n, dof) of the arm on ``side``, which of its links touches
        what: ``(link, target)`` pairs, targets in order (``boxes``, then ``bodies``' names,
        then the robot's own body, then the other arm's links), links in chain order within a
        target. Targets as :meth:`collisions`; the other arm's are named after its links."""
        arm = self.arm(side)
        q = np.atleast_2d(np.asarray(q, dtype=float))
        poses = self.link_poses(side, q)
        targets = Targets.from_boxes(list(boxes)) if boxes else Targets()
        for body in bodies:
            targets = targets + Targets.from_body(body)
        if own_body and len(self.body):
            spared = set(self.spared(side))
            own = self.body.subset([name not in spared for name in self.body.names])
            targets = targets + Targets.from_body(own)
        links = arm.shapes.links
        hits = world_hits(arm.shapes, poses, targets, margin=margin)  # (n, L, K)
        out = [[(links[j], targets.names[k]) for k, j in zip(*np.nonzero(row.T), strict=True)]
               for row in hits]  # fmt: skip
        if other is not None:
            other_side, q_other = other
            o = self.arm(other_side)
            q_other = np.atleast_2d(np.asarray(q_other, dtype=float))
            touch = arms_hits(arm.shapes, poses, o.shapes, self.link_poses(other_side, q_other),
                              margin=margin)  # (n, L, Lb)  # fmt: skip
            for row, found in zip(out, touch, strict=True):
                row.extend((links[j], o.shapes.links[k])
                           for k, j in zip(*np.nonzero(found.T), strict=True))
        return out

    def spared(self, side: str) -> tuple[str, ...]:
        """The names of the robot body's primitives the arm's links are never tested against:
        the link the arm is mounted on, and any its links touch at every one of
        :data:`SPARED_SAMPLES` configurations drawn within its limits (seeded): the shoulder
        it turns in, whatever a robot's YAML ``body`` calls it (as MoveIt's setup assistant
        disables the pairs always in collision)."""
        if side not in self._spared:
            arm = self.arm(side)
            q = arm.kin.random_configurations(SPARED_SAMPLES, np.random.default_rng(0))
            targets = Targets.from_body(self.body)
            hits = world_hits(arm.shapes, self.link_poses(side, q), targets).any(axis=1)
            always = [targets.names[k] for k in np.flatnonzero(hits.all(axis=0))]
            self._spared[side] = tuple(dict.fromkeys([arm.mount, *always]))
        return self._spared[side]

    def distal(self, side: str) -> tuple[LinkShapes, np.ndarray]:
        """The arm's links rigidly attached to its grasp frame (those the last joint carries:
        a wrist's last link, the flange) as their own :class:`LinkShapes`, and their poses
        (L', 4, 4) in the grasp frame: where they are follows from a grasp pose alone, with no
        inverse kinematics (:meth:`distal_contacts`)."""
        if side not in self._distal:
            arm = self.arm(side)
            chain, shapes = arm.chain, arm.shapes
            keep = np.flatnonzero(np.asarray(chain.link_joint) == arm.dof - 1)
            index = np.full(len(shapes.links), -1, dtype=np.intp)
            index[keep] = np.arange(len(keep))
            caps = np.flatnonzero(index[shapes.cap_link] >= 0)
            boxes = np.flatnonzero(index[shapes.box_link] >= 0)
            sub = LinkShapes(tuple(shapes.links[k] for k in keep),
                             index[shapes.cap_link[caps]], shapes.cap_a[caps],
                             shapes.cap_b[caps], shapes.cap_radius[caps],
                             index[shapes.box_link[boxes]], shapes.box_pose[boxes],
                             shapes.box_extents[boxes])  # fmt: skip
            to_joint = invert_transform(chain.tip_offset @ arm.tcp)
            self._distal[side] = (sub, to_joint @ np.asarray(chain.link_offsets)[keep])
        return self._distal[side]

    def distal_contacts(self, side: str, poses_world: np.ndarray, *,
                        bodies: Sequence[Body] = ()) -> list[list[tuple[str, str]]]:
        """For grasp poses (n, 4, 4), world, m, which of the arm's :meth:`distal` links touch
        which primitive of ``bodies``: ``(link, target)`` pairs per pose, as
        :meth:`contacts` would find them at any configuration reaching the pose."""
        shapes, rel = self.distal(side)
        poses = np.asarray(poses_world, dtype=float).reshape(-1, 4, 4)
        targets = Targets()
        for body in bodies:
            targets = targets + Targets.from_body(body)
        hits = world_hits(shapes, poses[:, None] @ rel[None], targets)  # (n, L', K)
        return [[(shapes.links[j], targets.names[k]) for k, j in zip(*np.nonzero(row.T),
                                                                     strict=True)]
                for row in hits]  # fmt: skip

    def collisions(
        self,
        side: str,
        q: np.ndarray,
        *,
        boxes: Sequence[tuple[str, np.ndarray, np.ndarray]] = (),
        bodies: Sequence[Body] = (),
        other: tuple[str, np.ndarray] | None = None,
        own_body: bool = True,
        margin: float = 0.0,
    ) -> list[list[str]]:
        """For each configuration q (n, dof) of the arm on ``side``, the names of what its
        links touch (target order, each once): ``boxes`` ``(name, extents (3,), pose (4,
        4))`` in the world (a table, obstacles), the primitives of ``bodies`` (world; a
        receiver), the robot's own body (``own_body``; not :meth:`spared`) and, with
        ``other = (side, q_other (n, dof))``, the other arm's links at the same moments.
        margin : m, grows the arm's links. Which link touches what: :meth:`contacts`."""
        found = self.contacts(side, q, boxes=boxes, bodies=bodies, other=other,
                              own_body=own_body, margin=margin)
        return [list(dict.fromkeys(target for _, target in row)) for row in found]

    # ------------------------------------------------------------------ the result's field

    def rest_body(self, side: str) -> Body | None:
        """The arm on ``side`` at its rest configuration (world): its links' capsules and
        boxes named ``<link>``, or None for an arm without ``rest``. Memoised."""
        arm = self.arm(side)
        if arm.rest is None:
            return None
        if side not in self._rest:
            from handover.geometry.armcollision import posed_boxes, posed_capsules

            shapes = arm.shapes
            poses = self.link_poses(side, arm.rest[None])
            a, b = posed_capsules(shapes, poses)
            centres, rotations = posed_boxes(shapes, poses)
            boxes = []
            for i, link in enumerate(shapes.box_link):
                pose = np.eye(4)
                pose[:3, :3], pose[:3, 3] = rotations[0, i], centres[0, i]
                boxes.append((shapes.links[link], shapes.box_extents[i], pose))
            self._rest[side] = Body.from_primitives(
                capsules=[(shapes.links[link], a[0, i], b[0, i], float(shapes.cap_radius[i]))
                          for i, link in enumerate(shapes.cap_link)], boxes=boxes)
        return self._rest[side]

    def describe(self) -> dict:
        """The result's ``robot`` field: ``{id, urdf (relative to the KB folder), root_link
        (the URDF's), base_pose (4x4 world: the root link's pose), arms: {side: {base_link,
        tip_link, tcp (4x4, tip link -> grasp frame), gripper, joints: [names], rest: {joint:
        value} or null, finger_joints: [two names]}}, squeeze_force (N each arm presses in a
        squeeze, or null)}``, plain JSON types."""
        return {
            "id": self.spec.id,
            "urdf": self.urdf,
            "root_link": self.model.root_link,
            "base_pose": self.base_pose.tolist(),
            "arms": {
                side: {
                    "base_link": arm.chain.base_link,
                    "tip_link": arm.chain.tip_link,
                    "tcp": arm.tcp.tolist(),
                    "gripper": arm.gripper,
                    "joints": list(arm.chain.joint_names),
                    "rest": None if arm.rest is None else arm.chain.as_dict(arm.rest),
                    "finger_joints": list(arm.finger_joints),
                }
                for side, arm in ((s, self.arms[s]) for s in self.sides)
            },
            "squeeze_force": self.spec.squeeze_force,
        }


def robot_arms(
    kb: KB,
    robot: str | RobotSpec,
    *,
    db: GraspDB | None = None,
    map_params: dict | None = None,
) -> RobotArms | None:
    """The arms of ``robot`` with maps cached next to ``db`` (:func:`reach_dir`), or None for
    a robot without arms (a floating gripper per hand)."""
    spec = kb.robot(robot) if isinstance(robot, str) else robot
    if not spec.arms:
        return None
    return RobotArms.load(kb, spec, reach_dir=reach_dir(db), map_params=map_params)


def plan_arms(kb_root: Path | str | None, spec: RobotSpec,
              kept: LRU[tuple, RobotArms] | None = None) -> RobotArms | None:
    """The arms a plan uses: ``spec``'s (a robot document of the KB folder ``kb_root``), None
    without arms or without a folder. Maps are cached in ``reach/`` of the default grasp
    database folder (``$HANDOVER_DB`` or the user's cache), whatever database the plan reads
    its candidates from: a map depends on the URDF, the chain and the tcp only and takes
    seconds to build, so every database shares it. Loaded once per robot (its folder, its
    document and its URDF's content) and kept in ``kept`` (a :class:`handover.Planner`'s
    ``arms_cache``), or without one in this process's :data:`PLAN_ARMS`."""
    from handover.engine.assets.graspdb import open_db
    from handover.engine.store.kb import KB

    if not spec.arms or kb_root is None:
        return None
    import hashlib

    kb = KB(root=Path(kb_root), robots={spec.id: spec})  # paths and error positions only
    try:
        digest = hashlib.sha256(kb.relative_path(spec, spec.urdf).read_bytes()).hexdigest()
    except OSError:
        digest = ""  # RobotArms.load says what is wrong
    def load() -> RobotArms:
        from handover.engine.store.yamlpos import parse_yaml

        # The robot file's node positions, so that an error names the line at fault (the
        # tip_link, not the document's first line), as ``handover kb validate`` does.
        parsed = parse_yaml(kb.root / spec.source.file, spec.source.file)
        if isinstance(parsed, tuple):
            kb.marks[spec.source.file] = parsed[1]
        return RobotArms.load(kb, spec, reach_dir=reach_dir(open_db()))

    return (PLAN_ARMS if kept is None else kept).fetch(
        (str(kb_root), spec.model_dump_json(), digest), load)


ARMS_KEPT = 2
"""How many robots' arms a cache of arms keeps (:data:`PLAN_ARMS`, a Planner's
``arms_cache``): each holds its arms' reachability maps, about 17 MB per arm with the default
map (the whole map and its core, one byte per bit; ``benchmarks/planner_caches.py``), and at
most :data:`IK_KEPT` inverse-kinematics answers (about 26 MB when full); a plan uses one
robot."""
PLAN_ARMS: LRU[tuple, RobotArms] = LRU(ARMS_KEPT)
"""The arms of plans made without a Planner (the CLI's one plan, a batch worker's plans),
by (KB folder, robot document, URDF digest), least recently used dropped first."""
