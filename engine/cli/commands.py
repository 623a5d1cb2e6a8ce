"""Imports every command module so that each registers its commands on the app.

Add a new command module here (one line) when you add one.
"""

from __future__ import annotations

from handover.engine.cli import (
    batch,  # noqa: F401,E402  (batch)
    compare,  # noqa: F401,E402  (compare)
    grasps,  # noqa: F401,E402  (grasps)
    kb,  # noqa: F401,E402  (kb validate, kb list, kb show, kb schema)
    kbtest,  # noqa: F401,E402  (kb test)
    plan,  # noqa: F401,E402  (plan, explain-graph)
    review,  # noqa: F401,E402  (review)
    serve,  # noqa: F401,E402  (serve)
)
