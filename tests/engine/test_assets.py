"""KB specs to geometry objects (engine.assets.objects)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose

from handover.engine.assets.objects import (
    gripper_from_spec,
    mesh_file_object,
    object_part_mesh,
    primitive_mesh,
)
from handover.engine.load.loader import load_kb
from handover.engine.spec.schema import GripperSpec, Primitive
from handover.geometry.mesh import MeshError

BRICK = """\
id: brick
name: A brick with a marked end
mass: 0.5
geometry:
  mesh:
    file: meshes/brick.stl
    scale: 0.001
    default_part: body
    regions:
      - {part: end, center: [0.05, 0, 0], extents: [0.04, 1, 1]}
parts:
  body: {tags: []}
  end: {tags: [handle]}
"""

MALLET = """\
id: mallet
name: A mallet
mass: 0.4
geometry:
  primitives:
    - {shape: cylinder, part: handle, radius: 0.01, height: 0.2, position: [0.1, 0, 0],
       rotation_deg: [0, 90, 0], sections: 16}
    - {shape: box, part: head, extents: [0.04, 0.04, 0.08]}
parts:
  handle: {tags: [handle]}
  head: {tags: []}
"""


def _kb(tmp_path: Path, **docs: str) -> Path:
    for name, text in docs.items():
        (tmp_path / "objects").mkdir(parents=True, exist_ok=True)
        (tmp_path / "objects" / f"{name}.yaml").write_text(text)
    return tmp_path


def test_primitive_placement_position_then_extrinsic_rotation():
    box = primitive_mesh(
        Primitive(
            shape="box",
            part="p",
            extents=(0.1, 0.02, 0.04),
            position=(1, 2, 3),
            rotation_deg=(0, 0, 90),
        )  # fmt: skip
    )
    assert_allclose(box.extents, [0.02, 0.1, 0.04], atol=1e-12)
    assert_allclose(box.bounds.mean(axis=0), [1, 2, 3], atol=1e-12)
    # a cylinder along z turned 90 degrees about x lies along y
    cyl = primitive_mesh(
        Primitive(shape="cylinder", part="p", radius=0.01, height=0.3, rotation_deg=(90, 0, 0))
    )
    assert cyl.extents[1] == pytest.approx(0.3)
    sphere = primitive_mesh(Primitive(shape="sphere", part="p", radius=0.05, subdivisions=1))
    assert len(sphere.faces) == 80
    capsule = primitive_mesh(Primitive(shape="capsule", part="p", radius=0.01, height=0.05))
    assert capsule.extents[2] == pytest.approx(0.07)


def test_object_from_primitives_is_one_tagged_surface(tmp_path):
    kb = load_kb(_kb(tmp_path, mallet=MALLET))
    pm = object_part_mesh(kb, kb.object("mallet"))
    assert pm.part_names == ["handle", "head"]
    assert pm.mesh.is_watertight
    # the handle runs along x from 0 to 0.2; its first 0.02 m is inside the head
    handle_faces = pm.mesh.triangles_center[pm.face_part == 0]
    assert (handle_faces[:, 0] >= 0.02 - 1e-9).all()
    cap = 16 / 2 * 0.01**2 * np.sin(2 * np.pi / 16)
    assert pm.mesh.volume == pytest.approx(0.04 * 0.04 * 0.08 + cap * 0.18, rel=1e-9)


def test_object_from_a_mesh_file_with_regions(tmp_path):
    root = _kb(tmp_path, brick=BRICK)
    (root / "objects" / "meshes").mkdir()
    trimesh.creation.box(extents=(100, 50, 30)).export(root / "objects" / "meshes" / "brick.stl")
    kb = load_kb(root)
    pm = object_part_mesh(kb, kb.object("brick"))
    assert_allclose(sorted(pm.mesh.extents), [0.03, 0.05, 0.1], rtol=1e-6)  # mm scaled to m
    assert pm.part_names == ["body", "end"]
    # the +x end (0.05 x 0.03) is "end", everything else "body"
    assert pm.part_areas()["end"] == pytest.approx(0.05 * 0.03, rel=1e-5)


def test_mesh_file_gone_after_loading_is_a_mesh_error(tmp_path):
    root = _kb(tmp_path, brick=BRICK)
    (root / "objects" / "meshes").mkdir()
    stl = root / "objects" / "meshes" / "brick.stl"
    trimesh.creation.box(extents=(100, 50, 30)).export(stl)
    kb = load_kb(root)
    stl.unlink()
    with pytest.raises(MeshError, match="not found"):
        object_part_mesh(kb, kb.object("brick"))


def test_mesh_file_object_is_one_body(tmp_path):
    path = tmp_path / "thing.obj"
    trimesh.creation.icosphere(subdivisions=1, radius=0.03).export(path)
    pm = mesh_file_object(path)
    assert pm.part_names == ["body"]
    assert (pm.face_part == 0).all()
    assert_allclose(pm.mass_centre, 0.0, atol=1e-9)


def test_gripper_from_spec_keeps_every_number():
    spec = GripperSpec(
        id="g", name="G", max_opening=0.1, min_opening=0.01, finger_length=0.05,
        finger_width=0.02, finger_thickness=0.008, palm=(0.05, 0.12, 0.07), clearance=0.004,
        friction=0.6, parallel_tol_deg=8, min_overlap_area=2e-4, roll_step_deg=30,
    )  # fmt: skip
    g = gripper_from_spec(spec)
    assert (g.max_opening, g.min_opening, g.finger_length, g.finger_width) == (
        0.1, 0.01, 0.05, 0.02
    )  # fmt: skip
    assert (g.finger_thickness, g.palm, g.clearance, g.friction) == (
        0.008, (0.05, 0.12, 0.07), 0.004, 0.6
    )  # fmt: skip
    assert (g.parallel_tol_deg, g.min_overlap_area, g.roll_step_deg) == (8, 2e-4, 30)


# ---------------------------------------------------------------- hollow primitives

MUG = """\
id: mug
name: A mug from a cup, a rim and a handle
mass: 0.3
tags: [open_container]
geometry:
  primitives:
    - {shape: tube, part: rim, radius: 0.04, height: 0.01, thickness: 0.004,
       position: [0, 0, 0.095]}
    - {shape: cup, part: body, radius: 0.04, height: 0.1, thickness: 0.004,
       bottom_thickness: 0.006, position: [0, 0, 0.05]}
    - {shape: box, part: handle, extents: [0.012, 0.02, 0.07], position: [0.05, 0, 0.05]}
parts:
  rim: {tags: [rim, food_contact]}
  body: {tags: []}
  handle: {tags: [handle]}
axes:
  up: [0, 0, 1]
"""


def test_a_mug_from_a_cup_is_gripped_across_its_body_wall(tmp_path):
    from handover.engine.assets.objects import object_interior
    from handover.geometry.collision import ObjectCollider
    from handover.geometry.generate import generate_candidates

    kb = load_kb(_kb(tmp_path, mug=MUG))
    obj = kb.objects["mug"]
    pm = object_part_mesh(kb, obj)
    assert pm.mesh.is_watertight
    grip = gripper_from_spec(next(iter(load_kb(None).grippers.values())))
    c = generate_candidates(pm, grip, collider=ObjectCollider(pm.mesh))
    body = pm.part_names.index("body")
    wall = (c.parts == body).all(axis=1) & (c.width < 0.0045)
    assert wall.any()  # across the 4 mm wall of the body
    radial = np.linalg.norm(c.contacts[wall][..., :2], axis=-1)
    assert (radial.min(axis=1) < 0.037).all() and (radial.max(axis=1) > 0.039).all()
    # no finger pad centre of those grasps lies in the drink: the inner contact is on the
    # wall, and the interior is the cup's cavity from the bottom (6 mm) to the rim plane
    inside = object_interior(kb, obj)
    assert len(inside) == 2  # the cup's cavity and the rim's bore
    probes = [[0, 0, 0.05], [0, 0, 0.101], [0, 0, 0.005], [0.035, 0, 0.097], [0.038, 0, 0.05]]
    assert inside.contains(np.array(probes)).tolist() == [True, False, False, True, False]
    assert not inside.contains(c.contacts[wall].reshape(-1, 3)).any()
    # contacts in the top centimetre are the rim's, inside and outside
    top = (c.contacts[..., 2] > 0.0901).all(axis=1)
    assert (c.parts[top] == pm.part_names.index("rim")).all()


@pytest.mark.parametrize(
    "prim, message",
    [
        ("{shape: cup, part: body, radius: 0.02, height: 0.1, thickness: 0.02}", "its radius"),
        ("{shape: cup, part: body, radius: 0.02, height: 0.1}", "needs thickness"),
        ("{shape: box, part: body, extents: [0.1, 0.1, 0.1], thickness: 0.01}", "does not take"),
        ("{shape: bowl, part: body, radius: 0.05, height: 0.02, thickness: 0.004,"
         " bottom_radius: 0.02}", "conical"),
    ],
)
def test_impossible_hollow_primitives_are_kb_errors_at_their_line(make_kb, prim, message):
    from handover.engine.errors import KBError

    text = f"""\
        id: cupish
        name: Cupish
        mass: 0.1
        geometry:
          primitives:
            - {prim}
        parts:
          body: {{tags: []}}
        """
    root = make_kb({"objects/cupish.yaml": text})
    with pytest.raises(KBError) as info:
        load_kb(root)
    (issue,) = info.value.issues
    assert issue.line == 6 and message in issue.message
