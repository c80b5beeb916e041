"""Parameter identification: recover a liver's Young's modulus and Poisson's ratio from a
force-indentation curve and the bulge it makes, with scipy.optimize.

The "measurement" is synthetic: fem-static on the shipped liver with the true E and nu, the
probe pressed to several depths; we record the probe force (proportional to E) and the
displacement of surface points away from the probe (under prescribed displacements these do
not depend on E but do depend on nu). A least-squares fit from a wrong start recovers both.

    python examples/identify_parameters.py [--depths 4] [--noise 0.0]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

import tissue

REPO = Path(__file__).resolve().parents[2]
FIXED = [3, 39, 64]  # the liver's ligament nodes, as in scenes/liver-probe.toml


def probe_vertex(model: tissue.Model) -> int:
    """The top-most surface vertex: where a probe pressing down touches first."""
    rest = model.rest_surface()
    return int(np.argmax(rest[:, 1]))


def observe(liver: tissue.Mesh, e: float, nu: float, depths: np.ndarray, watch: np.ndarray):
    """Probe force (N, along the push) per depth, and the watched vertices' displacements."""
    m = tissue.Model("fem-static", liver, {"young_modulus": e, "poisson_ratio": nu})
    v = probe_vertex(m)
    rest = m.rest_surface()
    forces, bulges = [], []
    for d in depths:
        m.set_constraints(fixed=FIXED, prescribed=[v], positions=rest[[v]] + [0.0, -d, 0.0])
        m.step(0.01)
        _, r = m.reactions()
        forces.append(r[0, 1])  # the tissue pushes the probe back up
        pos, _ = m.surface()
        bulges.append((pos[watch] - rest[watch]).ravel())
    return np.array(forces), np.concatenate(bulges)


def identify(liver, depths, forces, bulges, watch, start=(1500.0, 0.3)):
    """Least squares on relative residuals of the forces and bulges; E on a log scale."""
    f_scale = np.abs(forces).max()
    b_scale = np.abs(bulges).max()

    def residual(p):
        e, nu = np.exp(p[0]), p[1]
        f, b = observe(liver, e, nu, depths, watch)
        return np.concatenate([(f - forces) / f_scale, (b - bulges) / b_scale])

    fit = least_squares(
        residual,
        x0=[np.log(start[0]), start[1]],
        bounds=([np.log(1.0), 0.0], [np.log(1e7), 0.49]),
        x_scale=[1.0, 0.1],
        xtol=1e-12,
        ftol=1e-12,
    )
    return np.exp(fit.x[0]), fit.x[1], fit


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--true-e", type=float, default=4500.0, help="Pa")
    ap.add_argument("--true-nu", type=float, default=0.42)
    ap.add_argument("--depths", type=int, default=4, help="indentation depths, 2 to 8 mm")
    ap.add_argument("--noise", type=float, default=0.0, help="relative noise on the data")
    args = ap.parse_args(argv)

    liver = tissue.Mesh.read(REPO / "assets" / "meshes" / "liver.msh").scaled(0.01)
    depths = np.linspace(0.002, 0.008, args.depths)
    probe = tissue.Model("fem-static", liver, {"young_modulus": 1e3, "poisson_ratio": 0.3})
    rest = probe.rest_surface()
    v = probe_vertex(probe)
    # Watch the vertices 2-4 cm from the probe: far enough that nu shapes their motion.
    dist = np.linalg.norm(rest - rest[v], axis=1)
    watch = np.flatnonzero((dist > 0.02) & (dist < 0.04))[:40]

    forces, bulges = observe(liver, args.true_e, args.true_nu, depths, watch)
    rng = np.random.default_rng(7)
    forces = forces * (1 + args.noise * rng.standard_normal(forces.shape))
    bulges = bulges * (1 + args.noise * rng.standard_normal(bulges.shape))

    e, nu, fit = identify(liver, depths, forces, bulges, watch)
    result = {
        "true_e": args.true_e,
        "true_nu": args.true_nu,
        "e": e,
        "nu": nu,
        "e_error": abs(e - args.true_e) / args.true_e,
        "nu_error": abs(nu - args.true_nu) / args.true_nu,
        "evaluations": fit.nfev,
    }
    print(
        f"E = {e:.2f} Pa (true {args.true_e}, error {100 * result['e_error']:.3g} %), "
        f"nu = {nu:.4f} (true {args.true_nu}, error {100 * result['nu_error']:.3g} %), "
        f"{fit.nfev} model solves of {len(depths)} depths"
    )
    return result


if __name__ == "__main__":
    main()
