"""``place_objects(placement="inside")``: only interiors (behind a door, in a drawer) of an
articulated target; clear failures for a rigid target and for a task's object."""

from __future__ import annotations

from pathlib import Path

from factory.assets import AssetLibrary
from factory.scenes.tools import ToolSession


def _session(tmp_path: Path, articulated: bool) -> ToolSession:
    session = ToolSession(AssetLibrary(tmp_path / "assets", articulated=articulated), physics=False)
    assert session.init_scene("a kitchen", seed=2)["ok"]
    return session


def test_inside_places_on_interiors_only(tmp_path: Path) -> None:
    session = _session(tmp_path, articulated=True)
    res = session.place_objects("kitchen cabinet", placement="floor", rule="wall")
    assert res["ok"], res
    cab = session.scene.object(res["placed"][0])
    assert cab.category == "base_cabinet"
    meta = session.state.metas[cab.id]
    interiors = [s for s in meta.supports if s.get("access")]
    assert interiors, "a base cabinet has shelves or drawers behind its fronts"
    put = session.place_objects("bottle", placement="inside", target=cab.id, count=3)
    assert put["ok"], put
    top = max(float(s["z"]) for s in meta.supports)
    for oid in put["placed"]:
        obj = session.scene.object(oid)
        assert obj.placement.support_id == cab.id
        assert obj.position.z - cab.position.z < top - 1e-3, "not inside"


def test_inside_a_rigid_object_or_for_a_task_object_fails_clearly(tmp_path: Path) -> None:
    session = _session(tmp_path, articulated=False)
    table = session.place_objects("dining table", placement="floor", rule="center")
    assert table["ok"], table
    tid = table["placed"][0]
    res = session.place_objects("mug", placement="inside", target=tid)
    assert not res["ok"]
    assert "no free surface inside" in res["failures"][0]["reason"], res
    res = session.place_objects("mug", placement="inside", target=tid, task_role="pick")
    assert not res["ok"] and "not stored inside" in str(res), res
    res = session.place_objects("mug", placement="inside")
    assert not res["ok"] and "needs target" in str(res), res
