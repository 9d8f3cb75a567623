"""FLEM from Python: scenes, runs as numpy arrays, parameter sweeps on Dask (docs/python.md).

>>> import flem
>>> scene = flem.Scene.from_file("examples/weibull_bar.toml")
>>> scene.set("cracking.weibull.seed", 7)
>>> r = flem.run(scene, threads=1)
>>> r.displacement.shape, r.summary["splits"].sum()

The solver is the Rust library behind the ``flem`` command line (the extension module
``flem._native``): a scene is validated with the CLI's messages (:class:`SceneError`), a run
writes the same folder as ``flem run`` (VTU, history.csv, summary.json, checkpoints) with the
GIL released, and Ctrl-C stops it cleanly with a checkpoint (:class:`RunInterrupted`).
"""
from __future__ import annotations

import csv
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

import numpy as np

from . import _native
from ._errors import FlemError, RunInterrupted, SceneError
from ._sweep import sweep, grid

__version__: str = _native.__version__
__all__ = ["Scene", "Result", "run", "compare", "plugins", "sweep", "grid", "SceneError", "FlemError", "RunInterrupted", "allow_plugins"]

PathLike = Union[str, "os.PathLike[str]"]


def _jsonable(v: Any) -> Any:
    """numpy scalars and arrays as plain Python values (for json.dumps)."""
    if hasattr(v, "tolist"):
        return v.tolist()
    if isinstance(v, Path):
        return str(v)
    raise TypeError(f"{v!r} ({type(v).__name__}) has no TOML value")


class Scene:
    """A validated FLEM scene: TOML text with the path it came from (named in messages) and the
    folder that relative paths (mesh files) are resolved from.

    Build one with :meth:`from_file`, :meth:`from_toml` or :meth:`from_dict`; change values by
    key path with :meth:`set`. Every change is validated as ``flem check`` would; a bad one
    raises :class:`SceneError` with the CLI's message and leaves the scene as it was.
    Scenes pickle (they are sent to Dask workers by :func:`flem.sweep`).
    """

    __slots__ = ("_text", "_path", "_base")

    def __init__(self, text: str, path: str = "<scene>", base_dir: Optional[PathLike] = None) -> None:
        base = os.path.abspath(base_dir if base_dir is not None else os.getcwd())
        _native.scene_check(text, str(path), base)
        self._text = text
        self._path = str(path)
        self._base = base

    @classmethod
    def from_file(cls, path: PathLike) -> "Scene":
        """Reads and validates a scene file (relative mesh paths are resolved from its folder)."""
        p = Path(path)
        try:
            text = p.read_text()
        except OSError as e:
            raise SceneError(f"{p}: cannot be read: {e}", str(p), "") from None
        return cls(text, str(p), p.parent.resolve())

    @classmethod
    def from_toml(cls, text: str, path: str = "<string>", base_dir: Optional[PathLike] = None) -> "Scene":
        """A scene from TOML text; ``path`` names it in messages, ``base_dir`` (default: the
        current folder) resolves relative paths."""
        return cls(text, path, base_dir)

    @classmethod
    def from_dict(cls, d: Dict[str, Any], path: str = "<dict>", base_dir: Optional[PathLike] = None) -> "Scene":
        """A scene from a dict of the TOML structure (tables as dicts, arrays of tables as lists
        of dicts), e.g. ``{"mesh": {"type": "rectangle", ...}, "material": [{...}], ...}``."""
        base = os.path.abspath(base_dir if base_dir is not None else os.getcwd())
        text = _native.scene_from_json(json.dumps(d, default=_jsonable), path, base)
        return cls(text, path, base)

    def set(self, key: str, value: Any) -> "Scene":
        """Sets the value at a key path and validates the scene; returns the scene (chainable).

        Key paths are written as the scene's error messages name them: tables joined by ``.``,
        an element of an array of tables as ``name[i]``: ``"cracking.criterion.tensile_strength"``,
        ``"material[0].young_modulus"``, ``"stage[1].levels.pull"``. Missing tables are created.
        Raises :class:`SceneError` (the scene is left unchanged).
        """
        try:
            self._text = _native.scene_set(self._text, self._path, self._base, key, json.dumps(value, default=_jsonable))
        except SceneError as e:
            # A TOML parse error (an unknown field) names a line, not the key: name the key set.
            e.key = e.key or key
            raise
        return self

    def get(self, key: str) -> Any:
        """The value at a key path (as :meth:`set` names it); KeyError if absent."""
        v: Any = self.to_dict()
        for part in key.split("."):
            name, _, idx = part.partition("[")
            v = v[name]
            if idx:
                v = v[int(idx.rstrip("]"))]
        return v

    def copy(self) -> "Scene":
        s = Scene.__new__(Scene)
        s._text, s._path, s._base = self._text, self._path, self._base
        return s

    def to_toml(self) -> str:
        """The scene's TOML text (as given, or re-written after :meth:`set`)."""
        return self._text

    def to_dict(self) -> Dict[str, Any]:
        return json.loads(_native.scene_to_json(self._text))

    def resolved_toml(self) -> str:
        """The scene with every default filled in (a run's scene.resolved.toml)."""
        return _native.scene_resolved(self._text, self._path, self._base)

    @property
    def path(self) -> str:
        return self._path

    @property
    def base_dir(self) -> str:
        return self._base

    def __reduce__(self):
        return (_restore_scene, (self._text, self._path, self._base))

    def __repr__(self) -> str:
        return f"Scene({self._path!r})"


def _restore_scene(text: str, path: str, base: str) -> Scene:
    s = Scene.__new__(Scene)
    s._text, s._path, s._base = text, path, base
    return s


def _as_scene(scene: Union[Scene, PathLike]) -> Scene:
    return scene if isinstance(scene, Scene) else Scene.from_file(scene)


def _table(columns: Dict[str, Any]) -> Any:
    """A pandas DataFrame when pandas is installed, else the dict of numpy arrays."""
    try:
        import pandas as pd
    except ImportError:
        return columns
    return pd.DataFrame(columns)


def _column(values: List[str]) -> np.ndarray:
    try:
        return np.array([float(v) if v != "" else np.nan for v in values], dtype=np.float64)
    except ValueError:
        return np.array(values, dtype=object)


def _read_csv(path: Path) -> Any:
    """A CSV log as a table (empty fields: NaN); an absent file: an empty table."""
    if not path.exists():
        return _table({})
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        return _table({})
    head, body = rows[0], [r for r in rows[1:] if len(r) == len(rows[0])]
    return _table({h: _column([r[i] for r in body]) for i, h in enumerate(head)})


class Result:
    """What :func:`run` gives back: the final state as numpy arrays, the logs as tables.

    Arrays (bit-identical to the last VTU snapshot of the run: the same function builds both):

    - ``points`` (n, 2) float64: reference coordinates of each *cluster* (a cluster is a set of
      element corners moving as one node; before any split, cluster ``i`` is mesh point ``i``).
    - ``point_id`` (n,) int64: the mesh point each cluster was split from.
    - ``cells``: dict ``{"quad": (nq, 4), "triangle": (nt, 3)}`` int64, element connectivity on
      clusters (meshio's ``cells_dict`` names), elements in order within a kind.
    - ``clusters`` (ncopies,) int64: the cluster of each element copy (corner), element after
      element; ``copy_offsets`` (nelems + 1,) where each element's copies start.
    - ``crack_faces`` (nf, 2) int64: the two clusters of each crack face (one side of a
      separated edge); ``crack_state`` (nf,): 1 separated at one end, 2 at both.
    - ``displacement``, ``velocity`` (n, 2); ``mass`` (n,); ``nodal_stress`` (n, 3)
      ``[sxx, syy, sxy]`` (tension positive); ``elem_stress`` (nelems, 3); ``region`` (nelems,);
      ``failure_index`` (n,) or None without ``[cracking]``.

    Tables (a pandas DataFrame when pandas is installed, else a dict of numpy arrays):
    ``history`` (history.csv), ``splits`` (splits.csv), ``summary`` (one row per stage of
    summary.json: name, steps, converged, final_ratio, wall_seconds, time, splits,
    energy_residual, checks). ``info`` is the whole summary.json as a dict, ``compare`` the
    ``[check]`` rows (list of dicts), ``warnings`` the run's warnings, ``out`` its folder (None
    when it was a temporary one, removed after reading).

    A 3D scene (``[model] dim = 3``, docs/3d.md; ``dim`` is 3, else 2): ``points``,
    ``displacement``, ``velocity`` (n, 3); ``nodal_stress`` (n, 6) and ``elem_stress``
    (nelems, 6) ``[sxx, syy, szz, sxy, syz, szx]``; ``cells`` ``{"tetra": (m, 4),
    "hexahedron": (m, 8)}`` on clusters; ``fragment`` (nelems,); ``crack_faces`` (nf, 2) the two
    *elements* of each separated face, ``crack_state`` (nf,) at how many of its corners it is
    separated; ``splits`` is splits3.csv; no ``clusters``/``copy_offsets``, ``failure_index``
    None. ``resume``, ``on_stage`` and ``on_progress`` are refused for a 3D scene (not yet).
    """

    points: np.ndarray
    point_id: np.ndarray
    cells: Dict[str, np.ndarray]
    clusters: np.ndarray
    copy_offsets: np.ndarray
    cell_kinds: List[str]
    region: np.ndarray
    elem_stress: np.ndarray
    crack_faces: np.ndarray
    crack_state: np.ndarray
    displacement: np.ndarray
    velocity: np.ndarray
    mass: np.ndarray
    nodal_stress: np.ndarray
    failure_index: Optional[np.ndarray]

    def __init__(self, arrays: Dict[str, Any], out: Path, keep: bool, compare: List[Dict[str, Any]], warnings: List[str]) -> None:
        for k, v in arrays.items():
            setattr(self, k, v)
        self.dim: int = int(arrays.get("dim", 2))
        self.history = _read_csv(out / "history.csv")
        self.splits = _read_csv(out / ("splits3.csv" if self.dim == 3 else "splits.csv"))
        self.info: Dict[str, Any] = json.loads((out / "summary.json").read_text())
        stages = self.info.get("stages", [])
        keys = ["name", "steps", "converged", "final_ratio", "wall_seconds", "time", "splits", "energy_residual", "checks"]
        self.summary = _table({k: np.array([s.get(k) for s in stages], dtype=object if k == "name" else None) for k in keys})
        self.compare = compare
        self.warnings = warnings
        self.out: Optional[str] = str(out) if keep else None

    def __repr__(self) -> str:
        return f"<flem.Result: {len(self.points)} clusters, {len(self.crack_faces)} crack faces, {self.info.get('splits', 0)} splits, out={self.out!r}>"


def run(
    scene: Union[Scene, PathLike],
    out: Optional[PathLike] = None,
    threads: Optional[int] = None,
    resume: Optional[PathLike] = None,
    on_stage: Optional[Callable[[Dict[str, Any]], None]] = None,
    on_progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    progress_every: float = 0.2,
) -> Result:
    """Runs a scene (a :class:`Scene` or a scene file) as ``flem run`` does and returns its
    :class:`Result`. The GIL is released during the run (other Python threads go on).

    - ``out``: the output folder (VTU, PVD, history.csv, splits.csv, summary.json,
      checkpoints); None: a temporary folder, removed once the results are read (kept, and
      named by the exception, when the run stops early).
    - ``threads``: ``solver.threads`` for this run (results are bit-identical for any count).
    - ``resume``: a folder to continue from (its newest valid checkpoint), as ``--resume``.
    - ``on_stage(info)``: called after each stage with a dict (stage, name, steps, converged,
      final_ratio, wall_seconds, time, splits, energy_residual, total_splits, levels).
    - ``on_progress(info)``: called at most every ``progress_every`` seconds (stage, n_stages,
      step, stage_step, max_steps, ratio, tolerance).

    Raises :class:`SceneError` (bad scene), :class:`FlemError` (divergence, output error, ...),
    :class:`RunInterrupted` (Ctrl-C: a checkpoint was written; resume with ``resume=out``), or
    the exception a callback raised (the run stopped the same way, with a checkpoint).
    """
    sc = _as_scene(scene)
    tmp = out is None
    folder = Path(tempfile.mkdtemp(prefix="flem-run-")) if tmp else Path(out)
    try:
        d = _native.run(sc._text, sc._path, sc._base, str(folder), threads, None if resume is None else str(resume), on_stage, on_progress, progress_every)
    except BaseException:
        # Keep the folder of a run that stopped (its checkpoint and logs); remove an empty one.
        if tmp and not any(folder.iterdir()):
            shutil.rmtree(folder, ignore_errors=True)
        raise
    res = Result(d["arrays"], folder, not tmp, json.loads(d["compare"]), list(d["warnings"]))
    if tmp:
        shutil.rmtree(folder, ignore_errors=True)
    return res


def compare(scene: Union[Scene, PathLike], out: Optional[PathLike] = None) -> Any:
    """``flem compare``: runs every stage to equilibrium and compares it with the implicit FEM
    solve of the same model (the scene's ``[check]``, or its defaults). Returns the rows of
    compare.json as a table (per stage: rel_l2_displacement, max_abs_displacement_error,
    rel_l2_nodal_stress, wall_seconds_flem, wall_seconds_implicit, ...). ``out`` receives
    compare.json and the comparison VTUs (None: a temporary folder, removed)."""
    sc = _as_scene(scene)
    tmp = out is None
    folder = Path(tempfile.mkdtemp(prefix="flem-compare-")) if tmp else Path(out)
    try:
        rows = json.loads(_native.compare(sc._text, sc._path, sc._base, str(folder)))
    finally:
        if tmp:
            shutil.rmtree(folder, ignore_errors=True)
    keys: List[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    return _table({k: np.array([r.get(k) for r in rows], dtype=object) for k in keys})


def plugins() -> List[Tuple[str, str, Optional[str]]]:
    """The registered plugins as (kind, name, library file or None for built-ins), as
    ``flem plugins`` lists them."""
    return [tuple(p) for p in _native.plugins()]  # type: ignore[misc]


def allow_plugins(yes: bool = True) -> None:
    """Lets scenes load the native plugin libraries they name in ``[plugins] load``
    (``flem --allow-plugins``): code that runs in this process; only for scenes you trust."""
    _native.allow_plugins(yes)
