"""``experiments NAME from "..."``: one scene, many recordings.

The source is a glob of files (``"throws/*/trajectory.csv"``: each match is one recording,
named by its folder, and the scene's observation files are read from that folder) or a
manifest CSV (one row per recording: ``name``, ``folder`` relative to the manifest, and any
known settings as further columns, ``speed [m/s]``; a column without ``[unit]`` is a plain
number). A setting is written ``NAME.column`` in the scene (``throws.speed``) and stands there
as a ``Ref`` filled per recording. Priors written ``~ per_experiment dist(..)`` draw one value
per recording; every other unknown is shared by all of them. Mistakes are located: the scene
line for the statement, file/row/column for the manifest and each recording's data.
"""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path

from .. import expr as E
from ..errors import DataError, PhysError, PhysStructureError
from ..scene import Experiments, Recording, Scene
from . import ast
from .data import _col, _number, _rows, read_observation
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


def declare(res, item: ast.ExperimentsItem) -> list[Source]:
    """Read the recordings of ``item``, register its settings as ``NAME.column`` values and
    point the observations at the first recording's folder; [] (error recorded) on failure."""
    sources = res.collect(_read, res, item)
    if not sources:
        return []
    res.items_by_name[item.name] = "experiments"
    res.setting_names = set(sources[0].settings["dims"])
    for key, dim in sources[0].settings["dims"].items():
        res.register(key, R(E.Ref(key), dim, ()), None)
    res.observation_base = sources[0].folder
    return sources


def _read(res, item: ast.ExperimentsItem) -> list[Source]:
    path = res.data_file(item.source, item.span, "recordings")
    if any(c in item.source for c in GLOB_CHARS):
        return _from_glob(res, item, path)
    if path.suffix.lower() != ".csv":
        raise res.err(PhysStructureError, f"'{item.source}' is neither a glob nor a manifest "
                      "CSV", item.span, 'e.g. "throws/*/trajectory.csv" or "throws.csv"')
    return _from_manifest(item, path)


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


def _from_manifest(item, path: Path) -> list[Source]:
    """One recording per row of the manifest: its name, folder and known settings."""
    header, rows = _rows(path, item.span)
    iname, ifolder = (_col(header, c, path, item.span) for c in (NAME_COLUMN, FOLDER_COLUMN))
    settings = {}  # column index -> (dotted name, SI scale, dim, header text)
    for i, h in enumerate(header):
        if i in (iname, ifolder):
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
        folder = path.parent / cells[FOLDER_COLUMN]
        if not folder.is_dir():
            raise DataError(f"no folder '{cells[FOLDER_COLUMN]}'", path, row=n,
                            column=FOLDER_COLUMN, span=item.span,
                            hint="folders are relative to the manifest")
        dims = {key: dim for key, _, dim, _ in settings.values()}
        out.append(Source(cells[NAME_COLUMN], folder, {"values": values, "dims": dims}, n))
    if not out:
        raise DataError("no recordings listed", path, span=item.span,
                        hint=f"one row per recording: {NAME_COLUMN}, {FOLDER_COLUMN}, settings")
    return out


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
        recordings.append(Recording(s.name, s.folder, dict(s.settings["values"]), obs, s.row))
    res.raise_errors()
    ends = [float(o.times[-1]) for r in recordings for o in r.observations if len(o.times)]
    world = scene.world
    if world.duration is None and ends:
        world = dataclasses.replace(world, duration=max(ends))
    ex = Experiments(item.name, res.base / item.source, tuple(recordings),
                     tuple(sources[0].settings["dims"]), item.span)
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

