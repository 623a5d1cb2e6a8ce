"""Semantic checks of a loaded knowledge base, reported together with the schema errors.

Each check returns :class:`engine.errors.KBIssue` located at the offending YAML node.
Errors stop loading (exit code 3); warnings are shown by ``handover kb validate``.

Errors:
  - duplicate ids across the files of one kind (checked by the loader);
  - an object's geometry naming a part not declared in ``parts`` (primitive ``part``,
    region ``part``, ``default_part``); a task's ``present.axis`` that the object does not
    define; a task's ``receiver_tags`` that no part of the object carries; a ``default_task``
    that is not one of the object's tasks;
  - a mesh file that is missing, or whose path is absolute or leaves the KB folder;
  - a culture extending an unknown culture (also the implicit ``common``), or an ``extends``
    cycle (a culture extending itself included);
  - a rule overriding a rule id that none of the extended cultures has, or one already
    overridden in the same culture; a rule id that repeats a rule in force without
    ``overrides``; a rule overriding a ``safety`` rule without ``override_safety``;
  - a rule naming a tag that no object or part carries and no culture's ``vocabulary``
    documents (``applies.object_tags_any``/``none``, ``forbid_tags``, ``require_tags``, a
    ``keep_out`` or ``pinch`` rule's ``tags``). This is an error, not a warning, because a
    misspelt tag silently disables a rule, safety rules included; add the object before the
    rule, or document the tag in a vocabulary (the hazard tags of ``common``);
  - an ``axis`` rule naming an axis no object defines and no vocabulary documents, a rule's
    ``applies.tasks`` naming a task no object has;
  - a receiver's ``hand`` or a robot's (or an arm's) ``gripper`` that does not exist (or a
    grasp a receiver uses, or a ``receiver_grasp`` rule names, that no hand has); two
    obstacles with one id in a scene;
  - in ``hazards/``: a hazard tag declared twice, an implied tag nothing declares or
    documents, a cycle of implications, a measured hazard whose tag is not declared
    (:func:`handover.engine.store.hazards.hazard_issues`);
  - a robot's ``urdf`` that is missing, outside the KB, xacro, or does not parse (the URDF's
    file:line in the message); an arm naming a link the URDF lacks; an arm's chain with mimic,
    floating or planar joints or none that moves (:func:`lint_robot`);
  - a scene whose receiver or robot stands inside the table or an obstacle, whose receiver
    stands on the robot or faces straight up or down, or whose object is placed off the table;
  - a test case (``tests/``) whose query names an unknown object, task, receiver, culture,
    scene, gripper or robot, or whose expectations name an axis the object lacks, a part or
    tag the object does not have, or a rule not in force in the case's culture; two cases
    with one name in a file.

Warnings:
  - a safety rule overridden with ``override_safety`` ("safety rule X overridden by Y: why");
    ``override_safety`` on a rule that overrides no safety rule;
  - a robot's ``reach`` beyond what its arms reach at full stretch;
  - a tag on an object or a part that no rule of any culture names, no task wants for the
    receiver and no vocabulary documents (a typo, or a hazard nobody handles), at the tag;
  - an object part that no geometry belongs to; an ``axis`` rule that applies to an object by
    its tags (``applies.object_tags_any``) when the object lacks that axis; a document
    whose id differs from its file name (loader); a file outside the KB folders (loader);
  - an object tagged for a ``keep_out`` rule whose geometry has no opening to measure
    (:mod:`handover.engine.load.lint_measure`, with the deep checks only).

Checks that refer across documents are skipped for a kind whose files failed to load, so one
broken file does not cause a cascade of false errors.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from pathlib import PurePosixPath, PureWindowsPath
from typing import TYPE_CHECKING

from handover.engine.errors import KBIssue
from handover.engine.load.lint_scene import lint_scene
from handover.engine.load.lint_tests import lint_tests
from handover.engine.spec.applies import Facts
from handover.engine.spec.schema import KBModel, ObjectSpec, RobotSpec, RuleBase
from handover.engine.store.cultures import (
    _resolve,
    applies_to_object,
    object_facts,
    object_tags,
)
from handover.engine.store.hazards import hazard_issues, tag_families

if TYPE_CHECKING:
    from handover.engine.store.kb import KB

__all__ = [
    "lint_kb", "lint_object", "lint_cultures", "lint_references", "lint_robot", "lint_scene",
    "lint_tests", "rule_tags", "vocabulary", "used_tags", "lint_object_tags",
]


def lint_kb(kb: KB, failed_kinds: Iterable[str] = (), urdf: bool = True) -> list[KBIssue]:
    """Every semantic problem of ``kb``, sorted, each once.

    failed_kinds : document kinds (folder names) with a file that did not load; checks that
    need all documents of such a kind are skipped. urdf : the deep checks too: parse robots'
    URDF files (else only their paths are checked), and build the geometry of the objects a
    rule must measure (:mod:`handover.engine.load.lint_measure`).
    """
    failed = set(failed_kinds)
    issues: list[KBIssue] = []
    for obj in kb.objects.values():
        issues.extend(lint_object(kb, obj))
    issues.extend(lint_cultures(kb, failed))
    if "hazards" not in failed and not {"etiquette", "objects"} & failed:
        known = {name for c in kb.cultures.values() for name in c.vocabulary}
        known |= set().union(*(object_tags(o) for o in kb.objects.values()))
        issues.extend(hazard_issues(kb, known))
    issues.extend(lint_references(kb, failed, urdf))
    if urdf and not {"objects", "etiquette"} & failed:  # the deep checks build geometry
        from handover.engine.load.lint_measure import lint_measurements

        issues.extend(lint_measurements(kb))
    for test_file in kb.tests.values():
        issues.extend(lint_tests(kb, test_file, failed))
    return sorted(set(issues))


# ---------------------------------------------------------------- objects


def lint_object(kb: KB, obj: ObjectSpec) -> Iterator[KBIssue]:
    """Problems inside one object: parts, tasks, axes, mesh file."""
    geometry_parts: set[str] = set()
    declared = ", ".join(obj.parts) or "none"

    def part_ref(part: str, model, *sub) -> Iterator[KBIssue]:
        geometry_parts.add(part)
        if part not in obj.parts:
            yield kb.issue(
                model,
                f"part '{part}' is not declared in the object's parts (declared: {declared})",
                *sub,
            )

    for prim in obj.geometry.primitives:
        yield from part_ref(prim.part, prim, "part")
    mesh = obj.geometry.mesh
    if mesh is not None:
        yield from part_ref(mesh.default_part, mesh, "default_part")
        for region in mesh.regions:
            yield from part_ref(region.part, region, "part")
        yield from _lint_mesh_file(kb, obj)
    for name, part in obj.parts.items():
        if name not in geometry_parts:
            yield kb.issue(
                part,
                f"part '{name}' has no geometry (no primitive or region names it)",
                severity="warning",
            )
    part_tags = {t for part in obj.parts.values() for t in part.tags}
    for task_id, task in obj.tasks.items():
        for present in task.present:
            if present.axis not in obj.axes:
                yield kb.issue(
                    present,
                    f"task '{task_id}' presents axis '{present.axis}', which object "
                    f"'{obj.id}' does not define (axes: {', '.join(obj.axes) or 'none'})",
                    "axis",
                )
        for k, tag in enumerate(task.receiver_tags):
            if tag not in part_tags:
                yield kb.issue(
                    task,
                    f"task '{task_id}' wants the receiver on a part tagged '{tag}', but no "
                    f"part of '{obj.id}' carries it",
                    "receiver_tags",
                    k,
                )
    if obj.default_task is not None and obj.default_task not in obj.tasks:
        yield kb.issue(
            obj,
            f"default_task '{obj.default_task}' is not one of the object's tasks "
            f"({', '.join(obj.tasks) or 'none'})",
            "default_task",
        )


def _lint_mesh_file(kb: KB, obj: ObjectSpec) -> Iterator[KBIssue]:
    mesh = obj.geometry.mesh
    assert mesh is not None
    yield from lint_mesh_path(kb, mesh, obj, mesh.file, "file")


def lint_mesh_path(
    kb: KB, at: KBModel, owner: KBModel, name: str, *sub: str | int, what: str = "mesh file"
) -> Iterator[KBIssue]:
    """A mesh file ``name`` given relative to ``owner``'s YAML file: not empty, not absolute,
    inside the KB folder (also through symbolic links), existing. Issues are located at the
    node ``sub`` of ``at``; ``what`` names the kind of file in the messages (a URDF file)."""
    if not name.strip():
        yield kb.issue(at, f"{what} name is empty", *sub)
        return
    if PurePosixPath(name).is_absolute() or PureWindowsPath(name).is_absolute():
        yield kb.issue(
            at,
            f"{what} '{name}' is an absolute path; give it relative to the YAML file, "
            "inside the KB folder",
            *sub,
        )
        return
    path = kb.relative_path(owner, name)
    root = os.path.normpath(kb.root)
    if os.path.commonpath([root, str(path)]) != root:
        yield kb.issue(at, f"{what} '{name}' leaves the KB folder; keep it inside", *sub)
        return
    if not path.is_file():
        rel = os.path.relpath(path, root)
        yield kb.issue(at, f"{what} '{name}' does not exist (looked for {rel})", *sub)
        return
    real_root = os.path.realpath(root)
    if os.path.commonpath([real_root, os.path.realpath(path)]) != real_root:
        yield kb.issue(
            at,
            f"{what} '{name}' leads through a symbolic link to {os.path.realpath(path)}, "
            "outside the KB folder; copy it into the KB",
            *sub,
        )


# ---------------------------------------------------------------- cultures and rules


RULE_TAG_FIELDS = ("forbid_tags", "require_tags", "tags")
"""The fields of rule kinds that name tags (contact: forbid/require; keep_out, pinch: tags)."""


def rule_tags(rule: RuleBase) -> Iterator[tuple[str, tuple[str | int, ...]]]:
    """Every tag ``rule`` names, with the path of its YAML node: its ``applies`` object tags
    and its kind's tag fields (:data:`RULE_TAG_FIELDS`)."""
    for field in ("object_tags_any", "object_tags_none"):
        for k, tag in enumerate(getattr(rule.applies, field)):
            yield tag, ("applies", field, k)
    for field in RULE_TAG_FIELDS:
        if field in type(rule).model_fields:  # the kinds that name tags
            for k, tag in enumerate(getattr(rule, field)):
                yield tag, (field, k)


def vocabulary(kb: KB) -> dict[str, str]:
    """The tags and axis names the KB documents, name -> meaning: the hazard tags of its
    ``hazards/`` files first (their ``means``), then the cultures' ``vocabulary``; the first
    meaning kept for a name documented twice."""
    out: dict[str, str] = {}
    for doc in kb.hazards.values():
        for name, spec in doc.tags.items():
            out.setdefault(name, spec.means)
    for culture in kb.cultures.values():
        for name, meaning in culture.vocabulary.items():
            out.setdefault(name, meaning)
    return out


def used_tags(kb: KB) -> set[str]:
    """Tags something uses: a rule of any culture (:func:`rule_tags`) or an object's task
    (``receiver_tags``)."""
    used = {tag for c in kb.cultures.values() for r in c.rules for tag, _ in rule_tags(r)}
    used |= {t for o in kb.objects.values() for task in o.tasks.values()
             for t in task.receiver_tags}
    return used


def lint_object_tags(kb: KB, obj: ObjectSpec, known: set[str]) -> Iterator[KBIssue]:
    """Warnings at each tag of ``obj`` and of its parts that is not in ``known`` (the tags
    a rule or task uses, or a vocabulary documents): a typo, or a hazard nobody handles."""
    def warn(tag: str, where: str, model, k: int) -> KBIssue:
        return kb.issue(model, f"tag '{tag}' on {where} is used by no rule and no task, and no "
                        "culture's vocabulary documents it (a typo, or a hazard nobody "
                        "handles?)", "tags", k, severity="warning")

    for k, tag in enumerate(obj.tags):
        if tag not in known:
            yield warn(tag, f"object '{obj.id}'", obj, k)
    for name, part in obj.parts.items():
        for k, tag in enumerate(part.tags):
            if tag not in known:
                yield warn(tag, f"part '{name}' of '{obj.id}'", part, k)


def lint_cultures(kb: KB, failed: set[str]) -> Iterator[KBIssue]:
    """extends and overrides (through resolution), rule tags, axes and tasks."""
    if "etiquette" not in failed:
        for culture_id in kb.cultures:
            _, problems = _resolve(kb, culture_id)
            yield from problems
    if "objects" in failed:
        return
    documented = set(vocabulary(kb)) if "etiquette" not in failed else set()
    families = tag_families(kb) if "hazards" not in failed else None
    carried = set().union(*(object_tags(o, families) for o in kb.objects.values()))
    carried |= {m.tag for m in families.measured} if families is not None else set()
    if "etiquette" not in failed:
        known = used_tags(kb) | documented
        for obj in kb.objects.values():
            yield from lint_object_tags(kb, obj, known)
    used_axes = {a for o in kb.objects.values() for a in o.axes}
    facts: dict[str, Facts] = {}  # each object's, computed once for every axis rule
    used_tasks = {t for o in kb.objects.values() for t in o.tasks}
    for culture in kb.cultures.values():
        for rule in culture.rules:
            for tag, sub in rule_tags(rule):
                if tag not in carried and tag not in documented:
                    yield kb.issue(
                        rule,
                        f"rule '{rule.id}' names tag '{tag}', which no object or part carries "
                        "and no culture's vocabulary documents (a misspelt tag silently "
                        "disables a rule)",
                        *sub,
                    )
            for k, task in enumerate(rule.applies.tasks):
                if task not in used_tasks:
                    yield kb.issue(
                        rule,
                        f"rule '{rule.id}' applies to task '{task}', which no object has",
                        "applies",
                        "tasks",
                        k,
                    )
            if rule.kind == "receiver_grasp" and "hands" not in failed:
                yield from _lint_grasp_names(kb, rule)
            if rule.kind == "axis" and rule.axis is not None:
                if rule.axis not in used_axes and rule.axis not in documented:
                    yield kb.issue(
                        rule,
                        f"rule '{rule.id}' is about axis '{rule.axis}', which no object defines "
                        "and no culture's vocabulary documents",
                        "axis",
                    )
                    continue
                for obj in kb.objects.values():
                    # a rule with no tag condition is about every object with that axis
                    if rule.axis in obj.axes or not rule.applies.object_tags_any:
                        continue
                    if obj.id not in facts:
                        facts[obj.id] = object_facts(obj, families)
                    if applies_to_object(rule, obj, facts=facts[obj.id]):
                        yield kb.issue(
                            rule,
                            f"rule '{rule.id}' applies to object '{obj.id}' ({obj.source}), "
                            f"which defines no axis '{rule.axis}': the rule cannot judge it "
                            "(it is unknown in a plan, and a hard rule then does not hand the "
                            "object over)",
                            "axis",
                            severity="warning",
                        )


def _lint_grasp_names(kb: KB, rule: RuleBase) -> Iterator[KBIssue]:
    """A ``receiver_grasp`` rule naming a grasp no hand of the KB has (a misspelt grasp
    silently disables the rule)."""
    known = {g.name for hand in kb.hands.values() for g in hand.repertoire()}
    for k, name in enumerate(rule.grasps):
        if name not in known:
            yield kb.issue(
                rule,
                f"rule '{rule.id}' names grasp '{name}', which no hand has (grasps: "
                f"{', '.join(sorted(known)) or 'none'})",
                "grasps",
                k,
            )


# ---------------------------------------------------------------- references


def lint_references(kb: KB, failed: set[str], urdf: bool = True) -> Iterator[KBIssue]:
    """Receivers' hands, robots' grippers, scene obstacle ids."""
    if "hands" not in failed:
        for receiver in kb.receivers.values():
            if receiver.hand not in kb.hands:
                yield kb.issue(
                    receiver,
                    f"receiver '{receiver.id}' has hand '{receiver.hand}', which does not "
                    f"exist (hands: {', '.join(sorted(kb.hands)) or 'none'})",
                    "hand",
                )
            elif receiver.grasps is not None:
                known = [g.name for g in kb.hands[receiver.hand].repertoire()]
                for k, name in enumerate(receiver.grasps):
                    if name not in known:
                        yield kb.issue(
                            receiver,
                            f"receiver '{receiver.id}' uses grasp '{name}', which hand "
                            f"'{receiver.hand}' does not have (grasps: {', '.join(known)})",
                            "grasps",
                            k,
                        )
    if "grippers" not in failed:
        for gripper in kb.grippers.values():
            if gripper.meshes is not None:
                for part in ("palm", "finger"):
                    name = getattr(gripper.meshes, part)
                    yield from lint_mesh_path(kb, gripper, gripper, name, "meshes", part)
        for robot in kb.robots.values():
            known = f"(grippers: {', '.join(sorted(kb.grippers)) or 'none'})"
            if robot.gripper not in kb.grippers:
                yield kb.issue(
                    robot,
                    f"robot '{robot.id}' has gripper '{robot.gripper}', which does not exist "
                    + known,
                    "gripper",
                )
            for side, arm in robot.arms.items():
                if arm.gripper not in kb.grippers and arm.gripper != robot.gripper:
                    yield kb.issue(
                        robot,
                        f"robot '{robot.id}': the {side} arm's gripper '{arm.gripper}' does "
                        "not exist " + known,
                        "arms",
                        side,
                        "gripper",
                    )
    for robot in kb.robots.values():
        yield from lint_robot(kb, robot, parse=urdf)
    for scene in kb.scenes.values():
        seen: dict[str, object] = {}
        for k, box in enumerate(scene.obstacles):
            if box.id in seen:
                yield kb.issue(
                    scene,
                    f"obstacle id '{box.id}' appears twice in scene '{scene.id}'",
                    "obstacles",
                    k,
                    "id",
                )
            seen.setdefault(box.id, box)
        yield from lint_scene(kb, scene)


# ---------------------------------------------------------------- robots


def lint_robot(kb: KB, robot: RobotSpec, parse: bool = True) -> Iterator[KBIssue]:
    """A robot's URDF: the file exists inside the KB (as mesh files do), parses (a problem is
    reported at the ``urdf`` key with the URDF's own file:line; xacro is not supported), the
    links each arm names exist, each chain has only revolute, continuous, prismatic and fixed
    joints and at least one that moves, an arm's base link is fixed to the URDF's root; a
    warning when ``reach`` exceeds what the arms reach
    (:func:`~handover.engine.assets.robot_load.check_robot`)."""
    if robot.urdf is None:
        return
    path_issues = list(lint_mesh_path(kb, robot, robot, robot.urdf, "urdf", what="URDF file"))
    if path_issues or not parse:
        yield from path_issues
        return
    from handover.engine.assets.robot_load import check_robot

    issues = check_robot(kb, robot)
    yield from issues
    if not any(i.severity == "error" for i in issues):
        yield from _rest_issues(kb, robot)


def _rest_issues(kb: KB, robot: RobotSpec) -> Iterator[KBIssue]:
    """An arm's ``rest`` whose links touch the robot's own body (but the shoulder it turns
    in) or the other arm at its rest: it could never wait there."""
    if not any(arm.rest is not None for arm in robot.arms.values()):
        return
    from handover.engine.assets.robot import RobotArms

    arms = RobotArms.load(kb, robot)
    for side in arms.sides:
        rest = arms.arm(side).rest
        if rest is None:
            continue
        found = list(arms.contacts(side, rest)[0])
        for other in arms.sides:
            if other < side and arms.arm(other).rest is not None:
                found += arms.contacts(side, rest, other=(other, arms.arm(other).rest),
                                       own_body=False)[0]
        if found:
            said = ", ".join(f"{link} hits {target}" for link, target in found[:4])
            yield kb.issue(robot, f"robot '{robot.id}': the {side} arm's rest puts its links "
                                  f"into the robot: {said}", "arms", side, "rest")
