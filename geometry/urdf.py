"""Robots from URDF files: kinematic chains and links' collision primitives, as plain arrays.
Longer than 500 lines: checking the XML with its line numbers before yourdfpy reads it (every
error at file:line) and turning the result into chains and shapes belong together.

:func:`load_urdf` reads a URDF with ``yourdfpy`` (after checking the XML itself, so that every
error names the file and line) into a :class:`RobotModel`. :meth:`RobotModel.chain` gives the
serial chain between two links as a :class:`Chain`: the moving joints in order, each with the
fixed transform from the previous joint's frame (fixed joints folded in), its axis, type and
limits; :mod:`geometry.kinematics` computes with it. :meth:`RobotModel.shapes` gives links'
collision geometry as :class:`LinkShapes` (capsules and boxes in link frames), which
:mod:`geometry.armcollision` tests.

Collision geometry is read conservatively, as shapes that contain the URDF's: a ``<cylinder>``
becomes the capsule around it (the same axis and radius, with hemispherical caps), a
``<sphere>`` a capsule of length zero, a ``<box>`` a box, and a ``<mesh>`` the box around its
vertices (its axis-aligned bounding box in the collision element's frame). A sphere lying wholly
inside another capsule of the same link is dropped (URDFs often draw a capsule as a cylinder
with two spheres).

Not supported, each reported with the file and line: xacro files (expand them with ``xacro``
first), mimic, floating and planar joints in a chain, a mesh file that cannot be found.

>>> robot = load_urdf("kb/robots/idro_arms.urdf")  # doctest: +SKIP
>>> chain = robot.chain("base_link", "left_flange")  # doctest: +SKIP
>>> chain.dof, chain.joint_names[0]
(7, 'left_joint1')  # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "DEFAULT_VELOCITY",
    "RobotModelError",
    "VelocityLimitWarning",
    "Chain",
    "LinkShapes",
    "RobotModel",
    "load_urdf",
]

_XACRO_NS = "http://www.ros.org/wiki/xacro"
_MOVING = ("revolute", "continuous", "prismatic")

DEFAULT_VELOCITY = 0.5
"""rad/s (m/s for a prismatic joint): the velocity limit of a moving joint whose URDF gives
none (no ``velocity`` attribute, a value that is not a positive number, or no ``<limit>`` on a
continuous joint). Slow for an arm joint (a Panda's are 2.2-2.6 rad/s), so a missing limit errs
on the safe side; :meth:`Chain.velocity_limits` warns when it is used."""


class VelocityLimitWarning(UserWarning):
    """A joint's URDF gives no usable velocity limit; :data:`DEFAULT_VELOCITY` is used."""


class RobotModelError(ValueError):
    """A URDF file or a chain request that cannot be used. ``path`` and ``line`` (1-based,
    or None) say where; the message starts with ``path:line:``."""

    def __init__(self, message: str, path: str | os.PathLike | None = None,
                 line: int | None = None) -> None:  # fmt: skip
        self.path = None if path is None else str(path)
        self.line = line
        self.reason = message
        where = "" if path is None else f"{path}:{line}: " if line else f"{path}: "
        super().__init__(f"{where}{message}")


@dataclass(frozen=True, eq=False)
class Chain:
    """A serial chain of ``dof`` moving joints from ``base_link`` to ``tip_link``.

    Frames: joint ``i``'s frame is its child link's frame. With ``M_i(q)`` the joint's
    motion (rotation by ``q`` rad about ``axes[i]``, or translation by ``q`` m along it), the
    tip's pose in the base link's frame is
    ``origins[0] @ M_0(q_0) @ origins[1] @ M_1(q_1) ... @ M_{dof-1} @ tip_offset``.

    origins : (dof, 4, 4) fixed transforms from the previous joint's frame (the base link's
        for joint 0) to joint i's frame at q = 0; fixed joints between are folded in.
    axes : (dof, 3) unit axes in joint i's frame. kinds : (dof,) ``revolute`` | ``continuous``
        | ``prismatic``. lower, upper : (dof,) limits, rad or m (continuous: -pi, pi).
    tip_offset : (4, 4) from the last joint's frame to the tip link (identity if the tip is
        the last joint's child).
    links : the links rigidly carried by the chain, in order: ``link_joint[k]`` is the index of
        the joint whose frame carries ``links[k]`` (-1: the base link and the links between it
        and the first moving joint, not moved) and
        ``link_offsets[k]`` (4, 4) the link's frame in that joint's frame. Links hanging off
        the chain through fixed joints (a camera, a gripper) are included.
    velocity : (dof,) the URDF's velocity limits, rad/s (m/s), :data:`DEFAULT_VELOCITY` where
        it gives none (None: none known). velocity_missing : ``"joint (file:line)"`` for each
        joint given the default. Read them through :meth:`velocity_limits`.
    """

    base_link: str
    tip_link: str
    joint_names: tuple[str, ...]
    kinds: tuple[str, ...]
    origins: np.ndarray
    axes: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    tip_offset: np.ndarray
    links: tuple[str, ...]
    link_joint: np.ndarray
    link_offsets: np.ndarray
    source: str = ""
    velocity: np.ndarray | None = None
    velocity_missing: tuple[str, ...] = ()

    @property
    def dof(self) -> int:
        """Number of moving joints."""
        return len(self.joint_names)

    @property
    def continuous(self) -> np.ndarray:
        """(dof,) bool: joints without limits (wrapped to [-pi, pi] instead of clamped)."""
        return np.array([k == "continuous" for k in self.kinds], dtype=bool)

    @property
    def mid(self) -> np.ndarray:
        """(dof,) the middle of each joint's range (a neutral start)."""
        return 0.5 * (self.lower + self.upper)

    def within_limits(self, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """(n,) bool: whether configurations q (n, dof) lie within the joint limits."""
        q = np.asarray(q, dtype=float)
        ok = (q >= self.lower - tol) & (q <= self.upper + tol)
        return np.all(ok | self.continuous, axis=-1)

    def velocity_limits(self) -> np.ndarray:
        """(dof,) velocity limits, rad/s (m/s for prismatic joints): the URDF's, and
        :data:`DEFAULT_VELOCITY` for the joints it gives none, with a
        :class:`VelocityLimitWarning` naming them."""
        if self.velocity is None:
            missing = self.joint_names
            limits = np.full(self.dof, DEFAULT_VELOCITY)
        else:
            missing = self.velocity_missing
            limits = np.asarray(self.velocity, dtype=float).copy()
        if missing:
            warnings.warn(
                f"no velocity limit for {', '.join(missing)}: using {DEFAULT_VELOCITY} "
                "rad/s (m/s) (handover.geometry.urdf.DEFAULT_VELOCITY)",
                VelocityLimitWarning, stacklevel=2)
        return limits

    def as_dict(self, q: np.ndarray) -> dict[str, float]:
        """One configuration q (dof,) as ``{joint name: value}``."""
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape != (self.dof,):
            raise RobotModelError(f"expected {self.dof} joint values, got {q.shape[0]}")
        return dict(zip(self.joint_names, map(float, q), strict=True))


@dataclass(frozen=True, eq=False)
class LinkShapes:
    """Collision shapes of a list of links, struct-of-arrays, each in its link's frame (m).

    links : the link names; the ``*_link`` arrays index into it.
    Capsules (c of them): ``cap_link`` (c,) int, ``cap_a``, ``cap_b`` (c, 3) segment end
    points, ``cap_radius`` (c,). A sphere has ``cap_a == cap_b``.
    Boxes (b of them): ``box_link`` (b,) int, ``box_pose`` (b, 4, 4) box centre and axes,
    ``box_extents`` (b, 3) full edge lengths.
    """

    links: tuple[str, ...]
    cap_link: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    cap_a: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    cap_b: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    cap_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))
    box_link: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    box_pose: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    box_extents: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __len__(self) -> int:
        return len(self.cap_link) + len(self.box_link)


@dataclass(eq=False)
class RobotModel:
    """A URDF, parsed: links, joints, and where each came from.

    path : the file. content_hash : sha256 hex digest of its bytes (keys caches).
    urdf : the ``yourdfpy.URDF`` (no scene graph built). lines : element name -> line number
    (keys ``link:NAME``, ``joint:NAME``).
    """

    path: Path
    content_hash: str
    urdf: object
    lines: dict[str, int]
    mesh_files: dict[str, Path] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return str(self.urdf.robot.name)

    @property
    def link_names(self) -> tuple[str, ...]:
        return tuple(link.name for link in self.urdf.robot.links)

    @property
    def root_link(self) -> str:
        """The link no joint has as its child (the first, if several)."""
        children = {j.child for j in self.urdf.robot.joints}
        return next(name for name in self.link_names if name not in children)

    def _error(self, message: str, key: str | None = None) -> RobotModelError:
        return RobotModelError(message, self.path, self.lines.get(key) if key else None)

    def _check_link(self, name: str, role: str) -> None:
        if name not in self.urdf.link_map:
            known = ", ".join(self.link_names)
            raise self._error(f"{role} link {name!r} is not in the URDF (links: {known})")

    def _parent_joint(self) -> dict:
        return {j.child: j for j in self.urdf.robot.joints}

    def chain(self, base_link: str, tip_link: str) -> Chain:
        """The serial chain from ``base_link`` to ``tip_link`` (an ancestor of it).

        Raises :class:`RobotModelError` if a link is unknown, the base is not an ancestor of
        the tip, or a joint on the way is mimic, floating or planar.
        """
        self._check_link(base_link, "base")
        self._check_link(tip_link, "tip")
        parent_joint = self._parent_joint()
        path = []  # joints from tip up to base
        link = tip_link
        while link != base_link:
            joint = parent_joint.get(link)
            if joint is None:
                raise self._error(
                    f"link {base_link!r} is not an ancestor of {tip_link!r}: no chain between them",
                    f"link:{tip_link}",
                )
            path.append(joint)
            link = joint.parent
        path.reverse()

        names, kinds, origins, axes, lower, upper = [], [], [], [], [], []
        velocity, missing = [], []
        pending = np.eye(4)  # fixed transform accumulated since the last moving joint
        chain_links: list[tuple[str, int, np.ndarray]] = [(base_link, -1, np.eye(4))]
        for joint in path:
            key = f"joint:{joint.name}"
            if joint.mimic is not None:
                raise self._error(f"joint {joint.name!r}: mimic joints are not supported", key)
            if joint.type in ("floating", "planar"):
                raise self._error(
                    f"joint {joint.name!r}: {joint.type} joints are not supported in a chain", key
                )
            origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, float)
            if joint.type == "fixed":
                pending = pending @ origin
                chain_links.append((joint.child, len(names) - 1, pending.copy()))
                continue
            if joint.type not in _MOVING:
                raise self._error(f"joint {joint.name!r}: unknown type {joint.type!r}", key)
            axis = np.array([1.0, 0, 0]) if joint.axis is None else np.asarray(joint.axis, float)
            norm = float(np.linalg.norm(axis))
            if not np.isfinite(norm) or norm < 1e-9:
                raise self._error(f"joint {joint.name!r}: axis must be a non-zero vector", key)
            if joint.type == "continuous":
                lo, hi = -np.pi, np.pi
            else:
                limit = joint.limit
                if limit is None or limit.lower is None or limit.upper is None:
                    raise self._error(
                        f"joint {joint.name!r}: a {joint.type} joint needs <limit lower upper>",
                        key,
                    )
                lo, hi = float(limit.lower), float(limit.upper)
                if not (np.isfinite(lo) and np.isfinite(hi)) or lo > hi:
                    raise self._error(
                        f"joint {joint.name!r}: limits must be finite with lower <= upper, "
                        f"got {lo}, {hi}",
                        key,
                    )
            speed = None if joint.limit is None else joint.limit.velocity
            if speed is None or not (np.isfinite(speed) and speed > 0):
                line = self.lines.get(key)
                missing.append(f"{joint.name} ({self.path}:{line})" if line
                               else f"{joint.name} ({self.path})")  # fmt: skip
                speed = DEFAULT_VELOCITY
            velocity.append(float(speed))
            names.append(joint.name)
            kinds.append(joint.type)
            origins.append(pending @ origin)
            axes.append(axis / norm)
            lower.append(lo)
            upper.append(hi)
            pending = np.eye(4)
            chain_links.append((joint.child, len(names) - 1, np.eye(4)))
        tip_offset = pending

        # Links hanging off the chain's moving links through fixed joints only (those on the
        # base's side of the first moving joint belong to the base's body, not to the chain).
        on_chain = {name for name, _, _ in chain_links}
        children: dict[str, list] = {}
        for joint in self.urdf.robot.joints:
            children.setdefault(joint.parent, []).append(joint)
        stack = [(name, j, off) for name, j, off in chain_links if j >= 0]
        while stack:
            name, j, off = stack.pop()
            for joint in children.get(name, []):
                if joint.type != "fixed" or joint.child in on_chain:
                    continue
                origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, float)
                entry = (joint.child, j, off @ origin)
                on_chain.add(joint.child)
                chain_links.append(entry)
                stack.append(entry)

        dof = len(names)
        return Chain(
            base_link=base_link,
            tip_link=tip_link,
            joint_names=tuple(names),
            kinds=tuple(kinds),
            origins=np.array(origins, dtype=float).reshape(dof, 4, 4),
            axes=np.array(axes, dtype=float).reshape(dof, 3),
            lower=np.array(lower, dtype=float),
            upper=np.array(upper, dtype=float),
            tip_offset=tip_offset,
            links=tuple(name for name, _, _ in chain_links),
            link_joint=np.array([j for _, j, _ in chain_links], dtype=np.intp),
            link_offsets=np.array([off for _, _, off in chain_links], dtype=float),
            source=str(self.path),
            velocity=np.array(velocity, dtype=float),
            velocity_missing=tuple(missing),
        )

    def fixed_pose(self, link: str, relative_to: str | None = None) -> np.ndarray:
        """(4, 4) pose of ``link`` in ``relative_to``'s frame (default: the root link), for a
        link joined to it through fixed joints only (a torso, a head, an arm's mount)."""
        chain = self.chain(relative_to or self.root_link, link)
        if chain.dof:
            raise self._error(
                f"link {link!r} moves relative to {chain.base_link!r} "
                f"(joint {chain.joint_names[0]!r}): it has no fixed pose",
                f"link:{link}",
            )
        return chain.tip_offset

    def shapes(self, links: tuple[str, ...] | list[str]) -> LinkShapes:
        """The collision shapes of ``links`` (each in its own frame), as :class:`LinkShapes`."""
        cap_link, cap_a, cap_b, cap_r = [], [], [], []
        box_link, box_pose, box_ext = [], [], []
        for index, name in enumerate(links):
            self._check_link(name, "collision")
            caps: list[tuple[np.ndarray, np.ndarray, float]] = []
            for col in self.urdf.link_map[name].collisions:
                origin = np.eye(4) if col.origin is None else np.asarray(col.origin, float)
                g = col.geometry
                if g is None:
                    continue
                if g.cylinder is not None:
                    half = 0.5 * float(g.cylinder.length) * origin[:3, 2]
                    caps.append((origin[:3, 3] - half, origin[:3, 3] + half,
                                 float(g.cylinder.radius)))  # fmt: skip
                elif g.sphere is not None:
                    caps.append((origin[:3, 3], origin[:3, 3], float(g.sphere.radius)))
                elif g.box is not None:
                    box_link.append(index)
                    box_pose.append(origin)
                    box_ext.append(np.asarray(g.box.size, float))
                elif g.mesh is not None:
                    pose, ext = self._mesh_box(g.mesh, name)
                    box_link.append(index)
                    box_pose.append(origin @ pose)
                    box_ext.append(ext)
            keep = [not _sphere_inside(c, caps) for c in caps]
            for (a, b, r), k in zip(caps, keep, strict=True):
                if k:
                    cap_link.append(index)
                    cap_a.append(a)
                    cap_b.append(b)
                    cap_r.append(r)
        return LinkShapes(
            links=tuple(links),
            cap_link=np.array(cap_link, dtype=np.intp),
            cap_a=np.array(cap_a, dtype=float).reshape(-1, 3),
            cap_b=np.array(cap_b, dtype=float).reshape(-1, 3),
            cap_radius=np.array(cap_r, dtype=float),
            box_link=np.array(box_link, dtype=np.intp),
            box_pose=np.array(box_pose, dtype=float).reshape(-1, 4, 4),
            box_extents=np.array(box_ext, dtype=float).reshape(-1, 3),
        )

    def chain_shapes(self, chain: Chain, *, moving_only: bool = True) -> LinkShapes:
        """The collision shapes of ``chain.links`` (indexed like ``Kinematics.link_poses``);
        with ``moving_only`` the links that do not move with a joint (the base, a torso, an
        arm's mount) keep no shapes, so that an arm is not found touching its own body."""
        shapes = self.shapes(chain.links)
        if not moving_only:
            return shapes
        moving = chain.link_joint >= 0
        keep_c, keep_b = moving[shapes.cap_link], moving[shapes.box_link]
        return LinkShapes(
            shapes.links,
            shapes.cap_link[keep_c], shapes.cap_a[keep_c], shapes.cap_b[keep_c],
            shapes.cap_radius[keep_c],
            shapes.box_link[keep_b], shapes.box_pose[keep_b], shapes.box_extents[keep_b],
        )  # fmt: skip

    def _mesh_box(self, mesh, link: str) -> tuple[np.ndarray, np.ndarray]:
        """(pose (4, 4), extents (3,)) of the axis-aligned box around a collision mesh."""
        import trimesh

        path = self.mesh_files[mesh.filename]
        try:
            loaded = trimesh.load(path, force="mesh")
            vertices = np.asarray(loaded.vertices, dtype=float)
        except Exception as exc:  # trimesh raises many kinds
            raise self._error(f"link {link!r}: cannot read mesh {str(path)!r}: {exc}",
                              f"link:{link}") from None  # fmt: skip
        if len(vertices) == 0:
            raise self._error(f"link {link!r}: mesh {str(path)!r} is empty", f"link:{link}")
        if mesh.scale is not None:
            vertices = vertices * np.asarray(mesh.scale, dtype=float)
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        pose = np.eye(4)
        pose[:3, 3] = 0.5 * (lo + hi)
        return pose, np.maximum(hi - lo, 1e-6)


def _floats(text: str | None, count: int) -> list[float] | None:
    """``count`` numbers from an attribute's text, None when they are not that many finite
    numbers."""
    try:
        values = [float(v) for v in (text or "").split()]
    except ValueError:
        return None
    return values if len(values) == count and all(np.isfinite(values)) else None

def _check_numbers(root, path: Path) -> None:
    """Every ``<origin>`` (xyz, rpy) finite, every mesh's scale finite and non-zero, every
    collision shape's size finite and positive (a cylinder's length may be 0), at the
    element's line, before any is used."""
    for element in root.iter("origin"):
        for attr in ("xyz", "rpy"):
            if element.get(attr) is not None and _floats(element.get(attr), 3) is None:
                raise RobotModelError(f"<origin {attr}={element.get(attr)!r}>: expected three "
                                      "finite numbers", path, element.sourceline)
    for element in root.iter("mesh"):
        scale = element.get("scale")
        if scale is not None and ((v := _floats(scale, 3)) is None or min(map(abs, v)) == 0):
            raise RobotModelError(f"<mesh scale={scale!r}>: expected three finite, non-zero "
                                  "numbers", path, element.sourceline)
    sizes = {"box": (("size", 3),), "sphere": (("radius", 1),),
             "cylinder": (("radius", 1), ("length", 1))}
    for collision in root.iter("collision"):
        for tag, attrs in sizes.items():
            for element in collision.iter(tag):
                for attr, count in attrs:
                    values = _floats(element.get(attr), count)
                    least_ok = 0.0 if attr == "length" else 1e-12
                    if values is None or min(values) < least_ok:
                        raise RobotModelError(
                            f"<{tag} {attr}={element.get(attr)!r}>: expected "
                            f"{'a' if count == 1 else count} finite "
                            f"{'length' if count == 1 else 'lengths'} "
                            f"{'>= 0' if attr == 'length' else '> 0'} (m)",
                            path, element.sourceline)  # fmt: skip


def _sphere_inside(cap, caps) -> bool:
    """Whether ``cap`` is a sphere lying wholly inside another capsule of ``caps``."""
    a, b, r = cap
    if np.any(a != b):
        return False
    for other in caps:
        if other is cap:
            continue
        oa, ob, orad = other
        d = ob - oa
        t = 0.0 if not d.any() else float(np.clip(np.dot(a - oa, d) / np.dot(d, d), 0, 1))
        if np.linalg.norm(a - (oa + t * d)) + r <= orad + 1e-12:
            return True
    return False


def _resolve_mesh(filename: str, directory: Path) -> Path | None:
    """The file a URDF mesh reference names, or None. ``package://PKG/rest`` is looked up
    as ``rest`` and ``PKG/rest`` under the URDF's folder and its parents; ``file://`` and
    plain paths relative to the URDF's folder."""
    if filename.startswith("file://"):
        candidate = Path(filename[len("file://"):])
        return candidate if candidate.is_file() else None
    if filename.startswith("package://"):
        rest = filename[len("package://"):]
        tails = [rest, rest.split("/", 1)[1] if "/" in rest else rest]
        for folder in (directory, *directory.parents):
            for tail in tails:
                if (folder / tail).is_file():
                    return folder / tail
        return None
    candidate = Path(filename)
    if not candidate.is_absolute():
        candidate = directory / candidate
    return candidate if candidate.is_file() else None


def load_urdf(path: str | os.PathLike) -> RobotModel:
    """Read a URDF file into a :class:`RobotModel`.

    Raises :class:`RobotModelError` (with the line where known) for a missing or unreadable
    file, malformed XML, a xacro file, a root element other than ``<robot>``, joints naming
    links that do not exist, a link with two parents, and mesh files that cannot be found.
    """
    from lxml import etree

    path = Path(path)
    if not path.is_file():
        raise RobotModelError("URDF file not found", path)
    data = path.read_bytes()
    if path.suffix == ".xacro" or b"xmlns:xacro" in data:
        raise RobotModelError("xacro is not supported; expand it with xacro first", path, 1)
    try:
        root = etree.fromstring(data, parser=etree.XMLParser(remove_blank_text=True))
    except etree.XMLSyntaxError as exc:
        line = exc.lineno if exc.lineno else None
        raise RobotModelError(f"malformed XML: {exc.msg}", path, line) from None
    for element in root.iter():
        if isinstance(element.tag, str) and element.tag.startswith("{" + _XACRO_NS):
            raise RobotModelError(
                "xacro is not supported; expand it with xacro first", path, element.sourceline
            )
    if root.tag != "robot":
        raise RobotModelError(f"the root element must be <robot>, got <{root.tag}>", path,
                              root.sourceline)  # fmt: skip

    lines: dict[str, int] = {}
    link_names = []
    for element in root.findall("link"):
        name = element.get("name")
        if name is None:
            raise RobotModelError("<link> without a name", path, element.sourceline)
        if f"link:{name}" in lines:
            raise RobotModelError(f"link {name!r} is defined twice", path, element.sourceline)
        lines[f"link:{name}"] = element.sourceline
        link_names.append(name)
    if not link_names:
        raise RobotModelError("the URDF has no <link>", path, root.sourceline)
    parents: dict[str, str] = {}
    parent_link: dict[str, str] = {}
    for element in root.findall("joint"):
        name = element.get("name")
        line = element.sourceline
        if name is None:
            raise RobotModelError("<joint> without a name", path, line)
        lines[f"joint:{name}"] = line
        for role in ("parent", "child"):
            tag = element.find(role)
            link = None if tag is None else tag.get("link")
            if link is None:
                raise RobotModelError(f"joint {name!r} has no <{role} link=...>", path, line)
            if f"link:{link}" not in lines:
                raise RobotModelError(
                    f"joint {name!r}: {role} link {link!r} is not defined", path, line
                )
        child = element.find("child").get("link")
        if child in parents:
            raise RobotModelError(
                f"link {child!r} has two parent joints ({parents[child]!r} and {name!r})",
                path,
                line,
            )
        parents[child] = name
        parent_link[child] = element.find("parent").get("link")
    for start in link_names:  # the joints must form a tree: no link is its own ancestor
        seen, link = {start}, start
        while link in parent_link:
            link = parent_link[link]
            if link in seen:
                raise RobotModelError(
                    f"the joints form a cycle through link {link!r}", path, lines[f"link:{link}"]
                )
            seen.add(link)

    _check_numbers(root, path)

    # Every referenced mesh must exist (yourdfpy would load a missing one as nothing).
    mesh_files: dict[str, Path] = {}
    for element in root.iter("mesh"):
        filename = element.get("filename")
        if not filename:
            raise RobotModelError("<mesh> without a filename", path, element.sourceline)
        resolved = _resolve_mesh(filename, path.parent)
        if resolved is None:
            raise RobotModelError(f"mesh file {filename!r} not found", path, element.sourceline)
        mesh_files[filename] = resolved

    def filename_handler(fname: str) -> str:
        if fname in mesh_files:
            return str(mesh_files[fname])
        raise RobotModelError(f"mesh file {fname!r} not found", path)

    import yourdfpy

    try:
        robot = yourdfpy.URDF._parse_robot(xml_element=root)
        urdf = yourdfpy.URDF(
            robot=robot,
            build_scene_graph=False,
            build_collision_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
            filename_handler=filename_handler,
        )
    except RobotModelError:
        raise
    except Exception as exc:  # yourdfpy raises many kinds on bad attribute values
        raise RobotModelError(f"cannot read the URDF: {exc}", path) from None
    return RobotModel(
        path=path,
        content_hash=hashlib.sha256(data).hexdigest(),
        urdf=urdf,
        lines=lines,
        mesh_files=mesh_files,
    )
