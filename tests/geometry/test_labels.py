"""Contacts labelled by the part at their point, not by the face they lie on."""

from __future__ import annotations

import numpy as np

from handover.geometry import hollow
from handover.geometry import mesh as gm
from handover.geometry.frames import transform_from
from handover.geometry.generate import generate_candidates
from handover.geometry.gripper import Gripper


def tall_can_with_a_rim():
    # a can 4 cm wide, 12 cm tall: each side face is a triangle spanning the whole height,
    # so no side face's centroid lies in the top centimetre; the region says that
    # centimetre is the rim
    can = gm.cylinder(0.02, 0.12, 32)
    rim = ("rim", np.array([0.0, 0.0, 0.055]), np.array([0.1, 0.1, 0.01]))
    return gm.part_mesh_from_regions(can, "body", [rim])


def test_region_labels_points_first_match_wins():
    labels = gm.RegionLabels(
        parts=np.array([1, 2]),
        centers=np.array([[0.0, 0, 0.05], [0.0, 0, 0.0]]),
        extents=np.array([[1.0, 1, 0.02], [1.0, 1, 0.2]]),
        default=0,
    )
    points = np.array([[0, 0, 0.055], [0, 0, 0.0], [0, 0, 0.5], [0, 0, 0.045]])
    assert labels.part_at(points).tolist() == [1, 2, 0, 1]


def test_a_contact_in_the_top_centimetre_of_a_tall_face_is_the_rim():
    pm = tall_can_with_a_rim()
    rim = pm.part_names.index("rim")
    side = np.abs(pm.mesh.face_normals[:, 2]) < 0.5
    assert (pm.face_part[side] != rim).all()  # by face, no side would be the rim
    c = generate_candidates(pm, Gripper.default())
    z = c.contacts[..., 2]
    sides = np.abs(c.o[:, 2]) < 0.5  # gripped across the can, not top to bottom
    assert sides.any()
    is_rim = c.parts[sides] == rim
    assert is_rim.any() and (~is_rim).any()
    assert (is_rim == (z[sides] >= 0.05 - 1e-12)).all()
    # the same face carries rim and body contacts
    top_faces = set(c.faces[sides][is_rim].ravel().tolist())
    low_faces = set(c.faces[sides][~is_rim].ravel().tolist())
    assert top_faces & low_faces


def test_primitive_labels_a_rim_lining_a_cup_listed_first_wins():
    r, h, t = 0.04, 0.1, 0.004
    cup = hollow.cup(r, h, t)
    rim = hollow.tube(r, 0.01, t, transform=transform_from(None, [0, 0, h / 2 - 0.005]))
    handle = gm.box((0.01, 0.02, 0.06), transform_from(None, [0.044, 0, 0]))
    pm = gm.compose([("rim", rim), ("body", cup), ("handle", handle)])
    assert pm.mesh.is_watertight
    assert cup.volume < pm.mesh.volume < cup.volume + 0.01 * 0.02 * 0.06  # the rim adds none
    names = [
        ("rim", [-r, 0, 0.047]),  # outside, top centimetre
        ("rim", [0, -(r - t), 0.047]),  # inside, top centimetre
        ("rim", [-(r - t / 2), 0, h / 2]),  # the lip
        ("body", [-r, 0, 0.0]),  # outside, lower
        ("body", [0, r - t, -0.02]),  # inside, lower
        ("body", [0, 0, -h / 2]),  # the bottom
        ("handle", [0.049, 0, 0.0]),  # the handle's far side
    ]
    labels = pm.part_at(np.array([p for _, p in names]))
    assert [pm.part_names[k] for k in labels] == [n for n, _ in names]
    # every face is labelled by the part at its centroid
    assert (pm.part_at(pm.mesh.triangles_center) == pm.face_part).all()


def test_without_labels_a_contact_gets_its_face_part():
    m = gm.box((0.1, 0.1, 0.1))
    face_part = (m.triangles_center[:, 0] > 0).astype(np.int64)
    pm = gm.PartMesh(m, face_part, ["a", "b"], np.zeros(3))
    faces = np.arange(len(m.faces))
    assert (pm.part_at(m.triangles_center, faces) == face_part).all()
