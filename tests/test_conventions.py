import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.conventions import (convert_length, height_of, length_factor, make_measurement, normalize_units, spacing,
                               validate)
from xtopo.errors import GridError, UnitsError, ValidationError, XtopoError


def test_unit_normalisation_and_factors():
    assert normalize_units("µm") == "um"
    assert normalize_units("micrometer") == "um"
    assert length_factor("mm", "nm") == pytest.approx(1e6, rel=1e-15)
    with pytest.raises(UnitsError):
        normalize_units("kg")
    with pytest.raises(UnitsError):
        normalize_units("not-a-unit")
    assert issubclass(UnitsError, XtopoError)


def test_to_units_converts_coords_heights_and_length_attrs_consistently():
    ds = make_measurement(np.arange(12.0).reshape(3, 4) * 1e-9, size=(3e-6, 4e-6), units="m", tip_radius=2e-8,
                          resolution=1e-7)
    nm = ds.topo.to_units("nm")
    np.testing.assert_allclose(nm.height.values, ds.height.values * 1e9, rtol=1e-15)
    np.testing.assert_allclose(nm.x.values, ds.x.values * 1e9, rtol=1e-15)
    assert nm.height.attrs["units"] == nm.x.attrs["units"] == nm.y.attrs["units"] == "nm"
    assert nm.attrs["tip_radius"] == pytest.approx(20.0) and nm.attrs["tip_radius_units"] == "nm"
    assert nm.attrs["resolution"] == pytest.approx(100.0)
    assert spacing(nm, "x") == pytest.approx(1e3)
    assert "convert_length" in nm.attrs["history"]
    # the original is untouched and the round trip is exact to round-off
    assert ds.height.attrs["units"] == "m"
    back = convert_length(nm, "m")
    xr.testing.assert_allclose(back.height, ds.height, rtol=1e-14)
    validate(nm)


def test_make_measurement_masks_nan_and_validate_catches_errors():
    h = np.ones((4, 5))
    h[1, 2] = np.nan
    ds = make_measurement(h, spacing=(0.5, 0.25), units="um")
    assert bool(ds.mask[1, 2]) and int(ds.mask.sum()) == 1
    assert np.isnan(float(height_of(ds)[1, 2]))
    validate(ds)
    bad = ds.copy()
    bad["x"] = bad.x.assign_attrs(units="nm")
    with pytest.raises(ValidationError, match="one length unit"):
        validate(bad)
    with pytest.raises(ValidationError, match="height"):
        validate(ds.drop_vars("height"))
    with pytest.raises(GridError):
        make_measurement(np.ones((2, 2, 2)), size=1.0)
    with pytest.raises(GridError):
        make_measurement(np.ones(3), size=-1.0)


def test_nonuniform_line_scan():
    x = np.array([0.0, 0.1, 0.35, 0.4, 1.0])
    ds = make_measurement(np.sin(x), x=x, units="mm")
    assert ds.attrs["grid"] == "nonuniform"
    validate(ds)
    with pytest.raises(GridError, match="not uniformly spaced"):
        spacing(ds, "x")
    with pytest.raises(GridError, match="strictly increasing"):
        make_measurement(np.ones(3), x=[0, 2, 1])


def test_height_of_does_not_write_into_the_dataset():
    ds = make_measurement(np.ones((4, 4)), spacing=1.0, units="m", periodic=True, tip_radius=2e-8)
    height_of(ds)
    assert ds.height.attrs == {"units": "m", "long_name": "height"}
    # so a later conversion is seen by the height (it carried tip_radius 2e-8 next to units "nm")
    nm = convert_length(ds, "nm")
    assert height_of(nm).attrs["tip_radius"] == pytest.approx(20.0)


@pytest.mark.parametrize("value,expected", [
    (1, True), (0, False), (True, True), (np.int8(1), True), (np.bool_(False), False), (1.0, True),
    ("1", True), ("0", False), ("true", True), ("False", False), (" TRUE ", True), (b"1", True),
    (np.array([1]), True), (np.array(["false"]), False)])
def test_periodic_attr_spellings_accepted_by_is_periodic_and_validate(value, expected):
    # files spell the flag as text ("true": NetCDF has no boolean attribute); "1" was accepted but "true" refused
    ds = make_measurement(np.ones((3, 3)), spacing=1.0)
    ds.attrs["periodic"] = value
    assert xtopo.conventions.is_periodic(ds) is expected
    validate(ds)


@pytest.mark.parametrize("value", [2, -1, 0.5, "yes", "1.0", "", None, [1], np.array([0, 1])])
def test_periodic_attr_other_values_refused_by_both(value):
    ds = make_measurement(np.ones((3, 3)), spacing=1.0)
    ds.attrs["periodic"] = value
    with pytest.raises(ValidationError, match="periodic"):
        xtopo.conventions.is_periodic(ds)
    with pytest.raises(ValidationError, match="periodic"):
        validate(ds)


@pytest.mark.parametrize("value", ["false", "0", None, 2])
def test_make_measurement_periodic_must_be_a_bool(value):
    # periodic="false" was stored as periodic=1 (bool of a non-empty string)
    with pytest.raises(ValidationError, match="periodic must be True or False"):
        make_measurement(np.ones(3), spacing=1.0, periodic=value)
