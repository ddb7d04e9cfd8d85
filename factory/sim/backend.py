"""Physics backends for batched settling: one interface, three implementations.

A backend runs ``n`` copies of one model (or ``n`` models of one layout) from given initial
positions, at rest, for ``nstep`` steps, and returns the final positions plus a per-simulation
``invalid`` flag with a reason (NaN, contact or constraint buffer overflow, MuJoCo error).

Registry (resolved lazily; importing this module imports no backend):

* ``cpu``: ``mujoco.batch.Batch`` on a thread pool, the reference (:mod:`.backend_cpu`);
* ``warp``: MuJoCo Warp on CUDA (or Warp's CPU device), graph-captured (:mod:`.backend_warp`);
* ``mjx``: MJX's JAX implementation, small models only (:mod:`.backend_mjx`).

``auto`` picks ``warp`` when a CUDA device and ``mujoco_warp`` are available, else ``cpu``.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import mujoco
import numpy as np

from factory.errors import ConfigError

log = logging.getLogger(__name__)

BACKENDS: dict[str, str] = {
    "cpu": "factory.sim.backend_cpu:CpuBackend",
    "warp": "factory.sim.backend_warp:WarpBackend",
    "mjx": "factory.sim.backend_mjx:MjxBackend",
}


@dataclass
class Rollout:
    """The outcome of settling ``n`` simulations.

    Attributes:
        qpos: final joint positions, ``(n, nq)``.
        invalid: ``(n,)`` bool: the simulation cannot be trusted (never report it stable).
        reasons: ``n`` strings, empty where valid.
        seconds: wall time of the simulation itself (s), excluding set-up.
    """

    qpos: np.ndarray
    invalid: np.ndarray
    reasons: list[str] = field(default_factory=list)
    seconds: float = 0.0


class Backend(Protocol):
    """What a physics backend provides."""

    name: str

    def settle(
        self,
        model: mujoco.MjModel | Sequence[mujoco.MjModel],
        qpos0: np.ndarray,
        nstep: int,
    ) -> Rollout:
        """Simulates each row of ``qpos0`` ``(n, nq)`` from rest for ``nstep`` steps.

        ``model`` is one model for all simulations, or one per simulation (same layout).
        """
        ...


def init_warp() -> Any:
    """Imports and initialises Warp with its per-module load and compile lines off (Warp
    prints them to stdout, past the terminal's filter): ``config.log_level`` at warnings on
    Warp versions that have it (1.19: ``config.quiet`` is gone and silences nothing), else
    ``config.quiet``. Returns the ``warp`` module."""
    import warp as wp

    if hasattr(wp.config, "log_level") and hasattr(wp, "LOG_WARNING"):
        wp.config.log_level = wp.LOG_WARNING
    else:  # pragma: no cover - older Warp
        wp.config.quiet = True  # type: ignore[attr-defined]
    wp.init()
    return wp


def cuda_available() -> bool:
    """Whether a CUDA device is visible (without importing a GPU stack)."""
    if os.environ.get("CUDA_VISIBLE_DEVICES", None) == "":
        return False
    return os.path.exists("/dev/nvidiactl") or os.path.exists("/dev/nvidia0")


def resolve_backend_name(name: str) -> str:
    """``auto`` -> ``warp`` (CUDA + mujoco_warp present) or ``cpu``; others are checked."""
    if name == "auto":
        if cuda_available() and importlib.util.find_spec("mujoco_warp") is not None:
            return "warp"
        return "cpu"
    if name not in BACKENDS:
        raise ConfigError(f"sim.backend={name!r} is not one of auto, {', '.join(BACKENDS)}")
    return name


def get_backend(name: str = "auto", **options: object) -> Backend:
    """Instantiates a backend by name (``auto``, ``cpu``, ``warp``, ``mjx``)."""
    name = resolve_backend_name(name)
    module, cls = BACKENDS[name].split(":")
    backend: Backend = getattr(importlib.import_module(module), cls)(**options)
    return backend


def check_qpos(model: mujoco.MjModel, qpos0: np.ndarray) -> np.ndarray:
    """``qpos0`` as a float64 ``(n, nq)`` array; raises on a wrong shape."""
    q = np.asarray(qpos0, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != model.nq:
        raise ConfigError(f"qpos0 must be (n, {model.nq}), got {q.shape}")
    return q


def one_model(model: mujoco.MjModel | Sequence[mujoco.MjModel], backend: str) -> mujoco.MjModel:
    """The single model of a batch, for backends that run one model per batch."""
    if isinstance(model, mujoco.MjModel):
        return model
    models = list(model)
    if any(m is not models[0] for m in models):
        raise ConfigError(
            f"the {backend} backend runs one model per batch: use the cpu backend for "
            "per-candidate models, or batch candidates of one scene"
        )
    return models[0]


def nonfinite_rows(qpos: np.ndarray) -> np.ndarray:
    """``(n,)`` bool: rows with NaN or infinite entries."""
    return ~np.isfinite(qpos).all(axis=1)
