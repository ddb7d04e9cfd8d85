# mypy: ignore-errors
"""Warp kernels of the GPU demo executor (:mod:`factory.demos.execute.warp`).

A call's worlds follow a :class:`~factory.demos.execute.world_schedule.WorldSchedule`: ``(B, n)``
tables (episode, frame, start, row) indexed by the frame boundary ``b = step // per_frame``, where
``step`` is a device-side counter of physics steps, so one captured recording period serves
every boundary.

No ``from __future__ import annotations`` here: Warp reads the kernels' annotations as types.
Importing this module imports Warp (not cheap); only the executor imports it.
"""

import warp as wp


@wp.kernel
def set_ctrl(
    plan: wp.array2d(dtype=float),
    offset: wp.array(dtype=int),
    length: wp.array(dtype=int),
    episode: wp.array2d(dtype=int),
    frame: wp.array2d(dtype=int),
    step: wp.array(dtype=int),
    per_frame: int,
    ctrl: wp.array2d(dtype=float),
):
    """Each world's control of the current physics step: ``plan[offset[e] + k]`` for the
    world's episode ``e`` at its step ``k`` (its frame times ``per_frame`` plus the step within
    the period; the episode's last control is held past its end). ``plan``: (sum of the
    episodes' steps, nu), the episodes' controls one after another. Worlds without an episode
    keep their control."""
    w, u = wp.tid()
    b = step[0] // per_frame
    e = episode[b, w]
    if e < 0:
        return
    k = wp.min(frame[b, w] * per_frame + step[0] - b * per_frame, length[e] - 1)
    ctrl[w, u] = plan[offset[e] + k, u]


@wp.kernel
def tick(step: wp.array(dtype=int)):
    """Advances the physics step counter read by :func:`set_ctrl`."""
    step[0] = step[0] + 1


@wp.kernel
def starts(
    start: wp.array2d(dtype=bool),
    episode: wp.array2d(dtype=int),
    step: wp.array(dtype=int),
    per_frame: int,
    overflow: wp.array(dtype=int),
    reset: wp.array(dtype=bool),
    overflow_of: wp.array(dtype=int),
):
    """Marks the worlds that start an episode at this boundary (``reset[w]``) and files the
    overflow flags of the episode each of them ends into ``overflow_of`` (one per episode; a
    reset clears the world's flags)."""
    w = wp.tid()
    b = step[0] // per_frame
    go = start[b, w] and b > 0
    reset[w] = go
    if go:
        e = episode[b - 1, w]
        if e >= 0:
            overflow_of[e] = overflow_of[e] | overflow[w]


@wp.kernel
def begin(
    reset: wp.array(dtype=bool),
    episode: wp.array2d(dtype=int),
    step: wp.array(dtype=int),
    per_frame: int,
    qpos0: wp.array2d(dtype=float),
    plan: wp.array2d(dtype=float),
    offset: wp.array(dtype=int),
    qpos: wp.array2d(dtype=float),
    ctrl: wp.array2d(dtype=float),
):
    """After ``mujoco_warp.reset_data`` of the worlds marked in ``reset``: their episode's
    initial configuration ``qpos0[e]`` (one row per episode) and first control."""
    w = wp.tid()
    if not reset[w]:
        return
    e = episode[step[0] // per_frame, w]
    for i in range(qpos.shape[1]):
        qpos[w, i] = qpos0[e, i]
    for u in range(ctrl.shape[1]):
        ctrl[w, u] = plan[offset[e], u]


@wp.kernel
def set_looks(
    reset: wp.array(dtype=bool),
    episode: wp.array2d(dtype=int),
    step: wp.array(dtype=int),
    per_frame: int,
    geoms: wp.array(dtype=int),
    rgba_rows: wp.array2d(dtype=wp.vec4),
    matid_rows: wp.array2d(dtype=int),
    lights: wp.array(dtype=int),
    light_pos_rows: wp.array2d(dtype=wp.vec3),
    diffuse_rows: wp.array2d(dtype=wp.vec3),
    specular_rows: wp.array2d(dtype=wp.vec3),
    active_rows: wp.array2d(dtype=bool),
    cams: wp.array(dtype=int),
    cam_pos_rows: wp.array2d(dtype=wp.vec3),
    cam_quat_rows: wp.array2d(dtype=wp.quat),
    geom_rgba: wp.array2d(dtype=wp.vec4),
    geom_matid: wp.array2d(dtype=int),
    light_pos: wp.array2d(dtype=wp.vec3),
    light_diffuse: wp.array2d(dtype=wp.vec3),
    light_specular: wp.array2d(dtype=wp.vec3),
    light_active: wp.array2d(dtype=bool),
    cam_pos: wp.array2d(dtype=wp.vec3),
    cam_quat: wp.array2d(dtype=wp.quat),
):
    """The appearance of the episode each world marked in ``reset`` starts at this boundary:
    row ``e`` of the episodes' patch tables (:class:`~factory.demos.record.appearance.PatchTables`;
    column ``k`` is element ``geoms[k]``, ``lights[k]`` or ``cams[k]``) into the world's row of
    the model's per-world fields (``(nworld, ...)``). Thread ``(w, k)``: world ``w``, the
    ``k``-th changed geom, light and camera."""
    w, k = wp.tid()
    if not reset[w]:
        return
    e = episode[step[0] // per_frame, w]
    if e < 0:
        return
    if k < geoms.shape[0]:
        g = geoms[k]
        geom_rgba[w, g] = rgba_rows[e, k]
        geom_matid[w, g] = matid_rows[e, k]
    if k < lights.shape[0]:
        i = lights[k]
        light_pos[w, i] = light_pos_rows[e, k]
        light_diffuse[w, i] = diffuse_rows[e, k]
        light_specular[w, i] = specular_rows[e, k]
        light_active[w, i] = active_rows[e, k]
    if k < cams.shape[0]:
        c = cams[k]
        cam_pos[w, c] = cam_pos_rows[e, k]
        cam_quat[w, c] = cam_quat_rows[e, k]


@wp.kernel
def to_images(
    packed: wp.array2d(dtype=wp.uint32),
    depth: wp.array2d(dtype=float),
    rgb_adr: wp.array(dtype=int),
    depth_adr: wp.array(dtype=int),
    c: int,
    npix: int,
    depth_mm: int,
    far: float,
    rows: wp.array2d(dtype=int),
    step: wp.array(dtype=int),
    per_frame: int,
    rgb_out: wp.array2d(dtype=wp.uint8),
    mm_out: wp.array2d(dtype=wp.uint16),
    m_out: wp.array2d(dtype=float),
):
    """The renderer's packed ARGB pixels and planar depth (m) of camera ``c`` of world ``w`` ->
    camera ``c``'s image store at row ``r = rows[b, w]`` of boundary ``b = step // per_frame``
    (nothing when ``r < 0``): ``rgb_out[r, 3 p + k]`` (uint8 RGB), ``mm_out[r, p]`` (uint16 mm,
    when ``depth_mm``) or ``m_out[r, p]`` (float32 m); ``p`` runs over the ``npix`` pixels row
    by row from the top: the host's ``(rows, H, W, 3)``. A depth that is not finite is stored
    as the far value: 65535 mm, or ``far`` (m).

    One store per camera (launched once per camera), never one array over all cameras: Warp
    keeps an array's strides in 32-bit ints, so a camera-major ``(ncam, rows, 3 H W)`` store of
    over 43,690 rows of 128 x 128 images (2 GiB a camera) had a negative first stride, and the
    first production-size call on an H100 (761 episodes, about 120,000 rows) wrote outside its
    store: CUDA error 700, an illegal memory access. A row of one camera is 49,152 bytes at
    128 x 128; the row index times it is computed in 64 bits."""
    w, p = wp.tid()
    r = rows[step[0] // per_frame, w]
    if r < 0:
        return
    val = packed[w, rgb_adr[c] + p]
    rgb_out[r, 3 * p + 0] = wp.uint8((val >> wp.uint32(16)) & wp.uint32(0xFF))
    rgb_out[r, 3 * p + 1] = wp.uint8((val >> wp.uint32(8)) & wp.uint32(0xFF))
    rgb_out[r, 3 * p + 2] = wp.uint8(val & wp.uint32(0xFF))
    z = depth[w, depth_adr[c] + p]
    finite = wp.isfinite(z)
    if depth_mm != 0:
        if finite:
            mm_out[r, p] = wp.uint16(wp.clamp(wp.round(z * 1000.0), 0.0, 65535.0))
        else:  # the far value, as the CPU recorder's encode_depth (a NaN never cast)
            mm_out[r, p] = wp.uint16(65535)
    else:
        if finite:
            m_out[r, p] = z
        else:
            m_out[r, p] = far
