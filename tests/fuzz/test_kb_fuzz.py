"""Random YAML fed to the loader: it loads or raises KBError, never anything else.

Three sources of documents: random nested data (with keys of the real models, so validation
goes deep), random text, and random edits of the real KB files.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handover.engine.errors import KBError
from handover.engine.load.loader import load_kb
from handover.engine.spec.schema import DOCUMENT_KINDS
from handover.engine.store.kb import builtin_kb_dir

FOLDERS = sorted(DOCUMENT_KINDS)
FIELD_NAMES = sorted(
    {name for model in DOCUMENT_KINDS.values() for name in model.model_fields}
    | {
        "shape",
        "part",
        "extents",
        "radius",
        "rules",
        "kind",
        "who",
        "forbid_tags",
        "axis",
        "toward",
        "min_deg",
        "applies",
        "object_tags_any",
        "overrides",
        "primitives",
        "mesh",
    }
)
REAL_FILES = sorted(
    p.relative_to(builtin_kb_dir()).as_posix()
    for kind in DOCUMENT_KINDS
    for p in (builtin_kb_dir() / kind).glob("*.yaml")
)
FUZZ = settings(
    max_examples=200,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

scalars = (
    st.none()
    | st.booleans()
    | st.integers(-(10**6), 10**6)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=12)
    | st.sampled_from(["box", "sphere", "contact", "axis", "up", "sharp", "H2G1", "common"])
)
keys = st.sampled_from(FIELD_NAMES) | st.text(max_size=8)
documents = st.recursive(
    scalars,
    lambda children: st.lists(children, max_size=4) | st.dictionaries(keys, children, max_size=6),
    max_leaves=25,
)


def check(rel: str, content: str | bytes) -> None:
    """Write one file into an empty KB folder and load it."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8", errors="surrogatepass")
        try:
            kb = load_kb(root)
        except KBError as e:
            assert e.issues, "a KBError lists its problems"
            for issue in e.issues:
                assert issue.line >= 0 and issue.col >= 0
                assert issue.message
        else:
            assert kb.root == root.absolute()


@FUZZ
@given(folder=st.sampled_from(FOLDERS), data=documents)
def test_random_data(folder, data):
    check(f"{folder}/doc.yaml", yaml.safe_dump(data, allow_unicode=True))


@FUZZ
@given(
    folder=st.sampled_from(FOLDERS),
    text=st.text(alphabet=st.characters(blacklist_categories=["Cs"]), max_size=300)
    | st.binary(max_size=200),
)
def test_random_text(folder, text):
    check(f"{folder}/doc.yaml", text)


@st.composite
def mutated_files(draw):
    rel = draw(st.sampled_from(REAL_FILES))
    text = (builtin_kb_dir() / rel).read_text()
    lines = text.splitlines(keepends=True)
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["delete", "duplicate", "swap", "indent", "chars", "replace"]))
        if not lines:
            break
        i = draw(st.integers(0, len(lines) - 1))
        if op == "delete":
            del lines[i]
        elif op == "duplicate":
            lines.insert(i, lines[i])
        elif op == "swap":
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == "indent":
            lines[i] = draw(st.sampled_from(["", " ", "  ", "    ", "\t"])) + lines[i].lstrip()
        elif op == "chars":
            line = lines[i]
            k = draw(st.integers(0, len(line)))
            junk = draw(
                st.sampled_from(
                    [
                        ":",
                        "- ",
                        "[",
                        "{",
                        "}",
                        "&a ",
                        "*a",
                        "!!python/none ",
                        "'",
                        '"',
                        "#",
                        ".nan",
                        "-1",
                        "~",
                        "<<: ",
                        "|",
                        "%",
                    ]
                )
            )
            lines[i] = line[:k] + junk + line[k:]
        else:
            scalar = draw(scalars)
            key = lines[i].split(":", 1)[0]
            lines[i] = f"{key}: {yaml.safe_dump(scalar, default_flow_style=True).strip()}\n"
    return rel, "".join(lines)


@FUZZ
@given(case=mutated_files())
def test_mutated_real_files(case):
    rel, text = case
    check(rel, text)
