#!/usr/bin/env python3
"""Kinetic damping on a linear oscillator under symplectic Euler (docs/hybrid.md, "Session 20").

The integrator's update (v += kick*h*a, x += h*v; `integrate::schemes::symplectic_euler`), n
substeps per step, and the comparison's rule (`compare::drive::run`): after each step, if the
kinetic energy fell below the last step's, every velocity is zeroed. "whole": the next step
starts with a whole kick (before session 20); "half": with half a kick (leapfrog from rest,
`Integrator::motion_stopped`). Over h*omega = 0.01..1.60 (the automatic substeps' range) and
1-4 substeps, 400 steps from rest at x = 1: how often the energy at a stop rises above its
start, how often it drains below 1e-12. Run: python3 scripts/kinetic-damping-oscillator.py
"""


def stops(hw, sub, half, steps=400):
    x, v, last = 1.0, 0.0, 0.0
    kick = 0.5 if half else 1.0
    energies = []
    for _ in range(steps):
        for s in range(sub):
            v -= (kick if s == 0 else 1.0) * hw * x
            x += hw * v
        kick = 1.0
        e = 0.5 * v * v
        if e < last:
            v, last = 0.0, 0.0
            energies.append(0.5 * x * x / 0.5)
            if half:
                kick = 0.5
        else:
            last = e
    return energies


for half in (False, True):
    grew = drained = total = 0
    worst = 0.0
    for i in range(1, 161):
        for sub in (1, 2, 3, 4):
            e = stops(i * 0.01, sub, half)
            total += 1
            top = max(e, default=0.0)
            worst = max(worst, top)
            grew += top > 1.0 + 1e-9
            drained += bool(e) and e[-1] < 1e-12
    print(f"{'half' if half else 'whole'} kick after a stop: energy rose above its start in "
          f"{grew} of {total}, drained below 1e-12 in {drained}, largest {worst:.3g} times")
