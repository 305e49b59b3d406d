"""``experiments NAME from "..."``: one scene, many recordings.

The source is a glob of files (``"throws/*/trajectory.csv"``: each match is one recording,
named by its folder, and the scene's observation files are read from that folder) or a
manifest CSV (one row per recording: ``name``, ``folder`` relative to the manifest, and any
known settings as further columns, ``speed [m/s]``; a column without ``[unit]`` is a plain
number). A setting is written ``NAME.column`` in the scene (``throws.speed``) and stands there
as a ``Ref`` filled per recording. Priors written ``~ per_experiment dist(..)`` draw one value
per recording; every other unknown is shared by all of them. Mistakes are located: the scene
line for the statement, file/row/column for the manifest and each recording's data.

A manifest column may name a file per recording instead of a number: ``control push on ball
from throws.push column (fx, fy, fz)`` reads each recording's control table from the file in
its ``push`` cell (relative to the manifest). The tables are put on one time grid (the union of
their times: exact for the zero-order hold) and enter the rollout as a per-recording setting.
"""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np

from .. import expr as E
from ..errors import DataError, PhysError, PhysStructureError
from ..scene import Experiments, Recording, Scene
from . import ast
from .data import _col, _number, _rows, read_control, read_observation
from .expressions import R
from .units import DIMLESS, UnitError, parse_unit

GLOB_CHARS = "*?["
NAME_COLUMN, FOLDER_COLUMN = "name", "folder"
_HEADER = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:\[([^\]]*)\])?\s*$")


@dataclasses.dataclass(frozen=True)
class Source:
    """A recording as its source lists it: name, folder, settings (SI by dotted name), row."""

    name: str
    folder: Path
    settings: dict
    row: int | None = None


def find_item(res, scene: ast.SceneDecl) -> ast.ExperimentsItem | None:
    """The scene's ``experiments`` statement (a second one is an error)."""
    items = [i for i in scene.items if isinstance(i, ast.ExperimentsItem)]
    for extra in items[1:]:
        res.errors.append(res.err(PhysStructureError, "a scene has one 'experiments' line",
                                  extra.span, "list every recording in one glob or manifest"))
    return items[0] if items else None


def declare(res, item: ast.ExperimentsItem, scene: ast.SceneDecl | None = None) -> list[Source]:
    """Read the recordings of ``item``, register its settings as ``NAME.column`` values and
    point the observations at the first recording's folder; [] (error recorded) on failure.
    Columns that a ``control ... from NAME.column`` names hold a file per recording."""
    res.experiments_name = item.name
    files = {} if scene is None else file_columns(item, scene)
    sources = res.collect(_read, res, item, files)
    if not sources:
        return []
    res.recording_sources = sources
    res.items_by_name[item.name] = "experiments"
    res.setting_names = set(sources[0].settings["dims"])
    for key, dim in sources[0].settings["dims"].items():
        res.register(key, R(E.Ref(key), dim, ()), None)
    res.observation_base = sources[0].folder
    return sources


def file_columns(item: ast.ExperimentsItem, scene: ast.SceneDecl) -> dict:
    """The manifest columns that controls read a file from: column -> the first such
    control's span (where a missing column is reported)."""
    out = {}
    for it in scene.items:
        if isinstance(it, ast.ControlItem) and it.setting and it.setting.startswith(item.name + "."):
            out.setdefault(it.setting.split(".", 1)[1], it.span)
    return out


def _read(res, item: ast.ExperimentsItem, files: dict) -> list[Source]:
    path = res.data_file(item.source, item.span, "recordings")
    if any(c in item.source for c in GLOB_CHARS):
        if files:
            raise res.err(PhysStructureError, f"control files per recording come from a "
                          f"manifest's column, but '{item.source}' is a glob",
                          next(iter(files.values())), "list the recordings in a manifest CSV: "
                          "name, folder, and a column naming each one's control file")
        return _from_glob(res, item, path)
    if path.suffix.lower() != ".csv":
        raise res.err(PhysStructureError, f"'{item.source}' is neither a glob nor a manifest "
                      "CSV", item.span, 'e.g. "throws/*/trajectory.csv" or "throws.csv"')
    return _from_manifest(item, path, files)


def _from_glob(res, item, path: Path) -> list[Source]:
    """One recording per matching file, named by its folder below the glob's fixed part."""
    prefix = re.split(r"[*?\[]", item.source, maxsplit=1)[0]
    fixed = Path(prefix.rsplit("/", 1)[0] if "/" in prefix else ".")
    matches = sorted(p for p in res.base.glob(item.source) if p.is_file())
    if not matches:
        raise DataError("no file matches", path, span=item.span,
                        hint="the pattern is relative to the scene file, e.g. "
                             "\"throws/*/trajectory.csv\" (one folder per recording)")
    out, seen = [], {}
    for p in matches:
        res.bounds.check(p, "recording", str(p), item.span, res.source)
        rel = p.parent.relative_to(res.base / fixed) if p.parent != res.base / fixed else Path(p.stem)
        name = "-".join(rel.parts) or p.stem
        if p.parent in seen:
            raise DataError(f"two recordings in one folder ({seen[p.parent].name} and {p.name})",
                            p, span=item.span,
                            hint="each recording needs its own folder: its observations are "
                                 "read from there")
        seen[p.parent] = p
        out.append(Source(name, p.parent, {"values": {}, "dims": {}}))
    return out


def _from_manifest(item, path: Path, files: dict | None = None) -> list[Source]:
    """One recording per row of the manifest: its name, folder, known settings and files."""
    header, rows = _rows(path, item.span)
    iname, ifolder = (_col(header, c, path, item.span) for c in (NAME_COLUMN, FOLDER_COLUMN))
    ifiles = {_col(header, c, path, span): c for c, span in (files or {}).items()}
    settings = {}  # column index -> (dotted name, SI scale, dim, header text)
    for i, h in enumerate(header):
        if i in (iname, ifolder) or i in ifiles:
            continue
        m = _HEADER.match(h)
        if m is None:
            raise DataError(f"cannot read the column name '{h}'", path, row=1, column=h,
                            span=item.span, hint="a setting column is NAME or NAME [UNIT], "
                                                 "e.g. speed [m/s]")
        try:
            scale, dim = parse_unit(m.group(2)) if m.group(2) else (1.0, DIMLESS)
        except UnitError as ex:
            raise DataError(str(ex).split(": ", 1)[-1], path, row=1, column=h,
                            span=item.span, hint="write the unit as in a scene: m/s, deg, kg")
        settings[i] = (f"{item.name}.{m.group(1)}", scale, dim, h)
    out, names = [], {}
    for n, row in enumerate(rows, start=2):
        if not any(c.strip() for c in row):
            continue
        row = row + [""] * (len(header) - len(row))
        cells = {c: row[i].strip() for c, i in ((NAME_COLUMN, iname), (FOLDER_COLUMN, ifolder))}
        for c, cell in cells.items():
            if not cell:
                raise DataError(f"missing {c}", path, row=n, column=c, span=item.span,
                                hint="every recording needs a name and a folder")
        if cells[NAME_COLUMN] in names:
            raise DataError(f"the recording '{cells[NAME_COLUMN]}' is listed twice (first in "
                            f"row {names[cells[NAME_COLUMN]]})", path, row=n, column=NAME_COLUMN,
                            span=item.span)
        names[cells[NAME_COLUMN]] = n
        values = {}
        for i, (key, scale, _, h) in settings.items():
            if not row[i].strip():
                raise DataError("missing value", path, row=n, column=h, span=item.span,
                                hint="every recording needs every setting")
            values[key] = _number(row[i].strip(), path, n, h, item.span) * scale
        named = {c: _file_cell(row[i].strip(), path, n, c, item.span) for i, c in ifiles.items()}
        folder = path.parent / cells[FOLDER_COLUMN]
        if not folder.is_dir():
            raise DataError(f"no folder '{cells[FOLDER_COLUMN]}'", path, row=n,
                            column=FOLDER_COLUMN, span=item.span,
                            hint="folders are relative to the manifest")
        dims = {key: dim for key, _, dim, _ in settings.values()}
        out.append(Source(cells[NAME_COLUMN], folder,
                          {"values": values, "dims": dims, "files": named}, n))
    if not out:
        raise DataError("no recordings listed", path, span=item.span,
                        hint=f"one row per recording: {NAME_COLUMN}, {FOLDER_COLUMN}, settings")
    return out


def _file_cell(cell: str, manifest: Path, row: int, column: str, span) -> Path:
    """The file a manifest cell names (relative to the manifest); located errors."""
    if not cell:
        raise DataError("missing file", manifest, row=row, column=column, span=span,
                        hint="every recording needs its own file in this column")
    file = manifest.parent / cell
    if not file.is_file():
        raise DataError(f"no file '{cell}'", manifest, row=row, column=column, span=span,
                        hint="files are relative to the manifest")
    return file


def control_table(res, item: ast.ControlItem, width: int):
    """(the shared time grid, the setting's key) of a control read per recording from the
    manifest column ``item.setting``: each recording's table (its file's ``t`` and
    ``item.columns``) held on the union of every recording's times, stacked (R, N[, 3]) in
    ``res.recording_tables`` under the key ``NAME.column.CONTROL``; None when the recordings
    could not be read."""
    head, column = item.setting.split(".", 1)
    if head != res.experiments_name:
        raise res.err(PhysStructureError, f"'{item.setting}': '{head}' is not the scene's "
                      "experiments", item.span, "a control file per recording comes from a "
                      "column of the experiments' manifest: from NAME.column")
    if not res.recording_sources:
        return None  # the experiments could not be read: that error is recorded already
    tables = []
    for s in res.recording_sources:
        file = s.settings["files"][column]
        res.bounds.check(file, "control file", str(file), item.span, res.source)
        tables.append(read_control(file, item.columns, item.span))
    grid = np.unique(np.concatenate([t for t, _ in tables]))
    held = np.stack([_hold(t, v, grid) for t, v in tables])
    key = f"{item.setting}.{item.name}"
    res.recording_tables[key] = list(held if width == 3 else held[..., 0])
    return grid, key


def _hold(times: np.ndarray, values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """``values`` (zero-order hold at ``times``, 0 before the first) sampled at ``grid``, as
    ``physics/effects/control_force.hold`` reads them."""
    k = np.searchsorted(times, grid + 1e-9, side="right") - 1
    return np.where((k >= 0)[:, None], values[np.clip(k, 0, len(times) - 1)], 0.0)


def check_unknowns(res, scene: ast.SceneDecl, has_experiments: bool) -> None:
    """``per_experiment`` needs an ``experiments`` line, and a shared unknown's prior may not
    depend on a per-recording value (errors recorded)."""
    per = {n for n, u in res.unknowns.items() if u.per_experiment}
    for name, u in res.unknowns.items():
        if u.per_experiment and not has_experiments:
            res.errors.append(res.err(PhysStructureError, f"'{name}' is per_experiment, but the "
                                      "scene has no experiments", u.span,
                                      "add a line 'experiments NAME from \"folder/*/data.csv\"'"))
            continue
        if u.per_experiment:
            continue
        refs = set().union(*(E.references(a) for a in
                             list(u.prior.args) + [v for _, v in u.prior.kwargs]))
        bad = sorted(r for r in refs if r in per or r in res.setting_names)
        if bad:
            res.errors.append(res.err(PhysStructureError, f"the shared unknown '{name}' depends "
                                      f"on '{bad[0]}', which differs between recordings",
                                      u.span, "write its prior '~ per_experiment ...'"))


def attach(res, item: ast.ExperimentsItem, scene_ast: ast.SceneDecl, sources: list[Source],
           scene: Scene) -> Scene:
    """``scene`` with its recordings: every observation read again from each recording's
    folder; the simulated duration covers the longest recording."""
    observes = {f"{i.target}.{i.quantity}": i for i in scene_ast.items
                if isinstance(i, ast.ObserveItem)}
    if any(o.quantity == "image" for o in scene.observations):
        raise res.err(PhysStructureError, "image observations with experiments are not "
                      "supported yet", item.span, "observe trajectories (CSV) per recording")
    recordings = []
    for i, s in enumerate(sources):
        obs = scene.observations if i == 0 else tuple(
            _reread(res, o, observes[o.name], s.folder) for o in scene.observations)
        values = {**s.settings["values"], **{k: v[i] for k, v in res.recording_tables.items()}}
        recordings.append(Recording(s.name, s.folder, values, obs, s.row))
    res.raise_errors()
    ends = [float(o.times[-1]) for r in recordings for o in r.observations if len(o.times)]
    world = scene.world
    if world.duration is None and ends:
        world = dataclasses.replace(world, duration=max(ends))
    ex = Experiments(item.name, res.base / item.source, tuple(recordings),
                     tuple(sources[0].settings["dims"]) + tuple(res.recording_tables), item.span)
    return dataclasses.replace(scene, world=world, experiments=ex)


def _reread(res, o, node: ast.ObserveItem, folder: Path):
    """Observation ``o`` with its data read from ``folder`` (same columns and row filter)."""
    file = folder / node.file
    try:
        res.bounds.check(file, "data file", node.file, node.span, res.source)
        times, values, mask = read_observation(file, o.columns, node.where, node.span)
    except PhysError as ex:
        res.errors.append(ex)
        return o
    return dataclasses.replace(o, file=file, times=times, values=values, mask=mask)

