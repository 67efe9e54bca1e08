"""Particle swarm optimisation of an ANFIS's parameters (the paper's ANFIS baseline).

The swarm is a dict of tensors on the CPU (a few hundred numbers a particle), saved in
checkpoints as it is: positions and velocities, each particle's best and the swarm's best with
their losses. The trainer (:mod:`sik_ros.learning.training`) computes the particles' losses
where its rows are and copies the swarm's best into the model after each step.
"""

from typing import Callable, Dict

import torch

#: Inertia and the pulls towards a particle's own best and the swarm's best (the usual
#: constriction values), and the bound of every parameter.
INERTIA, OWN, SWARM, BOUND = 0.72, 1.49, 1.49, 10.0


def new_swarm(flat: torch.Tensor, particles: int,
              gen: torch.Generator) -> Dict[str, torch.Tensor]:
    """A swarm of ``particles`` around the parameters ``flat`` (the first one at them)."""
    pos = flat[None] + (torch.rand(particles, len(flat), generator=gen) * 2 - 1)
    pos[0] = flat
    return {'pos': pos, 'vel': torch.zeros_like(pos), 'best': pos.clone(),
            'best_f': torch.full((particles,), float('inf')), 'gbest': flat.clone(),
            'gbest_f': torch.tensor(float('inf'))}


def swarm_step(state: Dict[str, torch.Tensor], losses: Callable[[torch.Tensor], torch.Tensor],
               gen: torch.Generator) -> float:
    """One step of the swarm ``state`` (in place); the best loss so far.

    ``losses``: the particles' positions (P, k) to their losses (P,) on the CPU (NaN: worst).
    """
    f = torch.nan_to_num(losses(state['pos']), nan=float('inf'))
    better = f < state['best_f']
    state['best'][better] = state['pos'][better]
    state['best_f'][better] = f[better]
    i = int(torch.argmin(state['best_f']))
    state['gbest'] = state['best'][i].clone()
    state['gbest_f'] = state['best_f'][i].clone()
    r1 = torch.rand(state['pos'].shape, generator=gen)
    r2 = torch.rand(state['pos'].shape, generator=gen)
    state['vel'] = (INERTIA * state['vel'] + OWN * r1 * (state['best'] - state['pos'])
                    + SWARM * r2 * (state['gbest'][None] - state['pos']))
    state['pos'] = (state['pos'] + state['vel']).clamp(-BOUND, BOUND)
    return float(state['gbest_f'])
