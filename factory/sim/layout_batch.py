"""Scenes that share a layout, checked in one batch.

Configuration-level variants of a scene (and repeated scenes) compile to models that differ
only in where their free bodies start: the same bodies, geoms, meshes, masses and static
furniture. Such models are one simulation model with different initial ``qpos`` rows, so
``stage=validate`` checks them as the candidates of one batched call (one GPU launch for a
whole group of variants instead of one launch per scene) and gets the verdicts a call per
scene gives.

The layout key hashes every numeric array and option of the model with the free bodies'
initial poses (``qpos0`` and their ``body_pos``/``body_quat``, which a free joint overrides,
and what the compiler derives from ``qpos0``: camera and light frames, the constraint
weights ``*_invweight0`` and ``dof_M0``) zeroed and names left out, so two models share a key
only when everything else is byte-identical. The CPU backend still simulates each scene's own
model in the batch (``mujoco.batch`` takes one model per row): its verdicts are exactly the
per-scene ones. GPU backends run one model per batch, the group's first: the others'
qpos0-derived constraint weights (which depend on how the free bodies start turned) are
replaced by its own, a difference far below the protocol's thresholds.
"""

from __future__ import annotations

import copy
import hashlib
import logging
from collections.abc import Mapping
from typing import Any

import mujoco
import numpy as np

from factory.sim.stability import StabilityProtocol, StabilityResult, check_stability

log = logging.getLogger(__name__)


_POSE_FIELDS = (
    "qpos0",
    "qpos_spring",
    # Camera and light frames at qpos0 (rendering only) follow the free bodies too.
    "cam_pos0",
    "cam_poscom0",
    "cam_mat0",
    "light_pos0",
    "light_poscom0",
    "light_dir0",
    # Inverse weights and the diagonal inertia at qpos0 (constraint regularisation) follow
    # the free bodies' orientations.
    "body_invweight0",
    "dof_invweight0",
    "dof_M0",
)
_NAME_FIELDS = ("names", "paths", "names_map")


def layout_key(model: mujoco.MjModel) -> str:
    """A hash of everything in ``model`` but the free bodies' initial poses and the names
    (hex sha256): every numeric array of the model and its options."""
    m = copy.copy(model)
    free = np.flatnonzero(m.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    bodies = m.jnt_bodyid[free]
    m.body_pos[bodies] = 0.0
    m.body_quat[bodies] = 0.0
    for name in _POSE_FIELDS:
        getattr(m, name)[:] = 0.0
    h = hashlib.sha256()
    for name in sorted(dir(m)):
        if name.startswith("_") or name in _NAME_FIELDS or name.startswith("name_"):
            continue
        value = getattr(m, name)
        if isinstance(value, np.ndarray):
            h.update(name.encode())
            h.update(np.ascontiguousarray(value).tobytes())
    for obj in (m.opt,):
        for name in sorted(dir(obj)):
            if not name.startswith("_"):
                value = getattr(obj, name)
                if isinstance(value, (int, float, np.ndarray)):
                    h.update(name.encode())
                    h.update(np.asarray(value).tobytes())
    return h.hexdigest()


def check_by_layout(
    models: Mapping[str, mujoco.MjModel],
    backend: Any,
    protocol: StabilityProtocol,
) -> dict[str, StabilityResult]:
    """Checks each model at its own initial state, models of one layout in one batch.

    Args:
        models: scene id -> compiled model.
        backend: a physics backend instance.
        protocol: the stability protocol.

    Returns:
        scene id -> a one-candidate result, as ``check_stability(model)`` would give it.
    """
    groups: dict[str, list[str]] = {}
    for sid, model in models.items():
        groups.setdefault(layout_key(model), []).append(sid)
    out: dict[str, StabilityResult] = {}
    for ids in groups.values():
        qpos = np.stack([models[sid].qpos0 for sid in ids])
        # The CPU backend runs each model (exactly the per-scene call); one-model backends
        # (GPU) run the first: its qpos0-derived constraint weights stand for all.
        target: Any = [models[sid] for sid in ids] if backend.name == "cpu" else models[ids[0]]
        result = check_stability(target, qpos, backend=backend, protocol=protocol)
        for k, sid in enumerate(ids):
            out[sid] = result.rows([k])
    log.info(
        "validate: %d scene(s) in %d layout batch(es) (largest %d)",
        len(models),
        len(groups),
        max((len(g) for g in groups.values()), default=0),
    )
    return out


__all__ = ["check_by_layout", "layout_key"]
