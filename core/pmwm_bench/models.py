"""The one catalogue of benchmark meshes: bench name -> file, the paper model it stands for, a note.

Every evaluation (``pmwm bench``, the equal-distortion sweep, the scripts in benchmarks/) names its
meshes here, so a file name or a stand-in note is written once. The meshes themselves are not
shipped (they are large and carry their own terms): they are looked up in a data folder given on the
command line, then in ``$PMWM_BENCH_DATA``. The bunny falls back to the copy packaged with pmwm
(``pmwm/data/bunny.off``, the same file as ``bunny_wm_benchmark.off``), so a quick run works on a
fresh install. A name that is not in the catalogue is taken as a mesh path (or a file name inside
the data folders).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence, Union

import numpy as np

import pmwm

#: environment variable naming the folder of the benchmark meshes
DATA_ENV = "PMWM_BENCH_DATA"

PathLike = Union[str, os.PathLike]


@dataclass(frozen=True)
class Model:
    """One catalogue entry: ``file`` inside the data folder, the paper model it stands for ("" when
    none of the paper's three), and the note printed with every table that uses it."""

    name: str
    file: str
    paper_model: str
    note: str


def _models(*entries: Model) -> dict[str, Model]:
    return {m.name: m for m in entries}


#: bench name -> catalogue entry; the first four are the paper's models or their stand-ins
CATALOGUE: dict[str, Model] = _models(
    Model("bunny", "bunny_wm_benchmark.off", "bunny", "the paper's bunny (34,835 V), exact"),
    Model("dragon", "dragon_wm_benchmark.off", "dragon", "the paper's dragon (50,000 V), exact"),
    Model(
        "venus-head",
        "venus_head_jigsaw.ply",
        "venus",
        "Venus STAND-IN: a remeshed Venus head (14,303 V); the paper's 100k Venus is not public",
    ),
    Model(
        "igea",
        "igea_cyberware.ply",
        "venus",
        "Venus STAND-IN: the Igea statue (134,345 V), similar size, different statue",
    ),
    Model("armadillo", "armadillo_libigl.obj", "", "the Armadillo (libigl, 43,243 V)"),
    Model("horse", "horse_cyberware.ply", "", "the Cyberware horse (48,485 V; faces point inward)"),
    Model("camelhead", "camelhead.off", "", "a camel head, an open mesh with one boundary loop (11,381 V)"),
    Model("rocker-arm", "rocker_arm.obj", "", "a CAD-like rocker arm, genus 1 (10,044 V)"),
    Model("fandisk", "fandisk.obj", "", "a CAD-like part with sharp features (6,475 V)"),
    Model("cow", "cow_libigl.off", "", "the libigl cow, closed and manifold (2,762 V)"),
)
#: what ``pmwm bench`` runs when no model is named
DEFAULT_MODELS: tuple[str, ...] = ("bunny", "dragon", "venus-head", "igea")


def packaged_bunny() -> Path:
    """The bunny shipped inside the pmwm package (``pmwm/data/bunny.off``)."""
    return Path(pmwm.__file__).resolve().parent / "data" / "bunny.off"


def data_dirs(data_dir: Union[PathLike, Sequence[PathLike], None] = None) -> list[Path]:
    """The folders searched, in order: ``data_dir`` (one folder or several), then $PMWM_BENCH_DATA."""
    given: list[PathLike] = []
    if isinstance(data_dir, (str, os.PathLike)):
        given.append(data_dir)
    elif data_dir is not None:
        given.extend(data_dir)
    env = os.environ.get(DATA_ENV)
    if env:
        given.append(env)
    return [Path(d) for d in given if str(d)]


@dataclass(frozen=True)
class ResolvedModel:
    """Where a model name led: ``path`` None when the mesh was not found."""

    label: str  # the name tables use (the catalogue name, or a path's stem)
    path: Optional[Path]
    paper_model: str
    note: str


def resolve(name: str, data_dir: Union[PathLike, Sequence[PathLike], None] = None) -> ResolvedModel:
    """Find the mesh of ``name``: a catalogue name (looked up in ``data_dirs(data_dir)``, the bunny
    falling back to the packaged copy), else a path, else a file name inside the data folders."""
    dirs = data_dirs(data_dir)
    model = CATALOGUE.get(name)
    if model is not None:
        for d in dirs:
            p = d / model.file
            if p.exists():
                return ResolvedModel(name, p, model.paper_model, model.note)
        if name == "bunny" and packaged_bunny().exists():
            return ResolvedModel(
                name, packaged_bunny(), model.paper_model, model.note + " (the copy packaged with pmwm)"
            )
        return ResolvedModel(name, None, model.paper_model, model.note)
    by_file = {m.file: m.name for m in CATALOGUE.values()}
    if name in by_file and not Path(name).exists():  # a catalogue file named by its file name
        return resolve(by_file[name], data_dir)
    p = Path(name)
    if not p.exists():
        p = next((d / name for d in dirs if (d / name).exists()), p)
    return ResolvedModel(p.stem, p if p.exists() else None, "", f"user model {p.name}")


def model_path(name: str, data_dir: Union[PathLike, Sequence[PathLike], None] = None) -> Path:
    """Like :func:`resolve`, but the path itself; FileNotFoundError (saying where it looked) if absent."""
    r = resolve(name, data_dir)
    if r.path is None:
        where = ", ".join(str(d) for d in data_dirs(data_dir)) or f"nowhere: pass a data folder or set ${DATA_ENV}"
        raise FileNotFoundError(f"benchmark mesh {name!r} not found (looked in {where})")
    return r.path


def load(path: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3) float64, faces (m, 3) int64) of a mesh file, read as ``pmwm.read_mesh`` reads it
    (welded, triangulated), so every benchmark measures the arrays a user's ``pmwm embed`` would see."""
    src = pmwm.read_mesh(str(path))
    return np.asarray(src.vertices, dtype=np.float64), np.asarray(src.faces, dtype=np.int64)


def load_model(name: str, data_dir: Union[PathLike, Sequence[PathLike], None] = None) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of catalogue model or path ``name`` (see :func:`model_path`, :func:`load`)."""
    return load(model_path(name, data_dir))


__all__ = [
    "CATALOGUE",
    "DATA_ENV",
    "DEFAULT_MODELS",
    "Model",
    "ResolvedModel",
    "data_dirs",
    "load",
    "load_model",
    "model_path",
    "packaged_bunny",
    "resolve",
]
