"""Fingerprint every bundled example's run, to show a refactor changed no result.

Runs ``plan-and-run`` on each ``examples/*.toml`` and hashes what a run computes: every array
of ``results.npz`` (bytes, dtype and shape), the planned path (``path.json`` without the name
of the propagator class) and ``summary.json`` without its wall-clock fields. ``--save FILE``
writes the fingerprints; ``--compare FILE`` reruns and prints each example as ``same`` or
``DIFFERENT`` (naming what differs), exiting 1 on any difference.

    python benchmarks/fingerprint_examples.py --save /tmp/before.json
    ... change the code ...
    python benchmarks/fingerprint_examples.py --compare /tmp/before.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
WALL_CLOCK_FIELDS = {"wall_time_s", "steps_per_second", "plan_time_s", "wall_time"}


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def _without(obj, keys):
    if isinstance(obj, dict):
        return {k: _without(v, keys) for k, v in obj.items() if k not in keys}
    if isinstance(obj, list):
        return [_without(v, keys) for v in obj]
    return obj


def fingerprint(run_dir: Path) -> dict:
    """Hashes of one run folder's results (see the module docstring)."""
    out = {}
    npz = run_dir / "results.npz"
    if npz.exists():
        with np.load(npz) as data:
            for name in sorted(data.files):
                a = np.ascontiguousarray(data[name])
                out[f"results.npz:{name}"] = _digest(a.tobytes() + str((a.dtype, a.shape)).encode())
    path = run_dir / "path.json"
    if path.exists():
        d = json.loads(path.read_text())
        d.get("info", {}).pop("propagator", None)
        out["path.json"] = _digest(json.dumps(d, sort_keys=True).encode())
    summary = run_dir / "summary.json"
    if summary.exists():
        d = _without(json.loads(summary.read_text()), WALL_CLOCK_FIELDS)
        out["summary.json"] = _digest(json.dumps(d, sort_keys=True).encode())
    return out


def run_example(scenario: Path, workdir: Path) -> dict:
    out_dir = workdir / scenario.stem
    proc = subprocess.run(["plan-and-run", str(scenario), "--out", str(out_dir), "--no-plots"],
                          capture_output=True, text=True)
    if proc.returncode not in (0, 1):
        print(f"{scenario.name}: exit {proc.returncode}\n{proc.stderr[-2000:]}", file=sys.stderr)
    return {"exit": proc.returncode, **fingerprint(out_dir)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--save", type=Path)
    group.add_argument("--compare", type=Path)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    scenarios = sorted((ROOT / "examples").glob("*.toml"))
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(args.workers) as pool:
        prints = dict(zip((s.name for s in scenarios),
                          pool.map(lambda s: run_example(s, Path(tmp)), scenarios), strict=True))
    if args.save:
        args.save.write_text(json.dumps(prints, indent=1, sort_keys=True))
        print(f"saved fingerprints of {len(prints)} examples to {args.save}")
        return 0
    before = json.loads(args.compare.read_text())
    differ = 0
    for name in sorted(set(before) | set(prints)):
        a, b = before.get(name, {}), prints.get(name, {})
        bad = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        differ += bool(bad)
        print(f"{name:28s} {'DIFFERENT: ' + ', '.join(bad) if bad else 'same'}")
    print(f"{len(prints) - differ} of {len(prints)} examples identical")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
