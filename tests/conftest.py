"""Shared fixtures: the built-in KB, small KBs written into ``tmp_path`` by tests, and the
code blocks of the documentation.

``make_kb(files)`` writes a minimal valid KB (one object, a ``common`` culture, a gripper,
a hand, a robot, a receiver, a scene) and then the given files over it (relative path ->
YAML text, or None to delete a file). Tests break one thing and check the error.

``docs`` reads README.md and docs/*.md into :class:`CodeBlock` records. A test finds the
block it checks by the name of the HTML comment just before its opening fence
(``<!-- example: own-robot -->``), never by a heading, so pages can be rewritten and
examples moved between them: ``docs.example("own-robot").text``.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

MINIMAL_KB: dict[str, str] = {
    "objects/stick.yaml": """\
        id: stick
        name: Stick
        mass: 0.1
        geometry:
          primitives:
            - shape: box
              part: grip
              extents: [0.1, 0.02, 0.02]
              position: [-0.05, 0, 0]
            - shape: box
              part: point
              extents: [0.1, 0.01, 0.01]
              position: [0.05, 0, 0]
        parts:
          grip:
            tags: [handle]
          point:
            tags: [sharp]
        axes:
          tip: [1, 0, 0]
        """,
    "etiquette/common.yaml": """\
        id: common
        name: Common
        rules:
          - id: no_sharp
            kind: contact
            who: receiver
            forbid_tags: [sharp]
            safety: true
            why: Never hand over a blade first.
          - id: tip_away
            kind: axis
            axis: tip
            toward: toward_receiver
            min_deg: 100
            applies: {object_tags_any: [sharp]}
            why: Points away from people.
        vocabulary:
          handle: The part made to be held.
        """,
    "grippers/jaw.yaml": """\
        id: jaw
        name: Jaw
        max_opening: 0.085
        finger_length: 0.04
        finger_width: 0.022
        finger_thickness: 0.01
        palm: [0.06, 0.13, 0.08]
        """,
    "hands/adult_hand.yaml": """\
        id: adult_hand
        name: Hand
        palm: [0.09, 0.03, 0.1]
        finger_length: 0.08
        finger_thickness: 0.02
        grip_width: 0.09
        """,
    "robots/bot.yaml": """\
        id: bot
        name: Bot
        payload_per_hand: 1.5
        gripper: jaw
        """,
    "receivers/adult.yaml": """\
        id: adult
        name: Adult
        """,
    "scenes/table.yaml": """\
        id: table
        name: Table
        support: {position: [0.5, 0, 0.75], size: [0.6, 1.0]}
        """,
}


def write_files(root: Path, files: dict[str, str | None]) -> Path:
    """Write ``files`` (path -> text, dedented; None deletes) under ``root``."""
    for rel, text in files.items():
        path = root / rel
        if text is None:
            path.unlink(missing_ok=True)
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text), encoding="utf-8")
    return root


@pytest.fixture
def make_kb(tmp_path: Path) -> Callable[..., Path]:
    """``make_kb(files=None, minimal=True) -> Path``: a KB folder in ``tmp_path``."""

    def make(files: dict[str, str | None] | None = None, minimal: bool = True) -> Path:
        root = tmp_path / "kb"
        root.mkdir(exist_ok=True)
        if minimal:
            write_files(root, MINIMAL_KB)
        return write_files(root, files or {})

    return make


@pytest.fixture
def armless_kb(tmp_path: Path) -> Path:
    """The built-in KB copied with the robot's arms taken off (a floating gripper per hand)."""
    import shutil

    from handover.engine.store.kb import builtin_kb_dir

    root = tmp_path / "armless_kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    return take_arms_off(root)


def take_arms_off(root: Path) -> Path:
    """The KB folder ``root`` with the shipped robot's arms taken off its YAML (a floating
    gripper per hand); returns ``root``."""
    import yaml

    path = root / "robots" / "idro.yaml"
    spec = yaml.safe_load(path.read_text(encoding="utf-8"))
    for key in ("urdf", "arms", "base_pose"):
        spec.pop(key, None)
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    return root


@pytest.fixture(scope="session")
def arms_off():
    """:func:`take_arms_off`, for tests that build their own KB folder."""
    return take_arms_off


@pytest.fixture(scope="session")
def builtin_kb():
    """The built-in knowledge base, loaded once (do not modify it)."""
    from handover.engine.load.loader import load_kb
    from handover.engine.store.kb import builtin_kb_dir

    return load_kb(builtin_kb_dir())


@pytest.fixture(autouse=True, scope="session")
def _grasp_db_in_a_temporary_folder(tmp_path_factory):
    """Plans in tests read and write the grasp database in a temporary folder, never in the
    user's cache (subprocesses inherit it through the environment)."""
    import os

    old = os.environ.get("HANDOVER_DB")
    os.environ["HANDOVER_DB"] = str(tmp_path_factory.mktemp("grasp-db"))
    yield
    if old is None:
        os.environ.pop("HANDOVER_DB", None)
    else:
        os.environ["HANDOVER_DB"] = old


@pytest.fixture(scope="session")
def reach_maps(builtin_kb, _grasp_db_in_a_temporary_folder) -> Path:
    """The folder of the built-in robot's reachability maps in this session's database
    (built once per worker, if no plan has yet): a map depends on the robot only, and takes
    about 20 s to build."""
    import os

    from handover.engine.assets.robot import REACH_FOLDER, RobotArms

    folder = Path(os.environ["HANDOVER_DB"]) / REACH_FOLDER
    for spec in builtin_kb.robots.values():
        if spec.arms:
            arms = RobotArms.load(builtin_kb, spec, reach_dir=folder)
            for side in arms.arms:
                for core in (False, True):
                    arms.reach_map(side, core=core)  # read, or built and saved
    return folder


@pytest.fixture
def db_with_maps(tmp_path: Path, reach_maps: Path) -> Path:
    """A new, empty grasp database folder for subprocesses (``HANDOVER_DB``) holding only
    a copy of the session's reachability maps, so that a process planning with it finds
    its candidates cold without building the robot's maps again."""
    import shutil

    db = tmp_path / "db"
    shutil.copytree(reach_maps, db / "reach")
    return db


# ---------------------------------------------------------------- the documentation's code

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```(?P<lang>[\w+-]*)\s*$")
MARKER = re.compile(r"^<!--\s*example:\s*(?P<name>[\w.-]+)\s*-->\s*$")


@dataclass(frozen=True)
class CodeBlock:
    """One fenced code block of a documentation page.

    page : the Markdown file. line : 1-based line of its opening fence. lang : the fence's
    language (``python``, ``yaml``, ``sh``, ... or ``""``). text : its content, each line
    ending in a newline. example : the name given by an ``<!-- example: NAME -->`` comment on
    the nearest non-blank line before the fence, else None.
    """

    page: Path
    line: int
    lang: str
    text: str
    example: str | None

    @property
    def where(self) -> str:
        """``page:line`` (relative to the repository when in it), for assertion messages."""
        page = self.page.relative_to(ROOT) if self.page.is_relative_to(ROOT) else self.page
        return f"{page.as_posix()}:{self.line}"


def code_blocks(page: Path) -> list[CodeBlock]:
    """The fenced code blocks of ``page`` in order. Fences start at the line's first column
    (three backticks and an optional language); a fence left open is a ValueError."""
    lines = page.read_text(encoding="utf-8").splitlines()
    out: list[CodeBlock] = []
    k = 0
    while k < len(lines):
        opening = FENCE.match(lines[k])
        if opening is None:
            k += 1
            continue
        end = next((j for j in range(k + 1, len(lines)) if lines[j].rstrip() == "```"), None)
        if end is None:
            raise ValueError(f"{page}:{k + 1}: a code fence is opened and never closed")
        before = next((lines[j] for j in range(k - 1, -1, -1) if lines[j].strip()), "")
        marker = MARKER.match(before.strip())
        out.append(CodeBlock(page=page, line=k + 1, lang=opening["lang"],
                             text="".join(f"{s}\n" for s in lines[k + 1 : end]),
                             example=marker["name"] if marker else None))
        k = end + 1
    return out


@dataclass(frozen=True)
class Docs:
    """The documentation: README.md, then docs/*.md in name order."""

    pages: tuple[Path, ...]

    def blocks(self, lang: str | None = None) -> list[CodeBlock]:
        """Every code block of every page (of language ``lang`` when given)."""
        return [b for page in self.pages for b in code_blocks(page)
                if lang is None or b.lang == lang]

    def example(self, name: str) -> CodeBlock:
        """The one block named ``name`` by its ``<!-- example: NAME -->`` comment."""
        found = [b for b in self.blocks() if b.example == name]
        if not found:
            raise LookupError(f"no code block is marked <!-- example: {name} --> in README.md "
                              "or docs/*.md")
        if len(found) > 1:
            raise ValueError(f"example {name!r} is marked more than once: "
                             + ", ".join(b.where for b in found))
        return found[0]


@pytest.fixture(scope="session")
def docs() -> Docs:
    """README.md and docs/*.md, their code blocks found by marker (:class:`Docs`)."""
    return Docs(pages=(ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))))
