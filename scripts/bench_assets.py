"""Benchmark: procedural assets per second (cold, into the cache) and the cost of a cache hit.

    python scripts/bench_assets.py [--seeds 3] [--out benchmarks/results/assets-<host>.json]

Cold: every category x seed generated and written to an empty cache (meshes, collision parts,
meta.json). Warm: the same requests again (cache hits: id hash + meta.json read + file checks).
Also the text resolver's cost per request.
"""

from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
from pathlib import Path

from factory.assets import CATEGORIES, AssetLibrary, AssetSpec, resolve

RESULTS = Path(__file__).resolve().parent.parent / "benchmarks" / "results"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--out", default=None)
    args = p.parse_args()
    specs = [AssetSpec(c, seed=s) for c in CATEGORIES for s in range(args.seeds)]
    with tempfile.TemporaryDirectory() as tmp:
        lib = AssetLibrary(Path(tmp))
        t0 = time.perf_counter()
        for spec in specs:
            lib.get(spec)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        for spec in specs:
            lib.get(spec)
        warm = time.perf_counter() - t0
        size = sum(f.stat().st_size for f in Path(tmp).rglob("*") if f.is_file())
    texts = [
        "small blue ceramic bowl",
        "a rusty metal stool",
        "king-size bed",
        "mid-century armchair",
        "refridgerator",
        "a wooden chair next to the table",
    ] * 50
    t0 = time.perf_counter()
    for t in texts:
        resolve(t)
    res_s = (time.perf_counter() - t0) / len(texts)
    result = {
        "schema_version": 1,
        "benchmark": "assets",
        "machine": {
            "host": platform.node(),
            "python": platform.python_version(),
            "processor": platform.processor() or platform.machine(),
        },
        "assets": len(specs),
        "categories": len(CATEGORIES),
        "cold_s": round(cold, 3),
        "cold_assets_per_s": round(len(specs) / cold, 1),
        "cache_hit_ms": round(1000 * warm / len(specs), 3),
        "cache_bytes_per_asset": size // len(specs),
        "resolve_ms": round(1000 * res_s, 3),
    }
    print(json.dumps(result, indent=2))
    out = Path(args.out) if args.out else RESULTS / f"assets-{platform.node()}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
