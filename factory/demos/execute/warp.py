"""Execution and recording of the planned episodes of one scene on the GPU (MuJoCo Warp).

The episodes of a scene (same model; different object poses, seeds and trajectories) run as the
worlds of one MuJoCo Warp model. Their timed control sequences are uploaded once as one
``(n, T, nu)`` array (episodes shorter than the longest hold their last control); a small
kernel writes each world's control of the current physics step before ``mujoco_warp.step``.
One recording period (``1 / fps``) is a fixed sequence of launches: the period's steps, a
``forward`` (so kinematics and contacts match the recorded state, as the CPU executor's
``mj_forward`` does), a refit of the renderer's BVH, MuJoCo Warp's batched ray-traced render
of every world and camera, and a conversion kernel to ``uint8`` RGB and depth (``uint16`` mm or
``float32`` m). On CUDA that sequence is captured once into a CUDA graph and replayed per
frame. The host copies each frame's images, states and contacts in a few large blocks.

Appearance randomisation (``looks``, as the CPU executor takes them): the call's model copy has one
row per world of the fields an appearance sets, and
:func:`~factory.demos.execute.warp_kernels.set_looks` writes an episode's row of the patch tables
into its world's fields when the episode starts (before the first ``forward``, and in the captured
period after a packed world's reset), so each world renders its episode's look. The recorded
calibration of the cameras fixed in the scene (``camera_poses``, ``camera_fovy``) is computed on
the host from the model and each episode's patch, as the CPU executor computes it
(:func:`~factory.demos.execute.cpu.calibrate_recordings`).

The recorded MuJoCo integration state has the layout of ``mj_getState(..., mjSTATE_INTEGRATION)``
(:func:`state_layout`), so recordings replay on the CPU like the CPU executor's; the success
check is the same function (:func:`factory.demos.execute.cpu.finish_recordings`).

MuJoCo Warp computes in float32 (the CPU executor in float64): trajectories agree closely but
not bit for bit, and its renderer (ray tracing, headlight and model lights, no shadows) draws
images that are alike but not identical to the OpenGL ones (tests/demos/test_execute_warp.py
states the tolerances).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from factory.demos.execute.cpu import (
    STATE_SPEC,
    RecordConfig,
    Recording,
    calibrate_recordings,
    finish_recordings,
)
from factory.demos.execute.world_schedule import WorldSchedule
from factory.demos.record.frame_render import NEAR_CLIP_M
from factory.errors import AppearanceError, RenderError
from factory.robots.panda import CAMERAS
from factory.sim.kernel_preload import PreloadReport
from factory.tasks.pick_place.plan import EpisodePlan, SceneSetup

log = logging.getLogger(__name__)

DEVICE_LOCK = threading.Lock()
"""Held while a call captures its CUDA graph and while an executor is made or warmed up on the
device. The next scene's executor is made and its kernels traced in the GPU pipeline's set-up
thread while the current scene's call runs (:meth:`WarpExecutor.warm_up`): Warp's current
stream belongs to the device, not to the thread, so that thread's copies during a capture
would be recorded into the call's graph. Copies and launches outside captures are ordered on
the device's stream; the kernels' compilation itself is not held."""

OVERFLOW = "sim_overflow"
"""Failure reason of a world whose contact or constraint buffers overflowed."""

DYNAMIC = ("time", "qpos", "qvel", "act", "qacc_warmstart", "ctrl")
"""Parts of the integration state that change during an episode (read from the device)."""

_BITS: dict[str, int] = {
    "time": int(mujoco.mjtState.mjSTATE_TIME),
    "qpos": int(mujoco.mjtState.mjSTATE_QPOS),
    "qvel": int(mujoco.mjtState.mjSTATE_QVEL),
    "act": int(mujoco.mjtState.mjSTATE_ACT),
    "history": int(mujoco.mjtState.mjSTATE_HISTORY),
    "qacc_warmstart": int(mujoco.mjtState.mjSTATE_WARMSTART),
    "ctrl": int(mujoco.mjtState.mjSTATE_CTRL),
    "qfrc_applied": int(mujoco.mjtState.mjSTATE_QFRC_APPLIED),
    "xfrc_applied": int(mujoco.mjtState.mjSTATE_XFRC_APPLIED),
    "eq_active": int(mujoco.mjtState.mjSTATE_EQ_ACTIVE),
    "mocap_pos": int(mujoco.mjtState.mjSTATE_MOCAP_POS),
    "mocap_quat": int(mujoco.mjtState.mjSTATE_MOCAP_QUAT),
    "userdata": int(mujoco.mjtState.mjSTATE_USERDATA),
    "plugin": int(mujoco.mjtState.mjSTATE_PLUGIN),
    "plastic": int(mujoco.mjtState.mjSTATE_PLASTIC),
}


INT32_MAX = 2**31 - 1
"""Largest stride (bytes) a Warp array may have: Warp passes strides to kernels as 32-bit
ints."""


def check_strides(arrays: list[Any]) -> None:
    """Refuses Warp arrays whose strides do not fit Warp's 32-bit ints (a kernel would index
    outside them: an illegal memory access on CUDA, a crash on the CPU).

    Raises:
        RenderError: names the array's shape and the smaller call that avoids it.
    """
    for a in arrays:
        big = [int(st) for st in a.strides if int(st) > INT32_MAX]
        if big:
            raise RenderError(
                f"a Warp array of shape {tuple(a.shape)} has a stride of {big[0]} bytes, past "
                f"Warp's 32-bit limit ({INT32_MAX}): use a smaller demos.gpu_batch"
            )


def trace_sim(
    wp: Any,
    mjw: Any,
    m: Any,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    nconmax: int,
    njmax: int,
    rc: Any = None,
) -> None:
    """MuJoCo Warp's launches of a call, on one world, for the trace of
    :func:`factory.sim.kernel_preload.preload`: ``put_data`` (buffers of ``nconmax`` contacts
    and ``njmax`` constraint rows, as the call's), ``forward``, ``reset_data``, ``step`` and,
    with a render context ``rc`` (of one world, the call's cameras and size), the BVH refit
    and the render. ``m`` is the device model of ``model``; nothing made is kept."""
    d = mjw.put_data(model, data, nworld=1, nconmax=nconmax, njmax=njmax)
    mjw.forward(m, d)
    mjw.reset_data(m, d, reset=wp.zeros(1, dtype=bool))
    mjw.step(m, d)
    if rc is not None:
        mjw.refit_bvh(m, d, rc)
        mjw.render(m, d, rc)


def launch_images(
    wp: Any,
    rc: Any,
    rgb_adr: Any,
    depth_adr: Any,
    npix: int,
    depth_mm: bool,
    rows: Any,
    step: Any,
    per_frame: int,
    rgb: list[Any],
    mm: list[Any],
    m: list[Any],
) -> None:
    """Files the render context's last drawing into the image stores, one
    :func:`~factory.demos.execute.warp_kernels.to_images` launch per camera (``rgb[c]``,
    ``mm[c]``, ``m[c]``: camera ``c``'s stores; ``rows``: (boundaries, worlds) store rows of
    each world, -1 for none). Depth that is not finite becomes the far clip of
    :data:`RENDER_CLIP`."""
    from factory.demos.execute.warp_kernels import to_images

    for c in range(len(rgb)):
        wp.launch(
            to_images,
            dim=(rows.shape[1], npix),
            inputs=[
                rc.rgb_data,
                rc.depth_data,
                rgb_adr,
                depth_adr,
                c,
                npix,
                int(depth_mm),
                float(RENDER_CLIP[1]),
                rows,
                step,
                per_frame,
            ],
            outputs=[rgb[c], mm[c], m[c]],
        )


def state_layout(model: mujoco.MjModel, spec: int = int(STATE_SPEC)) -> dict[str, slice]:
    """Where each part of a MuJoCo state vector lies (``mj_getState`` order: the ``mjtState``
    bits in increasing order), for the parts in ``spec``.

    Returns:
        part name (``time``, ``qpos``, ...) -> slice into the state vector.
    """
    out: dict[str, slice] = {}
    at = 0
    for name, bit in sorted(_BITS.items(), key=lambda kv: kv[1]):
        if not spec & bit:
            continue
        size = mujoco.mj_stateSize(model, bit)
        out[name] = slice(at, at + size)
        at += size
    if at != mujoco.mj_stateSize(model, spec):
        raise AssertionError(f"state layout covers {at} of {mujoco.mj_stateSize(model, spec)}")
    return out


def quat_from_mat(mat: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z) of rotation matrices ``mat`` (..., 3, 3), as
    ``mju_mat2Quat`` gives them."""
    m = np.asarray(mat, np.float64).reshape(-1, 9)
    out = np.zeros((len(m), 4))
    tr = m[:, 0] + m[:, 4] + m[:, 8]
    c0 = tr > 0
    c1 = ~c0 & (m[:, 0] > m[:, 4]) & (m[:, 0] > m[:, 8])
    c2 = ~c0 & ~c1 & (m[:, 4] > m[:, 8])
    c3 = ~c0 & ~c1 & ~c2
    with np.errstate(invalid="ignore", divide="ignore"):
        w = 0.5 * np.sqrt(np.maximum(1 + tr, 0))
        x = 0.5 * np.sqrt(np.maximum(1 + m[:, 0] - m[:, 4] - m[:, 8], 0))
        y = 0.5 * np.sqrt(np.maximum(1 - m[:, 0] + m[:, 4] - m[:, 8], 0))
        z = 0.5 * np.sqrt(np.maximum(1 - m[:, 0] - m[:, 4] + m[:, 8], 0))
        cases = (
            (
                c0,
                w,
                (
                    w,
                    0.25 * (m[:, 7] - m[:, 5]) / w,
                    0.25 * (m[:, 2] - m[:, 6]) / w,
                    0.25 * (m[:, 3] - m[:, 1]) / w,
                ),
            ),
            (
                c1,
                x,
                (
                    0.25 * (m[:, 7] - m[:, 5]) / x,
                    x,
                    0.25 * (m[:, 1] + m[:, 3]) / x,
                    0.25 * (m[:, 2] + m[:, 6]) / x,
                ),
            ),
            (
                c2,
                y,
                (
                    0.25 * (m[:, 2] - m[:, 6]) / y,
                    0.25 * (m[:, 1] + m[:, 3]) / y,
                    y,
                    0.25 * (m[:, 5] + m[:, 7]) / y,
                ),
            ),
            (
                c3,
                z,
                (
                    0.25 * (m[:, 3] - m[:, 1]) / z,
                    0.25 * (m[:, 2] + m[:, 6]) / z,
                    0.25 * (m[:, 5] + m[:, 7]) / z,
                    z,
                ),
            ),
        )
        for mask, _, parts in cases:
            for j, v in enumerate(parts):
                out[mask, j] = v[mask]
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return out.reshape(*np.shape(mat)[:-2], 4)


_STAGED: dict[str, Any] = {}
_STAGED_LOCK = threading.Lock()


def staged_copy(wp: Any, device: str) -> Any:
    """The process's :class:`~factory.demos.execute.staged_copy.StagedCopy` for ``device``
    (made at first use; its page-locked buffers serve every executor and call after)."""
    from factory.demos.execute.staged_copy import StagedCopy

    with _STAGED_LOCK:
        copy = _STAGED.get(device)
        if copy is None:
            copy = _STAGED[device] = StagedCopy(wp, device)
        return copy


def host_reader(wp: Any, sources: dict[str, Any], pinned: bool) -> Any:
    """A function that copies the device arrays ``sources`` into host mirrors made once here
    (page-locked when ``pinned``), waits for the device, and returns them as numpy arrays by
    name (views of the mirrors: the next read overwrites them)."""
    mirrors = {
        k: wp.empty(a.shape, dtype=a.dtype, device="cpu", pinned=pinned) for k, a in sources.items()
    }

    def grab() -> dict[str, np.ndarray]:
        for k, a in sources.items():
            wp.copy(mirrors[k], a)
        wp.synchronize()
        return {k: a.numpy() for k, a in mirrors.items()}

    return grab


def run_period(wp: Any, period: Any, captured: Any, graph: bool) -> Any:
    """Runs one recording period: ``period()`` itself, or with ``graph`` its CUDA graph,
    captured at the first call (under :data:`DEVICE_LOCK`: another thread's copies must not
    be recorded into it) and replayed after; returns the graph to pass to the next call (None
    without ``graph``)."""
    if graph and captured is None:
        with DEVICE_LOCK, wp.ScopedCapture() as cap:
            period()
        captured = cap.graph
    if captured is not None:
        wp.capture_launch(captured)
    else:
        period()
    return captured


def size_class(n: int) -> int:
    """The smallest of 1, 2, 3, 4, 6, 8, 12, 16, 24, ... (``2^k`` and ``3 * 2^k``) that is at
    least ``n``: less than half as much again as asked, and few distinct sizes."""
    n = max(1, int(n))
    k = (n - 1).bit_length()  # 2^(k-1) < n <= 2^k
    return 3 << (k - 2) if k >= 2 and 3 << (k - 2) >= n else 1 << k


def buffer_sizes(model: mujoco.MjModel, qpos: np.ndarray, headroom: float = 3.0) -> tuple[int, int]:
    """``(nconmax, njmax)`` per world: ``headroom`` times the contacts of the initial states
    (sampled) plus room for the gripper's contacts and every free body touching twice.

    ``njmax`` is rounded up to its :func:`size_class`: MuJoCo Warp compiles its solver's tiled
    gradient kernel for the exact ``njmax`` (its loop bound), so every call of another size
    compiled that kernel again; with the classes, scenes and calls share a few variants."""
    data = mujoco.MjData(model)
    most = 0
    for q in qpos[np.linspace(0, len(qpos) - 1, min(len(qpos), 8)).astype(int)]:
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        most = max(most, int(data.ncon))
    free = int(np.sum(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE))
    nconmax = int(headroom * most) + 4 * free + 64
    rows = 4 if model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL else 6
    njmax = size_class(rows * nconmax + model.nv)
    return nconmax, njmax


RENDER_CLIP = (NEAR_CLIP_M, 100.0)
"""Near and far clip distances (m) of the GPU renderer's cameras, the same in every scene.
MuJoCo Warp's render kernel takes them as compile-time constants (``vis.map.znear`` and
``zfar`` times the scene's ``stat.extent``), so clip planes that followed the scene's extent
compiled a new render kernel for every scene (20-30 s of an H200 node's set-up per scene, its
CPUs busy). The near distance only scales each camera ray before it is normalised; the far one
ends rays at 100 m, beyond any room."""


def render_context(model: mujoco.MjModel, nworld: int, cam_res: Any, cameras: list[str]) -> Any:
    """MuJoCo Warp's render context for recording: RGB and depth (no segmentation), textures,
    no shadows, geom groups 0-2, the clip planes of :data:`RENDER_CLIP` (``model`` is left
    as it was).

    Args:
        model: the scene's compiled model.
        nworld: worlds drawn per call.
        cam_res: ``(width, height)`` px of every camera, or a list of them per camera.
        cameras: the model's names of the cameras drawn, in order.
    """
    import mujoco_warp as mjw

    vis, stat = model.vis.map, model.stat
    saved = (float(vis.znear), float(vis.zfar), float(stat.extent))
    vis.znear, vis.zfar = RENDER_CLIP
    stat.extent = 1.0
    try:
        return mjw.create_render_context(
            model,
            nworld=nworld,
            cam_res=cam_res,
            render_rgb=True,
            render_depth=True,
            render_seg=False,
            use_textures=True,
            use_shadows=False,
            enabled_geom_groups=[0, 1, 2],
            cam_active=cameras,
        )
    finally:
        vis.znear, vis.zfar, stat.extent = saved


@dataclass
class WarpTimes:
    """Seconds spent by one :meth:`WarpExecutor.execute` call."""

    setup: float = 0.0
    frames: float = 0.0
    copy: float = 0.0
    finish: float = 0.0


class WarpExecutor:
    """Runs the planned episodes of one scene as worlds of one MuJoCo Warp model and records
    them (the GPU twin of :func:`factory.demos.execute.cpu.execute`).

    Args:
        setup: the scene with the robot (its composed model).
        cfg: what to record.
        device: Warp device; default ``cuda:0`` when CUDA is present, else ``cpu`` (slow: tests).
        graph: capture one recording period into a CUDA graph (CUDA only).
        broadphase: MuJoCo Warp's broadphase (``nxn``, ``sap_tile``, ``sap_segmented``);
            None keeps its own choice (by the number of geom pairs).
        arenas: allocate each call's recordings in shared memory arenas taken from this
            :class:`~factory.demos.execute.shared_frames.ArenaPool` (Linux), so that writer
            processes read them in place; :meth:`take_arenas` hands them over (to be given back to
            the pool once written). None: ordinary numpy arrays.
        images_on_device: keep a call's images on the device until the call ends, then copy
            them into an arena in one block per camera (needs ``arenas``): the host holds no
            images while the call runs, so calls of many more worlds fit in host memory, and
            the arena is taken only at the end, once the previous call's writes are done.
    """

    def __init__(
        self,
        setup: SceneSetup,
        cfg: RecordConfig,
        device: str | None = None,
        graph: bool = True,
        broadphase: str | None = None,
        arenas: Any = None,
        images_on_device: bool = False,
    ) -> None:
        import mujoco_warp as mjw
        import warp as wp

        from factory.sim.backend import cuda_available, init_warp

        init_warp()
        self.wp, self.mjw = wp, mjw
        self._kernels_ready = False
        self._warm_report: PreloadReport | None = None
        self.setup = setup
        self.cfg = cfg
        self.device = device or ("cuda:0" if cuda_available() else "cpu")
        self.graph = graph and self.device.startswith("cuda")
        model = setup.model
        self.layout = state_layout(model)
        self.per_frame = max(1, round(1.0 / (cfg.fps * float(model.opt.timestep))))
        with DEVICE_LOCK, wp.ScopedDevice(self.device):
            self.m = mjw.put_model(model)
        if broadphase is not None:
            self.m.opt.broadphase = mjw.BroadphaseType[broadphase.upper()]
        self.times = WarpTimes()
        self.arenas = arenas
        self.images_on_device = images_on_device and arenas is not None
        self._arenas: list[Any] = []
        self._look_base: dict[str, np.ndarray] = {}  # the model's appearance fields (1, ...)

    def take_arenas(self) -> list[Any]:
        """The shared memory arenas holding the recordings of the calls since the last
        :meth:`take_arenas` (give them back to the pool once nothing reads them any more)."""
        out, self._arenas = self._arenas, []
        return out

    def _render_context(self, n: int) -> Any:
        cfg = self.cfg
        names = [CAMERAS[c] for c in cfg.cameras]
        return render_context(self.setup.model, n, (cfg.width, cfg.height), names)

    def execute(
        self,
        plans: list[EpisodePlan],
        worlds: int | None = None,
        looks: list[tuple[Any, Any]] | None = None,
    ) -> list[Recording]:
        """Runs ``plans`` together and records them (one recording per plan, success checked).

        Args:
            plans: the episodes (of this scene).
            worlds: worlds of the call; fewer than ``len(plans)`` packs the episodes onto them back
                to back (:func:`~factory.demos.execute.world_schedule.packed_schedule`: no world
                waits for the longest episode); None: one world per episode, all starting together
                (:func:`~factory.demos.execute.world_schedule.padded_schedule`).
            looks: per plan, its appearance (an
                :class:`~factory.schema.episode.EpisodeAppearance`) and the model fields it
                sets (a :class:`~factory.demos.record.appearance.ModelPatch`), as
                :func:`~factory.demos.record.appearance.episode_looks` gives them and the CPU
                executor takes them: each world's copy of those fields is set to its episode's
                when the episode starts (:func:`~factory.demos.execute.warp_kernels.set_looks`), and
                each recording's ``appearance`` is the episode's (its cameras' calibration
                that patch's). ``None``: the model as it is (``appearance`` None).

        Worlds whose contact or constraint buffers overflowed are run again with doubled
        buffers (twice at most); if they still overflow their outcome is ``sim_overflow``.
        """
        n = len(plans)
        if n == 0:
            return []
        if looks is not None and len(looks) != n:
            raise AppearanceError(
                f"{len(looks)} appearance(s) for {n} episode(s): pass one look per plan "
                "(episode_looks of the plans' seeds) or looks=None"
            )
        recs = self._execute(plans, headroom=3.0, worlds=worlds, looks=looks)
        for grow in (6.0, 12.0):
            again = [i for i, r in enumerate(recs) if r.outcome and r.outcome.reason == OVERFLOW]
            if not again:
                break
            log.info("warp demos: %d world(s) overflowed; re-running with more room", len(again))
            redo = self._execute(
                [plans[i] for i in again],
                headroom=grow,
                worlds=worlds,
                looks=[looks[i] for i in again] if looks is not None else None,
            )
            for i, r in zip(again, redo, strict=True):
                recs[i] = r
        return recs

    def _world_looks(self, tables: Any, n: int) -> tuple[Any, list[Any]]:
        """A copy of the device model whose appearance fields have one row per world (the
        model's values), and the inputs of :func:`~factory.demos.execute.warp_kernels.set_looks`
        (the patch tables on the device, then the per-world fields it writes). The other
        fields are the executor's model's arrays, shared."""
        import copy

        from factory.demos.record.appearance import PATCH_FIELDS, PATCH_GROUPS

        wp = self.wp
        m = copy.copy(self.m)
        for f in PATCH_FIELDS:
            base = getattr(self.m, f)
            rows = self._look_base.get(f)
            if rows is None:
                rows = self._look_base[f] = base.numpy()[:1]
            arr = wp.array(np.repeat(rows, n, axis=0), dtype=base.dtype)
            arr._is_batched = True  # as put_model(..., batch_sizes={f: n}) marks it
            setattr(m, f, arr)
        inputs: list[Any] = []
        for group, names in PATCH_GROUPS.items():
            inputs.append(wp.array(tables.ids[group], dtype=int))
            for f in names:
                inputs.append(wp.array(tables.rows[f], dtype=getattr(m, f).dtype))
        return m, inputs + [getattr(m, f) for f in PATCH_FIELDS]

    def warm_up(self) -> PreloadReport:
        """Compiles (or loads from Warp's kernel cache) the kernels of this scene's calls now,
        on every core (:meth:`_preload_kernels` with the model's own initial state): call it
        while the scene's episodes are still being planned, or from another thread while the
        scene before runs on the device (the GPU pipeline's set-up thread does; see
        :data:`DEVICE_LOCK`), so that the first call finds them ready. Idempotent; the first
        call's own preload then finds nothing left to load.

        Returns:
            what the preload did (module variants traced, those loaded now, seconds); a later
            call returns the first call's report.
        """
        if self._warm_report is not None:
            return self._warm_report
        model = self.setup.model
        data = mujoco.MjData(model)
        nconmax, njmax = buffer_sizes(model, model.qpos0[None].copy(), 3.0)
        ncam = len(self.cfg.cameras) if self.cfg.render else 0
        t0 = time.perf_counter()
        with self.wp.ScopedDevice(self.device):
            report = self._preload_kernels(self.m, data, nconmax, njmax, ncam, True)
        self._warm_report = report
        log.info(
            "demos %s: GPU kernels warmed up in %.1f s, ahead of the scene's calls",
            self.setup.scene.id,
            time.perf_counter() - t0,
        )
        return report

    def _preload_kernels(
        self, m: Any, data: mujoco.MjData, nconmax: int, njmax: int, ncam: int, looks: bool
    ) -> PreloadReport:
        """Compiles the kernels of a call's launches on every core before the call
        (:func:`factory.sim.kernel_preload.preload`): a dry trace of :meth:`_execute`'s
        launches on one world (same device model, appearance and cameras), then the modules
        in parallel. Warp would otherwise compile them one after the other at first launch.
        Returns the preload's report."""
        from factory.demos.execute import warp_kernels as k
        from factory.sim.kernel_preload import preload

        wp, mjw, model = self.wp, self.mjw, self.setup.model

        def trace() -> None:
            for kernel in (k.set_ctrl, k.tick, k.starts, k.begin, k.to_images):
                wp.launch(kernel, dim=1)
            if looks:
                wp.launch(k.set_looks, dim=1)
            rc = self._render_context(1) if ncam else None
            trace_sim(wp, mjw, m, model, data, nconmax, njmax, rc)

        r = preload(wp, trace, around_trace=DEVICE_LOCK)
        log.info("demos %s: GPU kernels: %s", self.setup.scene.id, r.describe())
        return r

    def _execute(
        self,
        plans: list[EpisodePlan],
        headroom: float,
        worlds: int | None,
        looks: list[tuple[Any, Any]] | None = None,
    ) -> list[Recording]:
        wp, mjw = self.wp, self.mjw
        from factory.demos.execute.warp_kernels import (
            begin,
            set_ctrl,
            set_looks,
            starts,
            tick,
        )
        from factory.demos.execute.world_schedule import packed_schedule, padded_schedule

        cfg, setup = self.cfg, self.setup
        model, robot = setup.model, setup.robot
        per_frame = self.per_frame
        t0 = time.perf_counter()
        lengths = np.array([len(p.ctrl) for p in plans], np.int64)
        n_frames = [int(np.ceil(t / per_frame)) + 1 for t in lengths]
        if worlds is not None and worlds < len(plans):
            sched = packed_schedule(n_frames, worlds)
        else:
            sched = padded_schedule(n_frames)
        n, nb, n_ep = sched.worlds, sched.boundaries, len(plans)
        # The episodes' controls and recorded targets one after another: (sum of steps, nu|8).
        offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        ctrl = np.concatenate([p.ctrl for p in plans]).astype(np.float32)
        targets = np.concatenate([p.targets for p in plans])
        q0 = np.stack([p.qpos0 for p in plans])
        nconmax, njmax = buffer_sizes(model, q0, headroom)
        # Template states: the CPU executor's initial state of each episode (reset, qpos0,
        # first control, forward); the parts that never change on the device come from here.
        data = mujoco.MjData(model)
        nstate = mujoco.mj_stateSize(model, STATE_SPEC)
        template = np.empty((n_ep, nstate))
        for i, p in enumerate(plans):
            mujoco.mj_resetData(model, data)
            data.qpos[:] = p.qpos0
            data.ctrl[:] = p.ctrl[0]
            mujoco.mj_forward(model, data)
            mujoco.mj_getState(model, data, template[i], STATE_SPEC)
        mujoco.mj_resetData(model, data)
        parts = {"templates": time.perf_counter() - t0}
        ncam = len(cfg.cameras) if cfg.render else 0
        store = self.images_on_device and ncam > 0  # images stay on the device until the end
        arena = None
        if self.arenas is not None and not store:
            arena = self.arenas.take(_Frames.nbytes(sched.n_rows, nstate, cfg))
            self._arenas.append(arena)
        t_part = time.perf_counter()
        frames = _Frames.allocate(sched.n_rows, nstate, cfg, arena, images=not store)
        parts["frames"] = time.perf_counter() - t_part
        npix = cfg.width * cfg.height
        pick = model.body(setup.objects.pick.id).id
        target = model.body(setup.objects.target.id).id
        support = model.body(setup.objects.support.id).id
        robot_geom = np.zeros(model.ngeom, bool)
        robot_geom[robot.geoms] = True
        allowed = np.isin(model.geom_bodyid, [pick, target, support])
        worst = np.zeros(n_ep)
        first = sched.episode[0]
        with wp.ScopedDevice(self.device):
            m, look_in = self.m, list[Any]()
            if looks is not None:
                from factory.demos.record.appearance import patch_tables

                t_part = time.perf_counter()
                tables = patch_tables(model, [patch for _, patch in looks])
                m, look_in = self._world_looks(tables, n)
                parts["looks"] = time.perf_counter() - t_part
                look_dim = (n, max(1, tables.width))
            t_part = time.perf_counter()
            first_call = not self._kernels_ready
            if first_call:  # the kernels compile now, unless Warp's cache holds them
                from factory.sim.kernel_cache import cached_modules, kernel_cache_dir

                cache = kernel_cache_dir(wp)
                log.info(
                    "demos %s: loading the GPU kernels (Warp kernel cache %s, %d modules there; "
                    "a bare machine compiles for minutes, sim.kernel_cache keeps them)",
                    setup.scene.id,
                    cache,
                    cached_modules(cache),
                )
                t_kernels = t_part
                self._preload_kernels(m, data, nconmax, njmax, ncam, looks is not None)
                parts["kernels"] = time.perf_counter() - t_part
                t_part = time.perf_counter()
            d = mjw.put_data(model, data, nworld=n, nconmax=nconmax, njmax=njmax)
            parts["put_data"] = time.perf_counter() - t_part
            d.qpos.assign(wp.array(q0[first].astype(np.float32), dtype=float))
            plan_d = wp.array(ctrl, dtype=float)
            offset_d = wp.array(offsets.astype(np.int32), dtype=int)
            length_d = wp.array(lengths.astype(np.int32), dtype=int)
            episode_d = wp.array(sched.episode, dtype=int)
            frame_d = wp.array(sched.frame, dtype=int)
            step_d = wp.zeros(1, dtype=int)
            ctrl_in = [plan_d, offset_d, length_d, episode_d, frame_d, step_d, per_frame]
            wp.launch(set_ctrl, dim=(n, model.nu), inputs=ctrl_in, outputs=[d.ctrl])
            if looks is not None:  # every world's first episode's appearance
                everyone = wp.array(np.ones(n, bool), dtype=bool)
                look_at = [episode_d, step_d, per_frame]
                wp.launch(set_looks, dim=look_dim, inputs=[everyone, *look_at, *look_in])
            mjw.forward(m, d)
            if sched.resets:
                start_d = wp.array(sched.start, dtype=bool)
                reset_d = wp.zeros(n, dtype=bool)
                qpos0_d = wp.array(q0.astype(np.float32), dtype=float)
                overflow_of = wp.zeros(n_ep, dtype=int)
                # reset_data's kernels are made per call: load them outside the capture.
                mjw.reset_data(m, d, reset=reset_d)
            parts["device_state"] = time.perf_counter() - t_part - parts["put_data"]
            t_part = time.perf_counter()
            rc = self._render_context(n) if ncam else None
            parts["render_context"] = time.perf_counter() - t_part
            if rc is not None:
                # The image store: a row per filed frame of the call (kept on the device), or a
                # row per world that the host copies after each period; camera-major.
                mm = cfg.depth == "uint16_mm"
                nr = sched.n_rows if store else n
                img_rows = sched.row if store else np.where(sched.row >= 0, np.arange(n), -1)
                rows_d = wp.array(img_rows.astype(np.int32), dtype=int)
                t_part = time.perf_counter()
                # one 2-D store per camera: Warp's strides are 32-bit (to_images' docstring)
                rgb_store = [wp.empty((nr, 3 * npix), dtype=wp.uint8) for _ in range(ncam)]
                none_mm, none_m = wp.empty((1, 1), wp.uint16), wp.empty((1, 1), dtype=float)
                mm_store = [wp.empty((nr, npix), wp.uint16) if mm else none_mm for _ in range(ncam)]
                m_store = [none_m if mm else wp.empty((nr, npix), dtype=float) for _ in range(ncam)]
                check_strides([*rgb_store, *mm_store, *m_store])
                rgb_adr = wp.array(np.asarray(rc.rgb_adr.numpy(), np.int32), dtype=int)
                depth_adr = wp.array(np.asarray(rc.depth_adr.numpy(), np.int32), dtype=int)

            def draw() -> None:
                if rc is None:
                    return
                mjw.refit_bvh(m, d, rc)
                mjw.render(m, d, rc)
                launch_images(
                    wp,
                    rc,
                    rgb_adr,
                    depth_adr,
                    npix,
                    mm,
                    rows_d,
                    step_d,
                    per_frame,
                    rgb_store,
                    mm_store,
                    m_store,
                )

            def period() -> None:
                for _ in range(per_frame):
                    wp.launch(set_ctrl, dim=(n, model.nu), inputs=ctrl_in, outputs=[d.ctrl])
                    mjw.step(m, d)
                    wp.launch(tick, dim=1, inputs=[step_d])
                if sched.resets:  # worlds whose next episode starts now
                    wp.launch(
                        starts,
                        dim=n,
                        inputs=[start_d, episode_d, step_d, per_frame, d.overflow],
                        outputs=[reset_d, overflow_of],
                    )
                    mjw.reset_data(m, d, reset=reset_d)
                    wp.launch(
                        begin,
                        dim=n,
                        inputs=[reset_d, episode_d, step_d, per_frame, qpos0_d, plan_d, offset_d],
                        outputs=[d.qpos, d.ctrl],
                    )
                    if looks is not None:  # the appearance of the episodes starting now
                        wp.launch(set_looks, dim=look_dim, inputs=[reset_d, *look_at, *look_in])
                mjw.forward(m, d)
                draw()

            draw()
            # Pinned host mirrors of what a frame records; a frame's copies are taken right
            # after its GPU work, and the host files them while the GPU computes the next one.
            pinned = self.device.startswith("cuda")
            sources = {
                name: getattr(d, name)
                for name in (*DYNAMIC, "site_xpos", "site_xmat", "xpos", "xquat", "nacon")
            }
            sources.update(
                contact_geom=d.contact.geom,
                contact_dist=d.contact.dist,
                contact_world=d.contact.worldid,
            )
            if rc is not None and not store:
                for c in range(ncam):
                    sources[f"rgb{c}"] = rgb_store[c]
                    sources[f"depth{c}"] = (mm_store if mm else m_store)[c]
            sources = {k: a for k, a in sources.items() if a.size}
            if rc is not None:
                parts["stores_first_draw"] = time.perf_counter() - t_part
            if first_call:
                self._kernels_ready = True
                log.info(
                    "demos %s: GPU kernels ready in %.1f s (%d modules in the cache now)",
                    setup.scene.id,
                    time.perf_counter() - t_kernels,
                    cached_modules(cache),
                )
            t_part = time.perf_counter()
            grab = host_reader(wp, sources, pinned)
            parts["mirrors"] = time.perf_counter() - t_part
            setup_s = time.perf_counter() - t0
            self.times.setup += setup_s
            parts["rest"] = setup_s - sum(parts.values())
            captured = None
            copy_s = frames_s = 0.0
            t1 = time.perf_counter()
            host = grab()
            frames_s += time.perf_counter() - t1
            ep_step = _EpisodeSteps(offsets, lengths, per_frame)
            for b in range(nb):
                t1 = time.perf_counter()
                if b + 1 < nb:  # boundary b + 1 runs on the GPU while boundary b is filed
                    captured = run_period(wp, period, captured, self.graph)
                t2 = time.perf_counter()
                self._record(
                    b,
                    sched,
                    host,
                    frames,
                    template,
                    targets,
                    ep_step,
                    robot_geom,
                    allowed,
                    worst,
                    (pick, target),
                    rc is not None and not store,
                )
                t3 = time.perf_counter()
                if b + 1 < nb:
                    host = grab()
                frames_s += (t2 - t1) + (time.perf_counter() - t3)
                copy_s += t3 - t2
            overflow = np.zeros(n_ep, np.int64)
            if sched.resets:
                overflow |= overflow_of.numpy()
            last = sched.episode[-1]
            on = last >= 0
            np.bitwise_or.at(overflow, last[on], d.overflow.numpy()[on])
            if store:  # the call's images, one block per camera, into an arena
                t4 = time.perf_counter()
                frames.rgb, frames.depth = self._images_to_host(
                    rgb_store, mm_store, m_store, sched.n_rows
                )
                del rgb_store, mm_store, m_store
                copy_s += time.perf_counter() - t4
        self.times.frames += frames_s
        self.times.copy += copy_s
        t3 = time.perf_counter()
        recs = frames.recordings(sched.rows, n_frames, cfg)
        finish_recordings(setup, plans, recs, n_frames, per_frame, worst, cfg.fps)
        calibrate_recordings(setup, recs, cfg, looks)
        from factory.tasks.pick_place.objects import Outcome

        for i in map(int, np.flatnonzero(overflow)):
            recs[i].outcome = Outcome(
                False,
                OVERFLOW,
                {"nconmax": nconmax, "njmax": njmax, "overflow_bits": float(overflow[i])},
            )
        for i, r in enumerate(recs):
            r.appearance = looks[i][0] if looks is not None else None
            r.sim_seconds = frames_s / n_ep
            r.render_seconds = copy_s / n_ep
        finish_s = time.perf_counter() - t3
        self.times.finish += finish_s
        log.info(
            "warp call: %d episodes on %d worlds x %d frames (%.0f %% busy): setup %.1f s (%s), "
            "GPU and copies %.1f s, filing and image copies %.1f s, success checks %.1f s",
            n_ep,
            n,
            nb,
            100 * sched.busy(),
            setup_s,
            ", ".join(f"{k} {v:.1f}" for k, v in parts.items()),
            frames_s,
            copy_s,
            finish_s,
        )
        return recs

    def _images_to_host(
        self, rgb: Any, mm: Any, m: Any, n_rows: int
    ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Copies the device image stores of a call (one per camera, in ``cfg.cameras``
        order: ``rgb[c]`` (R, 3 H W) uint8; ``mm[c]``/``m[c]`` (R, H W) depth) into an arena
        taken now from :attr:`arenas`: from a CUDA device through page-locked staging buffers
        (:func:`staged_copy`; the arena itself is not page-locked), on the CPU directly.

        Returns:
            ``rgb[cam]`` (R, H, W, 3) and ``depth[cam]`` (R, H, W), views of the arena.
        """
        wp, cfg = self.wp, self.cfg
        depth = mm if cfg.depth == "uint16_mm" else m
        specs = {
            k: v
            for k, v in _Frames.specs(n_rows, 0, cfg).items()
            if k.startswith(("rgb/", "depth/"))
        }
        from factory.demos.execute.shared_frames import Arena

        nbytes = Arena.bytes_for(list(specs.values()))
        arena = self.arenas.take(nbytes)
        self._arenas.append(arena)
        dev = wp.get_device(self.device)
        out_rgb: dict[str, np.ndarray] = {}
        out_depth: dict[str, np.ndarray] = {}
        pairs: list[tuple[np.ndarray, Any]] = []
        for k, cam in enumerate(cfg.cameras):
            for out, key, src in ((out_rgb, f"rgb/{cam}", rgb), (out_depth, f"depth/{cam}", depth)):
                out[cam] = arena.empty(*specs[key])
                pairs.append((out[cam], src[k]))
        if dev.is_cuda:
            staged_copy(wp, self.device)(pairs)
        else:
            for dest, src in pairs:
                host = wp.array(dest.reshape(n_rows, -1), dtype=src.dtype, device="cpu", copy=False)
                wp.copy(host, src)
        return out_rgb, out_depth

    def _record(
        self,
        b: int,
        sched: WorldSchedule,
        host: dict[str, np.ndarray],
        frames: _Frames,
        template: np.ndarray,
        targets: np.ndarray,
        ep_step: _EpisodeSteps,
        robot_geom: np.ndarray,
        allowed: np.ndarray,
        worst: np.ndarray,
        bodies: tuple[int, int],
        images: bool,
    ) -> None:
        """Files the frames of boundary ``b`` into their rows of ``frames`` (whole-batch array
        operations over the worlds that record a frame there).

        Args:
            host: host copies of the boundary's device arrays (``qpos``, ``xpos``, ``rgb``,
                ..., ``contact_*``; world-major).
            template: (episodes, nstate) each episode's initial state.
            targets: (sum of the episodes' steps, 8) their recorded actions, one after another.
            worst: (episodes,) deepest robot penetration so far (m), updated.
            images: whether ``host`` holds RGB (ncam, n, 3*H*W) and depth (ncam, n, H*W).
        """
        lay = self.layout
        robot = self.setup.robot
        live = np.flatnonzero(sched.row[b] >= 0)
        if live.size == 0:
            return
        rows = sched.row[b, live]
        ep = sched.episode[b, live]
        states = template[ep]
        for name in DYNAMIC:
            if name in lay and lay[name].stop > lay[name].start and name in host:
                states[:, lay[name]] = host[name].reshape(sched.worlds, -1)[live]
        frames.state[rows] = states
        qpos = states[:, lay["qpos"]]
        frames.joint_pos[rows] = qpos[:, robot.qpos]
        fingers = qpos[:, robot.finger_qpos]
        frames.gripper[rows, 0] = fingers[:, 0] - fingers[:, 1]
        frames.ee_pose[rows, :3] = host["site_xpos"][live, robot.site]
        frames.ee_pose[rows, 3:] = quat_from_mat(host["site_xmat"][live, robot.site])
        xpos, xquat = host["xpos"][live], host["xquat"][live]
        a, c = bodies
        frames.env_state[rows] = np.concatenate(
            [xpos[:, a], xquat[:, a], xpos[:, c], xquat[:, c]], axis=1
        )
        frames.action[rows] = targets[ep_step.action_index(ep, sched.frame[b, live])]
        # Robot penetration: the deepest contact between a robot geom and a geom that is not
        # the pick object, the target or its support (as the CPU executor's check).
        nacon = min(int(host["nacon"][0]), len(host.get("contact_dist", ())))
        if nacon:
            geom = host["contact_geom"][:nacon]
            dist = host["contact_dist"][:nacon]
            world = host["contact_world"][:nacon]
            g1, g2 = geom[:, 0], geom[:, 1]
            ok = (g1 >= 0) & (g2 >= 0) & (world >= 0) & (world < sched.worlds)
            g1, g2, dist, world = g1[ok], g2[ok], dist[ok], world[ok]
            one = robot_geom[g1] != robot_geom[g2]
            other = np.where(robot_geom[g1], g2, g1)
            hit = one & ~allowed[other] & (sched.row[b, world] >= 0)
            if hit.any():
                np.maximum.at(worst, sched.episode[b, world[hit]], np.maximum(0.0, -dist[hit]))
        if images:
            h, w = self.cfg.height, self.cfg.width
            for k, cam in enumerate(self.cfg.cameras):
                frames.rgb[cam][rows] = host[f"rgb{k}"][live].reshape(-1, h, w, 3)
                frames.depth[cam][rows] = host[f"depth{k}"][live].reshape(-1, h, w)


@dataclass(frozen=True)
class _EpisodeSteps:
    """Where each episode's steps lie in the call's concatenated controls and targets."""

    offsets: np.ndarray
    lengths: np.ndarray
    per_frame: int

    def action_index(self, ep: np.ndarray, frame: np.ndarray) -> np.ndarray:
        """Row of the recorded action of frame ``frame`` of episodes ``ep``: the target of the
        last step of the period that follows the frame (the episode's last one past its end)."""
        step = np.minimum((frame + 1) * self.per_frame, self.lengths[ep]) - 1
        return self.offsets[ep] + step


@dataclass
class _Frames:
    """The call's recorded signals in flat rows, one row per filed frame: ``state`` (R, nstate),
    ``joint_pos`` (R, 7), ... , ``rgb[cam]`` (R, H, W, 3); an episode's frames are the rows of
    its :attr:`WorldSchedule.rows` slice (strided for a padded call, a block for a packed one).
    """

    state: np.ndarray
    joint_pos: np.ndarray
    gripper: np.ndarray
    ee_pose: np.ndarray
    action: np.ndarray
    env_state: np.ndarray
    rgb: dict[str, np.ndarray]
    depth: dict[str, np.ndarray]

    @staticmethod
    def specs(rows: int, nstate: int, cfg: RecordConfig) -> dict[str, Any]:
        """``name -> (shape, dtype)`` of every buffer (``rgb/<cam>``, ``depth/<cam>``)."""
        depth_type = np.uint16 if cfg.depth == "uint16_mm" else np.float32
        cams = cfg.cameras if cfg.render else ()
        out: dict[str, Any] = {
            "state": ((rows, nstate), np.float64),
            "joint_pos": ((rows, 7), np.float64),
            "gripper": ((rows, 1), np.float64),
            "ee_pose": ((rows, 7), np.float64),
            "action": ((rows, 8), np.float64),
            "env_state": ((rows, 14), np.float64),
        }
        for c in cams:
            out[f"rgb/{c}"] = ((rows, cfg.height, cfg.width, 3), np.uint8)
            out[f"depth/{c}"] = ((rows, cfg.height, cfg.width), depth_type)
        return out

    @classmethod
    def nbytes(cls, rows: int, nstate: int, cfg: RecordConfig) -> int:
        """Bytes of every buffer together (page-aligned, as an arena places them)."""
        from factory.demos.execute.shared_frames import Arena

        return Arena.bytes_for(list(cls.specs(rows, nstate, cfg).values()))

    @classmethod
    def allocate(
        cls,
        rows: int,
        nstate: int,
        cfg: RecordConfig,
        arena: Any = None,
        images: bool = True,
    ) -> _Frames:
        """Buffers of ``rows`` frames: zero-filled, or in ``arena`` as they are
        (:meth:`WarpExecutor._record` writes every row an episode reads); without ``images``
        the RGB and depth buffers are left out (filled in later)."""
        made = {
            k: (np.zeros(shape, dt) if arena is None else arena.empty(shape, dt))
            for k, (shape, dt) in cls.specs(rows, nstate, cfg).items()
            if images or not k.startswith(("rgb/", "depth/"))
        }
        return cls(
            state=made["state"],
            joint_pos=made["joint_pos"],
            gripper=made["gripper"],
            ee_pose=made["ee_pose"],
            action=made["action"],
            env_state=made["env_state"],
            rgb={k[4:]: a for k, a in made.items() if k.startswith("rgb/")},
            depth={k[6:]: a for k, a in made.items() if k.startswith("depth/")},
        )

    def recordings(
        self, rows: list[slice], n_frames: list[int], cfg: RecordConfig
    ) -> list[Recording]:
        """One :class:`Recording` per episode: views of its rows (no copies)."""
        out = []
        for sl, f in zip(rows, n_frames, strict=True):
            out.append(
                Recording(
                    time=np.arange(f) / cfg.fps,
                    state=self.state[sl],
                    joint_pos=self.joint_pos[sl],
                    gripper=self.gripper[sl],
                    ee_pose=self.ee_pose[sl],
                    action=self.action[sl],
                    env_state=self.env_state[sl],
                    rgb={c: a[sl] for c, a in self.rgb.items()},
                    depth={c: a[sl] for c, a in self.depth.items()},
                )
            )
        return out
