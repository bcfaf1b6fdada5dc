"""primfit.research: the shipped networks, their held-out scores, and ``experiments evaluate``.

These tests need torch; they skip without it, and fail under PRIMFIT_REQUIRE_ALL=1.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import require

from primfit.research import nine


@pytest.fixture(scope="module")
def torch():
    t = require("torch")
    t.set_num_threads(1)
    return t


@pytest.fixture(scope="module")
def pretrained(torch):
    import primfit.research.pretrained as pretrained

    return pretrained


@pytest.mark.parametrize("name", ["pointnet2", "local"])
def test_shipped_networks_reach_the_thesis_accuracy_on_held_out_scenes(pretrained, name):
    """Table 5.1's all → all row (thesis 0.96 / 0.98) on 300 scenes no training run saw."""
    from primfit.research.evaluate import evaluate

    r = evaluate(name, 300, seed=11)
    assert r["scene_accuracy"] >= 0.95 and r["primitive_accuracy"] >= 0.99, r
    assert r["false_positive_rate"] <= 0.01 and r["recall"] >= 0.99, r


def test_shipped_weights_are_small_and_carry_their_card(pretrained):
    total = sum((pretrained.WEIGHTS / f"{n}.pt").stat().st_size for n in pretrained.NAMES)
    assert total < 20e6
    for name in pretrained.NAMES:
        card = pretrained.pretrained_card(name)
        assert card["config"]["arch"] == name and card["seconds"] > 0 and "primfit.research.pretrained" in card["command"]


def test_load_pretrained_imports_torch_only_when_called_and_returns_an_eval_module(torch):
    probe = "import sys, primfit.research; primfit.research.load_pretrained; print('torch' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0 and done.stdout.strip() == "False", done.stderr
    import primfit.research

    model = primfit.research.load_pretrained("local")
    assert not model.training
    clouds = nine.make_scenes([0b101], spec=nine.SceneSpec(), seed=3, problems=False).clouds
    with torch.no_grad():
        p = model(torch.as_tensor(clouds))
    assert p.shape == (1, 9) and ((p > 0.5).numpy()[0] == (nine.bits([0b101])[0] > 0.5)).all()


def test_save_and_load_round_trip(pretrained, torch, tmp_path):
    from primfit.research.nn import PointNet2
    from primfit.research.train import TrainConfig

    torch.manual_seed(0)
    model = PointNet2(9, width=0.25, centres=(16, 4), k=8).eval()
    pretrained.save_pretrained(tmp_path / "pointnet2.pt", model, TrainConfig("pointnet2"), nine.SceneSpec(), {"seconds": 1.0})
    back = pretrained.load_pretrained("pointnet2", folder=tmp_path)
    x = torch.as_tensor(nine.make_scenes([7, 300], seed=1, problems=False).clouds)
    with torch.no_grad():
        assert torch.equal(model(x), back(x))


def test_bad_names_and_files_raise_clear_errors(pretrained, tmp_path):
    with pytest.raises(ValueError, match="no pretrained network 'resnet'"):
        pretrained.load_pretrained("resnet")
    with pytest.raises(FileNotFoundError, match="missing"):
        pretrained.load_pretrained("local", folder=tmp_path)
    (tmp_path / "local.pt").write_bytes(b"not a torch file")
    with pytest.raises(ValueError, match="local.pt: not a readable weights file"):
        pretrained.load_pretrained("local", folder=tmp_path)


def test_held_out_scenes_are_seeded_and_disjoint_from_training():
    from primfit.research.evaluate import HELD_OUT_SEEDS, held_out_scenes

    a = held_out_scenes(20, 4, nine.SceneSpec())
    b = held_out_scenes(20, 4, nine.SceneSpec())
    c = held_out_scenes(20, 5, nine.SceneSpec())
    assert np.array_equal(a.clouds, b.clouds) and np.array_equal(a.masks, b.masks)
    assert not np.array_equal(a.masks, c.masks)
    assert HELD_OUT_SEEDS > 10**9  # training scenes are seeded seed · 10⁶ + s
    with pytest.raises(ValueError, match="--scenes"):
        held_out_scenes(0, 1, nine.SceneSpec())


def _evaluate_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "primfit.research.experiments", "evaluate", *args],
        capture_output=True, text=True, timeout=300, check=False,
    )


def test_evaluate_command_prints_json_scores(torch):
    done = _evaluate_cli("--model", "local", "--scenes", "40", "--seed", "2", "--json")
    assert done.returncode == 0, done.stderr
    r = json.loads(done.stdout)
    assert (r["model"], r["scenes"], r["seed"]) == ("local", 40, 2)
    for key in ("scene_accuracy", "primitive_accuracy", "recall", "false_positive_rate"):
        assert 0 <= r[key] <= 1
    again = json.loads(_evaluate_cli("--model", "local", "--scenes", "40", "--seed", "2", "--json").stdout)
    assert {k: v for k, v in again.items() if k != "seconds"} == {k: v for k, v in r.items() if k != "seconds"}


def test_evaluate_command_rejects_bad_input_in_one_line(torch):
    done = _evaluate_cli("--model", "local", "--scenes", "0")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "--scenes" in done.stderr.strip().splitlines()[-1]
