"""The CPU backend: ``mujoco.batch.Batch`` on a thread pool (the reference).

Results are bit-identical for any number of threads (MuJoCo's guarantee for Batch), which the
tests check. Different models of one layout run together through ``Batch.set_models``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import mujoco
import numpy as np
from mujoco.batch import Batch, SimulationError

from factory.cores import usable_cores
from factory.sim.backend import Rollout, check_qpos, nonfinite_rows

_BAD_WARNINGS = {
    mujoco.mjtWarning.mjWARN_BADQPOS: "NaN or huge value in qpos",
    mujoco.mjtWarning.mjWARN_BADQVEL: "NaN or huge value in qvel",
    mujoco.mjtWarning.mjWARN_BADQACC: "NaN or huge value in qacc (simulation diverged)",
    mujoco.mjtWarning.mjWARN_CONTACTFULL: "contact buffer full",
    mujoco.mjtWarning.mjWARN_CNSTRFULL: "constraint buffer full",
}


class CpuBackend:
    """``mujoco.batch`` settling.

    Args:
        nthread: worker threads (0: one per CPU core).
        chunk: simulations per Batch (bounds memory).
    """

    name = "cpu"

    def __init__(self, nthread: int = 0, chunk: int = 4096) -> None:
        self.nthread = nthread or usable_cores()
        self.chunk = chunk

    def settle(
        self,
        model: mujoco.MjModel | Sequence[mujoco.MjModel],
        qpos0: np.ndarray,
        nstep: int,
    ) -> Rollout:
        models = None if isinstance(model, mujoco.MjModel) else list(model)
        base = model if models is None else models[0]
        q = check_qpos(base, qpos0)
        n = len(q)
        if models is not None and len(models) != n:
            raise ValueError(f"{len(models)} models for {n} simulations")
        out = q.copy()
        invalid = nonfinite_rows(q)
        reasons = ["non-finite initial pose" if bad else "" for bad in invalid]
        seconds = 0.0
        for start in range(0, n, self.chunk):
            ids = np.arange(start, min(n, start + self.chunk))
            run = ids[~invalid[ids]]
            if len(run) == 0:
                continue
            batch = Batch(base, len(run), min(self.nthread, len(run)))
            if models is not None:
                batch.set_models([models[i] for i in run])
            batch.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
            batch.bind("qpos")[:] = q[run]
            t0 = time.perf_counter()
            failed: set[int] = set()
            try:
                batch.step(nstep=nstep)
            except SimulationError as e:
                for k in e.ids:
                    failed.add(int(k))
                    reasons[run[k]] = f"MuJoCo error: {batch.error(int(k))}"
            seconds += time.perf_counter() - t0
            counts = batch.warning[:, :, 1]
            final = batch.bind("qpos")
            for k, i in enumerate(run):
                out[i] = final[k]
                bad = [msg for w, msg in _BAD_WARNINGS.items() if counts[k, int(w)] > 0]
                if k in failed or bad or not np.isfinite(final[k]).all():
                    invalid[i] = True
                    reasons[i] = reasons[i] or "; ".join(bad) or "non-finite final pose"
        return Rollout(qpos=out, invalid=invalid, reasons=reasons, seconds=seconds)
