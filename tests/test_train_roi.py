"""The ROI classifier experiment (examples/aircraft_cabin/train_roi.py) at a tiny size.

It needs the ``train`` extra (torch). CI installs it (``.ci/run``), so there a missing torch
fails; elsewhere these tests skip with the install command as the reason. The crops are drawn
here (one pattern per label), so no render is needed; 1 epoch at 16 px.
"""

from __future__ import annotations

import csv
import importlib
import json
import os
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

pytestmark = pytest.mark.train

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "aircraft_cabin"
LABELS = ("correct", "incorrect", "empty")


def _script():
    if str(EXAMPLE) not in sys.path:
        sys.path.insert(0, str(EXAMPLE))
    return importlib.import_module("train_roi")


def _torch():
    if os.environ.get("CI"):
        import torch  # CI installs the train extra: a missing torch fails the test here

        return torch
    return pytest.importorskip("torch", reason="needs the train extra: pip install -e '.[train]'")


def _roi_folder(folder: Path, counts: dict[str, int], seed: int) -> Path:
    """An exports/rois folder: ``counts[label]`` crops of 20x14 px, a pattern per label
    (correct: a dark box low, incorrect: a bright box high, empty: noise only)."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for label, n in counts.items():
        (folder / label).mkdir(parents=True, exist_ok=True)
        for i in range(n):
            image = rng.integers(90, 140, size=(14, 20, 3)).astype(np.uint8)
            if label == "correct":
                image[8:13, 4:16] = 20
            elif label == "incorrect":
                image[1:6, 4:16] = 240
            name = f"{label}/cam_{i:06d}_seat_{i:02d}_is_on.png"
            cv2.imwrite(str(folder / name), image)
            rows.append([name, label, "cam", i, f"seat_{i:02d}", "seat", "is_on", "", 0, 0, 20, 14, "x.png"])
    with open(folder / "index.csv", "w", newline="") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(["path", "label", "camera", "frame", "place", "place_kind", "relation", "objects",
                         "x", "y", "w", "h", "image"])
        writer.writerows(rows)
    return folder


def _sets(tmp_path: Path, counts: dict[str, int]) -> list[str]:
    args = []
    for k, name in enumerate(("balanced", "random", "single-class", "test")):
        args += ["--rois", f"{name}={_roi_folder(tmp_path / 'rois' / name, counts, k)}"]
    return args


TINY = ["--epochs", "1", "--size", "16", "--batch", "8", "--seeds", "0", "1", "--threads", "1", "--quiet"]


def test_smoke_three_trainings_write_the_report(tmp_path, capsys):
    _torch()
    train_roi = _script()
    work = tmp_path / "work"
    status = train_roi.main(["--work", str(work), *TINY, "--rois-per-set", "12", "--test-rois", "0",
                             *_sets(tmp_path, {"correct": 6, "incorrect": 5, "empty": 4})])
    assert status == 0, capsys.readouterr().err
    results = json.loads((work / "results.json").read_text())
    assert results["classes"] == list(LABELS)
    assert list(results["trainings"]) == ["balanced", "random", "single-class"]
    for name, training in results["trainings"].items():
        assert training["size"] == 12  # equal sizes, drawn from 15 crops
        assert [r["seed"] for r in training["runs"]] == [0, 1]
        for run in training["runs"]:
            final = run["final"]["test"]
            assert 0.0 <= final["accuracy"] <= 1.0
            assert np.asarray(final["confusion"]).sum() == 15  # the whole test set
            assert np.trace(final["confusion"]) / 15 == pytest.approx(final["accuracy"])
            assert run["steps"] == 2 and run["seconds_per_step"] > 0.0  # 12 crops in batches of 8
            assert len(run["curves"]["train_loss"]) == 1 and len(run["curves"]["test_accuracy"]) == 1
    assert results["data"]["counts"]["test"] == {"correct": 6, "empty": 4, "incorrect": 5}
    table = (work / "results.md").read_text()
    assert "| balanced |" in table and "| single-class |" in table and "recall incorrect" in table
    curves = cv2.imread(str(work / "curves.png"))
    assert curves is not None and curves.shape[0] > 400 and curves.shape[1] > 1000
    assert "results.json" in capsys.readouterr().out


def test_real_test_folder_is_evaluated_too(tmp_path):
    _torch()
    train_roi = _script()
    real = tmp_path / "real"
    _roi_folder(real, {"correct": 3, "empty": 2}, 9)
    (real / "index.csv").unlink()  # a plain image folder: one sub-folder per label
    work = tmp_path / "work"
    assert train_roi.main(["--work", str(work), *TINY, "--train-sets", "balanced", "--real-test", str(real),
                           *_sets(tmp_path, {"correct": 4, "incorrect": 4, "empty": 4})]) == 0
    results = json.loads((work / "results.json").read_text())
    assert results["eval_sets"] == ["test", "real"] and results["eval_sizes"]["real"] == 5
    assert np.asarray(results["trainings"]["balanced"]["runs"][0]["final"]["real"]["confusion"]).sum() == 5
    assert "Evaluated on `real`" in (work / "results.md").read_text()


@pytest.mark.parametrize("counts, message", [
    ({"correct": 7}, "has crops of one label only (correct 7, incorrect 0, empty 0)"),
    ({}, "is empty (correct 0, incorrect 0, empty 0)"),
])
def test_empty_or_one_class_sets_are_refused_with_the_counts(tmp_path, capsys, counts, message):
    _torch()
    train_roi = _script()
    status = train_roi.main(["--work", str(tmp_path / "work"), *TINY, *_sets(tmp_path, counts)])
    err = capsys.readouterr().err
    assert status == 1
    assert err.startswith("train_roi.py: error: ROI set 'single-class' ") and message in err
    assert "Traceback" not in err and not (tmp_path / "work" / "results.json").exists()


def test_a_real_test_folder_with_an_unknown_label_is_refused(tmp_path, capsys):
    _torch()
    train_roi = _script()
    real = tmp_path / "real"
    (real / "misplaced").mkdir(parents=True)
    status = train_roi.main(["--work", str(tmp_path / "work"), *TINY, "--real-test", str(real),
                             *_sets(tmp_path, {"correct": 3, "empty": 3})])
    assert status == 1
    assert "folder(s) misplaced are no label of the roi_rules (labels: correct, incorrect, empty)" in capsys.readouterr().err


def test_the_setup_says_the_rules_judge_luggage():
    """The labels come from ``usdscene export rois`` alone: the experiment's setup (which
    ``usdscene generate`` copies into every set) leaves seats holding only a passenger empty."""
    train_roi = _script()
    setup = train_roi.cabin_setup(["seats_L03"], ["seat_03*"], 64, 1)
    assert setup.roi_ignore == ("passenger",)
    assert train_roi.roi_classes(setup.roi_rules) == LABELS


def test_without_torch_the_install_command_is_named(tmp_path, capsys, monkeypatch):
    """No torch installed (import fails): one line naming the extra's install command, exit 1."""
    train_roi = _script()
    monkeypatch.setitem(sys.modules, "torch", None)  # makes `import torch` raise ImportError
    status = train_roi.main(["--work", str(tmp_path / "work"), *TINY])
    err = capsys.readouterr().err
    assert status == 1
    assert err == ("train_roi.py: error: training needs PyTorch, which is not installed; install the train "
                   "extra: pip install 'usdscene[train]' (in a checkout: pip install -e '.[train]')\n")


def test_efficientnet_b0_matches_torchvisions_and_loads_its_state_dict(tmp_path, capsys):
    """5,288,548 parameters with 1000 classes: torchvision's efficientnet_b0. A state dict saved
    from one model loads into another (all but the classifier); a wrong file is refused."""
    torch = _torch()
    train_roi = _script()
    imagenet = train_roi.efficientnet_b0(1000)
    assert sum(p.numel() for p in imagenet.parameters()) == 5_288_548
    assert "features.1.0.block.1.fc1.weight" in imagenet.state_dict()  # torchvision's names
    weights = tmp_path / "b0.pth"
    torch.save(imagenet.state_dict(), weights)
    model = train_roi.efficientnet_b0(3)
    loaded = train_roi.load_weights(model, weights)
    assert loaded == len(imagenet.state_dict()) - 2  # all but classifier.1.weight/bias
    assert torch.equal(model.state_dict()["features.8.0.weight"], imagenet.state_dict()["features.8.0.weight"])
    assert model(torch.zeros(2, 3, 32, 32)).shape == (2, 3)
    bad = tmp_path / "other.pth"
    torch.save({"conv.weight": torch.zeros(3)}, bad)
    with pytest.raises(train_roi.UsageError, match="not an EfficientNet-B0 state dict"):
        train_roi.load_weights(model, bad)


def test_metrics_and_summaries():
    train_roi = _script()
    result = train_roi.metrics(np.array([0, 0, 1, 2, 2, 2]), np.array([0, 1, 1, 2, 2, 0]), LABELS)
    assert result["confusion"] == [[1, 1, 0], [0, 1, 0], [1, 0, 2]]
    assert result["accuracy"] == pytest.approx(4 / 6)
    assert result["recall"] == {"correct": 0.5, "incorrect": 1.0, "empty": pytest.approx(2 / 3)}
    assert result["mean_recall"] == pytest.approx((0.5 + 1.0 + 2 / 3) / 3)
    assert train_roi.summarise([0.5, 0.7, 0.6]) == {"mean": pytest.approx(0.6), "std": pytest.approx(0.1),
                                                    "min": 0.5, "max": 0.7}
    assert train_roi.roi_classes({"is_below": "correct", "is_in": "correct", "is_on": "incorrect"}) == LABELS
