"""Batch planning: objects and queries expanded, broken meshes reported, the same rows on
every backend (in-process, local pool, Ray), resume."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from handover.engine.errors import UsageError
from handover.engine.load.loader import load_kb
from handover.engine.tools import batch

GOOD = ("bar.stl", "can.stl", "ball.ply")
BROKEN = ("empty.stl", "garbage.obj", "flat.stl")


def _write_meshes(folder: Path) -> Path:
    import trimesh

    folder.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box(extents=(0.12, 0.04, 0.03)).export(folder / "bar.stl")
    trimesh.creation.cylinder(radius=0.02, height=0.1, sections=16).export(folder / "can.stl")
    trimesh.creation.icosphere(subdivisions=1, radius=0.03).export(folder / "ball.ply")
    (folder / "empty.stl").write_bytes(b"")
    (folder / "garbage.obj").write_bytes(bytes(range(256)) * 3)
    flat = trimesh.Trimesh(  # every face degenerate: three vertices on one line
        vertices=[[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [0.3, 0, 0]],
        faces=[[0, 1, 2], [1, 2, 3]],
        process=False,
    )
    flat.export(folder / "flat.stl")
    (folder / "notes.txt").write_text("not a mesh: ignored")
    return folder


@pytest.fixture(scope="module")
def kb():
    return load_kb()


@pytest.fixture()
def meshes(tmp_path):
    return _write_meshes(tmp_path / "meshes")


def _by_file(rows: list[dict]) -> dict[str, list[dict]]:
    out: dict[str, list[dict]] = {}
    for r in rows:
        out.setdefault(Path(r["object"]).name, []).append(r)
    return out


# ---------------------------------------------------------------- what to plan


def test_folder_lists_its_mesh_files_sorted(kb, meshes):
    refs = batch.resolve_objects(str(meshes), kb)
    assert [Path(r.name).name for r in refs] == sorted(GOOD + BROKEN)
    assert all(r.kind == "mesh" and r.query_object == r.name for r in refs)


def test_glob_comma_list_and_kb(kb, meshes):
    refs = batch.resolve_objects(str(meshes / "*.stl"), kb)
    assert sorted(Path(r.name).name for r in refs) == ["bar.stl", "can.stl", "empty.stl",
                                                       "flat.stl"]  # fmt: skip
    ids = sorted(kb.objects)
    assert [r.name for r in batch.resolve_objects("kb", kb)] == ids
    refs = batch.resolve_objects(f"{ids[0]}, {meshes / 'bar.stl'}", kb)
    assert [r.kind for r in refs] == ["kb", "mesh"]
    with pytest.raises(UsageError, match="unknown object"):
        batch.resolve_objects("no_such_object", kb)
    with pytest.raises(UsageError, match="does not exist"):
        batch.resolve_objects(str(meshes / "missing.stl"), kb)
    with pytest.raises(UsageError, match="no file"):
        batch.resolve_objects(str(meshes / "*.glb"), kb)


def test_queries_are_the_product_of_the_lists(kb):
    obj = next(o for o in sorted(kb.objects) if len(kb.objects[o].tasks) >= 2)
    cultures = sorted(kb.cultures)[:2]
    units = batch.expand(kb, obj, [",".join(cultures)], ["adult", "child"], ["all"])
    (unit,) = units
    tasks = sorted(kb.objects[obj].tasks)
    assert len(unit.queries) == len(cultures) * 2 * len(tasks)
    assert {(q.culture, q.receiver, q.task) for q in unit.queries} == {
        (c, r, t) for c in cultures for r in ("adult", "child") for t in tasks
    }
    (default,) = batch.expand(kb, obj)
    assert [(q.culture, q.receiver, q.task) for q in default.queries] == [
        ("common", "adult", kb.objects[obj].default_task)
    ]
    with pytest.raises(UsageError, match="unknown culture"):
        batch.expand(kb, obj, ["martian"])
    with pytest.raises(UsageError, match="unknown receiver"):
        batch.expand(kb, obj, receivers=["robot"])
    with pytest.raises(UsageError, match="no object of this batch has task fly"):
        batch.expand(kb, obj, tasks=[f"{tasks[0]},fly"])
    (only,) = batch.expand(kb, obj, tasks=[tasks[0]])
    assert [q.task for q in only.queries] == [tasks[0]]


def test_content_hash_follows_the_mesh_bytes(kb, meshes):
    before = {u.obj.name: u.content_hash for u in batch.expand(kb, str(meshes))}
    import trimesh

    trimesh.creation.box(extents=(0.12, 0.04, 0.035)).export(meshes / "bar.stl")
    after = {u.obj.name: u.content_hash for u in batch.expand(kb, str(meshes))}
    changed = {Path(n).name for n in before if before[n] != after[n]}
    assert changed == {"bar.stl"}


# ---------------------------------------------------------------- running


def _run(kb, units, out, **kwargs):
    return batch.run_batch(kb, units, out, db_root=kwargs.pop("db_root", None), **kwargs)


def test_broken_meshes_are_reported_and_do_not_stop_the_batch(kb, meshes, tmp_path):
    units = batch.expand(kb, str(meshes))
    report = _run(kb, units, tmp_path / "out.parquet", workers=2,
                  db_root=tmp_path / "db")  # fmt: skip
    rows = _by_file(report.rows)
    assert sorted(rows) == sorted(GOOD + BROKEN)
    for name in BROKEN:
        (row,) = rows[name]
        assert row["error"].startswith("MeshError: ") and name in row["error"]
        assert row["feasible"] is None and row["mode"] is None
    assert "no area" in rows["flat.stl"][0]["error"]
    for name in GOOD:
        (row,) = rows[name]
        assert row["error"] is None
        assert row["feasible"] in (True, False)
        assert row["candidates"] > 0  # every good shape fits the 85 mm gripper somewhere
        grasps = json.loads(row["grasps"])
        if row["feasible"]:
            assert row["mode"] in ("H1G1", "H2G2", "H2G1") and row["reason"] is None
            assert grasps and grasps[0]["score"] == row["score"]
            assert np.asarray(grasps[0]["pose"]).shape == (4, 4)
        else:
            assert row["reason"] and grasps == []
    assert [batch.row_key(r) for r in report.rows] == sorted(batch.row_key(r)
                                                            for r in report.rows)  # fmt: skip
    assert batch.read_rows(tmp_path / "out.parquet") == report.rows


def test_pool_and_inline_give_the_same_rows(kb, meshes, tmp_path):
    units = batch.expand(kb, str(meshes), receivers=["adult,child"])
    inline = _run(kb, units, tmp_path / "a.parquet", workers=1)
    pool = _run(kb, units, tmp_path / "b.parquet", workers=2)
    assert (inline.backend, pool.backend) == ("inline", "pool")
    assert inline.rows == pool.rows
    assert len(pool.rows) == 2 * len(GOOD + BROKEN)
    assert (tmp_path / "a.parquet").read_bytes() == (tmp_path / "b.parquet").read_bytes()


def test_resume_skips_finished_rows(kb, meshes, tmp_path):
    out = tmp_path / "out.parquet"
    units = batch.expand(kb, str(meshes))
    first = _run(kb, units, out, workers=1)
    assert first.skipped == 0 and len(first.planned) == len(GOOD + BROKEN)
    second = _run(kb, units, out, workers=1)
    # finished rows are kept; rows with an error are tried again
    assert second.skipped == len(GOOD)
    assert sorted(Path(r["object"]).name for r in second.planned) == sorted(BROKEN)
    assert second.rows == first.rows
    # a new receiver adds rows, the old ones stay
    more = batch.expand(kb, str(meshes), receivers=["adult,child"])
    third = _run(kb, more, out, workers=1)
    assert third.skipped == len(GOOD)
    assert len(third.rows) == 2 * len(GOOD + BROKEN)
    # a changed mesh is planned again, under the same key, with its new content hash
    import trimesh

    trimesh.creation.box(extents=(0.1, 0.05, 0.03)).export(meshes / "bar.stl")
    fourth = _run(kb, batch.expand(kb, str(meshes)), out, workers=1)
    replanned = {Path(r["object"]).name for r in fourth.planned}
    assert replanned == {"bar.stl", *BROKEN}
    assert len(fourth.rows) == len(third.rows)


def _crash_once(marker: Path, victim: str):
    """A run_unit that kills its process the first time it sees ``victim`` (forked pool
    processes inherit the patched module)."""
    real = batch.run_unit

    def run_unit(unit, kb_dir, db_root):
        if Path(unit.obj.name).name == victim and not marker.exists():
            marker.write_text("crashed")
            os._exit(3)
        return real(unit, kb_dir, db_root)

    return run_unit


def test_a_crashed_worker_is_retried(kb, meshes, tmp_path, monkeypatch):
    units = batch.expand(kb, str(meshes))
    clean = _run(kb, units, tmp_path / "clean.parquet", workers=1)
    monkeypatch.setattr(batch, "run_unit", _crash_once(tmp_path / "marker", "can.stl"))
    retried = _run(kb, units, tmp_path / "retried.parquet", workers=2, max_retries=1)
    assert (tmp_path / "marker").exists()
    assert retried.rows == clean.rows


def test_a_unit_that_keeps_crashing_is_reported(kb, meshes, tmp_path, monkeypatch):
    units = batch.expand(kb, str(meshes))
    monkeypatch.setattr(batch, "run_unit", _crash_once(tmp_path / "marker", "can.stl"))
    report = _run(kb, units, tmp_path / "out.parquet", workers=2, max_retries=0)
    rows = _by_file(report.rows)
    assert rows["can.stl"][0]["error"].startswith("WorkerCrashed: ")
    assert "exit code 3" in rows["can.stl"][0]["error"]
    assert all(rows[name][0]["error"] is None for name in GOOD if name != "can.stl")


def test_out_that_is_not_a_batch_output_is_refused(kb, tmp_path):
    bad = tmp_path / "out.parquet"
    bad.write_bytes(b"not parquet")
    with pytest.raises(UsageError, match="cannot be read"):
        _run(kb, batch.expand(kb, sorted(kb.objects)[0]), bad, workers=1)


def test_batch_fills_the_grasp_database(kb, meshes, tmp_path):
    from handover.engine.assets.graspdb import GraspDB

    db = tmp_path / "db"
    units = batch.expand(kb, str(meshes), receivers=["adult,child"])
    first = _run(kb, units, tmp_path / "a.parquet", workers=2, db_root=db)
    assert len(GraspDB(db).keys()) == len(GOOD)  # one entry per good mesh, shared by queries
    warm = _run(kb, units, tmp_path / "b.parquet", workers=2, db_root=db)
    assert warm.rows == first.rows


def test_ray_missing_is_a_clear_error(kb, tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    units = batch.expand(kb, sorted(kb.objects)[0])
    with pytest.raises(UsageError, match=r"pip install 'handover-grasp\[ray\]'"):
        _run(kb, units, tmp_path / "out.parquet", ray_address="local")


def test_cli_batch(meshes, tmp_path, monkeypatch):
    from handover.engine.assets.graspdb import GraspDB
    from handover.engine.cli.app import main

    out = tmp_path / "out.parquet"
    args = ["batch", "--objects", str(meshes), "--out", str(out), "--workers", "2",
            "--db", str(tmp_path / "db"), "--no-progress"]  # fmt: skip
    assert main(args) == 0
    rows = batch.read_rows(out)
    assert len(rows) == len(GOOD + BROKEN)
    assert sum(1 for r in rows if r["error"]) == len(BROKEN)
    assert len(GraspDB(tmp_path / "db").keys()) == len(GOOD)
    assert main([*args[:-1], "--no-db", "--no-progress"]) == 0
    monkeypatch.setenv("HANDOVER_DB", str(tmp_path / "env_db"))
    out2 = str(tmp_path / "out2.parquet")
    assert main(["batch", "--objects", str(meshes), "--out", out2, "--no-progress"]) == 0
    assert len(GraspDB(tmp_path / "env_db").keys()) == len(GOOD)
    assert main(["batch", "--objects", "kb", "--out", str(out), "--cultures", "martian"]) == 2


def test_cli_batch_mesh_scale_reads_millimetres_and_is_part_of_the_work(tmp_path):
    import trimesh

    from handover.engine.cli.app import main

    folder = tmp_path / "mm"
    folder.mkdir()
    trimesh.creation.cylinder(radius=33, height=120, sections=48).export(folder / "can.stl")
    out = tmp_path / "out.parquet"
    args = ["batch", "--objects", str(folder), "--out", str(out), "--workers", "1", "--no-db",
            "--no-progress"]  # fmt: skip
    assert main(args) == 0
    (as_metres,) = batch.read_rows(out)
    assert as_metres["feasible"] is False
    assert any("--mesh-scale 0.001" in w for w in json.loads(as_metres["warnings"]))
    # Another scale is other work: not skipped as finished, planned again.
    assert main([*args, "--mesh-scale", "0.001"]) == 0
    (scaled,) = batch.read_rows(out)
    assert scaled["feasible"] is True and scaled["mode"] == "H1G1"
    assert scaled["content_hash"] != as_metres["content_hash"]
    assert main([*args, "--mesh-scale", "-2"]) == 2


# ---------------------------------------------------------------- Ray


@pytest.fixture(scope="module")
def local_ray():
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_ray_gives_the_same_rows_as_the_local_pool(kb, local_ray, tmp_path):
    folder = _write_meshes(tmp_path / "meshes")
    shutil.copy(folder / "bar.stl", folder / "bar_copy.stl")
    units = batch.expand(kb, str(folder), receivers=["adult,child"])
    pool = _run(kb, units, tmp_path / "pool.parquet", workers=2, db_root=tmp_path / "db1")
    on_ray = _run(kb, units, tmp_path / "ray.parquet", ray_address="auto",
                  db_root=tmp_path / "db2")  # fmt: skip
    assert on_ray.backend == "ray"
    assert on_ray.rows == pool.rows
    assert sum(1 for r in on_ray.rows if r["error"]) == 2 * len(BROKEN)
    assert (tmp_path / "pool.parquet").read_bytes() == (tmp_path / "ray.parquet").read_bytes()
    assert os.path.getsize(tmp_path / "ray.parquet") > 0


def test_each_row_says_which_rules_applied_rejected_and_decided(kb, tmp_path):
    units = batch.expand(kb, "mug", cultures=["common,korean"], receivers=["adult,elder"])
    report = _run(kb, units, tmp_path / "rules.parquet", workers=1, db_root=tmp_path / "db")
    assert len(report.rows) == 4
    summary = batch.rule_summary(report.rows)
    # Two hands for elders is Korean etiquette: it applies to the Korean elder alone and
    # decides that plan (H2G1); one hand is preferred, and decides, everywhere else.
    assert summary["two_hands_for_elders"] == {"applied": 1, "rejected": 0, "decided": 1}
    assert summary["prefer_one_hand"]["decided"] == 3
    korean_elder = next(r for r in report.rows
                        if (r["culture"], r["receiver"]) == ("korean", "elder"))
    use = json.loads(korean_elder["rules"])
    assert "two_hands_for_elders" in use["applied"] and korean_elder["mode"] == "H2G1"
    assert batch.read_rows(tmp_path / "rules.parquet") == report.rows


def test_a_file_written_before_the_outcome_column_reads_it_from_feasible(tmp_path):
    """Rows of an older batch file (no ``outcome`` or ``rules`` column) are kept on resume:
    their outcome is read from ``feasible`` (then only handover or infeasible), a failed
    query's stays null."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    old = [c for c in batch.COLUMNS if c not in ("outcome", "rules")]
    rows = [{c: None for c in old} | {"object": o, "culture": "common", "receiver": "adult",
                                      "scene": "table", "query_mode": "auto", "feasible": f,
                                      "warnings": "[]", "content_hash": "x"}
            for o, f in (("a", True), ("b", False), ("c", None))]
    path = tmp_path / "old.parquet"
    pq.write_table(pa.Table.from_pylist(rows), path)
    got = {r["object"]: r["outcome"] for r in batch.read_rows(path)}
    assert got == {"a": "handover", "b": "infeasible", "c": None}


def test_physics_columns_say_whether_the_chosen_grasps_hold(kb, tmp_path):
    out = tmp_path / "physics.parquet"
    plain = _run(kb, batch.expand(kb, "knife"), out, workers=1, db_root=tmp_path / "db")
    assert plain.rows[0]["physics_passed"] is None  # not asked: not checked
    # asked on the same file: the handover planned without the check is planned again
    checked = _run(kb, batch.expand(kb, "knife", physics=True), out, workers=1,
                   db_root=tmp_path / "db")
    assert checked.skipped == 0 and len(checked.rows) == 1
    row = checked.rows[0]
    assert row["outcome"] == "handover" and row["physics_passed"] is True
    assert 0.0 <= row["physics_mm"] < 5.0 and 0.0 <= row["physics_margin"] <= 1.0
    assert batch.read_rows(out) == checked.rows
