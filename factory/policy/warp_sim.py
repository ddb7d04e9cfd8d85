"""The env's simulation on MuJoCo Warp (``eval.executor=warp``): the worlds of one scene stepped
together on the GPU and their cameras drawn by MuJoCo Warp's batch renderer.

:class:`WarpBatchSim` is :class:`~factory.policy.batch_sim.BatchSim` with the physics and the
observation cameras moved to the device; everything the task decides stays the CPU env's: the
rules' initial configurations, controller and success checks
(:class:`~factory.tasks.pick_place.env.PickPlaceRules`) run on a host copy of each world's
state, loaded into a scratch ``MjData`` with ``mj_forward`` as the CPU env loads its own, so
both executors judge episodes with the same code.

One frame of all worlds is a fixed sequence of launches: per physics step, a kernel writes each
world's control of that step (the rules' per-step controls of the frame's actions, uploaded
once per frame as ``(n, per_frame, nu)``) and ``mujoco_warp.step``; then ``forward`` (current
kinematics for the renderer), a refit of the renderer's BVH, the batched ray-traced render of
every world and camera and the demos' conversion kernel to uint8 RGB and uint16 millimetres of
depth. On CUDA the sequence is captured once into a CUDA graph and replayed every frame. After
each frame the host copies the worlds' dynamic state (time, qpos, qvel, act, warm start, ctrl)
and the images in a few blocks.

Every world steps every frame: the worlds whose episodes are over (``ids`` of :meth:`advance`
leaves them out) move on under their last controls, and nothing reads them until they are
reset. A world whose contact or constraint buffers overflowed ends its episode as
:data:`~factory.demos.execute.warp.OVERFLOW` rather than go on with a wrong simulation.

MuJoCo Warp computes in float32 and renders by ray tracing (no shadows), so trajectories and
images are close to, not equal to, the CPU env's (tests/policy/test_warp_sim.py states the
agreement); the ``video`` renderer of rollout videos stays the CPU's OpenGL one.

``eval.executor=warp_opengl`` (:data:`WARP_EXECUTORS`) is a diagnostic: MuJoCo Warp's physics
with the observation cameras drawn by OpenGL from each world's host state, as the CPU env draws
them (slow: the CPU draws every world's cameras every frame). Set beside ``cpu`` and ``warp``
on the same configurations it tells how much of a disagreement between the two envs is the
renderer's and how much the physics'.
"""

from __future__ import annotations

import logging
import time
from typing import Any

import mujoco
import numpy as np

from factory.demos.record.payload import STATE_SPEC
from factory.errors import ConfigError, TaskError
from factory.policy.batch_sim import BatchRules, BatchSim
from factory.robots.panda import CAMERAS
from factory.sim.kernel_preload import PreloadReport

log = logging.getLogger(__name__)

WARP_EXECUTORS = {"warp": "warp", "warp_opengl": "opengl"}
"""``eval.executor`` values stepped on MuJoCo Warp -> who draws their observation cameras
(``warp``: MuJoCo Warp's batch renderer; ``opengl``: the CPU env's OpenGL renderer, drawing
each world's host state)."""

HEADROOM = 3.0
"""Contacts per world the buffers hold, as a multiple of the most an initial configuration has
(:func:`~factory.demos.execute.warp.buffer_sizes`)."""


class DeviceImages:
    """The observation cameras drawn on the device for every world (the marker
    :meth:`WarpBatchSim.renderer` returns for them; :meth:`WarpBatchSim.draw` reads the host
    copy of the last frame)."""

    def __init__(self, cfg: Any) -> None:
        self.cfg = cfg

    def close(self) -> None:
        """Nothing to close (the device buffers go with the simulation)."""


def _warp() -> tuple[Any, Any]:
    try:
        import mujoco_warp as mjw
        import warp as wp
    except ImportError as e:  # pragma: no cover - both are dependencies of the GPU extra
        raise ConfigError(
            f"eval.executor=warp needs warp-lang and mujoco-warp ({e}): install them "
            "(scripts/setup.sh, or the GPU bundle) or use eval.executor=cpu"
        ) from e
    return wp, mjw


class WarpBatchSim(BatchSim):
    """``num_envs`` worlds of one scene stepped together on MuJoCo Warp (module docstring).

    Args:
        rules: the task's rules for this scene.
        num_envs: episodes run at once (the worlds).
        spec: what to observe (:class:`~factory.policy.obs_spec.ObsSpec`).
        device: Warp device; default ``cuda:0`` when CUDA is present, else ``cpu`` (slow:
            tests).
        graph: capture a frame's launches into a CUDA graph (CUDA only).
        images: who draws the observation cameras: ``warp`` (the device's batch renderer) or
            ``opengl`` (the CPU env's renderer, from each world's host state; a diagnostic).

    Raises:
        ConfigError: an unknown ``images``.
    """

    def __init__(
        self,
        rules: BatchRules,
        num_envs: int,
        spec: Any,
        device: str | None = None,
        graph: bool = True,
        images: str = "warp",
    ) -> None:
        from factory.demos.execute.cpu import RecordConfig
        from factory.demos.execute.warp import buffer_sizes, render_context, state_layout
        from factory.policy.warp_kernels import frame_ctrl
        from factory.sim.backend import cuda_available, init_warp
        from factory.tasks.pick_place.objects import Outcome

        if images not in ("warp", "opengl"):
            raise ConfigError(f"WarpBatchSim images={images!r} is unknown: use warp or opengl")
        wp, mjw = _warp()
        init_warp()
        t0 = time.perf_counter()
        self.wp, self.mjw = wp, mjw
        self._outcome = Outcome
        self._bind(rules, num_envs, spec)
        m, n = self.model, num_envs
        self.device = device or ("cuda:0" if cuda_available() else "cpu")
        self.graph = graph and self.device.startswith("cuda")
        self.layout = state_layout(m)
        self._nstate = mujoco.mj_stateSize(m, STATE_SPEC)
        self._template = np.zeros((n, self._nstate))
        self._overflow = np.zeros(n, np.int64)
        self.nconmax, self.njmax = buffer_sizes(m, self._sample_states(), HEADROOM)
        self._cams = tuple(spec.cameras)
        ncam = len(self._cams) if images == "warp" else 0  # drawn on the device
        with wp.ScopedDevice(self.device):
            self.m = mjw.put_model(m)
            mujoco.mj_resetData(m, self._data)
            mujoco.mj_forward(m, self._data)
            self.d = mjw.put_data(m, self._data, nworld=n, nconmax=self.nconmax, njmax=self.njmax)
            self._ctrl = wp.zeros((n, self.per_frame, m.nu), dtype=float)
            self._reset = wp.zeros(n, dtype=bool)
            self.rc = None
            if ncam:
                names = [CAMERAS[c] for c in self._cams]
                self.rc = render_context(m, n, (spec.width, spec.height), names)
                npix = spec.width * spec.height
                self._npix = npix
                # one 2-D store per camera, as the demos' (to_images' docstring)
                self._rgb = [wp.empty((n, 3 * npix), dtype=wp.uint8) for _ in range(ncam)]
                self._mm = [wp.empty((n, npix), dtype=wp.uint16) for _ in range(ncam)]
                self._m = wp.empty((1, 1), dtype=float)
                self._rgb_adr = wp.array(np.asarray(self.rc.rgb_adr.numpy(), np.int32), dtype=int)
                self._depth_adr = wp.array(
                    np.asarray(self.rc.depth_adr.numpy(), np.int32), dtype=int
                )
                self._rows = wp.array(np.arange(n, dtype=np.int32)[None], dtype=int)
                self._step0 = wp.zeros(1, dtype=int)
            self._kernels = (frame_ctrl,)
            self._captured: Any = None
            pinned = self.device.startswith("cuda")
            self._sources = {
                name: getattr(self.d, name)
                for name in ("time", "qpos", "qvel", "act", "qacc_warmstart", "ctrl", "overflow")
            }
            if self.rc is not None:
                for k in range(ncam):
                    self._sources[f"rgb{k}"] = self._rgb[k]
                    self._sources[f"depth{k}"] = self._mm[k]
            self._sources = {k: a for k, a in self._sources.items() if a.size}
            self._mirrors = {
                k: wp.empty(a.shape, dtype=a.dtype, device="cpu", pinned=pinned)
                for k, a in self._sources.items()
            }
        self._host: dict[str, np.ndarray] = {}
        self.images_cfg = RecordConfig(spec.fps, spec.width, spec.height, self._cams, "uint16_mm")
        log.info(
            "eval: MuJoCo Warp on %s: %d worlds, %d cameras (%s), buffers of %d contacts and %d "
            "constraint rows a world, set up in %.1f s",
            self.device,
            n,
            len(self._cams),
            "drawn on the device" if ncam else "drawn by OpenGL on the host",
            self.nconmax,
            self.njmax,
            time.perf_counter() - t0,
        )
        self.preload = self._preload_kernels()

    def _preload_kernels(self) -> PreloadReport:
        """Compiles (or loads from Warp's kernel cache) the kernels of a frame's launches on
        every core before the first frame (:func:`factory.sim.kernel_preload.preload`: a dry
        trace of :meth:`_frame` on one world, then the modules in parallel); Warp would
        otherwise compile them one after the other at the first launch (minutes on a machine
        without its kernel cache). Returns what the preload did."""
        from factory.demos.execute import warp_kernels as k
        from factory.demos.execute.warp import render_context, trace_sim
        from factory.sim.kernel_preload import preload

        wp, mjw, model, spec = self.wp, self.mjw, self.model, self.spec
        (frame_ctrl,) = self._kernels

        def trace() -> None:
            wp.launch(frame_ctrl, dim=1)
            rc = None
            if self.rc is not None:
                wp.launch(k.to_images, dim=1)
                names = [CAMERAS[c] for c in self._cams]
                rc = render_context(model, 1, (spec.width, spec.height), names)
            trace_sim(wp, mjw, self.m, model, self._data, self.nconmax, self.njmax, rc)

        with wp.ScopedDevice(self.device):
            r = preload(wp, trace)
        log.info("eval: MuJoCo Warp kernels: %s", r.describe())
        return r

    def _sample_states(self) -> np.ndarray:
        """Initial configurations (k, nq) of a few seeds, to size the contact buffers."""
        rows = []
        for seed in range(8):
            try:
                rows.append(self.rules.sample_qpos(seed))
            except TaskError:  # a seed without a configuration: the next
                continue
            if len(rows) == 4:
                break
        return np.stack(rows) if rows else self.model.qpos0[None].copy()

    # ---- the device
    def _frame(self) -> None:
        """One frame of every world: the controls of each physics step, the steps, then the
        kinematics and the cameras (the launches a CUDA graph captures)."""
        wp, mjw = self.wp, self.mjw
        (frame_ctrl,) = self._kernels
        nu = self.model.nu
        for k in range(self.per_frame):
            wp.launch(
                frame_ctrl, dim=(self.num_envs, nu), inputs=[self._ctrl, k], outputs=[self.d.ctrl]
            )
            mjw.step(self.m, self.d)
        mjw.forward(self.m, self.d)
        self._draw_device()

    def _draw_device(self) -> None:
        if self.rc is None:
            return
        from factory.demos.execute.warp import launch_images

        wp, mjw = self.wp, self.mjw
        mjw.refit_bvh(self.m, self.d, self.rc)
        mjw.render(self.m, self.d, self.rc)
        launch_images(
            wp,
            self.rc,
            self._rgb_adr,
            self._depth_adr,
            self._npix,
            True,
            self._rows,
            self._step0,
            1,
            self._rgb,
            self._mm,
            [self._m] * len(self._cams),
        )

    def _grab(self) -> None:
        """Copies the worlds' dynamic state and images of the last frame to the host."""
        wp = self.wp
        for k, a in self._sources.items():
            wp.copy(self._mirrors[k], a)
        wp.synchronize()
        self._host = {k: a.numpy() for k, a in self._mirrors.items()}
        if "overflow" in self._host:
            self._overflow |= self._host["overflow"].astype(np.int64)

    # ---- the env's side (TaskSim)
    def reset(
        self, ids: list[int], states: np.ndarray | None, qpos: np.ndarray | None, spawned: bool
    ) -> None:
        """Sets worlds ``ids`` to recorded integration states or to ``qpos`` held still (the
        CPU env's initial states, built on the host), uploads them and draws every world."""
        wp, mjw = self.wp, self.mjw
        m, d = self.model, self._data
        for k, i in enumerate(ids):
            mujoco.mj_resetData(m, d)
            if states is not None:
                mujoco.mj_setState(m, d, states[k], STATE_SPEC)
            else:
                assert qpos is not None
                d.qpos[:] = qpos[k]
                d.ctrl[:] = self.rules.hold(qpos[k])
            mujoco.mj_forward(m, d)
            mujoco.mj_getState(m, d, self._template[i], STATE_SPEC)
            self._overflow[i] = 0
        mask = np.zeros(self.num_envs, bool)
        mask[ids] = True
        with wp.ScopedDevice(self.device):
            self._reset.assign(wp.array(mask, dtype=bool))
            mjw.reset_data(self.m, self.d, reset=self._reset)
            for part in ("time", "qpos", "qvel", "act", "qacc_warmstart", "ctrl"):
                arr = getattr(self.d, part)
                if not arr.size:
                    continue
                host = arr.numpy()
                rows = self._template[ids][:, self.layout[part]]
                host[ids] = rows.reshape(host[ids].shape)
                arr.assign(wp.array(host.astype(host.dtype), dtype=arr.dtype))
            if self.d.overflow.size:
                self.d.overflow.zero_()
            mjw.forward(self.m, self.d)
            self._draw_device()
            self._grab()

    def load(self, i: int) -> mujoco.MjData:
        """World ``i``'s state after the last frame in the scratch data, with kinematics and
        contacts (``mj_forward`` on the host, as the CPU env)."""
        state = self._template[i].copy()
        for part in ("time", "qpos", "qvel", "act", "qacc_warmstart", "ctrl"):
            if part in self._host:
                state[self.layout[part]] = np.ravel(self._host[part][i])
        d = self._data
        mujoco.mj_setState(self.model, d, state, STATE_SPEC)
        mujoco.mj_forward(self.model, d)
        return d

    def advance(self, ids: list[int], actions: np.ndarray) -> None:
        """One frame of every world: worlds ``ids`` under the frame's actions (len(ids), A),
        the others under their last controls."""
        wp = self.wp
        ctrl = np.repeat(self._host["ctrl"][:, None, :], self.per_frame, axis=1)
        ctrl[ids] = self.rules.controls(self._prev[ids], actions)
        with wp.ScopedDevice(self.device):
            self._ctrl.assign(wp.array(ctrl.astype(np.float32), dtype=float))
            if self.graph:
                if self._captured is None:
                    with wp.ScopedCapture() as cap:
                        self._frame()
                    self._captured = cap.graph
                wp.capture_launch(self._captured)
            else:
                self._frame()
            self._grab()

    def observe(
        self,
        i: int,
        data: mujoco.MjData,
        obs: dict[str, np.ndarray],
        ep: Any,
        action: np.ndarray | None,
    ) -> Any:
        """As the CPU env; a world whose buffers overflowed ends its episode as
        :data:`~factory.demos.execute.warp.OVERFLOW`."""
        from factory.demos.execute.warp import OVERFLOW

        out = super().observe(i, data, obs, ep, action)
        if action is not None and self._overflow[i]:
            return self._outcome(
                False,
                OVERFLOW,
                {
                    "nconmax": float(self.nconmax),
                    "njmax": float(self.njmax),
                    "overflow_bits": float(self._overflow[i]),
                },
            )
        return out

    def renderer(self, cameras: tuple[str, ...]) -> Any:
        """The device's images for the observation cameras; a CPU (OpenGL) renderer for
        others (rollout videos)."""
        if self.rc is not None and tuple(cameras) == self._cams:
            return DeviceImages(self.images_cfg)
        return super().renderer(cameras)

    def draw(
        self, renderer: Any, data: mujoco.MjData, i: int = -1
    ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Camera -> (RGB, depth mm) of world ``i``: the device's images of the last frame,
        or ``renderer``'s drawing of ``data``."""
        if not isinstance(renderer, DeviceImages):
            return super().draw(renderer, data, i)
        if i < 0:
            raise ValueError("the device's images are per world: pass the env index")
        h, w = self.spec.height, self.spec.width
        host = self._host
        return {
            c: (host[f"rgb{k}"][i].reshape(h, w, 3), host[f"depth{k}"][i].reshape(h, w))
            for k, c in enumerate(self._cams)
        }
