"""The result dataset contract (docs/conventions.md §3) and its atomic netCDF round trip."""

from __future__ import annotations

import netCDF4
import numpy as np
import pytest
import xarray as xr

from simgap.core.axes import AXES
from simgap.results.dataset import build_dataset, read_netcdf, write_netcdf

TAGS = (0, 1)
PS = (0, 7, 14)
THETAS = np.deg2rad([0.0, 90.0, 180.0, 270.0])
VARIANTS = ("baseline", "blur")
REPEATS = (0, 1)
ATTRS = {"config": "name: test\nrender: {spp: 4}\n", "seed": "123", "renderer": "llvm_ad_rgb"}

FULL = ("variant", "repeat", "tag", "p", "theta")
CONTRACT = {
    "expected": ("tag", "p", "theta", "axis"),
    "estimated": FULL + ("axis",),
    "error": FULL + ("axis",),
    "visible": ("tag", "p", "theta"),
    "detected": FULL,
    "reproj_px": FULL,
    "corners": FULL + ("corner", "uv"),
}
#: units attrs in memory: one string for the pose variables (split on disk, simgap.results.cf),
#: "1" for pixel quantities (udunits has no pixel; a pixel distance is dimensionless)
UNITS = {
    "expected": "m (tx, ty, tz); rad (rx, ry, rz)",
    "estimated": "m (tx, ty, tz); rad (rx, ry, rz)",
    "error": "m (tx, ty, tz); rad (rx, ry, rz)",
    "reproj_px": "1",
    "corners": "1",
}


def make_inputs(seed: int = 0, visible_per_variant: bool = False):
    rng = np.random.default_rng(seed)
    nt, npin, nth = len(TAGS), len(PS), len(THETAS)
    nv, nr = len(VARIANTS), len(REPEATS)
    expected = rng.normal(size=(nt, npin, nth, 6))
    vshape = (nv, nt, npin, nth) if visible_per_variant else (nt, npin, nth)
    visible = rng.random(vshape) > 0.5
    detected = rng.random((nv, nr, nt, npin, nth)) > 0.3
    estimated = rng.normal(size=(nv, nr, nt, npin, nth, 6))
    estimated[~detected] = np.nan
    error = estimated - expected
    reproj = rng.random((nv, nr, nt, npin, nth))
    reproj[~detected] = np.nan
    corners = rng.uniform(0, 1920, size=(nv, nr, nt, npin, nth, 4, 2))
    corners[~detected] = np.nan
    results = {
        "detected": detected,
        "estimated": estimated,
        "error": error,
        "reproj_px": reproj,
        "corners": corners,
    }
    return expected, visible, results


def build(visible_per_variant: bool = False):
    expected, visible, results = make_inputs(visible_per_variant=visible_per_variant)
    ds = build_dataset(
        TAGS,
        PS,
        THETAS,
        expected,
        visible,
        results,
        variants=VARIANTS,
        repeats=REPEATS,
        attrs=ATTRS,
    )
    return ds, expected, visible, results


def check_contract(ds, visible_dims=CONTRACT["visible"]):
    for name in ("tag", "p", "theta", "axis", "variant", "repeat"):
        assert name in ds.coords, name
    assert list(ds.axis.values) == list(AXES) == ["tx", "ty", "tz", "rx", "ry", "rz"]
    assert list(ds.tag.values) == list(TAGS)
    assert np.issubdtype(ds.tag.dtype, np.integer)
    assert list(ds.p.values) == list(PS)
    assert np.issubdtype(ds.p.dtype, np.integer)
    assert np.issubdtype(ds.theta.dtype, np.floating)
    assert list(ds.variant.values) == list(VARIANTS)
    assert list(ds.repeat.values) == list(REPEATS)
    assert np.issubdtype(ds.repeat.dtype, np.integer)
    assert ds.sizes["corner"] == 4
    assert ds.sizes["uv"] == 2
    for name, dims in CONTRACT.items():
        assert name in ds.data_vars, name
        want = visible_dims if name == "visible" else dims
        assert ds[name].dims == want, (name, ds[name].dims)
    for name, units in UNITS.items():
        assert ds[name].attrs["units"] == units, name
    assert ds.visible.dtype == bool
    assert ds.detected.dtype == bool


def test_build_has_contract():
    ds, *_ = build()
    check_contract(ds)


def test_build_per_variant_visibility():
    ds, *_ = build(visible_per_variant=True)
    check_contract(ds, visible_dims=("variant", "tag", "p", "theta"))


def test_single_variant_defaults_have_length_one_dims():
    expected, visible, results = make_inputs()
    results = {k: v[:1, :1] for k, v in results.items()}
    ds = build_dataset(TAGS, PS, THETAS, expected, visible, results)
    assert ds.sizes["variant"] == 1
    assert ds.sizes["repeat"] == 1
    assert list(ds.variant.values) == ["baseline"]


@pytest.mark.parametrize("visible_per_variant", [False, True])
def test_netcdf_round_trip(tmp_path, visible_per_variant):
    ds, expected, visible, results = build(visible_per_variant)
    path = tmp_path / "sub" / "result.nc"
    out = write_netcdf(ds, path)
    assert out == path
    assert path.is_file()
    # Atomic write: the temporary file was renamed away, nothing else left behind.
    assert sorted(p.name for p in path.parent.iterdir()) == ["result.nc"]

    back = read_netcdf(path)
    vdims = ("variant", "tag", "p", "theta") if visible_per_variant else CONTRACT["visible"]
    check_contract(back, visible_dims=vdims)

    # netCDF stores float64/bool/int exactly: values must be bit-equal (NaN in the same places).
    np.testing.assert_array_equal(back.expected.values, expected)
    np.testing.assert_array_equal(back.visible.values, visible)
    for name, arr in results.items():
        np.testing.assert_array_equal(back[name].values, arr, err_msg=name)
    assert np.isnan(back.estimated.values).sum() == np.isnan(results["estimated"]).sum() > 0
    np.testing.assert_array_equal(back.theta.values, THETAS)
    for name in ds.variables:
        assert back[name].attrs == ds[name].attrs, name
    for key, value in ATTRS.items():
        assert back.attrs[key] == value
    # The file is closed after reading: it can be replaced in place (atomic rewrite).
    write_netcdf(back, path)
    assert sorted(p.name for p in path.parent.iterdir()) == ["result.nc"]
    assert read_netcdf(path).identical(back)


def test_read_missing_file(tmp_path):
    path = tmp_path / "missing.nc"
    with pytest.raises(FileNotFoundError) as info:
        read_netcdf(path)
    assert str(path) in str(info.value)


def unwritable(ds):
    """``ds`` plus a variable netCDF cannot encode; xarray fails after creating the file."""
    out = ds.copy()
    out["junk"] = ("tag", np.array([{"a": 1}, None], dtype=object))
    return out


def test_failed_write_keeps_previous_file(tmp_path):
    ds, *_ = build()
    path = write_netcdf(ds, tmp_path / "result.nc")
    with pytest.raises(ValueError, match="junk"):
        write_netcdf(unwritable(ds), path)
    back = read_netcdf(path)
    assert "junk" not in back
    np.testing.assert_array_equal(back.error.values, ds.error.values)


def test_failed_write_leaves_no_temp_file(tmp_path):
    ds, *_ = build()
    path = tmp_path / "result.nc"
    with pytest.raises(ValueError, match="junk"):
        write_netcdf(unwritable(ds), path)
    assert list(tmp_path.iterdir()) == []


def test_file_holds_the_cf_form(tmp_path):
    """On disk (docs/conventions.md §3): translation (m) and rotation (rad) parts, char labels."""
    ds, *_ = build()
    path = write_netcdf(ds, tmp_path / "result.nc")
    with xr.open_dataset(path, engine="netcdf4") as raw:
        assert raw.attrs["Conventions"] == "CF-1.10"
        assert "error" not in raw and "axis" not in raw.variables
        for part, axes, unit in (("translation", AXES[:3], "m"), ("rotation", AXES[3:], "rad")):
            var = raw[f"error_{part}"]
            assert var.dims == FULL + (f"{part}_axis",) and var.attrs["units"] == unit
            assert raw[f"{part}_axis"].values.tolist() == list(axes)
            np.testing.assert_array_equal(var.values, ds.error.sel(axis=list(axes)).values)
        assert raw["variant"].values.tolist() == list(VARIANTS)
        # plain xarray indexes every label dimension: selection by name
        ty = raw.error_translation.sel(translation_axis="ty", variant=VARIANTS[-1])
        np.testing.assert_array_equal(
            ty.values, ds.error.sel(axis="ty", variant=VARIANTS[-1]).values
        )
    with netCDF4.Dataset(path) as nc:  # labels are char arrays, not variable-length strings
        assert nc["variant"].dtype == np.dtype("S1")
        assert "variant_label" not in nc.variables


def test_reads_files_with_auxiliary_labels(tmp_path):
    """A file whose labels sit in ``D_label`` auxiliary variables (before they were indexed)."""
    ds, *_ = build()
    path = write_netcdf(ds, tmp_path / "new.nc")
    with xr.open_dataset(path, engine="netcdf4") as raw:
        old = raw.load()
    for dim in [d for d in old.dims if d in old.coords and old[d].dtype.kind in "OSU"]:
        label = (dim, old[dim].values.astype(str), old[dim].attrs)
        old = old.drop_vars(dim).assign_coords({f"{dim}_label": label})
    old.to_netcdf(tmp_path / "old.nc", engine="netcdf4")
    xr.testing.assert_identical(read_netcdf(tmp_path / "old.nc"), read_netcdf(path))


def test_reads_files_written_before_the_cf_form(tmp_path):
    """A file with one mixed-units ``error`` and string coordinates (before CF) still reads."""
    ds, *_ = build()
    path = tmp_path / "old.nc"
    ds.to_netcdf(path, engine="netcdf4")
    assert read_netcdf(path).identical(ds)


def test_flags_say_what_they_mean_on_disk(tmp_path):
    """``visible`` and ``detected`` are 0/1 bytes with CF's flag_values and flag_meanings, so
    plain xarray or netCDF4 readers see what each value means (issue 53); read back as booleans."""
    ds = build()[0]
    path = write_netcdf(ds, tmp_path / "flags.nc")
    with netCDF4.Dataset(path) as nc:
        for name in ("visible", "detected"):
            var = nc[name]
            assert var.dtype == np.int8
            assert list(var.getncattr("flag_values")) == [0, 1]
            assert var.getncattr("flag_meanings") == f"not_{name} {name}"
    back = read_netcdf(path)
    assert back.visible.dtype == bool and back.detected.dtype == bool
    assert bool((back.visible == ds.visible).all()) and bool((back.detected == ds.detected).all())


def test_cf_check_fails_on_a_variable_without_units_or_long_name(tmp_path):
    """The CF check of every dataset test names a new variable that lacks units or long_name."""
    from tests.cf_check import missing_metadata

    ds, *_ = build()
    path = write_netcdf(ds, tmp_path / "ok.nc")
    assert missing_metadata(path) == []
    ds["new_thing"] = ds["reproj_px"] * 2.0
    ds["new_thing"].attrs = {}
    path = write_netcdf(ds, tmp_path / "bad.nc")
    assert missing_metadata(path) == ["new_thing: no long_name", "new_thing: no units"]
