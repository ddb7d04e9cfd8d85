"""Recorded states of the episodes a task simulates itself, drawn in batches on MuJoCo Warp with
the scene's own cameras (the GPU twin of the task's CPU renderer: the articulated tasks'
:class:`~factory.tasks.articulated.record.ArticulatedRenderer`, the mobile task's
:class:`~factory.tasks.mobile_pick_place.execute.MobileRenderer`).

An episode of a :class:`~factory.demos.record.scene.SimulatingScene` is simulated first (on the
CPU, in the GPU pipeline's planner processes, without images) and drawn afterwards from its
recorded integration states. :class:`WarpRecordingRenderer` makes the recorded frames of one or
several episodes of a scene the worlds of one MuJoCo Warp model: per call it uploads each world's
configuration (``qpos``, and the mocap poses when the model has mocap bodies) from the recorded
states, runs ``mujoco_warp.kinematics`` and ``camlight`` (plus ``com_pos`` where a camera or light
tracks a centre of mass), refits the renderer's BVH, ray-traces every camera of every world in one
``mujoco_warp.render``, converts the pixels on the device
(:mod:`factory.demos.execute.recording_warp_kernels`) and copies RGB and depth back in one block
each.

Cameras: the scene's :class:`~factory.demos.record.rig.CameraRig`
(:meth:`~factory.demos.record.scene.SimulatingScene.camera_rig`: the fixed-base Panda's ``left``,
``right`` and ``wrist``; the mobile robot's ``left``, ``right``, ``wrist``, ``fisheye_front`` and
``fisheye_back``), never a list of its own. Pinhole cameras use MuJoCo Warp's own rays; each
fisheye camera is one camera whose precomputed per-pixel rays (``RenderContext.ray``) are
overwritten with the lens's directions (:attr:`factory.sim.fisheye.FisheyeSpec.rays`, in MuJoCo's
camera frame: ``-z`` forward, ``+y`` up, ``+x`` right), so a fisheye is one ray-traced image, not
a cube map.

Output: what the CPU path records, camera -> ``(F, H, W, 3)`` uint8 RGB and ``(F, H, W)``
depth (``uint16_mm`` millimetres or ``float32`` metres; fisheye images square). Pinhole depth
is along the optical axis (MuJoCo Warp's planar depth); a ray that hits nothing, or hits beyond
the far plane, reads the far plane (``vis.map.zfar`` x ``stat.extent`` of the model, m), as
OpenGL's depth buffer does (:class:`~factory.demos.record.frame_render.CameraStrip`). Fisheye
depth is the ray length (planar depth / cos(theta)); pixels outside the image circle are black
with depth 0, and rays that hit nothing, or beyond the lens's ``far`` (50 m), read 0, as
:class:`~factory.sim.fisheye.FisheyeRenderer` writes them. No depth is NaN.

The images are alike, not identical, to the OpenGL ones: a ray tracer with the model's lights
and headlight, no shadows (``demos.shadows`` does not apply), the geom groups 0-2 OpenGL draws
(tests/demos/test_recording_render_warp.py states the tolerances, per task).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import mujoco
import numpy as np

if TYPE_CHECKING:
    from factory.demos.record.rig import CameraRig
    from factory.sim.kernel_preload import PreloadReport

log = logging.getLogger(__name__)

_CAMERA = int(mujoco.mjtObj.mjOBJ_CAMERA)

DEVICE_MEMORY_SHARE = 0.5
"""Share of a CUDA device's free memory one batch of worlds may take (physics data, BVH,
render buffers and converted images)."""

HOST_BUDGET_BYTES = 1 << 30
"""Memory one batch may take on Warp's CPU device (bytes)."""

MAX_WORLDS = {"cuda": 2048, "cpu": 64}
"""Most worlds (frames) per call by device kind: beyond a few thousand frames per call the GPU
is busy anyway; on the CPU device a call is slow whatever its size."""


@dataclass
class WarpRenderTimes:
    """Where the renderer's time went (s), over all calls.

    Attributes:
        upload: host side states -> device (configurations, padding).
        draw: kinematics, BVH refit, ray tracing and pixel conversion (device work, waited for).
        copy: device -> host copies and the per-camera blocks' slicing.
        frames: frames rendered (padding excluded). calls: render calls.
    """

    upload: float = 0.0
    draw: float = 0.0
    copy: float = 0.0
    frames: int = 0
    calls: int = 0


def _device_bytes(obj: Any, seen: set[int] | None = None) -> int:
    """Bytes of the Warp arrays held by ``obj`` and the dataclasses it holds."""
    import warp as wp

    seen = set() if seen is None else seen
    if id(obj) in seen:
        return 0
    seen.add(id(obj))
    if isinstance(obj, wp.array):
        return int(obj.capacity)
    if hasattr(obj, "__dict__") and not isinstance(obj, type):
        return sum(_device_bytes(v, seen) for v in vars(obj).values())
    return 0


class DrawnRecording(Protocol):
    """A recording the renderer draws into: a task's recording type (the articulated tasks'
    :class:`~factory.tasks.articulated.record.Recording`, the mobile task's
    :class:`~factory.tasks.mobile_pick_place.execute.MobileRecording`).

    Attributes:
        state: (F, nstate) MuJoCo integration states, one per frame.
        rgb: camera -> (F, H, W, 3) uint8 (filled here).
        depth: camera -> (F, H, W) uint16 mm or float32 m (filled here).
        render_seconds: seconds spent drawing it (added to here).
    """

    state: np.ndarray
    rgb: dict[str, np.ndarray]
    depth: dict[str, np.ndarray]
    render_seconds: float


class WarpRecordingRenderer:
    """Renders recorded states of a scene on MuJoCo Warp with the scene's cameras, a batch of
    frames per call.

    Args:
        model: the scene's compiled model, the robot included (not changed).
        rig: the cameras, image sizes and depth format, as the CPU path draws them
            (:meth:`~factory.demos.record.scene.SimulatingScene.camera_rig`).
        device: Warp device; default ``cuda:0`` when CUDA is present, else ``cpu`` (slow: tests).
        max_worlds: most frames per call (default by device kind, :data:`MAX_WORLDS`).
        budget: bytes one call's worlds may take (default: :data:`DEVICE_MEMORY_SHARE` of the
            device's free memory on CUDA, :data:`HOST_BUDGET_BYTES` on the CPU device).

    Attributes:
        worlds: frames per call (the batch size): the fewest of ``max_worlds`` and what fits
            in ``budget``.
        times: seconds spent so far (:class:`WarpRenderTimes`).

    Raises:
        ConfigError: the rig names no camera, or a camera the model lacks.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        rig: CameraRig,
        device: str | None = None,
        max_worlds: int | None = None,
        budget: int | None = None,
    ) -> None:
        import mujoco_warp as mjw
        import warp as wp

        from factory.demos.execute.warp import state_layout
        from factory.errors import ConfigError
        from factory.sim.backend import cuda_available, init_warp

        if not rig.cameras:
            raise ConfigError(
                "the GPU renderer got no cameras to draw; record at least one camera "
                "(demos.cameras), or demos.render=false to record no images"
            )
        missing = [c.camera for c in rig.cameras if mujoco.mj_name2id(model, _CAMERA, c.camera) < 0]
        if missing:
            raise ConfigError(
                f"the scene's model has no camera(s) {missing} that its camera rig draws; the "
                "task's camera_rig must name cameras of the model its set-up composed"
            )
        init_warp()
        self.wp, self.mjw = wp, mjw
        self.model = model
        self.rig = rig
        self.device = device or ("cuda:0" if cuda_available() else "cpu")
        dev = wp.get_device(self.device)
        self.layout = state_layout(model)
        self.times = WarpRenderTimes()
        self.cameras = list(rig.keys)
        names = [c.camera for c in rig.cameras]
        res = [(c.width, c.height) for c in rig.cameras]
        self._names, self._res = names, res
        self.sizes = [(h, w) for w, h in res]  # (rows, columns) per camera
        npix = [w * h for w, h in res]
        self.starts = np.concatenate([[0], np.cumsum(npix)[:-1]]).astype(np.int64)
        self.total = int(sum(npix))
        modes = (
            int(mujoco.mjtCamLight.mjCAMLIGHT_TRACKCOM),
            int(mujoco.mjtCamLight.mjCAMLIGHT_TARGETBODYCOM),
        )
        self.needs_com = bool(
            np.isin(model.cam_mode, modes).any() or np.isin(model.light_mode, modes).any()
        )
        depth_bytes = 2 if rig.depth == "uint16_mm" else 4
        with wp.ScopedDevice(self.device):
            self.m = mjw.put_model(model)
            one = mjw.make_data(model, nworld=1, nconmax=1, njmax=1)
            per_world = (
                _device_bytes(one)
                + self.total * (4 + 4 + 3 + depth_bytes)  # packed RGB, depth, converted
                + 256 * model.ngeom  # BVH bounds and nodes
            )
            del one
            if budget is None:
                budget = (
                    int(DEVICE_MEMORY_SHARE * dev.free_memory) if dev.is_cuda else HOST_BUDGET_BYTES
                )
            cap = max_worlds or MAX_WORLDS["cuda" if dev.is_cuda else "cpu"]
            self.worlds = max(1, min(cap, budget // max(1, per_world)))
            n = self.worlds
            self.d = mjw.make_data(model, nworld=n, nconmax=1, njmax=1)
            from factory.demos.execute.warp import render_context

            self.rc = render_context(model, n, res, names)
            rgb_adr = np.asarray(self.rc.rgb_adr.numpy(), np.int64)
            depth_adr = np.asarray(self.rc.depth_adr.numpy(), np.int64)
            if not (
                np.array_equal(rgb_adr, self.starts) and np.array_equal(depth_adr, self.starts)
            ):
                raise AssertionError(f"render buffers not laid out per ray: {rgb_adr}, {depth_adr}")
            # Per ray: its camera's first ray and pixel count, depth scale, inside the image,
            # the depth of a miss and the farthest depth kept.
            start = np.repeat(self.starts, npix)
            count = np.repeat(np.asarray(npix, np.int64), npix)
            scale = np.ones(self.total, np.float32)
            inside = np.ones(self.total, np.int32)
            extent = model.stat.extent
            far_gl = np.float32(model.vis.map.zfar * extent)
            miss = np.full(self.total, far_gl, np.float32)
            far = np.full(self.total, far_gl, np.float32)  # beyond OpenGL's far plane: cleared
            rays = self.rc.ray.numpy()
            for k, cam in enumerate(rig.cameras):
                spec = cam.fisheye
                if spec is None:
                    continue
                mask = spec.mask.reshape(-1)
                d = np.array(spec.rays.reshape(-1, 3), np.float64)
                d[~mask] = (0.0, 0.0, -1.0)  # outside the circle: masked, cast straight ahead
                cos = -d[:, 2]
                sl = slice(int(self.starts[k]), int(self.starts[k]) + npix[k])
                rays[sl] = d.astype(np.float32)
                # planar depth -> ray length (beyond 90 degrees both are negative); a ray at
                # 90 degrees has no planar depth: its depth reads 0
                level = np.abs(cos) < 1e-6
                scale[sl] = np.where(level, 0.0, 1.0 / np.where(level, 1.0, cos))
                inside[sl] = mask
                miss[sl] = 0.0
                far[sl] = spec.far
            self.rc.ray.assign(wp.array(rays, dtype=wp.vec3))
            self._ray_in: list[Any] = [
                wp.array(start.astype(np.int32), dtype=int),
                wp.array(count.astype(np.int32), dtype=int),
                wp.array(scale, dtype=float),
                wp.array(inside, dtype=int),
                wp.array(miss, dtype=float),
                wp.array(far, dtype=float),
            ]
            mm = rig.depth == "uint16_mm"
            self._mm = mm
            self._rgb = wp.empty(n * self.total * 3, dtype=wp.uint8)
            self._depth_mm = wp.empty(n * self.total if mm else 1, dtype=wp.uint16)
            self._depth_m = wp.empty(1 if mm else n * self.total, dtype=float)
        pinned = dev.is_cuda
        self._host_rgb = wp.empty(n * self.total * 3, dtype=wp.uint8, device="cpu", pinned=pinned)
        self._host_depth = wp.empty(
            n * self.total, dtype=wp.uint16 if mm else float, device="cpu", pinned=pinned
        )
        log.info(
            "warp recording renderer on %s: %d frames per call (%d cameras, %d rays per frame, "
            "%.1f MB per world)",
            self.device,
            n,
            len(self.cameras),
            self.total,
            per_world / 1e6,
        )

    def _draw(self, states: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Renders up to :attr:`worlds` states (n, nstate) in one call; camera -> RGB (n, H, W,
        3) and depth (n, H, W), views of the host buffers (valid until the next call)."""
        from factory.demos.execute.recording_warp_kernels import to_images

        wp, mjw = self.wp, self.mjw
        n, nw = len(states), self.worlds
        if not 0 < n <= nw:
            raise ValueError(f"a call renders 1..{nw} frames, got {n}")
        t0 = time.perf_counter()
        lay = self.layout
        rows = np.minimum(np.arange(nw), n - 1)  # padding worlds repeat the last frame
        model = self.model
        with wp.ScopedDevice(self.device):
            if model.nq:
                self.d.qpos.assign(states[rows][:, lay["qpos"]].astype(np.float32))
            if model.nmocap:
                pos = states[rows][:, lay["mocap_pos"]].reshape(nw, model.nmocap, 3)
                quat = states[rows][:, lay["mocap_quat"]].reshape(nw, model.nmocap, 4)
                self.d.mocap_pos.assign(wp.array(pos.astype(np.float32), dtype=wp.vec3))
                self.d.mocap_quat.assign(wp.array(quat.astype(np.float32), dtype=wp.quat))
            t1 = time.perf_counter()
            mjw.kinematics(self.m, self.d)
            if self.needs_com:
                mjw.com_pos(self.m, self.d)
            mjw.camlight(self.m, self.d)
            mjw.refit_bvh(self.m, self.d, self.rc)
            mjw.render(self.m, self.d, self.rc)
            wp.launch(
                to_images,
                dim=(nw, self.total),
                inputs=[self.rc.rgb_data, self.rc.depth_data, *self._ray_in, nw, int(self._mm)],
                outputs=[self._rgb, self._depth_mm, self._depth_m],
            )
            wp.synchronize_device(self.device)
            t2 = time.perf_counter()
            wp.copy(self._host_rgb, self._rgb)
            wp.copy(self._host_depth, self._depth_mm if self._mm else self._depth_m)
            wp.synchronize_device(self.device)
        rgb_all, depth_all = self._host_rgb.numpy(), self._host_depth.numpy()
        rgb: dict[str, np.ndarray] = {}
        depth: dict[str, np.ndarray] = {}
        for k, c in enumerate(self.cameras):
            h, w = self.sizes[k]
            s = int(self.starts[k])
            rgb[c] = rgb_all[3 * nw * s : 3 * nw * (s + h * w)].reshape(nw, h, w, 3)[:n]
            depth[c] = depth_all[nw * s : nw * (s + h * w)].reshape(nw, h, w)[:n]
        t3 = time.perf_counter()
        self.times.upload += t1 - t0
        self.times.draw += t2 - t1
        self.times.copy += t3 - t2
        self.times.frames += n
        self.times.calls += 1
        return rgb, depth

    def render(self, states: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Renders recorded integration states (F, nstate), :attr:`worlds` per call (calls of
        equal size, the last one padded).

        Returns:
            camera -> RGB (F, H, W, 3) uint8 and camera -> depth (F, H, W) (uint16 mm or
            float32 m), new arrays.
        """
        f = len(states)
        depth_type = np.uint16 if self.rig.depth == "uint16_mm" else np.float32
        rgb = {c: np.zeros((f, *self.sizes[k], 3), np.uint8) for k, c in enumerate(self.cameras)}
        depth = {c: np.zeros((f, *self.sizes[k]), depth_type) for k, c in enumerate(self.cameras)}
        for a in range(0, f, self.worlds):
            b = min(f, a + self.worlds)
            im, dp = self._draw(states[a:b])
            for c in self.cameras:
                rgb[c][a:b] = im[c]
                depth[c][a:b] = dp[c]
        return rgb, depth

    def warm_up(self) -> PreloadReport:
        """Compiles (or loads from Warp's kernel cache) the kernels a call launches, now and on
        every core (:func:`factory.sim.kernel_preload.preload`): a dry trace of :meth:`_draw`'s
        launches on one world of a throwaway data and render context (same model, cameras and
        options), then the modules in parallel; Warp would otherwise compile them one after
        the other at the first call (``stage=warmup``).

        Returns:
            what the preload did (module variants traced, those loaded now, seconds).
        """
        from factory.demos.execute import recording_warp_kernels as k
        from factory.demos.execute.warp import render_context
        from factory.sim.kernel_preload import preload

        wp, mjw, model = self.wp, self.mjw, self.model

        def trace() -> None:
            wp.launch(k.to_images, dim=1)
            d = mjw.make_data(model, nworld=1, nconmax=1, njmax=1)
            rc = render_context(model, 1, self._res, self._names)
            mjw.kinematics(self.m, d)
            if self.needs_com:
                mjw.com_pos(self.m, d)
            mjw.camlight(self.m, d)
            mjw.refit_bvh(self.m, d, rc)
            mjw.render(self.m, d, rc)

        t0 = time.perf_counter()
        with wp.ScopedDevice(self.device):
            report = preload(wp, trace)
        log.info(
            "warp recording renderer: kernels: %s; %.1f s in all",
            report.describe(),
            time.perf_counter() - t0,
        )
        return report

    def render_recordings(self, recs: list[DrawnRecording]) -> None:
        """Draws every frame of ``recs`` (episodes of this scene) into their ``rgb``/``depth``,
        the frames of all of them filling the calls together; adds each recording's share of
        the time to its ``render_seconds``."""
        stream = RecordingStream(self)
        for r in recs:
            stream.push(r)
        stream.flush()

    def close(self) -> None:
        """Frees the device buffers."""
        for name in ("rc", "d", "m", "_rgb", "_depth_mm", "_depth_m", "_host_rgb", "_host_depth"):
            if hasattr(self, name):
                delattr(self, name)


class RecordingStream:
    """Feeds the frames of recordings to a :class:`WarpRecordingRenderer` in full calls.

    Recordings are queued whole; every time the queue holds a call's worth of frames
    (:attr:`WarpRecordingRenderer.worlds`) they are rendered, an episode's frames possibly split
    over two calls, and the recordings whose last frame is drawn come back complete
    (``rgb``/``depth`` filled, ``render_seconds`` added). :meth:`flush` draws the rest in one
    last, padded call.
    """

    def __init__(self, renderer: WarpRecordingRenderer) -> None:
        self.renderer = renderer
        self._queue: list[list[Any]] = []  # [recording, next frame to draw]
        self._queued = 0

    @property
    def queued(self) -> int:
        """Frames waiting to be drawn."""
        return self._queued

    def image_specs(self, frames: int) -> list[tuple[tuple[int, ...], Any]]:
        """``(shape, dtype)`` of the image arrays of a recording of ``frames`` frames, in the
        order :meth:`push` allocates them: each camera's RGB ``(frames, H, W, 3)`` uint8, then
        its depth ``(frames, H, W)`` (uint16 mm or float32 m, the rig's)."""
        r = self.renderer
        depth_type = np.uint16 if r.rig.depth == "uint16_mm" else np.float32
        out: list[tuple[tuple[int, ...], Any]] = []
        for k in range(len(r.cameras)):
            out += [((frames, *r.sizes[k], 3), np.uint8), ((frames, *r.sizes[k]), depth_type)]
        return out

    def push(
        self, rec: DrawnRecording, alloc: Callable[[tuple[int, ...], Any], np.ndarray] = np.empty
    ) -> list[DrawnRecording]:
        """Queues a recording; returns the recordings completed by the calls this made.

        Args:
            rec: the recording (its ``state`` rows are the frames to draw).
            alloc: makes its image arrays (``alloc(shape, dtype)``; e.g. a shared memory
                arena's ``empty``, so that a writer process reads them in place).
        """
        r = self.renderer
        f = len(rec.state)
        specs = iter(self.image_specs(f))
        for c in r.cameras:
            rec.rgb[c] = alloc(*next(specs))
            rec.depth[c] = alloc(*next(specs))
        self._queue.append([rec, 0])
        self._queued += f
        done: list[DrawnRecording] = []
        while self._queued >= r.worlds:
            done.extend(self._call(r.worlds))
        return done

    def flush(self) -> list[DrawnRecording]:
        """Draws every queued frame; returns the recordings completed."""
        done: list[DrawnRecording] = []
        while self._queued:
            done.extend(self._call(min(self._queued, self.renderer.worlds)))
        return done

    def _call(self, n: int) -> list[DrawnRecording]:
        pieces: list[tuple[DrawnRecording, int, int]] = []
        need = n
        for item in self._queue:
            if not need:
                break
            rec, at = item
            take = min(need, len(rec.state) - at)
            pieces.append((rec, at, at + take))
            item[1] = at + take
            need -= take
        states = np.concatenate([rec.state[a:b] for rec, a, b in pieces])
        t0 = time.perf_counter()
        rgb, depth = self.renderer._draw(states)
        row = 0
        for rec, a, b in pieces:
            for c in self.renderer.cameras:
                rec.rgb[c][a:b] = rgb[c][row : row + b - a]
                rec.depth[c][a:b] = depth[c][row : row + b - a]
            row += b - a
        seconds = time.perf_counter() - t0
        for rec, a, b in pieces:
            rec.render_seconds += seconds * (b - a) / n
        self._queued -= n
        done = [rec for rec, at in self._queue if at == len(rec.state)]
        self._queue = [item for item in self._queue if item[1] < len(item[0].state)]
        log.debug("warp render call: %d frames of %d episodes, %.2f s", n, len(pieces), seconds)
        return done


def frames_per_second(times: WarpRenderTimes) -> float:
    """Frames rendered per second of the renderer's time (all cameras of a frame)."""
    spent = times.upload + times.draw + times.copy
    return times.frames / spent if spent > 0 else math.nan
