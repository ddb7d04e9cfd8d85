"""A copy of a model for OpenGL rendering, with infinite planes drawn as a few large quads.

MuJoCo draws an infinite plane (``size`` 0 0 ...) as a grid of 200 x 200 quads reaching past
the far clipping distance (``mjr_makeContext``: ``mjMAXPLANEGRID``), whatever its grid spacing:
80,000 triangles through the vertex stage in every view. A generated scene's ground plane was
thus the costliest geom of a mobile-task frame on a CPU renderer (Mesa llvmpipe: about 2 ms
of each of the 13 draws of a frame, more than the whole robot). :func:`render_model` returns a
copy of the model in which each infinite plane is a finite plane of the same extent (half
size ``1.05 * zfar``) drawn as 4 x 4 quads; the physics model is left alone (a plane's size
limits ``mj_ray``, so it is not changed there). The picture is the same geometry and texture
(texture coordinates of planes are generated from positions, not from the grid); only
per-vertex lighting is interpolated over larger quads, which changes the ground's shading by
a few levels at most (directional lights light a plane uniformly; specular highlights differ).

``mjv_updateScene`` with the copy and the physics model's ``MjData`` works as with the model
itself: the copy has the same structure.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import mujoco


def infinite_planes(model: mujoco.MjModel) -> list[int]:
    """Ids of the model's plane geoms with an infinite extent in x or y (size 0)."""
    import mujoco

    plane = int(mujoco.mjtGeom.mjGEOM_PLANE)
    return [
        g
        for g in range(model.ngeom)
        if model.geom_type[g] == plane
        and (model.geom_size[g, 0] <= 0 or model.geom_size[g, 1] <= 0)
    ]


def render_model(model: mujoco.MjModel) -> mujoco.MjModel:
    """The model itself if it has no infinite plane, else a copy for rendering whose infinite
    planes are finite planes of the same extent, drawn as 4 x 4 quads (see the module
    docstring)."""
    import copy

    planes = infinite_planes(model)
    if not planes:
        return model
    out = copy.copy(model)
    half = 1.05 * float(model.vis.map.zfar * model.stat.extent)
    for g in planes:
        # spacing = half: MuJoCo lays 2 cells of 2 x spacing (plus empty padding) per side
        out.geom_size[g] = [half, half, half / 2.0]
    return out
