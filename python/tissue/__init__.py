"""tissue: real-time deformable models of soft tissue for surgery simulation.

Every model kind of the Rust library (``tissue.kinds()``), its meshes and its scenes, with
numpy arrays in and out, SI units (m, kg, s, Pa, N), and failures raised as
``tissue.TissueError`` (a ``ValueError``) carrying the library's message, which names the
file, line, key or element at fault. Stepping releases the GIL.

    import tissue
    liver = tissue.Mesh.read("liver.msh").scaled(0.01)
    model = tissue.Model("fem-static", liver, {"young_modulus": 3000.0, "poisson_ratio": 0.45})
    model.set_constraints(fixed=[3, 39, 64], prescribed=[120], positions=[[0.01, 0.02, 0.03]])
    model.step(0.01)
    fixed_forces, probe_forces = model.reactions()
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path
from typing import Any, Callable, Optional

from ._native import Mesh, Model, Scene, Simulation, TissueError, __version__
from ._native import kinds as _kinds

__all__ = [
    "Mesh",
    "Model",
    "Scene",
    "Simulation",
    "TissueError",
    "__version__",
    "kinds",
    "load_scene",
    "run_scene",
    "demo",
    "compare",
]


def kinds() -> list[str]:
    """The model kind names, as ``tissue models`` lists them."""
    return [name for name, _ in _kinds()]


def kind_summaries() -> dict[str, str]:
    """Each model kind with its one-line description."""
    return dict(_kinds())


def load_scene(path: str | os.PathLike[str]) -> Scene:
    """Reads and checks a TOML scene file."""
    return Scene.load(Path(path))


def run_scene(
    path: str | os.PathLike[str],
    callback: Optional[Callable[[dict[str, Any]], None]] = None,
    every: int = 1,
) -> dict[str, Any]:
    """Loads, builds and runs a scene to its end; returns the run's summary.

    ``callback(report)`` is called every ``every`` steps with the step's report (time,
    forces per instrument, contacts, solver figures). A step that fails ends the run and the
    summary's ``error`` says why.
    """
    return load_scene(path).build().run(callback=callback, every=every)


def demo() -> Simulation:
    """The built-in demo scene (``tissue demo``), built: a probe pressing into a liver."""
    return Scene.demo().build()


def compare(
    organ: Optional[str | os.PathLike[str]] = None,
    models: Optional[list[str]] = None,
    out: str | os.PathLike[str] = "compare-out",
    quick: bool = False,
    jobs: Optional[int] = None,
    tissue_bin: Optional[str] = None,
) -> dict[str, Any]:
    """Runs ``tissue compare`` and returns its ``compare.json`` as a dict.

    The comparison is the command-line tool's (it writes tables and plots beside the JSON);
    ``tissue_bin`` or the ``TISSUE_BIN`` environment variable names the binary, else it is
    looked up on PATH.
    """
    exe = tissue_bin or os.environ.get("TISSUE_BIN") or shutil.which("tissue")
    if exe is None:
        raise TissueError(
            "compare: the `tissue` command was not found: install it "
            "(cargo install --path crates/tissue-cli) or set TISSUE_BIN"
        )
    cmd = [exe, "compare"]
    if organ is not None:
        cmd.append(str(organ))
    if models:
        cmd += ["--models", ",".join(models)]
    cmd += ["--out", str(out)]
    if quick:
        cmd.append("--quick")
    if jobs is not None:
        cmd += ["--jobs", str(jobs)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise TissueError(f"tissue compare failed ({done.returncode}): {done.stderr.strip()}")
    with open(Path(out) / "compare.json", encoding="utf-8") as f:
        return json.load(f)
