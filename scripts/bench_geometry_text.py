"""Benchmark: the text resolver and the 2-D footprint geometry of placement, and what they cost
inside scene generation (CPU).

    python scripts/bench_geometry_text.py --tag before   # or --tag after
    python scripts/bench_geometry_text.py --quick         # one seed each, no critic-on runs

Measured, each on realistic inputs:

* ``resolve``: every catalogue phrase and synonym (and its plural), every furniture and small
  object text of the room types, and 200 misspelled or unknown texts (the fuzzy path), each
  resolved ``--repeat`` times;
* ``free`` (a candidate footprint against the objects, doors and windows of the room: the
  overlap checks of placement) and ``inside``: the calls that placement makes while generating
  kitchens (seeds 0-2, physics critic off), recorded once and replayed;
* ``generate_scene`` of a kitchen, physics critic off and on, seeds 0-2 (asset cache warmed
  first, so that the times are about placement, text and physics, not mesh generation).

Every group also gets a digest of its outputs (the resolver's decisions, the geometry answers,
the scene JSON), so that two result files show whether an implementation change altered any
result. Prints and saves JSON to ``benchmarks/results/geometry-text-<tag>-cpu<N>.json``.
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
import os
import platform
import tempfile
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from factory.assets import resolve
from factory.assets.resolver import _VOCAB
from factory.scenes import footprint, placement
from factory.scenes.brain import AgentConfig, generate_scene
from factory.scenes.rooms import ROOM_TYPES
from factory.schema import scene_to_json

RESULTS = Path(__file__).resolve().parent.parent / "benchmarks" / "results"
TEST_TEXTS = (
    "small blue ceramic bowl",
    "a rusty metal stool",
    "king-size bed",
    "mid-century armchair",
    "a refridgerator",
    "a wooden chair next to the table",
    "xyzzy plugh",
    "a tall oak bookshelf in the corner",
    "a cyberpunk sofa",
    "a red mug on the kitchen counter",
)
UNKNOWN_WORDS = (
    "thingamajig",
    "gizmo",
    "contraption",
    "whatsit",
    "doohickey",
    "gadget",
    "ornament",
    "sculpture",
    "statue",
    "trophy",
    "hammock",
    "aquarium",
    "easel",
    "harp",
    "telescope",
    "globe",
    "mannequin",
    "tripod",
    "birdcage",
    "xylophone",
)


def _digest(items: Iterable[Any]) -> str:
    h = hashlib.sha256()
    for it in items:
        h.update(json.dumps(it, sort_keys=True, default=str).encode())
    return h.hexdigest()[:16]


def _typo(word: str, rng: np.random.Generator) -> str:
    """One or two random edits (delete, substitute, swap, insert) of a word."""
    letters = "abcdefghijklmnopqrstuvwxyz"
    w = list(word)
    for _ in range(int(rng.integers(1, 3))):
        i = int(rng.integers(0, len(w)))
        op = int(rng.integers(0, 4))
        if op == 0 and len(w) > 3:
            del w[i]
        elif op == 1:
            w[i] = letters[int(rng.integers(0, 26))]
        elif op == 2 and i + 1 < len(w):
            w[i], w[i + 1] = w[i + 1], w[i]
        else:
            w.insert(i, letters[int(rng.integers(0, 26))])
    return "".join(w)


def text_inputs() -> dict[str, list[str]]:
    """The resolver's inputs: catalogue phrases, room-type texts, fuzzy texts (200)."""
    rooms = sorted(
        {it.text for rt in ROOM_TYPES.values() for it in rt.items}
        | {f for rt in ROOM_TYPES.values() for f in rt.fillers}
    )
    rng = np.random.default_rng(0)
    words = sorted({w for p in _VOCAB for w in p.split() if len(w) > 3})
    fuzzy: list[str] = []
    while len(fuzzy) < 180:
        w = words[int(rng.integers(0, len(words)))]
        t = _typo(w, rng)
        prefix = ("", "a ", "a small ", "the red ", "an old wooden ")[int(rng.integers(0, 5))]
        fuzzy.append(prefix + t)
    fuzzy += [f"a {w}" for w in UNKNOWN_WORDS]
    return {"catalogue": sorted(_VOCAB), "rooms": rooms, "tests": list(TEST_TEXTS), "fuzzy": fuzzy}


def resolution(text: str) -> list[Any]:
    r = resolve(text)
    return [text, r.spec.category, r.matched, r.confidence, r.approximated, r.spec.dims, r.notes]


def bench_resolve(repeat: int) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for group, texts in text_inputs().items():
        decisions = [resolution(t) for t in texts]  # also warms caches
        t0 = time.perf_counter()
        for _ in range(repeat):
            for t in texts:
                resolve(t)
        dt = (time.perf_counter() - t0) / (repeat * len(texts))
        out[group] = {
            "texts": len(texts),
            "ms_per_text": round(1000 * dt, 4),
            "approximated": sum(d[4] for d in decisions),
            "digest": _digest(decisions),
        }
    return out


class Recorder:
    """Records the geometry calls of placement (arguments and answers) while it runs."""

    def __init__(self) -> None:
        self.inside: list[tuple[Any, ...]] = []
        self.free: list[tuple[Any, ...]] = []
        self._saved: list[tuple[Any, str, Any]] = []

    def _wrap(self, owner: Any, name: str, sink: list[tuple[Any, ...]], snap: bool) -> None:
        orig = getattr(owner, name)
        self._saved.append((owner, name, orig))

        def wrapped(*args: Any, **kw: Any) -> Any:
            result = orig(*args, **kw)
            if snap:  # SceneState.free(self, fp, room, ignore, on): keep the objects then
                state, *rest = args
                sink.append((copy.deepcopy(state.scene.objects), tuple(rest), kw, result))
            else:
                sink.append((args, kw, result))
            return result

        setattr(owner, name, wrapped)

    def __enter__(self) -> Recorder:
        self._wrap(placement, "inside", self.inside, False)
        self._wrap(placement.SceneState, "free", self.free, True)
        return self

    def __exit__(self, *exc: Any) -> None:
        for owner, name, orig in reversed(self._saved):
            setattr(owner, name, orig)


def _time_calls(calls: list[Callable[[], Any]], repeat: int) -> tuple[float, list[Any]]:
    answers = [c() for c in calls]
    t0 = time.perf_counter()
    for _ in range(repeat):
        for c in calls:
            c()
    return (time.perf_counter() - t0) / (repeat * max(len(calls), 1)), answers


def bench_geometry(lib_dir: Path, seeds: list[int], repeat: int) -> dict[str, Any]:
    from factory.assets import AssetLibrary

    lib = AssetLibrary(lib_dir)
    cfg = AgentConfig(physics_critic=False)
    with Recorder() as rec:
        for seed in seeds:
            generate_scene("a kitchen", lib, seed=seed, config=cfg)
    # replays call the modules' current functions (not the recorded wrappers)
    ins = [(lambda a=a, kw=kw: footprint.inside(*a, **kw)) for a, kw, _ in rec.inside]
    state = placement.SceneState(
        generate_scene("a kitchen", lib, seed=seeds[0], config=cfg)[0], lib, 0
    )

    def free_call(objs: Any, rest: tuple[Any, ...], kw: dict[str, Any]) -> bool:
        state.scene.objects = objs
        return state.free(*rest, **kw)

    fr = [(lambda o=o, r=r, kw=kw: free_call(o, r, kw)) for o, r, kw, _ in rec.free]
    out: dict[str, Any] = {}
    for name, calls, recorded in (
        ("inside", ins, rec.inside),
        ("free", fr, rec.free),
    ):
        dt, answers = _time_calls(calls, repeat)
        out[name] = {
            "calls": len(calls),
            "us_per_call": round(1e6 * dt, 2),
            "true": int(sum(bool(a) for a in answers)),
            "same_as_recorded": answers == [bool(r[-1]) for r in recorded],
            "digest": _digest(bool(a) for a in answers),
        }
    return out


def bench_generate(lib_dir: Path, seeds: list[int], critic_seeds: list[int]) -> dict[str, Any]:
    from factory.assets import AssetLibrary

    lib = AssetLibrary(lib_dir)
    runs = [(False, s) for s in seeds] + [(True, s) for s in critic_seeds]
    for critic, seed in runs:  # warm the asset cache
        generate_scene("a kitchen", lib, seed=seed, config=AgentConfig(physics_critic=critic))
    rows = []
    for critic, seed in runs:
        t0 = time.perf_counter()
        scene, _ = generate_scene(
            "a kitchen", lib, seed=seed, config=AgentConfig(physics_critic=critic)
        )
        rows.append(
            {
                "physics_critic": critic,
                "seed": seed,
                "objects": len(scene.objects),
                "generate_s": round(time.perf_counter() - t0, 3),
                "scene_digest": hashlib.sha256(scene_to_json(scene).encode()).hexdigest()[:16],
            }
        )
    summary = {}
    for critic in (False, True):
        sel = [r["generate_s"] for r in rows if r["physics_critic"] is critic]
        if sel:
            summary[f"critic_{'on' if critic else 'off'}_mean_s"] = round(float(np.mean(sel)), 3)
    return {"rows": rows, **summary}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tag", default="run", help="before / after: goes into the file name")
    p.add_argument("--repeat", type=int, default=3, help="replays of each recorded call set")
    p.add_argument("--text-repeat", type=int, default=1, help="passes over the resolver texts")
    p.add_argument("--quick", action="store_true", help="seed 0 only, no physics critic")
    p.add_argument("--out", default=None)
    args = p.parse_args()
    seeds = [0] if args.quick else [0, 1, 2]
    critic_seeds = [] if args.quick else [0, 1, 2]
    result: dict[str, Any] = {
        "schema_version": 1,
        "benchmark": "geometry-text",
        "tag": args.tag,
        "machine": {
            "host": platform.node(),
            "python": platform.python_version(),
            "processor": platform.processor() or platform.machine(),
            "cpus": os.cpu_count(),
            "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
        },
        "resolve": bench_resolve(args.text_repeat),
    }
    with tempfile.TemporaryDirectory() as tmp:
        result["geometry"] = bench_geometry(Path(tmp), seeds, args.repeat)
        result["generate_kitchen"] = bench_generate(Path(tmp), seeds, critic_seeds)
    print(json.dumps(result, indent=2))
    name = f"geometry-text-{args.tag}-cpu{os.cpu_count()}.json"
    out = Path(args.out) if args.out else RESULTS / name
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
