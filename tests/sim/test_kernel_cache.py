"""``sim.kernel_cache``: where Warp keeps the kernels it compiles (``factory.sim.kernel_cache``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from factory.errors import ConfigError
from factory.sim.kernel_cache import cached_modules, configure_kernel_cache

# one worker compiles Warp's CPU kernels for every Warp module (tests/conftest.py)
pytestmark = pytest.mark.xdist_group("warp")

REPO = Path(__file__).resolve().parents[2]


def test_kernel_cache_folder_receives_the_compiled_kernels(tmp_path: Path) -> None:
    """A process that sets ``sim.kernel_cache`` before Warp starts compiles its kernels into
    that folder (and the environment it hands its children names it); empty leaves Warp's
    choice; a folder that cannot be made is a one-line error naming the setting."""
    pytest.importorskip("warp")
    cache = tmp_path / "kernels"
    code = f"""
import os
from factory.sim.kernel_cache import configure_kernel_cache, kernel_cache_dir
configure_kernel_cache({str(cache)!r})
from factory.sim.backend import init_warp
wp = init_warp()

@wp.kernel
def twice(a: wp.array(dtype=float)):
    i = wp.tid()
    a[i] = 2.0 * a[i]

a = wp.ones(4, dtype=float, device="cpu")
wp.launch(twice, dim=4, inputs=[a], device="cpu")
assert a.numpy().tolist() == [2.0] * 4
print(os.environ["WARP_CACHE_PATH"], kernel_cache_dir(wp))
"""
    script = tmp_path / "compile_one.py"  # Warp reads a kernel's source from its file
    script.write_text(code)
    env = {k: v for k, v in os.environ.items() if k != "WARP_CACHE_PATH"}
    env["PYTHONPATH"] = str(REPO)
    out = subprocess.run(
        [sys.executable, str(script)],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert cached_modules(str(cache)) >= 1
    assert str(cache.resolve()) in out.stdout
    assert configure_kernel_cache("") is None
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(ConfigError, match=r"sim\.kernel_cache") as e:
        configure_kernel_cache(str(blocker / "sub"))
    assert "\n" not in str(e.value)
