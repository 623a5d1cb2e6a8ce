"""``handover kb test``: run the KB's test cases (``tests/*.yaml``) and report like a test
runner; ``--coverage`` adds rule coverage. Computed by :mod:`handover.engine.tools.kbtest` and
:mod:`handover.engine.tools.coverage`; this module renders.

Exit codes: 0 every case passed, 1 a case failed, 3 an invalid KB or test file, 2 usage.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from handover.engine.cli.app import kb_app, state

__all__ = ["test"]


@kb_app.command("test")
def test(
    paths: list[Path] = typer.Argument(
        None, metavar="[PATH]...",
        help="Test files or folders (default: the KB's tests/ folder).",
    ),
    select: str | None = typer.Option(
        None, "-k", help="Only the cases whose name contains this text (any case)."
    ),
    coverage: bool = typer.Option(False, "--coverage", help="Report rule coverage too."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Run KB test cases: plan each case's query and check what its result must show.

    Exit codes: 0 all cases passed, 1 some case failed, 3 invalid KB or test file.
    """
    from handover.engine.load.loader import load_kb
    from handover.engine.tools.answer import kb_tests, kb_tests_text

    kb = load_kb(state.kb_dir, urdf=False)
    report, cov = kb_tests(kb, select=select, coverage=coverage, paths=list(paths or []))
    if json_out:
        typer.echo(kb_tests_text(report, cov), nl=False)
    else:
        _render(report, cov)
    raise typer.Exit(1 if report.failed else 0)


def _render(report: Any, cov: dict[str, Any] | None) -> None:
    from rich.markup import escape

    from handover.engine.cli.out import rich_console

    out = rich_console()
    for c in report.cases:
        mark = "[green]PASS[/]" if c.passed else "[bold red]FAIL[/]"
        out.print(f"{mark} {c.file}:{c.line} {escape(c.name)}")
    for c in report.cases:
        if c.passed:
            continue
        out.print(f"\n[bold red]FAILED[/] {c.file}:{c.line} [bold]{escape(c.name)}[/]")
        for f in c.failures:
            out.print(f"  {f['expect']}: {escape(f['message'])}")
            out.print(f"    expected: {escape(str(f['expected']))}")
            out.print(f"    got:      {escape(str(f['got']))}")
        if c.decisive:
            out.print("  decided by:")
            for line in c.decisive:
                out.print(f"    {escape(line)}")
    if cov is not None:
        _render_coverage(out, cov)
    colour = "red" if report.failed else "green"
    out.print(f"\n[bold {colour}]{report.passed} passed, {report.failed} failed[/]")


def _render_coverage(out: Any, cov: dict[str, Any]) -> None:
    from rich.markup import escape

    rules = cov["rules"]
    width = max([len(k) for k in rules] + [4])
    out.print("\n[bold]rule coverage[/] (cases where each rule applied, rejected candidates, "
              "decided)")
    out.print(f"{'rule':<{width}}  {'culture':<9} {'applied':>7} {'rejected':>8} "
              f"{'decided':>7}  source")
    for key, r in rules.items():
        line = (f"{key:<{width}}  {r['culture']:<9} {r['applied']:>7} {r['rejected']:>8} "
                f"{r['decided']:>7}  {r['source']}")
        out.print(f"[dim]{escape(line)}[/]" if r["applied"] == 0 else escape(line))
    never = cov["never_applied"]
    out.print(f"never applied: {', '.join(never) if never else 'none'}")
    unread = cov["unread_tags"]
    out.print(f"tags no rule reads: {', '.join(unread) if unread else 'none'}")
