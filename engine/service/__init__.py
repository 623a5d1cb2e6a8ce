"""The plan service: ``handover serve``, a long-running HTTP + JSON service over one knowledge
base loaded once, and :class:`~handover.engine.service.client.Client`, its Python client
with the ``Planner``'s interface (``handover.Client``).

One module a concern: :mod:`.worker` (what a worker process holds and does: its KB, grasp
database and memo of answers; every answer built by :mod:`handover.engine.tools.answer`, as
the CLI's), :mod:`.pool` (the worker processes, deadlines, reloading the KB atomically),
:mod:`.app` (the HTTP routes, errors as JSON, the token, request logs), :mod:`.server`
(binding, printing the address, running it) and :mod:`.client`. Importing this package
imports none of them (the client does not need the server's libraries).
"""

from __future__ import annotations

__all__: list[str] = []
