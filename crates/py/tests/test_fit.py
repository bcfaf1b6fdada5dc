"""`fit`, `candidates`, and the same problem solved three ways: primfit.fit, scipy's
L-BFGS-B on our loss, and the Rust CLI."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import require, unavailable

import primfit

REPO = Path(__file__).resolve().parents[3]

# The plain lattice pipeline (`primfit fit --types square --frame axis --no-refine`):
# primitives exactly on the lattice, which these tests compare with other solutions of the
# same loss (the default, types auto, is the compact model: no lattice).
LATTICE = {"types": "square", "frame": "axis", "refine": False}


def corner() -> np.ndarray:
    """A 2 m × 2 m floor patch at z = 0 and a wall at x = 0, on a 0.5 m lattice."""
    a = np.arange(40) * 0.05 + 0.025
    u, v = (m.ravel() for m in np.meshgrid(a, a, indexing="ij"))
    floor = np.stack([u, v, np.zeros_like(u)], axis=1)
    wall = np.stack([np.zeros_like(u), u, v], axis=1)
    return np.concatenate([floor, wall])


def key(primitive: dict) -> tuple:
    """A primitive's identity for comparing solutions (type, sizes, pose)."""
    pose = primitive["pose"]
    return (
        primitive["type"],
        json.dumps(primitive["size"], sort_keys=True),
        tuple(np.round(pose["translation"], 9)),
        tuple(np.round(pose["rotation"], 9)),
    )


def test_fit_result_round_trip():
    cloud = corner()
    result = primfit.fit(cloud, size=1.0, **LATTICE)
    assert len(result) == len(result.primitives) >= 8
    assert result.existence.shape == (len(result.primitives),)
    assert result.existence.dtype == np.float64
    for q, e in zip(result.primitives, result.existence):
        assert q["type"] == "square" and q["size"] == {"side": 1.0}
        assert q["existence"] == pytest.approx(e)
        assert set(q["pose"]) == {"translation", "rotation", "scale"}
    doc = json.loads(result.to_json())
    assert set(doc) == {"primfit", "settings", "metrics", "primitives"}
    assert doc["primfit"] == primfit.__version__
    assert doc["primitives"] == result.primitives
    assert doc["settings"] == result.settings
    assert result.settings["size"] == 1.0 and result.settings["spacing"] == 0.5
    # Every point lies on the fitted squares.
    assert result.metrics["point_to_model_max"] < 1e-9
    assert "square" in repr(result)


def test_fit_options_reach_the_core():
    cloud = corner()
    result = primfit.fit(
        cloud, size=1.0, spacing=0.5, model="independent", alpha=5, beta=3,
        cap=0.4, weights=(1.0, 2.0), parameterization="logit", max_iterations=50, seed=7,
        origin=(0, 0, 0), **LATTICE,
    )
    s = result.settings
    assert (s["model"], s["alpha"], s["beta"], s["cap"]) == ("independent", 5, 3, 0.4)
    assert (s["weights"], s["parameterization"], s["max_iterations"], s["seed"]) == ([1.0, 2.0], "logit", 50, 7)
    assert s["types"] == ["square"]
    assert (s["frame"]["source"], s["refine"]) == ("axis", None)
    unlimited = primfit.fit(cloud, size=1.0, beta="inf", alpha=float("inf"), **LATTICE).settings
    assert (unlimited["alpha"], unlimited["beta"]) == ("inf", "inf")


def test_fit_is_deterministic_and_float32_gives_the_same_answer():
    cloud = corner()
    a = primfit.fit(cloud, size=1.0, **LATTICE)
    b = primfit.fit(cloud.astype(np.float32), size=1.0, **LATTICE)  # rounded points, same lattice
    c = primfit.fit(cloud, size=1.0, **LATTICE)
    assert a.to_json() == c.to_json()
    assert [key(q) for q in b.primitives] == [key(q) for q in a.primitives]


def test_mesh_type_with_an_array_mesh():
    # A unit square (two triangles) as the `mesh` type: fits the floor like a square.
    vertices = np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    cloud = corner()[:1600]  # the floor only
    options = {**LATTICE, "types": ["mesh"]}
    result = primfit.fit(cloud, mesh_model=(vertices, faces), size=1.0, spacing=0.5, **options)
    assert result.primitives and all(q["type"] == "mesh" for q in result.primitives)
    assert result.metrics["point_to_model_mean"] < 0.01


def test_candidates_reproduce_the_fit_loss():
    cloud = corner()
    cands = primfit.candidates(cloud, size=1.0, **LATTICE)
    n = len(cands)
    assert n > 8 and cands.samples.shape[1] == 3 and cands.owner.shape == (len(cands.samples),)
    assert set(np.unique(cands.owner)) == set(range(n))
    assert cands.settings["size"] == 1.0
    problem = cands.problem()
    assert problem.n_candidates == n and problem.n_points == len(cloud)


def test_scipy_lbfgsb_on_our_loss_reaches_the_fit_solution():
    optimize = require("scipy.optimize")
    rng = np.random.default_rng(3)
    cloud = corner() + rng.normal(0.0, 0.005, (3200, 3))
    options = dict(size=1.0, **LATTICE)
    cands = primfit.candidates(cloud, **options)
    problem = cands.problem()
    w_prim, w_point = problem.weights

    def loss(p):
        prim, point, grad = problem.evaluate(p)
        return w_prim * prim + w_point * point, grad

    n = len(cands)
    x, _, info = optimize.fmin_l_bfgs_b(loss, np.full(n, 0.5), bounds=[(0.0, 1.0)] * n, maxiter=500)
    assert info["warnflag"] == 0, info
    ours = sorted(key(cands.primitives[i]) for i in np.flatnonzero(x > 0.5))

    fitted = primfit.fit(cloud, polish=False, **options)
    assert sorted(key(q) for q in fitted.primitives) == ours
    assert len(ours) == 8
    polished = primfit.fit(cloud, **options)
    assert sorted(key(q) for q in polished.primitives) == ours


def cli_binary() -> Path:
    """The `primfit` CLI: $PRIMFIT_CLI, or built from this checkout with cargo."""
    if "PRIMFIT_CLI" in os.environ:
        return Path(os.environ["PRIMFIT_CLI"])
    cargo = shutil.which("cargo")
    if cargo is None or not (REPO / "crates" / "cli").is_dir():
        unavailable("no primfit CLI: set PRIMFIT_CLI or run from a checkout with cargo")
    # The test profile reuses what `cargo test --workspace` (scripts/test.sh) built.
    build = subprocess.run(
        [cargo, "build", "--profile", "test", "-p", "primfit-cli", "--locked", "-q"],
        cwd=REPO, capture_output=True, text=True,
    )
    if build.returncode != 0:
        unavailable(f"the primfit CLI does not build: {build.stderr.strip()[-400:]}")
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    return target / "debug" / "primfit"


def test_cli_fit_gives_the_same_result(tmp_path):
    cli = cli_binary()
    rng = np.random.default_rng(5)
    cloud = corner() + rng.normal(0.0, 0.003, (3200, 3))
    scene = tmp_path / "corner.ply"
    primfit.write_ply(scene, cloud)
    out = tmp_path / "result.json"
    run = subprocess.run(
        [str(cli), "fit", str(scene), "-o", str(out), "--types", "square", "--size", "1", "--frame", "axis",
         "--no-refine", "--quiet"],
        capture_output=True,
        text=True
    )
    assert run.returncode == 0, run.stderr
    doc = json.loads(out.read_text())
    ours = primfit.fit(primfit.read_ply(scene)["points"], size=1.0, **LATTICE)
    assert [key(q) for q in doc["primitives"]] == [key(q) for q in ours.primitives]
    np.testing.assert_allclose([q["existence"] for q in doc["primitives"]], ours.existence, rtol=1e-12)
    settings = {k: v for k, v in doc["settings"].items() if k != "scene"}
    assert settings == ours.settings
    for name, value in ours.metrics.items():
        assert doc["metrics"][name] == pytest.approx(value, rel=1e-9), name


@pytest.mark.parametrize("name", ["hallway", "pipe", "plane_scan", "table_mug"])
def test_fit_without_options_is_primfit_fit_on_every_bundled_example(tmp_path, name):
    """`primfit.fit(points)` with no options gives the primitives of `primfit fit FILE`."""
    cli = cli_binary()
    scene = REPO / "examples" / f"{name}.ply"
    out = tmp_path / "result.json"
    run = subprocess.run([str(cli), "fit", str(scene), "-o", str(out), "--quiet"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    doc = json.loads(out.read_text())
    ours = primfit.fit(primfit.read_ply(scene)["points"])
    assert len(ours.primitives) == len(doc["primitives"]) > 0
    for q, c in zip(ours.primitives, doc["primitives"]):
        assert (q["type"], set(q["size"])) == (c["type"], set(c["size"]))
        ours_numbers = [*q["size"].values(), *q["pose"]["translation"], *q["pose"]["rotation"], q["pose"]["scale"]]
        cli_numbers = [*c["size"].values(), *c["pose"]["translation"], *c["pose"]["rotation"], c["pose"]["scale"]]
        np.testing.assert_allclose(ours_numbers, cli_numbers, rtol=0, atol=1e-9)
    np.testing.assert_allclose([q["existence"] for q in doc["primitives"]], ours.existence, rtol=0, atol=1e-9)
    settings = {k: v for k, v in doc["settings"].items() if k != "scene"}
    assert settings == ours.settings


def test_every_fit_option_reaches_the_core(tmp_path):
    cloud = corner()
    frame = {"rotation": [1.0, 0.0, 0.0, 0.0], "origin": [0.0, 0.0, 0.0]}
    s = primfit.fit(
        cloud, size=1.0, frame=frame, refine=True, refine_rounds=2, search_points=0, polish=False,
        max_iterations=30, sample_spacing=0.1, types=["square", "disk"],
    ).settings
    assert s["frame"]["source"] == "given" and s["origin"] == [0.0, 0.0, 0.0]
    assert s["refine"]["rounds"] == 2 and s["polish"] is False and s["max_iterations"] == 30
    assert s["types"] == ["square", "disk"] and s["sample_spacing"] == 0.1
    assert s["search_points"] == primfit.fit(cloud, size=1.0, search_points="inf", **LATTICE).settings["search_points"]
    # A frame file (here an earlier result) is read as `--frame FILE` does.
    earlier = tmp_path / "earlier.json"
    earlier.write_text(primfit.fit(cloud, size=1.0, **LATTICE).to_json())
    again = primfit.fit(cloud, types="square", size=1.0, frame=str(earlier), refine=False)
    assert again.settings["frame"]["source"] == "given"
    # The method's own options; mcmc needs sensor origins.
    with pytest.raises(ValueError, match="sensor"):
        primfit.fit(cloud, types="square", size=1.0, method="mcmc", steps=10)
    with pytest.raises(ValueError, match="method"):
        primfit.fit(cloud, method="annealing")
    with pytest.raises(OSError, match="sideways"):  # neither auto, axis nor a file
        primfit.fit(cloud, frame="sideways")


def test_mcmc_on_a_scanned_dict_as_read_ply_returns(tmp_path):
    cli = cli_binary()
    scan = tmp_path / "scan.ply"
    run = subprocess.run([str(cli), "synth", "hallway", "--length", "4", "--scan", "2", "-o", str(scan), "--quiet"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    cloud = primfit.read_ply(scan)
    assert "sensors" in cloud
    result = primfit.fit(cloud, size=1.0, method="mcmc", steps=500, sigma=0.02, **LATTICE)
    s = result.settings
    assert s["method"] == "mcmc" and s["mcmc"]["steps"] == 500 and s["ray"]["sigma"] == 0.02
    assert "beta" not in s and result.primitives


def test_free_space_is_on_exactly_with_sensor_origins():
    points = corner()
    # One sensor above the corner's open side: every ray reaches its point unobstructed.
    sensors = np.tile([1.5, 1.5, 1.5], (len(points), 1))
    scan = {"points": points, "sensors": sensors}
    on = primfit.fit(scan, size=1.0, **LATTICE)
    assert on.settings["free_space"] is True and on.primitives
    off = primfit.fit(scan, size=1.0, free_space=False, **LATTICE)
    assert off.settings["free_space"] is False
    # The true squares block no ray: the same fit either way.
    assert sorted(map(key, on.primitives)) == sorted(map(key, off.primitives))
    assert primfit.fit(points, size=1.0, **LATTICE).settings["free_space"] is False
    with pytest.raises(ValueError, match="sensor"):
        primfit.fit(points, size=1.0, free_space=True, **LATTICE)


def test_fit_result_reads_back_from_json(tmp_path):
    result = primfit.fit(corner(), size=1.0, **LATTICE)
    for source in (result.to_json(), json.loads(result.to_json())):
        back = primfit.FitResult.from_json(source)
        assert back.primitives == result.primitives
        assert (back.settings, back.metrics) == (result.settings, result.metrics)
        np.testing.assert_array_equal(back.existence, result.existence)
        assert json.loads(back.to_json()) == json.loads(result.to_json())
    # A result the CLI wrote, with its extra settings (the scene), reads back as it is.
    cli = cli_binary()
    scene, out = tmp_path / "corner.ply", tmp_path / "result.json"
    primfit.write_ply(scene, corner())
    run = subprocess.run([str(cli), "fit", str(scene), "-o", str(out), "--types", "square", "--size", "1", "--quiet"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    from_cli = primfit.FitResult.from_json(out.read_text())
    assert from_cli.settings["scene"] == str(scene) and len(from_cli) == len(json.loads(out.read_text())["primitives"])
    with pytest.raises(ValueError, match="settings"):
        primfit.FitResult.from_json({"settings": {}, "metrics": {}, "primitives": []})
    with pytest.raises(ValueError, match="JSON"):
        primfit.FitResult.from_json("{")
