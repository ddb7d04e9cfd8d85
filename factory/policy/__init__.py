"""Policies on factory scenes: the simulation env, training (``stage=train``) and closed-loop
evaluation (``stage=eval``).

Importing this package is cheap (no mujoco, torch or lerobot); the names below load their
module on first use.
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY: dict[str, str] = {
    "PickPlaceEnv": "factory.policy.env",
    "PickPlaceVectorEnv": "factory.policy.env",
    "make_vec_env": "factory.policy.env",
    "eval_seed": "factory.policy.env",
    "ObsSpec": "factory.policy.obs_spec",
    "PickPlaceVecEnv": "factory.policy.vector_env",
}
"""Public name -> the module that defines it."""

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'factory.policy' has no attribute {name!r}")
