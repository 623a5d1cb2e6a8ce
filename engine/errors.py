"""The project's own errors and the exit codes the CLI maps them to.

Exit codes (documented in docs/cli.md):

====  =====================================================================
0     a plan was found (or the command succeeded)
1     internal error (a bug: please report it with ``--debug`` output)
2     usage error (unknown option, unknown object/culture/receiver/scene id)
3     invalid knowledge base (every problem listed as ``file:line:col: message``)
4     no feasible handover (the JSON result still explains why)
5     bad mesh or geometry input (missing, empty, degenerate, too large)
====  =====================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "EXIT_OK",
    "EXIT_INTERNAL",
    "EXIT_USAGE",
    "EXIT_INVALID_KB",
    "EXIT_INFEASIBLE",
    "EXIT_BAD_MESH",
    "HandoverError",
    "UsageError",
    "UnknownIdError",
    "KBIssue",
    "KBError",
    "InfeasibleError",
]

EXIT_OK = 0
EXIT_INTERNAL = 1
EXIT_USAGE = 2
EXIT_INVALID_KB = 3
EXIT_INFEASIBLE = 4
EXIT_BAD_MESH = 5


class HandoverError(Exception):
    """Base of every error this project raises on purpose; carries its exit code."""

    exit_code: int = EXIT_INTERNAL


class UsageError(HandoverError):
    """The request names something that does not exist or combines options wrongly."""

    exit_code = EXIT_USAGE


class UnknownIdError(UsageError):
    """The request names an id (object, culture, receiver, ...) the knowledge base does not
    hold."""


@dataclass(frozen=True, order=True)
class KBIssue:
    """One problem in the knowledge base, located in its YAML source.

    file : path of the YAML file (as given, relative to the KB root where possible)
    line, col : 1-based position of the offending node (0 when unknown)
    message : what is wrong, in one sentence
    severity : "error" or "warning"
    """

    file: str
    line: int
    col: int
    message: str
    severity: str = "error"

    def __str__(self) -> str:
        prefix = "" if self.severity == "error" else f"{self.severity}: "
        return f"{self.file}:{self.line}:{self.col}: {prefix}{self.message}"


class KBError(HandoverError):
    """The knowledge base is invalid; ``issues`` lists every problem found at once."""

    exit_code = EXIT_INVALID_KB

    def __init__(self, issues: list[KBIssue], warnings: list[KBIssue] | None = None):
        self.issues = sorted(issues)
        self.warnings = sorted(warnings or [])
        super().__init__("\n".join(str(i) for i in self.issues))


class InfeasibleError(HandoverError):
    """No handover satisfies the hard rules (used where no result object can be returned)."""

    exit_code = EXIT_INFEASIBLE
