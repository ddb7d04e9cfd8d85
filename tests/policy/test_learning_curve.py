"""The learning curve's GPU (``eval.device=cuda:<i>``, :func:`curve_gpu`)."""

from __future__ import annotations

import pytest

from factory.errors import PolicyError
from factory.policy.learning_curve import curve_gpu


@pytest.mark.parametrize(
    ("device", "visible", "want"),
    [
        ("auto", None, (None, "auto")),
        ("cuda", "0,1", (None, "cuda")),
        ("cpu", None, (None, "cpu")),
        ("cuda:1", None, ("1", "cuda")),
        ("cuda:1", "2,3", ("3", "cuda")),
        ("cuda:0", "GPU-abc, GPU-def", ("GPU-abc", "cuda")),
    ],
)
def test_curve_gpu(device: str, visible: str | None, want: tuple[str | None, str]) -> None:
    assert curve_gpu(device, visible) == want


@pytest.mark.parametrize(
    ("device", "visible"), [("cuda:2", "0,1"), ("cuda:0", ""), ("cuda:x", None)]
)
def test_curve_gpu_refuses(device: str, visible: str | None) -> None:
    with pytest.raises(PolicyError, match=r"eval\.device=cuda"):
        curve_gpu(device, visible)
