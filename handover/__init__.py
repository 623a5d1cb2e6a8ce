"""handover-grasp: knowledge-base driven grasp planning for robots handing objects to people.

>>> from handover import Planner, Query
>>> planner = Planner()
>>> planner.plan("knife").mode
'H1G1'
>>> planner.plan(Query("knife", receiver="elder")).mode
'H1G1'

The installed package holds ``handover.engine`` (knowledge meets geometry), ``handover.geometry``
(meshes, grasp candidates, collision; knows nothing of the knowledge base) and ``handover.kb``
(the built-in knowledge base, YAML). ``Planner`` and ``Plan`` are the Python facade;
``Client`` has the ``Planner``'s interface over the plan service (``handover serve``).
``Query`` is what a plan is asked (``Planner.plan`` takes one, or its fields as keywords).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["Planner", "Plan", "Query", "RobotGrasp", "HumanGrasp", "Robot", "RobotArm", "Client"]

if TYPE_CHECKING:
    from handover.engine.planner import (
        HumanGrasp,
        Plan,
        Planner,
        Query,
        Robot,
        RobotArm,
        RobotGrasp,
    )
    from handover.engine.service.client import Client


def __getattr__(name: str):
    # Lazy: `import handover.engine.cli` (the command's start-up) does not pay for the
    # planner's imports.
    if name == "Client":
        from handover.engine.service.client import Client

        return Client
    if name in __all__:
        from handover.engine import planner

        return getattr(planner, name)
    raise AttributeError(f"module 'handover' has no attribute {name!r}")
