"""The command's consoles: rich, with no highlighting and no emoji codes (a trace that says
``body:robot:torso`` prints those words, not a robot face)."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.console import Console

__all__ = ["rich_console"]


def rich_console(*, stderr: bool = False, soft_wrap: bool = True) -> Console:
    """A rich console on stdout (``stderr``: on stderr) that prints text as it is."""
    from rich.console import Console

    return Console(stderr=stderr, highlight=False, soft_wrap=soft_wrap, emoji=False)
