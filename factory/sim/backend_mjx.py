"""The MJX backend: MJX's Warp implementation on CUDA, its JAX implementation elsewhere.

* ``impl="warp"`` (default with a CUDA device and ``mujoco_warp`` installed): MJX calls MuJoCo
  Warp's kernels through JAX (``mjx.put_model(m, impl="warp")``); any number of free bodies.
  Contact and constraint buffers are sized as the ``warp`` backend sizes them
  (``naconmax`` counts the contacts of all worlds of a call).
* ``impl="jax"`` (CPU, or no Warp): MJX unrolls collision code per geom pair at trace time, so
  compilation time grows quickly with the number of free bodies (minutes at ~20); models with
  more than ``max_free_bodies`` free bodies are refused with a pointer to the ``warp``
  backend.

Candidates are ``jax.vmap``-ed, the steps run in a ``lax.fori_loop`` inside one jitted call.
The compiled call is cached per model, step count and batch size, so repeated calls on one
model pay the compile once.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from factory.errors import ConfigError
from factory.sim.backend import Rollout, check_qpos, cuda_available, nonfinite_rows, one_model

IMPLS = ("auto", "warp", "jax")


class MjxBackend:
    """MJX settling (``jax.vmap`` over candidates, ``lax.fori_loop`` over steps).

    Args:
        max_free_bodies: with ``impl="jax"``, refuse larger models (their compile takes
            minutes).
        chunk: candidates per device call.
        impl: ``auto`` (``warp`` with CUDA and ``mujoco_warp``, else ``jax``), ``warp``,
            ``jax``.
    """

    name = "mjx"

    def __init__(self, max_free_bodies: int = 8, chunk: int = 1024, impl: str = "auto") -> None:
        if impl not in IMPLS:
            raise ConfigError(f"mjx impl={impl!r} is not one of {', '.join(IMPLS)}")
        if impl == "auto":
            import importlib.util

            warp = importlib.util.find_spec("mujoco_warp") is not None
            impl = "warp" if warp and cuda_available() else "jax"
        self.impl = impl
        self.max_free_bodies = max_free_bodies
        self.chunk = chunk
        self._cache: dict[tuple[int, int, int], Any] = {}

    def _free_bodies(self, model: mujoco.MjModel) -> int:
        return int(np.sum(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE))

    def _compiled(self, model: mujoco.MjModel, nstep: int, n: int, sample: np.ndarray) -> Any:
        key = (id(model), nstep, n)
        if key not in self._cache:
            import jax
            from mujoco import mjx

            mx = mjx.put_model(model, impl=self.impl)
            if self.impl == "warp":
                from factory.sim.backend_warp import WarpBackend

                nconmax, njmax = WarpBackend.initial_sizes(model, sample)
                d0 = mjx.make_data(model, impl="warp", naconmax=n * nconmax, njmax=njmax)
            else:
                d0 = mjx.make_data(mx, impl="jax")
            step = jax.vmap(mjx.step, in_axes=(None, 0))

            def settle_all(qpos: Any) -> Any:
                d = jax.vmap(lambda q: d0.replace(qpos=q))(qpos)
                d = jax.lax.fori_loop(0, nstep, lambda _, dd: step(mx, dd), d)
                return d.qpos

            self._cache = {key: jax.jit(settle_all)}
        return self._cache[key]

    def settle(
        self,
        model: mujoco.MjModel | Sequence[mujoco.MjModel],
        qpos0: np.ndarray,
        nstep: int,
    ) -> Rollout:
        model = one_model(model, "mjx")
        k = self._free_bodies(model)
        if self.impl == "jax" and k > self.max_free_bodies:
            raise ConfigError(
                f"the mjx backend's JAX implementation is for small models: this one has {k} "
                f"free bodies (> {self.max_free_bodies}), and MJX would compile for minutes; "
                "use sim.backend=warp or sim.backend=mjx on a CUDA machine (MJX's Warp "
                "implementation), or sim.backend=cpu"
            )
        q = check_qpos(model, qpos0)
        invalid = nonfinite_rows(q)
        reasons = ["non-finite initial pose" if b else "" for b in invalid]
        out = q.copy()
        seconds = 0.0
        run = np.flatnonzero(~invalid)
        for start in range(0, len(run), self.chunk):
            ids = run[start : start + self.chunk]
            fn = self._compiled(model, nstep, len(ids), q[ids])
            t0 = time.perf_counter()
            final = np.asarray(fn(q[ids]), dtype=np.float64)
            seconds += time.perf_counter() - t0
            out[ids] = final
            bad = ~np.isfinite(final).all(axis=1)
            for i in ids[bad]:
                invalid[i] = True
                reasons[i] = "NaN in the final pose (simulation diverged)"
        return Rollout(qpos=out, invalid=invalid, reasons=reasons, seconds=seconds)
