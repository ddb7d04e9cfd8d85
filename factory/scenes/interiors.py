"""Which objects of a scene are stored inside articulated furniture (behind a door, in a
drawer): those standing below their support's top surface."""

from __future__ import annotations

from pathlib import Path

from factory.schema import Scene, SceneObject


def stored_inside(scene: Scene, assets: Path) -> list[tuple[SceneObject, SceneObject]]:
    """``(object, holder)`` pairs: objects placed on an articulated asset's support below its
    top surface (z in the world frame, m; the holder's supports scaled by its asset's z scale).

    Args:
        scene: the scene.
        assets: the run's assets folder (the holders' cached metadata).
    """
    from factory.assets import CATEGORIES
    from factory.assets.cache import cached

    out = []
    for o in scene.objects:
        if o.placement.kind != "on_top" or o.placement.support_id is None:
            continue
        sup = scene.object(o.placement.support_id)
        spec = CATEGORIES.get(sup.category)
        if spec is None or not spec.articulated or sup.asset is None:
            continue
        meta = cached(assets, sup.asset.asset_id)
        if meta is None or not meta.supports:
            continue
        top = max(float(x["z"]) for x in meta.supports) * sup.asset.scale.z
        if o.position.z - sup.position.z < top - 1e-3:
            out.append((o, sup))
    return out
