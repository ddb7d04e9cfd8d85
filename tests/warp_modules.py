"""Which Warp modules a test path compiles after :func:`factory.sim.kernel_preload.preload` has
run (the demos' executor and the evaluation's MuJoCo Warp env preload their kernels)."""

from __future__ import annotations

import pytest


def modules_compiled_after_preload(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Names of the Warp modules first loaded outside a :func:`factory.sim.kernel_preload.preload`
    after one has run without an early stop (filled as the test goes on). Modules an earlier
    test of the session loaded are loaded already and do not count."""
    import warp._src.context as ctx

    import factory.sim.kernel_preload as kp

    late: list[str] = []
    seen: set[str] = set()
    armed: list[bool] = []
    real_preload, real_load = kp.preload, ctx.Module.load

    inside: list[bool] = []

    def preload(*args, **kwargs):  # type: ignore[no-untyped-def]
        inside.append(True)
        try:
            report = real_preload(*args, **kwargs)
        finally:
            inside.pop()
        assert not report.error, report.error
        armed.append(True)
        return report

    def load(self, device, block_dim=None, *args, **kwargs):  # type: ignore[no-untyped-def]
        # Warp calls load at every launch; a variant not loaded yet, of a module no earlier
        # load named (reset_data makes new module objects of the same kernels per call), and
        # not loaded by a preload, is a compile the preloads missed.
        # Without a block size, Warp loads the module's own (``get_suggested_block_size``
        # does: MuJoCo Warp's CCD modules have 64), not the launch default of 256.
        own = block_dim if block_dim is not None else self.options.get("block_dim")
        key = (device.context, ctx._resolve_launch_block_dim(device, own))
        if armed and not inside and key not in self.execs and self.name not in seen:
            late.append(self.name)
        seen.add(self.name)
        return real_load(self, device, block_dim, *args, **kwargs)

    monkeypatch.setattr(kp, "preload", preload)
    monkeypatch.setattr(ctx.Module, "load", load)
    return late


def without_sleep(setup):  # type: ignore[no-untyped-def]
    """A copy of a scene set-up (a dataclass with a ``model``) whose model has MuJoCo's island
    sleeping off: what Warp's CPU device runs. The demos stage turns sleeping off there
    (``demos.sleep=false``: the GPU pipeline's test), since MuJoCo Warp's sleeping path is
    for CUDA; on the CPU device it takes about 6x longer a step (60 ms against 10 ms for the
    test kitchen: launch overhead). The ``gpu`` twins keep the model's sleeping."""
    import copy
    import dataclasses

    import mujoco

    model = copy.deepcopy(setup.model)
    model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    return dataclasses.replace(setup, model=model)
