"""Batch runs (deformable_flsm.batch) on a local Dask cluster: the example's grid written with an
index, resumed after a loss, bad specs refused before any sample runs."""
import csv
import json
import os

import numpy as np
import pytest
import yaml

from deformable_flsm import batch as B
from deformable_flsm.fit import Cluster

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
POKES = os.path.join(REPO, "examples", "batch", "pokes.yaml")
PATH = os.path.join(REPO, "examples", "fit", "punch_fem.csv")


@pytest.fixture(scope="module")
def local():
    cluster = Cluster(workers=2)
    yield cluster
    cluster.close()


def rows(out):
    with open(os.path.join(out, "index.csv")) as f:
        return list(csv.DictReader(f))


def test_the_example_grid_is_written_with_an_index_and_resumes(local, tmp_path):
    out = str(tmp_path)
    summary = B.batch(POKES, out, local, log=lambda m: None)
    assert summary == {"samples": 12, "ran": 12, "seconds": summary["seconds"], "refused": 0}
    index = rows(out)
    assert [int(r["sample"]) for r in index] == list(range(12))
    peak = {}
    for r in index:
        d = np.load(os.path.join(out, r["file"]))
        params = json.loads(str(d["params"]))
        assert float(r["youngs_modulus"]) == params["youngs_modulus"]
        n = len(d["rest/flsm_object"])
        assert d["positions/flsm_object"].shape == (len(d["times"]), n, 3)
        assert list(d["colliders"]) == ["punch"]
        assert np.all(np.isfinite(d["positions/flsm_object"]))
        peak[(params["youngs_modulus"], params["poissons_ratio"], params["damping"])] = d["wrenches"][:, 0, 2].max()
    # linear elasticity: at 2 mm in 5 cm the punch's force is proportional to the modulus
    for nu in (0.0, 0.3):
        for c in (5.0, 20.0):
            assert peak[(100000.0, nu, c)] / peak[(10000.0, nu, c)] == pytest.approx(10.0, rel=0.02)
    # a lost sample (its file gone) is run again, and only it
    os.remove(os.path.join(out, index[5]["file"]))
    again = B.batch(POKES, out, local, log=lambda m: None)
    assert again["ran"] == 1 and again["samples"] == 12
    assert os.path.isfile(os.path.join(out, index[5]["file"]))


def test_a_random_set_of_drops(local, tmp_path):
    spec = tmp_path / "drops.yaml"
    spec.write_text(yaml.safe_dump({
        "scene": os.path.join(REPO, "examples", "fit", "punch_scene.yaml"),
        "seconds": 0.5, "record_every": 5,
        "random": {"count": 3, "seed": 4, "bounds": {"youngs_modulus": [1e4, 1e6], "damping": [0.1, 0.9]}}}))
    summary = B.batch(str(spec), str(tmp_path / "out"), local, log=lambda m: None)
    assert summary["ran"] == 3
    values = [float(r["youngs_modulus"]) for r in rows(str(tmp_path / "out"))]
    assert all(1e4 <= v <= 1e6 for v in values) and len(set(values)) == 3


def test_bad_specs_are_refused_before_any_sample(local, tmp_path):
    def spec(**kw):
        p = tmp_path / "spec.yaml"
        p.write_text(yaml.safe_dump({"scene": os.path.join(REPO, "examples", "fit", "punch_scene.yaml"), **kw}))
        return str(p)
    with pytest.raises(B.BatchError, match="either grid"):
        B.batch(spec(), str(tmp_path / "a"), local)
    with pytest.raises(B.BatchError, match="low < high"):
        B.batch(spec(random={"count": 2, "bounds": {"damping": [0.5, 0.1]}}), str(tmp_path / "a"), local)
    with pytest.raises(B.BatchError, match="~youngs_modulus"):
        B.batch(spec(grid={"youngs_modulus": ["soft"]}), str(tmp_path / "a"), local)
    with pytest.raises(B.BatchError, match="no collider 'finger'"):
        B.batch(spec(grid={"damping": [0.1]}, tool={"id": "finger", "path": PATH}), str(tmp_path / "a"), local)
    with pytest.raises(B.BatchError, match="tool path"):
        B.batch(spec(grid={"damping": [0.1]}, tool={"id": "punch", "path": POKES}), str(tmp_path / "a"), local)
    assert not os.path.exists(tmp_path / "a")
