"""A sweep over model kinds x Young's moduli x probe depths, run as Ray tasks.

Each task builds one model on the shipped liver, presses a probe to one depth and reports
the settled force. `ray.init()` starts Ray on this machine; pointed at a cluster
(`RAY_ADDRESS=ray://head:10001` or `ray.init(address=...)`), the same script runs there
unchanged. Writes one CSV table.

    python examples/sweep_ray.py --models fem-static,tensor-mass --moduli 3000,6000 \
        --depths 0.002,0.004 --out sweep.csv
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np
import ray

REPO = Path(__file__).resolve().parents[2]
FIXED = [3, 39, 64]


@ray.remote
def press(kind: str, e: float, depth: float, settle: float) -> dict:
    """One case: `kind` at modulus `e` pressed `depth` m at the liver's top vertex."""
    import tissue

    liver = tissue.Mesh.read(REPO / "assets" / "meshes" / "liver.msh").scaled(0.01)
    start = time.perf_counter()
    m = tissue.Model(kind, liver, {"young_modulus": e, "poisson_ratio": 0.4, "density": 1000.0, "damping": 20.0})
    rest = m.rest_surface()
    v = int(np.argmax(rest[:, 1]))
    m.set_constraints(fixed=FIXED, prescribed=[v], positions=rest[[v]] + [0.0, -depth, 0.0])
    info = m.info()
    dt = 1e-3
    steps = 1 if info["is_static"] else int(round(settle / dt))
    error = ""
    try:
        for _ in range(steps):
            m.step(dt)
    except tissue.TissueError as exc:
        error = str(exc)
    _, r = m.reactions()
    return {
        "model": kind,
        "young_modulus": e,
        "depth": depth,
        "force": float(r[:, 1].sum()) if len(r) else float("nan"),  # the push back, +y
        "steps": steps,
        "seconds": time.perf_counter() - start,
        "error": error,
    }


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default="fem-static,fem-corotational,tensor-mass")
    ap.add_argument("--moduli", default="3000,6000")
    ap.add_argument("--depths", default="0.002,0.004")
    ap.add_argument("--settle", type=float, default=0.5, help="s of simulated time for dynamic kinds")
    ap.add_argument("--out", default="sweep.csv")
    ap.add_argument("--num-cpus", type=int, default=None, help="local Ray only")
    args = ap.parse_args(argv)

    if not ray.is_initialized():
        ray.init(num_cpus=args.num_cpus, include_dashboard=False, log_to_driver=False)
    cases = [
        (k, float(e), float(d))
        for k in args.models.split(",")
        for e in args.moduli.split(",")
        for d in args.depths.split(",")
    ]
    start = time.perf_counter()
    rows = ray.get([press.remote(k, e, d, args.settle) for k, e, d in cases])
    wall = time.perf_counter() - start
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"{len(rows)} cases in {wall:.1f} s wall -> {args.out}")
    for r in rows:
        print(f"  {r['model']:<24} E={r['young_modulus']:>7.0f} Pa  depth={1e3 * r['depth']:.1f} mm  "
              f"F={r['force']:.5f} N  {r['seconds']:.2f} s {r['error']}")
    return rows


if __name__ == "__main__":
    main()
