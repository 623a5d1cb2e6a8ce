"""``reach``: an arm of the robot reaches the grasp within its joint limits wherever it holds
the object: at pick-up, at H2G2's midair regrasp and at the handover
(:mod:`handover.engine.plan.arms.solve`).

Over every row the arms' reachability maps screen the gripper poses: a row passes when one
arm's map holds all of its stages. A grasp whose arm is decided (the chosen grasps: the
phase names the arm) is judged by exact inverse kinematics instead, with the arm's links at
those configurations tested against the table, the obstacles, the receiver's body (and, at
the handover, the hands taking the object), the robot's own body and the object held (and,
where both arms hold the object at once, the other arm: the modes' pair choice,
:mod:`handover.engine.plan.arms.pairs`); its trace entry gives the arm, the joint
values and what the links were found clear of. A robot without arms (no URDF) makes the
rule not applicable.
"""

from __future__ import annotations

from typing import Literal

from handover.engine.spec.kinds.base import FEATURES, RuleBase, register

FEATURES.setdefault("reach", (10.0, "grasp x presentation",
                              "an arm reaches the grasp at each stage (map; exact IK, its "
                              "links clear, for the chosen grasps)"))  # fmt: skip


@register
class ReachRule(RuleBase):
    """No fields of its own: the stages come from the attempt (pick-up when the grasp takes
    the object off the table, the midair regrasp in H2G2, the handover when the receiver
    takes it). Measured: the fraction of those stages the best arm reaches (1: every one);
    with the arm decided, the fraction it reaches with its links clear."""

    kind: Literal["reach"] = "reach"

    colour = (200, 120, 0)
    summary = ("an arm reaches the grasp at pick-up, midair and handover (map, then IK with "
               "its links clear)")
    example = {}

    def features(self) -> list[str]:
        return ["reach"]

    def describe(self) -> str:
        return "an arm reaches the grasp's poses within its joint limits"


