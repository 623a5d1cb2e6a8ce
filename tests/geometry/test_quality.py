"""Friction cones, grasp quality and lever arms (geometry.quality), by hand."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from handover.geometry.quality import (
    ContactPairs,
    antipodal_quality,
    com_distance,
    cone_angles,
    in_friction_cone,
)

CLOSE_Y = np.array([[0.0, 1.0, 0.0]])  # closing along +y


def _normals(tilt0_deg: float, tilt1_deg: float) -> np.ndarray:
    """Outward normals: contact 0 faces -y, contact 1 faces +y, each tilted about z."""
    t0, t1 = np.deg2rad([tilt0_deg, tilt1_deg])
    n0 = [np.sin(t0), -np.cos(t0), 0.0]
    n1 = [np.sin(t1), np.cos(t1), 0.0]
    return np.array([[n0, n1]])


def test_cone_angles_are_the_tilts():
    assert_allclose(np.rad2deg(cone_angles(_normals(0, 0), CLOSE_Y)), [[0, 0]], atol=1e-6)
    assert_allclose(np.rad2deg(cone_angles(_normals(20, -5), CLOSE_Y)), [[20, 5]], atol=1e-9)


def test_friction_cone_of_mu_one_half():
    # atan(0.5) = 26.565 degrees
    assert in_friction_cone(_normals(26.0, 0.0), CLOSE_Y, 0.5).all()
    assert not in_friction_cone(_normals(0.0, 27.0), CLOSE_Y, 0.5).any()


def test_quality_is_the_margin_of_the_worse_contact():
    half = np.rad2deg(np.arctan(0.5))
    assert antipodal_quality(_normals(0, 0), CLOSE_Y, 0.5)[0] == pytest.approx(1.0)
    assert antipodal_quality(_normals(half / 2, 1.0), CLOSE_Y, 0.5)[0] == pytest.approx(0.5)
    assert antipodal_quality(_normals(0, 40), CLOSE_Y, 0.5)[0] == 0.0


def test_com_distance_is_the_distance_to_the_contact_line():
    contacts = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]])
    assert com_distance(contacts, [0.5, 0.3, 0.4])[0] == pytest.approx(0.5)
    assert com_distance(contacts, [7.0, 0.0, 0.0])[0] == pytest.approx(0.0)


def test_contact_pairs_derived_fields_and_rows():
    pairs = ContactPairs(
        contacts=np.array([[[0, -0.02, 0], [0, 0.02, 0]], [[1, 0, 0], [1, 0, 0.03]]], float),
        normals=np.array([[[0, -1, 0], [0, 1, 0]], [[0, 0, -1], [0, 0, 1]]], float),
        faces=np.array([[0, 1], [2, 3]]),
        approach=np.array([[0, 0, -1], [-1, 0, 0]], float),
        overlap_area=np.array([1e-3, 0.0]),
        source=np.array([0, 1], np.int8),
    )
    assert_allclose(pairs.width, [0.04, 0.03])
    assert_allclose(pairs.axis, [[0, 1, 0], [0, 0, 1]])
    assert_allclose(pairs.centre, [[0, 0, 0], [1, 0, 0.015]])
    both = ContactPairs.concatenate([pairs.take([1]), pairs.take(np.array([True, False]))])
    assert_allclose(both.faces, [[2, 3], [0, 1]])
    assert len(ContactPairs.concatenate([])) == 0
