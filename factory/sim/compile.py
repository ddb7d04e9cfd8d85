"""Scene -> ``mujoco.MjSpec`` -> ``MjModel`` and a standalone ``model.xml``.

What a compiled scene holds:

* a ground plane (collision) and one visual floor slab per room, with its floor material;
* walls as boxes around their door and window openings (:mod:`factory.sim.walls`), glass panes
  in windows, and optionally a ceiling; floors, walls and ceilings are textured by their
  material text (:mod:`factory.textures`: "oak" is a plank floor, "dusty oak" a dusty one),
  the images cached in ``<assets>/textures/``;
* lights (:mod:`factory.sim.lights`): spot lights under the ceiling of every room (one or
  more by its size, with shadows), a warm light in every lamp, a weak directional fill and a
  soft headlight;
* one body per object, named by the object's id, at its bottom centre
  (``pos_obj_in_world``) with its rotation: a free joint unless the object is static
  (wall-mounted or ``physics.static``); geoms from the asset's convex collision parts (or, with
  none listed, the hull of its visual mesh); an object without an asset is a box of its
  dimensions (logged). Visual parts with a texture get a textured material (the part's colour
  times the texture's gain, the part's finish). Mass is the scene's (uniform density over the
  collision geometry), sliding friction the scene's.

Mesh and texture files stay in ``<run_dir>/assets/`` and ``model.xml`` refers to them by
relative path, so plain ``mujoco.MjModel.from_xml_path(".../model.xml")`` loads it.
"""

from __future__ import annotations

import logging
import math
import os
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from factory.errors import CompileError
from factory.schema import (
    AssetMeta,
    Door,
    Room,
    Scene,
    SceneObject,
    SchemaError,
    Window,
    load_asset_meta,
)
from factory.schema.asset import ROOT_LINK, Articulation
from factory.schema.joint_pose import link_transform
from factory.sim.lights import LightSpec, ceiling_lights, lamp_light
from factory.sim.materials import (
    DEFAULT_FLOOR,
    DEFAULT_WALL,
    SURFACES,
    Surface,
    object_rgba,
    surface,
)
from factory.sim.walls import PlanRect, opening_rect, solid_rects, subtract, wall_keepout

log = logging.getLogger(__name__)

LINK_JOINT_GROUP = 3
"""MuJoCo joint group of articulated objects' link joints (the robot's are in group 0): the
stability check judges the joints of this group (``factory.sim.stability.LinkJoints``)."""

FLOOR_SLAB = 0.01
"""Thickness of the visual floor slab of a room (m); its top is at z = 0.0005."""

TORSIONAL_FRICTION = 0.005
ROLLING_FRICTION = 0.0001

GROUP_ARCH = 0
GROUP_VISUAL = 2
GROUP_COLLISION = 3


@dataclass
class CompileOptions:
    """Options of the compiler (mirrors :class:`factory.config.CompileConfig`).

    Attributes:
        ceiling: add a ceiling slab per room.
        timestep: simulation step (s).
        offscreen_size: offscreen framebuffer width and height (px).
        textures: procedural textures on floors, walls, ceilings and asset parts (off: flat
            colours, as before issue 17).
        texture_size: size (px) of the floor, wall and ceiling textures.
        lights: room lighting (:mod:`factory.sim.lights`: ceiling lights per room, a light
            in every lamp, a weak sun and a soft headlight); off: the lighting before issue
            17 (a brighter headlight and sun, no ceiling or lamp lights).
        light_mesh_edge: longest edge (m, at the object's scale) of the visual meshes the
            model draws: longer edges are split (:mod:`factory.assets.lighting_mesh`), so
            that OpenGL, which lights vertices, and MuJoCo Warp, which lights every hit,
            draw the same picture; the refined copies are kept beside the asset's files
            (``lit<mm>mm-<file>``). ``0`` (the default): the assets' meshes as built. Measured
            (docs/POLICY.md, 2026-11-30): 0.1 m halves the renderers' image difference at 8
            times the visual faces and 4 times the CPU (llvmpipe) drawing time, and did not
            bring a camera policy's verdicts on the two envs together.
    """

    ceiling: bool = False
    timestep: float = 0.002
    offscreen_size: int = 1280
    textures: bool = True
    texture_size: int = 256
    lights: bool = True
    light_mesh_edge: float = 0.0

    def __post_init__(self) -> None:
        if not self.light_mesh_edge >= 0:
            raise CompileError(
                f"compile.light_mesh_edge must be >= 0 (m; 0 turns the refinement off), "
                f"got {self.light_mesh_edge}"
            )


@dataclass
class CompiledScene:
    """A compiled scene.

    Attributes:
        spec: the MjSpec (meshes referenced by absolute path).
        model: the compiled model.
        boxed: ids of objects compiled as boxes because they have no asset.
        assets_root: where asset meshes were read (``None`` if none was used).
    """

    spec: mujoco.MjSpec
    model: mujoco.MjModel
    boxed: list[str] = field(default_factory=list)
    assets_root: Path | None = None


HEADLIGHT_AMBIENT = [0.2, 0.2, 0.2]
"""Ambient light of the viewer's headlight (per channel): the fill of shadowed sides."""

HEADLIGHT_DIFFUSE = [0.15, 0.15, 0.15]
"""Diffuse light of the viewer's headlight (per channel)."""

SUN_DIFFUSE = [0.2, 0.2, 0.19]
"""The directional "sun": a weak fill from above at a slant, without shadows."""

FLAT_HEADLIGHT_AMBIENT = [0.35, 0.35, 0.35]
"""Headlight ambient without room lights (``CompileOptions.lights=False``: before issue 17)."""

FLAT_HEADLIGHT_DIFFUSE = [0.45, 0.45, 0.45]
"""Headlight diffuse without room lights."""

FLAT_SUN_DIFFUSE = [0.55, 0.55, 0.52]
"""The sun without room lights: the main light, casting shadows."""


def _add_light(parent: mujoco.MjsBody, light: LightSpec) -> None:
    """Adds a spot light (:mod:`factory.sim.lights`) to a body of the spec."""
    parent.add_light(
        name=light.name,
        type=mujoco.mjtLightType.mjLIGHT_SPOT,
        pos=list(light.pos),
        dir=list(light.dir),
        diffuse=list(light.diffuse),
        specular=list(light.specular),
        cutoff=light.cutoff,
        exponent=light.exponent,
        attenuation=list(light.attenuation),
        castshadow=light.castshadow,
    )


def _yaw_quat(yaw: float) -> list[float]:
    return [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]


MIN_WALL_PIECE = 1e-6
"""Pieces of a wall thinner than this after the keep-out (m) are dropped (rounding slivers)."""


def _kept_pieces(
    cx: float,
    cy: float,
    half_u: float,
    half_t: float,
    along_x: bool,
    keepout: list[PlanRect],
) -> list[tuple[float, float, float, float]]:
    """A wall piece of a plan-aligned wall (centre ``cx, cy``, half sizes along the wall and
    across it, m) minus the room's keep-out rectangles: ``(centre x, centre y, half size along
    the wall, half size across)`` per remaining box (the piece itself if nothing is left out)."""
    hx, hy = (half_u, half_t) if along_x else (half_t, half_u)
    rect = PlanRect(cx - hx, cy - hy, cx + hx, cy + hy)
    parts = subtract(rect, keepout)
    if parts == [rect]:
        return [(cx, cy, half_u, half_t)]
    out = []
    for p in parts:
        sx, sy = (p.x1 - p.x0) / 2, (p.y1 - p.y0) / 2
        if min(sx, sy) < MIN_WALL_PIECE / 2:
            continue
        hu, ht = (sx, sy) if along_x else (sy, sx)
        out.append(((p.x0 + p.x1) / 2, (p.y0 + p.y1) / 2, hu, ht))
    return out


@dataclass(frozen=True)
class _Joint:
    """A joint's kind, anchor (m) and axis in the object frame, scaled (``link_transform``)."""

    kind: str
    anchor: list[float]
    axis: list[float]


class _Builder:
    def __init__(self, scene: Scene, assets_root: Path | None, options: CompileOptions):
        self.scene = scene
        self.assets_root = assets_root
        self.options = options
        self.spec = mujoco.MjSpec()
        self.spec.modelname = scene.id
        self.materials: set[str] = set()
        self.boxed: list[str] = []
        self.mesh_assets: dict[str, AssetMeta] = {}
        self.dynamic_geoms: dict[str, list[mujoco.MjsGeom]] = {}
        self.textures: set[str] = set()
        self.tiles: dict[str, float] = {}  # textured surface material -> its tile (m)

    def lit_mesh(self, aid: str, file: str, scale: list[float]) -> str:
        """The file (relative to the asset's folder) of visual mesh ``file`` refined for
        lighting at ``options.light_mesh_edge`` (see :class:`CompileOptions`), written on
        first use; ``file`` itself when the option is off or the mesh needs no split."""
        edge = self.options.light_mesh_edge
        if edge <= 0 or self.assets_root is None:
            return file
        from factory.sim.lit_mesh import lit_copy

        return lit_copy(self.assets_root / aid, file, edge, scale)

    # ---- global settings
    def setup(self) -> None:
        spec = self.spec
        spec.option.timestep = self.options.timestep
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        spec.compiler.degree = False
        if self.assets_root is not None:
            spec.meshdir = str(self.assets_root)
            spec.texturedir = str(self.assets_root)
        vis = spec.visual
        vis.global_.offwidth = self.options.offscreen_size
        vis.global_.offheight = self.options.offscreen_size
        vis.quality.shadowsize = 4096
        # The room's ceiling and lamp lights (factory.sim.lights) do most of the lighting; the
        # headlight is a soft fill from the viewer so that shadowed sides are not black.
        lit = self.options.lights
        vis.headlight.ambient = HEADLIGHT_AMBIENT if lit else FLAT_HEADLIGHT_AMBIENT
        vis.headlight.diffuse = HEADLIGHT_DIFFUSE if lit else FLAT_HEADLIGHT_DIFFUSE
        vis.headlight.specular = [0.05, 0.05, 0.05] if lit else [0.1, 0.1, 0.1]
        vis.map.znear = 0.01
        tex = spec.add_texture(
            name="ground_tex",
            type=mujoco.mjtTexture.mjTEXTURE_2D,
            builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
            rgb1=[0.42, 0.44, 0.46],
            rgb2=[0.36, 0.38, 0.40],
            width=256,
            height=256,
        )
        ground = spec.add_material(name="ground", texrepeat=[1, 1], texuniform=True)
        ground.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex.name
        spec.worldbody.add_geom(
            name="ground",
            type=mujoco.mjtGeom.mjGEOM_PLANE,
            size=[0, 0, 0.05],
            material="ground",
            group=GROUP_ARCH,
        )
        xmin, ymin, xmax, ymax = self.scene.bounds_xy()
        cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
        spec.worldbody.add_light(
            name="sun",
            type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
            pos=[cx, cy, 10.0],
            dir=[0.3, 0.2, -1.0],
            diffuse=SUN_DIFFUSE if lit else FLAT_SUN_DIFFUSE,
            specular=[0.05, 0.05, 0.05] if lit else [0.1, 0.1, 0.1],
            castshadow=not lit,
        )

    def material(self, key: str, name: str, default_rgba: tuple[float, ...] | None = None) -> str:
        """A material for a named surface (architecture) or an explicit colour (objects)."""
        mat_name = f"mat/{key}"
        if mat_name in self.materials:
            return mat_name
        self.materials.add(mat_name)
        if default_rgba is not None:
            self.spec.add_material(name=mat_name, rgba=list(default_rgba), roughness=0.6)
            return mat_name
        floor = key.startswith("floor")
        default = DEFAULT_FLOOR if floor else DEFAULT_WALL
        surf = surface(name, default)
        if self.options.textures:
            self._surface_material(mat_name, key, name, surf, floor)
            return mat_name
        mat = self.spec.add_material(
            name=mat_name, rgba=list(surf.rgba), roughness=surf.roughness, metallic=surf.metallic
        )
        if surf.checker:
            r, g, b, _ = surf.rgba
            tex = self.spec.add_texture(
                name=f"tex/{key}",
                type=mujoco.mjtTexture.mjTEXTURE_2D,
                builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                rgb1=[1.0, 1.0, 1.0],
                rgb2=[0.88, 0.88, 0.88],
                width=128,
                height=128,
            )
            mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex.name
            mat.texrepeat = [2.0, 2.0]
            mat.texuniform = True
            mat.rgba = [r, g, b, 1.0]
        return mat_name

    def _surface_material(
        self, mat_name: str, key: str, name: str, surf: Surface, floor: bool
    ) -> None:
        """A textured floor, wall or ceiling material (:func:`factory.textures.appearance`)."""
        from factory.textures.appearance import appearance
        from factory.textures.cache import default_folder

        folder = self.assets_root / "textures" if self.assets_root else default_folder()
        app = appearance(
            name,
            surf.rgba,
            folder,
            seed=(self.scene.seed or 0) + zlib.crc32(key.encode()),
            size=self.options.texture_size,
            default="hardwood" if floor else "drywall",
            floor=floor,
            metallic=surf.metallic,
            roughness=surf.roughness,
        )
        mat = self.spec.add_material(
            name=mat_name,
            rgba=list(app.rgba),
            roughness=app.roughness,
            metallic=app.metallic,
            specular=app.finish.specular,
            shininess=app.finish.shininess,
            reflectance=app.finish.reflectance,
            # MuJoCo repeats a texuniform texture once per 2 / texrepeat metres on a box face
            texrepeat=[2.0 / app.tile, 2.0 / app.tile],
            texuniform=True,
        )
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = self._texture(app.texture.path)
        self.tiles[mat_name] = app.tile

    def _upright(self, mat_name: str, half_y: float, half_z: float) -> str:
        """The textured material ``mat_name`` for the upright faces (local ±y) of a box of half
        sizes ``half_y`` and ``half_z`` (a wall piece).

        MuJoCo lays a ``texuniform`` texture on a box face with the repeats of the box's x and
        y sizes whatever the face, so on an upright face the vertical repeat follows the
        thickness, not the height (a plaster wall would be stretched 27-fold). The copy made
        here scales the vertical repeat by height over thickness, so the texel is square.
        """
        tile = self.tiles.get(mat_name)
        if tile is None or half_y <= 0:
            return mat_name
        ratio = round(half_z / half_y, 3)
        name = f"{mat_name}/upright_{ratio:g}"
        if name not in self.materials:
            self.materials.add(name)
            base = self.spec.material(mat_name)
            mat = self.spec.add_material(
                name=name,
                rgba=list(base.rgba),
                roughness=base.roughness,
                metallic=base.metallic,
                specular=base.specular,
                shininess=base.shininess,
                reflectance=base.reflectance,
                texrepeat=[2.0 / tile, 2.0 / tile * ratio],
                texuniform=True,
            )
            role = mujoco.mjtTextureRole.mjTEXROLE_RGB
            mat.textures[role] = base.textures[role]
        return name

    def _texture(self, path: Path) -> str:
        """The model's texture for an image file, added once (named by the file's content key;
        a path inside the assets folder is written relative to it)."""
        name = f"tex/{path.stem}"
        if name not in self.textures:
            self.textures.add(name)
            file = str(path)
            if self.assets_root is not None and path.is_relative_to(self.assets_root):
                file = str(path.relative_to(self.assets_root))
            self.spec.add_texture(name=name, type=mujoco.mjtTexture.mjTEXTURE_2D, file=file)
        return name

    def _part_material(
        self, key: str, folder: Path, vp: dict[str, Any], rgba: tuple[float, ...], obj: SceneObject
    ) -> str:
        """The textured material of an asset's visual part (its meta entry ``vp``)."""
        from factory.textures.appearance import material_rgb

        mat_name = f"mat/{key}"
        if mat_name in self.materials:
            return mat_name
        self.materials.add(mat_name)
        rgb = material_rgb(rgba, vp.get("texture_gain", 1.0), bool(vp.get("tinted", True)))
        metallic = obj.appearance.metallic
        roughness = obj.appearance.roughness
        mat = self.spec.add_material(
            name=mat_name,
            rgba=[*rgb, float(rgba[3]) if len(rgba) > 3 else 1.0],
            metallic=float(vp.get("metallic", 0.0) if metallic is None else metallic),
            roughness=float(vp.get("roughness", 0.5) if roughness is None else roughness),
            specular=float(vp.get("specular", 0.5)),
            shininess=float(vp.get("shininess", 0.5)),
            reflectance=float(vp.get("reflectance", 0.0)),
        )
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = self._texture(folder / vp["texture"])
        return mat_name

    # ---- architecture
    def room(self, room: Room, keepout: list[PlanRect] | None = None) -> None:
        """A room's floor, optional ceiling, lights, walls (boxes around the openings; pieces
        inside ``keepout``, :func:`~factory.sim.walls.wall_keepout`, left out) and window
        panes."""
        spec = self.spec
        w, ln = room.dimensions.width, room.dimensions.length
        x0, y0, z0 = room.position.as_tuple()
        spec.worldbody.add_geom(
            name=f"{room.id}/floor",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            pos=[x0 + w / 2, y0 + ln / 2, z0 + 0.0005 - FLOOR_SLAB / 2],
            size=[w / 2, ln / 2, FLOOR_SLAB / 2],
            material=self.material(f"floor/{room.floor_material}", room.floor_material),
            contype=0,
            conaffinity=0,
            group=GROUP_ARCH,
        )
        if self.options.ceiling:
            spec.worldbody.add_geom(
                name=f"{room.id}/ceiling",
                type=mujoco.mjtGeom.mjGEOM_BOX,
                pos=[x0 + w / 2, y0 + ln / 2, z0 + room.ceiling_height + 0.05],
                size=[w / 2, ln / 2, 0.05],
                material=self.material("wall/ceiling", "plaster"),
                group=GROUP_ARCH,
            )
        for light in ceiling_lights(room) if self.options.lights else []:
            _add_light(spec.worldbody, light)
        for wall in room.walls:
            openings: list[Door | Window] = [d for d in room.doors if d.wall_id == wall.id]
            openings += [w for w in room.windows if w.wall_id == wall.id]
            dx, dy = wall.end.x - wall.start.x, wall.end.y - wall.start.y
            length = wall.length
            ux, uy = dx / length, dy / length
            quat = _yaw_quat(math.atan2(dy, dx))
            mat = self.material(f"wall/{wall.material}", wall.material)
            half_t = wall.thickness / 2
            along_x = abs(uy) <= 1e-9
            plan_aligned = along_x or abs(ux) <= 1e-9
            k = 0
            for r in solid_rects(wall, openings):
                u0 = r.u0 - (half_t if r.u0 <= 1e-9 else 0.0)
                u1 = r.u1 + (half_t if r.u1 >= length - 1e-9 else 0.0)
                uc, zc = (u0 + u1) / 2, (r.z0 + r.z1) / 2
                hz = (r.z1 - r.z0) / 2
                cx, cy = wall.start.x + ux * uc, wall.start.y + uy * uc
                # (centre x, centre y, half size along the wall, half thickness)
                pieces = [(cx, cy, (u1 - u0) / 2, half_t)]
                if keepout and plan_aligned:
                    pieces = _kept_pieces(cx, cy, (u1 - u0) / 2, half_t, along_x, keepout)
                for px, py, hu, ht in pieces:
                    spec.worldbody.add_geom(
                        name=f"{room.id}/{wall.id}/{k}",
                        type=mujoco.mjtGeom.mjGEOM_BOX,
                        pos=[px, py, wall.start.z + zc],
                        quat=quat,
                        size=[hu, ht, hz],
                        material=self._upright(mat, ht, hz),
                        group=GROUP_ARCH,
                    )
                    k += 1
            for win in (op for op in room.windows if op.wall_id == wall.id):
                r = opening_rect(wall, win)
                uc, zc = (r.u0 + r.u1) / 2, (r.z0 + r.z1) / 2
                spec.worldbody.add_geom(
                    name=f"{room.id}/{win.id}/glass",
                    type=mujoco.mjtGeom.mjGEOM_BOX,
                    pos=[wall.start.x + ux * uc, wall.start.y + uy * uc, wall.start.z + zc],
                    quat=quat,
                    size=[(r.u1 - r.u0) / 2, 0.005, (r.z1 - r.z0) / 2],
                    rgba=list(SURFACES["glass"].rgba),
                    contype=0,
                    conaffinity=0,
                    group=GROUP_ARCH,
                )

    # ---- objects
    def _asset(self, obj: SceneObject) -> AssetMeta | None:
        if obj.asset is None or not obj.asset.asset_id or self.assets_root is None:
            return None
        folder = self.assets_root / obj.asset.asset_id
        if not (folder / "meta.json").is_file():
            return None
        try:
            return load_asset_meta(folder)
        except SchemaError as e:
            raise CompileError(f"object {obj.id!r}: {e}") from None

    def obj(self, obj: SceneObject) -> None:
        spec = self.spec
        body = spec.worldbody.add_body(
            name=obj.id, pos=list(obj.position.as_tuple()), quat=list(obj.rotation.quat_wxyz())
        )
        if not obj.is_static:
            body.add_freejoint(name=f"{obj.id}/free")
        lamp = lamp_light(obj) if self.options.lights else None
        if lamp is not None:
            _add_light(body, lamp)
        friction = [obj.physics.friction, TORSIONAL_FRICTION, ROLLING_FRICTION]
        rgba = tuple(obj.appearance.rgba) if obj.appearance.rgba else object_rgba(obj.category)
        meta = self._asset(obj)
        geoms: list[mujoco.MjsGeom] = []
        if meta is None:
            self.boxed.append(obj.id)
            d = obj.dimensions
            geoms.append(
                body.add_geom(
                    name=f"{obj.id}/box",
                    type=mujoco.mjtGeom.mjGEOM_BOX,
                    pos=[0, 0, d.height / 2],
                    size=[d.width / 2, d.length / 2, d.height / 2],
                    friction=friction,
                    material=self.material(f"obj/{obj.id}", "", rgba),
                    group=GROUP_VISUAL,
                )
            )
        else:
            assert obj.asset is not None
            scale = list(obj.asset.scale.as_tuple())
            aid = meta.asset_id
            # the link bodies (articulated assets) and which of them carries each piece
            carrier: dict[tuple[str, int], mujoco.MjsBody] = {}
            if meta.articulation is not None:
                carrier = self._links(obj, body, meta.articulation, scale)
            visual_mesh = f"{aid}/visual"
            if visual_mesh not in self.mesh_assets and not (meta.collision and meta.visual_parts):
                file = (
                    self.lit_mesh(aid, meta.visual, scale) if meta.collision else meta.visual
                )  # a visual mesh without collision pieces is also the collision geometry
                spec.add_mesh(name=visual_mesh, file=f"{aid}/{file}", scale=scale)
                self.mesh_assets[visual_mesh] = meta
            if meta.texture:
                tex_name = f"tex/{aid}"
                mat_name = f"mat/{aid}"
                if mat_name not in self.materials:
                    self.materials.add(mat_name)
                    spec.add_texture(
                        name=tex_name,
                        type=mujoco.mjtTexture.mjTEXTURE_2D,
                        file=f"{aid}/{meta.texture}",
                    )
                    m = spec.add_material(name=mat_name)
                    m.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex_name
                    if obj.appearance.roughness is not None:
                        m.roughness = obj.appearance.roughness
                    if obj.appearance.metallic is not None:
                        m.metallic = obj.appearance.metallic
                material = mat_name
            else:
                material = self.material(f"obj/{obj.id}", "", rgba)
            if meta.collision and meta.visual_parts:
                for k, vp in enumerate(meta.visual_parts):
                    part_mesh = f"{aid}/visual_{k}"
                    if part_mesh not in self.mesh_assets:
                        file = self.lit_mesh(aid, vp["file"], scale)
                        spec.add_mesh(name=part_mesh, file=f"{aid}/{file}", scale=scale)
                        self.mesh_assets[part_mesh] = meta
                    rgba_k = tuple(obj.appearance.rgba or vp.get("rgba") or rgba)
                    if vp.get("texture") and self.options.textures and self.assets_root:
                        part_mat = self._part_material(
                            f"obj/{obj.id}/{k}", self.assets_root / aid, vp, rgba_k, obj
                        )
                    else:
                        part_mat = self.material(f"obj/{obj.id}/{k}", "", rgba_k)
                    carrier.get(("visual", k), body).add_geom(
                        name=f"{obj.id}/visual_{k}",
                        type=mujoco.mjtGeom.mjGEOM_MESH,
                        meshname=part_mesh,
                        material=part_mat,
                        contype=0,
                        conaffinity=0,
                        density=0,
                        group=GROUP_VISUAL,
                    )
            elif meta.collision:
                body.add_geom(
                    name=f"{obj.id}/visual",
                    type=mujoco.mjtGeom.mjGEOM_MESH,
                    meshname=visual_mesh,
                    material=material,
                    contype=0,
                    conaffinity=0,
                    density=0,
                    group=GROUP_VISUAL,
                )
            else:
                geoms.append(
                    body.add_geom(
                        name=f"{obj.id}/visual",
                        type=mujoco.mjtGeom.mjGEOM_MESH,
                        meshname=visual_mesh,
                        material=material,
                        friction=friction,
                        group=GROUP_VISUAL,
                    )
                )
            for k, part in enumerate(meta.collision):
                mesh_name = f"{aid}/collision_{k}"
                if mesh_name not in self.mesh_assets:
                    spec.add_mesh(name=mesh_name, file=f"{aid}/{part}", scale=scale)
                    self.mesh_assets[mesh_name] = meta
                geoms.append(
                    carrier.get(("collision", k), body).add_geom(
                        name=f"{obj.id}/collision_{k}",
                        type=mujoco.mjtGeom.mjGEOM_MESH,
                        meshname=mesh_name,
                        friction=friction,
                        rgba=[0.5, 0.5, 0.5, 0.4],
                        group=GROUP_COLLISION,
                    )
                )
        if not obj.is_static or (meta is not None and meta.articulation is not None):
            # a static articulated object's links move: its pieces get the object's density
            for g in geoms:
                g.density = 1.0
            self.dynamic_geoms[obj.id] = geoms

    def _links(
        self, obj: SceneObject, body: mujoco.MjsBody, art: Articulation, scale: list[float]
    ) -> dict[tuple[str, int], mujoco.MjsBody]:
        """Adds an articulated object's link bodies under its body, each with its joint.

        A link body's frame is the object frame when every joint is closed; at the scene's
        joint state ``q`` (``SceneObject.joint_states``, default 0: closed) it is placed where
        its joint moves it, and the joint's ``ref`` is ``q``: ``qpos0`` is the scene's state
        while joint positions keep their meaning (0 closed, ``range`` and ``springref`` as in
        the asset). Anchors and slide travel follow the asset's scale.

        Returns:
            ``("collision" | "visual", piece index) -> the link body that carries it`` (the
            pieces of no link stay on the object's body).
        """
        sx, sy, sz = scale
        bodies = {ROOT_LINK: body}
        carrier: dict[tuple[str, int], mujoco.MjsBody] = {}
        for link in art.links:
            joint = art.joint(next(j.name for j in art.joints if j.link == link.name))
            lo, hi = joint.range
            travel = 1.0
            if joint.kind == "slide":
                travel = float(
                    abs(joint.axis[0] * sx) + abs(joint.axis[1] * sy) + abs(joint.axis[2] * sz)
                )
            anchor = [joint.anchor[0] * sx, joint.anchor[1] * sy, joint.anchor[2] * sz]
            q = float(obj.joint_states.get(joint.name, 0.0)) * travel
            rng = [lo * travel, hi * travel]
            if not rng[0] - 1e-9 <= q <= rng[1] + 1e-9:
                raise CompileError(
                    f"object {obj.id!r}: joint_states[{joint.name!r}] = {q:g} is outside the "
                    f"joint's range {rng} (closed: 0)"
                )
            posed = _Joint(joint.kind, anchor, list(joint.axis))
            tf = link_transform(posed, q)
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, tf[:3, :3].flatten())
            child = bodies[link.parent].add_body(
                name=f"{obj.id}/{link.name}", pos=list(tf[:3, 3]), quat=list(quat)
            )
            child.add_joint(
                name=f"{obj.id}/{joint.name}",
                type=mujoco.mjtJoint.mjJNT_SLIDE
                if joint.kind == "slide"
                else mujoco.mjtJoint.mjJNT_HINGE,
                pos=anchor,
                axis=list(joint.axis),
                range=rng,
                limited=mujoco.mjtLimited.mjLIMITED_TRUE,
                damping=joint.damping,
                frictionloss=joint.frictionloss,
                armature=joint.armature,
                stiffness=joint.stiffness,
                springref=joint.springref * travel,
                ref=q,
                group=LINK_JOINT_GROUP,
            )
            bodies[link.name] = child
            for k in link.collision:
                carrier[("collision", k)] = child
            for k in link.visual:
                carrier[("visual", k)] = child
        return carrier


def _build(
    scene: Scene, assets_root: str | Path | None, options: CompileOptions | None
) -> _Builder:
    root = Path(assets_root).resolve() if assets_root else None
    b = _Builder(scene, root, options or CompileOptions())
    b.setup()
    keepouts = wall_keepout(scene.rooms) if len(scene.rooms) > 1 else [[] for _ in scene.rooms]
    for room, keepout in zip(scene.rooms, keepouts, strict=True):
        b.room(room, keepout)
    for obj in scene.objects:
        b.obj(obj)
    return b


def build_spec(
    scene: Scene, assets_root: str | Path | None = None, options: CompileOptions | None = None
) -> tuple[mujoco.MjSpec, list[str]]:
    """Builds the MjSpec of a scene; returns it and the ids of objects compiled as boxes.

    Dynamic geoms have density 1 here; :func:`compile_scene` sets the scene's masses.
    """
    b = _build(scene, assets_root, options)
    return b.spec, b.boxed


def compile_scene(
    scene: Scene, assets_root: str | Path | None = None, options: CompileOptions | None = None
) -> CompiledScene:
    """Compiles a scene into a MuJoCo model.

    Args:
        scene: a validated scene.
        assets_root: the run's ``assets/`` folder (objects whose asset is found there use its
            meshes; the others become boxes).
        options: compiler options.

    Returns:
        the compiled scene; every dynamic object body has exactly the scene's mass.

    Raises:
        CompileError: MuJoCo rejects the model (the message says which part).
    """
    b = _build(scene, assets_root, options)
    spec, boxed, dynamic = b.spec, b.boxed, b.dynamic_geoms
    try:
        model = spec.compile()
        # Uniform density per object so that its body mass is exactly the scene's mass.
        for obj in scene.objects:
            if obj.id not in dynamic:
                continue
            volume = float(model.body_subtreemass[model.body(obj.id).id])  # its links too
            if volume <= 0:
                raise CompileError(f"object {obj.id!r}: its collision geometry has no volume")
            for g in dynamic[obj.id]:
                g.density = obj.physics.mass / volume
        model = spec.compile()
    except ValueError as e:
        raise CompileError(f"scene {scene.id!r} does not compile in MuJoCo: {e}") from None
    if boxed:
        log.info(
            "scene %s: %d object(s) have no asset and compile as boxes of their dimensions: %s",
            scene.id,
            len(boxed),
            ", ".join(boxed[:10]) + (" ..." if len(boxed) > 10 else ""),
        )
    return CompiledScene(
        spec=spec,
        model=model,
        boxed=boxed,
        assets_root=Path(assets_root).resolve() if assets_root else None,
    )


def model_xml(compiled: CompiledScene, model_dir: str | Path) -> str:
    """The MJCF text of a compiled scene, with asset paths relative to ``model_dir``."""
    import xml.etree.ElementTree as ET

    text = compiled.spec.to_xml()
    if compiled.assets_root is None:
        return text
    rel = os.path.relpath(compiled.assets_root, Path(model_dir).resolve())
    root = ET.fromstring(text)
    compiler = root.find("compiler")
    if compiler is None:  # pragma: no cover - MuJoCo always writes one with meshdir set
        compiler = ET.SubElement(root, "compiler")
    compiler.set("meshdir", rel)
    compiler.set("texturedir", rel)
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"
