"""The arms' links in a plan: at the joint values a plan gives, no link of an arm intersects the
table, an obstacle, the receiver's body, the robot's own body or (where both arms hold the
object at once) the other arm. Checked independently of the planner: the links are posed by
yourdfpy's forward kinematics of the URDF and their collision elements (cylinders, spheres,
boxes, as the URDF declares them) tested with python-fcl against the table's volume (from the
scene's YAML), the receiver's body (the result's ``bodies``) and the robot's fixed links."""

from __future__ import annotations

import shutil
from pathlib import Path

import fcl
import numpy as np
import pytest
import yaml
import yourdfpy

from handover.engine.load.loader import load_kb
from handover.engine.planner import Planner
from handover.engine.store.kb import builtin_kb_dir

TORSO_LINKS = ("base_link", "torso", "head")  # the URDF's links fixed to its root


@pytest.fixture(scope="module")
def builtin_urdf() -> yourdfpy.URDF:
    return yourdfpy.URDF.load(str(builtin_kb_dir() / "robots" / "idro_arms.urdf"))


def base_pose(kb: Path) -> np.ndarray:
    spec = yaml.safe_load((kb / "robots" / "idro.yaml").read_text())
    assert spec["base_pose"]["rotation_deg"] == [0, 0, 0]
    pose = np.eye(4)
    pose[:3, 3] = spec["base_pose"]["position"]
    return pose


def fcl_object(geometry, pose: np.ndarray) -> fcl.CollisionObject:
    return fcl.CollisionObject(geometry, fcl.Transform(pose[:3, :3], pose[:3, 3]))


def link_objects(urdf: yourdfpy.URDF, base: np.ndarray, links) -> dict[str, list]:
    """Each link's collision elements at the URDF's current configuration, in the world."""
    return {name: link_objects_at(urdf, name, base @ urdf.get_transform(name, urdf.base_link))
            for name in links}


def link_objects_at(urdf: yourdfpy.URDF, name: str, world: np.ndarray) -> list:
    """The collision elements of link ``name`` with the link at pose ``world`` (4, 4)."""
    shapes = []
    for c in urdf.link_map[name].collisions:
        origin = np.eye(4) if c.origin is None else c.origin
        g = c.geometry
        if g.cylinder is not None:
            geom = fcl.Cylinder(float(g.cylinder.radius), float(g.cylinder.length))
        elif g.sphere is not None:
            geom = fcl.Sphere(float(g.sphere.radius))
        elif g.box is not None:
            geom = fcl.Box(*map(float, g.box.size))
        else:
            raise AssertionError(f"{name}: a collision geometry this test does not model")
        shapes.append(fcl_object(geom, world @ origin))
    return shapes


def arm_links(urdf: yourdfpy.URDF, side: str) -> list[str]:
    """The links the arm's joints move (its mount, ``<side>_link0``, is fixed to the torso)."""
    return [n for n in urdf.link_map if n.startswith(f"{side}_link") and n != f"{side}_link0"]


def posed_arm(urdf, base, side, joints) -> dict[str, list]:
    urdf.update_cfg(joints)
    return link_objects(urdf, base, arm_links(urdf, side))


def collide(a: fcl.CollisionObject, b: fcl.CollisionObject) -> bool:
    return fcl.collide(a, b, fcl.CollisionRequest(), fcl.CollisionResult()) > 0


def table_volume(kb: Path, scene: str) -> fcl.CollisionObject:
    """The table from the scene's YAML: its top's footprint, from the floor to the top
    surface (nothing passes under a table top here: its legs and the space a receiver does not
    reach into)."""
    support = yaml.safe_load((kb / "scenes" / f"{scene}.yaml").read_text())["support"]
    x, y, top = support["position"]
    pose = np.eye(4)
    pose[:3, 3] = [x, y, top / 2.0]
    return fcl_object(fcl.Box(support["size"][0], support["size"][1], top), pose)


def obstacle_boxes(kb: Path, scene: str) -> dict[str, fcl.CollisionObject]:
    out = {}
    for o in yaml.safe_load((kb / "scenes" / f"{scene}.yaml").read_text()).get("obstacles", []):
        assert "rotation_deg" not in o
        pose = np.eye(4)
        pose[:3, 3] = o["position"]
        out[f"scene:{o['id']}"] = fcl_object(fcl.Box(*o["extents"]), pose)
    return out


def receiver_body(result: dict, without: tuple[str, ...] = ()) -> dict[str, fcl.CollisionObject]:
    """The receiver's primitives as the result gives them (world), but the arms of the hands
    in ``without`` (raised to take the object at the handover)."""
    out = {}
    for p in result["bodies"]["receiver"]:
        if any(p["name"].startswith(f"{h}_") and p["name"].split("_", 1)[1] in
               ("upper_arm", "forearm", "hand") for h in without):
            continue
        if p["shape"] == "capsule":
            out.update(capsule_objects(f"body:receiver:{p['name']}", p["p0"], p["p1"],
                                       p["radius"]))
        else:
            assert p["shape"] == "box", p
            out[f"body:receiver:{p['name']}"] = fcl_object(fcl.Box(*p["extents"]),
                                                           np.asarray(p["pose"]))
    return out


def receiver_hands(result: dict) -> dict[str, fcl.CollisionObject]:
    """The boxes of the receiver's hands that take the object, where the result puts them
    at the handover (``human_grasps[].model``, world), and each arm reaching for it, as thick
    as the body's upper arm: from the shoulder (the result's body) through the elbow to the
    wrist where the result bends it (``human_grasps[].arm``), the wrist at most a hand's
    length (0.2 m) from the hand's boxes."""
    out = {f"body:receiver:{h['hand']}_hand:{b['name']}": fcl_object(
        fcl.Box(*b["extents"]), np.asarray(b["pose"])) for h in result["human_grasps"]
        for b in h["model"]}
    parts = {p["name"]: p for p in result["bodies"]["receiver"]}
    for h in result["human_grasps"]:
        upper = parts[f"{h['hand']}_upper_arm"]
        arm = h["arm"]
        assert np.allclose(arm["shoulder"], upper["p0"], atol=1e-6)
        hand = np.mean([np.asarray(b["pose"])[:3, 3] for b in h["model"]], axis=0)
        assert np.linalg.norm(hand - np.asarray(arm["wrist"])) < 0.2
        out.update(capsule_objects(f"body:receiver:{h['hand']}_upper_arm", upper["p0"],
                                   arm["elbow"], upper["radius"]))
        out.update(capsule_objects(f"body:receiver:{h['hand']}_forearm", arm["elbow"],
                                   arm["wrist"], upper["radius"]))
    return out


def capsule_objects(name: str, p0, p1, radius: float) -> dict[str, fcl.CollisionObject]:
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    pose = np.eye(4)
    pose[:3, 3] = 0.5 * (p0 + p1)
    if length > 1e-9:
        z = axis / length
        x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
        pose[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return {name: fcl_object(fcl.Capsule(radius, length), pose)}


def held_object(result: dict, boxes, stage: str) -> dict[str, fcl.CollisionObject]:
    """The object held, as boxes ``(extents, centre)`` in its own frame (from its YAML), at
    pick-up (``initial_pose``) or at the handover (``object_pose``)."""
    pose = np.asarray(result["initial_pose" if stage == "pickup" else "object_pose"])
    out = {}
    for i, (extents, centre) in enumerate(boxes):
        local = np.eye(4)
        local[:3, 3] = centre
        out[f"object:{result['object']}:{i}"] = fcl_object(fcl.Box(*extents), pose @ local)
    return out


def link_hits(kb: Path, urdf, result: dict, scene: str, object_boxes=()) -> list[str]:
    """Every (stage, arm's link, target) the plan's joint values put in contact,
    independently of the planner; [] for a clear plan. Targets: the table, the obstacles,
    the receiver's body (without the arms that take the object at the handover), the hands
    that take it and the arms reaching for it, the robot's fixed links, the other arm (at
    its ``rest`` where it waits: H1G1, H2G2 but midair), and (``object_boxes``, its boxes in
    its own frame) the object held at pick-up and at the handover."""
    base = base_pose(kb)
    urdf.update_cfg(np.zeros(len(urdf.actuated_joint_names)))
    torso = {f"body:robot:{n}": o for n, objs in
             link_objects(urdf, base, TORSO_LINKS).items() for o in objs}
    world = {"scene:table": table_volume(kb, scene), **obstacle_boxes(kb, scene)}
    receiving = tuple(h["hand"] for h in result["human_grasps"])
    found = []
    posed: dict[str, dict[str, dict]] = {}
    for g in result["robot_grasps"]:
        side = g["arm"]
        other = "right" if side == "left" else "left"
        urdf.update_cfg(np.zeros(len(urdf.actuated_joint_names)))
        mount = link_objects(urdf, base, [f"{other}_link0"])[f"{other}_link0"]
        rest = result["robot"]["arms"][other]["rest"]
        resting = {f"body:robot:{n}": o for n, objs in
                   posed_arm(urdf, base, other, rest).items() for o in objs} if rest else {}
        for stage, joints in g["joints"].items():
            arm = posed_arm(urdf, base, side, joints)
            posed.setdefault(stage, {})[side] = arm
            person = receiver_body(result, receiving if stage == "handover" else ())
            if stage == "handover":
                person.update(receiver_hands(result))
            held = held_object(result, object_boxes, stage) if stage != "midair" else {}
            # The other arm waits at rest but where both arms work (H2G2's midair, H2G1).
            idle = resting if result["mode"] != "H2G1" and stage != "midair" else {}
            targets = {**world, **person, **torso, **held, **idle,
                       **{f"body:robot:{other}_link0": o for o in mount}}
            for link, objs in arm.items():
                for name, target in targets.items():
                    if any(collide(o, target) for o in objs):
                        found.append(f"{stage}: {link} hits {name}")
    for stage, arms in posed.items():  # both arms at once
        if len(arms) == 2:
            for la, objs_a in arms["left"].items():
                for lb, objs_b in arms["right"].items():
                    if any(collide(a, b) for a in objs_a for b in objs_b):
                        found.append(f"{stage}: {la} hits {lb}")
    return found


@pytest.mark.parametrize(("obj", "kwargs", "arms"), [
    ("knife", {}, 1),
    ("mug", {}, 1),
    ("knife", {"receiver": "seated_adult"}, 2),
    ("mug", {"receiver": "seated_adult"}, 1),
    ("tray", {"mode": "h2g1"}, 2),
    ("pen", {"mode": "h2g2"}, 2),
])
def test_no_link_of_a_planned_arm_hits_the_table_the_bodies_or_the_other_arm(
        builtin_urdf, obj, kwargs, arms):
    r = Planner().plan(obj, **kwargs).to_dict()
    assert r["outcome"] == "handover", r["reason"]
    assert len({g["arm"] for g in r["robot_grasps"]}) == arms
    assert link_hits(builtin_kb_dir(), builtin_urdf, r, r["query"]["scene"]) == []


# ----------------------------------------------------------------- an obstacle in the way

SCENE = """\
id: {id}
name: {name}
support: {{position: [0.55, 0.0, 0.75], size: [0.5, 1.0], thickness: 0.03}}
obstacles:
  - {{id: {obstacle}, position: [{x:.4f}, {y:.4f}, {z:.4f}], extents: [{ex}, {ey}, {ez}]}}
receiver: {{position: [1.0, 0.0, 0.0], facing: [-1.0, 0.0, 0.0]}}
object: {{position: [0.33, 0.0]}}
"""


@pytest.fixture(scope="module")
def links_kb(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("armlinks") / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    return root


def test_a_lamp_where_the_elbow_went_moves_the_elbow(links_kb, builtin_urdf):
    # Without the lamp: where the giving arm's elbow (its link4) is at pick-up.
    kb = load_kb(links_kb)
    before = Planner(kb=kb).plan("mug", scene="table", mode="h1g1").to_dict()
    assert before["outcome"] == "handover"
    (grasp,) = before["robot_grasps"]
    side = grasp["arm"]
    builtin_urdf.update_cfg(grasp["joints"]["pickup"])
    elbow = (base_pose(links_kb) @ builtin_urdf.get_transform(f"{side}_link4",
                                                              builtin_urdf.base_link))[:3, 3]
    # A lamp (a 10 cm box) hung there, far from the gripper and the object at both stages.
    pick = (np.asarray(before["initial_pose"]) @ np.asarray(grasp["pose"]))[:3, 3]
    give = np.asarray(grasp["pose_world"])[:3, 3]
    assert min(np.linalg.norm(elbow - pick), np.linalg.norm(elbow - give)) > 0.3
    (links_kb / "scenes" / "lamp.yaml").write_text(SCENE.format(
        id="lamp", name="A lamp hanging where the elbow went", obstacle="lamp",
        x=elbow[0], y=elbow[1], z=elbow[2], ex=0.1, ey=0.1, ez=0.1), encoding="utf-8")
    # The old configuration goes through it (checked here, not by the planner) ...
    assert any("hits scene:lamp" in h for h in link_hits(links_kb, builtin_urdf, before, "lamp"))
    after = Planner(kb=load_kb(links_kb)).plan("mug", scene="lamp", mode="h1g1").to_dict()
    assert after["outcome"] == "handover", after["reason"]
    # ... the plan with the lamp holds the mug with its links clear of the lamp and the rest.
    assert link_hits(links_kb, builtin_urdf, after, "lamp") == []
    assert after["robot_grasps"][0]["joints"] != grasp["joints"]
    entry = next(e for e in after["trace"] if e["rule"] == "arm_reaches")
    assert entry["status"] == "pass" and "scene:lamp" in entry["links"]


def test_a_glass_wall_before_the_robot_makes_it_infeasible_naming_the_links(links_kb):
    # A glass wall from 5 cm above the table top to 1.8 m, 0.17-0.21 m in front of the
    # robot's axis: the gripper reaches over the table beyond it, the arms cannot.
    (links_kb / "scenes" / "glass.yaml").write_text(SCENE.format(
        id="glass", name="A glass wall between the robot and the table", obstacle="glass",
        x=0.19, y=0.0, z=1.3, ex=0.04, ey=2.0, ez=1.0), encoding="utf-8")
    plan = Planner(kb=load_kb(links_kb)).plan("mug", scene="glass")
    r = plan.to_dict()
    assert r["outcome"] == "infeasible" and not r["feasible"]
    assert "arm_reaches" in r["reason"]
    assert "hit scene:glass" in r["reason"] or "hits scene:glass" in r["reason"]
    assert "_link" in r["reason"]  # the link is named
    assert "the arms' links hit scene:glass" in r["reason"]


def test_the_trace_says_what_the_links_were_checked_against(links_kb):
    r = Planner().plan("pen", mode="h2g2").to_dict()
    assert r["outcome"] == "handover"
    entries = [e for e in r["trace"] if e["rule"] == "arm_reaches"]
    assert len(entries) == 2
    for e in entries:
        assert e["status"] == "pass" and e["measured"] == 1.0
        assert "its links clear of scene:table, body:receiver, body:robot" in e["threshold"]
        assert e["links"].startswith("clear of scene:table, body:receiver, body:robot")
        other = "right" if e["arm"] == "left" else "left"
        assert f"of the {other} arm's links at the midair regrasp" in e["links"]
    single = Planner().plan("knife", mode="h1g1").to_dict()
    (e,) = [e for e in single["trace"] if e["rule"] == "arm_reaches"]
    assert e["links"] == ("clear of scene:table, body:receiver, body:robot, object:knife at "
                          "pick-up and at the handover")


def test_the_shoulders_an_arm_turns_in_are_spared_whatever_the_body_calls_them(
        tmp_path, builtin_urdf):
    # The robot's YAML body names its shoulder mounts unlike the URDF's links: the arm's first
    # link always touches its mount, which is found by sampling, not by name; the torso and
    # the head still count.
    root = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    robot = root / "robots" / "idro.yaml"
    text = robot.read_text()
    assert "{id: left_link0," in text and "{id: right_link0," in text
    robot.write_text(text.replace("{id: left_link0,", "{id: left_shoulder,")
                     .replace("{id: right_link0,", "{id: right_shoulder,"), encoding="utf-8")
    plan = Planner(kb=load_kb(root)).plan("knife")
    r = plan.to_dict()
    assert r["outcome"] == "handover", r["reason"]
    assert link_hits(root, builtin_urdf, r, "table") == []
    arms = plan.context.arms
    assert arms.spared("left") == ("left_link0", "left_shoulder")
    assert arms.spared("right") == ("right_link0", "right_shoulder")
    # Any configuration still hits the torso when it goes through it.
    q = arms.arm("left").kin.random_configurations(400, np.random.default_rng(3))
    hits = arms.collisions("left", q)
    assert any("torso" in row for row in hits)
    assert not any("left_shoulder" in row for row in hits)


# ----------------------------------------------------------------- the object held

TROPHY = """\
id: trophy
name: A trophy, its post on a wide plinth
mass: 0.4
geometry:
  primitives:
    - {shape: box, part: base, extents: [0.40, 0.40, 0.10], position: [0, 0, 0.05]}
    - {shape: box, part: post, extents: [0.02, 0.02, 0.16], position: [0, 0, 0.18]}
parts:
  base: {tags: []}
  post: {tags: [handle]}
axes:
  up: [0, 0, 1]
"""
TROPHY_BOXES = (((0.40, 0.40, 0.10), (0.0, 0.0, 0.05)), ((0.02, 0.02, 0.16), (0.0, 0.0, 0.18)))


@pytest.fixture(scope="module")
def trophy_plan(links_kb):
    (links_kb / "objects" / "trophy.yaml").write_text(TROPHY, encoding="utf-8")
    return Planner(kb=load_kb(links_kb)).plan("trophy")


def test_no_link_goes_into_the_object_held_or_the_hands_taking_it(links_kb, builtin_urdf,
                                                                  trophy_plan):
    r = trophy_plan.to_dict()
    assert r["outcome"] == "handover", r["reason"]
    assert link_hits(links_kb, builtin_urdf, r, "table", TROPHY_BOXES) == []
    (entry,) = [e for e in r["trace"] if e["rule"] == "arm_reaches"]
    assert entry["links"] == ("clear of scene:table, body:receiver, body:robot, object:trophy "
                              "at pick-up and at the handover")


def test_a_grasp_low_on_the_post_puts_the_wrist_into_the_base(links_kb, builtin_urdf,
                                                              trophy_plan):
    # Side grasps 3.6 cm above the plinth, the fingers closing horizontally: the gripper
    # fits (its palm is 6 cm thick), the wrist behind it does not (its last link, a cylinder
    # of 5 cm radius about the approach, 15-22 cm behind the grasp, over the plinth).
    # Whatever the arm's other joints do, the exact check finds it in the plinth, names the
    # link and the object, and passes the row over.
    from handover.engine.plan.arms.solve import confirm
    from handover.engine.plan.hands import hands as plan_hands
    from handover.engine.plan.phase import Phase, Roles

    ctx = trophy_plan.context
    r = trophy_plan.to_dict()
    poses = ctx.gripper_poses()  # object frame
    low = np.flatnonzero((np.abs(poses[:, 2, 2]) < 0.05) & (np.abs(poses[:, 2, 0]) > 0.95)
                         & (poses[:, 2, 3] > 0.12) & (poses[:, 2, 3] < 0.15))
    assert len(low)
    hands = plan_hands(ctx, Roles(want=frozenset({"handle"})))
    (base_box,) = held_object(r, TROPHY_BOXES[:1], "pickup").values()
    checked = 0
    for side in ("left", "right"):
        phase = Phase("H1G1", hands=hands, arm=side)
        flange_to_link7 = np.linalg.inv(builtin_urdf.get_transform(f"{side}_flange",
                                                                   f"{side}_link7"))
        tcp = np.asarray(r["robot"]["arms"][side]["tcp"])
        for grasp in low:
            check = confirm(ctx, phase, side, np.array([grasp]), np.array([0]))[0]
            if not check.reached[0]:  # not within this arm's reach at pick-up
                continue
            checked += 1
            assert not check.ok
            words = check.failure()
            assert words.startswith(f"the {side} arm's ") and words.endswith(" at pick-up")
            assert f"{side}_link7" in words and "object:trophy" in words, words
            # Here: the URDF's cylinder of the last link, where the grasp puts it.
            link7 = (np.asarray(r["initial_pose"]) @ poses[grasp] @ np.linalg.inv(tcp)
                     @ flange_to_link7)
            (cylinder,) = link_objects_at(builtin_urdf, f"{side}_link7", link7)
            assert collide(cylinder, base_box)
    assert checked


# ----------------------------------------------------------------- the other arm at rest

def test_an_arm_resting_over_the_object_is_worked_around(links_kb, builtin_urdf):
    # The right arm's rest puts its gripper 10 cm above where the left arm picks the knife up
    # (the inverse kinematics of that pose, pointing down). One hand cannot pick it there
    # (the left arm's wrist would go into the resting right arm's, and that is said); the
    # plan found picks it up around the resting arm, its links clear of it (checked here
    # with the URDF posed at the rest joints).
    default = Planner(kb=load_kb(links_kb)).plan("knife").to_dict()
    assert default["mode"] == "H1G1" and default["robot_grasps"][0]["arm"] == "left"
    rest = default["robot"]["arms"]["right"]["rest"]
    assert link_hits(links_kb, builtin_urdf, default, "table") == []
    robot = links_kb / "robots" / "idro.yaml"
    text = robot.read_text(encoding="utf-8")
    over = dict(zip([f"right_joint{i}" for i in range(1, 8)],
                    [2.167, -1.476, -2.61, -2.139, -2.405, 0.895, 1.453], strict=True))
    assert set(rest) == set(over)
    try:
        lines = text.splitlines()
        start = next(i for i, line in enumerate(lines) if "rest: {right_joint1" in line)
        end = next(i for i in range(start, len(lines)) if lines[i].rstrip().endswith("}"))
        lines[start:end + 1] = ["    rest: {" + ", ".join(f"{j}: {v}" for j, v in over.items())
                                + "}"]
        robot.write_text("\n".join(lines) + "\n", encoding="utf-8")
        r = Planner(kb=load_kb(links_kb)).plan("knife").to_dict()
    finally:
        robot.write_text(text, encoding="utf-8")
    assert r["robot"]["arms"]["right"]["rest"] == over
    # Where the right arm rests, 10 cm over the left arm's pick-up grasp (URDF, yourdfpy).
    builtin_urdf.update_cfg(over)
    hover = (base_pose(links_kb) @ builtin_urdf.get_transform("right_flange",
                                                              builtin_urdf.base_link))[:3, 3]
    g = default["robot_grasps"][0]
    pick = (np.asarray(default["initial_pose"]) @ np.asarray(g["pose"]))[:3, 3]
    assert np.linalg.norm(hover - pick) < 0.25
    one_hand = next(t for t in r["modes_tried"] if t["mode"] == "H1G1")
    assert r["outcome"] == "handover", r["reason"]
    if r["mode"] != "H1G1":
        assert "body:robot:right_link" in one_hand["reason"], one_hand["reason"]
    assert link_hits(links_kb, builtin_urdf, r, "table") == []


def test_the_shipped_arms_rest_beside_the_torso_clear_of_the_body_and_each_other(builtin_urdf):
    r = Planner().plan("knife").to_dict()
    base = base_pose(builtin_kb_dir())
    posed = {}
    for side, arm in r["robot"]["arms"].items():
        rest = arm["rest"]
        assert list(rest) == arm["joints"]
        for joint, value in rest.items():
            limit = builtin_urdf.joint_map[joint].limit
            assert limit.lower <= value <= limit.upper
        posed[side] = posed_arm(builtin_urdf, base, side, rest)
    builtin_urdf.update_cfg(np.zeros(len(builtin_urdf.actuated_joint_names)))
    torso = [o for objs in link_objects(builtin_urdf, base, TORSO_LINKS).values() for o in objs]
    for side, links in posed.items():
        other = "right" if side == "left" else "left"
        for link, objs in links.items():
            assert not any(collide(o, t) for o in objs for t in torso), (side, link)
            assert not any(collide(o, t) for o in objs for objs_b in posed[other].values()
                           for t in objs_b), (side, link)
            # Behind the torso's front (x <= 0.12 m) and out to its side (|y| >= 0.12 m).
            builtin_urdf.update_cfg(r["robot"]["arms"][side]["rest"])
            origin = (base @ builtin_urdf.get_transform(link, builtin_urdf.base_link))[:3, 3]
            assert origin[0] <= 0.12 and abs(origin[1]) >= 0.12, (side, link, origin)


def test_an_arm_that_cannot_wait_at_its_rest_does_not_wait(links_kb, builtin_urdf):
    # A post by the robot's left side, where the left arm's elbow rests (the URDF posed at
    # the rest joints): the right arm cannot work while the left waits there, so the
    # screwdriver the right arm hands over on the plain table is handed over by the left,
    # and the one-hand attempt with the right arm says why.
    plain = Planner(kb=load_kb(links_kb)).plan("screwdriver", mode="h1g1").to_dict()
    assert [g["arm"] for g in plain["robot_grasps"]] == ["right"]
    builtin_urdf.update_cfg(plain["robot"]["arms"]["left"]["rest"])
    elbow = (base_pose(links_kb) @ builtin_urdf.get_transform("left_link4",
                                                              builtin_urdf.base_link))[:3, 3]
    assert elbow[0] < 0.0 and elbow[1] > 0.4  # behind the torso's front, out to the left
    (links_kb / "scenes" / "post.yaml").write_text(SCENE.format(
        id="post", name="A post by the robot's left side", obstacle="post",
        x=elbow[0], y=elbow[1], z=elbow[2], ex=0.05, ey=0.05, ez=0.05), encoding="utf-8")
    planner = Planner(kb=load_kb(links_kb))
    r = planner.plan("screwdriver", scene="post", mode="h1g1").to_dict()
    assert r["outcome"] == "handover", r["reason"]
    assert [g["arm"] for g in r["robot_grasps"]] == ["left"]
    assert link_hits(links_kb, builtin_urdf, r, "post") == []
    # Posts by both sides: neither arm can wait, so one hand cannot hand it over, and says so.
    text = SCENE.format(id="posts", name="Posts by both sides of the robot",
                        obstacle="left_post", x=elbow[0], y=elbow[1], z=elbow[2], ex=0.05,
                        ey=0.05, ez=0.05)
    right = (f"  - {{id: right_post, position: [{elbow[0]:.4f}, {-elbow[1]:.4f}, "
             f"{elbow[2]:.4f}], extents: [0.05, 0.05, 0.05]}}\n")
    text = text.replace("receiver:", right + "receiver:", 1)
    (links_kb / "scenes" / "posts.yaml").write_text(text, encoding="utf-8")
    r = Planner(kb=load_kb(links_kb)).plan("screwdriver", scene="posts", mode="h1g1").to_dict()
    assert r["outcome"] == "infeasible"
    assert "the left arm cannot wait at its rest at pick-up while the right arm works: its " \
           "left_link3, left_link4 hit scene:left_post" in r["reason"], r["reason"]
    assert "the right arm cannot wait at its rest" in r["reason"], r["reason"]


def test_the_object_held_must_not_pass_through_the_arm_that_waits(builtin_urdf):
    # The screwdriver offered where the left arm rests (its elbow, from the URDF posed at the
    # rest joints) while the right arm works: the row is blocked, naming the resting arm's
    # link and the object, whatever the right arm's joints; offered where the plan offers
    # it, nothing of the resting arm is hit. The words a failed check says, too.
    from dataclasses import replace

    from handover.engine.plan.arms.links import rest_blocked
    from handover.engine.plan.arms.stages import ArmCheck

    plan = Planner().plan("screwdriver", mode="h1g1")
    ctx, attempt = plan.context, plan.attempt
    (chosen,) = attempt.chosen
    phase = chosen.phase
    assert phase.arm == "right"
    k = np.array([chosen.presentation])
    assert rest_blocked(ctx, phase, "right", "handover", k) == [()]
    r = plan.to_dict()
    builtin_urdf.update_cfg(r["robot"]["arms"]["left"]["rest"])
    elbow = (base_pose(builtin_kb_dir()) @ builtin_urdf.get_transform(
        "left_link4", builtin_urdf.base_link))[:3, 3]
    poses = phase.hands.poses.copy()
    pose = poses[k[0]]
    pose[:3, 3] += elbow - pose[:3, :3] @ ctx.part_mesh.mesh.centroid - pose[:3, 3]
    moved = phase.but(hands=replace(phase.hands, poses=poses, key=("moved",)))
    (there,) = rest_blocked(ctx, moved, "right", "handover", k)
    assert ("rest:left:left_link4", "object:screwdriver") in there, there
    assert rest_blocked(ctx, moved.but(mode="H2G1"), "right", "handover", k) == [()]
    check = ArmCheck("right", ("handover",), pose[None], np.zeros((1, 7)), np.array([True]),
                     np.array([False]), np.zeros(1), np.zeros(1), (there,))
    assert check.failure().startswith("the left arm cannot wait at its rest at the handover "
                                      "while the right arm works: its ")
    assert "left_link4" in check.failure() and "rest:" not in check.failure()


# ------------------------------------------------------ the midair regrasp, higher or lower


def test_a_lamp_below_the_midair_regrasp_raises_it(links_kb, builtin_urdf):
    # The book goes H2G2 for a standing adult: where the second gripper takes it (the
    # handover pose 20 cm back toward the robot) a lamp hangs, its top 5 cm below the
    # book's centre there. People pass a thing between their hands higher then.
    book = yaml.safe_load((links_kb / "objects" / "book.yaml").read_text())
    boxes = [(p["extents"], p.get("position", [0, 0, 0]))
             for p in book["geometry"]["primitives"]]  # its pages and spine
    before = Planner(kb=load_kb(links_kb)).plan("book").to_dict()
    assert before["mode"] == "H2G2" and before["regrasp"]["midair_lift"] == 0.0
    default = np.asarray(before["regrasp"]["midair_pose"])
    centre = default[:3, 3] - [0.0, 0.0, 0.10]  # the lamp's centre, 10 cm below the book's
    (links_kb / "scenes" / "lamp_at_midair.yaml").write_text(SCENE.format(
        id="lamp_at_midair", name="A lamp below where the hands pass the book",
        obstacle="lamp", x=centre[0], y=centre[1], z=centre[2], ex=0.14, ey=0.24, ez=0.10),
        encoding="utf-8")
    lamp = obstacle_boxes(links_kb, "lamp_at_midair")["scene:lamp"]
    at = {"object_pose": default, "initial_pose": default, "object": "book"}
    # There, the book goes through the lamp (checked here, with fcl) ...
    assert any(collide(o, lamp) for o in held_object(at, boxes, "handover").values())
    after = Planner(kb=load_kb(links_kb)).plan("book", scene="lamp_at_midair").to_dict()
    assert after["outcome"] == "handover" and after["mode"] == "H2G2", after["reason"]
    # ... so the regrasp is 10 cm higher, the handover where it was, the book there clear of
    # the lamp, and every arm's link at every stage clear of it and of everything else.
    regrasp = after["regrasp"]
    assert regrasp["midair_lift"] == pytest.approx(0.10)
    midair = np.asarray(regrasp["midair_pose"])
    handover = np.asarray(after["object_pose"])
    np.testing.assert_allclose(midair[:3, 3], handover[:3, 3] - 0.2 * np.array([1.0, 0, 0])
                               + [0.0, 0.0, 0.10], atol=1e-6)
    at = {"object_pose": midair, "initial_pose": midair, "object": "book"}
    assert not any(collide(o, lamp) for o in held_object(at, boxes, "handover").values())
    assert link_hits(links_kb, builtin_urdf, after, "lamp_at_midair", boxes) == []
    assert {"midair", "handover"} <= {s for g in after["robot_grasps"] for s in g["joints"]}
