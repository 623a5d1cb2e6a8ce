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

from typing import TYPE_CHECKING, Literal

import numpy as np

from handover.engine.spec.kinds.base import FEATURES, Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext

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

    def not_applicable(self, ctx: PlanContext) -> str | None:
        if not hasattr(ctx, "candidates"):  # a listing without a query
            return None
        if ctx.arms is None:
            robot = ctx.situation.robot
            return f"robot '{robot.id}' has no arms (no urdf and arms in {robot.source})"
        return None

    def _stages(self, phase: Phase) -> tuple[str, ...]:
        from handover.engine.plan.arms.stages import screened_stages, stages

        return stages(phase) if getattr(phase, "arm", None) else screened_stages(phase)

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        from handover.engine.plan.arms.links import link_targets, target_groups
        from handover.engine.plan.arms.solve import confirm, screen
        from handover.engine.plan.arms.stages import STAGE_WORDS

        names = self._stages(phase)
        where = ", ".join(STAGE_WORDS[s] for s in names) or "no stage"
        side = getattr(phase, "arm", None)
        if ctx.arms is None or not names:
            ok = np.ones(len(gi), dtype=bool)
            return Outcome(ok, np.ones(len(gi)), ok.astype(float), ">= 1", "fraction of stages")
        if side is not None:  # the arm is decided: exact inverse kinematics
            checks = confirm(ctx, phase, side, gi, pk)
            measured = np.array([c.held.mean() for c in checks]) if checks \
                else np.zeros(0)
            against = target_groups([n for s in names
                                     for n in link_targets(ctx, phase, side, s).names])
            how = (f"the {side} arm {where}, inverse kinematics within its joint limits, "
                   f"its links clear of {', '.join(against) or 'nothing'}")
        else:
            sides, mapped = screen(ctx, phase, gi, pk)  # (R, S, T)
            measured = mapped.mean(axis=2).max(axis=1) if len(sides) else np.zeros(len(gi))
            how = f"the {' or '.join(sides)} arm {where}, reachability map"
        ok = measured >= 1.0 - 1e-9
        return Outcome(ok, measured, ok.astype(float), f">= 1 ({how})", "fraction of stages")

    def detail(self, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
        from handover.engine.plan.arms.links import links_words
        from handover.engine.plan.arms.solve import arm_record, confirm, reach_words

        if ctx.arms is None or not self._stages(phase):
            return {}
        side = getattr(phase, "arm", None)
        if side is None:
            words = reach_words(ctx, phase, grasp, presentation)
            return {"cannot": words} if words else {}
        out = arm_record(ctx, phase, grasp, presentation)
        check = confirm(ctx, phase, side, np.array([grasp]), np.array([presentation]))[0]
        failure = check.failure()
        if failure:
            out["cannot"] = failure
        else:
            out["links"] = links_words(ctx, phase, check, grasp, presentation)
        return out
