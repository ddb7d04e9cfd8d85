"""``import factory`` stays cheap: none of the heavy stacks is imported."""

from __future__ import annotations

import subprocess
import sys

HEAVY = ["jax", "torch", "warp", "ompl", "lerobot", "mujoco_warp", "mujoco", "zarr"]


def test_import_factory_imports_no_heavy_stack() -> None:
    code = (
        "import sys, factory, factory.schema, factory.store, factory.config, factory.stages, "
        "factory.errors, factory.scenes, factory.sim\n"
        f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"imported: {out.stdout.strip()}"
