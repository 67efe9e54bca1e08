"""Training on several processes (GPUs or machines) with ``torch.distributed``.

``torchrun --nproc_per_node N -m sik_ros.cli.train ...`` starts N copies of ``sik-train`` with
``RANK``, ``WORLD_SIZE`` and the rendezvous in their environment; :func:`init` joins them
(NCCL on GPUs, gloo on CPUs), and the trainer wraps its model in
:class:`~torch.nn.parallel.DistributedDataParallel`, which averages the gradients of every step
across the processes. Each process draws its own batches; rank 0 alone writes checkpoints, so
checkpoints and resume are those of a single process.
"""

import os
from typing import Tuple

import torch
import torch.distributed as dist


def world() -> Tuple[int, int]:
    """This process's rank and the number of processes (0, 1 without torchrun)."""
    return int(os.environ.get('RANK', 0)), int(os.environ.get('WORLD_SIZE', 1))


def init(device: str) -> Tuple[int, int]:
    """Join the process group when started by torchrun; the rank and the world size."""
    rank, size = world()
    if size > 1 and not dist.is_initialized():
        backend = 'nccl' if device == 'cuda' else 'gloo'
        dist.init_process_group(backend)
        if device == 'cuda':
            torch.cuda.set_device(int(os.environ.get('LOCAL_RANK', 0)))
    return rank, size


def finish() -> None:
    """Leave the process group (after a last barrier)."""
    if dist.is_initialized():
        dist.barrier()
        dist.destroy_process_group()
