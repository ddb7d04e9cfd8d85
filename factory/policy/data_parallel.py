"""Data-parallel training on several GPUs of one node (``train.gpus=N``).

``stage=train`` starts ``N`` processes (``spawn``; rank ``r`` on ``cuda:r``, or on the CPU with
``train.device=cpu``, which the tests use), each with lerobot's way of joining them: an
``accelerate.Accelerator`` (which reads ``RANK``, ``WORLD_SIZE``, ``MASTER_ADDR`` /
``MASTER_PORT`` set here and sets up the NCCL or gloo process group). Every rank builds the same
model from the same seed, holds the training frames in its own device memory
(:class:`~factory.policy.device_batches.DeviceBatches`, its own sample order: ``train.seed`` +
rank) and computes the loss of its own batch of ``train.batch_size`` samples (the effective
batch is ``N`` times that); after each backward pass the gradients of the policy and of the
auxiliary head are averaged over the ranks in one flat all-reduce (:class:`GradientSync`), so
the weights stay equal without a model wrapper (the policy stays lerobot's own module, saved
as it is). Rank 0 alone logs, saves checkpoints and runs the learning curve; the decision to
stop at ``train.max_minutes`` is rank 0's, shared at each logged step.
"""

from __future__ import annotations

import logging
import os
import socket
from typing import Any

log = logging.getLogger(__name__)


def free_port() -> int:
    """A free TCP port on this host for the process group's rendezvous."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _rank_main(rank: int, world: int, port: int, device: str, fn: Any, args: tuple) -> None:
    os.environ.update(
        {
            "RANK": str(rank),
            "LOCAL_RANK": str(rank),
            "WORLD_SIZE": str(world),
            "LOCAL_WORLD_SIZE": str(world),
            "MASTER_ADDR": "127.0.0.1",
            "MASTER_PORT": str(port),
        }
    )
    if rank == 0:  # a spawned process has no handlers: rank 0 speaks where stderr goes
        logging.basicConfig(
            level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s"
        )
    else:
        logging.getLogger("factory").setLevel(logging.WARNING)
    from accelerate import Accelerator

    accelerator = Accelerator(cpu=not device.startswith("cuda"))
    try:
        fn(accelerator, *args)
    finally:
        import torch.distributed as dist

        if dist.is_initialized():
            dist.destroy_process_group()


def launch(world: int, device: str, fn: Any, args: tuple) -> None:
    """Runs ``fn(accelerator, *args)`` in ``world`` spawned processes and waits for them.

    Raises:
        the first rank's error, re-raised by torch's process context.
    """
    import torch.multiprocessing as mp

    port = free_port()
    log.info("train: %d data-parallel processes on %s (port %d)", world, device, port)
    mp.start_processes(
        _rank_main,
        args=(world, port, device, fn, args),
        nprocs=world,
        join=True,
        start_method="spawn",
    )


class GradientSync:
    """Averages the gradients of ``params`` over the ranks: one flat all-reduce per step."""

    def __init__(self, accelerator: Any, params: list[Any]) -> None:
        self.acc = accelerator
        self.params = params
        self.world = int(accelerator.num_processes)

    @property
    def rank(self) -> int:
        return int(self.acc.process_index)

    def broadcast_weights(self) -> None:
        """Rank 0's weights to every rank (the same seed gives the same weights; this makes
        sure)."""
        import torch.distributed as dist

        for p in self.params:
            dist.broadcast(p.data, 0)

    def average(self) -> None:
        import torch
        import torch.distributed as dist

        grads = [p.grad if p.grad is not None else torch.zeros_like(p) for p in self.params]
        flat = torch.cat([g.reshape(-1).float() for g in grads])
        dist.all_reduce(flat)
        flat /= self.world
        offset = 0
        for p, g in zip(self.params, grads, strict=True):
            n = g.numel()
            chunk = flat[offset : offset + n].view_as(g).to(g.dtype)
            if p.grad is None:
                p.grad = chunk.clone()
            else:
                p.grad.copy_(chunk)
            offset += n

    def any(self, flag: bool) -> bool:
        """Whether rank 0 says so (every rank gets rank 0's ``flag``)."""
        import torch
        import torch.distributed as dist

        t = torch.tensor([1 if flag else 0], device=self.acc.device)
        dist.broadcast(t, 0)
        return bool(t.item())
