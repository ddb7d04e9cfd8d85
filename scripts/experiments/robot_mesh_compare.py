"""Side-by-side renders of the mobile Panda with robosuite's visual meshes and simplified ones.

    python scripts/experiments/robot_mesh_compare.py [--faces 1000 2500] [--size 256]
        [--out docs/images/robot_meshes.png] [--cache-root /tmp/robot-mesh-compare]

Each row is one version of the robot's visual meshes: robosuite's originals first, then the
robot cache's simplification (:func:`factory.robots.visual_mesh.simplify_visual_mesh`) at each
``--faces`` budget (a cache per budget is exported under ``--cache-root``). Columns: the whole
robot from the front left, the base from behind, and the hand close up. Each row is labelled
with the robot's visual triangles. Renders use MuJoCo's default lighting with shadows on (the
demos' cameras draw without), so that shading differences show.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from factory.robots.visual_mesh import VISUAL_FACES

log = logging.getLogger("robot_mesh_compare")

VIEWS: tuple[tuple[str, tuple[float, float, float], float, float, float], ...] = (
    ("robot, front left", (0.2, 0.0, 0.75), 2.6, 35.0, -20.0),
    ("base, from behind", (0.0, 0.0, 0.25), 1.4, 200.0, -25.0),
    ("hand", (0.0, 0.0, 0.0), 0.45, 60.0, -15.0),
)
"""Name, look-at point (world; the hand's view is relative to the hand), distance (m),
azimuth and elevation (deg) of each column."""


def _model(xml: str) -> object:
    """The mobile robot (arm in a reaching pose) on a floor, from an MJCF string."""
    import mujoco

    from factory.robots import mobile_panda as mr

    mr._mobile_xml.cache_clear()
    original = mr._mobile_xml
    mr._mobile_xml = lambda: xml  # type: ignore[assignment]
    try:
        spec = mujoco.MjSpec()
        spec.compiler.degree = False
        spec.worldbody.add_geom(
            type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1], rgba=[0.55, 0.5, 0.45, 1]
        )
        spec.worldbody.add_light(pos=[1.5, 1.5, 3.0], dir=[-0.4, -0.4, -1.0], castshadow=True)
        mr.add_mobile_robot(spec, (0.0, 0.0, 0.0))
        return spec.compile()
    finally:
        mr._mobile_xml = original  # type: ignore[assignment]


def _faces(model: object) -> int:
    import mujoco

    m = model
    return sum(
        int(m.mesh_facenum[m.geom_dataid[g]])  # type: ignore[attr-defined]
        for g in range(m.ngeom)  # type: ignore[attr-defined]
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH and m.geom_group[g] <= 2  # type: ignore[attr-defined]
    )


def _row(model: object, size: int) -> np.ndarray:
    import mujoco

    from factory.robots.mobile_panda import MobileRobotIndex

    m = model
    data = mujoco.MjData(m)
    robot = MobileRobotIndex.of(m)
    data.qpos[robot.qpos] = [0.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.785]
    data.qpos[robot.finger_qpos] = robot.finger_pos(0.06)
    mujoco.mj_forward(m, data)
    m.vis.global_.offwidth = max(m.vis.global_.offwidth, size)  # type: ignore[attr-defined]
    m.vis.global_.offheight = max(m.vis.global_.offheight, size)  # type: ignore[attr-defined]
    option = mujoco.MjvOption()
    option.geomgroup[:] = [1, 1, 1, 0, 0, 0]
    option.sitegroup[:] = 0
    images = []
    with mujoco.Renderer(m, size, size) as r:
        for _, at, dist, az, el in VIEWS:
            cam = mujoco.MjvCamera()
            look = np.asarray(at, float)
            if dist < 0.5:  # the hand
                look = look + data.xpos[robot.hand]
            cam.lookat[:] = look
            cam.distance, cam.azimuth, cam.elevation = dist, az, el
            r.update_scene(data, camera=cam, scene_option=option)
            images.append(r.render().copy())
    return np.concatenate(images, axis=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--faces", type=int, nargs="+", default=[VISUAL_FACES], help="budgets (VISUAL_FACES)"
    )
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--out", type=Path, default=Path("docs/images/robot_meshes.png"))
    ap.add_argument("--cache-root", type=Path, default=Path("/tmp/robot-mesh-compare"))
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from factory.sim.gl import configure_gl

    configure_gl("auto")
    from PIL import Image, ImageDraw

    from factory.robots.mobile_panda import _robosuite_xml
    from factory.robots.panda import cached_mjcf, export_mjcf

    source = _robosuite_xml()
    versions: list[tuple[str, str]] = [("robosuite's meshes", source)]
    for budget in args.faces:
        cache = args.cache_root / f"faces-{budget}"
        if not (cache / "robot.xml").is_file():
            export_mjcf(source, cache, max_faces=budget)
        label = f"simplified, {budget} faces per mesh up to 0.4 m across"
        versions.append((label, cached_mjcf(cache, lambda: source)))
    rows = []
    for label, xml in versions:
        model = _model(xml)
        im = Image.fromarray(_row(model, args.size))
        text = f"{label}: {_faces(model):,} visual faces"
        draw = ImageDraw.Draw(im)
        draw.rectangle((0, 0, 8 + 6 * len(text), 14), fill=(0, 0, 0))
        draw.text((4, 2), text, fill=(255, 255, 255))
        rows.append(np.asarray(im))
        log.info("%s", text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.concatenate(rows, axis=0)).save(args.out, optimize=True)
    log.info("wrote %s", args.out)


if __name__ == "__main__":
    main()
