"""Renders: five readable views of a compiled scene, offscreen on the CPU."""

from __future__ import annotations

import numpy as np
import pytest

from factory.errors import RenderError
from factory.scenes.render import VIEWS, render_views, view_cameras
from factory.schema import load_scene
from factory.sim.compile import compile_scene


def test_views_render_readable_images(example_scene_path) -> None:
    scene = load_scene(example_scene_path)
    model = compile_scene(scene).model
    images = render_views(model, scene, VIEWS, width=160, height=120)
    assert list(images) == list(VIEWS)
    for view, im in images.items():
        assert im.shape == (120, 160, 3) and im.dtype == np.uint8
        assert im.std() > 10, f"{view} is flat"  # not a blank frame
    # the views differ from each other
    assert not np.array_equal(images["corner_0"], images["corner_2"])


def test_top_camera_sees_the_whole_plan(example_scene_path) -> None:
    scene = load_scene(example_scene_path)
    cams = view_cameras(scene)
    top = cams["top"]
    assert top.elevation < -89 and top.lookat[:2] == pytest.approx((2.0, 2.5))
    for k in range(4):
        assert cams[f"corner_{k}"].elevation < 0  # looking down into the room


def test_unknown_view(example_scene_path) -> None:
    scene = load_scene(example_scene_path)
    with pytest.raises(RenderError, match="unknown view"):
        render_views(compile_scene(scene).model, scene, ["side"], 64, 48)
