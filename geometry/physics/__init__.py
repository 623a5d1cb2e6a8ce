"""The physics check of grasps in MuJoCo: the object, the grippers and the receiver's pads
simulated through pick-up, lift, carry, hold, shake and the hand-over.

This package knows nothing of the knowledge base: primitives or meshes, poses and numbers
in, typed results out. Its parts: :mod:`.params` (every parameter with its reason),
:mod:`.shapes` (the object), :mod:`.hands` (grippers and a receiver's pads),
:mod:`.protocol` (the phases as targets over time), :mod:`.model` (the MjSpec of object,
hands and pads), :mod:`.results` (grasps in, slips and outcomes out), :mod:`.check` (run,
measure, the robustness ensemble), :mod:`.slip` (the object's slip in a holder's frame) and
:mod:`.decompose` (a mesh's convex parts by CoACD, cached by the mesh's hash).
"""

from handover.geometry.physics.check import check, ensemble
from handover.geometry.physics.hands import Hand
from handover.geometry.physics.params import (
    DEFAULT_ENSEMBLE,
    GRIP_FORCES,
    RECEIVER_PINCH_FORCES,
    Perturbation,
    Protocol,
    Solver,
    Thresholds,
    receiver_grip_force,
)
from handover.geometry.physics.protocol import MODES, Motion
from handover.geometry.physics.results import (
    GRASP_KINDS,
    RECORD_HZ,
    CheckResult,
    EnsembleResult,
    Grasp,
    PhaseSlip,
    Trajectory,
)
from handover.geometry.physics.shapes import ConvexPart, ObjectModel, Primitive

__all__ = [
    "GRASP_KINDS",
    "CheckResult",
    "EnsembleResult",
    "Grasp",
    "PhaseSlip",
    "RECORD_HZ",
    "Trajectory",
    "check",
    "ensemble",
    "ConvexPart",
    "Hand",
    "ObjectModel",
    "Primitive",
    "DEFAULT_ENSEMBLE",
    "GRIP_FORCES",
    "MODES",
    "RECEIVER_PINCH_FORCES",
    "Motion",
    "Perturbation",
    "Protocol",
    "Solver",
    "Thresholds",
    "receiver_grip_force",
]
