"""The validated, hash-keyed KB cache: a hit gives the KB a full load gives, without
validating again; any edit of a file is seen; a broken edit is an error, never served from an
older entry; an entry is a snapshot (an edit while a process holds it does not leak in)."""

from __future__ import annotations

import pickle
import shutil
from pathlib import Path

import pytest

from handover.engine.errors import KBError
from handover.engine.load import cache as kbcache
from handover.engine.load.cache import LazyObjects, kb_digest, load_kb_cached
from handover.engine.load.loader import load_kb
from handover.engine.store.kb import KIND_ATTRS, builtin_kb_dir


@pytest.fixture
def kb_copy(tmp_path: Path) -> Path:
    root = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    return root


def _no_validation(*_args, **_kwargs):
    raise AssertionError("the KB was validated again")


def test_a_hit_is_the_full_load_without_validating(kb_copy: Path, tmp_path: Path,
                                                   monkeypatch) -> None:
    cache = tmp_path / "cache"
    full = load_kb(kb_copy, urdf=False)
    load_kb_cached(kb_copy, cache)  # the miss: validated and stored
    monkeypatch.setattr("handover.engine.load.loader.load_kb", _no_validation)
    kb = load_kb_cached(kb_copy, cache)
    assert isinstance(kb.objects, LazyObjects)
    assert list(kb.objects) == list(full.objects)
    assert kb.object("knife") == full.object("knife")
    assert {k: v for k, v in kb.objects.items()} == full.objects
    for attr, _ in KIND_ATTRS.values():  # every kind of document, the hazards too
        if attr != "objects":
            assert getattr(kb, attr) == getattr(full, attr), attr
    assert kb.counts() == full.counts() and kb.counts()["hazards"] >= 1
    assert kb.warnings == full.warnings
    mug = kb.object("mug")
    assert kb.locate(mug, "mass") == full.locate(full.object("mug"), "mass")
    assert kb.root == full.root


def test_any_edit_gives_another_digest_and_is_seen(kb_copy: Path, tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    before = kb_digest(kb_copy)
    assert load_kb_cached(kb_copy, cache).object("mug").mass == 0.35
    path = kb_copy / "objects" / "mug.yaml"
    path.write_text(path.read_text().replace("mass: 0.35", "mass: 0.4"))
    assert kb_digest(kb_copy) != before
    assert load_kb_cached(kb_copy, cache).object("mug").mass == 0.4
    (kb_copy / "objects" / "mug.stl").write_bytes(b"solid x\nendsolid x\n")  # a new file
    assert kb_digest(kb_copy) not in (before,)


def test_a_broken_edit_is_an_error_not_the_old_entry(kb_copy: Path, tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    load_kb_cached(kb_copy, cache)
    path = kb_copy / "objects" / "knife.yaml"
    path.write_text(path.read_text().replace("mass:", "mass: -1\nmas:"))
    with pytest.raises(KBError) as err:
        load_kb_cached(kb_copy, cache)
    assert any(i.file == "objects/knife.yaml" and i.line > 0 for i in err.value.issues)
    assert len([p for p in cache.iterdir() if not p.name.startswith(".")]) == 1  # not stored


def test_an_entry_is_a_snapshot(kb_copy: Path, tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    load_kb_cached(kb_copy, cache)
    kb = load_kb_cached(kb_copy, cache)  # no object read yet
    path = kb_copy / "objects" / "pen.yaml"
    mass = kb.object("book").mass
    path.write_text(path.read_text().replace("mass:", "mass: 9.0\nmas:"))  # now invalid
    assert kb.object("pen").mass != 9.0  # the validated pen, not the edit
    assert kb.object("book").mass == mass
    shipped = pickle.loads(pickle.dumps(kb))  # as the service sends it to its workers
    assert shipped.object("pen") == kb.object("pen")


def test_an_unreadable_entry_file_falls_back_to_its_unchanged_yaml(kb_copy: Path,
                                                                   tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    load_kb_cached(kb_copy, cache)
    (entry,) = [p for p in cache.iterdir() if p.is_dir()]
    for f in (entry / "objects").iterdir():
        f.write_bytes(b"not a pickle")
    kb = load_kb_cached(kb_copy, cache)
    assert kb.object("hammer") == load_kb(kb_copy, urdf=False).object("hammer")
    path = kb_copy / "objects" / "tray.yaml"
    path.write_text(path.read_text() + "\n# edited\n")
    with pytest.raises(Exception, match="load the KB again"):
        kb.object("tray")


def test_old_entries_are_pruned(kb_copy: Path, tmp_path: Path, monkeypatch) -> None:
    cache = tmp_path / "cache"
    monkeypatch.setattr(kbcache, "KEEP", 2)
    monkeypatch.setattr(kbcache._prune, "__defaults__", (2,))
    path = kb_copy / "objects" / "ball.yaml"
    for k in range(4):
        path.write_text(path.read_text() + f"\n# edit {k}\n")
        load_kb_cached(kb_copy, cache)
    assert len([p for p in cache.iterdir() if not p.name.startswith(".")]) == 2


def test_a_plan_from_the_cache_is_the_same_bytes(kb_copy: Path, tmp_path: Path,
                                                 arms_off) -> None:
    from handover.engine.planner import plan
    from handover.engine.spec.query import Query

    arms_off(kb_copy)  # a floating gripper: no reachability map to build for this folder
    query = Query(object="screwdriver")
    full = plan(load_kb(kb_copy, urdf=False), query).to_json()
    load_kb_cached(kb_copy, tmp_path / "cache")
    assert plan(load_kb_cached(kb_copy, tmp_path / "cache"), query).to_json() == full


SYRINGE = """\
id: syringe
name: Syringe
mass: 0.02
geometry:
  primitives:
    - {shape: cylinder, part: barrel, radius: 0.008, height: 0.09, position: [0, 0, 0.008],
       rotation_deg: [0, 90, 0]}
    - {shape: cylinder, part: needle, radius: 0.001, height: 0.03, position: [0.06, 0, 0.008],
       rotation_deg: [0, 90, 0]}
parts:
  barrel: {tags: [handle]}
  needle: {tags: [needle]}
axes:
  tip: [1, 0, 0]
"""


def test_the_hazards_a_tag_implies_are_applied_from_the_cache_too(kb_copy: Path,
                                                                   tmp_path: Path,
                                                                   arms_off) -> None:
    """A needle is pointed (kb/hazards: ``needle`` implies ``pointed``): the rules about
    points judge it whether the KB comes from its files or from the cache (the CLI's and the
    service's way), and the plan is the same."""
    from handover.engine.planner import plan
    from handover.engine.spec.query import Query

    arms_off(kb_copy)
    (kb_copy / "objects" / "syringe.yaml").write_text(SYRINGE)
    full = plan(load_kb(kb_copy, urdf=False), Query(object="syringe")).to_dict()
    load_kb_cached(kb_copy, tmp_path / "cache")
    cached = plan(load_kb_cached(kb_copy, tmp_path / "cache"), Query(object="syringe"))
    assert cached.to_dict() == full
    implied = [why for tag, why in cached.context.facts.derived if tag == "pointed"]
    assert implied, cached.context.facts.derived


def test_a_misspelt_tag_is_warned_about_where_the_object_is_planned(kb_copy: Path,
                                                                    tmp_path: Path,
                                                                    arms_off) -> None:
    """A blade tagged ``sharpp``: no rule about sharp parts reads it. ``kb validate`` warns;
    so does the plan of that object (file:line:col), from the files and from the cache."""
    from handover.engine.planner import plan
    from handover.engine.spec.query import Query

    arms_off(kb_copy)
    text = SYRINGE.replace("id: syringe", "id: cutter").replace("[needle]", "[blade, sharpp]")
    (kb_copy / "objects" / "cutter.yaml").write_text(text)
    line = text.splitlines().index("  needle: {tags: [blade, sharpp]}") + 1
    want = f"objects/cutter.yaml:{line}:"
    for kb in (load_kb(kb_copy, urdf=False), load_kb_cached(kb_copy, tmp_path / "cache"),
               load_kb_cached(kb_copy, tmp_path / "cache")):
        warned = [w for w in plan(kb, Query(object="cutter")).result.warnings if "sharpp" in w]
        assert len(warned) == 1 and warned[0].startswith(want), warned
    # another object's plan does not carry it
    assert not [w for w in plan(kb, Query(object="pen")).result.warnings if "sharpp" in w]
