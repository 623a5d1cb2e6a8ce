"""The documentation's examples are tested: README.md and docs/*.md.

Every ``python`` block runs as a doctest (a page's blocks in order, sharing their names).
Every ``yaml`` block that is a whole KB document, one starting with a modeline
(``# yaml-language-server: $schema=../schema/KIND.json``) or a ``# folder/file.yaml``
comment, is written into a copy of the built-in KB and validated with ``handover kb
validate``; every other ``yaml`` block is marked ``<!-- example: NAME -->`` and read by the
test that checks it (:data:`MARKED`). Links between the pages resolve. The facade's
docstrings run as doctests too.
"""

from __future__ import annotations

import doctest
import json
import re
import shutil
from importlib.resources import files
from pathlib import Path

import pytest
import yaml

import handover
import handover.engine.assets.lru
import handover.engine.plan.records
import handover.engine.planner
import handover.engine.spec.applies
from handover.engine.cli.app import main

ROOT = Path(__file__).resolve().parents[1]
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))
PYTHON_PAGES = [p for p in PAGES if "\n```python\n" in p.read_text(encoding="utf-8")]

# The marked YAML blocks and the test that reads each (every marked block is one of these).
MARKED = {
    "service-curl": "tests/engine/test_service.py: each request is answered by the service",
    "service-python": "tests/engine/test_service.py: runs against the service",
    "shipped-robot": "tests/engine/test_robot.py: it is robots/idro.yaml",
    "own-robot": "tests/engine/test_user_robot.py: planned beside the URDF the test writes",
    "korean-bends": "here: it is the rule of etiquette/korean.yaml",
    "gripper-meshes": "here: the built-in gripper with it and two mesh files validates",
    "gripper-corridors": "tests/engine/test_corridors.py: the built-in gripper's corridors",
}
MODELINE = re.compile(r"^# yaml-language-server: \$schema=\.\./schema/(?P<kind>\w+)\.json$")
PATH_COMMENT = re.compile(r"^# (?P<path>\w+/[\w.-]+\.yaml)$")
FOLDERS = ("objects", "etiquette", "receivers", "grippers", "hands", "robots", "scenes", "tests",
           "hazards")
TWO_COMMANDS = (
    "python3.11 -m venv .venv && . .venv/bin/activate && pip install . "
    "&& handover plan knife --explain\n",
    "python3.11 -m venv .venv && . .venv/bin/activate && pip install -e '.[test]' && pytest\n",
)


def _run_doctest(text: str, name: str, filename: str) -> None:
    parser = doctest.DocTestParser()
    test = parser.get_doctest(text, {}, name, filename, 0)
    assert test.examples, f"{name}: no examples"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    assert runner.failures == 0, f"{name}: {runner.failures} example(s) failed (see output)"


def kb_documents(text: str) -> list[tuple[str, str]] | None:
    """``[(path in the KB, document text)]`` of a YAML block that is whole KB documents (each
    ``---``-separated document with a modeline or a path comment first), else None."""
    out = []
    for doc in re.split(r"^---\n", text, flags=re.M):
        first = doc.split("\n", 1)[0]
        mode, path = MODELINE.match(first), PATH_COMMENT.match(first)
        if mode is None and path is None:
            return None
        if path is not None:
            out.append((path["path"], doc))
        else:
            out.append((f"{mode['kind']}/{yaml.safe_load(doc)['id']}.yaml", doc))
    return out


def validate(root: Path, capsys) -> tuple[int, dict]:
    """``handover --kb ROOT kb validate --json``: exit code and the report."""
    code = main(["--kb", str(root), "kb", "validate", "--json"])
    out, _ = capsys.readouterr()
    return code, json.loads(out)


@pytest.fixture
def kb_copy(tmp_path: Path) -> Path:
    """A copy of the built-in KB to write the documentation's documents into."""
    root = tmp_path / "kb"
    shutil.copytree(Path(str(files("handover.kb"))), root,
                    ignore=shutil.ignore_patterns("schema", "__*"))
    return root


# ---------------------------------------------------------------- the helper


def test_a_block_is_found_by_its_marker_whatever_its_heading(docs, tmp_path):
    page = tmp_path / "page.md"
    page.write_text("# Title\n\n```sh\nls\n```\n\n## Any heading\n\n"
                    "<!-- example: robot -->\n\n```yaml\nid: r\nname: R\n```\n\n"
                    "<!-- example: other -->\ntext between\n```python\n>>> 1\n1\n```\n",
                    encoding="utf-8")
    found = type(docs)(pages=(page,))
    block = found.example("robot")
    assert (block.lang, block.text, block.line) == ("yaml", "id: r\nname: R\n", 11)
    assert [(b.lang, b.example) for b in found.blocks()] == [
        ("sh", None), ("yaml", "robot"), ("python", None)]  # a marker must be just before
    with pytest.raises(LookupError, match="other"):
        found.example("other")
    page.write_text("<!-- example: twice -->\n```yaml\na: 1\n```\n"
                    "<!-- example: twice -->\n```yaml\na: 2\n```\n", encoding="utf-8")
    with pytest.raises(ValueError, match="more than once"):
        found.example("twice")
    page.write_text("```yaml\na: 1\n", encoding="utf-8")
    with pytest.raises(ValueError, match="never closed"):
        found.blocks()


# ---------------------------------------------------------------- the pages


def test_the_readme_starts_with_the_two_commands_and_is_short(docs):
    first, second = docs.blocks()[:2]
    assert first.page.name == "README.md" and second.page.name == "README.md"
    assert (first.lang, first.text) == ("sh", TWO_COMMANDS[0])
    assert (second.lang, second.text) == ("sh", TWO_COMMANDS[1])
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert text.count("\n") <= 250
    # nothing but a title comes before the two commands
    assert [s for s in text[: text.index("```")].splitlines() if s.strip()] == [
        text.splitlines()[0]]


def test_the_ci_script_runs_the_readme_s_test_command():
    script = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert TWO_COMMANDS[1].strip() in script


@pytest.mark.parametrize("page", PYTHON_PAGES, ids=lambda p: p.name)
def test_every_python_block_runs_as_a_doctest(docs, page):
    blocks = [b for b in docs.blocks("python") if b.page == page]
    assert blocks, f"{page.name}: no python block found"
    _run_doctest("\n".join(b.text for b in blocks), f"{page.name} python blocks", str(page))


def test_the_readme_shows_python_and_the_json_page_checks_its_fields(docs):
    pages = {b.page.name for b in docs.blocks("python")}
    assert {"README.md", "json.md"} <= pages


def write_documents(docs, root: Path) -> dict[str, str]:
    """Write every unmarked YAML block of the pages into the KB folder ``root``; returns
    ``{path in the KB: page:line of its block}``. A block that is not whole KB documents,
    or a document that would replace a built-in file or another page's, fails the test."""
    written: dict[str, str] = {}
    for block in docs.blocks("yaml"):
        if block.example is not None:
            continue
        documents = kb_documents(block.text)
        assert documents is not None, (
            f"{block.where}: a YAML block must be whole KB documents (a modeline or a "
            "'# folder/file.yaml' comment first) or be marked <!-- example: NAME --> and "
            "read by a test")
        for path, text in documents:
            assert path.split("/")[0] in FOLDERS, f"{block.where}: {path} is in no KB folder"
            assert path not in written, f"{block.where}: {path} is also {written[path]}"
            assert not (root / path).exists(), f"{block.where}: {path} is a built-in file"
            (root / path).write_text(text, encoding="utf-8")
            written[path] = block.where
    return written


def test_every_kb_document_in_the_docs_validates(docs, kb_copy, capsys):
    written = write_documents(docs, kb_copy)
    # what the pages show of each kind (what was tested before they were split, and more)
    assert {p.split("/")[0] for p in written} >= {"objects", "etiquette", "receivers", "tests"}
    code, report = validate(kb_copy, capsys)
    errors = [f"{written.get(e['file'], e['file'])}: {e['file']}:{e['line']}:{e['col']}: "
              f"{e['message']}" for e in report.get("errors", [])]
    assert code == 0 and not errors, "\n".join(errors)
    ours = [w for w in report["warnings"] if w["file"] in written]
    assert all("overridden by" in w["message"] for w in ours), ours  # the overrides shown


def test_the_documents_shown_plan_as_the_pages_say(docs, kb_copy, capsys):
    """What the pages say their own documents do: the culture ``mine`` sets the knife down
    for a seven-year-old, the toddler is not handed the hot saucepan, and the test file
    ``kitchen`` passes."""
    write_documents(docs, kb_copy)
    planner = handover.Planner(kb=kb_copy)
    placed = planner.plan("knife", receiver="child", culture="mine")
    assert placed.outcome == "place", placed.reason
    assert "set_down_for_small_children" in {r["rule"] for r in placed.to_dict()["refused"]}
    refused = planner.plan("saucepan", receiver="toddler")
    assert refused.outcome == "refuse" and "no_hazards_to_young_children" in refused.reason
    code = main(["--kb", str(kb_copy), "kb", "test", str(kb_copy / "tests" / "kitchen.yaml")])
    out, _ = capsys.readouterr()
    assert code == 0, out


def test_the_json_page_names_every_top_level_field():
    """Each field of a result (a handover asked why-not and what-if, a refusal, an H2G2
    regrasp) is a row of docs/json.md's table."""
    table = (ROOT / "docs" / "json.md").read_text(encoding="utf-8").split("## The top level")[1]
    table = table.split("\n## ", 1)[0]
    named = {name for row in table.splitlines() if row.startswith("| `")
             for name in re.findall(r"`(\w+)`", row.split("|")[1])}
    planner = handover.Planner()
    fields = set(planner.plan("knife", why_not=(12,), what_if=True).to_dict())
    fields |= set(planner.plan("knife", receiver="child").to_dict())
    fields |= set(planner.plan("hammer", scene="hammer_by_wall", mode="h2g2").to_dict())
    assert {"why_not", "what_if", "refused", "regrasp"} <= fields
    assert fields <= named, f"not in docs/json.md: {sorted(fields - named)}"


def test_a_broken_document_in_a_page_would_be_caught(kb_copy, capsys):
    """The validation above can fail: a misspelt key in an object is an error at its line."""
    text = ("# yaml-language-server: $schema=../schema/objects.json\n"
            "id: bread_knife\nname: Bread knife\nmas: 0.15\n"
            "geometry: {primitives: [{shape: box, part: handle, extents: [0.1, 0.02, 0.02]}]}\n"
            "parts: {handle: {tags: [handle]}}\n")
    ((path, document),) = kb_documents(text)
    assert path == "objects/bread_knife.yaml"
    (kb_copy / path).write_text(document, encoding="utf-8")
    code, report = validate(kb_copy, capsys)
    assert code != 0
    assert any(e["file"] == path and e["line"] == 4 for e in report.get("errors", [])), report


def test_a_block_that_is_no_document_is_told_apart():
    assert kb_documents("  - id: a_rule\n    kind: contact\n") is None
    assert kb_documents("# objects/a.yaml\nid: a\n---\nid: b\n") is None
    assert kb_documents("# objects/a.yaml\nid: a\n---\n# receivers/b.yaml\nid: b\n") == [
        ("objects/a.yaml", "# objects/a.yaml\nid: a\n"),
        ("receivers/b.yaml", "# receivers/b.yaml\nid: b\n")]


def test_every_marked_block_is_read_by_a_test(docs):
    marked = {b.example for b in docs.blocks() if b.example is not None}
    assert marked == set(MARKED), "marked blocks and the tests that read them differ"
    for name in MARKED:
        docs.example(name)  # each is marked once


def test_the_bending_rule_shown_is_korean_s(docs):
    (shown,) = yaml.safe_load(docs.example("korean-bends").text)
    korean = yaml.safe_load((Path(str(files("handover.kb"))) / "etiquette" / "korean.yaml")
                            .read_text(encoding="utf-8"))
    assert shown == next(r for r in korean["rules"] if r["id"] == shown["id"])


def test_the_gripper_meshes_shown_validate(docs, kb_copy, capsys):
    import trimesh

    shown = yaml.safe_load(docs.example("gripper-meshes").text)
    meshes = shown["meshes"]
    assert meshes["scale"] == 0.001
    folder = kb_copy / "grippers"
    spec = yaml.safe_load((folder / "parallel_jaw.yaml").read_text(encoding="utf-8"))
    # meshes in millimetres the size of the boxes they replace, in the frames the page gives
    # (extents along n, o, a): the palm behind its finger face (a <= 0), the +o finger with
    # its origin at the centre of its pad (o >= 0)
    palm = [1000 * v for v in spec["palm"]]
    trimesh.creation.box(palm).apply_translation([0, 0, -palm[2] / 2]).export(
        folder / meshes["palm"])
    finger = [1000 * spec["finger_width"], 1000 * spec["finger_thickness"],
              1000 * spec["finger_length"]]
    trimesh.creation.box(finger).apply_translation([0, finger[1] / 2, 0]).export(
        folder / meshes["finger"])
    spec.update(shown)
    (folder / "parallel_jaw.yaml").write_text(yaml.safe_dump(spec), encoding="utf-8")
    code, report = validate(kb_copy, capsys)
    assert code == 0, report.get("errors")
    (folder / meshes["finger"]).unlink()
    code, report = validate(kb_copy, capsys)
    assert code != 0 and any(meshes["finger"] in e["message"] for e in report.get("errors", []))


def test_the_links_between_the_pages_resolve():
    link = re.compile(r"\]\((?P<target>[^)\s]+)\)")
    bad = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for m in link.finditer(text):
            target = m["target"]
            if re.match(r"\w+://", target):
                continue
            file, _, anchor = target.partition("#")
            path = (page.parent / file).resolve() if file else page
            if not path.exists():
                bad.append(f"{page.name}: {target}: no such file")
            elif anchor and path.suffix == ".md" and anchor not in _anchors(path):
                bad.append(f"{page.name}: {target}: no heading #{anchor} in {path.name}")
    assert not bad, "\n".join(bad)


def _anchors(page: Path) -> set[str]:
    """GitHub's anchors of a page's headings (outside code blocks): lower case, punctuation
    dropped, spaces to hyphens."""
    out, fenced = set(), False
    for line in page.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and re.match(r"#{1,6} ", line):
            title = line.lstrip("#").strip().lower()
            out.add(re.sub(r"[^\w\- ]", "", title).replace(" ", "-"))
    return out


def test_the_facade_docstrings_run():
    for module in (handover, handover.engine.planner, handover.engine.spec.applies,
                   handover.engine.plan.records, handover.engine.assets.lru):
        finder = doctest.DocTestFinder()
        for test in finder.find(module):
            if test.examples:
                runner = doctest.DocTestRunner()
                runner.run(test)
                assert runner.failures == 0, test.name
