"""The auxiliary state loss of image policies (``train.aux_state``).

A diffusion policy that reads cameras must learn from the action loss alone where the objects
are, which takes far longer than learning the motion (a state policy, told the poses, learns
the task in minutes). Here a small head reads the image features that lerobot's encoder
computes for the newest observation step (all cameras; tapped by a forward hook, so the model
and its forward pass are lerobot's own) and predicts the environment state of that frame: the
pick object's and the target's poses in the robot's base frame and the tool's offsets to them
(:func:`factory.policy.inputs.env_features`, 24 values scaled to [-1, 1] by their range over
the training frames). Its mean squared error, weighted, is added to the policy's loss. The
head is training-only: the checkpoint's ``pretrained_model`` is a plain lerobot policy, and the
head's weights are kept in ``training_state`` for a resumed training.
"""

from __future__ import annotations

from typing import Any

import numpy as np

AUX_TARGET = "aux.environment_state"
"""Batch key of the auxiliary target (B, 24): the environment state of each sample's frame
(popped from the batch before lerobot's processors, which drop keys they do not know)."""
HIDDEN = 256
"""Width of the head's hidden layer."""


def _torch() -> Any:
    import torch

    return torch


class FeatureTap:
    """Keeps the output of lerobot's image encoder(s) of the last forward pass.

    Args:
        encoder: ``policy.diffusion.rgb_encoder``: one module shared by the cameras, or a
            ``ModuleList`` of one per camera (``use_separate_rgb_encoder_per_camera``).
    """

    def __init__(self, encoder: Any) -> None:
        self.separate = isinstance(encoder, _torch().nn.ModuleList)
        modules = list(encoder) if self.separate else [encoder]
        self.outputs: list[Any] = []
        self.handles = [m.register_forward_hook(self._keep) for m in modules]

    def _keep(self, module: Any, inputs: Any, output: Any) -> None:
        self.outputs.append(output)

    def take(self, batch_size: int, n_obs: int, n_cams: int) -> Any:
        """The newest observation step's features of every camera, (B, n_cams * D); clears the
        kept outputs.

        The shared encoder's output is (B * n_obs * n_cams, D) in lerobot's ``(b s n)`` order;
        separate encoders give one (B * n_obs, D) per camera.
        """
        torch = _torch()
        outs, self.outputs = self.outputs, []
        if not outs:
            raise RuntimeError("the image encoder did not run: no features to read")
        if self.separate:
            feats = torch.stack(outs[-n_cams:], 0)  # (n, b*s, d)
            feats = feats.reshape(n_cams, batch_size, n_obs, -1).permute(1, 2, 0, 3)
        else:
            feats = outs[-1].reshape(batch_size, n_obs, n_cams, -1)
        return feats[:, -1].reshape(batch_size, -1)

    def clear(self) -> None:
        self.outputs = []

    def remove(self) -> None:
        for h in self.handles:
            h.remove()


def make_head(in_dim: int, target: np.ndarray) -> Any:
    """The head: ``in_dim`` image features -> the target's width, with the target's range
    over the training frames (``target``: (N, T)) as buffers for the scaling."""
    torch = _torch()

    class AuxStateHead(torch.nn.Module):  # type: ignore[name-defined]
        """MLP from image features to the environment state scaled to [-1, 1]."""

        def __init__(self) -> None:
            super().__init__()
            dim = int(target.shape[-1])
            self.net = torch.nn.Sequential(
                torch.nn.Linear(in_dim, HIDDEN), torch.nn.ReLU(), torch.nn.Linear(HIDDEN, dim)
            )
            low = torch.as_tensor(target.min(0), dtype=torch.float32)
            high = torch.as_tensor(target.max(0), dtype=torch.float32)
            self.register_buffer("low", low)
            self.register_buffer("span", torch.clamp(high - low, min=1e-6))

        def loss(self, feats: Any, value: Any) -> Any:
            """Mean squared error of the prediction from ``feats`` (B, in_dim) against the
            environment state ``value`` (B, T), both scaled to [-1, 1]."""
            want = 2 * (value.float() - self.low) / self.span - 1
            got = self.net(feats.float())
            return torch.nn.functional.mse_loss(got, want)

    return AuxStateHead()
