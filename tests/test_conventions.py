import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.conventions import (convert_length, height_of, is_periodic, lateral_dims, length_factor, length_units_of,
                               make_measurement, normalize_units, physical_size, spacing, validate)
from xtopo.datasets import fractal_surface
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


def test_periodic_attr_other_values_refused_by_both():
    for value in [2, -1, 0.5, "yes", "1.0", "", None, [1], np.array([0, 1])]:
        ds = make_measurement(np.ones((3, 3)), spacing=1.0)
        ds.attrs["periodic"] = value
        with pytest.raises(ValidationError, match="periodic"):
            xtopo.conventions.is_periodic(ds)
        with pytest.raises(ValidationError, match="periodic"):
            validate(ds)


_ANALYSES = {
    "scalars": lambda d: d.topo.scalars(),
    "psd": lambda d: d.topo.psd(),
    "acf": lambda d: d.topo.acf(),
    "vbm": lambda d: d.topo.vbm(),
    "sdrp": lambda d: d.topo.sdrp(),
    "distribution": lambda d: d.topo.distribution(),
}


@pytest.mark.parametrize("analysis", sorted(_ANALYSES))
def test_analyses_refuse_heights_in_another_unit_than_positions(analysis):
    # heights in nm on a µm grid were analysed as µm: Sq 1000x, slopes 1000x, labelled 'um', silently
    ds = fractal_surface((16, 16), 1.0, hurst=0.8, rms_height=0.01, seed=1, units="um")
    _ANALYSES[analysis](ds)
    nm = ds.assign(height=(ds.height * 1000).assign_attrs(units="nm"))
    with pytest.raises(UnitsError, match="height in 'nm', coordinate 'y' in 'um'"):
        _ANALYSES[analysis](nm)
    with pytest.raises(UnitsError, match="height in 'nm', coordinate 'y' in 'um'"):
        _ANALYSES[analysis](nm.height)


def test_analyses_refuse_units_that_are_not_lengths():
    # a coordinate in 's' gave a PSD in 's3' on q in 's-1'; heights in 'kg' were analysed as metres
    for analysis in sorted(_ANALYSES):
        for units in ["furlongz", "s", "kg"]:
            ds = fractal_surface((16, 16), 1.0, hurst=0.8, seed=1)
            for bad in (ds.assign_coords(x=ds.x.assign_attrs(units=units)),
                        ds.assign(height=ds.height.assign_attrs(units=units))):
                with pytest.raises(UnitsError, match=f"units {units!r}, which is not a length unit"):
                    _ANALYSES[analysis](bad)


def test_heights_that_are_not_real_numbers_refused():
    # complex heights: vbm, sdrp and scalars dropped the imaginary part silently, psd/acf raised scipy's
    # TypeError; no heights at all: detrend raised numpy's 'zero-size array to reduction'
    for analysis in sorted(_ANALYSES) + ["detrend", "fill_missing"]:
        for values in [np.arange(16) + 1j, np.array(["a"] * 16), np.ones(16, bool), np.array([])]:
            call = {**_ANALYSES, "detrend": xtopo.preprocess.detrend, "fill_missing": xtopo.preprocess.fill_missing}[analysis]
            x = np.arange(values.size) * 0.1
            ds = xr.Dataset({"height": ("x", values, {"units": "um"})}, coords={"x": ("x", x, {"units": "um"})})
            with pytest.raises(ValidationError, match="'height' (must hold real numbers|has no points)"):
                call(ds)
            with pytest.raises(ValidationError, match="'height' (must hold real numbers|has no points)"):
                height_of(ds.height)


def test_conventions_helpers_refuse_non_xarray_objects():
    # were a bare AttributeError ('NoneType' object has no attribute 'coords'/'attrs'/'dims'/'copy')
    for helper in [spacing, physical_size, lateral_dims, is_periodic, length_units_of,
                                        lambda o: convert_length(o, "nm"), height_of]:
        for obj in [None, "abc", np.zeros((4, 4)), {"height": [1.0]}]:
            with pytest.raises(ValidationError, match="expected a topography"):
                helper(obj)


def test_spacing_and_size_refuse_bad_dims():
    # physical_size raised a bare KeyError for any dim but 'x'/'y', spacing a TypeError for unhashable ones
    for dim in [None, 0, True, ["x"], np.array(["x"]), "z"]:
        for helper in [spacing, physical_size]:
            ds = make_measurement(np.zeros((4, 8)), size=(2.0, 4.0), units="um")
            assert helper(ds, "x") == pytest.approx({spacing: 0.5, physical_size: 4.0}[helper])
            with pytest.raises(GridError, match="dim must be the name|has no coordinate"):
                helper(ds, dim)


def test_make_measurement_refuses_bad_arguments():
    for kwargs, match in [
        (dict(size="abc"), "size must be positive finite"),            # numpy's ValueError
        (dict(size=[]), "size must be positive finite"),               # numpy's broadcast ValueError
        (dict(size=[1.0, "a"]), "size must be positive finite"),
        (dict(size=np.zeros((2, 2, 2))), "size must be positive finite"),
        (dict(size=True), "size must be positive finite"),             # was the size 1
        (dict(spacing=-1.0), "spacing must be positive finite"),
        (dict(size=1.0, height_scale=0), "height_scale must be a finite number other than 0"),
    ]:
        h = np.random.default_rng(0).random((4, 4))
        with pytest.raises(XtopoError, match=match):
            make_measurement(h, **kwargs)


def test_make_measurement_size_spacing_and_scale_still_work():
    h = np.arange(8.0).reshape(2, 4)
    ds = make_measurement(h, size=(1.0, 2.0), height_scale=-2, tip_radius=np.float32(0.5), units="um")
    np.testing.assert_allclose(ds.height.values, -2 * h)
    assert spacing(ds, "x") == spacing(ds, "y") == pytest.approx(0.5) and ds.attrs["tip_radius"] == 0.5
    by_spacing, by_size = make_measurement(h, spacing=0.5, units="um"), make_measurement(h, size=(1, 2), units="um")
    xr.testing.assert_identical(by_spacing.x, by_size.x)


def test_append_history_refuses_non_xarray_objects():
    # a bare AttributeError ('NoneType' object has no attribute 'copy')
    for obj in [None, "abc", 3]:
        with pytest.raises(ValidationError, match="expected a topography"):
            xtopo.conventions.append_history(obj, "step")


def test_to_units_converts_each_length_from_its_own_unit():
    """Heights in nm on positions in µm: analyses refuse the mix and name .topo.to_units as the fix, but
    to_units converted only the lengths in the positions' unit (to 'um' it changed nothing), and a
    tip radius in its own unit was scaled as if it were in the positions' unit."""
    ds = xtopo.datasets.fractal_surface((16, 16), 2.0, hurst=0.8, rms_height=0.05, units="um", seed=3)
    mixed = ds.assign(height=(ds.height * 1000).assign_attrs(units="nm"))
    mixed.attrs.update(tip_radius=20.0, tip_radius_units="nm")
    with pytest.raises(xtopo.UnitsError, match="one length unit"):
        mixed.topo.scalars()
    for to, f in (("um", 1.0), ("nm", 1000.0)):
        out = mixed.topo.to_units(to)
        np.testing.assert_allclose(out.height.values, ds.height.values * f, rtol=1e-12)
        np.testing.assert_allclose(out.x.values, ds.x.values * f, rtol=1e-12)
        assert out.x.attrs["units"] == out.height.attrs["units"] == to
        np.testing.assert_allclose(out.attrs["tip_radius"], 0.02 * f, rtol=1e-12)
        assert out.attrs["tip_radius_units"] == to
        np.testing.assert_allclose(float(out.topo.scalars().Sq), float(ds.topo.scalars().Sq) * f, rtol=1e-10)
    assert "from 'nm', 'um'" in mixed.topo.to_units("m").attrs["history"]
    same = ds.topo.to_units("um")
    assert same.attrs.get("history") == ds.attrs.get("history")  # nothing to convert, nothing recorded


@pytest.mark.parametrize("masked", [False, True])
def test_validate_refuses_a_measurement_without_any_valid_height(masked):
    """All-NaN (or all-masked) heights passed validate: a measurement without a single height."""
    ds = fractal_surface((8, 8), 1.0, hurst=0.8)
    ds = ds.assign(mask=(("y", "x"), np.ones((8, 8), bool))) if masked else ds.assign(height=ds.height * np.nan)
    with pytest.raises(ValidationError, match="'height' has no valid value: all 64 points are NaN or masked"):
        xtopo.validate(ds)


def test_validate_accepts_a_partly_missing_measurement():
    ds = fractal_surface((8, 8), 1.0, hurst=0.8)
    ds = ds.assign(height=ds.height.where(ds.x > ds.x[3]))
    assert xtopo.validate(ds) is ds


def test_validate_of_heights_in_another_unit_names_what_fixes_it():
    """The message suggested .topo.to_units, which then converted only the lengths in the coordinates' unit
    (the heights stayed apart); it converts each length from its own unit now, and the fix it names works."""
    ds = fractal_surface((8, 8), 1.0, hurst=0.8, units="um")
    ds["height"] = (ds.height * 1000).assign_attrs(units="nm")
    with pytest.raises(ValidationError, match=r"convert them to one, e.g. ds.topo.to_units\('um'\)"):
        xtopo.validate(ds)
    fixed = ds.topo.to_units("um")
    xr.testing.assert_allclose(xtopo.validate(fixed).height, fractal_surface((8, 8), 1.0, hurst=0.8).height)
    with pytest.raises(UnitsError, match=r"ds.topo.to_units\('um'\)"):
        xtopo.conventions.shared_length_unit(ds.height)


def test_is_uniform_refuses_what_is_no_coordinate():
    """is_uniform('abc') raised numpy's 'could not convert string to float', a dict a TypeError."""
    for coord in ["abc", {"a": 1}, object(), np.zeros((3, 3)), [True, False, True]]:
        with pytest.raises(GridError, match="is_uniform needs a 1D sequence of positions"):
            xtopo.conventions.is_uniform(coord)


def test_length_attr_key_must_be_a_name():
    """length_attr(ds, key=[...]) raised 'unhashable type: list'."""
    for key in [["tip_radius"], np.zeros(2), {"a": 1}, 3]:
        with pytest.raises(ValidationError, match="key must be the name"):
            xtopo.conventions.length_attr(fractal_surface((8, 8), 1.0, hurst=0.8), key)


def test_a_unit_that_is_not_a_string_is_refused():
    """A non-string unit was str()-ed and handed to pint: b'um' became "b'um'", and the messages quoted
    pint's parser internals ("unindent does not match any outer indentation level", "'ParserHelper'")."""
    for units in [b"um", 5, True, ["um"], np.array(["um"]), 1 + 2j]:
        with pytest.raises(UnitsError, match=rf"a length unit must be a string such as 'm' or 'um', not "
                                             rf"{type(units).__name__}$"):
            normalize_units(units)


def test_common_length_units_need_no_pint_and_equal_its_factors():
    """The fixed table of common length units gives pint's factors exactly (pint is only built for others)."""
    from xtopo import _units

    ureg = _units._ureg()
    for unit, metres in _units._METRES.items():
        assert metres == float(ureg.Quantity(1.0, unit).to("m").magnitude), unit
