"""Particle swarm optimisation of an ANFIS's parameters (the paper's trainer for ANFIS).

The swarm is a dict of tensors (positions, velocities, each particle's best and the best of
all), saved in checkpoints as it is; :func:`swarm_step` moves it one step against a batch.
"""

from typing import Dict

import torch

from sik_ros.learning.models import anfis_forward, ModelConfig

#: Inertia and the pulls towards a particle's best and the swarm's best (the usual
#: constriction values).
INERTIA, PULL_OWN, PULL_BEST = 0.72, 1.49, 1.49
#: Parameters stay within +-this (normalised units).
BOUND = 10.0


def new_swarm(flat: torch.Tensor, particles: int, gen: torch.Generator) -> Dict[str, torch.Tensor]:
    """A swarm of ``particles`` around the parameters ``flat`` (one particle on them).

    Args:
        flat: the model's parameters as one vector.
        particles: swarm size.
        gen: the random stream (CPU).
    """
    pos = flat[None] + (torch.rand(particles, len(flat), generator=gen) * 2 - 1)
    pos[0] = flat
    return {'pos': pos, 'vel': torch.zeros_like(pos), 'best': pos.clone(),
            'best_f': torch.full((particles,), float('inf')), 'gbest': flat.clone(),
            'gbest_f': torch.tensor(float('inf'))}


@torch.no_grad()
def swarm_step(state: Dict[str, torch.Tensor], cfg: ModelConfig, goal: torch.Tensor,
               x: torch.Tensor, gen: torch.Generator) -> Dict[str, torch.Tensor]:
    """One step of the swarm on a batch; the swarm is updated in place and returned.

    Args:
        state: the swarm (:func:`new_swarm`), on the CPU.
        cfg: the ANFIS's config.
        goal: normalised goals of the batch (N, goal entries), where the rows are.
        x: normalised joints of the batch (N, dof), the targets.
        gen: the random stream (CPU).
    """
    # the swarm stays on the CPU (a few hundred numbers a particle); its losses are
    # computed where the rows are
    outputs = anfis_forward(cfg, state['pos'].to(goal.device), goal)
    f = ((outputs - x[None]) ** 2).mean((1, 2)).cpu()
    f = torch.nan_to_num(f, nan=float('inf'))
    better = f < state['best_f']
    state['best'][better] = state['pos'][better]
    state['best_f'][better] = f[better]
    i = int(torch.argmin(state['best_f']))
    state['gbest'] = state['best'][i].clone()
    state['gbest_f'] = state['best_f'][i].clone()
    r1 = torch.rand(state['pos'].shape, generator=gen)
    r2 = torch.rand(state['pos'].shape, generator=gen)
    state['vel'] = (INERTIA * state['vel'] + PULL_OWN * r1 * (state['best'] - state['pos'])
                    + PULL_BEST * r2 * (state['gbest'][None] - state['pos']))
    state['pos'] = (state['pos'] + state['vel']).clamp(-BOUND, BOUND)
    return state
