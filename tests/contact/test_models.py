"""The contact model interface (issue 25): a scene composes its models, and a new model is one class."""

import numpy as np
import pytest
import xarray as xr

from xtopo import datasets
from xtopo.contact import ElasticHalfSpace, Model, PlasticCap, Scene
from xtopo.errors import ContactError


def _surface():
    return datasets.fractal_surface((32, 32), 1.0, hurst=0.8, units="um", seed=4)


def test_hardness_is_the_plastic_cap_model():
    """``hardness=`` builds a PlasticCap: the same scene as giving the model, the same result to the bit."""
    ds = _surface()
    by_keyword, by_model = Scene(ds, hardness=0.05), Scene(ds, models=[PlasticCap(0.05)])
    assert [type(m) for m in by_model.models] == [ElasticHalfSpace, PlasticCap] and by_model.hardness == 0.05
    assert repr(by_keyword) == repr(by_model)
    a, b = by_keyword.solve(mean_pressure=0.02), by_model.solve(mean_pressure=0.02)
    xr.testing.assert_identical(a, b)
    assert a["plastic"].any() and float(a["pressure"].max()) <= 0.05
    assert len(Scene(ds).models) == 1 and Scene(ds).hardness is None


class _Tagged(Model):
    """A model that only adds an output and a line of the repr (what a new model's class declares)."""

    def outputs(self, scene, res):
        return {"touching": (scene.dims, res.pressure > 0, {"units": "1", "long_name": "touching (tag model)"})}

    attrs = {"tag": "yes"}

    def check_control(self, name, value, label, scene=None):
        if name == "penetration":
            raise ContactError(f"{label}: the tag model takes loads only")


def test_a_new_model_is_composed_without_touching_the_solver():
    ds = _surface()
    scene = Scene(ds, models=[_Tagged()])
    r = scene.solve(mean_pressure=0.01)
    np.testing.assert_array_equal(r["touching"].values, r["contact"].values)
    assert r["touching"].attrs["units"] == "1" and r.attrs["tag"] == "yes" and "tag=yes" in r.attrs["history"]
    assert "_Tagged(tag=yes)" in repr(scene)
    xr.testing.assert_equal(r["pressure"], Scene(ds).solve(mean_pressure=0.01)["pressure"])
    with pytest.raises(ContactError, match="loads only"):
        scene.curve(penetrations=[0.01])


@pytest.mark.parametrize("models", [[PlasticCap(0.1), PlasticCap(0.2)], ["hardness"], [ElasticHalfSpace(2.0)]])
def test_models_one_of_each_kind(models):
    with pytest.raises(ContactError, match="one of each kind"):
        Scene(_surface(), models=models)
    with pytest.raises(ContactError, match="one of each kind"):
        Scene(_surface(), hardness=0.1, models=[PlasticCap(0.2)])
