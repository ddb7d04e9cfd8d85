"""Appearance randomisation of recorded episodes (``demos.appearance``).

Per episode, from a seed derived from the episode's seed, :func:`choose` draws what changes
(an :class:`~factory.schema.episode.EpisodeAppearance`, stored in the episode's metadata):

* background objects (every scene object but the task objects; also each room's floor and
  walls): a colour tint, and for a share of the objects the materials (textures and colours)
  of another object of the scene;
* lights: ceiling lights moved horizontally, every light's intensity and warm/cool colour;
* recording cameras: a small shift and turn from the rig pose.

:func:`model_patch` turns that record into the model fields it changes (a
:class:`ModelPatch`: whole arrays of ``geom_rgba``, ``geom_matid``, ``light_pos``,
``light_diffuse``, ``light_specular``, ``light_active``, ``cam_pos``, ``cam_quat``) and
:func:`apply_patch` writes them into an ``MjModel`` (the CPU executor does so before it draws
each episode's frame and restores the model after; :func:`place_cameras_and_lights` then moves
the cameras and lights that ``mj_forward`` does not recompute). Only rendering reads these
fields, so physics is untouched. Every field is per-world in MuJoCo Warp's kinematics and batch
renderer (a model array of leading size ``nworld`` is indexed by world); the GPU executor
keeps the episodes' patches as :class:`PatchTables` (only the elements some patch changes) and
copies an episode's row into its world's fields when the episode starts.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from factory.config import AppearanceConfig
from factory.schema.episode import CameraLook, EpisodeAppearance, LightLook, ObjectLook

PATCH_FIELDS = (
    "geom_rgba",
    "geom_matid",
    "light_pos",
    "light_diffuse",
    "light_specular",
    "light_active",
    "cam_pos",
    "cam_quat",
)
"""``MjModel`` fields an appearance changes (all per-world batchable in MuJoCo Warp)."""

DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)
"""MuJoCo's default geom rgba: a geom with a material and this rgba shows the material's."""


@dataclass(frozen=True)
class AppearanceIndex:
    """What of a composed model the randomisation may change.

    Attributes:
        objects: background object id (or ``<room>/floor``, ``<room>/walls``) -> its visual
            geom ids, in order (the task objects and the robot are not in it).
        donors: object id -> visual geom ids, of the objects whose materials others may wear
            (scene objects with materials on all their visual geoms, the support among them;
            not the pick object or the target).
        lights: names of the lights that may change (those left on; ceiling lights also
            move).
        cameras: recording camera name -> camera id.
        scene_cameras: the recording cameras placed in the scene (on the world body), whose
            jitter ``scene_camera_pos`` / ``scene_camera_angle`` may widen.
        lights_off: names of the lights switched off in every episode's recording (the
            other rooms' ceiling lights and lamps).
    """

    objects: dict[str, tuple[int, ...]]
    donors: dict[str, tuple[int, ...]]
    lights: tuple[str, ...]
    cameras: dict[str, int]
    lights_off: tuple[str, ...] = ()
    scene_cameras: tuple[str, ...] = ()


@dataclass
class ModelPatch:
    """Whole arrays of the model fields in :data:`PATCH_FIELDS` as one appearance sets them."""

    geom_rgba: np.ndarray
    geom_matid: np.ndarray
    light_pos: np.ndarray
    light_diffuse: np.ndarray
    light_specular: np.ndarray
    light_active: np.ndarray
    cam_pos: np.ndarray
    cam_quat: np.ndarray


def appearance_seed(episode_seed: int) -> int:
    """The seed of an episode's appearance (independent of its planning's random stream)."""
    return zlib.crc32(f"appearance/{episode_seed}".encode())


def other_room_lights(model: mujoco.MjModel, objects: dict[str, str], robot_room: str) -> list[str]:
    """Names of the ceiling lights of the rooms other than ``robot_room`` and of the lamps
    standing in them (``objects``: scene object id -> room id)."""
    rooms = set(objects.values())
    off = []
    for i in range(model.nlight):
        name = model.light(i).name
        owner, _, kind = name.rpartition("/")
        other_ceiling = kind.startswith("ceiling_") and owner in rooms and owner != robot_room
        other_lamp = kind == "lamp" and objects.get(owner, robot_room) != robot_room
        if other_ceiling or other_lamp:
            off.append(name)
    return off


def appearance_index(
    model: mujoco.MjModel,
    objects: dict[str, str],
    protected: set[str],
    cameras: dict[str, str],
    robot_room: str | None = None,
    no_donor: frozenset[str] = frozenset(),
) -> AppearanceIndex:
    """The randomisable parts of a composed scene model.

    Args:
        model: the scene with the robot (:func:`factory.tasks.pick_place.plan.setup_scene`).
        objects: scene object id -> its room id.
        protected: object ids that never change (the task objects).
        no_donor: object ids whose materials no other object may wear (the pick object and
            the target: a look-alike would make the instruction ambiguous).
        cameras: recording camera name -> camera name in the model.
        robot_room: the room the robot stands in; the other rooms' ceiling lights and lamps
            are switched off for recording (``None``: all lights stay on).
    """
    visual = model.geom_group < 3
    per_body: dict[int, list[int]] = {}
    for gid in np.flatnonzero(visual):
        per_body.setdefault(int(model.geom_bodyid[gid]), []).append(int(gid))
    out: dict[str, tuple[int, ...]] = {}
    donors: dict[str, tuple[int, ...]] = {}
    for oid in objects:
        try:
            body = model.body(oid).id
        except KeyError:  # taken out for the robot's base
            continue
        geoms = per_body.get(body, [])
        if not geoms:
            continue
        if oid not in no_donor and all(model.geom_matid[g] >= 0 for g in geoms):
            donors[oid] = tuple(geoms)
        if oid not in protected:
            out[oid] = tuple(geoms)
    rooms = sorted(set(objects.values()))
    for room in rooms:
        floor: list[int] = []
        walls: list[int] = []
        for g in per_body.get(0, []):
            name = model.geom(g).name
            if not name.startswith(f"{room}/"):
                continue
            rest = name[len(room) + 1 :]
            if rest == "floor":
                floor.append(g)
            elif rest.split("/")[-1].isdigit():  # <room>/<wall>/<k>
                walls.append(g)
        if floor:
            out[f"{room}/floor"] = tuple(floor)
        if walls:
            out[f"{room}/walls"] = tuple(walls)
    off = other_room_lights(model, objects, robot_room) if robot_room is not None else []
    on = [model.light(i).name for i in range(model.nlight) if model.light(i).name not in off]
    return AppearanceIndex(
        objects=out,
        donors=donors,
        lights=tuple(on),
        cameras={c: model.camera(n).id for c, n in cameras.items()},
        lights_off=tuple(off),
        scene_cameras=tuple(
            c for c, n in cameras.items() if int(model.cam_bodyid[model.camera(n).id]) == 0
        ),
    )


def _round(values: np.ndarray, digits: int = 5) -> list[float]:
    return [round(float(v), digits) for v in values]


def choose(index: AppearanceIndex, cfg: AppearanceConfig, seed: int) -> EpisodeAppearance:
    """Draws one episode's appearance (a pure function of the index, settings and seed).

    Args:
        index: the model's randomisable parts (:func:`appearance_index`).
        cfg: what to randomise and how much.
        seed: the appearance seed (:func:`appearance_seed` of the episode seed).

    Returns:
        what changes; empty lists for what ``cfg`` leaves alone.
    """
    app = EpisodeAppearance(seed=seed, lights_off=list(index.lights_off))
    if not cfg.enabled:
        return app
    # One random stream per kind, so switching one kind off leaves the others' draws alone.
    obj_rng, light_rng, cam_rng = (np.random.default_rng([seed, k]) for k in range(3))
    if cfg.colors or cfg.textures:
        for oid in index.objects:
            tint = np.ones(3)
            if cfg.colors:
                j = cfg.color_jitter
                tint = (1 + obj_rng.uniform(-j, j)) * (1 + obj_rng.uniform(-j / 3, j / 3, 3))
            donor = ""
            is_room = "/" in oid
            if cfg.textures and not is_room and obj_rng.random() < cfg.texture_swap:
                others = [d for d in index.donors if d != oid]
                if others:
                    donor = others[int(obj_rng.integers(len(others)))]
            if cfg.colors or donor:
                app.objects.append(ObjectLook(id=oid, tint=_round(tint), material_from=donor))
    if cfg.lights:
        for name in index.lights:
            offset = np.zeros(3)
            if "/ceiling_" in name:
                offset[:2] = light_rng.uniform(-cfg.light_pos, cfg.light_pos, 2)
            scale = 1 + light_rng.uniform(-cfg.light_intensity, cfg.light_intensity)
            t = light_rng.uniform(-cfg.light_color, cfg.light_color)
            color = np.array([1 + t, 1.0, 1 - t])
            app.lights.append(
                LightLook(
                    name=name, offset=_round(offset), intensity=round(scale, 5), color=_round(color)
                )
            )
    if cfg.camera:
        for cam in index.cameras:
            pos, turn = cfg.camera_pos, cfg.camera_angle
            if cam in index.scene_cameras:  # placed in the scene: its pose is recorded
                pos = max(pos, cfg.scene_camera_pos)
                turn = max(turn, cfg.scene_camera_angle)
            offset = cam_rng.uniform(-pos, pos, 3)
            axis = cam_rng.normal(size=3)
            axis /= np.linalg.norm(axis)
            angle = cam_rng.uniform(0, turn)
            app.cameras.append(
                CameraLook(name=cam, offset=_round(offset, 6), rotation=_round(axis * angle))
            )
    return app


def model_patch(
    model: mujoco.MjModel, index: AppearanceIndex, app: EpisodeAppearance | None
) -> ModelPatch:
    """The model fields an appearance sets (whole arrays; the model is not changed).

    ``app=None`` gives the model's own fields with only :attr:`AppearanceIndex.lights_off`
    switched off.
    """
    p = ModelPatch(**{f: np.array(getattr(model, f)) for f in PATCH_FIELDS})
    for name in app.lights_off if app is not None else index.lights_off:
        p.light_active[model.light(name).id] = 0
    if app is None:
        return p
    for look in app.objects:
        geoms = index.objects[look.id]
        if look.material_from:
            donor = index.donors[look.material_from]
            for k, g in enumerate(geoms):
                p.geom_matid[g] = model.geom_matid[donor[k % len(donor)]]
        tint = np.asarray(look.tint)
        for g in geoms:
            mat = p.geom_matid[g]
            rgba = model.geom_rgba[g]
            if mat >= 0 and tuple(float(v) for v in rgba) == DEFAULT_RGBA:
                rgba = model.mat_rgba[mat]
            p.geom_rgba[g, :3] = np.clip(rgba[:3] * tint, 0.0, 1.0)
            p.geom_rgba[g, 3] = rgba[3]
    for light in app.lights:
        i = model.light(light.name).id
        p.light_pos[i] += np.asarray(light.offset)
        scale = light.intensity * np.asarray(light.color)
        p.light_diffuse[i] = model.light_diffuse[i] * scale
        p.light_specular[i] = model.light_specular[i] * scale
    for cam in app.cameras:
        i = index.cameras[cam.name]
        p.cam_pos[i] += np.asarray(cam.offset)
        rotvec = np.radians(np.asarray(cam.rotation, float))
        angle = float(np.linalg.norm(rotvec))
        delta = np.array([1.0, 0.0, 0.0, 0.0])
        if angle > 0:
            mujoco.mju_axisAngle2Quat(delta, rotvec / angle, angle)
        q = np.zeros(4)
        mujoco.mju_mulQuat(q, model.cam_quat[i], delta)
        p.cam_quat[i] = q
    return p


def apply_patch(model: mujoco.MjModel, patch: ModelPatch) -> None:
    """Writes a patch's fields into ``model`` (in place)."""
    for f in PATCH_FIELDS:
        np.copyto(getattr(model, f), getattr(patch, f))


def place_cameras_and_lights(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Recomputes the world pose of every fixed camera and light of a body welded to the world
    (``cam_xpos``, ``cam_xmat``, ``light_xpos``, ``light_xdir`` of ``data``) from the model's
    ``cam_pos``, ``cam_quat``, ``light_pos`` and ``light_dir``, as ``mj_camlight`` does.

    Call it after ``mj_forward`` of a state drawn with a patch written by :func:`apply_patch`:
    with island sleeping on (the demos' models), MuJoCo's ``mj_forward`` never recomputes what
    hangs on static bodies (the world body's left and right cameras and ceiling lights) and
    keeps their poses as ``MjData`` first computed them, so the patch's camera and light moves
    would not show on the CPU renderer. MuJoCo Warp's ``camlight`` recomputes every camera and
    light in every world. (The patch moves nothing else: the wrist camera's shift rides on the
    hand, which ``mj_forward`` recomputes.)
    """
    fixed = int(mujoco.mjtCamLight.mjCAMLIGHT_FIXED)
    static = model.body_weldid == 0
    cams = np.flatnonzero((model.cam_mode == fixed) & static[model.cam_bodyid])
    if cams.size:
        body = model.cam_bodyid[cams]
        rot = data.xmat[body].reshape(-1, 3, 3)
        data.cam_xpos[cams] = data.xpos[body] + np.einsum("nij,nj->ni", rot, model.cam_pos[cams])
        local = np.empty((len(cams), 9))
        for k, c in enumerate(cams):
            quat = model.cam_quat[c] / np.linalg.norm(model.cam_quat[c])
            mujoco.mju_quat2Mat(local[k], quat)
        data.cam_xmat[cams] = (rot @ local.reshape(-1, 3, 3)).reshape(-1, 9)
    lights = np.flatnonzero((model.light_mode == fixed) & static[model.light_bodyid])
    if lights.size:
        body = model.light_bodyid[lights]
        rot = data.xmat[body].reshape(-1, 3, 3)
        data.light_xpos[lights] = data.xpos[body] + np.einsum(
            "nij,nj->ni", rot, model.light_pos[lights]
        )
        xdir = np.einsum("nij,nj->ni", rot, model.light_dir[lights])
        data.light_xdir[lights] = xdir / np.linalg.norm(xdir, axis=1, keepdims=True)


PATCH_GROUPS: dict[str, tuple[str, ...]] = {
    "geoms": ("geom_rgba", "geom_matid"),
    "lights": ("light_pos", "light_diffuse", "light_specular", "light_active"),
    "cameras": ("cam_pos", "cam_quat"),
}
"""The :data:`PATCH_FIELDS` by the model element they belong to (geoms, lights, cameras)."""


@dataclass(frozen=True)
class PatchTables:
    """The episodes' patches as small tables: only the elements some patch changes.

    For the GPU executor (:mod:`factory.demos.execute.warp`): a world that starts episode
    ``e`` copies row ``e`` of each table into its own copy of the model fields.

    Attributes:
        ids: group (``geoms``, ``lights``, ``cameras``) -> (K,) int32 ids of the elements of
            that group whose fields differ from the model's in at least one episode.
        rows: field name -> (episodes, K, ...) its values for those elements (float32; int32
            for ``geom_matid``, bool for ``light_active``; quaternions w, x, y, z; positions
            in m, in the frame of the element's body).
    """

    ids: dict[str, np.ndarray]
    rows: dict[str, np.ndarray]

    @property
    def width(self) -> int:
        """The largest number of changed elements of a group (a kernel's second dimension)."""
        return max((len(v) for v in self.ids.values()), default=0)


_TABLE_TYPES = {"geom_matid": np.int32, "light_active": np.bool_}


def patch_tables(model: mujoco.MjModel, patches: list[ModelPatch]) -> PatchTables:
    """The :class:`PatchTables` of the episodes' patches (one per episode, in order)."""
    ids: dict[str, np.ndarray] = {}
    rows: dict[str, np.ndarray] = {}
    for group, names in PATCH_GROUPS.items():
        changed = np.zeros(len(getattr(model, names[0])), bool)
        for p in patches:
            for f in names:
                diff = np.asarray(getattr(p, f)) != np.asarray(getattr(model, f))
                changed |= diff.reshape(len(changed), -1).any(axis=1)
        ids[group] = np.flatnonzero(changed).astype(np.int32)
        for f in names:
            dtype = _TABLE_TYPES.get(f, np.float32)
            rows[f] = np.stack(
                [np.asarray(getattr(p, f))[ids[group]].astype(dtype) for p in patches]
            )
    return PatchTables(ids=ids, rows=rows)


def setup_index(setup: Any, cameras: tuple[str, ...]) -> AppearanceIndex:
    """The :class:`AppearanceIndex` of a demos scene set-up
    (:class:`~factory.tasks.pick_place.plan.SceneSetup`): the task objects (pick, target, support)
    protected, the lights of the rooms the robot does not stand in switched off."""
    from factory.robots.panda import CAMERAS

    scene = setup.scene
    x, y = setup.placement.x, setup.placement.y
    robot_room = next((r.id for r in scene.rooms if r.contains_xy(x, y)), None)
    objects = {o.id: o.room_id for o in scene.objects}
    task = setup.objects
    protected = {task.pick.id, task.target.id, task.support.id}
    cams = {c: CAMERAS[c] for c in cameras}
    no_donor = frozenset({task.pick.id, task.target.id})
    return appearance_index(setup.model, objects, protected, cams, robot_room, no_donor)


def episode_looks(
    model: mujoco.MjModel, index: AppearanceIndex, cfg: AppearanceConfig, seeds: list[int]
) -> list[tuple[EpisodeAppearance, ModelPatch]]:
    """Each episode's appearance (drawn from :func:`appearance_seed` of its seed) and the
    model fields it sets, for :func:`factory.demos.execute.cpu.execute`."""
    out = []
    for seed in seeds:
        app = choose(index, cfg, appearance_seed(seed))
        out.append((app, model_patch(model, index, app)))
    return out
