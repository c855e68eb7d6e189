"""The bundled facility atlas (examples/atlas/facility.toml, 6 stations, n = 1..5, 30 pairs)
with one Dask worker and with two, side by side: the wall time of each and their ratio.

    python benchmarks/bench_atlas.py [--trailers 1-5] [--workers 1,2]

Targets (issue 27): the whole atlas in at most 10 minutes on 2 cores; 2 workers at least 1.7
times as fast as 1. Each run goes into a new folder, so nothing is resumed.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trailers", default="1-5")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--facility", type=Path, default=ROOT / "examples" / "atlas" /
                    "facility.toml")
    args = ap.parse_args()

    import logging

    logging.getLogger("pushtrain").setLevel(logging.WARNING)
    from pushtrain.studies.atlas import atlas, load_facility, parse_trailers

    facility = load_facility(args.facility)
    trailers = parse_trailers(args.trailers)
    times, answers = {}, {}
    for k in (int(w) for w in args.workers.split(",")):
        out = Path(tempfile.mkdtemp()) / f"atlas-{k}"
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        doc = atlas(facility, trailers, out, workers=k)
        times[k] = time.perf_counter() - t0
        answers[k] = {(p["from"], p["to"]): p["max_trailers"] for p in doc["pairs"]}
        print(f"{k} worker{'s' if k > 1 else ''}: {times[k]:.1f} s for {len(doc['pairs'])} "
              f"pairs (load {load:.1f} at the start, {os.cpu_count()} cores)", flush=True)
    ks = sorted(times)
    if len(ks) >= 2:
        print(f"speed-up of {ks[-1]} workers over {ks[0]}: {times[ks[0]] / times[ks[-1]]:.2f}x "
              "(target >= 1.7 for 2 over 1)")
        print("same answers:", all(answers[k] == answers[ks[0]] for k in ks))


if __name__ == "__main__":
    main()
