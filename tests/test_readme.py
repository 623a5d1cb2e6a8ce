"""The README's Python examples and the facade's docstrings run as doctests."""

from __future__ import annotations

import doctest
import re
from pathlib import Path

import handover
import handover.engine.assets.lru
import handover.engine.plan.records
import handover.engine.planner
import handover.engine.spec.applies

README = Path(__file__).resolve().parents[1] / "README.md"


def _run(text: str, name: str) -> None:
    parser = doctest.DocTestParser()
    test = parser.get_doctest(text, {}, name, str(README), 0)
    assert test.examples, f"{name}: no examples"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    assert runner.failures == 0, f"{name}: {runner.failures} example(s) failed (see output)"


def test_the_readme_from_python_section_runs():
    text = README.read_text(encoding="utf-8")
    section = text.split("## From Python", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert blocks
    _run("\n".join(blocks), "README: From Python")


def test_the_facade_docstrings_run():
    for module in (handover, handover.engine.planner, handover.engine.spec.applies,
                   handover.engine.plan.records, handover.engine.assets.lru):
        finder = doctest.DocTestFinder()
        for test in finder.find(module):
            if test.examples:
                runner = doctest.DocTestRunner()
                runner.run(test)
                assert runner.failures == 0, test.name
