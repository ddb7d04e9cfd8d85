"""An exponential moving average of a model's weights (``train.ema``), as Diffusion Policy
trains its image policies: the averaged weights are what a checkpoint's ``pretrained_model``
holds (what is evaluated), the raw ones what the optimizer steps.

The decay ramps up as in diffusers' ``EMAModel``: ``min(decay, (1 + n) / (10 + n))`` after
``n`` updates, so that the first steps are not averaged with the random initialisation.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any


class EmaWeights:
    """The averaged copy of ``params`` (a list of tensors that train).

    Args:
        params: the model's trained parameters, in a fixed order.
        decay: the largest decay per update, in [0, 1).
        updates: updates done before (a resumed training).
    """

    def __init__(self, params: list[Any], decay: float, updates: int = 0) -> None:
        self.decay = float(decay)
        self.updates = int(updates)
        self.shadow = [p.detach().clone() for p in params]

    def current_decay(self) -> float:
        n = self.updates
        return min(self.decay, (1 + n) / (10 + n))

    def update(self, params: list[Any]) -> None:
        """One averaging step after an optimizer step."""
        import torch

        weight = 1.0 - self.current_decay()
        with torch.no_grad():
            torch._foreach_lerp_(self.shadow, [p.detach() for p in params], weight)
        self.updates += 1

    @contextmanager
    def applied(self, params: list[Any]) -> Iterator[list[Any]]:
        """The averaged weights copied into ``params`` for the block (e.g. a save); yields the
        raw weights, which are copied back after it."""
        import torch

        with torch.no_grad():
            raw = [p.detach().clone() for p in params]
            for p, s in zip(params, self.shadow, strict=True):
                p.copy_(s)
        try:
            yield raw
        finally:
            with torch.no_grad():
                for p, r in zip(params, raw, strict=True):
                    p.copy_(r)
