"""The MJX backend: MuJoCo's JAX implementation (``impl="jax"``), for small models only.

MJX unrolls collision code per geom pair at trace time, so compilation time grows quickly with
the number of free bodies (minutes at ~20). Models with more than ``max_free_bodies`` free
bodies are refused with a pointer to the ``warp`` backend. The compiled step is cached per
model layout, so repeated calls on one model pay the compile once.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from factory.errors import ConfigError
from factory.sim.backend import Rollout, check_qpos, nonfinite_rows, one_model


class MjxBackend:
    """MJX settling (``jax.vmap`` over candidates, ``lax.fori_loop`` over steps).

    Args:
        max_free_bodies: refuse larger models (their compile takes minutes).
        chunk: candidates per device call.
    """

    name = "mjx"

    def __init__(self, max_free_bodies: int = 8, chunk: int = 1024) -> None:
        self.max_free_bodies = max_free_bodies
        self.chunk = chunk
        self._cache: dict[tuple[int, int], Any] = {}

    def _free_bodies(self, model: mujoco.MjModel) -> int:
        return int(np.sum(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE))

    def _compiled(self, model: mujoco.MjModel, nstep: int) -> Any:
        key = (id(model), nstep)
        if key not in self._cache:
            import jax
            from mujoco import mjx

            mx = mjx.put_model(model, impl="jax")
            d0 = mjx.make_data(mx, impl="jax")

            def settle_one(qpos: Any) -> Any:
                d = d0.replace(qpos=qpos)
                d = jax.lax.fori_loop(0, nstep, lambda _, dd: mjx.step(mx, dd), d)
                return d.qpos

            self._cache = {key: jax.jit(jax.vmap(settle_one))}
        return self._cache[key]

    def settle(
        self,
        model: mujoco.MjModel | Sequence[mujoco.MjModel],
        qpos0: np.ndarray,
        nstep: int,
    ) -> Rollout:
        model = one_model(model, "mjx")
        k = self._free_bodies(model)
        if k > self.max_free_bodies:
            raise ConfigError(
                f"the mjx backend is for small models: this one has {k} free bodies "
                f"(> {self.max_free_bodies}), and MJX would compile for minutes; use "
                "sim.backend=warp (GPU) or sim.backend=cpu"
            )
        q = check_qpos(model, qpos0)
        invalid = nonfinite_rows(q)
        reasons = ["non-finite initial pose" if b else "" for b in invalid]
        out = q.copy()
        fn = self._compiled(model, nstep)
        seconds = 0.0
        run = np.flatnonzero(~invalid)
        for start in range(0, len(run), self.chunk):
            ids = run[start : start + self.chunk]
            t0 = time.perf_counter()
            final = np.asarray(fn(q[ids]))
            seconds += time.perf_counter() - t0
            out[ids] = final
            bad = ~np.isfinite(final).all(axis=1)
            for i in ids[bad]:
                invalid[i] = True
                reasons[i] = "NaN in the final pose (simulation diverged)"
        return Rollout(qpos=out, invalid=invalid, reasons=reasons, seconds=seconds)
