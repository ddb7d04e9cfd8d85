"""A task's recording cameras as a renderer of recorded states needs them: which camera of the
compiled model each recorded image comes from, its size, and its lens.

A :class:`~factory.demos.record.scene.SimulatingScene` simulates its episodes itself and, in
the GPU pipeline, records them without images; the main process then draws the recorded states
on MuJoCo Warp (:class:`~factory.demos.execute.recording_render_warp.WarpRecordingRenderer`).
Which cameras it draws is the task's to say, not the renderer's: the scene's
:meth:`~factory.demos.record.scene.SimulatingScene.camera_rig` returns a :class:`CameraRig`
(the fixed-base Panda's ``left``, ``right`` and ``wrist``; the mobile robot's three pinhole
cameras and two fisheyes), the same cameras, sizes and depth format its CPU renderer draws.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from factory.errors import ConfigError

if TYPE_CHECKING:
    from factory.sim.fisheye import FisheyeSpec

__all__ = ["DEPTH_FORMATS", "CameraRig", "RigCamera"]

DEPTH_FORMATS = ("uint16_mm", "float32")
"""Recorded depth formats: millimetres as uint16, or metres as float32."""


@dataclass(frozen=True)
class RigCamera:
    """One recording camera.

    Attributes:
        key: the recording's name of the camera (``rgb/<key>``, ``depth/<key>``; ``left``,
            ``wrist``, ``fisheye_front``, ...).
        camera: the camera's name in the scene's compiled model.
        width, height: image size (px; columns, rows).
        fisheye: the lens of a fisheye camera (its image ``fisheye.resolution`` px square,
            depth the ray length; the model camera gives only the pose), None for a pinhole
            camera (the model camera's field of view; depth along the optical axis).
    """

    key: str
    camera: str
    width: int
    height: int
    fisheye: FisheyeSpec | None = None

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ConfigError(
                f"camera {self.key!r}: image size {self.width} x {self.height} px; give a "
                "width and height of at least 1 px (demos.width, demos.height)"
            )
        if self.fisheye is not None and not (self.width == self.height == self.fisheye.resolution):
            raise ConfigError(
                f"fisheye camera {self.key!r}: a fisheye image is square, its lens's "
                f"resolution ({self.fisheye.resolution} px) on a side; got {self.width} x "
                f"{self.height} px"
            )


@dataclass(frozen=True)
class CameraRig:
    """The cameras a scene's recordings hold, in their recorded order, and their depth format.

    Attributes:
        cameras: the cameras (keys unique).
        depth: ``uint16_mm`` (millimetres) or ``float32`` (metres), :data:`DEPTH_FORMATS`.
    """

    cameras: tuple[RigCamera, ...]
    depth: str = "uint16_mm"

    def __post_init__(self) -> None:
        if self.depth not in DEPTH_FORMATS:
            raise ConfigError(
                f"depth format {self.depth!r} is unknown: choose one of {', '.join(DEPTH_FORMATS)}"
            )
        keys = [c.key for c in self.cameras]
        if len(set(keys)) != len(keys):
            raise ConfigError(f"camera rig names a camera twice: {keys}; give each camera once")

    @property
    def keys(self) -> tuple[str, ...]:
        """The cameras' recording names, in order."""
        return tuple(c.key for c in self.cameras)
