"""The networks at a goal: posture indices decoded to joints, joints encoded to indices."""

import numpy as np
import torch

from sik_ros.models import make_goal
from sik_ros.solver.context import Context, Goal


def goal_net(ctx: Context, goal: Goal, rows: int) -> torch.Tensor:
    """The goal repeated ``rows`` times, in the network's normalised units."""
    g = make_goal(goal.kind, np.repeat(goal.position[None], rows, 0),
                  None if goal.rotation is None else np.repeat(goal.rotation[None], rows, 0))
    return ctx.models[goal.kind].norm.goal_to_net(torch.from_numpy(g.astype(np.float32)))


@torch.no_grad()
def decode(ctx: Context, goal: Goal, z: np.ndarray) -> np.ndarray:
    """Joint solutions (M, n) [rad] decoded from posture indices (M, latent), clipped."""
    gm = ctx.models[goal.kind]
    x = gm.model.decode(goal_net(ctx, goal, len(z)),
                        torch.from_numpy(np.asarray(z, dtype=np.float32)))
    q = gm.norm.q_from_net(x).double().numpy()
    return np.clip(q, ctx.robot.lower, ctx.robot.upper)


@torch.no_grad()
def encode(ctx: Context, goal: Goal, q: np.ndarray) -> np.ndarray:
    """Posture indices (M, latent) of configurations (M, n) for a goal."""
    gm = ctx.models[goal.kind]
    z, _ = gm.model.encode(goal_net(ctx, goal, len(q)),
                           gm.norm.q_to_net(torch.from_numpy(q.astype(np.float32))))
    return z.numpy().astype(np.float64)
