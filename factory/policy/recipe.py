"""What a training sets unless ``train.*`` says otherwise: the diffusion recipe per kind of
input, the learning rate, the numeric precision, the auxiliary state loss and the weight
average (EMA).

The state recipe was chosen by a sweep of six recipes trained side by side
(``benchmarks/results/policy-recipe-sweep-h100.json``; docs/POLICY.md). The image recipe
(``train.inputs=rgb`` / ``rgbd``) was chosen for speed by the measurements of
``scripts/bench_policy.py --variants`` on one H100 (training samples per second of each
variant on the same data, ``benchmarks/results/policy-recipe-rgbd-h100.json`` and
``policy-speed-rgbd-h100-bare.json``). Its held-out success is not established: the one run so
far (H200, 13 minutes, before the scenes lost their look-alike mugs and bowls) acted on none of
270 held-out configurations (docs/POLICY.md, "The paper's setting").
"""

from __future__ import annotations

from typing import Any

PRECISIONS = ("auto", "bf16", "fp32")
"""``train.precision`` settings."""

STATE_DIFFUSION_DEFAULTS: dict[str, Any] = {
    "prediction_type": "sample",
    "noise_scheduler_type": "DDIM",
    "num_inference_steps": 10,
}
"""Diffusion with ``train.inputs=state``, unless ``train.options`` says otherwise: predict the
clean action chunk rather than the noise, and sample it in 10 DDIM steps. With
:data:`DIFFUSION_LR` this took held-out success from 13.3 % (lerobot's preset) to 56.7 %
at the same 8,700 steps (``benchmarks/results/policy-recipe-sweep-h100.json``)."""

IMAGE_DIFFUSION_DEFAULTS: dict[str, Any] = {
    **STATE_DIFFUSION_DEFAULTS,
    "n_obs_steps": 1,
    "down_dims": (128, 256, 512),
    "resize_shape": (84, 84),
    "crop_ratio": 1.0,
}
"""Diffusion with ``train.inputs=rgb`` or ``rgbd``: the state recipe, one observation step
(the images of the newest frame; the joints and tool pose say how the arm moves), a U-Net of
128-256-512 channels (the state policies' size), and every camera image resized to 84 x 84 on
the device before the shared ResNet-18 (a 3 x 3 feature map, as at 96 px; random shifts of the
batch loader replace the random crop). On one H100, 96 px, two observation steps and a U-Net of
256-512-1024 trained at 1,757 samples/s with the GPU 99 % busy: the convolutions of twelve
images a sample are the bound, so each of these settings cuts them
(``benchmarks/results/policy-recipe-rgbd-h100.json``)."""

PERCEPTION_DIFFUSION_DEFAULTS: dict[str, Any] = {
    **STATE_DIFFUSION_DEFAULTS,
    "down_dims": (128, 256, 512),
}
"""The lerobot policy of ``train.vision=perception`` (it reads the robot state and the poses
that :mod:`factory.policy.perception` predicts): the state recipe with the U-Net of the state
policy that reached 75.6 % on 3 held-out kitchens after training on 16
(``benchmarks/results/scaling-h200.json``: 128-256-512 channels, 17 M parameters, where
lerobot's default 512-1024-2048 has 250 M)."""

DIFFUSION_LR = 3e-4
"""Learning rate of a diffusion policy when ``train.lr`` is 0 (lerobot's preset: 1e-4)."""
STATE_DIFFUSION_LR = DIFFUSION_LR
"""The same, by its older name."""

IMAGE_AUX_STATE = 1.0
"""``train.aux_state`` of an image diffusion policy of a dataset with the object poses, when not
set."""
IMAGE_EMA = 0.999
"""``train.ema`` of an image diffusion policy, when not set."""


def resolve_compile(setting: bool | None, policy: str, inputs: str, device: str) -> bool:
    """Whether ``train.compile`` compiles: the setting, or (None) on for an image diffusion
    policy on CUDA. On one bare H100 at batch 512 (bf16, the RGB-D recipe) compiling took
    9,065 training samples/s against 6,106 (1.48x) for 96 s more before the first step
    (``benchmarks/results/policy-speed-rgbd-h100-bare.json``); a CPU would compile for
    minutes and gain little."""
    if setting is None:
        return policy == "diffusion" and image_inputs(inputs) and device.startswith("cuda")
    return bool(setting)


def image_inputs(inputs: str) -> bool:
    """Whether ``train.inputs`` reads camera images."""
    return inputs in ("rgb", "rgbd")


def diffusion_defaults(inputs: str, perception: bool = False) -> dict[str, Any]:
    """The policy config fields a diffusion policy on these inputs gets by default
    (``perception``: the lerobot policy of ``train.vision=perception``)."""
    if perception:
        return dict(PERCEPTION_DIFFUSION_DEFAULTS)
    return dict(IMAGE_DIFFUSION_DEFAULTS if image_inputs(inputs) else STATE_DIFFUSION_DEFAULTS)


def default_lr(policy: str) -> float:
    """The learning rate when ``train.lr`` is 0 (0: the policy's preset)."""
    return DIFFUSION_LR if policy == "diffusion" else 0.0


def resolve_precision(setting: str, device: str) -> str:
    """``bf16`` or ``fp32`` for ``train.precision`` on ``device``: ``auto`` is bf16 autocast
    on CUDA (tensor cores; the weights stay fp32) and fp32 on a CPU."""
    if setting == "auto":
        return "bf16" if device.startswith("cuda") else "fp32"
    return setting


def resolve_aux_state(setting: float | None, policy: str, inputs: str, poses: bool) -> float:
    """The weight of the auxiliary state loss (0: off): ``train.aux_state``, or
    :data:`IMAGE_AUX_STATE` for an image diffusion policy. Off without images and where the
    dataset does not record the object poses it predicts (``poses``:
    :attr:`~factory.policy.inputs.InputSpec.poses`; e.g. a mobile dataset exported before its
    ``observation.environment_state``)."""
    if not poses or not image_inputs(inputs):
        return 0.0
    if setting is None:
        return IMAGE_AUX_STATE if policy == "diffusion" else 0.0
    return float(setting)


def resolve_ema(setting: float | None, policy: str, inputs: str) -> float:
    """The EMA decay of the saved weights (0: off): ``train.ema``, or :data:`IMAGE_EMA` for
    an image diffusion policy."""
    if setting is None:
        return IMAGE_EMA if policy == "diffusion" and image_inputs(inputs) else 0.0
    return float(setting)
