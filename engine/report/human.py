"""The receiver's records of a result: where each receiving hand takes the object, with the
grasp of their repertoire it takes there and the arm reaching for it (``human_grasps``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.records import HandBox, HumanGrasp, ReachingArm, TakenGrasp

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Hands
    from handover.engine.plan.receiver_sites import ReceiverSites

__all__ = ["human_record"]


def human_record(ctx: PlanContext, k: int, hand: str, hands: Hands,
                 sites: ReceiverSites, option: int | None = None) -> HumanGrasp | None:
    """A receiver's predicted grasp (the paper's C) in presentation ``k``: one hand's ``sites``
    of ``hands``, in grasp option ``option`` (the one it takes with the robot's grippers where
    they are, :func:`~handover.engine.plan.hand_features.joint_choice`; default its best
    usable one): where, on which part, its boxes (``model``, world), the ``grasp`` (its name
    and family, how it holds, its boxes, why; and why each other grasp is not the one) and
    the reaching ``arm`` (shoulder, elbow, wrist, world, and the radii of upper arm and
    forearm). None where that hand has no site."""
    if not sites.valid[k]:
        return None
    from handover.engine.plan.hand_features import hand_model, primary_options

    pose = hands.poses[k]
    opts = sites.options
    j = int(primary_options(sites)[k]) if option is None or option < 0 else int(option)
    site = sites.site[k] if opts is None or j < 0 else opts.site[k, j]
    # labelled by the part under the site among those the hand may hold, as a robot contact
    # is by the part it lies on
    allowed = None if hands.region is None or hands.region.empty else np.unique(hands.region.parts)
    part = int(ctx.part_mesh.part_under(site, allowed)[0])
    model = tuple(HandBox(name, ext, box)
                  for name, ext, box in hand_model(ctx, hands.region, sites, k, pose,
                                                   None if opts is None or j < 0 else j))
    taken = opts is not None and j >= 0
    return HumanGrasp(
        hand=hand, position=site, position_world=pose[:3, :3] @ site + pose[:3, 3],
        part=ctx.part_mesh.part_names[part], model=model,
        grasp=_grasp_record(ctx, sites, k, j, model) if taken else None,
        arm=_arm_record(ctx, hands, sites, k, j, hand) if taken else None)


def _grasp_record(ctx: PlanContext, sites: ReceiverSites, k: int, j: int,
                  model: tuple[HandBox, ...]) -> TakenGrasp:
    """``human_grasps[i].grasp``: the grasp taken (:func:`~handover.engine.plan.
    grasp_record.option_record`), its boxes (world), where its entry is and why it is a
    grasp of the hand, and why each other grasp is not the one."""
    from handover.engine.plan.grasp_record import not_taken, option_record

    rec = option_record(ctx, sites, k, j)
    spec = ctx.repertoire.specs[int(sites.options.grasp[k, j])]
    return TakenGrasp(**rec, boxes=model, source=str(spec.source),
                      why=(spec.why or "").strip() or None,
                      not_taken=not_taken(ctx, sites, k, j))


def _arm_record(ctx: PlanContext, hands: Hands, sites: ReceiverSites, k: int, j: int,
                hand: str) -> ReachingArm:
    """``human_grasps[i].arm``: the receiver's arm reaching for option ``j`` of presentation
    ``k`` (:func:`~handover.engine.plan.offer.reaching_arms`), world."""
    from handover.engine.plan.offer import reaching_arms

    pose = hands.poses[k]
    shoulder = ctx.world.receiver.shoulder(hand)
    wrists = np.einsum("ij,wj->wi", pose[:3, :3], sites.options.wrists[k, j]) + pose[:3, 3]
    wrist, elbow, hits = reaching_arms(ctx, wrists[None], shoulder, hand,
                                       ctx.world.arm_obstacles())
    names = ctx.world.arm_obstacles().names
    return ReachingArm(shoulder, elbow[0], wrist[0], tuple(ctx.world.arm_radii(hand)),
                       tuple(names[p] for p in np.flatnonzero(hits[0])))
