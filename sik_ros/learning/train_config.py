"""Training settings: one frozen dataclass saved in every checkpoint, and its schedule."""

from dataclasses import dataclass, replace
import math

from sik_ros.errors import InvalidArgument


SAMPLERS = ('dataset', 'uniform')


@dataclass(frozen=True)
class TrainConfig:
    """How a model is trained; saved inside every checkpoint.

    Attributes:
        steps: optimiser steps (the learning-rate schedule spans them).
        batch_size: samples per step.
        lr: peak learning rate of Adam.
        lr_min: final learning rate of the cosine schedule.
        warmup: linear warm-up steps.
        fk_weight: weight of the forward-kinematics consistency term (0 disables it).
        fk_start: step from which the FK term is on (before it: the paper's joint loss only).
        fk_scale: distance that counts as one unit in the FK term [m].
        rot_weight: weight of the orientation part of the FK term (pose goals).
        kl_weight: weight of the KL term (PSIK).
        kl_anneal: steps over which the KL weight rises linearly from 0 to ``kl_weight``
            (0: the full weight from the first step); a PSIK started from a SIK model first
            fits with little KL pull, then its indices are drawn towards the prior.
        val_rows: rows held out for validation.
        eval_every: steps between validations.
        checkpoint_every: steps between checkpoints.
        seed: seed of initialisation, batches and validation split.
        threads: torch intra-op threads.
        device: ``cpu`` or ``cuda``.
        uni_position: keep one row per distinct position (the paper's uni-position dataset).
        pso_particles: particles of the swarm (ANFIS).
        pso_batch: samples per swarm evaluation (ANFIS).
        bf16: run forward and backward under bfloat16 autocast (weights and optimiser stay
            float32); about twice the samples/s on CPUs with bfloat16 units
            (bench/train_step.py).
        sampler: ``dataset`` (batches of the collected rows) or ``uniform`` (every batch drawn
            afresh: joint angles uniform within the limits, their tips by torch FK; the
            dataset still gives the normaliser and the validation rows).
        cycle_weight: weight of the cycle term (SIK, PSIK): each sample's posture index is
            decoded at its goal position moved by a random offset (``cycle_shift`` [m] per
            axis, as an index from a nearby table cell is used), re-encoded, and must give
            the index back (squared error over the batch's index variance); the FK error of
            that posture at the moved goal joins the FK term. It keeps an FK-driven decoder
            from ignoring the index (docs/training.md).
        cycle_shift: standard deviation of the goal offset of the cycle term [m].
        cycle_turn: pose goals: the cycle term also turns the goal's orientation about a
            random axis by an angle of this standard deviation [rad] (an index from a table
            row of a nearby orientation decoded at the goal must reach it).
        anchor_joint: SIK: a joint the first learned index element is drawn towards
            (``-1``: none). With the pose goal and the branch code, one joint and the goal
            give the rest of a 7-joint arm's posture (the Panda's last joint, as its
            analytical IK takes it), so the decoder has a posture to learn from the first
            step instead of averaging the self-motion; the pull is released over
            ``anchor_steps`` and the index then keeps what the decoder made of it.
        anchor_weight: weight of that pull at the first step (the squared difference of the
            element and the normalised joint).
        anchor_steps: steps over which the pull falls linearly to zero (0: always on).
        init: model file the weights started from (``--init``; provenance only).
    """

    steps: int = 100_000
    batch_size: int = 2048
    lr: float = 1e-3
    lr_min: float = 1e-5
    warmup: int = 500
    fk_weight: float = 1.0
    fk_start: int = 0
    fk_scale: float = 0.05
    rot_weight: float = 1.0
    kl_weight: float = 1e-3
    kl_anneal: int = 0
    val_rows: int = 20_000
    eval_every: int = 1000
    checkpoint_every: int = 2000
    seed: int = 0
    threads: int = 1
    device: str = 'cpu'
    uni_position: bool = False
    pso_particles: int = 100
    pso_batch: int = 4096
    bf16: bool = False
    sampler: str = 'dataset'
    cycle_weight: float = 0.0
    cycle_shift: float = 0.02
    cycle_turn: float = 0.0
    anchor_joint: int = -1
    anchor_weight: float = 0.0
    anchor_steps: int = 0
    init: str = ''

    def __post_init__(self):
        """Validate the fields."""
        for name in ('steps', 'batch_size', 'eval_every', 'checkpoint_every', 'threads'):
            if getattr(self, name) < 1:
                raise InvalidArgument(f'{name} must be at least 1; got {getattr(self, name)}')
        if not (self.lr > 0 and math.isfinite(self.lr)):
            raise InvalidArgument(f'lr must be a positive number; got {self.lr}')
        if self.kl_anneal < 0:
            raise InvalidArgument(f'kl_anneal must be 0 or more steps; got {self.kl_anneal}')
        if self.sampler not in SAMPLERS:
            raise InvalidArgument(f'sampler must be one of {", ".join(SAMPLERS)}; '
                                  f'got {self.sampler!r}')
        if not (self.cycle_weight >= 0 and math.isfinite(self.cycle_weight)):
            raise InvalidArgument(f'cycle_weight must be a non-negative number; '
                                  f'got {self.cycle_weight}')
        if not (self.anchor_weight >= 0 and math.isfinite(self.anchor_weight)):
            raise InvalidArgument(f'anchor_weight must be a non-negative number; '
                                  f'got {self.anchor_weight}')
        if self.anchor_steps < 0:
            raise InvalidArgument(f'anchor_steps must be 0 or more; got {self.anchor_steps}')
        if self.device not in ('cpu', 'cuda'):
            raise InvalidArgument(f'device must be cpu or cuda; got {self.device!r}')
        if self.device == 'cuda' and not _cuda_available():
            raise InvalidArgument('device cuda requested but no CUDA device is available')


def lr_at(cfg: TrainConfig, step: int) -> float:
    """Learning rate at a step: linear warm-up then cosine decay to ``lr_min``."""
    if step < cfg.warmup:
        return cfg.lr * (step + 1) / cfg.warmup
    t = min(1.0, (step - cfg.warmup) / max(1, cfg.steps - cfg.warmup))
    return cfg.lr_min + 0.5 * (cfg.lr - cfg.lr_min) * (1 + math.cos(math.pi * t))


def kl_weight_at(cfg: TrainConfig, step: int) -> float:
    """Weight of the KL term at a step: rising linearly over ``kl_anneal`` steps."""
    if cfg.kl_anneal <= 0:
        return cfg.kl_weight
    return cfg.kl_weight * min(1.0, (step + 1) / cfg.kl_anneal)


def anchor_weight_at(cfg: TrainConfig, step: int) -> float:
    """Weight of the index anchor at a step: falling linearly to 0 over ``anchor_steps``."""
    if cfg.anchor_joint < 0:
        return 0.0
    if cfg.anchor_steps <= 0:
        return cfg.anchor_weight
    return cfg.anchor_weight * max(0.0, 1.0 - step / cfg.anchor_steps)


def with_overrides(cfg: TrainConfig, **kw) -> TrainConfig:
    """A copy of a config with some fields replaced (None values ignored)."""
    return replace(cfg, **{k: v for k, v in kw.items() if v is not None})


def _cuda_available() -> bool:
    """Whether torch sees a CUDA device (torch loaded only when CUDA is asked for)."""
    import torch
    return torch.cuda.is_available()
