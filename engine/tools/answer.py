"""What the ``handover`` command prints and the plan service answers, built once for both.

A request is a :class:`PlanRequest` (the query of ``handover plan`` by its option names:
``object``, ``task``, ``receiver``, ``culture``, ``scene``, ``mode``, ``gripper``, ``robot``,
``mesh-scale``, ``why-not``, ``what-if``, ``format``); :func:`plan_request` plans it and
:func:`render` gives its answer's bytes in a format: ``json`` (the result, what ``handover
plan --json`` prints), ``moveit`` (its ROS 2 messages as JSON,
:func:`handover.engine.report.moveit.moveit_messages`) or ``mcap`` (those messages as a ROS 2
bag). ``handover kb validate --json`` and ``handover kb test --json`` print
:func:`validate_text` and :func:`kb_tests_text`. The CLI and the service both call these, so
their answers are the same bytes.

>>> req = PlanRequest.from_mapping({"object": "mug", "receiver": "elder", "what-if": True})
>>> req.query().receiver, req.what_if
('elder', True)
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from handover.engine.errors import UsageError
from handover.engine.report.formats import FORMATS
from handover.engine.spec.query import DEFAULTS, MODES, Query

if TYPE_CHECKING:
    from handover.engine.errors import KBError, KBIssue
    from handover.engine.planner import Plan
    from handover.engine.store.kb import KB

__all__ = ["PlanRequest", "FORMATS", "MEDIA_TYPES", "plan_request", "render", "issue_json",
           "validate_data", "validate_text", "kb_tests", "kb_tests_text", "json_text",
           "PHYSICS_FAILED"]

MEDIA_TYPES = {"json": "application/json", "moveit": "application/json",
               "mcap": "application/x-mcap"}
_STRINGS = ("object", "task", "receiver", "culture", "scene", "mode", "gripper", "robot",
            "format")


@dataclass(frozen=True)
class PlanRequest:
    """One ``handover plan`` query and how its answer is given.

    object : an object id of the KB (or, from the CLI only, a mesh file). task, receiver,
    culture, scene, gripper, robot : ids, None for the defaults. mode : ``auto`` or a
    mode. mesh_scale : a mesh file's units to metres. why_not : candidate ids to explain.
    what_if : list the verified changes of an infeasible plan. physics : check the chosen
    grasps in MuJoCo (the result's ``physics``). motion : plan the arms' motion between the
    stages (each robot grasp's ``trajectory``, the result's ``motion``; ``--no-motion``
    skips it). format : one of :data:`FORMATS`.
    """

    object: str
    task: str | None = None
    receiver: str | None = None
    culture: str | None = None
    scene: str | None = None
    mode: str = "auto"
    gripper: str | None = None
    robot: str | None = None
    mesh_scale: float = 1.0
    why_not: tuple[int, ...] = ()
    what_if: bool = False
    physics: bool = False
    motion: bool = True
    format: str = "json"

    def __post_init__(self) -> None:
        if not isinstance(self.mesh_scale, int | float) or isinstance(self.mesh_scale, bool) \
                or not (math.isfinite(self.mesh_scale) and self.mesh_scale > 0):
            raise UsageError(f"--mesh-scale must be a positive number, got {self.mesh_scale}")
        if (self.mode or "auto").lower() not in MODES:
            raise UsageError(f"unknown mode '{self.mode}': choose one of {', '.join(MODES)}")
        if self.format not in FORMATS:
            raise UsageError(f"unknown format '{self.format}': choose {', '.join(FORMATS)}")

    @classmethod
    def from_mapping(cls, data: Any) -> PlanRequest:
        """A request from a JSON object whose keys are ``handover plan``'s option names
        (``mesh-scale`` or ``mesh_scale``, and so on; ``no-motion`` as the CLI's flag or
        ``motion``; ``object`` required; null: the option's default). Raises UsageError
        naming the key that is unknown, given twice, missing or of the wrong type."""
        if not isinstance(data, Mapping):
            raise UsageError(f"the request must be a JSON object, got {type(data).__name__}")
        known = {f.replace("_", "-") for f in cls.__dataclass_fields__} | {"no-motion"}
        values: dict[str, Any] = {}
        given: dict[str, str] = {}
        for key, value in data.items():
            name = str(key).replace("_", "-")
            if name not in known:
                raise UsageError(f"unknown key '{key}' (known: {', '.join(sorted(known))})")
            if name == "no-motion":  # the CLI's --no-motion
                if value is not None and not isinstance(value, bool):
                    raise UsageError(f"'{key}' must be true or false, got {value!r}")
                name, value = "motion", None if value is None else not value
            field = name.replace("-", "_")
            if field in given:
                raise UsageError(f"'{given[field]}' and '{key}' say the same thing: give one")
            given[field] = str(key)
            if value is not None or field == "object":  # null: the default
                values[field] = value
        if values.get("object") is None:
            raise UsageError("the request has no 'object': the object id to plan for")
        for name in _STRINGS:
            value = values.get(name)
            if value is not None and (not isinstance(value, str) or not value):
                raise UsageError(f"'{name}' must be a non-empty string, got {value!r}")
        why_not = values.get("why_not", ())
        if isinstance(why_not, int) and not isinstance(why_not, bool):
            why_not = [why_not]
        if not isinstance(why_not, list | tuple) or not all(
                isinstance(v, int) and not isinstance(v, bool) for v in why_not):
            raise UsageError(f"'why-not' must be a candidate id or a list of them, got "
                             f"{why_not!r}")
        values["why_not"] = tuple(why_not)
        for flag in ("what_if", "physics", "motion"):
            if not isinstance(values.get(flag, False), bool):
                raise UsageError(f"'{flag.replace('_', '-')}' must be true or false, got "
                                 f"{values[flag]!r}")
        scale = values.get("mesh_scale", 1.0)
        if isinstance(scale, bool) or not isinstance(scale, int | float):
            raise UsageError(f"'mesh-scale' must be a number, got {scale!r}")
        values["mesh_scale"] = float(scale)
        return cls(**values)

    def query(self) -> Query:
        """The planner's query (defaults filled in, the mode in lower case)."""
        return Query(
            object=self.object, task=self.task,
            receiver=self.receiver or DEFAULTS["receiver"],
            culture=self.culture or DEFAULTS["culture"],
            scene=self.scene or DEFAULTS["scene"],
            mode=(self.mode or "auto").lower(), gripper=self.gripper,
            robot=self.robot or DEFAULTS["robot"], mesh_scale=self.mesh_scale,
        )

    def key(self) -> tuple:
        """What decides the answer's bytes (for a memo of answers): the query as resolved,
        why-not, what-if and the format."""
        q = self.query()
        return (q.object, q.task, q.receiver, q.culture, q.scene, q.mode, q.gripper, q.robot,
                q.mesh_scale, self.why_not, self.what_if, self.physics, self.motion,
                self.format)


_GOAL_OPTIONS = ("task", "receiver", "culture", "scene", "mode", "robot", "gripper")
_GOAL_GEOMETRY = ("point_cluster", "primitives", "primitive_poses", "meshes", "mesh_poses",
                  "surface")


def grasp_planning_request(goal: Any, kb: KB | None = None) -> tuple[PlanRequest, str]:
    """The plan request and the group of a ``grasping_msgs/action/GraspPlanning`` goal, as
    JSON in the shape ``ros2 action send_goal`` takes it: ``{"object": {"name": OBJECT,
    "properties": [{"name": "receiver", "value": "elder"}, ...]}, "group_name": ""}``.
    ``object.name`` is the KB's object id; the properties are ``handover plan``'s options
    (:data:`_GOAL_OPTIONS`); ``header`` and ``support_surface`` are taken and not used (the
    scene says where the object is). The object is known by name: a goal that describes
    its geometry (points, primitives, meshes, a plane) is refused rather than planned for
    another shape; with the ``kb``, a ``group_name`` that is no arm of the query's robot
    (``left``, ``right`` or ``<arm>_arm``) is refused before anything is planned. Raises
    UsageError saying what is wrong (an unknown robot: the KB's own error)."""
    if not isinstance(goal, Mapping):
        raise UsageError(f"the goal must be a JSON object, got {type(goal).__name__}")
    unknown = sorted(set(goal) - {"object", "group_name"})
    if unknown:
        raise UsageError(f"unknown goal field(s) {', '.join(unknown)} (GraspPlanning's goal "
                         "has object and group_name)")
    obj, group = goal.get("object"), goal.get("group_name", "")
    if not isinstance(group, str):
        raise UsageError(f"'group_name' must be a string, got {group!r}")
    if not isinstance(obj, Mapping) or not isinstance(obj.get("name"), str) or not obj["name"]:
        raise UsageError("the goal's object needs a 'name': the object id of the knowledge "
                         "base")
    fields = {"header", "name", "support_surface", "properties", *_GOAL_GEOMETRY}
    unknown = sorted(set(obj) - fields)
    if unknown:
        raise UsageError(f"unknown object field(s) {', '.join(unknown)} (grasping_msgs/Object "
                         f"has {', '.join(sorted(fields))})")
    described = [k for k in _GOAL_GEOMETRY if _given(obj.get(k))]
    if described:
        raise UsageError(f"the goal describes the object's geometry ({', '.join(described)}): "
                         f"the service plans the knowledge base's objects by name; send "
                         f"'{obj['name']}' without it, or add the object to the KB")
    options: dict[str, str] = {}
    properties = obj.get("properties") or []
    if not isinstance(properties, list):
        raise UsageError("the object's 'properties' must be a list of {name, value}")
    for prop in properties:
        if not isinstance(prop, Mapping) or set(prop) - {"name", "value"} \
                or not isinstance(prop.get("name"), str) or not isinstance(prop.get("value"), str):
            raise UsageError(f"each property is {{name, value}}, two strings; got {prop!r}")
        if prop["name"] not in _GOAL_OPTIONS:
            raise UsageError(f"unknown property '{prop['name']}' (known: "
                             f"{', '.join(_GOAL_OPTIONS)})")
        if prop["name"] in options:
            raise UsageError(f"property '{prop['name']}' is given twice")
        options[prop["name"]] = prop["value"]
    request = PlanRequest.from_mapping({"object": obj["name"], **options})
    if kb is not None and group:
        robot = kb.robot(request.query().robot)
        arms = sorted(robot.arms or robot.hands)
        if group.removesuffix("_arm") not in arms:
            raise UsageError(f"group_name {group!r} is not an arm of robot '{robot.id}' "
                             f"(arms: {', '.join(arms)})")
    return request, group


def _given(value: Any) -> bool:
    """Whether a goal field holds anything but defaults: an all-zero plane, an empty point
    cloud or an empty list hold nothing (as ``ros2 action send_goal`` fills them in)."""
    if isinstance(value, Mapping):
        return any(_given(v) for v in value.values())
    if isinstance(value, list | tuple):
        return any(_given(v) for v in value)
    return bool(value)


def plan_request(kb: KB, request: PlanRequest, db=None) -> Plan:
    """Plan ``request`` with ``kb`` and the grasp database ``db`` (None: generate); with
    ``physics``, a handover's chosen grasps checked
    (:func:`handover.engine.tools.holding.physics_plan`), or the grasp that
    carries an object set down (to where it is set down)."""
    from handover.engine.planner import plan

    planned = plan(kb, request.query(), why_not=request.why_not, db=db,
                   what_if=request.what_if, motion=request.motion)
    if request.physics and request.object not in kb.objects:
        raise UsageError(f"--physics checks objects of the knowledge base; '{request.object}' "
                         "is not one")
    if request.physics and planned.outcome == "handover":
        from handover.engine.tools.holding import physics_plan

        planned, checked = physics_plan(kb, request.query(), planned, db,
                                        why_not=request.why_not, what_if=request.what_if,
                                        motion=request.motion)
    elif request.physics and planned.outcome == "place":  # the carry to where it is set down
        from handover.engine.plan.physics import check_plan
        from handover.engine.tools.holding import convex_cache

        checked = check_plan(kb, planned.result.to_dict(), convex_cache(db))
    else:
        return planned
    planned.result.physics = checked.to_dict()
    if not checked.passed:
        planned.result.warnings.append(PHYSICS_FAILED)
    return planned


PHYSICS_FAILED = ("physics: the plan's grasps do not hold in the simulated check (nor did the "
                  "next best): do not run it as it is; its physics block says where they slip")
"""The warning of a plan whose physics check fails (``handover plan --physics`` then exits
4, as ``handover verify`` does)."""


def render(planned: Plan, fmt: str = "json") -> bytes:
    """The answer's bytes in ``fmt`` (:func:`~handover.engine.report.formats.result_bytes`):
    ``json``, ``moveit`` or ``mcap``."""
    from handover.engine.report.formats import result_bytes

    if fmt not in FORMATS:
        raise UsageError(f"unknown format '{fmt}': choose {', '.join(FORMATS)}")
    return result_bytes(planned.result, fmt)


def json_text(data: Any) -> str:
    """Deterministic JSON text of plain data: indent 2, key order as built, a newline."""
    from handover.engine.plan.jsonable import dumps

    return dumps(data)


# ---------------------------------------------------------------- kb validate, kb test


def issue_json(issue: KBIssue) -> dict[str, Any]:
    """One KB problem as JSON: file, line, col, severity, message."""
    return {"file": issue.file, "line": issue.line, "col": issue.col,
            "severity": issue.severity, "message": issue.message}


def validate_data(kb_dir: Path | str | None) -> tuple[dict[str, Any], KBError | None]:
    """What ``handover kb validate --json`` prints for the KB folder ``kb_dir`` (every file,
    URDFs parsed): ``{"ok": true, "root", "counts", "warnings"}``, or ``{"ok": false,
    "errors", "warnings"}`` with the KBError. A folder that does not exist raises
    UsageError."""
    from handover.engine.errors import KBError
    from handover.engine.load.loader import load_kb

    try:
        kb = load_kb(kb_dir)
    except KBError as e:
        return {"ok": False, "errors": [issue_json(i) for i in e.issues],
                "warnings": [issue_json(i) for i in e.warnings]}, e
    return {"ok": True, "root": str(kb.root), "counts": kb.counts(),
            "warnings": [issue_json(i) for i in kb.warnings]}, None


def validate_text(data: dict[str, Any]) -> str:
    """:func:`validate_data`'s dict as ``kb validate --json`` prints it."""
    return json.dumps(data, indent=2, sort_keys=False, ensure_ascii=False) + "\n"


def kb_tests(kb: KB, select: str | None = None, coverage: bool = False,
             paths: list[Path] | None = None) -> tuple[Any, dict[str, Any] | None]:
    """Run the KB's test cases (or those of ``paths``) whose name contains ``select``:
    the report (:class:`handover.engine.tools.kbtest.KBTestReport`) and, with ``coverage``,
    the rule coverage. UsageError when no case is selected."""
    from handover.engine.tools.kbtest import case_files, run_tests

    report = run_tests(kb, case_files(kb, list(paths or [])), select=select)
    if not report.cases:
        where = "the given paths" if paths else f"{kb.root / 'tests'}"
        raise UsageError(f"no test cases in {where}" + (f" matching '{select}'" if select
                                                         else ""))
    cov = None
    if coverage:
        from handover.engine.tools.coverage import rule_coverage

        cov = rule_coverage(kb, report.cases)
    return report, cov


def kb_tests_text(report: Any, cov: dict[str, Any] | None = None) -> str:
    """What ``handover kb test --json`` prints of :func:`kb_tests`: ``cases``, ``passed``,
    ``failed``, and with coverage ``coverage``, ``never_applied``, ``unread_tags``."""
    data: dict[str, Any] = {"cases": [c.to_dict() for c in report.cases],
                            "passed": report.passed, "failed": report.failed}
    if cov is not None:
        data["coverage"] = cov["rules"]
        data["never_applied"] = cov["never_applied"]
        data["unread_tags"] = cov["unread_tags"]
    return json_text(data)
