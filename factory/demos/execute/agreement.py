"""CPU/GPU agreement of demo execution: the same plans on both executors, compared.

The CPU executor (``mujoco.batch``, float64, OpenGL images) is the reference; the GPU executor
(MuJoCo Warp, float32, ray-traced images) must agree on the success verdict of nearly every
episode and record trajectories and images that are alike. Used by the ``gpu`` tests and by
``scripts/bench_demos_agreement.py``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from factory.demos.execute.cpu import RecordConfig, Recording, execute
from factory.tasks.pick_place.plan import EpisodePlan, SceneSetup


@dataclass
class EpisodeAgreement:
    """One episode on both executors.

    Attributes:
        cpu_success, gpu_success: the verdicts; cpu_reason, gpu_reason: failure reasons.
        ee_max_m: largest tool-position difference over the frames (m).
        object_end_m: pick object's final position difference (m).
        rgb_mean_abs: camera -> mean absolute RGB difference over every frame (0-255 levels).
        depth_median_abs_mm: camera -> median absolute depth difference (mm).
    """

    cpu_success: bool
    gpu_success: bool
    cpu_reason: str
    gpu_reason: str
    ee_max_m: float
    object_end_m: float
    rgb_mean_abs: dict[str, float] = field(default_factory=dict)
    depth_median_abs_mm: dict[str, float] = field(default_factory=dict)


@dataclass
class Agreement:
    """Agreement over a set of episodes (:func:`compare_executors`)."""

    episodes: list[EpisodeAgreement]

    @property
    def verdicts_agree(self) -> float:
        """Share of episodes whose success verdicts agree."""
        same = [e.cpu_success == e.gpu_success for e in self.episodes]
        return float(np.mean(same)) if same else 1.0

    def disagreements(self) -> list[dict[str, Any]]:
        return [
            {"episode": i, **asdict(e)}
            for i, e in enumerate(self.episodes)
            if e.cpu_success != e.gpu_success
        ]

    def summary(self) -> dict[str, Any]:
        eps = self.episodes
        cams = sorted({c for e in eps for c in e.rgb_mean_abs})
        return {
            "episodes": len(eps),
            "cpu_successes": sum(e.cpu_success for e in eps),
            "gpu_successes": sum(e.gpu_success for e in eps),
            "verdicts_agree": self.verdicts_agree,
            "ee_max_m": {
                "median": float(np.median([e.ee_max_m for e in eps])) if eps else 0.0,
                "max": float(max((e.ee_max_m for e in eps), default=0.0)),
            },
            "object_end_m_median": float(np.median([e.object_end_m for e in eps])) if eps else 0.0,
            "rgb_mean_abs": {
                c: float(np.mean([e.rgb_mean_abs[c] for e in eps if c in e.rgb_mean_abs]))
                for c in cams
            },
            "depth_median_abs_mm": {
                c: float(
                    np.median([e.depth_median_abs_mm[c] for e in eps if c in e.depth_median_abs_mm])
                )
                for c in cams
            },
            "disagreements": self.disagreements(),
        }


def compare_recordings(setup: SceneSetup, cpu: list[Recording], gpu: list[Recording]) -> Agreement:
    """Compares recordings of the same plans from the two executors."""
    model = setup.model
    pick = model.body(setup.objects.pick.id).id
    qadr = 1 + int(model.jnt_qposadr[model.body_jntadr[pick]])  # time comes first in the state
    out = []
    for a, b in zip(cpu, gpu, strict=True):
        assert a.outcome is not None and b.outcome is not None
        f = min(len(a.time), len(b.time))
        e = EpisodeAgreement(
            cpu_success=a.outcome.success,
            gpu_success=b.outcome.success,
            cpu_reason=a.outcome.reason,
            gpu_reason=b.outcome.reason,
            ee_max_m=float(np.abs(a.ee_pose[:f, :3] - b.ee_pose[:f, :3]).max()),
            object_end_m=float(
                np.linalg.norm(a.state[f - 1, qadr : qadr + 3] - b.state[f - 1, qadr : qadr + 3])
            ),
        )
        for cam in a.rgb:
            if cam in b.rgb:
                diff = np.abs(a.rgb[cam][:f].astype(np.int16) - b.rgb[cam][:f].astype(np.int16))
                e.rgb_mean_abs[cam] = float(diff.mean())
                mm = 1.0 if a.depth[cam].dtype == np.uint16 else 1000.0
                dd = mm * np.abs(
                    a.depth[cam][:f].astype(np.float64) - b.depth[cam][:f].astype(np.float64)
                )
                e.depth_median_abs_mm[cam] = float(np.median(dd))
        out.append(e)
    return Agreement(out)


def compare_executors(
    setup: SceneSetup,
    plans: list[EpisodePlan],
    cfg: RecordConfig,
    device: str | None = None,
    nthread: int = 0,
) -> tuple[Agreement, list[Recording], list[Recording]]:
    """Executes ``plans`` on the CPU executor and on the GPU executor and compares them.

    Returns:
        the agreement and both executors' recordings (CPU, GPU).
    """
    from factory.demos.execute.warp import WarpExecutor

    cpu = execute(setup, plans, cfg, nthread)
    gpu = WarpExecutor(setup, cfg, device=device).execute(plans)
    return compare_recordings(setup, cpu, gpu), cpu, gpu
