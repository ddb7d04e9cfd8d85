"""The Warp backend: MuJoCo Warp, one world per candidate, graph-captured stepping.

* Device: ``cuda:0`` when CUDA is present, else Warp's CPU device (slow; used to test this
  code path without a GPU on tiny models).
* Contact and constraint buffers (``nconmax``/``njmax`` per world) are sized from the
  candidates' initial contacts with headroom; a world whose buffers overflow (MuJoCo Warp's
  per-world ``overflow`` bitmask) is re-run with doubled buffers, and reported ``invalid``
  (never stable) if it still overflows after ``max_grow`` doublings.
* Steps are captured once into a CUDA graph of ``graph_steps`` steps and replayed. The device
  data and the graph of the last batch shape are kept: a next call of the same shape (the
  chunks of a large batch, repeated checks of one scene) resets them (``reset_data``) instead
  of uploading a new data set and capturing again.
* Island sleeping (``sleep=True``, MuJoCo's ``mjENBL_SLEEP``): bodies at rest stop being
  simulated until touched, and the run stops early once every world of a launch is asleep
  (checked between graph replays): nothing can move after that, so the final poses are those
  of the full ``nstep``. Sleeping freezes a body whose speed stays under MuJoCo's sleep
  tolerance, so a candidate creeping slower than that stops where it is; the benchmark
  (``scripts/bench_stability.py --agree``) compares these verdicts with the strict ones
  (``sleep=False``). Only on CUDA: on Warp's CPU device MuJoCo Warp 4.0's sleeping solver path
  crashes, so sleeping is off there.
* Warp keeps compiled kernels in its kernel cache (``WARP_CACHE_PATH`` or ``~/.cache/warp``)
  between runs, so only the first run on a machine pays the cold compile.
* MuJoCo Warp computes in float32 (the CPU backend in float64): verdicts agree except for
  candidates within float noise of a threshold.
"""

from __future__ import annotations

import copy
import logging
import time
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from factory.sim.backend import (
    Rollout,
    check_qpos,
    cuda_available,
    init_warp,
    nonfinite_rows,
    one_model,
)

log = logging.getLogger(__name__)


class WarpBackend:
    """MuJoCo Warp settling.

    Args:
        device: Warp device (``cuda:0``, ``cpu``); default: CUDA if present, else CPU.
        chunk: worlds per launch (bounds GPU memory).
        graph_steps: steps per captured CUDA graph.
        max_grow: how many times buffers may double after an overflow.
        sleep: island sleeping, and an early stop once every world is asleep.
    """

    name = "warp"

    def __init__(
        self,
        device: str | None = None,
        chunk: int = 8192,
        graph_steps: int = 50,
        max_grow: int = 2,
        sleep: bool = True,
    ) -> None:
        wp = init_warp()
        self.wp = wp
        self.device = device or ("cuda:0" if cuda_available() else "cpu")
        self.chunk = chunk
        self.graph_steps = graph_steps
        self.max_grow = max_grow
        # MuJoCo Warp 4.0's sleeping solver path crashes on Warp's CPU device (a segfault in
        # smooth_solve_compact): sleeping is a CUDA-only speed-up here.
        self.sleep = sleep and self.device.startswith("cuda")
        self._models: dict[int, Any] = {}
        self._data: dict[tuple[int, int, int, int], Any] = {}
        self.steps_run: list[int] = []
        """Steps each launch of the last :meth:`settle` ran before all its worlds slept."""

    # ---- sizing
    @staticmethod
    def initial_sizes(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[int, int]:
        """``(nconmax, njmax)`` per world from the contacts of a sample of candidates."""
        data = mujoco.MjData(model)
        most = 0
        sample = qpos[np.linspace(0, len(qpos) - 1, min(len(qpos), 16)).astype(int)]
        for q in sample:
            data.qpos[:] = q
            mujoco.mj_forward(model, data)
            most = max(most, int(data.ncon))
        nconmax = max(64, 2 * most + 4 * int(np.sum(model.jnt_type == 0)) + 16)
        rows_per_contact = 4 if model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL else 6
        njmax = max(256, rows_per_contact * nconmax + model.nv)
        return int(nconmax), int(njmax)

    def _warp_model(self, model: mujoco.MjModel) -> Any:
        import mujoco_warp as mjw

        key = id(model)
        if key not in self._models:
            # A copy with this backend's sleep flag: put_model and put_data must both see it
            # (put_data sizes the sleeping arrays from the model's flags).
            flagged = copy.copy(model)
            bit = int(mujoco.mjtEnableBit.mjENBL_SLEEP)
            flags = int(model.opt.enableflags)
            flagged.opt.enableflags = flags | bit if self.sleep else flags & ~bit
            with self.wp.ScopedDevice(self.device):
                m = mjw.put_model(flagged)
            bits = mjw.OverflowType
            m.opt.warn_overflow = int(
                bits.NEFC
                | bits.NJMAX_NNZ
                | bits.BROADPHASE
                | bits.NARROWPHASE
                | bits.CCD
                | bits.EPA_HORIZON
            )
            self._models = {key: (model, flagged, m)}
            self._data = {}
        return self._models[key][2]

    # ---- stepping
    def _run(
        self, model: mujoco.MjModel, q: np.ndarray, nstep: int, nconmax: int, njmax: int
    ) -> tuple[np.ndarray, np.ndarray, float]:
        import mujoco_warp as mjw

        wp = self.wp
        m = self._warp_model(model)
        flagged = self._models[id(model)][1]
        n = len(q)
        with wp.ScopedDevice(self.device):
            key = (id(model), n, nconmax, njmax)
            if key in self._data:  # the same batch shape again: reset, keep the graph
                d, graph = self._data[key]
                mjw.reset_data(m, d)
                d.overflow.zero_()
            else:
                mjd = mujoco.MjData(flagged)
                d = mjw.put_data(flagged, mjd, nworld=n, nconmax=nconmax, njmax=njmax)
                graph = None
            d.qpos.assign(wp.array(q.astype(np.float32), dtype=float))
            t0 = time.perf_counter()
            # A captured graph is only recorded, not run: every step below is launched once.
            use_graph = self.device.startswith("cuda")
            left = nstep
            while left > 0 and not self._all_asleep(d):
                k = min(self.graph_steps, left)
                if use_graph and k == self.graph_steps:
                    if graph is None:
                        with wp.ScopedCapture() as cap:
                            for _ in range(k):
                                mjw.step(m, d)
                        graph = cap.graph
                    wp.capture_launch(graph)
                else:
                    for _ in range(k):
                        mjw.step(m, d)
                left -= k
            self._data = {key: (d, graph)}  # one batch shape kept (bounds GPU memory)
            self.steps_run.append(nstep - left)
            wp.synchronize()
            seconds = time.perf_counter() - t0
            return d.qpos.numpy().astype(np.float64), d.overflow.numpy().copy(), seconds

    def _all_asleep(self, d: Any) -> bool:
        """Whether every world's every tree sleeps (nothing can move any more)."""
        return self.sleep and int(d.ntree_awake.numpy().max()) == 0

    def settle(
        self,
        model: mujoco.MjModel | Sequence[mujoco.MjModel],
        qpos0: np.ndarray,
        nstep: int,
    ) -> Rollout:
        model = one_model(model, "warp")
        q = check_qpos(model, qpos0)
        invalid = nonfinite_rows(q)
        reasons = ["non-finite initial pose" if b else "" for b in invalid]
        out = q.copy()
        seconds = 0.0
        run = np.flatnonzero(~invalid)
        if len(run) == 0:
            return Rollout(out, invalid, reasons, 0.0)
        nconmax, njmax = self.initial_sizes(model, q[run])
        self.steps_run = []
        todo = run
        for attempt in range(self.max_grow + 1):
            overflowed = []
            for start in range(0, len(todo), self.chunk):
                ids = todo[start : start + self.chunk]
                final, overflow, sec = self._run(model, q[ids], nstep, nconmax, njmax)
                seconds += sec
                out[ids] = final
                overflowed.extend(ids[overflow != 0].tolist())
                bad = ~np.isfinite(final).all(axis=1)
                for i in ids[bad]:
                    invalid[i] = True
                    reasons[i] = "NaN in the final pose (simulation diverged)"
            if not overflowed:
                break
            todo = np.array(overflowed, dtype=int)
            if attempt == self.max_grow:
                for i in todo:
                    invalid[i] = True
                    reasons[i] = (
                        f"contact/constraint buffers overflowed (nconmax={nconmax}, "
                        f"njmax={njmax}) after {self.max_grow} doublings"
                    )
                break
            nconmax, njmax = 2 * nconmax, 2 * njmax
            log.info(
                "warp: %d world(s) overflowed; re-running them with nconmax=%d njmax=%d",
                len(todo),
                nconmax,
                njmax,
            )
        return Rollout(qpos=out, invalid=invalid, reasons=reasons, seconds=seconds)
