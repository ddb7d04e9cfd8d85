"""Benchmark of policy learning: training steps per second and closed-loop rollouts per minute,
with the memory they use.

* training: :class:`factory.policy.train.Trainer` on a merged dataset (``--inputs`` state, rgb
  or rgbd; ``--device`` cpu or cuda), the cold part (dataset, statistics, model; the first
  step) and ``--steps`` warm steps timed apart; peak resident memory of the process and, on
  CUDA, peak allocated GPU memory;
* rollouts: the policy so trained, saved as a lerobot checkpoint, acting in ``stage=eval``
  (a subprocess of the real command line) for ``--episodes`` episodes per scene of fixed length
  ``--max-steps`` frames in the dataset's scenes (``eval.scenes=train``) with ``--nthread``
  simulation threads: episodes per minute, frames per second, the subprocess's peak memory.

    python scripts/bench_policy.py --run-dir runs/small --inputs state --device cpu --threads 2

On CUDA, ``nvidia-smi`` is sampled every 0.2 s during the warm steps (``gpu_busy_mean``: the
mean utilisation, ``gpu_busy_samples``: how many samples).

``--variants rgbd-recipe`` (or ``rgbd-speed``, ``rgbd-baseline``, or a JSON file: a list of
``{"name": ..., <setting>: ...}``) trains each variant of :data:`VARIANTS` in its own process
on the same data, one after the other, and saves them side by side
(``policy-variants-<tag>.json``): how the image recipe of ``factory/policy/recipe.py`` was
chosen (``rgbd-recipe``) and the speed target measured (``rgbd-baseline``, then
``rgbd-speed``, on a machine doing nothing else). A variant's settings are those of the
command line (``inputs``, ``batch_size``, ``loader``, ``workers``, ``options``,
``precision``, ``aux_state``, ``ema``, ``n_obs_steps``, ``compile``).

Prints and saves JSON to ``benchmarks/results/policy-<inputs>-<device>-<tag>.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
LEROBOT_PRESET = {
    "diffusion": {
        "resize_shape": None,
        "down_dims": [512, 1024, 2048],
        "prediction_type": "epsilon",
        "noise_scheduler_type": "DDPM",
        "num_inference_steps": None,
    }
}
"""lerobot's own diffusion preset (282 M parameters with RGB-D of 3 cameras; a random 90 % crop
of the 128 px images): the image recipe before ``factory/policy/recipe.py``."""
OLD = {
    "options": LEROBOT_PRESET,
    "precision": "fp32",
    "aux_state": 0.0,
    "ema": 0.0,
    "compile": False,
}
BASELINE = {
    "name": "before: lerobot preset, DataLoader 8 workers, fp32, batch 64",
    **OLD,
    "loader": "dataloader",
    "workers": 8,
    "batch_size": 64,
}
VARIANTS: dict[str, list[dict[str, Any]]] = {
    "rgbd-baseline": [BASELINE],
    "rgbd-recipe": [
        {
            "name": "recipe, bf16, batch 256",
            "loader": "device",
            "compile": False,
            "batch_size": 256,
        },
        {
            "name": "lerobot preset, device batches, fp32, batch 64",
            **OLD,
            "loader": "device",
            "compile": False,
            "batch_size": 64,
        },
        {
            "name": "recipe, fp32, batch 256",
            "precision": "fp32",
            "loader": "device",
            "compile": False,
            "batch_size": 256,
        },
        {
            "name": "recipe, bf16, batch 512",
            "loader": "device",
            "compile": False,
            "batch_size": 512,
        },
        {
            "name": "recipe at 96 px, bf16, batch 256",
            "loader": "device",
            "compile": False,
            "batch_size": 256,
            "options": {"diffusion": {"resize_shape": [96, 96]}},
        },
        {
            "name": "recipe, 2 observation steps, bf16, batch 256",
            "loader": "device",
            "compile": False,
            "batch_size": 256,
            "n_obs_steps": 2,
        },
        {
            "name": "recipe, U-Net 256-512-1024, bf16, batch 256",
            "loader": "device",
            "compile": False,
            "batch_size": 256,
            "options": {"diffusion": {"down_dims": [256, 512, 1024]}},
        },
        {
            "name": "recipe without the auxiliary loss and EMA, bf16, batch 256",
            "loader": "device",
            "compile": False,
            "batch_size": 256,
            "aux_state": 0.0,
            "ema": 0.0,
        },
        {
            "name": "recipe, rgb only, bf16, batch 256",
            "inputs": "rgb",
            "loader": "device",
            "compile": False,
            "batch_size": 256,
        },
    ],
    "rgbd-speed": [
        {
            "name": "recipe, bf16, batch 256",
            "loader": "device",
            "batch_size": 256,
            "compile": False,
        },
        {
            "name": "recipe, bf16, batch 512",
            "loader": "device",
            "batch_size": 512,
            "compile": False,
        },
        {
            "name": "recipe, compiled, bf16, batch 256",
            "loader": "device",
            "batch_size": 256,
            "compile": True,
        },
        {
            "name": "recipe, compiled, bf16, batch 512",
            "loader": "device",
            "batch_size": 512,
            "compile": True,
        },
        {
            "name": "recipe at 72 px, compiled, bf16, batch 512",
            "loader": "device",
            "batch_size": 512,
            "compile": True,
            "options": {"diffusion": {"resize_shape": [72, 72]}},
        },
    ],
}
"""Named lists of variants for ``--variants``: ``rgbd-speed`` is the short list for the
throughput target (run after ``rgbd-baseline`` on a machine doing nothing else)."""
SETTINGS = (
    "inputs",
    "batch_size",
    "loader",
    "workers",
    "options",
    "precision",
    "aux_state",
    "ema",
    "n_obs_steps",
    "compile",
)


class GpuSampler:
    """``nvidia-smi`` utilisation samples every 0.2 s while running (no-op without it)."""

    def __init__(self) -> None:
        self.proc: Any = None
        self.samples: list[float] = []

    def __enter__(self) -> GpuSampler:
        exe = shutil.which("nvidia-smi")
        if exe:
            self.proc = subprocess.Popen(
                [
                    exe,
                    "--query-gpu=utilization.gpu",
                    "--format=csv,noheader,nounits",
                    "-lms",
                    "200",
                ],
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                text=True,
            )
        return self

    def __exit__(self, *exc: Any) -> None:
        if self.proc is None:
            return
        self.proc.terminate()
        out, _ = self.proc.communicate(timeout=10)
        for line in out.splitlines():
            try:
                self.samples.append(float(line.split(",")[0]))
            except ValueError:
                continue

    def summary(self) -> dict[str, Any]:
        if not self.samples:
            return {}
        busy = self.samples
        return {
            "gpu_busy_mean": round(sum(busy) / len(busy), 1),
            "gpu_busy_min": min(busy),
            "gpu_busy_samples": len(busy),
        }


def _gpu_name() -> str:
    try:
        import torch

        return torch.cuda.get_device_name(0) if torch.cuda.is_available() else ""
    except Exception:
        return ""


def bench_train(a: argparse.Namespace, root: Path, tmp: Path) -> tuple[dict[str, Any], Path]:
    import torch

    from factory.config import TrainConfig
    from factory.policy.checkpoint import PRETRAINED
    from factory.policy.inputs import input_spec
    from factory.policy.train import Trainer
    from factory.policy.train_stage import train_info

    options = json.loads(a.options) if a.options else {}
    tc = TrainConfig(
        name="bench",
        inputs=a.inputs,
        dataset=str(root),
        steps=a.steps + 1,
        batch_size=a.batch_size,
        device=a.device,
        threads=a.threads,
        num_workers=a.workers,
        loader=a.loader,
        options=options,
        precision=a.precision,
        aux_state=a.aux_state,
        ema=a.ema,
        n_obs_steps=a.n_obs_steps,
        compile={"true": True, "false": False}.get(a.compile),
    )
    features = json.loads((root / "meta" / "info.json").read_text())["features"]
    spec = input_spec(a.inputs, features, tc.action)
    t0 = time.perf_counter()
    trainer = Trainer(tc, spec, root, tmp / "bench")
    batches = trainer.loader()
    trainer.optimize(next(batches))
    if trainer.device.startswith("cuda"):
        torch.cuda.synchronize()
    cold = time.perf_counter() - t0
    for _ in range(min(5, a.steps)):  # allocator and autotuning settle
        trainer.optimize(next(batches))
    if trainer.device.startswith("cuda"):
        torch.cuda.synchronize()
    with GpuSampler() as gpu:
        t1 = time.perf_counter()
        for _ in range(a.steps):
            trainer.optimize(next(batches))
        if trainer.device.startswith("cuda"):
            torch.cuda.synchronize()
        warm = time.perf_counter() - t1
    t2 = time.perf_counter()  # the data pipeline alone: batches made, no model
    for _ in range(a.steps):
        batch = next(batches)
    if trainer.device.startswith("cuda"):
        torch.cuda.synchronize()
    data = time.perf_counter() - t2
    del batch
    info = train_info(tc, spec, root)
    ckpt = trainer.save(tmp / "bench" / "checkpoints", info)
    out = {
        "inputs": a.inputs,
        "policy": trainer.cfg.type,
        "device": trainer.device,
        "threads": torch.get_num_threads(),
        "num_workers": a.workers,
        "loader": "device" if type(batches).__name__ == "DeviceBatches" else "dataloader",
        "batch_size": a.batch_size,
        "precision": trainer.precision,
        "aux_state": trainer.aux_weight,
        "ema": trainer.ema_decay,
        "n_obs_steps": trainer.cfg.n_obs_steps,
        "compile": trainer.compiled,
        "image_size": list(getattr(trainer.cfg, "resize_shape", None) or spec.image_size)
        if spec.cameras
        else None,
        "crop_shape": list(getattr(trainer.cfg, "crop_shape", None) or []) or None,
        "down_dims": list(getattr(trainer.cfg, "down_dims", []) or []),
        "parameters": trainer.parameters(),
        "cold_seconds": round(cold, 2),
        "warm_steps": a.steps,
        "warm_seconds": round(warm, 2),
        "steps_per_s": round(a.steps / warm, 2),
        "samples_per_s": round(a.steps * a.batch_size / warm, 1),
        "data_only_samples_per_s": round(a.steps * a.batch_size / data, 1),
        **gpu.summary(),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "peak_gpu_mb": round(torch.cuda.max_memory_allocated() / 2**20, 1)
        if trainer.device.startswith("cuda")
        else 0.0,
    }
    return out, ckpt / PRETRAINED


def bench_rollouts(a: argparse.Namespace, model: Path) -> dict[str, Any]:
    env = {**os.environ, "OMP_NUM_THREADS": str(max(1, a.threads))}
    args = [
        sys.executable,
        "-m",
        "factory",
        "stage=eval",
        f"run_dir={a.run_dir}",
        f"eval.policy={model}",
        "eval.scenes=train",
        f"eval.episodes_per_scene={a.episodes}",
        f"eval.max_steps={a.max_steps}",
        f"eval.nthread={a.nthread}",
        f"eval.device={a.device}",
        "eval.videos=0",
        "force=true",
    ]
    t0 = time.perf_counter()
    done = subprocess.run(args, capture_output=True, text=True, env=env, cwd=REPO)
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        sys.exit(f"stage=eval failed:\n{done.stderr[-3000:]}")
    newest = max(Path(a.run_dir, "eval").glob("*/results.json"), key=lambda p: p.stat().st_mtime)
    res = json.loads(newest.read_text())
    frames = sum(int(r.get("steps", 0)) for r in _records(newest.parent))
    return {
        "episodes": res["episodes"],
        "max_steps": a.max_steps,
        "nthread": a.nthread,
        "eval_seconds": res["seconds"],
        "wall_seconds_with_start": round(seconds, 2),
        "episodes_per_min": round(60 * res["episodes"] / res["seconds"], 2),
        "frames_per_s": round(frames / res["seconds"], 1),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, 1),
    }


def _records(folder: Path) -> list[dict[str, Any]]:
    path = folder / "episodes.jsonl"
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip()]


def _machine() -> dict[str, Any]:
    return {
        "host": platform.node(),
        "python": platform.python_version(),
        "cpus": os.cpu_count(),
        "gpu": _gpu_name(),
    }


def _save(result: dict[str, Any], out: Path) -> None:
    """Writes a benchmark's JSON and says where."""
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {out}")


def bench_variants(a: argparse.Namespace) -> None:
    """Each variant in its own process of this script (``--no-rollouts``), side by side."""
    path = Path(a.variants)
    variants = json.loads(path.read_text()) if path.is_file() else VARIANTS.get(a.variants)
    if variants is None:
        sys.exit(f"--variants: no file or preset {a.variants!r} (presets: {', '.join(VARIANTS)})")
    flags = {
        "inputs": "--inputs",
        "batch_size": "--batch-size",
        "loader": "--loader",
        "workers": "--workers",
        "options": "--options",
        "precision": "--precision",
        "aux_state": "--aux-state",
        "ema": "--ema",
        "n_obs_steps": "--n-obs-steps",
        "compile": "--compile",
    }
    rows = []
    tmp = Path(tempfile.mkdtemp(prefix="bench_variants_"))
    for i, v in enumerate(variants):
        unknown = sorted(set(v) - set(SETTINGS) - {"name"})
        if unknown:
            sys.exit(
                f"variant {v.get('name', i)!r}: unknown settings {unknown} (known: {SETTINGS})"
            )
        setting = {
            "inputs": a.inputs,
            "batch_size": a.batch_size,
            "loader": a.loader,
            "workers": a.workers,
            "precision": a.precision,
            **v,
        }
        cmd = [
            sys.executable,
            __file__,
            "--run-dir",
            str(a.run_dir),
            "--device",
            a.device,
            "--steps",
            str(a.steps),
            "--threads",
            str(a.threads),
            "--no-rollouts",
            "--out",
            str(tmp / f"{i}.json"),
        ]
        if a.dataset:
            cmd += ["--dataset", str(a.dataset)]
        for key, flag in flags.items():
            if key in setting and setting[key] is not None:
                val = setting[key]
                text = json.dumps(val) if isinstance(val, dict | bool) else str(val)
                cmd += [flag, text]
        print(f"variant {i + 1}/{len(variants)}: {v.get('name', '')}", flush=True)
        t0 = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)
        row: dict[str, Any] = {
            "name": v.get("name", str(i)),
            "setting": setting,
            "wall_seconds": round(time.perf_counter() - t0, 1),
        }
        if done.returncode == 0:
            row["train"] = json.loads((tmp / f"{i}.json").read_text())["train"]
            t = row["train"]
            print(
                f"  {t['samples_per_s']} samples/s, GPU busy {t.get('gpu_busy_mean', '-')} %, "
                f"{t['parameters'] / 1e6:.1f} M parameters",
                flush=True,
            )
        else:
            row["error"] = done.stderr[-2000:]
            print(f"  failed: {done.stderr[-500:]}", flush=True)
        rows.append(row)
    shutil.rmtree(tmp, ignore_errors=True)
    result = {
        "schema_version": 1,
        "benchmark": "policy-variants",
        "tag": a.tag,
        "machine": _machine(),
        "dataset": str(a.dataset or a.run_dir / "dataset" / "merged"),
        "warm_steps": a.steps,
        "variants": rows,
    }
    _save(result, a.out or REPO / "benchmarks" / "results" / f"policy-variants-{a.tag}.json")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run-dir", required=True, type=Path)
    p.add_argument("--dataset", type=Path, default=None, help="default <run>/dataset/merged")
    p.add_argument("--inputs", default="state", choices=["state", "rgb", "rgbd"])
    p.add_argument("--device", default="cpu")
    p.add_argument("--steps", type=int, default=50, help="warm training steps timed")
    p.add_argument("--batch-size", type=int, default=64)
    p.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    p.add_argument("--workers", type=int, default=0, help="DataLoader processes")
    p.add_argument("--loader", default="auto", choices=["auto", "device", "dataloader"])
    p.add_argument("--options", default="", help='policy options JSON, {"diffusion": {...}}')
    p.add_argument("--precision", default="auto", choices=["auto", "bf16", "fp32"])
    p.add_argument("--aux-state", type=float, default=None, help="train.aux_state (default: auto)")
    p.add_argument("--ema", type=float, default=None, help="train.ema (default: auto)")
    p.add_argument("--n-obs-steps", type=int, default=0)
    p.add_argument(
        "--compile", default="auto", choices=["auto", "true", "false"], help="train.compile"
    )
    p.add_argument("--variants", default="", help="a name in VARIANTS or a JSON file")
    p.add_argument("--episodes", type=int, default=4, help="rollouts per scene")
    p.add_argument("--max-steps", type=int, default=200, help="frames per rollout")
    p.add_argument("--nthread", type=int, default=0, help="simulation threads of the rollouts")
    p.add_argument("--no-rollouts", action="store_true")
    p.add_argument("--tag", default="run")
    p.add_argument("--out", type=Path, default=None)
    a = p.parse_args()
    a.run_dir = a.run_dir.resolve()
    if a.variants:
        return bench_variants(a)
    root = (a.dataset or a.run_dir / "dataset" / "merged").resolve()
    tmp = Path(tempfile.mkdtemp(prefix="bench_policy_"))
    try:
        train, model = bench_train(a, root, tmp)
        print(json.dumps(train, indent=1))
        rollouts = None if a.no_rollouts else bench_rollouts(a, model)
        if rollouts:
            print(json.dumps(rollouts, indent=1))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    result = {
        "schema_version": 1,
        "benchmark": "policy",
        "tag": a.tag,
        "machine": _machine(),
        "dataset": str(root),
        "train": train,
        "rollouts": rollouts,
    }
    device = "cuda" if train["device"].startswith("cuda") else "cpu"
    _save(
        result,
        a.out or REPO / "benchmarks" / "results" / f"policy-{a.inputs}-{device}-{a.tag}.json",
    )


if __name__ == "__main__":
    main()
