"""The files of a diagnosis folder, ``result.json`` and ``evidence.nc``: all its report reads.

``simgap diagnose`` writes both (:func:`write_diagnosis_files`) and then the report from them
(:func:`read_diagnosis_files`, :func:`simgap.diagnosis.diagnosis_report.write_diagnosis_report`);
``simgap report-diagnosis`` writes the report again from the two files alone, byte for byte.

``result.json`` is the :class:`~simgap.diagnosis.result.DiagnosisResult`. ``evidence.nc`` is a
:class:`DiagnosisEvidence`: netCDF4 in simgap's CF-1.10 form (:mod:`simgap.results.cf`: a pose
error along ``axis`` is stored as its translation part in m and its rotation part in rad, labels
as char arrays, booleans as 0/1 flags), global attr ``schema_version`` (:data:`SCHEMA_VERSION`),
three groups:

- the root group (:class:`ItemEvidence`): per comparable item (a visible tag, pin hole and
  turntable angle of the capture; dim ``item``, in the diagnosis's order) its ``tag``, ``p`` and
  ``theta`` (rad), ``distance_m`` (camera-to-tag distance of the rig, m), ``in_split`` (item,
  split: ``fit``, ``choose``, ``measure``) and its repeat-mean pose errors per axis:
  ``real_error``, ``simulated_error``, ``fitted_error`` (the fast model with the selected
  effects, on the measure split; absent where nothing is selected) and ``confirmed_error``
  (every item re-rendered with them; absent without a confirmation);
- ``gap`` (:class:`GapEvidence`): the real - simulated signed error of every item of
  the capture's grid (tag, p, theta), as the gap heatmap draws it;
- ``image_stats`` (:class:`ImageStatEvidence`; absent where the capture or the simulation has
  no image statistics): per source (``real``, ``simulation``) and item what the image
  evidence figures draw.

Schema versions: 2 (this one); 1 (the third split was called ``report``) is still read
(:func:`upgrade_v1`).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import netCDF4
import numpy as np
import xarray as xr

from simgap.analysis.gap import align, image_stat_view
from simgap.analysis.report import compare_variants
from simgap.core.atomic import atomic_write
from simgap.core.axes import AXES
from simgap.diagnosis.result import DiagnosisResult
from simgap.diagnosis.result_json import lift_schema, write_json
from simgap.pose.image_stats import STATS
from simgap.results.cf import ERROR_UNITS, decode_cf, encode_cf
from simgap.results.contract import COORD_ATTRS

#: The diagnosis result in a diagnosis folder.
RESULT_FILE = "result.json"
#: The evidence beside it.
EVIDENCE_FILE = "evidence.nc"
#: Version of the ``evidence.nc`` schema written (its global attr ``schema_version``).
SCHEMA_VERSION = 2
#: The splits of the comparable items, in the order of the ``split`` dim.
SPLITS = ("fit", "choose", "measure")
#: The two sides of the gap, in the order of the ``source`` dim.
SOURCES = ("real", "simulation")
#: The reference variant of the gap comparison (:meth:`GapEvidence.comparison`) and the compared.
GAP_BASELINE, GAP_VARIANT = "simulation", "real"
#: The groups of ``evidence.nc`` beside its root group (module docstring).
GROUPS = ("gap", "image_stats")
#: What a diagnosis folder holds, for messages.
FOLDER_FILES = f"a diagnosis folder holds {RESULT_FILE} and {EVIDENCE_FILE} (simgap diagnose)"

#: ``units`` and ``long_name`` of the evidence's variables and of coordinates other than the
#: result dataset's (:data:`~simgap.results.contract.COORD_ATTRS`).
ATTRS: dict[str, dict[str, str]] = {
    "split": {"long_name": "split of the comparable items: fit, choose or measure"},
    "source": {"long_name": "side of the gap: the capture (real) or its simulation"},
    "distance_m": {"units": "m", "long_name": "camera-to-tag distance"},
    "in_split": {"long_name": "the item belongs to the split"},
    "real_error": {"units": ERROR_UNITS, "long_name": "repeat-mean pose error of the capture"},
    "simulated_error": {"units": ERROR_UNITS, "long_name": "repeat-mean simulated pose error"},
    "fitted_error": {
        "units": ERROR_UNITS,
        "long_name": "simulated pose error with the selected effects, fast model, measure split",
    },
    "confirmed_error": {
        "units": ERROR_UNITS,
        "long_name": "simulated pose error re-rendered with the selected effects",
    },
    "signed_gap": {
        "units": ERROR_UNITS,
        "long_name": "repeat-mean signed error, real - simulated, where both estimate a pose",
    },
    "paired": {"long_name": "both the capture and the simulation estimate every axis"},
    "turntable_from_facing_deg": {
        "units": "degree",
        "long_name": "turntable angle relative to the tag facing the camera",
    },
    "sight_elevation_deg": {
        "units": "degree",
        "long_name": "angle between the line of sight and the tag plane (90 facing)",
    },
    "visible": {"long_name": "the tag is expected in view"},
    "image_stat_median": {
        "units": "1",
        "long_name": "repeat-median image statistic, in the scale stat_units names",
    },
}


def _same(a: Any, b: Any) -> bool:
    """Whether two field values are equal: arrays by shape and values (NaN equal to NaN)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)) or a.shape != b.shape:
            return False
        return bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f" and b.dtype.kind == "f"))
    return bool(a == b)


def _labelled(ds: xr.Dataset) -> xr.Dataset:
    """``ds`` with the :data:`ATTRS` and :data:`~simgap.results.contract.COORD_ATTRS` it uses."""
    for name in ds.variables:
        attrs = ATTRS.get(str(name)) or COORD_ATTRS.get(str(name))
        if attrs:
            ds[name].attrs.update(attrs)
    return ds


def _values(ds: xr.Dataset, name: str, dims: tuple[str, ...], where: str) -> np.ndarray:
    """The values of ``ds[name]`` in the order ``dims``.

    Raises
    ------
    ValueError
        Naming ``where`` and the variable when it is missing or has other dims.
    """
    if name not in ds.variables:
        raise ValueError(f"{where}: missing variable {name!r}")
    if set(ds[name].dims) != set(dims):
        raise ValueError(f"{where}: {name}: expected dims {dims}, got {ds[name].dims}")
    return np.asarray(ds[name].transpose(*dims).values)


@dataclass(frozen=True)
class Stored:
    """How a record's field is stored in its dataset (:class:`_Record`).

    Attributes
    ----------
    name : str
        The variable's name.
    dims : tuple of str
        Its dims, in the order of the field's array axes.
    coord : bool
        A coordinate (an index, or an item's label), else a data variable.
    flag : bool
        Booleans (0/1 flags on disk).
    """

    name: str
    dims: tuple[str, ...]
    coord: bool = False
    flag: bool = False


R = TypeVar("R", bound="_Record")


class _Record:
    """A frozen record of arrays with its dataset form: a group of ``evidence.nc``.

    A subclass (a frozen dataclass) says how each field is stored (:attr:`layout`, fields with
    the default None may be absent), which label dims it has and their values (:attr:`labels`)
    and which int fields are attrs (:attr:`int_attrs`). Records are equal when every field is
    (:func:`_same`).
    """

    layout: ClassVar[dict[str, Stored]]
    labels: ClassVar[dict[str, tuple[str, ...]]]
    int_attrs: ClassVar[tuple[str, ...]] = ()
    #: a subclass is a dataclass (:func:`dataclasses.fields` reads its fields)
    __dataclass_fields__: ClassVar[dict[str, Any]]

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(
            _same(getattr(self, f.name), getattr(other, f.name)) for f in dataclasses.fields(self)
        )

    __hash__ = None  # type: ignore[assignment]

    def extra_coords(self) -> dict[str, Any]:
        """Coordinates written beside the fields, never read back (none)."""
        return {}

    def to_dataset(self) -> xr.Dataset:
        """The record as its group of ``evidence.nc`` (module docstring), in memory."""
        data: dict[str, Any] = {}
        coords: dict[str, Any] = {dim: list(values) for dim, values in self.labels.items()}
        for name, stored in self.layout.items():
            value = getattr(self, name)
            if value is not None:
                array = np.asarray(value, bool if stored.flag else None)
                (coords if stored.coord else data)[stored.name] = (stored.dims, array)
        attrs = {name: np.int64(getattr(self, name)) for name in self.int_attrs}
        ds = xr.Dataset(data, coords=coords | self.extra_coords(), attrs=attrs)
        return _labelled(ds)

    @classmethod
    def from_dataset(cls: type[R], ds: xr.Dataset, where: str = EVIDENCE_FILE) -> R:
        """The record of :meth:`to_dataset`'s form (``where`` names it in errors).

        Raises
        ------
        ValueError
            Naming ``where`` and the variable or attr that is missing or has other dims or
            labels.
        """
        for dim, expected in cls.labels.items():
            found = tuple(str(v) for v in ds[dim].values) if dim in ds.coords else None
            if found != expected:
                raise ValueError(f"{where}: {dim}: expected {list(expected)}, got {found}")
        optional = {f.name for f in dataclasses.fields(cls) if f.default is None}
        values: dict[str, Any] = {}
        for name, stored in cls.layout.items():
            if name in optional and stored.name not in ds.variables:
                values[name] = None
                continue
            array = _values(ds, stored.name, stored.dims, where)
            values[name] = array.astype(bool) if stored.flag else array
        for name in cls.int_attrs:
            if name not in ds.attrs:
                raise ValueError(f"{where}: missing attr {name!r}")
            values[name] = int(ds.attrs[name])
        return cls(**values)


#: An item's pose errors: (item, axis).
_ITEM_ERRORS = ("item", "axis")


@dataclass(frozen=True, kw_only=True, eq=False)
class ItemEvidence(_Record):
    """Per comparable item of a diagnosis, the pose errors its report tabulates and draws.

    Attributes
    ----------
    tag, p : ndarray of int (N,)
        Tag id and pin hole of each item.
    theta_rad : ndarray (N,)
        Turntable angle of each item (rad).
    distance_m : ndarray (N,)
        Camera-to-tag distance of the rig's nominal pose (m).
    in_split : ndarray of bool (N, 3)
        Whether the item is in each split of :data:`SPLITS` (the choose split as subsampled;
        with fewer than 3 items every item is in all three).
    real_error, simulated_error : ndarray (N, 6)
        Repeat-mean pose errors along :data:`~simgap.core.axes.AXES` (m, rad); NaN where a side
        did not detect the tag or either side's pose is a planar flip.
    fitted_error : ndarray (N, 6) or None
        Simulated errors with the selected effects, from the fast model on the measure split
        (NaN elsewhere); None where nothing is selected.
    confirmed_error : ndarray (N, 6) or None
        Simulated errors of every item re-rendered with the selected effects; None without a
        confirmation.
    """

    tag: np.ndarray
    p: np.ndarray
    theta_rad: np.ndarray
    distance_m: np.ndarray
    in_split: np.ndarray
    real_error: np.ndarray
    simulated_error: np.ndarray
    fitted_error: np.ndarray | None = None
    confirmed_error: np.ndarray | None = None

    layout: ClassVar[dict[str, Stored]] = {
        "tag": Stored("tag", ("item",), coord=True),
        "p": Stored("p", ("item",), coord=True),
        "theta_rad": Stored("theta", ("item",), coord=True),
        "distance_m": Stored("distance_m", ("item",)),
        "in_split": Stored("in_split", ("item", "split"), flag=True),
        **{
            name: Stored(name, _ITEM_ERRORS)
            for name in ("real_error", "simulated_error", "fitted_error", "confirmed_error")
        },
    }
    labels: ClassVar[dict[str, tuple[str, ...]]] = {"axis": AXES, "split": SPLITS}

    def __len__(self) -> int:
        return len(self.tag)

    @property
    def measure_items(self) -> int:
        """Number of items in the measure split."""
        return int(self.in_split[:, SPLITS.index("measure")].sum())

    @property
    def with_fitted_effects(self) -> np.ndarray:
        """The errors with the selected effects the report shows (N, 6) (m, rad).

        :attr:`confirmed_error` where confirmed, else :attr:`fitted_error`; all NaN where
        nothing is selected.
        """
        for errors in (self.confirmed_error, self.fitted_error):
            if errors is not None:
                return errors
        return np.full_like(self.real_error, np.nan)


def gap_dataset(real: xr.Dataset, sim: xr.Dataset) -> xr.Dataset:
    """The simulation and the real data as variants ``simulation`` and ``real`` of one dataset."""
    real, sim = align(real, sim)
    sim = sim.isel(variant=[0]).assign_coords(variant=[GAP_BASELINE])
    real = real.isel(variant=[0]).assign_coords(variant=[GAP_VARIANT])
    keep = ["error", "estimated", "detected", "reproj_px", "corners"]
    both = xr.concat([sim[keep], real[keep]], dim="variant", join="outer", fill_value=np.nan)
    both["detected"] = both.detected.fillna(False).astype(bool)
    visible = real.visible if "variant" not in real.visible.dims else real.visible.isel(variant=0)
    both["visible"] = visible
    both["expected"] = real.expected
    return both


#: The capture's grid of items (tag, p, theta).
_GRID = ("tag", "p", "theta")
#: The grid's coordinates, as a record on it stores them.
_GRID_LAYOUT = {
    "tag": Stored("tag", ("tag",), coord=True),
    "p": Stored("p", ("p",), coord=True),
    "theta_rad": Stored("theta", ("theta",), coord=True),
}


@dataclass(frozen=True, kw_only=True, eq=False)
class _GridRecord(_Record):
    """A record on the capture's grid of items (tag, p, theta).

    Attributes
    ----------
    tag, p : ndarray of int
        The grid's tags (T,) and pin holes (P,).
    theta_rad : ndarray (Θ,)
        Its turntable angles (rad).
    """

    tag: np.ndarray
    p: np.ndarray
    theta_rad: np.ndarray


@dataclass(frozen=True, kw_only=True, eq=False)
class GapEvidence(_GridRecord):
    """The gap on the capture's grid of items, as the gap heatmap draws it.

    Attributes
    ----------
    tag, p, theta_rad : ndarray
        The grid (:class:`_GridRecord`).
    signed_gap : ndarray (T, P, Θ, 6)
        Repeat-mean signed error, real - simulated, along :data:`~simgap.core.axes.AXES` (m,
        rad); NaN where not :attr:`paired`.
    paired : ndarray of bool (T, P, Θ)
        Both the capture and the simulation estimate every axis.
    turntable_from_facing_deg : ndarray (T, Θ)
        Turntable angle relative to where the tag faces the camera, wrapped to [-180, 180] deg
        (:func:`~simgap.analysis.report._comparisons.view_angle_deg`).
    distance_m : ndarray (T, P, Θ)
        Camera-to-tag distance of the capture's expected poses (m).
    repeats : int
        Repeats an item's mean is over (the ``repeats`` attr).
    """

    signed_gap: np.ndarray
    paired: np.ndarray
    turntable_from_facing_deg: np.ndarray
    distance_m: np.ndarray
    repeats: int

    layout: ClassVar[dict[str, Stored]] = _GRID_LAYOUT | {
        "signed_gap": Stored("signed_gap", (*_GRID, "axis")),
        "paired": Stored("paired", _GRID, flag=True),
        "turntable_from_facing_deg": Stored("turntable_from_facing_deg", ("tag", "theta")),
        "distance_m": Stored("distance_m", _GRID),
    }
    labels: ClassVar[dict[str, tuple[str, ...]]] = {"axis": AXES}
    int_attrs: ClassVar[tuple[str, ...]] = ("repeats",)

    @classmethod
    def of(cls, real: xr.Dataset, sim: xr.Dataset) -> GapEvidence:
        """The gap of ``real`` against ``sim`` (:func:`compare_variants` of :func:`gap_dataset`)."""
        cmp = compare_variants(gap_dataset(real, sim), GAP_BASELINE).sel(variant=GAP_VARIANT)
        return cls(
            tag=cmp.tag.values,
            p=cmp.p.values,
            theta_rad=cmp.theta.values,
            signed_gap=cmp.signed_shift.transpose(*_GRID, "axis").values,
            paired=cmp.paired.transpose(*_GRID).values.astype(bool),
            turntable_from_facing_deg=cmp.view_angle_deg.transpose("tag", "theta").values,
            distance_m=cmp.distance_m.transpose(*_GRID).values,
            repeats=int(cmp.attrs["n_repeat"]),
        )

    def comparison(self) -> xr.Dataset:
        """The gap in :func:`compare_variants`' layout: ``real`` against ``simulation``.

        What :func:`~simgap.analysis.report.plot_comparison_heatmap` reads:
        ``signed_shift`` and ``paired`` of the variant ``real``, the coordinates
        ``view_angle_deg`` and ``distance_m``, the attrs ``baseline`` and ``n_repeat``.
        """
        ds = self.to_dataset()
        return xr.Dataset(
            {
                "signed_shift": ds.signed_gap.expand_dims(variant=[GAP_VARIANT]),
                "paired": ds.paired.expand_dims(variant=[GAP_VARIANT]),
            },
            coords={
                "view_angle_deg": ds.turntable_from_facing_deg,
                "distance_m": ds.distance_m,
            },
            attrs={"baseline": GAP_BASELINE, "n_repeat": self.repeats},
        )


@dataclass(frozen=True, kw_only=True, eq=False)
class ImageStatEvidence(_GridRecord):
    """The image statistics of the capture and its simulation, as its figures draw them.

    Each side's :func:`~simgap.analysis.gap.image_stat_view`, on the capture's grid.

    Attributes
    ----------
    tag, p, theta_rad : ndarray
        The grid (:class:`_GridRecord`).
    stat : ndarray of str (S,)
        The statistics both sides have, in the order of
        :data:`~simgap.pose.image_stats.STAT_NAMES`.
    visible : ndarray of bool (2, T, P, Θ)
        Per source of :data:`SOURCES`, the tag is expected in view.
    distance_m : ndarray (2, T, P, Θ)
        Camera-to-tag distance of each source's expected poses (m).
    sight_elevation_deg : ndarray (2, T, P, Θ)
        Angle between the line of sight and the tag plane (deg; 90 facing the camera).
    image_stat_median : ndarray (2, T, P, Θ, S)
        Repeat-median image statistics of the first variant (each in its own scale,
        :data:`~simgap.pose.image_stats.STATS`).
    """

    stat: np.ndarray
    visible: np.ndarray
    distance_m: np.ndarray
    sight_elevation_deg: np.ndarray
    image_stat_median: np.ndarray

    layout: ClassVar[dict[str, Stored]] = _GRID_LAYOUT | {
        "stat": Stored("stat", ("stat",), coord=True),
        "visible": Stored("visible", ("source", *_GRID), flag=True),
        "distance_m": Stored("distance_m", ("source", *_GRID)),
        "sight_elevation_deg": Stored("sight_elevation_deg", ("source", *_GRID)),
        "image_stat_median": Stored("image_stat_median", ("source", *_GRID, "stat")),
    }
    labels: ClassVar[dict[str, tuple[str, ...]]] = {"source": SOURCES}

    @classmethod
    def of(cls, real: xr.Dataset, sim: xr.Dataset) -> ImageStatEvidence | None:
        """The statistics of ``real`` and ``sim`` aligned to it; None where either has none."""
        if "image_stats" not in real or "image_stats" not in sim:
            return None
        views = [image_stat_view(ds) for ds in align(real, sim)]
        stat = [s for s in views[0].stat.values if s in views[1].stat.values]
        both = xr.concat([v.sel(stat=stat) for v in views], dim="source")
        per_source = ("visible", "distance_m", "sight_elevation_deg", "image_stat_median")
        return cls(
            tag=both.tag.values,
            p=both.p.values,
            theta_rad=both.theta.values,
            stat=both.stat.values,
            **{name: both[name].transpose(*cls.layout[name].dims).values for name in per_source},
        )

    def extra_coords(self) -> dict[str, Any]:
        """Each statistic's scale and meaning (``stat_units``, ``stat_long_name``)."""
        scales = {name: (units, meaning) for name, units, meaning in STATS}
        return {
            "stat_units": ("stat", [scales[str(s)][0] for s in self.stat]),
            "stat_long_name": ("stat", [scales[str(s)][1] for s in self.stat]),
        }

    def views(self) -> dict[str, xr.Dataset]:
        """Per source, its :func:`~simgap.analysis.gap.image_stat_view`."""
        ds = self.to_dataset().reset_coords(drop=True)
        return {source: ds.sel(source=source, drop=True) for source in SOURCES}


@dataclass(frozen=True, kw_only=True, eq=False)
class DiagnosisEvidence(_Record):
    """What a diagnosis report draws beyond ``result.json``: ``evidence.nc`` (module docstring).

    Attributes
    ----------
    items : ItemEvidence
        Per comparable item: its splits and pose errors (the root group).
    gap : GapEvidence
        The signed gap on the capture's grid (the gap heatmap; group ``gap``).
    image_stats : ImageStatEvidence or None
        The image statistics of both sides (the image-evidence figures; group
        ``image_stats``); None where either has none.
    """

    items: ItemEvidence
    gap: GapEvidence
    image_stats: ImageStatEvidence | None = None

    def write(self, path: Path) -> Path:
        """Write ``evidence.nc`` at ``path`` atomically (CF-1.10, groups); return the path."""
        root = encode_cf(self.items.to_dataset())
        root.attrs.update(
            title="simgap diagnosis evidence: what the report draws beside result.json",
            schema_version=np.int64(SCHEMA_VERSION),
        )
        records: list[tuple[str, _Record | None]] = [
            ("gap", self.gap),
            ("image_stats", self.image_stats),
        ]
        groups = {name: encode_cf(r.to_dataset()) for name, r in records if r is not None}
        for ds in groups.values():
            ds.attrs.pop("Conventions", None)  # the file's, in its root group

        def to_file(tmp: Path) -> None:
            root.to_netcdf(tmp, engine="netcdf4", format="NETCDF4")
            for name, ds in groups.items():
                ds.to_netcdf(tmp, mode="a", group=name, engine="netcdf4", format="NETCDF4")

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        return atomic_write(path, to_file)

    @classmethod
    def read(cls, path: Path) -> DiagnosisEvidence:
        """Read an ``evidence.nc`` :meth:`write` wrote.

        Raises
        ------
        FileNotFoundError
            Naming the file, where it does not exist.
        ValueError
            Naming the file, where it is not readable netCDF, is of another schema version, or
            lacks a variable or group the report reads.
        """
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: diagnosis evidence not found ({FOLDER_FILES})")
        where = str(path)
        try:
            with netCDF4.Dataset(path) as nc:
                present = set(nc.groups)
            root = _read_group(path, None)
            groups = {name: _read_group(path, name) for name in GROUPS if name in present}
        except (OSError, ValueError, RuntimeError, KeyError) as exc:
            raise ValueError(
                f"{path}: cannot read the diagnosis evidence (expected a netCDF4 file written "
                f"by simgap diagnose): {type(exc).__name__}: {exc}"
            ) from exc
        root = lift_schema(
            root,
            root.attrs.get("schema_version"),
            UPGRADES,
            SCHEMA_VERSION,
            lambda ds: ds.attrs["schema_version"],
            where,
        )
        if "gap" not in groups:
            raise ValueError(f"{where}: missing group 'gap'")
        image_stats = groups.get("image_stats")
        return cls(
            items=ItemEvidence.from_dataset(root, where),
            gap=GapEvidence.from_dataset(groups["gap"], f"{where} (group gap)"),
            image_stats=None
            if image_stats is None
            else ImageStatEvidence.from_dataset(image_stats, f"{where} (group image_stats)"),
        )


#: Schema-1 split names renamed in schema 2.
_V1_SPLITS = {"report": "measure"}


def upgrade_v1(root: xr.Dataset) -> xr.Dataset:
    """A schema-1 root group in the schema-2 layout: its split ``report`` is ``measure``."""
    out = root.assign_coords(split=[_V1_SPLITS.get(str(s), str(s)) for s in root.split.values])
    return out.assign_attrs(schema_version=2)


#: The older schema versions of ``evidence.nc`` still read, and what lifts each to the current.
UPGRADES = {1: upgrade_v1}


def _read_group(path: Path, group: str | None) -> xr.Dataset:
    """One group of a netCDF file, loaded and in memory form (:func:`decode_cf`)."""
    with xr.open_dataset(path, group=group, engine="netcdf4") as ds:
        return decode_cf(ds.load())


def write_diagnosis_files(
    result: DiagnosisResult, evidence: DiagnosisEvidence, folder: Path
) -> list[Path]:
    """Write ``result.json`` and ``evidence.nc`` into ``folder``, each once, atomically."""
    folder = Path(folder)
    return [write_json(result, folder / RESULT_FILE), evidence.write(folder / EVIDENCE_FILE)]


def read_diagnosis_files(folder: Path) -> tuple[DiagnosisResult, DiagnosisEvidence]:
    """The result and the evidence of a diagnosis folder (:func:`write_diagnosis_files`).

    Raises
    ------
    FileNotFoundError
        Naming the file of the two that does not exist.
    ValueError
        Naming the file and key or variable that does not fit its schema.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: diagnosis folder not found ({FOLDER_FILES})")
    path = folder / RESULT_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path}: diagnosis result not found ({FOLDER_FILES})")
    try:
        data = json.loads(path.read_bytes())
    except ValueError as exc:
        raise ValueError(f"{path}: not JSON ({exc})") from exc
    result = DiagnosisResult.from_json(data, str(path))
    return result, DiagnosisEvidence.read(folder / EVIDENCE_FILE)
