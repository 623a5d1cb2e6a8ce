"""The grasp database: exact round trips, content keys, atomic writes, rebuilt bad entries."""

from __future__ import annotations

import os

import numpy as np
import pyarrow.parquet as pq
import pytest

from handover.engine.assets import graspdb
from handover.engine.assets.graspdb import (
    EntryError,
    GraspDB,
    cached_candidates,
    candidate_key,
    open_db,
)
from handover.geometry.candidates import SOURCE_ANTIPODAL, SOURCE_FACET, CandidateSet
from handover.geometry.gripper import Gripper


def _unit(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def random_set(n: int = 7, seed: int = 1) -> CandidateSet:
    """A candidate set with arbitrary (not geometric) values in every array and a mix of
    dtypes, including int32 faces: the database must give back exactly what it was given."""
    rng = np.random.default_rng(seed)
    return CandidateSet(
        centre=rng.normal(size=(n, 3)),
        n=_unit(rng, n),
        o=_unit(rng, n),
        a=_unit(rng, n),
        width=rng.uniform(0, 0.08, n),
        contacts=rng.normal(size=(n, 2, 3)),
        normals=rng.normal(size=(n, 2, 3)),
        faces=rng.integers(0, 2**31 - 1, size=(n, 2)).astype(np.int32),
        parts=rng.integers(0, 3, size=(n, 2)),
        site=np.arange(n, dtype=np.int64) // 2,
        roll=rng.uniform(-np.pi, np.pi, n),
        overlap_area=np.where(np.arange(n) % 2 == 0, 1e-4, 0.0),
        source=np.where(np.arange(n) % 2 == 0, SOURCE_FACET, SOURCE_ANTIPODAL).astype(np.int8),
        offset=rng.uniform(0, 0.01, n),
        quality=rng.uniform(0, 1, n),
        com_distance=np.full(n, np.pi * 1e-3),
        part_names=["handle", "blade", "tip"],
    )


def assert_same(a: CandidateSet, b: CandidateSet) -> None:
    assert a.part_names == b.part_names
    for name in CandidateSet.ARRAY_FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype, name
        assert x.shape == y.shape, name
        np.testing.assert_array_equal(x, y, err_msg=name)


KEY = "0" * 64


def test_round_trip_is_exact(tmp_path):
    db = GraspDB(tmp_path)
    cands = random_set()
    stats = {"facet_pairs": 3, "sources": {"facet": 4, "antipodal": 3}, "ratio": 0.1 + 0.2}
    db.store(KEY, cands, stats)
    loaded, loaded_stats = db.load(KEY)
    assert_same(cands, loaded)
    assert loaded_stats == stats


def test_empty_set_keeps_trailing_shapes(tmp_path):
    db = GraspDB(tmp_path)
    db.store(KEY, CandidateSet.empty(["body"]), {})
    loaded, _ = db.load(KEY)
    assert len(loaded) == 0
    assert loaded.contacts.shape == (0, 2, 3)
    assert loaded.faces.shape == (0, 2)
    assert loaded.part_names == ["body"]


def test_entry_is_plain_parquet_with_named_columns(tmp_path):
    cands = random_set()
    path = GraspDB(tmp_path).store(KEY, cands, {})
    table = pq.read_table(path)
    assert table.num_rows == len(cands)
    np.testing.assert_array_equal(table.column("centre_y").to_numpy(), cands.centre[:, 1])
    np.testing.assert_array_equal(table.column("contacts_1_z").to_numpy(), cands.contacts[:, 1, 2])
    np.testing.assert_array_equal(table.column("parts_0").to_numpy(), cands.parts[:, 0])
    assert "width" in table.column_names


def test_column_names():
    assert graspdb.column_names("width", ()) == ["width"]
    assert graspdb.column_names("centre", (3,)) == ["centre_x", "centre_y", "centre_z"]
    assert graspdb.column_names("faces", (2,)) == ["faces_0", "faces_1"]
    assert graspdb.column_names("contacts", (2, 3))[3:] == [
        "contacts_1_x", "contacts_1_y", "contacts_1_z"
    ]  # fmt: skip


def test_missing_entry_is_none(tmp_path):
    db = GraspDB(tmp_path / "nowhere")
    assert db.load(KEY) is None
    assert db.lookup(KEY) is None
    assert db.counts["miss"] == 1
    assert db.keys() == []


def test_store_leaves_no_temporary_file(tmp_path):
    db = GraspDB(tmp_path)
    db.store(KEY, random_set(), {})
    assert sorted(os.listdir(tmp_path)) == [f"{KEY}.parquet"]
    assert db.keys() == [KEY]


def test_crash_during_write_keeps_old_entry(tmp_path, monkeypatch):
    db = GraspDB(tmp_path)
    old = random_set(seed=1)
    db.store(KEY, old, {})

    def crash(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(graspdb.os, "replace", crash)
    with pytest.raises(OSError):
        db.store(KEY, random_set(seed=2), {})
    monkeypatch.undo()
    assert sorted(os.listdir(tmp_path)) == [f"{KEY}.parquet"]
    assert_same(db.load(KEY)[0], old)


def _corrupt_truncated(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _corrupt_garbage(path):
    path.write_bytes(b"\x00garbage, not parquet" * 10)


def _corrupt_empty(path):
    path.write_bytes(b"")


def _corrupt_wrong_schema(path):
    """Same metadata, one column dropped."""
    table = pq.read_table(path)
    pq.write_table(table.drop_columns(["width"]), path)


def _corrupt_wrong_type(path):
    """Same metadata, a float column stored as float32."""
    import pyarrow as pa

    table = pq.read_table(path)
    i = table.column_names.index("quality")
    table = table.set_column(i, "quality", table.column("quality").cast(pa.float32()))
    pq.write_table(table, path)


def _corrupt_value(path):
    """Valid Parquet, valid metadata, one value changed: the data digest no longer matches."""
    import pyarrow as pa

    table = pq.read_table(path)
    i = table.column_names.index("width")
    width = table.column("width").to_numpy().copy()
    width[0] += 0.001
    pq.write_table(table.set_column(i, "width", pa.array(width)), path)


def _no_metadata(path):
    table = pq.read_table(path)
    pq.write_table(table.replace_schema_metadata({}), path)


CORRUPTIONS = [
    _corrupt_truncated, _corrupt_garbage, _corrupt_empty, _corrupt_wrong_schema,
    _corrupt_wrong_type, _corrupt_value, _no_metadata,
]  # fmt: skip


@pytest.mark.parametrize("corrupt", CORRUPTIONS, ids=lambda f: f.__name__.strip("_"))
def test_corrupted_entry_is_detected(tmp_path, corrupt):
    db = GraspDB(tmp_path)
    path = db.store(KEY, random_set(), {})
    corrupt(path)
    with pytest.raises(EntryError):
        db.load(KEY)
    assert db.lookup(KEY) is None
    assert db.counts["unusable"] == 1 and db.last_problem


def test_entry_under_another_key_is_rejected(tmp_path):
    db = GraspDB(tmp_path)
    path = db.store(KEY, random_set(), {})
    other = "1" * 64
    path.rename(db.path(other))
    with pytest.raises(EntryError, match="key"):
        db.load(other)


def test_entry_of_another_generator_is_stale(tmp_path, monkeypatch):
    db = GraspDB(tmp_path)
    db.store(KEY, random_set(), {})
    monkeypatch.setattr(graspdb, "generator_fingerprint", lambda: "another version")
    with pytest.raises(EntryError, match="stale"):
        db.load(KEY)


# ---------------------------------------------------------------- keys and folders


def _part_mesh(extents=(0.2, 0.04, 0.03), names=("body",)):
    from handover.geometry.mesh import PartMesh, box

    mesh = box(np.array(extents))
    face_part = np.zeros(len(mesh.faces), dtype=np.int64)
    if len(names) > 1:
        face_part[len(face_part) // 2 :] = 1
    from handover.geometry.mesh import mass_centre

    return PartMesh(mesh, face_part, list(names), mass_centre(mesh))


def test_key_depends_on_mesh_parts_gripper_and_settings():
    g = Gripper.default()
    base = candidate_key(_part_mesh(), g, {"seed": 0})
    assert base == candidate_key(_part_mesh(), g, {"seed": 0})  # same content, same key
    assert len(base) == 64
    others = [
        candidate_key(_part_mesh(extents=(0.2, 0.04, 0.031)), g, {"seed": 0}),
        candidate_key(_part_mesh(names=("a", "b")), g, {"seed": 0}),
        candidate_key(_part_mesh(), Gripper(**{**vars(g), "max_opening": 0.1}), {"seed": 0}),
        candidate_key(_part_mesh(), g, {"seed": 1}),
    ]
    assert len({base, *others}) == 5


def test_open_db_order(tmp_path, monkeypatch):
    monkeypatch.delenv(graspdb.ENV_VAR, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert open_db(disabled=True) is None
    assert open_db().root == tmp_path / "cache" / "handover-grasp" / "grasps"
    monkeypatch.setenv(graspdb.ENV_VAR, str(tmp_path / "env"))
    assert open_db().root == tmp_path / "env"
    assert open_db(tmp_path / "given").root == tmp_path / "given"
    assert open_db(tmp_path / "given", disabled=True) is None


def test_plain_stats_are_json_data():
    stats = graspdb.plain_stats({"n": np.int64(3), "w": np.float64(0.25), "v": np.arange(2)})
    assert stats == {"n": 3, "w": 0.25, "v": [0, 1]}
    assert type(stats["n"]) is int


# ---------------------------------------------------------------- with the real generator


@pytest.fixture()
def generator():
    return pytest.importorskip("handover.geometry.generate")


def test_cached_candidates_generates_once_then_reads(tmp_path, generator):
    pm, g = _part_mesh(), Gripper.default()
    direct, direct_stats = cached_candidates(pm, g, {"seed": 0}, None)
    assert len(direct) > 0  # a 4 cm x 3 cm bar fits the 85 mm gripper
    db = GraspDB(tmp_path)
    first, first_stats = cached_candidates(pm, g, {"seed": 0}, db)
    assert db.counts["miss"] == 1 and db.counts["stored"] == 1
    second, second_stats = cached_candidates(pm, g, {"seed": 0}, db)
    assert db.counts["hit"] == 1 and db.counts["stored"] == 1
    assert_same(direct, first)
    assert_same(direct, second)
    assert direct_stats == first_stats == second_stats


def test_collision_filtered_candidates_have_their_own_entry(tmp_path, generator):
    from handover.geometry.collision import ObjectCollider

    pm, g = _part_mesh(), Gripper.default()
    collider = ObjectCollider(pm.mesh)
    db = GraspDB(tmp_path)
    plain, _ = cached_candidates(pm, g, {"seed": 0}, db)
    filtered, stats = cached_candidates(pm, g, {"seed": 0}, db, collider=collider)
    assert db.counts["stored"] == 2 and db.counts["hit"] == 0
    assert len(db.keys()) == 2
    assert stats["collision_checked"] is True
    assert len(filtered) <= len(plain)
    again, _ = cached_candidates(pm, g, {"seed": 0}, db, collider=collider)
    assert db.counts["hit"] == 1
    assert_same(filtered, again)


def test_stats_hold_no_timings(tmp_path, generator):
    _, stats = cached_candidates(_part_mesh(), Gripper.default(), {"seed": 0}, None)
    assert stats["faces"] == 12
    assert not any(name in stats for name in graspdb.TIMING_STATS)


@pytest.mark.parametrize("corrupt", CORRUPTIONS, ids=lambda f: f.__name__.strip("_"))
def test_corrupted_entry_is_rebuilt(tmp_path, generator, corrupt):
    pm, g = _part_mesh(), Gripper.default()
    db = GraspDB(tmp_path)
    good, _ = cached_candidates(pm, g, {"seed": 0}, db)
    key = graspdb.key_for(pm, g, {"seed": 0})
    corrupt(db.path(key))
    rebuilt, _ = cached_candidates(pm, g, {"seed": 0}, db)
    assert db.counts["rebuilt"] == 1
    assert_same(good, rebuilt)
    assert_same(good, db.load(key)[0])  # the file on disk is whole again


def test_unwritable_database_only_warns(tmp_path, generator):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    db = GraspDB(blocker / "db")
    with pytest.warns(UserWarning, match="cannot write"):
        cands, _ = cached_candidates(_part_mesh(), Gripper.default(), {"seed": 0}, db)
    assert len(cands) > 0
