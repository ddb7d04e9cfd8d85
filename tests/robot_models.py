"""Skipping tests that need the robot models where they cannot be made."""

from __future__ import annotations

import importlib.util
import os

import pytest


def require_robot_models() -> None:
    """Skips the calling test (or module, at its top) unless the Panda models can be made:
    robosuite is installed, or the robot caches it would make are present
    (``FACTORY_ROBOT_CACHE``; the GPU bundle of ``scripts/gpu_bundle.sh`` places them on a
    machine without robosuite)."""
    if importlib.util.find_spec("robosuite") is not None:
        return
    from factory.robots.robosuite_models import robosuite_cache_dir

    missing = [n for n in ("panda", "panda-omron") if not robosuite_cache_dir(n).is_dir()]
    if missing:
        root = os.environ.get("FACTORY_ROBOT_CACHE") or "~/.cache/factory/robots"
        pytest.skip(
            f"robosuite is not installed and {root} holds no robot cache of {missing}",
            allow_module_level=True,
        )
