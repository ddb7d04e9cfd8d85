"""Open-loop plans of one scene stepped together as MuJoCo Warp worlds, their states recorded
(the GPU physics of the ``episode`` execution: :mod:`factory.demos.episode_execution`).

A task that simulates its episodes itself (``open``, ``close``) plans each as per-physics-step
controls from an initial configuration, then judges it from what happened. Here the plans of a
scene run as the worlds of one MuJoCo Warp model, as the ``batch`` executor runs the fixed
task's (:mod:`factory.demos.execute.warp`: its controls kernel, its state layout, its contact
buffers), but nothing is drawn and nothing is judged: per recorded frame the host receives each
world's MuJoCo integration state and the deepest contact of a robot geom with a geom it may not
touch; per plan, the configuration after each of its *probe* steps (what a task's success check
reads between frames: ``open``'s hand-to-handle distance at the end of the pull). The task
rebuilds its recording and its verdict from those on the host
(:class:`~factory.demos.record.from_states.StatesRecorder`).

One call: the plans' controls are uploaded once, ``(sum of steps, nu)``; every world runs one
plan from step 0 (a plan shorter than the call's longest holds its last control, and its frames
past its end are not kept); a recording period (``1 / fps``) is ``per_frame`` times (the step's
controls, ``mujoco_warp.step``, the probes' configurations kept on the device) and a
``forward`` (kinematics and contacts of the recorded state, as the CPU executor's
``mj_forward``). On CUDA the period is captured once into a CUDA graph and replayed. After each
period the host copies the dynamic state and the contacts, while the device runs the next
period.

MuJoCo Warp computes in float32 (the CPU in float64): trajectories are close to the CPU
executor's, not equal, so a marginal episode may be judged differently (tests/demos/
test_episode_gpu_physics.py compares the verdicts on the same seeds).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import mujoco
import numpy as np

from factory.demos.execute.warp import (
    DEVICE_LOCK,
    DYNAMIC,
    buffer_sizes,
    host_reader,
    run_period,
    state_layout,
    trace_sim,
)
from factory.demos.record.from_states import PlanRun, WorldPlan
from factory.demos.record.payload import STATE_SPEC
from factory.sim.kernel_preload import PreloadReport

__all__ = ["PlanRun", "PlanWorldTimes", "WarpPlanWorlds", "WorldPlan"]

log = logging.getLogger(__name__)

HEADROOMS = (3.0, 6.0, 12.0)
"""Contact buffer sizes tried (times the initial states' contacts, :func:`~factory.demos.
execute.warp.buffer_sizes`): worlds that overflowed run again with the next."""


@dataclass
class PlanWorldTimes:
    """Seconds spent by :meth:`WarpPlanWorlds.run` (summed over calls).

    Attributes:
        setup: templates, device buffers and kernel loading.
        periods: the device's periods and the copies back (host waiting included).
        host: filing the states and the contacts on the host.
        record: the tasks' recordings rebuilt from the states on the host (added by the
            caller: :func:`~factory.demos.episode_physics.simulate_plans`).
        calls, worlds, frames: calls made, worlds over them, frames recorded.
    """

    setup: float = 0.0
    periods: float = 0.0
    host: float = 0.0
    record: float = 0.0
    calls: int = 0
    worlds: int = 0
    frames: int = 0
    preload: list[PreloadReport] = field(default_factory=list)


class WarpPlanWorlds:
    """Steps open-loop plans of one scene as worlds of one MuJoCo Warp model (module docstring).

    Args:
        model: the scene's compiled model (the planner processes' own: same set-up).
        robot_geom: (ngeom,) bool, the robot's geoms.
        allowed: (ngeom,) bool, geoms a robot contact with is no collision.
        fps: recording rate (Hz): a frame every ``round(1 / (fps * timestep))`` steps.
        device: Warp device; default ``cuda:0`` when CUDA is present, else ``cpu`` (slow:
            tests).
        max_worlds: most worlds per call (``demos.gpu_batch``); more plans run in several calls,
            of similar lengths together.
        graph: capture a period into a CUDA graph (CUDA only).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        robot_geom: np.ndarray,
        allowed: np.ndarray,
        fps: float,
        device: str | None = None,
        max_worlds: int = 512,
        graph: bool = True,
    ) -> None:
        import mujoco_warp as mjw
        import warp as wp

        from factory.sim.backend import cuda_available, init_warp

        init_warp()
        self.wp, self.mjw = wp, mjw
        self.model = model
        self.robot_geom = np.asarray(robot_geom, bool)
        self.allowed = np.asarray(allowed, bool)
        self.device = device or ("cuda:0" if cuda_available() else "cpu")
        self.graph = graph and self.device.startswith("cuda")
        self.max_worlds = max(1, int(max_worlds))
        self.per_frame = max(1, round(1.0 / (fps * float(model.opt.timestep))))
        self.layout = state_layout(model)
        self.nstate = mujoco.mj_stateSize(model, STATE_SPEC)
        with DEVICE_LOCK, wp.ScopedDevice(self.device):
            self.m = mjw.put_model(model)
        self.times = PlanWorldTimes()
        self._warm: PreloadReport | None = None

    # ---- kernels
    def warm_up(self) -> PreloadReport:
        """Compiles (or loads from Warp's kernel cache) the kernels of a call on every core
        (:func:`factory.sim.kernel_preload.preload`: a dry trace of one world's launches), so
        that the first call finds them ready; idempotent (later calls return the first
        report)."""
        if self._warm is not None:
            return self._warm
        from factory.demos.execute import plan_worlds_kernels as pk
        from factory.demos.execute import warp_kernels as k
        from factory.sim.kernel_preload import preload

        wp, mjw, model = self.wp, self.mjw, self.model
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        nconmax, njmax = buffer_sizes(model, model.qpos0[None].copy(), HEADROOMS[0])

        def trace() -> None:
            for kernel in (k.set_ctrl, k.tick, pk.keep_qpos):
                wp.launch(kernel, dim=1)
            trace_sim(wp, mjw, self.m, model, data, nconmax, njmax, None)

        with wp.ScopedDevice(self.device):
            self._warm = preload(wp, trace, around_trace=DEVICE_LOCK)
        self.times.preload.append(self._warm)
        log.info("demos: the plans' GPU physics kernels: %s", self._warm.describe())
        return self._warm

    # ---- runs
    def run(self, plans: list[WorldPlan]) -> list[PlanRun]:
        """Runs ``plans`` (one world each) and returns their runs, in order.

        Plans are sorted by length and run in calls of at most :attr:`max_worlds`; worlds whose
        contact or constraint buffers overflowed run again with larger buffers
        (:data:`HEADROOMS`); a run that still overflows keeps its ``overflow`` bits.
        """
        out: list[PlanRun | None] = [None] * len(plans)
        order = sorted(range(len(plans)), key=lambda i: len(plans[i].ctrl))
        self.warm_up()
        for lo in range(0, len(order), self.max_worlds):
            todo = order[lo : lo + self.max_worlds]
            for headroom in HEADROOMS:
                runs = self._call([plans[i] for i in todo], headroom)
                for i, r in zip(todo, runs, strict=True):
                    out[i] = r
                todo = [i for i, r in zip(todo, runs, strict=True) if r.overflow]
                if not todo:
                    break
                log.info("demos: %d world(s) overflowed; run again with more room", len(todo))
        return [r for r in out if r is not None]

    def _templates(self, plans: list[WorldPlan]) -> np.ndarray:
        """(n, nstate) each plan's initial state as the CPU executor makes it (reset, ``qpos0``,
        the first control, ``mj_forward``): the parts the device never changes come from here."""
        model = self.model
        data = mujoco.MjData(model)
        out = np.empty((len(plans), self.nstate))
        for i, p in enumerate(plans):
            mujoco.mj_resetData(model, data)
            data.qpos[:] = p.qpos0
            data.ctrl[:] = p.ctrl[0]
            mujoco.mj_forward(model, data)
            mujoco.mj_getState(model, data, out[i], STATE_SPEC)
        return out

    def _call(self, plans: list[WorldPlan], headroom: float) -> list[PlanRun]:
        from factory.demos.execute import plan_worlds_kernels as pk
        from factory.demos.execute.warp_kernels import set_ctrl, tick
        from factory.demos.execute.world_schedule import padded_schedule

        wp, mjw, model = self.wp, self.mjw, self.model
        t0 = time.perf_counter()
        per_frame, n = self.per_frame, len(plans)
        lengths = np.array([len(p.ctrl) for p in plans], np.int64)
        n_frames = [int(np.ceil(t / per_frame)) + 1 for t in lengths]
        sched = padded_schedule(n_frames)
        nb = sched.boundaries
        offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int32)
        ctrl = np.concatenate([p.ctrl for p in plans]).astype(np.float32)
        q0 = np.stack([p.qpos0 for p in plans])
        nprobe = max(1, max(len(p.probes) for p in plans))
        probe = np.full((n, nprobe), -1, np.int32)
        for w, p in enumerate(plans):
            probe[w, : len(p.probes)] = p.probes
        nconmax, njmax = buffer_sizes(model, q0, headroom)
        template = self._templates(plans)
        states = np.empty((nb, n, self.nstate))  # frame-major, as the device gives them
        worst = np.zeros(n)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        with wp.ScopedDevice(self.device):
            m = self.m
            d = mjw.put_data(model, data, nworld=n, nconmax=nconmax, njmax=njmax)
            d.qpos.assign(wp.array(q0.astype(np.float32), dtype=float))
            plan_d = wp.array(ctrl, dtype=float)
            ctrl_in = [
                plan_d,
                wp.array(offsets, dtype=int),
                wp.array(lengths.astype(np.int32), dtype=int),
                wp.array(sched.episode, dtype=int),
                wp.array(sched.frame, dtype=int),
                wp.zeros(1, dtype=int),
                per_frame,
            ]
            step_d = ctrl_in[5]
            probe_d = wp.array(probe, dtype=int)
            kept_d = wp.zeros((n, nprobe, model.nq), dtype=float)
            wp.launch(set_ctrl, dim=(n, model.nu), inputs=ctrl_in, outputs=[d.ctrl])
            mjw.forward(m, d)

            def period() -> None:
                for _ in range(per_frame):
                    wp.launch(set_ctrl, dim=(n, model.nu), inputs=ctrl_in, outputs=[d.ctrl])
                    mjw.step(m, d)
                    keep_in = [probe_d, step_d, d.qpos, kept_d]
                    wp.launch(pk.keep_qpos, dim=(n, nprobe), inputs=keep_in)
                    wp.launch(tick, dim=1, inputs=[step_d])
                mjw.forward(m, d)

            sources = {name: getattr(d, name) for name in (*DYNAMIC, "nacon")}
            sources.update(
                contact_geom=d.contact.geom,
                contact_dist=d.contact.dist,
                contact_world=d.contact.worldid,
            )
            sources = {k: a for k, a in sources.items() if a.size}
            pinned = self.device.startswith("cuda")
            grab = host_reader(wp, sources, pinned)
            self.times.setup += time.perf_counter() - t0
            captured = None
            periods_s = host_s = 0.0
            t1 = time.perf_counter()
            host = grab()
            periods_s += time.perf_counter() - t1
            for b in range(nb):
                t1 = time.perf_counter()
                if b + 1 < nb:  # the next period runs on the device while this one is filed
                    captured = run_period(wp, period, captured, self.graph)
                t2 = time.perf_counter()
                self._file(host, template, states[b], sched.row[b] >= 0, worst)
                t3 = time.perf_counter()
                if b + 1 < nb:
                    host = grab()
                periods_s += (t2 - t1) + (time.perf_counter() - t3)
                host_s += t3 - t2
            kept = kept_d.numpy().astype(np.float64)
            overflow = d.overflow.numpy() if d.overflow.size else np.zeros(n, np.int64)
        self.times.periods += periods_s
        self.times.host += host_s
        self.times.calls += 1
        self.times.worlds += n
        self.times.frames += sum(n_frames)
        log.info(
            "demos: GPU physics call: %d worlds x %d frames (%d steps each), %.1f s on the device "
            "and copies, %.1f s filing",
            n,
            nb,
            per_frame,
            periods_s,
            host_s,
        )
        over = np.broadcast_to(np.asarray(overflow, np.int64).reshape(-1), (n,))
        return [
            PlanRun(
                np.ascontiguousarray(states[: n_frames[w], w]),
                kept[w, : len(p.probes)],
                float(worst[w]),
                int(over[w]),
            )
            for w, p in enumerate(plans)
        ]

    def _file(
        self,
        host: dict[str, np.ndarray],
        template: np.ndarray,
        frame: np.ndarray,
        live: np.ndarray,
        worst: np.ndarray,
    ) -> None:
        """Files one recorded frame of every world: its integration state into ``frame``
        ((n, nstate): the template with the dynamic parts from ``host``) and, for the worlds
        ``live`` ((n,) bool: still within their plan), the robot's deepest penetration into
        ``worst`` ((n,) m, updated)."""
        lay = self.layout
        n = len(frame)
        frame[:] = template
        for name in DYNAMIC:
            if name in host and lay[name].stop > lay[name].start:
                frame[:, lay[name]] = host[name].reshape(n, -1)
        nacon = min(int(host["nacon"][0]), len(host.get("contact_dist", ())))
        if not nacon:
            return
        from factory.demos.record.contacts import penetration_by

        geom = host["contact_geom"][:nacon]
        world = host["contact_world"][:nacon]
        ok = (world >= 0) & (world < n)
        ok[ok] &= live[world[ok]]
        depth = penetration_by(
            geom[ok], host["contact_dist"][:nacon][ok], world[ok], n, self.robot_geom, self.allowed
        )
        np.maximum(worst, depth, out=worst)
